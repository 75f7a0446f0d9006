/* The fixed-step inner loop of the harness's master, in C: for each macro step set the inputs,
 * step the FMUs (Jacobi or Gauss-Seidel, inputs held or extrapolated linearly) and record a row.
 * Python prepares everything (instances, buffers, routes; the fmi2 function pointers are the ones
 * fmpy loaded) and keeps everything else: initialization, iteration, step doubling, rollback,
 * messages. Semantics are those of harness/cosim/master.py, which the tests compare against. */
#include <stddef.h>

typedef int (*SetReal)(void *, const unsigned *, size_t, const double *);
typedef int (*GetReal)(void *, const unsigned *, size_t, double *);
typedef int (*GetInteger)(void *, const unsigned *, size_t, int *);
typedef int (*DoStep)(void *, double, double, int);
typedef int (*SetDerivatives)(void *, const unsigned *, size_t, const int *, const double *);
typedef int (*GetDerivatives)(void *, const unsigned *, size_t, const int *, double *);

typedef struct {
    void *component;
    SetReal set_real;
    GetReal get_real;
    GetInteger get_integer;
    DoStep do_step;
    SetDerivatives set_derivatives;
    GetDerivatives get_derivatives;
    int n_out, n_in, n_int;
    const unsigned *out_vrs, *in_vrs, *int_vrs;
    const int *orders_out, *orders_in;
    double *y_now, *dy_now, *y_next, *dy_next, *u, *du;
    int *ints;
    const int *source_unit;  /* per input: index of the unit that feeds it */
    const int *source_index; /* per input: index of that unit's output */
    int energy_index;        /* output holding the unit's energy, -1 for none */
} CoreUnit;

enum { CORE_OK = 0, CORE_DISCARD = 2, CORE_ERROR = 3 };

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
    status = unit->set_real(unit->component, unit->in_vrs, (size_t)unit->n_in, unit->u);
    if (status >= CORE_ERROR || !linear) return status;
    return unit->set_derivatives(unit->component, unit->in_vrs, (size_t)unit->n_in, unit->orders_in, unit->du);
}

static int step_and_read(CoreUnit *unit, double t, double H, int linear)
{
    int status = unit->do_step(unit->component, t, H, 1);
    if (status != CORE_OK && status != 1) return status;
    status = unit->get_real(unit->component, unit->out_vrs, (size_t)unit->n_out, unit->y_next);
    if (status >= CORE_ERROR || !linear) return status;
    return unit->get_derivatives(unit->component, unit->out_vrs, (size_t)unit->n_out, unit->orders_out,
                                 unit->dy_next);
}

static int record(CoreUnit *units, int n_units, double t, double *row, double *energy)
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
        if (units[k].get_integer(units[k].component, units[k].int_vrs, (size_t)units[k].n_int, units[k].ints) >=
            CORE_ERROR)
            return CORE_ERROR;
        for (i = 0; i < units[k].n_int; i++) row[column++] = units[k].ints[i];
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
        if (record(units, n_units, t, table + p * row_length, energy + p) != CORE_OK) return CORE_ERROR;
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
