/* The FMI functions the harness's native loops call, in one shape for FMI 2.0 and FMI 3.0: the
 * addresses come from the binary fmpy loaded (harness/fmi/native_calls.py fills this struct), and
 * each call picks the version's argument list. */
#ifndef FMI_CALLS_H
#define FMI_CALLS_H

#include <stdbool.h>
#include <stddef.h>

#include "fmi_status.h" /* the return codes (the FMUs' core numbers them as the harness reads them) */

/* FMI 2.0's shapes */
typedef int (*SetReal2)(void *, const unsigned *, size_t, const double *);
typedef int (*GetReal2)(void *, const unsigned *, size_t, double *);
typedef int (*GetInteger2)(void *, const unsigned *, size_t, void *);
typedef int (*DoStep2)(void *, double, double, int);
typedef int (*SetDerivatives2)(void *, const unsigned *, size_t, const int *, const double *);
typedef int (*GetDerivatives2)(void *, const unsigned *, size_t, const int *, double *);
/* FMI 3.0's: every get and set also takes the number of values; no input derivatives */
typedef int (*SetFloat3)(void *, const unsigned *, size_t, const double *, size_t);
typedef int (*GetFloat3)(void *, const unsigned *, size_t, double *, size_t);
typedef int (*GetInteger3)(void *, const unsigned *, size_t, void *, size_t);
typedef int (*DoStep3)(void *, double, double, bool, bool *, bool *, bool *, double *);
typedef int (*GetDerivatives3)(void *, const unsigned *, size_t, const int *, double *, size_t);
/* FMU states: the same shape in both versions */
typedef int (*GetState)(void *, void **);
typedef int (*SetState)(void *, void *);
typedef int (*FreeState)(void *, void **);

/* The C type of the integers read: int32, int64 or uint64 */
enum { INTEGER_32 = 0, INTEGER_64 = 1, UNSIGNED_64 = 2 };

typedef struct {
    void *component;
    void *set_float, *get_float, *get_integer, *do_step, *set_derivatives, *get_derivatives;
    int fmi3; /* the function pointers are FMI 3.0's */
    int integer_kind; /* INTEGER_32, INTEGER_64 or UNSIGNED_64 */
    double *last_time; /* FMI 3.0: where fmi3DoStep's lastSuccessfulTime goes */
    void *get_state, *set_state, *free_state; /* NULL where the FMU cannot save its state */
} FmiCalls;

static inline int fmi_set_floats(const FmiCalls *f, const unsigned *vrs, int n, const double *values)
{
    return f->fmi3 ? ((SetFloat3)f->set_float)(f->component, vrs, (size_t)n, values, (size_t)n)
                   : ((SetReal2)f->set_float)(f->component, vrs, (size_t)n, values);
}

static inline int fmi_get_floats(const FmiCalls *f, const unsigned *vrs, int n, double *values)
{
    return f->fmi3 ? ((GetFloat3)f->get_float)(f->component, vrs, (size_t)n, values, (size_t)n)
                   : ((GetReal2)f->get_float)(f->component, vrs, (size_t)n, values);
}

static inline int fmi_get_integers(const FmiCalls *f, const unsigned *vrs, int n, void *values)
{
    return f->fmi3 ? ((GetInteger3)f->get_integer)(f->component, vrs, (size_t)n, values, (size_t)n)
                   : ((GetInteger2)f->get_integer)(f->component, vrs, (size_t)n, values);
}

static inline int fmi_get_output_derivatives(const FmiCalls *f, const unsigned *vrs, int n, const int *orders,
                                             double *values)
{
    return f->fmi3 ? ((GetDerivatives3)f->get_derivatives)(f->component, vrs, (size_t)n, orders, values, (size_t)n)
                   : ((GetDerivatives2)f->get_derivatives)(f->component, vrs, (size_t)n, orders, values);
}

/* FMI 2.0 only: FMI 3.0 has no input derivatives */
static inline int fmi_set_input_derivatives(const FmiCalls *f, const unsigned *vrs, int n, const int *orders,
                                            const double *values)
{
    return ((SetDerivatives2)f->set_derivatives)(f->component, vrs, (size_t)n, orders, values);
}

static inline int fmi_do_step(const FmiCalls *f, double t, double H)
{
    if (f->fmi3) {
        bool event = false, terminate = false, early = false;
        return ((DoStep3)f->do_step)(f->component, t, H, true, &event, &terminate, &early, f->last_time);
    }
    return ((DoStep2)f->do_step)(f->component, t, H, 1);
}

static inline int fmi_get_state(const FmiCalls *f, void **state)
{
    return ((GetState)f->get_state)(f->component, state);
}

static inline int fmi_set_state(const FmiCalls *f, void *state)
{
    return ((SetState)f->set_state)(f->component, state);
}

static inline int fmi_free_state(const FmiCalls *f, void **state)
{
    return ((FreeState)f->free_state)(f->component, state);
}

#endif
