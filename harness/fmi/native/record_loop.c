/* The recorder's loop in C (harness/fmi/simulation.py): step one FMU along a grid and write each
 * communication point's outputs straight into the rows of preallocated tables, many points per call
 * from Python. The Python loop beside it has the same contract; the tests compare the two. */
#include "record_loop.h"

int record_rows(const RecordUnit *unit, const double *grid, long first, long end, long *done, int *where)
{
    long i;
    int status;
    for (i = first; i < end; i++) {
        if (i > 0) {
            status = fmi_do_step(&unit->calls, grid[i - 1], grid[i] - grid[i - 1]);
            if (status == STATUS_DISCARD || status >= STATUS_ERROR) {
                *done = i;
                *where = AT_STEP;
                return status;
            }
        }
        status =
            fmi_get_floats(&unit->calls, unit->real_vrs, unit->n_real, (double *)(unit->reals + i * unit->real_stride));
        if (status >= STATUS_ERROR) {
            *done = i;
            *where = AT_FLOATS;
            return status;
        }
        if (unit->n_int) {
            status = fmi_get_integers(&unit->calls, unit->int_vrs, unit->n_int, unit->ints + i * unit->int_stride);
            if (status >= STATUS_ERROR) {
                *done = i;
                *where = AT_INTEGERS;
                return status;
            }
        }
    }
    *done = end;
    return STATUS_OK;
}
