/* The recorder's loop (record_loop.c): its unit and its one function, for the programs that call it
 * from C; harness/fmi/native_calls.py declares the same layout for Python. */
#ifndef RECORD_LOOP_H
#define RECORD_LOOP_H

#include "fmi_calls.h"

typedef struct {
    FmiCalls calls;
    int n_real, n_int;
    const unsigned *real_vrs, *int_vrs;
    char *reals; /* row i of the float outputs at reals + i * real_stride */
    long real_stride;
    char *ints; /* row i of the integer outputs (calls.integer_kind) at ints + i * int_stride */
    long int_stride;
} RecordUnit;

enum { AT_STEP = 0, AT_FLOATS = 1, AT_INTEGERS = 2 };

/* Fills rows first ... end - 1, row i > 0 after the step from grid[i - 1] to grid[i]. Returns STATUS_OK,
 * or the status that stopped it (a discarded or failed step, a failed read): *done is then the row
 * not written and *where the call (AT_*); on STATUS_OK *done is end. Warnings do not stop it. */
int record_rows(const RecordUnit *unit, const double *grid, long first, long end, long *done, int *where);

#endif
