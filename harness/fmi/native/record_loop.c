/* The recorder's loop in C (harness/fmi/simulation.py): step one FMU along a grid and write each
 * communication point's outputs straight into the rows of preallocated tables, many points per call
 * from Python. The Python loop beside it has the same contract; the tests compare the two. */
#include "fmi_calls.h"

typedef struct {
    FmiCalls calls;
    int n_real, n_int;
    const unsigned *real_vrs, *int_vrs;
    char *reals;      /* row i of the float outputs at reals + i * real_stride */
    long real_stride;
    char *ints;       /* row i of the integer outputs (calls.integer_kind) at ints + i * int_stride */
    long int_stride;
} RecordUnit;

enum { AT_STEP = 0, AT_FLOATS = 1, AT_INTEGERS = 2 };

/* Fills rows first ... end - 1, row i > 0 after the step from grid[i - 1] to grid[i]. Returns FMI_OK,
 * or the status that stopped it (a discarded or failed step, a failed read): *done is then the row
 * not written and *where the call (AT_*); on FMI_OK *done is end. Warnings do not stop it. */
int record_rows(const RecordUnit *unit, const double *grid, long first, long end, long *done, int *where)
{
    long i;
    int status;
    for (i = first; i < end; i++) {
        if (i > 0) {
            status = fmi_do_step(&unit->calls, grid[i - 1], grid[i] - grid[i - 1]);
            if (status == FMI_DISCARD || status >= FMI_ERROR) {
                *done = i;
                *where = AT_STEP;
                return status;
            }
        }
        status = fmi_get_floats(&unit->calls, unit->real_vrs, unit->n_real, (double *)(unit->reals + i * unit->real_stride));
        if (status >= FMI_ERROR) {
            *done = i;
            *where = AT_FLOATS;
            return status;
        }
        if (unit->n_int) {
            status = fmi_get_integers(&unit->calls, unit->int_vrs, unit->n_int, unit->ints + i * unit->int_stride);
            if (status >= FMI_ERROR) {
                *done = i;
                *where = AT_INTEGERS;
                return status;
            }
        }
    }
    *done = end;
    return FMI_OK;
}
