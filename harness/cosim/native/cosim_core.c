/* The fixed-step inner loop of the harness's master, in C: for each macro step set the inputs,
 * step the FMUs (Jacobi or Gauss-Seidel, inputs held or extrapolated linearly) and record a row.
 * Python prepares everything (instances, buffers, routes; the function pointers are the ones fmpy
 * loaded, of FMI 2.0 or 3.0 per unit) and keeps everything else: initialization, iteration, step
 * doubling, rollback, messages. Semantics are those of harness/cosim/master.py, which the tests
 * compare against. */
#include <math.h>
#include <stdint.h>

#include "fmi_calls.h"

/* FMI 3.0 has no input derivatives: an FMI 3.0 unit that receives inputs registers them for intermediate
 * updates, with this struct as its instance environment, and at the start of each step it asks (the callback
 * below) for their values at the step's end; it takes them on the line the master extrapolates, u + (t - t0) du,
 * and varies each input along the line from its value now to that one. */
typedef struct {
    void *component, *set_float; /* the instance and its fmi3SetFloat64 */
    int n;
    const unsigned *vrs;
    const double *u, *du; /* the inputs at the step's start t0, and their slopes */
    double *values; /* the n values set */
    double t0;
    int active; /* 0: inputs held (nothing is set) */
    int status; /* the worst status a set returned in the step */
} InputLine;

void cosim_answer_inputs(void *environment, double t, bool set_requested, bool get_allowed, bool step_finished,
                         bool can_return_early, bool *early_return_requested, double *early_return_time)
{
    InputLine *line = (InputLine *)environment;
    int i, status;
    (void)get_allowed, (void)step_finished, (void)can_return_early, (void)early_return_requested;
    (void)early_return_time;
    if (!line || !set_requested || !line->active) return;
    for (i = 0; i < line->n; i++) line->values[i] = line->u[i] + (t - line->t0) * line->du[i];
    status = ((SetFloat3)line->set_float)(line->component, line->vrs, (size_t)line->n, line->values, (size_t)line->n);
    if (status > line->status) line->status = status;
}

typedef struct {
    FmiCalls calls;
    InputLine *line; /* FMI 3.0 units that receive inputs: how they ask for them; else NULL */
    int n_out, n_in, n_int;
    const unsigned *out_vrs, *in_vrs, *int_vrs;
    const int *orders_out, *orders_in;
    double *y_now, *dy_now, *y_next, *dy_next, *u, *du;
    void *ints; /* n_int integers of calls.integer_kind */
    const int *source_unit; /* per input: index of the unit that feeds it */
    const int *source_index; /* per input: index of that unit's output */
    int energy_index; /* output holding the unit's energy, -1 for none */
} CoreUnit;

static double integer_value(const CoreUnit *unit, int i)
{
    switch (unit->calls.integer_kind) {
    case INTEGER_64: return (double)((const int64_t *)unit->ints)[i];
    case UNSIGNED_64: return (double)((const uint64_t *)unit->ints)[i];
    default: return ((const int *)unit->ints)[i];
    }
}

static const double PI = 3.14159265358979323846; /* math.pi, as the Python loop divides by it */

enum { CORE_OK = STATUS_OK, CORE_DISCARD = STATUS_DISCARD, CORE_ERROR = STATUS_ERROR };
/* cosim_run's answer to arguments it refuses (an algorithm it does not know), beside the FMI codes it passes on */
enum { CORE_REFUSED = -1 };
/* The algorithms, by the ids of their registry (harness/cosim/algorithm_registry.py; a test checks that they
 * agree). */
enum { ALGORITHM_JACOBI = 1, ALGORITHM_GAUSS_SEIDEL = 2 };

static int feed(CoreUnit *units, int k, double H, int linear, const int *stepped)
{
    CoreUnit *unit = &units[k];
    int i, status;
    if (!unit->n_in) return CORE_OK;
    for (i = 0; i < unit->n_in; i++) {
        const CoreUnit *source = &units[unit->source_unit[i]];
        const int o = unit->source_index[i];
        if (stepped[unit->source_unit[i]]) {
            unit->u[i] = linear ? source->y_now[o] : source->y_next[o];
            if (linear) unit->du[i] = (source->y_next[o] - source->y_now[o]) / H;
        } else {
            unit->u[i] = source->y_now[o];
            if (linear) unit->du[i] = source->dy_now[o];
        }
    }
    status = fmi_set_floats(&unit->calls, unit->in_vrs, unit->n_in, unit->u);
    /* an FMI 3.0 unit asks for its inputs' line during the step (InputLine) */
    if (status >= CORE_ERROR || !linear || unit->calls.fmi3) return status;
    return fmi_set_input_derivatives(&unit->calls, unit->in_vrs, unit->n_in, unit->orders_in, unit->du);
}

static int step_and_read(CoreUnit *unit, double t, double H, int linear)
{
    int status;
    if (unit->line) {
        unit->line->t0 = t;
        unit->line->status = CORE_OK;
    }
    status = fmi_do_step(&unit->calls, t, H);
    if (unit->line && unit->line->status >= CORE_ERROR) return CORE_ERROR; /* a set refused: the FMU logged why */
    if (status != CORE_OK && status != 1) return status;
    status = fmi_get_floats(&unit->calls, unit->out_vrs, unit->n_out, unit->y_next);
    if (status >= CORE_ERROR || !linear) return status;
    return fmi_get_output_derivatives(&unit->calls, unit->out_vrs, unit->n_out, unit->orders_out, unit->dy_next);
}

static int record(CoreUnit *units, int n_units, double t, double *row, double *energy, int *culprit)
{
    int k, i, column = 1;
    double total = 0.0;
    row[0] = t;
    for (k = 0; k < n_units; k++) {
        for (i = 0; i < units[k].n_out; i++) row[column++] = units[k].y_now[i];
        if (units[k].energy_index >= 0) total += units[k].y_now[units[k].energy_index];
    }
    for (k = 0; k < n_units; k++) {
        if (!units[k].n_int) continue;
        if (fmi_get_integers(&units[k].calls, units[k].int_vrs, units[k].n_int, units[k].ints) >= CORE_ERROR) {
            *culprit = k;
            return CORE_ERROR;
        }
        for (i = 0; i < units[k].n_int; i++) row[column++] = integer_value(&units[k], i);
    }
    *energy = total;
    return CORE_OK;
}

/* The energy check of harness/cosim/contact_guard.py (ContactGuard), the same arithmetic in the same order: after
 * each accepted macro step, the scene's energy E (each unit's energy output) risen above its lowest by more than
 * `share` of the largest energy in motion K seen before (every E_kin and every contact's stored E_pot), beyond the
 * rounding, stops the run. Python fills the settings and composes the message from what is left here. */
typedef struct {
    int n_kinetic, n_watches;
    const int *kinetic_unit, *kinetic_index; /* the units' E_kin outputs */
    const int *watch_unit, *watch_gap, *watch_rate, *watch_stored; /* per contact; watch_stored -1: no E_pot */
    double share, floor_share;
    double low, scale, magnitude; /* carried from one call to the next */
    double *before; /* 3 per contact: gap, rate, stored energy at the step's start */
    int failed;
    double failed_at, failed_step, created, failed_scale;
    double entry_low, entry_scale, entry_magnitude, *entry_before; /* where the units entered a contact */
} EnergyGuard;

static void guard_remember(EnergyGuard *g, const CoreUnit *units)
{
    int w;
    for (w = 0; w < g->n_watches; w++) {
        const CoreUnit *unit = &units[g->watch_unit[w]];
        g->before[3 * w] = unit->y_now[g->watch_gap[w]];
        g->before[3 * w + 1] = unit->y_now[g->watch_rate[w]];
        g->before[3 * w + 2] = g->watch_stored[w] >= 0 ? unit->y_now[g->watch_stored[w]] : 0.0;
    }
}

/* After an accepted macro step [t, t + H]: 0 where it created too much energy (g->failed set) */
static int guard_check(EnergyGuard *g, const CoreUnit *units, int n_units, double t, double H)
{
    double energy = 0.0, magnitude = 0.0, kinetic = 0.0, created;
    int k, w;
    if (!g) return 1;
    for (k = 0; k < n_units; k++)
        if (units[k].energy_index >= 0) {
            energy += units[k].y_now[units[k].energy_index];
            magnitude += fabs(units[k].y_now[units[k].energy_index]);
        }
    for (k = 0; k < g->n_kinetic; k++) kinetic += units[g->kinetic_unit[k]].y_now[g->kinetic_index[k]];
    for (w = 0; w < g->n_watches; w++)
        if (g->watch_stored[w] >= 0) kinetic += units[g->watch_unit[w]].y_now[g->watch_stored[w]];
    g->magnitude = fmax(g->magnitude, magnitude);
    created = energy - g->low;
    if (created > g->share * g->scale + g->floor_share * g->magnitude) {
        g->failed = 1;
        g->failed_at = t;
        g->failed_step = H;
        g->created = created;
        g->failed_scale = g->scale;
        return 0;
    }
    g->low = fmin(g->low, energy);
    g->scale = fmax(g->scale, kinetic);
    guard_remember(g, units);
    return 1;
}

/* One macro step [t, t + H] of every unit (by `algorithm`: Jacobi or Gauss-Seidel); the outputs read become those
 * at the start of the next step. */
static int macro_step(CoreUnit *units, int n_units, double t, double H, int algorithm, int linear, int *stepped,
                      int *culprit)
{
    const int gauss_seidel = algorithm == ALGORITHM_GAUSS_SEIDEL;
    int k, i, status;
    for (k = 0; k < n_units; k++) stepped[k] = 0;
    if (!gauss_seidel) {
        for (k = 0; k < n_units; k++)
            if ((status = feed(units, k, H, linear, stepped)) >= CORE_ERROR) {
                *culprit = k;
                return status;
            }
    }
    for (k = 0; k < n_units; k++) {
        if (gauss_seidel && (status = feed(units, k, H, linear, stepped)) >= CORE_ERROR) {
            *culprit = k;
            return status;
        }
        status = step_and_read(&units[k], t, H, linear);
        if (status == CORE_DISCARD || status >= CORE_ERROR) {
            *culprit = k;
            return status;
        }
        if (gauss_seidel) stepped[k] = 1;
    }
    for (k = 0; k < n_units; k++) {
        for (i = 0; i < units[k].n_out; i++) units[k].y_now[i] = units[k].y_next[i];
        if (linear)
            for (i = 0; i < units[k].n_out; i++) units[k].dy_now[i] = units[k].dy_next[i];
    }
    return CORE_OK;
}

/* The contact steps of harness/cosim/contacts.py (ContactSteps), the same arithmetic in the same order:
 * the tests hold both loops to the same numbers, bit for bit. Python fills the settings and reads back
 * the tallies and the state. */
typedef struct {
    int n_watches;
    const int *watch_unit, *watch_gap, *watch_rate; /* per watch: the unit and its outputs gap, gap_rate */
    int per_contact, max_landings;
    double largest, growth, landed_share, smallest_share;
    double contact_step, last_step, size; /* carried from one call to the next */
    double *last_rates; /* per watch; valid once have_rates */
    int have_rates;
    long macro_steps, retries, landings;
    double *landed; /* the ends of the steps planned onto an onset */
    long landed_capacity, n_landed;
    int failed; /* 1: the steps fell below the smallest at failed_at; 2: the contact entered
                                        at failed_at stayed shorter than its first steps (contacts.py's too_short) */
    double failed_at;
    double *scratch; /* 3 n_watches: gap, rate and its slope per watch */
    void **states; /* n_units */
    double *saved; /* 2 x every unit's n_out: y_now and dy_now at the saved state */
    /* where the units entered a contact, kept while its first steps are blind (contacts.py's Entry) */
    double swing, redo;
    int blind, have_entry, entry_redos, entry_have_rates;
    double entry_t, entry_contact_step, entry_size, entry_last_step;
    long entry_macro_steps, entry_n_landed;
    double *entry_rates; /* n_watches */
    void **entry_states; /* n_units */
    double *entry_saved; /* as saved */
    double rounding; /* a gap above minus this is no contact (contacts.py's ROUNDING) */
} ContactControl;

static void contact_values(const ContactControl *c, const CoreUnit *units, int linear)
{
    int w;
    for (w = 0; w < c->n_watches; w++) {
        const CoreUnit *unit = &units[c->watch_unit[w]];
        const double rate = unit->y_now[c->watch_rate[w]];
        double slope;
        if (linear)
            slope = unit->dy_now[c->watch_rate[w]];
        else
            slope = c->have_rates && c->last_step > 0 ? (rate - c->last_rates[w]) / c->last_step : 0.0;
        c->scratch[3 * w] = unit->y_now[c->watch_gap[w]] + c->rounding;
        c->scratch[3 * w + 1] = rate;
        c->scratch[3 * w + 2] = slope;
    }
}

/* The next step (at most room; *wanted: before the room cut it); *touching: a contact acts at its start;
 * *landing: it ends on an onset */
static double contact_plan(ContactControl *c, double room, int *touching, int *landing, double *wanted)
{
    int w, crossing = 0;
    double step, omega = 0.0, onset = INFINITY;
    *touching = 0;
    *landing = 0;
    for (w = 0; w < c->n_watches; w++) {
        const double g = c->scratch[3 * w], r = c->scratch[3 * w + 1], a = c->scratch[3 * w + 2];
        if (g < 0.0) {
            *touching = 1;
            if (-g > fabs(r) * c->size) omega = fmax(omega, sqrt(fabs(a) / -g));
        }
        if ((g >= 0.0 && r < 0.0) || (g < 0.0 && r > 0.0)) {
            const double estimate = g / -r;
            if (!crossing || estimate < onset) onset = estimate;
            crossing = 1;
        }
    }
    if (*touching) {
        const double sized = omega > 0 ? PI / omega / c->per_contact : INFINITY;
        step = fmin(sized, c->growth * c->size);
        c->contact_step = step;
        c->blind = !(sized <= c->growth * c->size); /* the step grows: the contact's frequency does not bound it */
    } else {
        step = fmin(c->largest, c->growth * c->size);
        c->blind = 0;
    }
    if (crossing) {
        if (onset <= c->contact_step * c->landed_share)
            step = fmin(step, c->contact_step);
        else if (onset <= fmin(step, c->contact_step)) {
            step = onset;
            *landing = 1;
        } else if (onset < 2 * step)
            step = onset / 2;
    }
    *wanted = step;
    return fmin(step, room);
}

/* After a step that began apart: 0 where no gap fell below the landing depth, else 1 and *shortest the
 * step to the earliest secant estimate of an onset */
static int contact_overshoot(const ContactControl *c, const CoreUnit *units, double step, double *shortest)
{
    int w, found = 0;
    for (w = 0; w < c->n_watches; w++) {
        const double g0 = c->scratch[3 * w], r0 = c->scratch[3 * w + 1];
        const double g1 = units[c->watch_unit[w]].y_now[c->watch_gap[w]] + c->rounding;
        const double depth = 0.5 * fabs(r0) * c->contact_step;
        if (g1 < -depth && g0 > 0.0) {
            const double guess = step * g0 / (g0 - g1);
            if (!found || guess < *shortest) *shortest = guess;
            found = 1;
        }
    }
    return found;
}

static void release_states(ContactControl *c, CoreUnit *units, int n_saved)
{
    int k;
    for (k = 0; k < n_saved; k++)
        if (c->states[k]) fmi_free_state(&units[k].calls, &c->states[k]);
}

/* Saves every unit's FMU state and outputs; on failure releases what it saved */
static int save_all(ContactControl *c, CoreUnit *units, int n_units, int *culprit)
{
    int k, i, offset = 0;
    for (k = 0; k < n_units; k++) {
        c->states[k] = NULL;
        if (fmi_get_state(&units[k].calls, &c->states[k]) >= CORE_ERROR) {
            release_states(c, units, k);
            *culprit = k;
            return CORE_ERROR;
        }
        for (i = 0; i < units[k].n_out; i++, offset += 2) {
            c->saved[offset] = units[k].y_now[i];
            c->saved[offset + 1] = units[k].dy_now[i];
        }
    }
    return CORE_OK;
}

static int restore_all(ContactControl *c, CoreUnit *units, int n_units, int *culprit)
{
    int k, i, offset = 0;
    for (k = 0; k < n_units; k++) {
        if (fmi_set_state(&units[k].calls, c->states[k]) >= CORE_ERROR) {
            *culprit = k;
            return CORE_ERROR;
        }
        for (i = 0; i < units[k].n_out; i++, offset += 2) {
            units[k].y_now[i] = c->saved[offset];
            units[k].dy_now[i] = c->saved[offset + 1];
        }
    }
    return CORE_OK;
}

/* The entry's FMU states released */
static void leave_entry(ContactControl *c, CoreUnit *units, int n_units)
{
    int k;
    if (!c->have_entry) return;
    for (k = 0; k < n_units; k++)
        if (c->entry_states[k]) fmi_free_state(&units[k].calls, &c->entry_states[k]);
    c->have_entry = 0;
}

/* The states just saved (save_all) become the entry of a contact, with the control's numbers before the step and the
 * energy check's (which has not seen the step yet) */
static void keep_entry(ContactControl *c, EnergyGuard *guard, int n_units, int n_saved_values, double t,
                       double contact_step, double size, double last_step, int have_rates, long macro_steps,
                       long n_landed)
{
    int k, w;
    if (guard) {
        guard->entry_low = guard->low;
        guard->entry_scale = guard->scale;
        guard->entry_magnitude = guard->magnitude;
        for (w = 0; w < 3 * guard->n_watches; w++) guard->entry_before[w] = guard->before[w];
    }
    for (k = 0; k < n_units; k++) {
        c->entry_states[k] = c->states[k];
        c->states[k] = NULL;
    }
    for (k = 0; k < n_saved_values; k++) c->entry_saved[k] = c->saved[k];
    for (w = 0; w < c->n_watches; w++) c->entry_rates[w] = c->last_rates[w];
    c->have_entry = 1;
    c->entry_redos = 0;
    c->entry_t = t;
    c->entry_contact_step = contact_step;
    c->entry_size = size;
    c->entry_last_step = last_step;
    c->entry_have_rates = have_rates;
    c->entry_macro_steps = macro_steps;
    c->entry_n_landed = n_landed;
}

/* After a blind step in a contact: whether a gap's rate changed by more than one contact step can change it, swing
 * times pi / per_contact of the fastest approach at the step's start, beside what the rates' slopes account for */
static int swung(const ContactControl *c, const CoreUnit *units, double step)
{
    const double share = c->per_contact ? PI / c->per_contact : 1.0;
    double fastest = 0.0, steepest = 0.0, bound;
    int w;
    for (w = 0; w < c->n_watches; w++) {
        fastest = fmax(fastest, fabs(c->scratch[3 * w + 1]));
        steepest = fmax(steepest, fabs(c->scratch[3 * w + 2]));
    }
    bound = c->swing * (share * fastest + steepest * step);
    for (w = 0; w < c->n_watches; w++)
        if (fabs(units[c->watch_unit[w]].y_now[c->watch_rate[w]] - c->scratch[3 * w + 1]) > bound) return 1;
    return 0;
}

/* The units back where they entered the contact, the control's numbers too, and the contact step redo times
 * shorter than at the last entry */
static int enter_again(ContactControl *c, EnergyGuard *guard, CoreUnit *units, int n_units, int *culprit)
{
    int k, i, w, offset = 0;
    if (guard) {
        guard->low = guard->entry_low;
        guard->scale = guard->entry_scale;
        guard->magnitude = guard->entry_magnitude;
        for (w = 0; w < 3 * guard->n_watches; w++) guard->before[w] = guard->entry_before[w];
    }
    for (k = 0; k < n_units; k++) {
        if (fmi_set_state(&units[k].calls, c->entry_states[k]) >= CORE_ERROR) {
            *culprit = k;
            return CORE_ERROR;
        }
        for (i = 0; i < units[k].n_out; i++, offset += 2) {
            units[k].y_now[i] = c->entry_saved[offset];
            units[k].dy_now[i] = c->entry_saved[offset + 1];
        }
    }
    c->entry_redos++;
    c->contact_step = c->entry_contact_step / pow(c->redo, c->entry_redos);
    c->size = c->entry_size;
    c->last_step = c->entry_last_step;
    c->have_rates = c->entry_have_rates;
    for (w = 0; w < c->n_watches; w++) c->last_rates[w] = c->entry_rates[w];
    c->macro_steps = c->entry_macro_steps;
    c->n_landed = c->entry_n_landed;
    c->retries++;
    return CORE_OK;
}

/* A step that began apart, rolled back and redone half way to the onset where it overshot one; where it enters a
 * contact, its start is kept as the contact's entry */
static int landed_step(ContactControl *c, EnergyGuard *guard, CoreUnit *units, int n_units, double t, double *step,
                       int *last, int *landing, int algorithm, int linear, int *stepped, int *culprit)
{
    const double contact_step = c->contact_step, size = c->size, last_step = c->last_step;
    const int have_rates = c->have_rates;
    const long macro_steps = c->macro_steps, n_landed = c->n_landed;
    int attempt, w, k, values = 0, status = save_all(c, units, n_units, culprit);
    if (status != CORE_OK) return status;
    for (attempt = 0; attempt <= c->max_landings; attempt++) {
        double missed = 0.0;
        const double shortest = c->contact_step * c->landed_share;
        status = macro_step(units, n_units, t, *step, algorithm, linear, stepped, culprit);
        if (status != CORE_OK) break;
        if (!contact_overshoot(c, units, *step, &missed) || attempt == c->max_landings || *step <= shortest) break;
        if ((status = restore_all(c, units, n_units, culprit)) != CORE_OK) break;
        c->retries++;
        c->landings++;
        *step = fmax(missed / 2, shortest);
        *last = 0;
        *landing = 0;
    }
    if (status == CORE_OK && !c->have_entry)
        for (w = 0; w < c->n_watches; w++)
            if (units[c->watch_unit[w]].y_now[c->watch_gap[w]] + c->rounding < 0.0) {
                for (k = 0; k < n_units; k++) values += 2 * units[k].n_out;
                keep_entry(c, guard, n_units, values, t, contact_step, size, last_step, have_rates, macro_steps,
                           n_landed);
                return status;
            }
    release_states(c, units, n_units);
    return status;
}

/* Covers [t, t_end] with contact steps */
static int contact_steps(ContactControl *c, EnergyGuard *guard, CoreUnit *units, int n_units, double t, double t_end,
                         int algorithm, int linear, int *stepped, int *culprit)
{
    int w, status;
    while (t < t_end) {
        int touching, landing, last;
        double step, wanted;
        contact_values(c, units, linear);
        step = contact_plan(c, t_end - t, &touching, &landing, &wanted);
        if (!(touching && c->blind)) leave_entry(c, units, n_units); /* the contact's frequency known, or none acts */
        /* harness.cosim.controls.ends_interval */
        last = (t_end - t) - step <= fmax(1e-12 * (t_end - t), 8 * (nextafter(fabs(t_end), INFINITY) - fabs(t_end)));
        if (!last && step < c->largest * c->smallest_share) {
            c->failed = 1;
            c->failed_at = t;
            return CORE_ERROR;
        }
        if (last) step = t_end - t;
        if (touching) {
            status = macro_step(units, n_units, t, step, algorithm, linear, stepped, culprit);
            if (status != CORE_OK) return status;
            if (c->have_entry && swung(c, units, step)) {
                if (c->entry_redos == c->max_landings) {
                    c->failed = 2;
                    c->failed_at = c->entry_t;
                    return CORE_ERROR;
                }
                if ((status = enter_again(c, guard, units, n_units, culprit)) != CORE_OK) return status;
                t = c->entry_t;
                continue;
            }
        } else {
            status =
                landed_step(c, guard, units, n_units, t, &step, &last, &landing, algorithm, linear, stepped, culprit);
        }
        if (status != CORE_OK) return status;
        if (!guard_check(guard, units, n_units, t, step)) {
            if (!c->have_entry || c->entry_redos == c->max_landings) return CORE_ERROR;
            guard->failed = 0; /* a blind step into a contact: enter it again, as where it swung */
            if ((status = enter_again(c, guard, units, n_units, culprit)) != CORE_OK) return status;
            t = c->entry_t;
            continue;
        }
        c->macro_steps++;
        for (w = 0; w < c->n_watches; w++) c->last_rates[w] = c->scratch[3 * w + 1];
        c->have_rates = 1;
        c->last_step = step;
        c->size = last ? fmax(step, wanted) : step;
        t = last ? t_end : t + step;
        if (landing && c->n_landed < c->landed_capacity) c->landed[c->n_landed++] = t;
    }
    return CORE_OK;
}

/* contact_steps, and no FMU state kept beyond the interval (its rows are recorded) */
static int contact_advance(ContactControl *c, EnergyGuard *guard, CoreUnit *units, int n_units, double t, double t_end,
                           int algorithm, int linear, int *stepped, int *culprit)
{
    const int status = contact_steps(c, guard, units, n_units, t, t_end, algorithm, linear, stepped, culprit);
    leave_entry(c, units, n_units);
    return status;
}

/* Records grid[0], then steps to grid[1] (one macro step, or contact steps where `contacts` is given),
 * records, ... up to grid[n_points - 1]. Returns the status; *rows is the number of rows written,
 * *culprit the unit that failed (or -1). `stepped` is scratch space of n_units ints. With contacts, a
 * run also returns early (OK, fewer rows) once half the landed buffer is used, for the caller to read it. With a
 * guard, a macro step that creates too much energy stops the run (CORE_ERROR, *culprit -1, guard->failed). An
 * algorithm id the loop does not know is refused before anything is done (CORE_REFUSED). */
int cosim_run(CoreUnit *units, int n_units, const double *grid, long n_points, int algorithm, int linear, double *table,
              long row_length, double *energy, int *stepped, ContactControl *contacts, EnergyGuard *guard, long *rows,
              int *culprit)
{
    long p;
    int status;
    *rows = 0;
    *culprit = -1;
    if (algorithm != ALGORITHM_JACOBI && algorithm != ALGORITHM_GAUSS_SEIDEL) return CORE_REFUSED;
    for (p = 0; p < n_points; p++) {
        const double t = grid[p];
        if (record(units, n_units, t, table + p * row_length, energy + p, culprit) != CORE_OK) return CORE_ERROR;
        *rows = p + 1;
        if (p + 1 == n_points) break;
        if (contacts) {
            if (2 * contacts->n_landed >= contacts->landed_capacity) break;
            status =
                contact_advance(contacts, guard, units, n_units, t, grid[p + 1], algorithm, linear, stepped, culprit);
        } else {
            status = macro_step(units, n_units, t, grid[p + 1] - t, algorithm, linear, stepped, culprit);
            if (status == CORE_OK && !guard_check(guard, units, n_units, t, grid[p + 1] - t)) status = CORE_ERROR;
        }
        if (status != CORE_OK) return status;
    }
    return CORE_OK;
}
