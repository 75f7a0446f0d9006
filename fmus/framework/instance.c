/* What every part of the framework needs of an instance: logging through the importer's callback,
 * the inputs gathered from the variables, and the finiteness check. Kept out of core.c so that
 * stepper.c depends on this file alone and the core depends on the stepper, not the reverse. */
#include <stdarg.h>
#include <stdio.h>

#define MODEL_DESCRIPTION_TABLES /* INPUT_VRS */
#include "framework.h"

#if defined(__SSE2__) || defined(_M_X64) || (defined(_M_IX86_FP) && _M_IX86_FP >= 2)
#include <xmmintrin.h>
#define FLUSH_BITS 0x8040u /* MXCSR: flush to zero (bit 15), denormals are zero (bit 6) */
#define ROUNDING_BITS 0x6000u /* MXCSR: rounding control (bits 13, 14), 0 to nearest */
#define TO_NEAREST 0u
static unsigned long float_control(void) { return _mm_getcsr(); }
static void set_float_control(unsigned long value) { _mm_setcsr((unsigned)value); }
#elif defined(__aarch64__)
#define FLUSH_BITS (1ul << 24) /* FPCR.FZ: subnormal operands and results are zero */
#define ROUNDING_BITS (3ul << 22) /* FPCR.RMode, 0 to nearest */
#define TO_NEAREST 0ul
static unsigned long float_control(void)
{
    unsigned long value;
    __asm__ __volatile__("mrs %0, fpcr" : "=r"(value));
    return value;
}
static void set_float_control(unsigned long value) { __asm__ __volatile__("msr fpcr, %0" : : "r"(value)); }
#else
#include <fenv.h>
#define FLUSH_BITS 0u
#define ROUNDING_BITS (~0ul)
#define TO_NEAREST ((unsigned long)FE_TONEAREST)
static unsigned long float_control(void) { return (unsigned long)fegetround(); } /* the rounding mode only */
static void set_float_control(unsigned long value) { (void)value; }
#endif

const char *real_variable_name(int k) { return REAL_VARIABLES[k].name; }

void flush_subnormals_begin(Instance *inst)
{
    inst->caller_float_control = float_control();
    inst->flushing = 1;
    if ((inst->caller_float_control & FLUSH_BITS) != FLUSH_BITS)
        set_float_control(inst->caller_float_control | FLUSH_BITS);
}

int rounding_to_nearest(const Instance *inst) { return (inst->caller_float_control & ROUNDING_BITS) == TO_NEAREST; }

void flush_subnormals_end(Instance *inst)
{
    if (!inst->flushing) return;
    inst->flushing = 0;
    if ((inst->caller_float_control & FLUSH_BITS) != FLUSH_BITS) set_float_control(inst->caller_float_control);
}

void caller_float_control_begin(Instance *inst)
{
    if (inst->flushing && (inst->caller_float_control & FLUSH_BITS) != FLUSH_BITS)
        set_float_control(inst->caller_float_control);
}

void caller_float_control_end(Instance *inst)
{
    if (inst->flushing && (inst->caller_float_control & FLUSH_BITS) != FLUSH_BITS)
        set_float_control(inst->caller_float_control | FLUSH_BITS);
}

static void log_with(Instance *inst, Status status, const char *category, const char *fmt, va_list args)
{
    char message[1024];
    char *p;
    if (!inst || !inst->emit) return;
    vsnprintf(message, sizeof message, fmt, args);
    /* Importers differ in whether they treat the message as a printf format: a '%' is never safe. */
    for (p = message; *p; p++)
        if (*p == '%') *p = '?';
    caller_float_control_begin(inst);
    inst->emit(inst, status, category, message);
    caller_float_control_end(inst);
}

void log_error(Instance *inst, const char *fmt, ...)
{
    va_list args;
    va_start(args, fmt);
    log_with(inst, STATUS_ERROR, "logStatusError", fmt, args);
    va_end(args);
}

void log_discard(Instance *inst, const char *fmt, ...)
{
    va_list args;
    va_start(args, fmt);
    log_with(inst, STATUS_DISCARD, "logStatusDiscard", fmt, args);
    va_end(args);
}

void log_debug(Instance *inst, const char *fmt, ...)
{
    va_list args;
    if (!inst || !inst->logging_on) return;
    va_start(args, fmt);
    log_with(inst, STATUS_OK, "logAll", fmt, args);
    va_end(args);
}

int first_non_finite(const double *values, int n)
{
    int i;
    for (i = 0; i < n; i++)
        if (!isfinite(values[i])) return i;
    return -1;
}

void scatter_inputs(double *real, const double *u)
{
#if N_INPUTS > 0
    int i;
    for (i = 0; i < N_INPUTS; i++) real[INPUT_VRS[i]] = u[i];
#else
    (void)real;
    (void)u;
#endif
}

void gather_inputs(const Instance *inst, double *u)
{
#if N_INPUTS > 0
    int i;
    for (i = 0; i < N_INPUTS; i++) u[i] = inst->s.real[INPUT_VRS[i]];
#else
    (void)inst;
    (void)u;
#endif
}

void advance_inputs_linearly(double *real, const double *du, double H)
{
#if N_INPUTS > 0
    int i;
    for (i = 0; i < N_INPUTS; i++) /* a held input keeps its bits: -0.0 + 0.0 would be +0.0 */
        if (du[i] != 0.0) real[INPUT_VRS[i]] += H * du[i];
#else
    (void)real;
    (void)du;
    (void)H;
#endif
}
