/* The integration of a communication step: from the FMU's state at t to t + H, with the solver the
 * user chose.
 * Finiteness is checked once per communication step; only when that check fails is the step
 * redone with a check after every substep, to stop at the last good one. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "integrators.h"

/* Forgets the Adams-Bashforth history and the adaptive methods' step and column proposals: after a reset, or when solver,
 * h or tol change. */
void restart_integrator(Instance *inst)
{
    inst->s.integrator.ab_count = 0;
    inst->s.integrator.ab_head = 0;
    inst->s.integrator.ab_step = 0.0;
    inst->s.integrator.step_proposal = 0.0;
    inst->s.integrator.gbs_columns = 0;
    inst->s.integrator.gbs_rejected = 0;
    inst->s.integrator.ab_restarted = 0;
}

/* Input slopes drive a step only when set for it: those left from the last step (kept so that the
 * output derivatives at its end follow them) give way to held inputs. */
static void take_slopes(SimState *s)
{
    if (!s->slopes_set) memset(s->input_derivative, 0, sizeof s->input_derivative);
}

#if N_STATES == 0

Status step_to(Instance *inst, const char *function, double t, double H)
{
    double before[N_REAL];
    take_slopes(&inst->s);
    memcpy(before, inst->s.real, sizeof before);
    model_advance_inputs(inst->s.real, inst->s.input_derivative, H);
    /* The outputs belong to the end of the step; a singular or overflowing end keeps the step from
     * happening. */
    if (!model_outputs(&inst->constants, t + H, NULL, inst->s.real) || first_non_finite(inst->s.real, N_REAL) >= 0) {
        memcpy(inst->s.real, before, sizeof before);
        inst->outputs_valid = 0;
        log_discard(inst,
                    "%s: singular configuration or non-finite outputs at t = %.17g; "
                    "last successful time %.17g",
                    function, t + H, t);
        inst->s.last_successful_time = t;
        return STATUS_DISCARD;
    }
    inst->s.slopes_set = 0;
    inst->s.time = t + H;
    inst->s.last_successful_time = t + H;
    inst->outputs_valid = 1;
    return STATUS_OK;
}

#else

/* ceil(q), without a library call where q fits an integer (most calls take one or a few substeps). */
static double round_up(double q)
{
    if (q > -1e15 && q < 1e15) {
        const double whole = (double)(int64_t)q; /* q rounded toward zero */
        return whole < q ? whole + 1.0 : whole;
    }
    return ceil(q);
}

/* ---- The call: what every phase is given, and the exits ----
 * step_to's phases, in their order: check the method's settings, take a closed form where the model has one, plan
 * the substeps, check the work bound, run the substeps (in blocks, or one at a time with events: take a substep,
 * find a crossing, locate the event, resolve it, the rest of the substep), and end by one of the exits below, each
 * named after the status it gives: ok_*, discard_*, error_*. */
typedef struct {
    Instance *inst;
    const char *function; /* the FMI function that called, for messages */
    RightHandSide *f;
    int solver;
    double t, H; /* the communication step [t, t + H] */
    double h, tol; /* the method's settings */
} Call;

/* What a phase returns where the call goes on (else the status the call ends with). */
#define GO_ON (-1)

/* The instance moved on by H_done to t_reached: its inputs along their slopes, its time. */
static void advance(Instance *inst, double H_done, double t_reached)
{
    model_advance_inputs(inst->s.real, inst->s.input_derivative, H_done);
    inst->s.slopes_set = 0; /* slopes hold for one step; kept for the output rates at its end */
    inst->s.time = t_reached;
    inst->s.last_successful_time = t_reached;
    inst->outputs_valid = 0;
    inst->derivatives_current = 0;
}

/* OK at the step's end; the outputs are computed when read. */
static Status ok_unchecked(const Call *call)
{
    advance(call->inst, call->H, call->t + call->H);
    return STATUS_OK;
}

/* OK at t + H_done (the step's end, or an event where the importer lets a step end early). Where the inputs held,
 * the outputs the check there computed (`checked`) are those of the new state and inputs: they become the cached
 * outputs instead of being computed again when the importer reads them. */
static Status ok_checked(const Call *call, double H_done, const double *checked)
{
    advance(call->inst, H_done, call->t + H_done);
    if (!call->f->inputs_vary) {
        memcpy(call->inst->s.real, checked, N_REAL * sizeof(double));
        call->inst->outputs_valid = 1;
    }
    return STATUS_OK;
}

/* OK at the step's end, whose check evaluated into the instance itself: the outputs and derivatives are in place. */
static Status ok_in_place(const Call *call)
{
    advance(call->inst, call->H, call->t + call->H);
    call->inst->outputs_valid = 1;
    call->inst->derivatives_current = rounding_to_nearest(call->inst);
    return STATUS_OK;
}

/* Fills real (a copy of the variables with the states x) with the inputs at t (moved along their
 * slopes from the step's start), the derivatives and the outputs; returns whether x is a state to
 * continue from: finite and regular, with finite inputs, derivatives and outputs (an input whose slope
 * overflows it within the step fails the step, also for methods that never evaluate at its end). Costs
 * a right-hand side and the outputs, so it runs once per communication step, or per substep only when
 * redoing a failed step. */
static int evaluate_at(const Instance *inst, double t, const double *x, double *real)
{
    double u[INPUT_SLOTS];
    int i;
    if (!model_state_ok(&inst->constants, x)) return 0;
    memcpy(real, inst->s.real, N_REAL * sizeof(double));
    memcpy(real, x, N_STATES * sizeof(double));
    gather_inputs(inst, u);
    for (i = 0; i < N_INPUTS; i++) u[i] += (t - inst->s.time) * inst->s.input_derivative[i];
    scatter_inputs(real, u);
    return model_evaluate(&inst->constants, t, u, real) && all_finite(real, N_REAL);
}

/* The importer's look at an accepted internal step whose time, states and outputs s.real holds: the instance
 * shows the step's time while report_step runs, and its own time and machine state afterwards. */
static void report_in_place(Instance *inst, double t)
{
    const double time = inst->s.time;
    const int32_t machine_state = inst->s.machine_state;
    const int outputs_valid = inst->outputs_valid;
    inst->s.time = t;
    inst->outputs_valid = 1;
    inst->s.machine_state = MS_INTERMEDIATE;
    caller_float_control_begin(inst);
    inst->report_step(inst, t);
    caller_float_control_end(inst);
    inst->s.time = time;
    inst->s.machine_state = machine_state;
    inst->outputs_valid = outputs_valid;
}

/* The same for a step evaluated into real: shown in s.real while report_step runs, the instance's own values
 * afterwards. */
static void report_internal_step(Instance *inst, double t, const double *real)
{
    double before[N_REAL];
    memcpy(before, inst->s.real, sizeof before);
    memcpy(inst->s.real, real, sizeof before);
    report_in_place(inst, t);
    memcpy(inst->s.real, before, sizeof before);
}

int first_non_finite_at(const Instance *inst, double t, const double *x)
{
    double real[N_REAL];
    if (!model_state_ok(&inst->constants, x) || evaluate_at(inst, t, x, real)) return -1;
    return first_non_finite(real, N_REAL);
}

int state_acceptable(void *context, double t, const double *x)
{
    Instance *inst = (Instance *)context;
    double real[N_REAL];
    if (!evaluate_at(inst, t, x, real)) return 0;
    if (inst->report_step && inst->s.machine_state == MS_STEP_COMPLETE) report_internal_step(inst, t, real);
    return 1;
}

/* The check of a fixed-step call's end state x = s.real at t. Where the inputs held it evaluates into the
 * instance itself, as the method evaluates f (the inputs it held, none where all are zero): the outputs need no
 * copy, and the derivatives serve as the next call's first evaluation. A failure leaves garbage there, which the
 * failure's finish forgets. */
#if defined(__GNUC__)
__attribute__((always_inline)) /* in step_to's every call: a call of its own costs it more than the check's set-up */
#endif
static inline int end_state_good(Instance *inst, const RightHandSide *f, double t, double *checked)
{
    double *real = inst->s.real;
    if (f->inputs_vary) return evaluate_at(inst, t, real, checked);
    return model_state_ok(&inst->constants, real) &&
           model_evaluate(&inst->constants, t, f->forces ? f->u0 : NULL, real) && computed_finite(real);
}

/* Whether a reporting pass takes its substeps one at a time (report_substeps): the methods whose substep starts from
 * its slope and depends on nothing else of the substeps before it in the call (the Adams methods' history lives in
 * the integrator memory), so that one at a time they give what the pass in one loop gives. */
static int reports_one_at_a_time(int solver)
{
    return (steps_from_slope(solver) && solver != SOLVER_STORMER_VERLET) || adams_bashforth_of(solver) != NULL;
}

/* Substeps first ... first + count - 1 of hs from t, reported with the inputs held: each a pass of its own,
 * checked as a call's end is (end_state_good: into the instance, as the method evaluates f) at the time the next
 * one starts (t_end for the last), reported from there without a copy, the next starting from that check's
 * derivatives as a call starts from its predecessor's. The substeps done; a refused one leaves x and the memory as
 * they were before it, the refused state in f. */
#if defined(__GNUC__)
__attribute__((noinline)) /* kept out of step_to, whose calls without reports it would slow */
#endif
static int64_t report_substeps(Instance *inst, RightHandSide *f, int solver, IntegratorMemory *memory, double *x,
                               double t, double hs, int64_t first, int64_t count, double t_end)
{
    const int reuse = rounding_to_nearest(inst);
    int64_t k;
    for (k = first; k < first + count; k++) {
        const double t_k = t + (double)k * hs, t_next = k + 1 == first + count ? t_end : t + (double)(k + 1) * hs;
        double saved[STATE_SLOTS];
        IntegratorMemory saved_memory = *memory;
        memcpy(saved, x, sizeof saved);
        if (k > first)
            f->start_slope = reuse ? inst->s.real + N_STATES : NULL; /* checked at t_k */
        else if (first > 0)
            f->start_slope = NULL;
        f->checks++;
        if (integrate_fixed(f, solver, memory, x, t_k, hs, 0, 1, 0) != 1 || !end_state_good(inst, f, t_next, NULL)) {
            memcpy(f->refused, x, sizeof f->refused);
            f->refused_known = 1;
            memcpy(x, saved, sizeof saved);
            *memory = saved_memory;
            return k - first;
        }
        if (inst->s.machine_state == MS_STEP_COMPLETE) report_in_place(inst, t_next);
    }
    return count;
}

/* Why a state was refused, for a message: the requirement it breaks or the variable it makes non-finite
 * ("" when neither is found). */
static void refusal_reason(const Instance *inst, double t, const double *refused, char *text, size_t size)
{
    char reason[1024];
    int k;
    text[0] = '\0';
    if (!refused) return;
    k = first_non_finite(refused, N_STATES);
    if (k >= 0)
        snprintf(text, size, " (%s would not be finite)", real_variable_name(k));
    else if (model_explain_singularity(&inst->constants, t, refused, reason, sizeof reason))
        snprintf(text, size, " (%s)", reason);
    else if ((k = first_non_finite_at(inst, t, refused)) >= 0)
        snprintf(text, size, " (%s would not be finite)", real_variable_name(k));
}

/* Discard or error: the message after "function: ", and where the call ends (moved: at t_good; else the instance is
 * left as the call found it). */
static Status end_with(const Call *call, Status status, int moved, double t_good, const char *fmt, va_list args)
{
    char message[1024];
    vsnprintf(message, sizeof message, fmt, args);
    if (moved) advance(call->inst, t_good - call->t, t_good);
    if (status == STATUS_ERROR)
        log_error(call->inst, "%s: %s", call->function, message);
    else
        log_discard(call->inst, "%s: %s", call->function, message);
    return status;
}

/* Discard: the call ends at t_good, the last state it stands by. The variadic exits take the call by value: were its
 * address passed to them (they are never inlined), its fields would live in memory on every call's way. */
static Status discard_at(Call call, double t_good, const char *fmt, ...)
{
    va_list args;
    Status status;
    va_start(args, fmt);
    status = end_with(&call, STATUS_DISCARD, 1, t_good, fmt, args);
    va_end(args);
    return status;
}

#if N_CONSTRAINTS > 0
/* Discard before the first substep: the instance as it was. */
static Status discard_untouched(Call call, const char *fmt, ...)
{
    va_list args;
    Status status;
    va_start(args, fmt);
    status = end_with(&call, STATUS_DISCARD, 0, call.t, fmt, args);
    va_end(args);
    return status;
}
#endif

/* Error: the call is refused as it stands (its settings, its work), the instance as it was. */
static Status error_refused(Call call, const char *fmt, ...)
{
    va_list args;
    Status status;
    va_start(args, fmt);
    status = end_with(&call, STATUS_ERROR, 0, call.t, fmt, args);
    va_end(args);
    return status;
}

/* Discard: a substep after t_good failed (Newton's iteration did not converge, or the state it reached is refused:
 * `refused`, NULL where unknown); the call ends at t_good. */
static Status discard_failed(const Call *call, double t_good, const char *method, double h, int unconverged,
                             const double *refused)
{
    char reason[1100];
    refusal_reason(call->inst, t_good, refused, reason, sizeof reason);
    if (unconverged)
        return discard_at(*call, t_good,
                          "%s with h = %g: Newton's iteration did not converge (%d iterations at most, "
                          "scaled correction below %g) in the substep after t = %.17g; stopped there (last successful "
                          "time %.17g): take a smaller h",
                          method, h, NEWTON_MAX_ITERATIONS, NEWTON_TOLERANCE, t_good, t_good);
    return discard_at(*call, t_good,
                      "%s with h = %g: the state would become non-finite or singular in the substep "
                      "after t = %.17g%s; stopped there (last successful time %.17g)",
                      method, h, t_good, reason, t_good);
}

/* ---- The rules, each written once ---- */

/* Whether the method picks its own steps (at most h long) to meet tol. */
static int adaptive_method(int solver, double tol) { return ADAPTIVE_METHOD(solver, tol); }

/* Whether the Adams-Bashforth history in memory serves substeps of hs: only if it was taken with them. */
static int history_serves(const IntegratorMemory *memory, double hs)
{
    return memory->ab_count > 0 && fabs(hs - memory->ab_step) <= 1e-10 * hs;
}

/* Substeps of hs from here: the history goes unless it serves them. */
static void keep_history_for(IntegratorMemory *memory, double hs)
{
    if (memory->ab_count > 0 && !history_serves(memory, hs)) memory->ab_count = memory->ab_restarted = 0;
    memory->ab_step = hs;
}

/* The substeps a fixed step of h plans over H: at least one, and none shorter than h but for rounding. */
static double planned_substeps(double H, double h)
{
    const double substeps = round_up(H / h - 1e-9);
    return substeps < 1.0 ? 1.0 : substeps;
}

/* Error: the call would need `work` right-hand-side evaluations, more than a call may take (`checks`: what the count
 * includes besides the method's). */
static Status error_too_much_work(const Call *call, double work, const char *checks)
{
    return error_refused(*call,
                         "communicationStepSize = %g with %s at h = %g needs %.0f right-hand-side evaluations%s "
                         "(allowed at most %.0f per call): raise h or shorten the step",
                         call->H, solver_name(call->solver), call->h, work, checks, MAX_EVALUATIONS_PER_CALL);
}

/* Discard: the method stopped short of its step (out of budget, or an adaptive step underflowed) at `reached`, where
 * the call ends, with the reason. */
static Status discard_stopped_short(const Call *call, double reached)
{
    const RightHandSide *f = call->f;
    const char *method = solver_name(call->solver);
    char reason[1100];
    refusal_reason(call->inst, reached, f->refused_known ? f->refused : NULL, reason, sizeof reason);
    if (f->out_of_budget && !adaptive_method(call->solver, call->tol)) /* a fixed-step method's checks for contacts */
        return discard_at(*call, reached,
                          "%s at h = %g used its %.0f right-hand-side evaluations allowed per call, with "
                          "the checks for contacts inside its steps, at t = %.17g; stopped at the last successful time "
                          "%.17g (take shorter communication steps)",
                          method, call->h, MAX_EVALUATIONS_PER_CALL, reached, reached);
    if (f->out_of_budget)
        return discard_at(*call, reached,
                          "%s with tol = %g used its %.0f right-hand-side evaluations allowed per call at "
                          "t = %.17g; stopped at the last successful time %.17g (take shorter communication steps or a "
                          "larger tol)",
                          method, call->tol, MAX_EVALUATIONS_PER_CALL, reached, reached);
    if (f->unconverged)
        return discard_at(*call, reached,
                          "%s with h = %g: Newton's iteration did not converge (%d iterations at most, "
                          "scaled correction below %g) in a trial step locating an event after t = %.17g; stopped at "
                          "the last successful time %.17g: take a smaller h",
                          method, call->h, NEWTON_MAX_ITERATIONS, NEWTON_TOLERANCE, reached, reached);
    if (call->solver == SOLVER_TAYLOR)
        return discard_at(*call, reached,
                          "taylor of order %d with tol = %g: the step its coefficients allow underflowed "
                          "at t = %.17g%s (tol is out of reach at this order in double precision, or the state is "
                          "non-finite or singular there: take a larger tol or a higher taylor_order); stopped at the "
                          "last successful time %.17g",
                          call->inst->s.integer[INT_taylor_order], call->tol, reached, reason, reached);
    return discard_at(*call, reached,
                      "%s with tol = %g: the step size underflowed at t = %.17g%s (the state is "
                      "non-finite, singular or too stiff there); stopped at the last successful time %.17g",
                      method, call->tol, reached, reason, reached);
}
/* The work of a call, into the counters. */
static void count_work(IntegratorMemory *memory, const RightHandSide *f)
{
    memory->n_rhs += f->evaluations;
    memory->n_jacobians += f->jacobians;
    memory->n_iterations += f->iterations;
}

/* J = df/dx and dx = f at (t, x) with inputs u (NULL: zero), a column of J per state from the model's exact
 * directional derivative. */
static void jacobian_at(void *context, double t, const double *x, const double *u, double *J, double *dx)
{
    const Instance *inst = (const Instance *)context;
    double real[N_REAL], change[N_REAL], ddx[STATE_SLOTS];
    double seed[STATE_SLOTS] = {0}, seed_u[INPUT_SLOTS] = {0}, zero[INPUT_SLOTS] = {0};
    int i, j;
    memcpy(real, inst->s.real, sizeof real);
    memcpy(real, x, N_STATES * sizeof(double));
    scatter_inputs(real, u ? u : zero);
    model_equations(&inst->constants, t, x, u, dx);
    for (j = 0; j < N_STATES; j++) {
        seed[j] = 1.0;
        model_directional(&inst->constants, t, real, dx, seed, seed_u, ddx, change);
        seed[j] = 0.0;
        for (i = 0; i < N_STATES; i++) J[i * N_STATES + j] = ddx[i];
    }
#if N_CONSTRAINTS > 0 && N_COMPLIANT > 0
    compliant_jacobian(&inst->constants, t, x, J); /* the free equations' J lacks the contacts' stiffness */
#endif
}

/* The adaptive methods: rkf45, gbs, and taylor with tol > 0. */
static double adaptive_pass(RightHandSide *f, int solver, IntegratorMemory *memory, double *x, double t, double t_end,
                            double h, double tol, int check_each)
{
    if (solver == SOLVER_TAYLOR) return integrate_taylor(f, memory, x, t, t_end, tol, check_each);
    if (solver == SOLVER_GBS) return integrate_extrapolation(f, memory, x, t, t_end, h, tol, check_each);
    return integrate_adaptive(f, solver, memory, x, t, t_end, h, tol, check_each);
}
#if N_CONSTRAINTS > 0
#include <float.h>

/* Steps with events: each substep is taken, then the event indicators are compared at its ends. Where
 * one crossed, the event time is found on the method's own step map (one step from the substep's start
 * over theta, solved for the indicator's zero by the Illinois variant of regula falsi), so that the
 * state at the event has the method's order; the event is resolved there (impacts, activations,
 * releases), and the rest of the substep is taken from it. Adams-Bashforth methods take their
 * Runge-Kutta starter for these partial steps and restart their history after an event. */
typedef struct {
    Instance *inst;
    RightHandSide *f;
    int solver, adaptive;
    double h, tol;
    /* the step's start, and the constraints it departs from (constraint_departs), decided where they cross */
    const double *x_start;
    double t_start;
    int32_t departing, decided;
    int short_of; /* a trial step of an adaptive method stopped short: the call stops */
    /* An Adams method's history after the step that crossed (its newest entry f at the step's start), while
     * its event is located; NULL otherwise */
    const IntegratorMemory *history;
    double hs;
    /* f at the step's start (t_start, x_start) where known: a method of steps_from_slope takes its trial steps from
     * it, and the step's interpolant its accelerations there */
    int slope_known;
    double slope[STATE_SLOTS];
} EventStepper;

static const double *inputs_at(const RightHandSide *f, double t, double *u)
{
    int i;
    for (i = 0; i < N_INPUTS; i++) u[i] = f->u0[i] + (t - f->t0) * f->du[i];
    return f->forces ? u : NULL;
}

static void indicators_at(const EventStepper *e, double t, const double *x, double *z)
{
    double u[INPUT_SLOTS];
    /* a resting or taut constraint's indicator is its force: an evaluation */
    e->f->evaluations += (uint64_t)constraint_indicators(&e->inst->constants, e->inst->s.active_constraints, t, x,
                                                         inputs_at(e->f, t, u), z);
}

/* f at the step's start, evaluated at the first need only. */
static const double *start_slope(EventStepper *e)
{
    if (!e->slope_known) {
        slope_at(e->f, e->solver, e->t_start, e->x_start, e->slope);
        e->slope_known = 1;
    }
    return e->slope;
}

/* w_j = the integral from 0 to sigma of the polynomial that is 1 at nodes[j] and 0 at the other nodes (in units of
 * the step): an Adams method's weights over a fraction sigma of its step. */
static void adams_fraction(const double *nodes, int n, double sigma, double *w)
{
    int j, i, m;
    for (j = 0; j < n; j++) {
        double poly[AB_MAX_STEPS + 1] = {1.0}, scale = 1.0, power = sigma, integral = 0.0;
        int degree = 0;
        for (i = 0; i < n; i++) {
            if (i == j) continue;
            for (m = degree + 1; m >= 1; m--) poly[m] = poly[m - 1] - nodes[i] * poly[m]; /* times (u - node i) */
            poly[0] *= -nodes[i];
            degree++;
            scale *= nodes[j] - nodes[i];
        }
        for (m = 0; m <= degree; m++, power *= sigma) integral += poly[m] * power / (m + 1);
        w[j] = integral / scale;
    }
}

/* An Adams method's step over theta (at most its step hs) from (t, x0), on its own polynomials from the history e->history
 * (newest first: f at t, t - hs, ...): Adams-Bashforth's x0 + hs sum_j beta_j(sigma) f_j, sigma = theta / hs, then for
 * the predictor-corrector methods Adams-Moulton's on the predicted point's f (one evaluation). At theta = hs these
 * are the method's own steps; inside, their error is of the method's order. */
static void adams_trial_step(EventStepper *e, const double *x0, double t, double theta, double *x)
{
    const AdamsBashforth *ab = adams_bashforth_of(e->solver);
    const IntegratorMemory *m = e->history;
    const double sigma = theta / e->hs;
    /* nodes set to 0 first: gcc cannot see that the loops below fill what adams_fraction reads */
    double nodes[AB_MAX_STEPS] = {0}, w[AB_MAX_STEPS], slope[STATE_SLOTS], u[INPUT_SLOTS];
    int j, q;
    for (j = 0; j < ab->steps; j++) nodes[j] = -j;
    adams_fraction(nodes, ab->steps, sigma, w);
    for (q = 0; q < N_STATES; q++) {
        double sum = 0.0;
        for (j = 0; j < ab->steps; j++) sum += w[j] * m->ab_history[(m->ab_head - j + AB_MAX_STEPS) % AB_MAX_STEPS][q];
        x[q] = x0[q] + e->hs * sum;
    }
    if (!ab->corrected) return;
    model_equations(&e->inst->constants, t + theta, x, inputs_at(e->f, t + theta, u), slope);
    e->f->evaluations++;
    nodes[0] = sigma; /* the predicted point, then the history's newest ab->steps - 1 */
    for (j = 1; j < ab->steps; j++) nodes[j] = 1 - j;
    adams_fraction(nodes, ab->steps, sigma, w);
    for (q = 0; q < N_STATES; q++) {
        double sum = w[0] * slope[q];
        for (j = 1; j < ab->steps; j++)
            sum += w[j] * m->ab_history[(m->ab_head - (j - 1) + AB_MAX_STEPS) % AB_MAX_STEPS][q];
        x[q] = x0[q] + e->hs * sum;
    }
}

/* x = the method's step of theta from (t, x0), with the integrator memory `memory` left as it was. An adaptive
 * method that stops short (out of budget, its step underflowed) sets e->short_of. */
static void trial_step(EventStepper *e, const IntegratorMemory *memory, const double *x0, double t, double theta,
                       double *x)
{
    IntegratorMemory scratch = *memory;
    memcpy(x, x0, STATE_SLOTS * sizeof(double));
    if (e->history && theta <= e->hs) { /* inside an Adams step: on its own polynomials, from its history */
        adams_trial_step(e, x0, t, theta, x);
        return;
    }
    if (e->adaptive) {
        if (adaptive_pass(e->f, e->solver, &scratch, x, t, t + theta, e->h, e->tol, 0) < t + theta) e->short_of = 1;
    } else if (steps_from_slope(e->solver) && x0 == e->x_start && t == e->t_start) {
        step_from_slope(e->f, e->solver, &scratch, x, t, theta, start_slope(e));
    } else {
        scratch.ab_count = 0;
        if (integrate_fixed(e->f, e->solver, &scratch, x, t, theta, 0, 1, 0) < 1) e->short_of = 1; /* Newton failed */
    }
}

static int crossed(EventStepper *e, int k, double before, double after)
{
    const int32_t bit = (int32_t)1 << k;
    if (!indicator_crossed(&e->inst->constants, k, before, after)) return 0;
    if (!(e->decided & bit)) { /* a touching constraint the motion leaves: its crossing is the method's error */
        double u[INPUT_SLOTS];
        e->decided |= bit;
        if (before <= CONTACT_GAP && constraint_departs(&e->inst->constants, e->inst->s.active_constraints, k,
                                                        e->t_start, e->x_start, inputs_at(e->f, e->t_start, u)))
            e->departing |= bit;
    }
    return !(e->departing & bit);
}

/* Whether a rigid constraint acts (bilateral, or resting or taut): the steps' ends are projected onto it. */
static int rigid_acting(const ModelConst *c, int32_t active)
{
    int i;
    for (i = 0; i < N_CONSTRAINTS; i++)
        if (!c->law[i].compliant && (c->law[i].bilateral || (active >> i & 1))) return 1;
    return 0;
}

/* A step from (t, x0): its start for the departing constraints, and the indicators there (z, or those the last
 * step ended with where nothing moved the state since: `reuse`). */
static void start_of_step(EventStepper *e, double t, const double *x0, double *z, const double *reuse)
{
    e->x_start = x0;
    e->t_start = t;
    e->slope_known = 0;
    e->departing = e->decided = 0;
    if (reuse)
        memcpy(z, reuse, N_CONSTRAINTS * sizeof(double));
    else
        indicators_at(e, t, x0, z);
}

/* The state at offset theta in [0, span] on the quintic Hermite interpolant of a step from x0 to x1 whose
 * accelerations at its ends are a0 and a1: positions to O(span^6), velocities (the interpolant's derivative) to
 * O(span^5). Costs no evaluation of the equations, so events are found on it first. */
static void interpolate(const double *x0, const double *a0, const double *x1, const double *a1, double span,
                        double theta, double *x)
{
    const double s = theta / span, s2 = s * s, s3 = s2 * s, s4 = s3 * s, s5 = s4 * s, h2 = span * span;
    const double b[6] = {1.0 - 10.0 * s3 + 15.0 * s4 - 6.0 * s5, s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5,
                         0.5 * (s2 - 3.0 * s3 + 3.0 * s4 - s5),  10.0 * s3 - 15.0 * s4 + 6.0 * s5,
                         -4.0 * s3 + 7.0 * s4 - 3.0 * s5,        0.5 * (s3 - 2.0 * s4 + s5)};
    const double d[6] = {-30.0 * s2 + 60.0 * s3 - 30.0 * s4,
                         1.0 - 18.0 * s2 + 32.0 * s3 - 15.0 * s4,
                         0.5 * (2.0 * s - 9.0 * s2 + 12.0 * s3 - 5.0 * s4),
                         30.0 * s2 - 60.0 * s3 + 30.0 * s4,
                         -12.0 * s2 + 28.0 * s3 - 15.0 * s4,
                         0.5 * (3.0 * s2 - 8.0 * s3 + 5.0 * s4)};
    int j;
    for (j = 0; j < N_COORDINATES; j++) {
        const double q0 = x0[j], v0 = x0[N_COORDINATES + j], q1 = x1[j], v1 = x1[N_COORDINATES + j];
        x[j] = b[0] * q0 + b[1] * span * v0 + b[2] * h2 * a0[j] + b[3] * q1 + b[4] * span * v1 + b[5] * h2 * a1[j];
        x[N_COORDINATES + j] =
            (d[0] * q0 + d[1] * span * v0 + d[2] * h2 * a0[j] + d[3] * q1 + d[4] * span * v1 + d[5] * h2 * a1[j]) /
            span;
    }
}

/* The accelerations at (t, x), counted as an evaluation. */
static void accelerations_at(const EventStepper *e, double t, const double *x, double *a)
{
    double dx[N_STATES], u[INPUT_SLOTS];
    model_equations(&e->inst->constants, t, x, inputs_at(e->f, t, u), dx);
    e->f->evaluations++;
    memcpy(a, dx + N_COORDINATES, N_COORDINATES * sizeof(double));
}

/* Whether indicator k at `value` lies on the far side of its event from where the step began (z0): the side a
 * located event must end on, so that handling it sees the contact or the release. */
static int past(const EventStepper *e, int k, double value, double start)
{
    return e->inst->constants.law[k].compliant ? (value > -GAP_ROUNDING) != (start > -GAP_ROUNDING) : value <= 0.0;
}

/* Indicator k's zero in [lo, hi] on the interpolant (Illinois), from zlo (not past) to zhi (past). */
static double zero_on_interpolant(const EventStepper *e, int k, double t, double span, const double *x0,
                                  const double *a0, const double *x1, const double *a1, double z0k, double lo,
                                  double zlo, double hi, double zhi)
{
    double xt[STATE_SLOTS], zt[N_CONSTRAINTS];
    int iteration, side = 0;
    for (iteration = 0; iteration < 100 && hi - lo > 4.0 * DBL_EPSILON * (fabs(t) + span); iteration++) {
        double theta = hi - zhi * (hi - lo) / (zhi - zlo);
        if (!(theta > lo && theta < hi)) theta = 0.5 * (lo + hi);
        interpolate(x0, a0, x1, a1, span, theta, xt);
        indicators_at(e, t + theta, xt, zt);
        if (past(e, k, zt[k], z0k)) {
            hi = theta;
            zhi = zt[k];
            if (side == 1) zlo *= 0.5; /* Illinois: the retained end's value halved */
            side = 1;
        } else {
            lo = theta;
            zlo = zt[k];
            if (side == -1) zhi *= 0.5;
            side = -1;
        }
    }
    return hi;
}

/* The accelerations at the step's start (t, x0): from what is known there (an Adams method's history, the slope a
 * method's step started from, an implicit step's point), else evaluated. */
static void start_accelerations(EventStepper *e, const double *x0, double t, double *a0)
{
    if (e->history) /* f at the step's start is the history's newest entry */
        memcpy(a0, e->history->ab_history[e->history->ab_head] + N_COORDINATES, N_COORDINATES * sizeof(double));
    else if (!e->adaptive && steps_from_slope(e->solver) && x0 == e->x_start && t == e->t_start)
        slope_accelerations(e->f, e->solver, start_slope(e), x0, a0);
    else if (e->f->kept_jacobian && e->f->kept_jacobian->valid && t == e->f->kept_jacobian->t &&
             memcmp(x0, e->f->kept_jacobian->x, N_STATES * sizeof(double)) == 0) /* an implicit step's start */
        memcpy(a0, e->f->kept_jacobian->slope + N_COORDINATES, N_COORDINATES * sizeof(double));
    else
        accelerations_at(e, t, x0, a0);
}

/* first_on_interpolant's answer where a rigid gap touches all along the step: the event is at its start. */
#define TOUCHING_ALL_ALONG (-2)

/* The constraint whose indicator crosses first on the step's interpolant, its offset in *first; -1 where none
 * crosses after all (rounding). */
static int first_on_interpolant(EventStepper *e, double t, double span, const double *x0, const double *a0,
                                const double *x1, const double *a1, const double *z0, const double *z1, double *first)
{
    double zt[N_CONSTRAINTS], xt[STATE_SLOTS];
    int k = -1, j;
    for (j = 0; j < N_CONSTRAINTS; j++) {
        double start = 0.0, zstart = z0[j], found;
        if (!crossed(e, j, z0[j], z1[j])) continue;
        if (!e->inst->constants.law[j].compliant && !(zstart > 0.0)) {
            /* a rigid gap that starts touching (just after an impact) and returns within the step: from a point
             * where it is open */
            double probe = span;
            int open = 0, halving;
            for (halving = 0; halving < 60 && !open; halving++) {
                probe *= 0.5;
                interpolate(x0, a0, x1, a1, span, probe, xt);
                indicators_at(e, t + probe, xt, zt);
                if (zt[j] > 0.0) {
                    start = probe;
                    zstart = zt[j];
                    open = 1;
                }
            }
            if (!open) return TOUCHING_ALL_ALONG;
        }
        found = zero_on_interpolant(e, j, t, span, x0, a0, x1, a1, z0[j], start, zstart, span, z1[j]);
        if (k < 0 || found < *first) {
            k = j;
            *first = found;
        }
    }
    return k;
}

/* Indicator k's event, found at `first` on the interpolant, located on the method's own step map: the state there in x
 * (past it by at most the indicator's rounding), its offset from t returned. */
static double onto_step_map(EventStepper *e, const IntegratorMemory *memory, double t, double span, const double *x0,
                            const double *a0, const double *x1, const double *a1, const double *z0, const double *z1,
                            int k, double first, double *x)
{
    double zt[N_CONSTRAINTS], xt[STATE_SLOTS], lo, hi, zlo, zhi, theta;
    int trial;
    /* Newton steps, kept inside a bracket [lo, hi] whose hi end is past the event, with the slope
     * of the interpolant bent through the last trial (the step map and the interpolant agree at the step's ends, so
     * their difference goes as theta (span - theta) times a smooth function, taken constant from the last trial: the
     * bent curve's slope is the step map's to a higher order than the interpolant's, and a few trials reach the
     * event). Each Newton step aims at half the tolerance past the event, so that it lands past it. A compliant
     * contact's onset and end (Hertz's delta^1.5, whose higher derivatives are unbounded there) keep the
     * interpolant's own slope and, where a trial falls short, a step twice as far: in a row of touching balls the
     * located times decide which contact opens first, and the Windows binaries (another libm) agree with Linux's
     * to 1e-11 this way. */
    const int compliant = e->inst->constants.law[k].compliant;
    const double tolerance = 1e-14 * fmax(1.0, fabs(z0[k]));
    const double aim = compliant ? 0.0 : -0.5 * tolerance;
    double bend[STATE_SLOTS] = {0.0};
    lo = 0.0;
    hi = span;
    zlo = z0[k];
    zhi = z1[k];
    memcpy(x, x1, STATE_SLOTS * sizeof(double));
    theta = first;
    for (trial = 0; trial < 60 && hi - lo > 4.0 * DBL_EPSILON * (fabs(t) + span); trial++) {
        double slope, zp[N_CONSTRAINTS], zm[N_CONSTRAINTS], xp[STATE_SLOTS], xm[STATE_SLOTS], next, width;
        const double delta = 1e-6 * span, up = fmin(theta + delta, span), down = fmax(theta - delta, 0.0);
        int q;
        trial_step(e, memory, x0, t, theta, xt);
        indicators_at(e, t + theta, xt, zt);
        if (past(e, k, zt[k], z0[k])) {
            hi = theta;
            zhi = zt[k];
            memcpy(x, xt, STATE_SLOTS * sizeof(double));
            if (fabs(zt[k]) <= tolerance) break;
        } else {
            lo = theta;
            zlo = zt[k];
        }
        width = theta * (span - theta);
        if (width > 0.0 && !compliant) { /* the bend that takes the interpolant through this trial */
            interpolate(x0, a0, x1, a1, span, theta, xp);
            for (q = 0; q < N_STATES; q++) bend[q] = (xt[q] - xp[q]) / width;
        }
        interpolate(x0, a0, x1, a1, span, up, xp);
        interpolate(x0, a0, x1, a1, span, down, xm);
        for (q = 0; q < N_STATES; q++) {
            xp[q] += up * (span - up) * bend[q];
            xm[q] += down * (span - down) * bend[q];
        }
        indicators_at(e, t + up, xp, zp);
        indicators_at(e, t + down, xm, zm);
        slope = (zp[k] - zm[k]) / (up - down);
        next = theta - (zt[k] - aim) / slope;
        if (compliant && !past(e, k, zt[k], z0[k])) /* to land past the event: a little beyond the zero */
            next += fmax(fabs(zt[k] / slope), 4.0 * DBL_EPSILON * (fabs(t) + span));
        if (!(next > lo && next < hi) || !isfinite(next)) next = hi - zhi * (hi - lo) / (zhi - zlo);
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        if (e->adaptive && t + next <= t + lo) { /* far from t = 0 a correction can be below the time's rounding */
            next = nextafter(t + lo, INFINITY) - t;
            if (!(t + next < t + hi)) break;
        }
        theta = next;
    }
    return hi;
}

/* The first event in (t, t + span] of the step from x0 (indicators z0) to x1, whose indicators crossed: found on
 * the step's interpolant, then on the method's own step map (so that every method keeps its order through
 * impacts) by a Newton step or two from there. Leaves the state at the event in x (past it by at most the
 * indicator's rounding) and returns the event's offset from t. Typically costs two evaluations and one or two
 * trial steps. */
static double locate_event(EventStepper *e, const IntegratorMemory *memory, const double *x0, double t, double span,
                           const double *z0, const double *x1, double *x)
{
    double a0[N_COORDINATES], a1[N_COORDINATES], z1[N_CONSTRAINTS], first = span;
    int k;
    start_accelerations(e, x0, t, a0);
    accelerations_at(e, t + span, x1, a1);
    indicators_at(e, t + span, x1, z1);
    k = first_on_interpolant(e, t, span, x0, a0, x1, a1, z0, z1, &first);
    if (k == TOUCHING_ALL_ALONG) {
        memcpy(x, x0, STATE_SLOTS * sizeof(double));
        return 0.0;
    }
    if (k < 0) { /* no crossing after all (rounding): the step's end */
        memcpy(x, x1, STATE_SLOTS * sizeof(double));
        return span;
    }
    return onto_step_map(e, memory, t, span, x0, a0, x1, a1, z0, z1, k, first, x);
}

/* A contact that closes and opens again between two comparisons (a ball through another within one long step)
 * changes no indicator's sign. An open contact's gap that approaches at the step's start and recedes at its end
 * may dip inside: below the tangents at the two ends, where they meet, lies the least value a convex gap can take
 * (a V for balls that pass through each other, a parabola for a near miss). Where that lies past contact, the step
 * is tried up to that point; a crossing there is an event like any other, and without one the side on which the
 * gap still approaches and recedes is searched the same way. Returns the offset of the first crossing found (x1
 * and z1 then the trial's state and indicators), or 0 where there is none. Costs the gaps' rates at the step's
 * ends (r0 those at its start where known, else NULL), which it leaves in r1 for the next step, and a trial step
 * with the gaps' rates per point tried. */
#define DIP_TRIALS 8
static double dip_within(EventStepper *e, const IntegratorMemory *memory, const double *x0, double t, double span,
                         const double *z0, const double *r0, double *x1, double *z1, double *r1)
{
    const ModelConst *c = &e->inst->constants;
    const int32_t active = e->inst->s.active_constraints;
    double g0[N_CONSTRAINTS], start[N_CONSTRAINTS], g1[N_CONSTRAINTS], best = 0.0;
    double found_x[STATE_SLOTS] = {0.0}, found_z[N_CONSTRAINTS] = {0.0};
    int k, j;
    if (r0)
        memcpy(start, r0, sizeof start); /* r0 may be r1, which the end's rates overwrite */
    else
        model_gap_rates(c, t, x0, g0, start);
    model_gap_rates(c, t + span, x1, g1, r1);
    for (k = 0; k < N_CONSTRAINTS; k++) {
        double a = 0.0, ga = z0[k], ra = start[k], b = span, gb = z1[k], rb = r1[k];
        int trial;
        if (c->law[k].bilateral || (active >> k & 1) || !(ga > 0.0) || !(gb > 0.0)) continue;
        for (trial = 0; trial < DIP_TRIALS && ra < 0.0 && rb > 0.0 && (best == 0.0 || a < best); trial++) {
            const double meet = (gb - ga + ra * a - rb * b) / (ra - rb);
            double xt[STATE_SLOTS], zt[N_CONSTRAINTS], gt[N_CONSTRAINTS], rt[N_CONSTRAINTS];
            int any = 0;
            if (!(meet > a && meet < b) || !(ga + ra * (meet - a) < -GAP_ROUNDING)) break;
            /* a fixed-step method's trials stay within the call's bound (an adaptive one's pass checks its own) */
            if (!e->adaptive &&
                e->f->evaluations + e->f->checks + (uint64_t)evaluations_needed(e->solver, 0, 1.0, e->f) >
                    e->f->budget) {
                e->f->out_of_budget = 1;
                e->short_of = 1;
                return 0.0;
            }
            trial_step(e, memory, x0, t, meet, xt);
            if (e->short_of) return 0.0;
            indicators_at(e, t + meet, xt, zt);
            for (j = 0; j < N_CONSTRAINTS; j++) any |= crossed(e, j, z0[j], zt[j]);
            if (any) {
                best = meet;
                memcpy(found_x, xt, sizeof found_x);
                memcpy(found_z, zt, sizeof found_z);
                break;
            }
            model_gap_rates(c, t + meet, xt, gt, rt);
            if (rt[k] < 0.0) { /* still approaching there: the dip, if any, lies after */
                a = meet;
                ga = gt[k];
                ra = rt[k];
            } else {
                b = meet;
                gb = gt[k];
                rb = rt[k];
            }
        }
    }
    if (best > 0.0) {
        memcpy(x1, found_x, sizeof found_x);
        memcpy(z1, found_z, sizeof found_z);
    }
    return best;
}

/* The history an Adams step that crossed (not its starter's) takes its trial steps from, on its polynomial; NULL
 * for the other methods. */
static const IntegratorMemory *adams_history(const EventStepper *e, const IntegratorMemory *memory)
{
    const AdamsBashforth *ab = e->adaptive ? NULL : adams_bashforth_of(e->solver);
    return ab && memory->ab_count >= ab->steps ? memory : NULL;
}

/* ---- A call with events: its phases ---- */

/* What passes from one substep to the next. */
typedef struct {
    const Call *call;
    EventStepper e;
    KeptJacobian kept; /* the implicit methods' Jacobian at a step's start, for the trial steps from there */
    double z0[N_CONSTRAINTS], z1[N_CONSTRAINTS]; /* the indicators at a substep's start and end */
    int reuse; /* the next substep starts with the indicators this one ended with (z1) */
    double rates[N_CONSTRAINTS]; /* the gaps' rates where the last step ended (adaptive methods) */
    int rates_known;
    double checked[N_REAL];
    double x_call[STATE_SLOTS]; /* the call's start, with m_call and active_call */
    IntegratorMemory m_call;
    int32_t active_call;
    uint64_t events_before;
} EventCall;

/* One substep: from ta (an event's time once one is resolved) to tb, and how its events went. */
typedef struct {
    double ta, tb;
    double step_end; /* a fixed-step method's step ends here, whatever it finds inside */
    double x0[STATE_SLOTS]; /* the state at ta, with the integrator memory m0 */
    IntegratorMemory m0;
    uint64_t events_seen;
    int32_t active_seen;
    int stalls, remainder;
} Substep;

/* The state and the integrator memory back where the substep began (or its last event), its work counted. */
static void back_to_substep_start(const EventCall *ec, const Substep *sub)
{
    IntegratorMemory *memory = &ec->call->inst->s.integrator;
    memcpy(ec->call->inst->s.real, sub->x0, sizeof sub->x0);
    *memory = sub->m0;
    count_work(memory, ec->call->f);
}

/* The state, the integrator memory and the constraints acting back where the call began. */
static void back_to_call_start(const EventCall *ec)
{
    SimState *s = &ec->call->inst->s;
    memcpy(s->real, ec->x_call, sizeof ec->x_call);
    s->integrator = ec->m_call;
    s->active_constraints = ec->active_call;
}

/* Discard: a method stopped short inside a substep with events; the call ends where the substep began. */
static Status discard_stopped_in_substep(const EventCall *ec, const Substep *sub)
{
    back_to_substep_start(ec, sub);
    return discard_stopped_short(ec->call, sub->ta);
}

#if N_COMPLIANT > 0
/* How much an oscillation grows over one period at y = h omega with `solver` (over one step where a step is longer). */
static double period_growth(const EventStepper *e, double y)
{
    const double growth = oscillation_growth(e->solver, e->f, y);
    return growth > 0.0 ? pow(growth, fmax(1.0, 6.283185307179586 / y)) : 0.0;
}

/* A fixed step of an explicit method must follow the compliant contacts' oscillation: where h omega lies beyond the
 * method's stability there, every step multiplies it (rk4: for h omega > 2.83) and energy appears from nothing. A
 * step from x at t (a step's start, or an onset) is refused where the oscillation the contacts that overlap or close
 * within it will reach would grow more than 2-fold per period: writes why into message and returns 1. */
static int too_stiff(const EventStepper *e, double t, const double *x, char *message, size_t size)
{
    double omega, low = 0.0, high, growth;
    int k, contact;
    if (!(oscillation_growth(e->solver, e->f, 1.0) > 0.0)) return 0; /* a method this does not cover */
    contact = compliant_frequency(&e->inst->constants, t, x, e->hs, &omega);
    if (contact < 0 || !(omega > 0.0)) return 0;
    high = e->hs * omega;
    growth = period_growth(e, high);
    if (!(growth > 2.0)) return 0;
    for (k = 0; k < 60; k++) { /* the largest h omega within 2-fold */
        const double middle = 0.5 * (low + high);
        if (period_growth(e, middle) > 2.0)
            high = middle;
        else
            low = middle;
    }
    snprintf(message, size,
             "the compliant contact %s at t = %.17g is too stiff for %s at h = %g: its oscillation from there "
             "(angular frequency up to %g rad/s at full compression) grows %.3g-fold per period, where h at most %.3g "
             "keeps it within "
             "2-fold (or take an implicit or an adaptive method)",
             CONSTRAINT_NAMES[contact], t, solver_name(e->solver), e->hs, omega, growth, low / omega);
    return 1;
}

/* Discard where a fixed step from x at ta meets contacts too stiff for h (too_stiff): the call ends at ta. */
static int stiffness_refused(const EventCall *ec, double ta, const double *x)
{
    char message[600];
    if (ec->e.adaptive || !too_stiff(&ec->e, ta, x, message, sizeof message)) return GO_ON;
    count_work(&ec->call->inst->s.integrator, ec->call->f);
    return discard_at(*ec->call, ta, "%s; stopped there (last successful time %.17g)", message, ta);
}
#endif

/* Phase: the method's step over the substep (an adaptive method's one step, at most h long, sets tb). */
static int take_substep(EventCall *ec, Substep *sub, int64_t i)
{
    const Call *call = ec->call;
    EventStepper *e = &ec->e;
    RightHandSide *f = call->f;
    IntegratorMemory *memory = &call->inst->s.integrator;
    double *x = call->inst->s.real;
    if (e->adaptive) {
        f->single_step = 1;
        sub->tb = adaptive_pass(f, call->solver, memory, x, sub->ta, sub->tb, e->h, e->tol, 0);
        f->single_step = 0;
        if (!(sub->tb > sub->ta)) /* no step accepted: out of budget, or the step fell below the resolution of time */
            return discard_stopped_in_substep(ec, sub);
    } else if (steps_from_slope(call->solver)) { /* its f at the start stays for the event's trial steps */
        step_from_slope(f, call->solver, memory, x, sub->ta, e->hs, start_slope(e));
    } else if (integrate_fixed(f, call->solver, memory, x, call->t, e->hs, i, 1, 0) < 1) { /* Newton failed */
        back_to_substep_start(ec, sub);
        return discard_failed(call, sub->ta, solver_name(call->solver), e->h, f->unconverged, NULL);
    }
    if (!model_state_ok(&call->inst->constants, x)) {
        back_to_substep_start(ec, sub);
        return discard_failed(call, sub->ta, solver_name(call->solver), e->h, f->unconverged,
                              f->refused_known ? f->refused : NULL);
    }
    return GO_ON;
}

/* Phase: whether an indicator crossed over the substep, or a contact closes and opens again inside it (then tb is
 * moved to where it was found). */
static int crossing_found(EventCall *ec, Substep *sub)
{
    EventStepper *e = &ec->e;
    double *x = ec->call->inst->s.real;
    int any, k;
    indicators_at(e, sub->tb, x, ec->z1);
    sub->step_end = sub->tb;
    for (any = 0, k = 0; k < N_CONSTRAINTS; k++) any |= crossed(e, k, ec->z0[k], ec->z1[k]);
    if (any) {
        ec->rates_known = 0; /* an event moves the state from where its rates were */
        return 1;
    }
    {
        double dip;
        e->history = adams_history(e, &ec->call->inst->s.integrator);
        dip = dip_within(e, &sub->m0, sub->x0, sub->ta, sub->tb - sub->ta, ec->z0,
                         ec->reuse && ec->rates_known ? ec->rates : NULL, x, ec->z1, ec->rates);
        e->history = NULL;
        ec->rates_known = dip == 0.0;
        if (dip > 0.0) sub->tb = sub->ta + dip;
        return dip > 0.0;
    }
}

/* Discard: the constraints at ta are dependent (handling the event found no unique solution); the call ends at ta,
 * or at its start where the state at ta cannot be output. */
static Status discard_dependent(EventCall *ec, double ta)
{
    Instance *inst = ec->call->inst;
    double good = ta;
    count_work(&inst->s.integrator, ec->call->f);
    if (!evaluate_at(inst, ta, inst->s.real, ec->checked)) { /* its outputs overflow: back to the call's start */
        back_to_call_start(ec);
        good = ec->call->t;
    }
    return discard_at(*ec->call, good,
                      "the constraints at t = %.17g are dependent (an impact or a contact force has no "
                      "unique solution); stopped at the last successful time %.17g",
                      ta, good);
}

/* Phase: whether the call stops after an event it resolved at sub->ta: a method of free motion where a constraint
 * now acts, a contact too stiff for h, an event that recurs at once, or too many events in one call. */
static int event_refused(EventCall *ec, Substep *sub)
{
    const Call *call = ec->call;
    SimState *s = &call->inst->s;
    IntegratorMemory *memory = &s->integrator;
    char message[512];
    if (free_motion_refused(call->solver, s->active_constraints, "from", sub->ta, message, sizeof message)) {
        count_work(memory, call->f);
        return discard_at(*call, sub->ta, "%s; stopped there (last successful time %.17g)", message, sub->ta);
    }
#if N_COMPLIANT > 0
    if (stiffness_refused(ec, sub->ta, s->real) != GO_ON) return STATUS_DISCARD; /* the contact begun */
#endif
    /* events found again and again where they change nothing: stop rather than spin */
    sub->stalls =
        memory->n_events == sub->events_seen && s->active_constraints == sub->active_seen ? sub->stalls + 1 : 0;
    sub->events_seen = memory->n_events;
    sub->active_seen = s->active_constraints;
    if (sub->stalls > 2) {
        count_work(memory, call->f);
        return discard_at(*call, sub->ta,
                          "an event at t = %.17g recurs at once after it was handled (the state cannot "
                          "leave the constraint's boundary with %s at h = %g); stopped there (last successful time "
                          "%.17g)",
                          sub->ta, solver_name(call->solver), ec->e.h, sub->ta);
    }
    if (memory->n_events - ec->events_before > MAX_EVENTS_PER_CALL) {
        count_work(memory, call->f);
        return discard_at(*call, sub->ta,
                          "%d events within this step, the most one call handles; stopped at t = %.17g "
                          "(last successful time %.17g): take a shorter communication step",
                          MAX_EVENTS_PER_CALL, sub->ta, sub->ta);
    }
    return GO_ON;
}

/* Phase: locate the first event in the substep, resolve it there (impacts, activations, releases) and start the rest
 * of the substep from it; ends the call where the importer lets a step end at an event. */
static int resolve_event(EventCall *ec, Substep *sub)
{
    const Call *call = ec->call;
    Instance *inst = call->inst;
    SimState *s = &inst->s;
    IntegratorMemory *memory = &s->integrator;
    const ModelConst *c = &inst->constants;
    EventStepper *e = &ec->e;
    double *x = s->real;
    double located[STATE_SLOTS], theta, u[INPUT_SLOTS];
    const int32_t active_before = s->active_constraints;
    int status;
    memcpy(located, x, sizeof located); /* the step's end, past the event */
    e->history = adams_history(e, memory);
    theta = locate_event(e, &sub->m0, sub->x0, sub->ta, sub->tb - sub->ta, ec->z0, located, x);
    e->history = NULL;
    if (!e->adaptive) sub->tb = sub->step_end; /* a dip was searched up to where the tangents met: the rest goes on */
    if (e->short_of) /* a trial step stopped short: the event is not located; back to the step's start */
        return discard_stopped_in_substep(ec, sub);
    sub->ta += theta;
    *memory = sub->m0;
    memory->ab_count = 0;
    memory->ab_restarted = 1;
    if (!e->adaptive && theta > 0.0) memory->n_steps++; /* the step onto the event */
    memcpy(located, x, sizeof located);
    ec->kept.valid = 0; /* the constraints acting may change */
    if (!leave_boundary(c, s->active_constraints, e->departing, sub->ta, x) ||
        !handle_event(c, &s->active_constraints, sub->ta, x, inputs_at(call->f, sub->ta, u), &memory->n_events) ||
        !model_state_ok(c, x)) {
        memcpy(x, located, sizeof located); /* the state the event was found in, as it was */
        s->active_constraints = active_before;
        memory->n_events = sub->m0.n_events;
        return discard_dependent(ec, sub->ta);
    }
    if ((status = event_refused(ec, sub)) != GO_ON) return status;
    memcpy(sub->x0, x, sizeof sub->x0);
    sub->m0 = *memory;
    start_of_step(e, sub->ta, sub->x0, ec->z0, NULL);
    if (inst->return_at_events && sub->ta > call->t && sub->ta < call->t + call->H &&
        memory->n_events > ec->events_before) { /* FMI 3.0 */
        count_work(memory, call->f);
        call->f->checks++;
        if (!evaluate_at(inst, sub->ta, x, ec->checked))
            return discard_failed(call, sub->ta, solver_name(call->solver), e->h, 0, x);
        return ok_checked(call, sub->ta - call->t, ec->checked);
    }
    return GO_ON;
}

/* Phase: the rest of the substep after an event, from it; sets *any where an indicator crossed again. */
static int rest_of_substep(EventCall *ec, Substep *sub, int *any)
{
    EventStepper *e = &ec->e;
    double *x = ec->call->inst->s.real;
    int k;
    *any = 0;
    sub->remainder = 0;
    if (!(sub->tb - sub->ta > 4.0 * DBL_EPSILON * fabs(sub->tb))) {
        memcpy(ec->z1, ec->z0, sizeof ec->z1);
        return GO_ON;
    }
    sub->remainder = !e->adaptive;
    trial_step(e, &sub->m0, sub->x0, sub->ta, sub->tb - sub->ta, x);
    if (e->short_of) return discard_stopped_in_substep(ec, sub); /* the call ends at the event */
    indicators_at(e, sub->tb, x, ec->z1);
    for (k = 0; k < N_CONSTRAINTS; k++) *any |= crossed(e, k, ec->z0[k], ec->z1[k]);
    return GO_ON;
}

/* Phase: the substep's end, projected onto the constraints that act, reported where the importer asks; *reached is
 * then tb. */
static int end_substep(EventCall *ec, Substep *sub, double *reached)
{
    const Call *call = ec->call;
    Instance *inst = call->inst;
    SimState *s = &inst->s;
    const ModelConst *c = &inst->constants;
    double *x = s->real;
    s->integrator.n_steps += (uint64_t)sub->remainder; /* the rest of a step that had an event */
    if (!leave_boundary(c, s->active_constraints, ec->e.departing, sub->tb, x) ||
        !project_constraints(c, s->active_constraints, sub->tb, x)) {
        count_work(&s->integrator, call->f);
        return discard_failed(call, sub->ta, solver_name(call->solver), ec->e.h, 0, NULL);
    }
    /* the next step starts with the indicators this one ended with, unless a projection moved the state */
    ec->reuse = !ec->e.departing && !rigid_acting(c, s->active_constraints);
    *reached = sub->tb;
    if (inst->report_step && inst->s.machine_state == MS_STEP_COMPLETE) state_acceptable(inst, sub->tb, x);
    return GO_ON;
}

/* Substep i of n (an adaptive method's steps: from *reached, at most h long) with its events: each substep is taken,
 * then the event indicators are compared at its ends. Where one crossed, the event time is found on the method's own
 * step map (locate_event), so that the state at the event has the method's order; the event is resolved there, and
 * the rest of the substep is taken from it. Adams-Bashforth methods take their Runge-Kutta starter for these partial
 * steps and restart their history after an event. */
static int substep_with_events(EventCall *ec, int64_t i, int64_t n, double *reached)
{
    const Call *call = ec->call;
    const EventStepper *e = &ec->e;
    const double t_end = call->t + call->H;
    IntegratorMemory *memory = &call->inst->s.integrator;
    Substep sub;
    int any, status;
    sub.ta = e->adaptive ? *reached : call->t + (double)i * e->hs;
    /* an adaptive method's substep ends where its one step does, at most h on */
    sub.tb = e->adaptive  ? (sub.ta + 1.001 * e->h >= t_end ? t_end : sub.ta + e->h)
             : i + 1 == n ? t_end
                          : call->t + (double)(i + 1) * e->hs;
    memcpy(sub.x0, call->inst->s.real, sizeof sub.x0);
    sub.m0 = *memory;
    sub.events_seen = memory->n_events;
    sub.active_seen = call->inst->s.active_constraints;
    sub.stalls = sub.remainder = 0;
    start_of_step(&ec->e, sub.ta, sub.x0, ec->z0, ec->reuse ? ec->z1 : NULL);
#if N_COMPLIANT > 0
    if (stiffness_refused(ec, sub.ta, call->inst->s.real) != GO_ON) return STATUS_DISCARD; /* the contacts it meets */
#endif
    if ((status = take_substep(ec, &sub, i)) != GO_ON) return status;
    any = crossing_found(ec, &sub);
    if (e->short_of) return discard_stopped_in_substep(ec, &sub);
    while (any) {
        if ((status = resolve_event(ec, &sub)) != GO_ON) return status;
        if ((status = rest_of_substep(ec, &sub, &any)) != GO_ON) return status;
    }
    return end_substep(ec, &sub, reached);
}

/* A call on an object with constraints: planned as a fixed-step call is (an adaptive method's substeps are its own
 * steps), its work bound counting an event's location per substep, its end checked. */
static Status steps_with_events(const Call *call)
{
    Instance *inst = call->inst;
    SimState *s = &inst->s;
    IntegratorMemory *memory = &s->integrator;
    EventCall ec;
    EventStepper *e = &ec.e;
    const double planned = planned_substeps(call->H, call->h);
    char message[512];
    double reached;
    int64_t i, n;
    ec.call = call;
    ec.events_before = memory->n_events;
    ec.reuse = ec.rates_known = 0;
    memset(ec.rates, 0, sizeof ec.rates);
    ec.kept.valid = 0;
    call->f->kept_jacobian = &ec.kept;
    memcpy(ec.x_call, s->real, sizeof ec.x_call);
    ec.m_call = *memory;
    ec.active_call = s->active_constraints;
    e->inst = inst;
    e->f = call->f;
    e->solver = call->solver;
    e->h = call->h;
    e->tol = call->tol;
    e->short_of = 0;
    e->history = NULL;
    e->adaptive = adaptive_method(call->solver, call->tol);
    if (free_motion_refused(call->solver, s->active_constraints, "at", call->t, message, sizeof message))
        return discard_untouched(*call, "%s; nothing was done (last successful time %.17g)", message, call->t);
    e->hs = call->H / planned;
    n = e->adaptive ? 0 : (int64_t)planned;
    if (!e->adaptive) {
        /* each substep, and at most an event's location per substep */
        const double work = 2.0 * evaluations_needed(call->solver, 0, planned, call->f) + planned;
        if (work > MAX_EVALUATIONS_PER_CALL) return error_too_much_work(call, work, " with its event checks");
        keep_history_for(memory, e->hs);
    }
    /* An adaptive method's indicators are compared at each of its own steps (at most h long): a gap that closes
     * and opens again between two comparisons (a ball through another) is missed, so h bounds the time between
     * them. */
    for (i = 0, reached = call->t; e->adaptive ? reached < call->t + call->H : i < n; i++) {
        const int status = substep_with_events(&ec, i, n, &reached);
        if (status != GO_ON) return (Status)status;
    }
    count_work(memory, call->f);
    call->f->checks++;
    if (!evaluate_at(inst, call->t + call->H, s->real, ec.checked)) { /* the call's start is its last good point */
        double refused[STATE_SLOTS];
        memcpy(refused, s->real, sizeof refused);
        back_to_call_start(&ec);
        return discard_failed(call, call->t, solver_name(call->solver), e->h, 0, refused);
    }
    return ok_checked(call, call->H, ec.checked);
}
#endif

/* ---- A call without events: its phases ---- */

/* Phase: the method's settings, checked also where a closed form (model = linear) takes the step; the Taylor
 * method's work series allocated at its first call. */
static int method_refused(const Call *call)
{
    Instance *inst = call->inst;
    if (call->solver == SOLVER_TAYLOR && !inst->taylor_work) {
        inst->taylor_work =
            (double (*)[TAYLOR_SLOTS])inst->allocate(TAYLOR_SERIES + STATE_SLOTS, sizeof *inst->taylor_work);
        if (!inst->taylor_work)
            return error_refused(*call, "out of memory for the Taylor method's %d work series of %d coefficients",
                                 TAYLOR_SERIES + STATE_SLOTS, TAYLOR_SLOTS);
    }
    if (NEEDS_TOL(call->solver) && !(call->tol > 0.0))
        return error_refused(*call,
                             "%s needs a tolerance: variable tol = 0 is out of its range (0, 1] for %s (tol = 0 "
                             "means a fixed step only for %s)",
                             solver_name(call->solver), solver_name(call->solver), FIXED_STEP_AT_ZERO_TOL);
    if (call->solver == SOLVER_GBS && call->tol > 0.0 && call->tol < GBS_SMALLEST_TOL)
        return error_refused(*call,
                             "gbs with tol = %g: out of reach in double precision (its columns agree to "
                             "rounding first); allowed for gbs: 0 (fixed step h) or [%g, 1]",
                             call->tol, GBS_SMALLEST_TOL);
    return GO_ON;
}

/* The right-hand side of the call: the model with the inputs held at their values now, or moving along their
 * slopes over the step; its counters at zero. */
static void prepare_right_hand_side(RightHandSide *f, Instance *inst, double t)
{
    int i;
    f->model = &inst->constants;
    gather_inputs(inst, f->u0);
    f->inputs_vary = 0;
    f->forces = 0;
    for (i = 0; i < N_INPUTS; i++) { /* no branch per input */
        f->du[i] = inst->s.input_derivative[i];
        f->inputs_vary |= f->du[i] != 0.0;
        f->forces |= f->u0[i] != 0.0;
    }
    f->forces |= f->inputs_vary;
    f->t0 = t;
    f->evaluations = 0;
    f->checks = 0;
    f->budget = (uint64_t)MAX_EVALUATIONS_PER_CALL - 1; /* one check of the end state stays in the budget */
    f->jacobians = 0;
    f->iterations = 0;
    f->unconverged = 0;
    f->out_of_budget = 0;
    f->taylor_order = inst->s.integer[INT_taylor_order];
    f->gbs_columns = inst->s.integer[INT_gbs_columns];
    f->single_step = 0;
    f->taylor_work = inst->taylor_work;
    f->taylor_series = inst->taylor_work ? inst->taylor_work + TAYLOR_SERIES : NULL;
    f->taylor_cached = 0;
    f->acceptable = state_acceptable;
    f->jacobian = jacobian_at;
    f->kept_jacobian = NULL;
    f->refused_known = 0;
    f->context = inst;
    f->start_slope = NULL;
}

#if HAS_LINEAR_MODEL
/* Phase: model = linear takes the whole step in closed form, where it has one. */
static int closed_form_step(const Call *call)
{
    Instance *inst = call->inst;
    double u_mid[INPUT_SLOTS], closed[STATE_SLOTS], checked[N_REAL];
    int i;
    if (!inst->constants.linear) return GO_ON; /* only model = linear has a closed form */
    for (i = 0; i < N_INPUTS; i++) u_mid[i] = call->f->u0[i] + 0.5 * call->H * call->f->du[i];
    memcpy(closed, inst->s.real, sizeof closed);
    if (!model_closed_form_step(&inst->constants, call->H, u_mid, closed)) return GO_ON;
    if (!evaluate_at(inst, call->t + call->H, closed, checked))
        return discard_failed(call, call->t, "closed form", call->H, 0, closed);
    memcpy(inst->s.real, closed, sizeof closed);
    inst->s.integrator.n_steps++;
    return ok_checked(call, call->H, checked);
}
#endif

/* An adaptive method's call: one pass to the step's end, its end checked (a pass that reports its steps checks each
 * of them; one that does not is redone, checking, where the end fails). */
static Status adaptive_steps(const Call *call)
{
    Instance *inst = call->inst;
    IntegratorMemory *memory = &inst->s.integrator;
    RightHandSide *f = call->f;
    double *x = inst->s.real;
    const int reporting = inst->report_step != NULL;
    const double t_end = call->t + call->H;
    double x_start[STATE_SLOTS], checked[N_REAL], reached;
    const IntegratorMemory memory_start = *memory;
    memcpy(x_start, x, sizeof x_start);
    reached = adaptive_pass(f, call->solver, memory, x, call->t, t_end, call->h, call->tol, reporting);
    f->checks++;
    if (reporting) {
        if (reached == t_end && evaluate_at(inst, reached, x, checked)) {
            count_work(memory, f);
            return ok_checked(call, call->H, checked);
        }
    } else if (!evaluate_at(inst, reached, x, checked)) { /* outputs overflowed although the state stayed finite */
        memcpy(x, x_start, sizeof x_start);
        *memory = memory_start;
        /* the checking pass runs on what is left of the budget */
        reached = adaptive_pass(f, call->solver, memory, x, call->t, t_end, call->h, call->tol, 1);
    } else if (reached == t_end) {
        count_work(memory, f);
        return ok_checked(call, call->H, checked);
    }
    count_work(memory, f);
    if (reached < t_end) return discard_stopped_short(call, reached);
    return ok_unchecked(call);
}

/* Phase: the work bound of a fixed-step call without events: the method's evaluations, one check per block (or per
 * substep when reporting), and the redo of one failing block with a check after each of its substeps. At most twice
 * the dearest substep's work plus two checks per substep: only a call near the bound is counted exactly (else 0). */
static double fixed_step_work(const Call *call, double planned, double hs, int reporting)
{
    Instance *inst = call->inst;
    const IntegratorMemory *memory = &inst->s.integrator;
    double redone;
    if (!(inst->substep_work > 0.0)) inst->substep_work = evaluations_needed(call->solver, 0, 1.0, call->f);
    if (!(planned * (2.0 * inst->substep_work + 2.0) > MAX_EVALUATIONS_PER_CALL)) return 0.0;
    redone = fmin(planned, (double)CHECK_BLOCK);
    return evaluations_needed(call->solver, history_serves(memory, hs) ? memory->ab_count : 0, planned, call->f) +
           (reporting ? planned
                      : ceil(planned / CHECK_BLOCK) + evaluations_needed(call->solver, 0, redone, call->f) + redone);
}

/* Phase: substeps first ... first + count - 1 of the n, checked at the block's end (as the call's end, for the last
 * block); whether the block stands. Where it fails it is redone from its start with a check after every substep, so
 * that x is the last good state: *done substeps stand. */
static int block_stands(const Call *call, double hs, int64_t first, int64_t count, int64_t n, double *checked,
                        int64_t *done)
{
    Instance *inst = call->inst;
    IntegratorMemory *memory = &inst->s.integrator;
    RightHandSide *f = call->f;
    double *x = inst->s.real;
    const int reporting = inst->report_step != NULL, last = first + count == n;
    const double t_block_end = last ? call->t + call->H : call->t + (double)(first + count) * hs;
    double x_block[STATE_SLOTS];
    const IntegratorMemory memory_block = *memory;
    memcpy(x_block, x, sizeof x_block);
    if (reporting && !f->inputs_vary && reports_one_at_a_time(call->solver)) {
        *done = report_substeps(inst, f, call->solver, memory, x, call->t, hs, first, count, t_block_end);
        if (*done == count) return 1; /* every substep checked in place, the last at t_block_end */
    } else {
        *done = integrate_fixed(f, call->solver, memory, x, call->t, hs, first, count, reporting);
    }
    if (*done == count) {
        f->checks++;
        if (last ? end_state_good(inst, f, t_block_end, checked) : evaluate_at(inst, t_block_end, x, checked)) return 1;
    }
    f->start_slope = NULL; /* the end check may have overwritten it */
    if (!reporting) { /* the reporting pass checked every substep already: x is the last good one */
        f->unconverged = 0; /* the checking pass finds the first failure again, whatever it is */
        memcpy(x, x_block, sizeof x_block);
        *memory = memory_block;
        *done = integrate_fixed(f, call->solver, memory, x, call->t, hs, first, count, 1);
    }
    return 0;
}

/* A fixed-step method's call: n substeps of H / n, in blocks of CHECK_BLOCK, each checked at its end; a failure is
 * redone, checking every substep, from the last good block only. */
static Status fixed_steps(const Call *call)
{
    Instance *inst = call->inst;
    SimState *s = &inst->s;
    IntegratorMemory *memory = &s->integrator;
    RightHandSide *f = call->f;
    const double planned = planned_substeps(call->H, call->h);
    const double hs = call->H / planned;
    const double work = fixed_step_work(call, planned, hs, inst->report_step != NULL);
    double checked[N_REAL];
    int64_t n, first, done;
    if (work > MAX_EVALUATIONS_PER_CALL) return error_too_much_work(call, work, ", its state checks included");
    n = (int64_t)planned;
    keep_history_for(memory, hs);
    /* The last call's end check evaluated f where this call starts, with these inputs: its derivatives are the
     * first substep's first evaluation (bit for bit: the same function of the same numbers, rounded to nearest;
     * in another mode the compiler's rewrites, exact only to nearest, may round the two apart). */
    if (inst->outputs_valid && inst->derivatives_current && call->t == s->time && !f->inputs_vary &&
        rounding_to_nearest(inst)
#if HAS_LINEAR_MODEL
        && !inst->constants.linear
#endif
    )
        f->start_slope = s->real + N_STATES;
    for (first = 0; first < n; first += CHECK_BLOCK) {
        if (block_stands(call, hs, first, n - first < CHECK_BLOCK ? n - first : CHECK_BLOCK, n, checked, &done))
            continue;
        count_work(memory, f);
        memory->ab_count = memory->ab_restarted = 0;
        return discard_failed(call, first + done == n ? call->t + call->H : call->t + (double)(first + done) * hs,
                              solver_name(call->solver), call->h, f->unconverged, f->refused_known ? f->refused : NULL);
    }
    count_work(memory, f);
    if (f->inputs_vary) return ok_checked(call, call->H, checked);
    return ok_in_place(call); /* the end check left the outputs and the derivatives in place */
}

/* One communication step from t to t + H: the method's settings checked, then the whole step in closed form where the
 * model has one, else the method's substeps, with events where the object has constraints. */
Status step_to(Instance *inst, const char *function, double t, double H)
{
    RightHandSide f;
    Call call;
    int status;
    call.inst = inst;
    call.function = function;
    call.f = &f;
    call.solver = inst->s.integer[INT_solver];
    call.t = t;
    call.H = H;
    call.h = inst->s.real[VR_h];
    call.tol = inst->s.real[VR_tol];
    take_slopes(&inst->s);
    if ((status = method_refused(&call)) != GO_ON) return (Status)status;
    prepare_right_hand_side(&f, inst, t);
#if HAS_LINEAR_MODEL
    if ((status = closed_form_step(&call)) != GO_ON) return (Status)status;
#endif
#if N_CONSTRAINTS > 0
    return steps_with_events(&call);
#endif
    if (adaptive_method(call.solver, call.tol)) return adaptive_steps(&call);
    return fixed_steps(&call);
}

#endif
