/* The fixed-step inner loop of the harness's master, in C: for each macro step set the inputs,
 * step the FMUs (Jacobi or Gauss-Seidel, inputs held or extrapolated linearly) and record a row.
 * Python prepares everything (instances, buffers, routes; the function pointers are the ones fmpy
 * loaded, of FMI 2.0 or 3.0 per unit) and keeps everything else: initialization, iteration, step
 * doubling, rollback, messages. Semantics are those of harness/cosim/master.py, which the tests
 * compare against. */
#include <stdint.h>

#include "fmi_calls.h"

typedef struct {
    FmiCalls calls;
    int n_out, n_in, n_int;
    const unsigned *out_vrs, *in_vrs, *int_vrs;
    const int *orders_out, *orders_in;
    double *y_now, *dy_now, *y_next, *dy_next, *u, *du;
    void *ints;              /* n_int integers of calls.integer_kind */
    const int *source_unit;  /* per input: index of the unit that feeds it */
    const int *source_index; /* per input: index of that unit's output */
    int energy_index;        /* output holding the unit's energy, -1 for none */
} CoreUnit;

static double integer_value(const CoreUnit *unit, int i)
{
    switch (unit->calls.integer_kind) {
    case INTEGER_64: return (double)((const int64_t *)unit->ints)[i];
    case UNSIGNED_64: return (double)((const uint64_t *)unit->ints)[i];
    default: return ((const int *)unit->ints)[i];
    }
}

enum { CORE_OK = FMI_OK, CORE_DISCARD = FMI_DISCARD, CORE_ERROR = FMI_ERROR };

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
    if (status >= CORE_ERROR || !linear) return status;
    /* linear only where every receiver is FMI 2.0 (the master refuses it otherwise) */
    return fmi_set_input_derivatives(&unit->calls, unit->in_vrs, unit->n_in, unit->orders_in, unit->du);
}

static int step_and_read(CoreUnit *unit, double t, double H, int linear)
{
    int status = fmi_do_step(&unit->calls, t, H);
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

/* Records grid[0], then steps to grid[1], records, ... up to grid[n_points - 1]. Returns the status;
 * *rows is the number of rows written, *culprit the unit that failed (or -1). `stepped` is scratch
 * space of n_units ints. */
int cosim_run(CoreUnit *units, int n_units, const double *grid, long n_points, int gauss_seidel, int linear,
              double *table, long row_length, double *energy, int *stepped, long *rows, int *culprit)
{
    long p;
    int k, i, status;
    *rows = 0;
    *culprit = -1;
    for (p = 0; p < n_points; p++) {
        const double t = grid[p];
        if (record(units, n_units, t, table + p * row_length, energy + p, culprit) != CORE_OK) return CORE_ERROR;
        *rows = p + 1;
        if (p + 1 == n_points) break;
        {
            const double H = grid[p + 1] - t;
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
        }
    }
    return CORE_OK;
}
