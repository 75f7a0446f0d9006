/* The shared FMI framework: instance layout, variable table types, the version-neutral core that
 * every FMI API layer calls (core.c), and the interface every model implements in its physics.c.
 * Nothing here names an FMI version: fmi2_functions.c is the FMI 2.0 layer over it. The framework is
 * compiled once per FMU, against that FMU's generated model_description.h, so array sizes and value
 * references are compile-time constants. */
#ifndef FRAMEWORK_H
#define FRAMEWORK_H

#include <math.h> /* INFINITY in the generated variable table */
#include <stddef.h>
#include <stdint.h>

/* Internal names stay private to the binary, also when an importer compiles the sources without the
 * project's build flags: only the FMI functions are exported, so that two FMUs in one process never
 * call each other's internals. (Windows DLLs export only what is marked for export anyway.) */
#if defined(FMU_SINGLE_UNIT)
/* fmu_fmi2.c and fmu_fmi3.c (what the model descriptions list for importers) compile the whole FMU as
 * one translation unit, where internal names are static: several source FMUs then link into one
 * program, each with its own FMI2_FUNCTION_PREFIX / FMI3_FUNCTION_PREFIX. A model uses only some of
 * the framework's functions, hence `unused`. */
#if defined(__GNUC__)
#define INTERNAL static __attribute__((unused))
#else
#define INTERNAL static
#endif
#define INTERNAL_DATA static
#define INTERNAL_DATA_DECLARATION static
#elif defined(__GNUC__) && !defined(_WIN32) && !defined(__CYGWIN__)
#define INTERNAL __attribute__((visibility("hidden")))
#else
#define INTERNAL
#endif
#ifndef INTERNAL_DATA
/* tables defined in one file and read in others */
#define INTERNAL_DATA INTERNAL
#define INTERNAL_DATA_DECLARATION extern INTERNAL
#endif

#include "fmi_status.h"
typedef enum { INTERFACE_MODEL_EXCHANGE, INTERFACE_CO_SIMULATION } Interface;

typedef enum {
    CAUSALITY_PARAMETER,
    CAUSALITY_CALCULATED_PARAMETER,
    CAUSALITY_INPUT,
    CAUSALITY_OUTPUT,
    CAUSALITY_LOCAL,
    CAUSALITY_INDEPENDENT
} Causality;
typedef enum {
    VARIABILITY_CONSTANT,
    VARIABILITY_FIXED,
    VARIABILITY_TUNABLE,
    VARIABILITY_DISCRETE,
    VARIABILITY_CONTINUOUS
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
#include "taylor.h"
#ifndef N_CONSTRAINTS /* a hand-written model without constraints (the Spring) */
#define N_CONSTRAINTS 0
#endif
/* An object's event indicators are its constraints'; a hand-written model declares its own in its XML. */
#if N_CONSTRAINTS > 0 && N_EVENT_INDICATORS != N_CONSTRAINTS
#error "numberOfEventIndicators of the model description differs from the object's constraints"
#endif

/* Sizes that stay legal C for a model without states or inputs (the Spring). */
#define STATE_SLOTS (N_STATES > 0 ? N_STATES : 1)
#define INPUT_SLOTS (N_INPUTS > 0 ? N_INPUTS : 1)
#define INTEGER_SLOTS (N_INTEGER > 0 ? N_INTEGER : 1)
#define AB_MAX_STEPS 6

/* States of the FMI state machines (CS and ME share one bit set; an API layer names them in its
 * version's terms: stepComplete is FMI 3.0's Step Mode). */
enum {
    MS_INSTANTIATED = 1 << 0,
    MS_INITIALIZATION = 1 << 1,
    MS_STEP_COMPLETE = 1 << 2,
    MS_STEP_FAILED = 1 << 3,
    MS_EVENT = 1 << 4,
    MS_CONTINUOUS = 1 << 5,
    MS_TERMINATED = 1 << 6,
    MS_ERROR = 1 << 7,
    MS_INTERMEDIATE = 1 << 8 /* FMI 3.0: inside the importer's intermediate-update callback */
};
#define MS_LAST MS_INTERMEDIATE
/* The states an instance of each interface can be in. */
#define CS_ANY \
    (MS_INSTANTIATED | MS_INITIALIZATION | MS_STEP_COMPLETE | MS_STEP_FAILED | MS_TERMINATED | MS_ERROR | \
     MS_INTERMEDIATE)
#define ME_ANY (MS_INSTANTIATED | MS_INITIALIZATION | MS_EVENT | MS_CONTINUOUS | MS_TERMINATED | MS_ERROR)

/* Integrator memory that must survive between fmi2DoStep calls. */
typedef struct {
    uint64_t n_rhs, n_steps, n_rejected;
    uint64_t n_jacobians, n_iterations; /* the implicit methods' Newton solves */
    uint64_t n_events; /* impacts, activations, releases, compliant onsets and ends */
    double ab_history[AB_MAX_STEPS][STATE_SLOTS]; /* past right-hand sides, ring buffer */
    int32_t ab_count; /* valid entries in ab_history */
    int32_t ab_head; /* slot of the newest entry */
    double ab_step; /* substep the history was taken with */
    double step_proposal; /* rkf45, gbs: next step size, 0 = start from h */
    int32_t gbs_columns; /* gbs: the column to reach next step, 0 = from tol */
    int32_t gbs_rejected; /* gbs: the last step was rejected (no growth next) */
    int32_t ab_restarted; /* 1: the history starts again after an event (restarter) */
} IntegratorMemory;

/* Everything that makes up the FMU state: plain numbers only, so it serializes as bytes and
 * restores in another process. */
typedef struct {
    double time;
    double last_successful_time;
    double real[N_REAL];
    int32_t integer[INTEGER_SLOTS];
    double input_derivative[INPUT_SLOTS]; /* first derivatives of the inputs over the next (or last) step */
    int32_t slopes_set; /* 1: set for the next step; 0: those of the last step, for its end's output rates */
    int32_t machine_state;
    int32_t active_constraints; /* a bit per rigid constraint that acts (resting, taut); bilateral ones always act */
    IntegratorMemory integrator;
} SimState;

typedef struct Instance Instance;
/* How a message reaches the importer: the API layer's translation to its version's logger. */
typedef void (*MessageSink)(const Instance *inst, Status status, const char *category, const char *message);

struct Instance {
    SimState s;
    ModelConst constants; /* derived from the parameters by model_prepare */
    int constants_valid;
    int outputs_valid; /* calculated outputs in s.real match the state */
    /* With outputs_valid: the derivatives in s.real are f(t, x, u) at the state's time, exactly as a fixed-step
     * method evaluates it there with the inputs held (set by a step whose inputs held; an input set since clears
     * it), so the next step takes them as its first evaluation. */
    int derivatives_current;
    /* Right-hand sides one substep of the chosen method takes at most, 0 until step_to computes it for the
     * constants (ensure_constants clears it): its work bound per call without counting each call's work. */
    double substep_work;
    Interface type;
    char *name;
    MessageSink emit;
    void (*api_logger)(void); /* the importer's logger, cast back to its type by the API layer */
    void *environment; /* the importer's pointer handed back with every message */
    /* Called at every accepted internal step of a communication step, with the state of that step
     * in place and the machine state MS_INTERMEDIATE; NULL when the importer asked for no reports. */
    void (*report_step)(Instance *inst, double t);
    void (*api_intermediate)(void); /* the importer's callback behind report_step, cast back by the layer */
    /* FMI 3.0 Co-Simulation: asks the importer, through the same callback, for the inputs it registered
     * (inputs_requested) at time t, the end of the step about to be taken; NULL when it registered none.
     * asking_inputs: inside that request, where those inputs may be set. */
    void (*request_inputs)(Instance *inst, double t);
    unsigned char inputs_requested[INPUT_SLOTS];
    int asking_inputs;
    const char *const *state_names; /* the layer's names of the MS_ states, by bit position */
    void *(*allocate)(size_t count, size_t size);
    void (*release)(void *memory);
    /* The Taylor method's work series (TAYLOR_SERIES of them: 3 KB for the simple pendulum, 79 KB for the
     * five-link chain), then STATE_SLOTS for the last series computed, allocated at its first step, so that an
     * instance that never uses it pays nothing. */
    double (*taylor_work)[TAYLOR_SLOTS];
    int logging_on;
    int return_at_events; /* FMI 3.0 Co-Simulation with earlyReturnAllowed: a step ends at the first event it handles */
    /* The importer's floating-point control word while a step runs with subnormal numbers flushed
     * (flush_subnormals); its callbacks run with it. */
    unsigned long caller_float_control;
    int flushing;
};

/* instance.c. A communication step runs with subnormal numbers flushed to zero, so that its cost does
 * not depend on them (x86 and ARM cores take some hundred cycles per subnormal operand or result;
 * they arise from states such as 1e-160 squared). Begin returns the importer's setting, which end
 * restores; the importer's callbacks in between (logger, intermediate steps) run with its own
 * setting. Elsewhere (WebAssembly) these do nothing. */
INTERNAL void flush_subnormals_begin(Instance *inst);
INTERNAL void flush_subnormals_end(Instance *inst);
INTERNAL void caller_float_control_begin(Instance *inst);
INTERNAL void caller_float_control_end(Instance *inst);
/* Whether the step runs rounding to nearest (the importer's mode, read by flush_subnormals_begin). */
INTERNAL int rounding_to_nearest(const Instance *inst);

/* instance.c. Logging: errors and discards are always reported; the rest only with debug logging on. */
INTERNAL void log_error(Instance *inst, const char *fmt, ...);
INTERNAL void log_discard(Instance *inst, const char *fmt, ...);
INTERNAL void log_debug(Instance *inst, const char *fmt, ...);

/* Index of the first non-finite value among n, or -1 when all are finite. */
INTERNAL int first_non_finite(const double *values, int n);
/* Whether all n values are finite, without a branch per value: v - v is 0 for a finite v and NaN otherwise, and a
 * NaN survives the sums (first_non_finite names the culprit where this fails). */
static inline int all_finite(const double *values, int n)
{
    double even = 0.0, odd = 0.0;
    int i;
    for (i = 0; i + 1 < n; i += 2) {
        even += values[i] - values[i];
        odd += values[i + 1] - values[i + 1];
    }
    if (i < n) even += values[i] - values[i];
    return even + odd == 0.0;
}

/* all_finite over the values a step or an evaluation computes (states, derivatives, outputs), leaving out the
 * parameters and inputs, which their setters checked. */
static inline int computed_finite(const double *real)
{
    return all_finite(real, SET_REALS_BEGIN) && all_finite(real + SET_REALS_END, N_REAL - SET_REALS_END);
}
/* The name of Real variable k (its value reference), for messages. */
INTERNAL const char *real_variable_name(int k);

/* The current inputs, gathered into a contiguous array, and an array of inputs put into real[]. */
INTERNAL void gather_inputs(const Instance *inst, double *u);
INTERNAL void scatter_inputs(double *real, const double *u);

/* stepper.c: the integration of a communication step from s.time to t + H; `function` names the API
 * function in messages. */
INTERNAL Status step_to(Instance *inst, const char *function, double t, double H);
INTERNAL void restart_integrator(Instance *inst);
#if N_STATES > 0
/* States x (of the Instance context) are finite and regular, with finite derivatives and outputs. */
INTERNAL int state_acceptable(void *context, double t, const double *x);
/* The first Real (state, derivative or output) that is not finite at (t, x), by value reference; -1 for
 * none, or where the model refuses the configuration before computing. */
INTERNAL int first_non_finite_at(const Instance *inst, double t, const double *x);
#endif

/* ---- core.c: what every API function does once its call is allowed in the current state. Each takes
 * the API function's name for its messages, logs what it refuses and returns a Status. ---- */
INTERNAL Instance *core_instantiate(const char *function, Interface type, const char *name, const char *token,
                                    MessageSink emit, void (*api_logger)(void), void *environment,
                                    void *(*allocate)(size_t, size_t), void (*release)(void *), int logging_on);
INTERNAL void core_free(Instance *inst);
/* Whether the call may come in the instance's machine state (masks of MS_ bits per interface);
 * logs an illegal call sequence otherwise. */
INTERNAL int core_call_allowed(Instance *inst, const char *function, unsigned cs, unsigned me);
INTERNAL Status core_set_logging(Instance *inst, const char *function, int on, size_t n,
                                 const char *const categories[]);
INTERNAL void core_reset(Instance *inst);
INTERNAL Status core_setup(Instance *inst, const char *function, double start, int stop_defined, double stop);
INTERNAL Status core_exit_initialization(Instance *inst, const char *function);
INTERNAL int core_arrays_present(Instance *inst, const char *function, size_t n, const void *a, const void *b);
/* The variable with value reference vr (Real or Integer), NULL for none. */
INTERNAL const VariableInfo *core_variable(unsigned int vr);
/* The index of the first of n value references that is not a Real output (also_allowed aside), n when all are. */
INTERNAL size_t core_first_not_output(const unsigned int vr[], size_t n, unsigned int also_allowed);
INTERNAL Status core_get_real(Instance *inst, const char *function, const unsigned int vr[], size_t n, double value[]);
INTERNAL Status core_set_real(Instance *inst, const char *function, const unsigned int vr[], size_t n,
                              const double value[]);
/* Integer variables (enumerations and the counters) by reference, as `width`-byte integers: 4 for
 * FMI 2.0's Integer (the counters saturate at INT32_MAX), 8 for FMI 3.0's Int64 and UInt64. */
INTERNAL Status core_get_integer(Instance *inst, const char *function, const unsigned int vr[], size_t n, void *value,
                                 int width);
INTERNAL Status core_set_integer(Instance *inst, const char *function, const unsigned int vr[], size_t n,
                                 const void *value, int width);
INTERNAL Status core_no_such_variables(Instance *inst, const char *function, size_t n, const unsigned int vr[],
                                       const char *type);
/* FMU states: `state` points to the importer's handle (NULL or one this FMU made). */
INTERNAL Status core_get_state(Instance *inst, const char *function, void **state);
INTERNAL Status core_set_state(Instance *inst, const char *function, const void *state);
INTERNAL Status core_free_state(Instance *inst, const char *function, void **state);
INTERNAL Status core_serialized_size(Instance *inst, const char *function, const void *state, size_t *size);
INTERNAL Status core_serialize(Instance *inst, const char *function, const void *state, unsigned char *out,
                               size_t size);
INTERNAL Status core_deserialize(Instance *inst, const char *function, const unsigned char *in, size_t size,
                                 void **state);
/* Model Exchange */
INTERNAL Status core_set_time(Instance *inst, const char *function, double time);
INTERNAL Status core_set_continuous_states(Instance *inst, const char *function, const double x[], size_t n);
INTERNAL Status core_get_derivatives(Instance *inst, const char *function, double dx[], size_t n);
INTERNAL Status core_get_continuous_states(Instance *inst, const char *function, double x[], size_t n);
/* Event indicators (one per constraint) and the event handling of event mode: impacts, activations, releases;
 * states_changed is set where the continuous states or the active constraints changed. */
INTERNAL Status core_get_event_indicators(Instance *inst, const char *function, double z[], size_t n);
INTERNAL Status core_new_discrete_states(Instance *inst, const char *function, int *states_changed);
INTERNAL Status core_get_nominals(Instance *inst, const char *function, double nominal[], size_t n);
/* Co-Simulation: first derivatives of inputs and outputs (`orders` must all be 1), the step itself. */
INTERNAL Status core_set_input_derivatives(Instance *inst, const char *function, const unsigned int vr[], size_t n,
                                           const int32_t orders[], const double value[]);
INTERNAL Status core_get_output_derivatives(Instance *inst, const char *function, const unsigned int vr[], size_t n,
                                            const int32_t orders[], double value[]);
INTERNAL Status core_do_step(Instance *inst, const char *function, double t, double H);
/* The index of the Real input with value reference vr among the inputs, or -1. */
INTERNAL int core_input_index(unsigned int vr);
/* Partial derivatives of state derivatives and continuous outputs (the unknowns) with respect to
 * states and inputs (the knowns), from the model's exact Jacobian: directional, J seed (seed per
 * known, sensitivity per unknown), and adjoint, seed^T J (seed per unknown, sensitivity per known). */
INTERNAL Status core_get_directional_derivative(Instance *inst, const char *function, const unsigned int unknown[],
                                                size_t n_unknown, const unsigned int known[], size_t n_known,
                                                const double seed[], double sensitivity[]);
INTERNAL Status core_get_adjoint_derivative(Instance *inst, const char *function, const unsigned int unknown[],
                                            size_t n_unknown, const unsigned int known[], size_t n_known,
                                            const double seed[], double sensitivity[]);
INTERNAL const char *core_state_name(const Instance *inst, int state);
INTERNAL void core_describe_states(const Instance *inst, unsigned mask, char *text, size_t size);

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
#if N_STATES > 0
/* The state derivatives (after the states in real[]) for the inputs u (NULL: all zero), then model_outputs: one
 * function, so that each sine and cosine the two share is computed once. */
INTERNAL int model_evaluate(const ModelConst *c, double t, const double *u, double *real);
#endif
/* rate[vr] = exact time derivative of every Real output vr; du are the input derivatives. */
INTERNAL void model_output_rates(const ModelConst *c, double t, const double *real, const double *dx, const double *du,
                                 double *rate);
/* The exact Jacobian times a seed: for a change seed_x of the states and seed_u of the inputs at the
 * state in real[] (dx its derivatives, NULL without states), the change ddx of the state
 * derivatives and change[vr] of every calculated Real output. */
INTERNAL void model_directional(const ModelConst *c, double t, const double *real, const double *dx,
                                const double *seed_x, const double *seed_u, double *ddx, double *change);
/* Advance the inputs over a step of H using their derivatives (and, for positions, velocities). */
INTERNAL void model_advance_inputs(double *real, const double *du, double H);
#if N_STATES > 0
/* Taylor coefficients 1 ... order of the state (x[i][0] given) at t, u0 (NULL: no forces) and du the
 * inputs and their rates there, w the work series; 0 where the mass matrix is not positive definite. The
 * arrays do not overlap (restrict): the compiler keeps what it loaded across the stores to the series. */
INTERNAL int model_taylor(const ModelConst *restrict c, double t, const double *restrict u0, const double *restrict du,
                          int order, double (*restrict x)[TAYLOR_SLOTS], double (*restrict w)[TAYLOR_SLOTS]);
#endif

#if N_CONSTRAINTS > 0
/* physics.c of an object with constraints: g, G = dg/dq (row-major), g' and gamma = g'' - G a at (t, x); the
 * mass matrix (row-major). */
INTERNAL void model_constraints(const ModelConst *c, double t, const double *x, double *g, double *G, double *rate,
                                double *gamma);
INTERNAL void model_gaps(const ModelConst *c, double t, const double *x, double *g); /* g alone */
INTERNAL void model_gap_rates(const ModelConst *c, double t, const double *x, double *g, double *rate); /* g, g' */
INTERNAL void model_mass(const ModelConst *c, double t, const double *x, double *M);
/* constraints.c. The accelerations dx[N_COORDINATES...] of the free motion get the constraint forces of
 * `active` (bits of the rigid unilateral constraints) and of the compliant ones; lambda (NULL: not
 * wanted) receives every constraint's force. 0 where the constraints are dependent. */
INTERNAL int constraint_forces(const ModelConst *c, int32_t active, double t, const double *x, double *dx,
                               double *lambda);
#if N_COMPLIANT > 0
/* constraints.c. The compliant contacts' part of J = df/dx at (t, x), added to J (row-major, N_STATES square): each
 * pushing contact's force changes with its gap and the gap's rate, M^-1 G^T dF/dg G and M^-1 G^T dF/dg' G (the
 * changes of G and M along the motion left out, small against the stiffness). */
INTERNAL void compliant_jacobian(const ModelConst *c, double t, const double *x, double *J);
/* An upper bound of the angular frequency the compliant contacts will oscillate at from (t, x), into omega: the root
 * of the sum over the contacts that overlap, or close within `horizon` at their present rate, of dF/d(depth)
 * G M^-1 G^T at the depth where each will stop (the trace of M^-1 K, at least its largest eigenvalue; their damping left out), 0 where none does.
 * Returns the stiffest contact's index, or -1. */
INTERNAL int compliant_frequency(const ModelConst *c, double t, const double *x, double horizon, double *omega);
#endif
/* Event indicators: the gap of an inactive or compliant constraint, the force of an active one, 1 for a
 * bilateral one; u the inputs (NULL: none). Returns whether it solved for the forces (an evaluation). */
INTERNAL int constraint_indicators(const ModelConst *c, int32_t active, double t, const double *x, const double *u,
                                   double *z);
/* The event indicators Model Exchange hands out: constraint_indicators, an inactive rigid gap's just past contact. */
INTERNAL void event_indicators(const ModelConst *c, int32_t active, double t, const double *x, const double *u,
                               double *z);
/* Whether indicator i's change from `before` to `after` is an event. */
INTERNAL int indicator_crossed(const ModelConst *c, int i, double before, double after);
/* The acting rigid constraints back to g = 0 and g' = 0 (the drift of a step). */
INTERNAL int project_constraints(const ModelConst *c, int32_t active, double t, double *x);
/* An event: the state projected onto the constraints that held up to it; impacts (Newton's restitution,
 * simultaneous ones one contact at a time until none approaches), then activations and releases (velocities
 * jump, positions stay; counted into events); the state projected onto the constraints that hold after it. 0 where the constraints are dependent. */
INTERNAL int handle_event(const ModelConst *c, int32_t *active, double t, double *x, const double *u, uint64_t *events);
/* Whether rigid unilateral constraint i touches without approaching and its force would not push: the exact
 * motion leaves it (a string gone slack, a ball lifting off), so a step's dip across it is the method's error,
 * not an event. */
INTERNAL int constraint_departs(const ModelConst *c, int32_t active, int i, double t, const double *x, const double *u);
/* Whether a rigid constraint acts in `active` while `solver` integrates free motion only (FREE_MOTION_ONLY: taylor,
 * stormer_verlet); if so, says which and why in `message`: acting `when` ("at the start", "from"), at time t
 * (NAN: none). Costs nothing but the test where it refuses nothing. */
INTERNAL int free_motion_refused(int solver, int32_t active, const char *when, double t, char *message, size_t size);
/* Those of `departing` that the step left below g = 0 back onto it, their approaching rates to zero. */
INTERNAL int leave_boundary(const ModelConst *c, int32_t active, int32_t departing, double t, double *x);
/* The start values against the rigid constraints (0 with a message naming the one violated) and the
 * constraints active from the start. */
INTERNAL int start_constraints(const ModelConst *c, int32_t *active, double t, double *x, const double *u,
                               char *message, size_t size);
/* model_outputs' and model_output_rates' part: gaps, forces, the compliant energies in E_pot and E. */
INTERNAL int constraint_outputs(const ModelConst *c, double t, const double *u, double *real);
INTERNAL void constraint_output_rates(const ModelConst *c, double t, const double *real, const double *dx,
                                      const double *u, double *rate);
#endif

#if N_CONSTRAINTS == 0 && N_EVENT_INDICATORS > 0
/* physics.c of a hand-written model with event indicators (the Contact): z at time t from the inputs and
 * parameters in real[]. Its events change no state: they tell Model Exchange where the outputs' law changes. */
INTERNAL void model_event_indicators(const ModelConst *c, double t, const double *real, double *z);
#endif

/* Default for model_advance_inputs (instance.c): each input moves with its own first derivative. */
INTERNAL void advance_inputs_linearly(double *real, const double *du, double H);

#endif
