/* What every part of the framework needs of an instance: logging through the importer's callback,
 * the inputs gathered from the variables, and the finiteness check. Kept out of core.c so that
 * stepper.c depends on this file alone and the core depends on the stepper, not the reverse. */
#include <stdarg.h>
#include <stdio.h>

#define MODEL_DESCRIPTION_TABLES /* INPUT_VRS */
#include "framework.h"

static void log_with(Instance *inst, Status status, const char *category, const char *fmt, va_list args)
{
    char message[1024];
    char *p;
    if (!inst || !inst->emit) return;
    vsnprintf(message, sizeof message, fmt, args);
    /* Importers differ in whether they treat the message as a printf format: a '%' is never safe. */
    for (p = message; *p; p++)
        if (*p == '%') *p = '?';
    inst->emit(inst, status, category, message);
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
    for (i = 0; i < N_INPUTS; i++) real[INPUT_VRS[i]] += H * du[i];
#else
    (void)real;
    (void)du;
    (void)H;
#endif
}
