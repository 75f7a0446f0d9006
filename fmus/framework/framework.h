/* The shared FMI framework: instance layout, variable table types and the interface every model
 * implements in its physics.c. The framework is compiled once per FMU, against that FMU's
 * generated model_description.h, so array sizes and value references are compile-time constants. */
#ifndef FRAMEWORK_H
#define FRAMEWORK_H

#include <math.h> /* INFINITY in the generated variable table */
#include <stddef.h>
#include <stdint.h>

#include "fmi2_api.h"

/* Internal names stay private to the binary, also when an importer compiles the sources without the
 * project's build flags: only the fmi2 functions are exported, so that two FMUs in one process never
 * call each other's internals. (Windows DLLs export only what is marked for export anyway.) */
#if defined(__GNUC__) && !defined(_WIN32) && !defined(__CYGWIN__)
#define INTERNAL __attribute__((visibility("hidden")))
#else
#define INTERNAL
#endif

typedef enum {
    CAUSALITY_PARAMETER, CAUSALITY_CALCULATED_PARAMETER, CAUSALITY_INPUT, CAUSALITY_OUTPUT,
    CAUSALITY_LOCAL, CAUSALITY_INDEPENDENT
} Causality;
typedef enum {
    VARIABILITY_CONSTANT, VARIABILITY_FIXED, VARIABILITY_TUNABLE, VARIABILITY_DISCRETE, VARIABILITY_CONTINUOUS
} Variability;
typedef enum { INITIAL_EXACT, INITIAL_APPROX, INITIAL_CALCULATED } Initial;

typedef struct {
    const char *name;
    Causality causality;
    Variability variability;
    Initial initial;
    int has_start;
    double start, min, max;
} VariableInfo;

#include "model_description.h"
#include "physics.h"

/* Sizes that stay legal C for a model without states or inputs (the Spring). */
#define STATE_SLOTS (N_STATES > 0 ? N_STATES : 1)
#define INPUT_SLOTS (N_INPUTS > 0 ? N_INPUTS : 1)
#define INTEGER_SLOTS (N_INTEGER > 0 ? N_INTEGER : 1)
#define AB_MAX_STEPS 6

/* States of the FMI 2.0 state machines (CS and ME share one bit set). */
enum {
    MS_INSTANTIATED = 1 << 0,
    MS_INITIALIZATION = 1 << 1,
    MS_STEP_COMPLETE = 1 << 2,
    MS_STEP_FAILED = 1 << 3,
    MS_EVENT = 1 << 4,
    MS_CONTINUOUS = 1 << 5,
    MS_TERMINATED = 1 << 6,
    MS_ERROR = 1 << 7
};

/* Integrator memory that must survive between fmi2DoStep calls. */
typedef struct {
    uint64_t n_rhs, n_steps, n_rejected;
    double ab_history[AB_MAX_STEPS][STATE_SLOTS]; /* past right-hand sides, ring buffer */
    int32_t ab_count;                              /* valid entries in ab_history */
    int32_t ab_head;                               /* slot of the newest entry */
    double ab_step;                                /* substep the history was taken with */
    double rkf_proposal;                           /* rkf45: next step size, 0 = start from h */
} IntegratorMemory;

/* Everything that makes up the FMU state: plain numbers only, so it serializes as bytes and
 * restores in another process. */
typedef struct {
    double time;
    double last_successful_time;
    double real[N_REAL];
    int32_t integer[INTEGER_SLOTS];
    double input_derivative[INPUT_SLOTS]; /* first derivatives of the inputs, for the next step */
    int32_t machine_state;
    IntegratorMemory integrator;
} SimState;

typedef struct {
    SimState s;
    ModelConst constants;   /* derived from the parameters by model_prepare */
    int constants_valid;
    int outputs_valid;      /* calculated outputs in s.real match the state */
    fmi2Type type;
    char *name;
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocate;
    fmi2CallbackFreeMemory release;
    fmi2ComponentEnvironment environment;
    int logging_on;
} Instance;

/* instance.c. Logging: errors and discards are always reported; the rest only with debug logging on. */
INTERNAL void log_error(Instance *inst, const char *fmt, ...);
INTERNAL void log_discard(Instance *inst, const char *fmt, ...);
INTERNAL void log_debug(Instance *inst, const char *fmt, ...);

/* Index of the first non-finite value among n, or -1 when all are finite. */
INTERNAL int first_non_finite(const double *values, int n);

/* The current inputs, gathered into a contiguous array. */
INTERNAL void gather_inputs(const Instance *inst, double *u);

/* stepper.c: fmi2DoStep's integration from s.time to t + H. */
INTERNAL fmi2Status step_to(Instance *inst, double t, double H);
INTERNAL void restart_integrator(Instance *inst);
#if N_STATES > 0
/* States x (of the Instance context) are finite and regular, with finite derivatives and outputs. */
INTERNAL int state_acceptable(const void *context, double t, const double *x);
#endif

/* ---- implemented by each model: physics.h defines ModelConst and, for a model with states,
 * static inline void model_equations(const ModelConst *c, double t, const double *x,
 *                                    const double *u, double *dx)
 * (dx = f(t, x, u) of the integrators; u == NULL when every input is zero and constant, so that
 * force terms can be skipped) and model_derivatives (the same signature: the model selected by a
 * model's own switch, such as its linear model, for Model Exchange and the outputs); physics.c
 * defines the rest. ---- */

/* Derived constants from the parameters (after initialization and after a tunable change); returns
 * 0, or 1 with a message when the parameters together are inconsistent. */
INTERNAL int model_prepare(const double *real, const int32_t *integer, ModelConst *c, char *message, size_t size);
#if N_STATES > 0
/* 0 when x is non-finite or a singular configuration. */
INTERNAL int model_state_ok(const ModelConst *c, const double *x);
/* Says why the derivatives at (t, x) are undefined (a requirement of the object or the mass matrix);
 * returns 0 when it finds no reason. */
INTERNAL int model_explain_singularity(const ModelConst *c, double t, const double *x, char *message, size_t size);
/* Closed-form step over H with inputs u held; returns 0 when the model has none in this configuration. */
INTERNAL int model_closed_form_step(const ModelConst *c, double H, const double *u, double *x);
#endif
/* Write all calculated outputs into real[] at time t, from the states and inputs already in real[]
 * (and the state derivatives dx, NULL for a model without states); returns 0 at a singular
 * configuration. */
INTERNAL int model_outputs(const ModelConst *c, double t, const double *dx, double *real);
/* rate[vr] = exact time derivative of every Real output vr; du are the input derivatives. */
INTERNAL void model_output_rates(const ModelConst *c, double t, const double *real, const double *dx, const double *du,
                        double *rate);
/* Advance the inputs over a step of H using their derivatives (and, for positions, velocities). */
INTERNAL void model_advance_inputs(double *real, const double *du, double H);

/* Default for model_advance_inputs (instance.c): each input moves with its own first derivative. */
INTERNAL void advance_inputs_linearly(double *real, const double *du, double H);

#endif
