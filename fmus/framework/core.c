/* The version-neutral core of the FMI API: start values, variable access with its checks, derived
 * constants and outputs, FMU state, Model Exchange and the Co-Simulation step. The API layers
 * (fmi2_functions.c, one file per FMI version) check each call against their version's state machine and
 * then call in here, passing their function's name for the messages. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#define MODEL_DESCRIPTION_TABLES
#include "framework.h"

/* ---------------------------------------------------------------- states and messages */

/* FMI 2.0's names; a layer of another version sets its own (Instance.state_names). */
static const char *const FMI2_STATE_NAMES[] = {"instantiated",
                                               "initializationMode",
                                               "stepComplete",
                                               "stepFailed",
                                               "eventMode",
                                               "continuousTimeMode",
                                               "terminated",
                                               "error",
                                               "intermediateUpdateMode"};

const char *core_state_name(const Instance *inst, int state)
{
    const char *const *names = inst && inst->state_names ? inst->state_names : FMI2_STATE_NAMES;
    int bit;
    for (bit = 0; (1 << bit) <= MS_LAST; bit++)
        if (state == 1 << bit) return names[bit];
    return "unknown";
}

void core_describe_states(const Instance *inst, unsigned mask, char *text, size_t size)
{
    unsigned bit;
    text[0] = '\0';
    for (bit = 1; bit <= MS_LAST; bit <<= 1) {
        if (mask & bit) {
            size_t used = strlen(text);
            snprintf(text + used, size - used, "%s%s", used ? ", " : "", core_state_name(inst, (int)bit));
        }
    }
    if (!text[0]) snprintf(text, size, "none");
}

/* Apart from core_call_allowed, so that an allowed call sets up no message buffer. */
#if defined(__GNUC__) || defined(__clang__)
__attribute__((noinline, cold))
#endif
static int refuse_call(Instance *inst, const char *function, unsigned mask)
{
    char allowed[256];
    core_describe_states(inst, mask, allowed, sizeof allowed);
    log_error(inst, "%s: illegal call sequence: not allowed in state %s for %s (allowed in: %s)", function,
              core_state_name(inst, inst->s.machine_state),
              inst->type == INTERFACE_CO_SIMULATION ? "Co-Simulation" : "Model Exchange", allowed);
    return 0;
}

int core_call_allowed(Instance *inst, const char *function, unsigned cs, unsigned me)
{
    const unsigned mask = inst->type == INTERFACE_CO_SIMULATION ? cs : me;
    if (mask & (unsigned)inst->s.machine_state) return 1;
    return refuse_call(inst, function, mask);
}

Status core_set_logging(Instance *inst, const char *function, int on, size_t n, const char *const categories[])
{
    static const char *const known[] = {"logStatusError", "logStatusWarning", "logStatusDiscard", "logAll"};
    size_t i, k;
    if (!core_arrays_present(inst, function, n, categories, categories)) return STATUS_ERROR;
    for (i = 0; i < n; i++) {
        int found = 0;
        for (k = 0; k < sizeof known / sizeof known[0]; k++)
            if (categories[i] && strcmp(categories[i], known[k]) == 0) found = 1;
        if (!found) {
            log_error(inst,
                      "%s: unknown log category %s (known: logStatusError, logStatusWarning, "
                      "logStatusDiscard, logAll)",
                      function, categories[i] ? categories[i] : "NULL");
            return STATUS_ERROR;
        }
    }
    inst->logging_on = on ? 1 : 0;
    return STATUS_OK;
}

int core_arrays_present(Instance *inst, const char *function, size_t n, const void *a, const void *b)
{
    if (n > 0 && (!a || !b)) {
        log_error(inst, "%s: NULL array for %lu values", function, (unsigned long)n);
        return 0;
    }
    return 1;
}

/* ---------------------------------------------------------------- start values and derived data */

void core_reset(Instance *inst)
{
    int i;
    memset(&inst->s, 0, sizeof inst->s);
    for (i = 0; i < N_REAL; i++)
        if (REAL_VARIABLES[i].has_start) inst->s.real[i] = REAL_VARIABLES[i].start;
#if N_INTEGER > 0
    for (i = 0; i < N_INTEGER; i++)
        if (INTEGER_VARIABLES[i].has_start) inst->s.integer[i] = (int32_t)INTEGER_VARIABLES[i].start;
#endif
    inst->s.machine_state = MS_INSTANTIATED;
    inst->constants_valid = 0;
    inst->outputs_valid = 0;
    inst->derivatives_current = 0;
}
/* model_prepare guarded by the cross-parameter checks, so that no output can become NaN. */
static int ensure_constants(Instance *inst, const char *function)
{
    char message[1024];
    if (inst->constants_valid) return 1;
    if (model_prepare(inst->s.real, inst->s.integer, &inst->constants, message, sizeof message)) {
        log_error(inst, "%s: %s", function, message);
        return 0;
    }
#if N_CONSTRAINTS > 0
    inst->constants.active = &inst->s.active_constraints; /* the instance never moves */
#endif
    inst->constants_valid = 1;
    inst->substep_work = 0.0; /* the method or its settings may have changed with them */
    return 1;
}

/* The state derivatives (which follow the states in real[]) and the calculated outputs for the states,
 * parameters and inputs in real[]; Discard where they are undefined or not finite. */
static Status compute_outputs(Instance *inst, const char *function, double *real)
{
    int bad, defined;
#if N_STATES > 0
    {
        double u[INPUT_SLOTS];
        gather_inputs(inst, u);
        defined = model_evaluate(&inst->constants, inst->s.time, u, real); /* der(x) follow the states */
    }
#else
    defined = model_outputs(&inst->constants, inst->s.time, NULL, real);
#endif
    if (!defined) {
        log_discard(inst, "%s: the outputs are undefined in the current (singular) configuration", function);
        return STATUS_DISCARD;
    }
    bad = computed_finite(real) ? -1 : first_non_finite(real, N_REAL);
    if (bad >= 0) {
        log_discard(inst, "%s: %s is not finite for the current inputs and states", function, REAL_VARIABLES[bad].name);
        return STATUS_DISCARD;
    }
    return STATUS_OK;
}

/* Calculated outputs and state derivatives, computed only when someone reads them. */
static Status ensure_outputs(Instance *inst, const char *function)
{
    Status status;
    if (inst->outputs_valid) return STATUS_OK;
    if (!ensure_constants(inst, function)) return STATUS_ERROR;
    status = compute_outputs(inst, function, inst->s.real);
    /* In Model Exchange these are the importer's solver's evaluations; in Co-Simulation the
       integrator counts its own and this one only serves the outputs. */
    if (N_STATES > 0 && inst->type == INTERFACE_MODEL_EXCHANGE) inst->s.integrator.n_rhs++;
    if (status != STATUS_OK) return status;
    inst->outputs_valid = 1;
    inst->derivatives_current = 0; /* evaluated with the inputs as an array, not as a step evaluates them */
    return STATUS_OK;
}

static int input_index(unsigned int vr)
{
#if N_INPUTS > 0
    int i;
    for (i = 0; i < N_INPUTS; i++)
        if (INPUT_VRS[i] == vr) return i;
#else
    (void)vr;
#endif
    return -1;
}

int core_input_index(unsigned int vr) { return input_index(vr); }

/* ---------------------------------------------------------------- life cycle */

Instance *core_instantiate(const char *function, Interface type, const char *name, const char *token, MessageSink emit,
                           void (*api_logger)(void), void *environment, void *(*allocate)(size_t, size_t),
                           void (*release)(void *), int logging_on)
{
    Instance *inst;
    Instance reporter; /* logs before an instance exists */
    size_t length;
    memset(&reporter, 0, sizeof reporter);
    reporter.emit = emit;
    reporter.api_logger = api_logger;
    reporter.environment = environment;
    reporter.name = (char *)(name ? name : "?");
    if (!allocate || !release) {
        log_error(&reporter, "%s: callback functions allocateMemory and freeMemory are required", function);
        return NULL;
    }
    if (!name || !name[0]) {
        log_error(&reporter, "%s: instanceName must be a non-empty string", function);
        return NULL;
    }
    if (!token || strcmp(token, MODEL_GUID) != 0) {
        log_error(&reporter, "%s: fmuGUID = %s does not match this FMU (%s, GUID %s)", function, token ? token : "NULL",
                  MODEL_IDENTIFIER_STRING, MODEL_GUID);
        return NULL;
    }
    inst = (Instance *)allocate(1, sizeof(Instance));
    if (!inst) {
        log_error(&reporter, "%s: out of memory", function);
        return NULL;
    }
    memset(inst, 0, sizeof *inst);
    length = strlen(name) + 1;
    inst->name = (char *)allocate(length, 1);
    if (!inst->name) {
        release(inst);
        log_error(&reporter, "%s: out of memory", function);
        return NULL;
    }
    memcpy(inst->name, name, length);
    inst->type = type;
    inst->emit = emit;
    inst->api_logger = api_logger;
    inst->allocate = allocate;
    inst->release = release;
    inst->environment = environment;
    inst->logging_on = logging_on ? 1 : 0;
    core_reset(inst);
    return inst;
}

void core_free(Instance *inst)
{
    if (!inst) return;
    if (inst->taylor_work) inst->release(inst->taylor_work);
    inst->release(inst->name);
    inst->release(inst);
}

Status core_setup(Instance *inst, const char *function, double start, int stop_defined, double stop)
{
    if (!isfinite(start)) {
        log_error(inst, "%s: startTime = %g must be a finite number", function, start);
        return STATUS_ERROR;
    }
    if (stop_defined && !(stop >= start)) {
        log_error(inst, "%s: stopTime = %g must not be before startTime = %g", function, stop, start);
        return STATUS_ERROR;
    }
    inst->s.time = start;
    inst->s.last_successful_time = start;
    return STATUS_OK;
}

#if N_CONSTRAINTS > 0
/* The current inputs in u, returned where any force acts, NULL where none does (the models' convention). */
static const double *acting_inputs(const Instance *inst, double *u)
{
    int i;
    gather_inputs(inst, u);
    for (i = 0; i < N_INPUTS; i++)
        if (u[i] != 0.0) return u;
    return NULL;
}
#endif

#if N_STATES > 0
/* Whether the states in inst->s (`what`: where they come from) are ones to start from: regular, with finite
 * derivatives and outputs; logs why not. */
static int states_usable(Instance *inst, const char *function, const char *what)
{
    char reason[1024], states[256];
    size_t used = 0;
    int i, k;
    if (state_acceptable(inst, inst->s.time, inst->s.real)) return 1;
    k = first_non_finite_at(inst, inst->s.time, inst->s.real);
    for (i = 0; i < N_STATES && used < sizeof states; i++) /* each state named, cut at the buffer's end */
        used += (size_t)snprintf(states + used, sizeof states - used, "%s%s = %g", i ? ", " : "",
                                 REAL_VARIABLES[i].name, inst->s.real[i]);
    if (model_explain_singularity(&inst->constants, inst->s.time, inst->s.real, reason, sizeof reason))
        log_error(inst, "%s: %s are refused: %s", function, what, reason);
    else if (k >= 0)
        log_error(inst, "%s: %s (%s) make %s not finite (allowed: states with finite derivatives and outputs)",
                  function, what, states, REAL_VARIABLES[k].name);
    else
        log_error(inst, "%s: %s (%s) give a singular configuration", function, what, states);
    return 0;
}
#endif

Status core_exit_initialization(Instance *inst, const char *function)
{
    inst->constants_valid = 0;
    if (!ensure_constants(inst, function)) return STATUS_ERROR;
#if N_STATES > 0
    if (!states_usable(inst, function, "the start values of the states")) return STATUS_ERROR;
#else
    { /* without states, the outputs decide: the same promise as the models with states */
        double real[N_REAL];
        memcpy(real, inst->s.real, sizeof real);
        if (!model_outputs(&inst->constants, inst->s.time, NULL, real) || first_non_finite(real, N_REAL) >= 0) {
            log_error(inst,
                      "%s: the start values of the inputs give a singular configuration "
                      "or non-finite outputs",
                      function);
            return STATUS_ERROR;
        }
    }
#endif
#if N_CONSTRAINTS > 0
    {
        char message[256];
        double u[INPUT_SLOTS];
        if (!start_constraints(&inst->constants, &inst->s.active_constraints, inst->s.time, inst->s.real,
                               acting_inputs(inst, u), message, sizeof message) ||
            (inst->type == INTERFACE_CO_SIMULATION &&
             free_motion_refused(inst->s.integer[INT_solver], inst->s.active_constraints, "at the start", NAN, message,
                                 sizeof message))) {
            log_error(inst, "%s: %s", function, message);
            return STATUS_ERROR;
        }
    }
#endif
    memset(&inst->s.integrator, 0, sizeof inst->s.integrator); /* counters count from here */
    restart_integrator(inst);
    inst->s.last_successful_time = inst->s.time;
    inst->outputs_valid = 0;
    inst->s.machine_state = inst->type == INTERFACE_CO_SIMULATION ? MS_STEP_COMPLETE : MS_EVENT;
    return STATUS_OK;
}

/* ---------------------------------------------------------------- variable access */

static unsigned settable_in(const VariableInfo *v)
{
    if (v->causality == CAUSALITY_PARAMETER) {
        return v->variability == VARIABILITY_TUNABLE ? MS_INSTANTIATED | MS_INITIALIZATION | MS_STEP_COMPLETE | MS_EVENT
                                                     : MS_INSTANTIATED | MS_INITIALIZATION;
    }
    if (v->causality == CAUSALITY_INPUT)
        return MS_INSTANTIATED | MS_INITIALIZATION | MS_STEP_COMPLETE | MS_EVENT | MS_CONTINUOUS;
    if (v->causality == CAUSALITY_OUTPUT && v->initial != INITIAL_CALCULATED)
        return MS_INSTANTIATED | MS_INITIALIZATION;
    return 0;
}

static const char *kind_of(const VariableInfo *v)
{
    if (v->causality == CAUSALITY_PARAMETER)
        return v->variability == VARIABILITY_TUNABLE ? "a tunable parameter" : "a fixed parameter";
    if (v->causality == CAUSALITY_INPUT) return "an input";
    if (v->causality == CAUSALITY_OUTPUT) return v->initial == INITIAL_CALCULATED ? "a calculated output" : "a state";
    return "a calculated variable";
}

/* A finite value within the variable's range; logs and returns 0 otherwise. exact: an Integer's value as set
 * (a 64-bit one is not exact as a double, and the message names it exactly), NULL for a Real. */
static int value_in_range(Instance *inst, const char *function, const VariableInfo *v, unsigned int vr, double value,
                          const int64_t *exact)
{
    if (!isfinite(value)) {
        log_error(inst, "%s: variable %s (value reference %u) = %g is not a finite number (allowed range [%g, %g])",
                  function, v->name, vr, value, v->min, v->max);
        return 0;
    }
    if (value < v->min || value > v->max) {
        if (exact)
            log_error(inst, "%s: variable %s (value reference %u) = %lld is out of its allowed range [%g, %g]",
                      function, v->name, vr, (long long)*exact, v->min, v->max);
        else
            log_error(inst, "%s: variable %s (value reference %u) = %.17g is out of its allowed range [%g, %g]",
                      function, v->name, vr, value, v->min, v->max);
        return 0;
    }
#if N_STATES > 0 && !SPLIT_ACCELERATIONS
    if (v == &INTEGER_VARIABLES[INT_solver] && value == SOLVER_STORMER_VERLET) {
        log_error(inst,
                  "%s: variable solver (value reference %u) = %d (stormer_verlet) needs accelerations of the "
                  "form a(t, q) - d v, and %s (allowed here: 1 to %d except %d; implicit_midpoint and gauss_legendre4 "
                  "are symmetric as well)",
                  function, vr, SOLVER_STORMER_VERLET, SPLIT_REASON, SOLVER_COUNT, SOLVER_STORMER_VERLET);
        return 0;
    }
#endif
#if N_STATES > 0 && !TAYLOR_AVAILABLE
    if (v == &INTEGER_VARIABLES[INT_solver] && value == SOLVER_TAYLOR) {
        log_error(inst,
                  "%s: variable solver (value reference %u) = %d (taylor) needs Taylor recurrences for every "
                  "function of the equations, and %s (allowed here: 1 to %d except %d)",
                  function, vr, SOLVER_TAYLOR, TAYLOR_REASON, SOLVER_COUNT, SOLVER_TAYLOR);
        return 0;
    }
#endif
    return 1;
}

/* Every check a value must pass before it is stored; logs and returns 0 on the first failure. */
static int value_acceptable(Instance *inst, const char *function, const VariableInfo *v, unsigned int vr, double value,
                            const int64_t *exact)
{
    /* an input also while the FMU asks for it (the layer checks which are asked for) */
    const unsigned allowed =
        settable_in(v) | (v->causality == CAUSALITY_INPUT && inst->asking_inputs ? MS_INTERMEDIATE : 0u);
    char states[256];
    if (!(allowed & (unsigned)inst->s.machine_state)) {
        core_describe_states(inst, allowed, states, sizeof states);
        log_error(inst, "%s: variable %s (value reference %u) is %s and cannot be set in state %s (settable in: %s)",
                  function, v->name, vr, kind_of(v), core_state_name(inst, inst->s.machine_state), states);
        return 0;
    }
    return value_in_range(inst, function, v, vr, value, exact);
}

/* What follows from a stored value: derived constants, integrator history, cached outputs. A parameter or
 * state set to the value it held (changed = 0) changes nothing: the integrator keeps its Adams history and
 * step proposals, which an importer setting every parameter before each step would otherwise throw away. */
static void value_stored(Instance *inst, const VariableInfo *v, unsigned int vr, int changed)
{
    if (!changed && v->causality != CAUSALITY_INPUT) return;
    if (v->causality == CAUSALITY_PARAMETER) {
        inst->constants_valid = 0;
        restart_integrator(inst); /* solver, h or tol may have changed */
    } else if (v->causality == CAUSALITY_INPUT) {
        const int k = input_index(vr);
        if (k >= 0) inst->s.input_derivative[k] = 0.0; /* setting the input again clears its slope */
        inst->derivatives_current = 0;
        /* After a step the outputs stay those of the step's end until the next step. */
        if (inst->s.machine_state == MS_STEP_COMPLETE) return;
    } else {
        restart_integrator(inst);
    }
    inst->outputs_valid = 0;
}

static int real_reference_known(Instance *inst, const char *function, unsigned int vr)
{
    if (vr < N_REAL) return 1;
    log_error(inst, "%s: unknown value reference %u (this FMU's Real variables are 0..%d)", function, vr, N_REAL - 1);
    return 0;
}

static int integer_reference_known(Instance *inst, const char *function, unsigned int vr)
{
    if (vr >= INTEGER_VR_BASE && vr < INTEGER_VR_BASE + N_INTEGER) return 1;
    if (N_INTEGER > 0)
        log_error(inst, "%s: unknown value reference %u (this FMU's Integer variables are %d..%d)", function, vr,
                  INTEGER_VR_BASE, INTEGER_VR_BASE + N_INTEGER - 1);
    else
        log_error(inst, "%s: unknown value reference %u (this FMU has no Integer variables)", function, vr);
    return 0;
}

const VariableInfo *core_variable(unsigned int vr)
{
    if (vr < N_REAL) return &REAL_VARIABLES[vr];
#if N_INTEGER > 0
    if (vr >= INTEGER_VR_BASE && vr < INTEGER_VR_BASE + N_INTEGER) return &INTEGER_VARIABLES[vr - INTEGER_VR_BASE];
#endif
    return NULL;
}

size_t core_first_not_output(const unsigned int vr[], size_t n, unsigned int also_allowed)
{
    size_t i;
    for (i = 0; i < n; i++)
        if (vr[i] != also_allowed && (vr[i] >= N_REAL || REAL_VARIABLES[vr[i]].causality != CAUSALITY_OUTPUT)) break;
    return i;
}

Status core_get_real(Instance *inst, const char *function, const unsigned int vr[], size_t nvr, double value[])
{
    Status status;
    size_t i;
    int unknown = 0;
    if (!core_arrays_present(inst, function, nvr, vr, value)) return STATUS_ERROR;
    for (i = 0; i < nvr; i++) unknown |= vr[i] >= N_REAL;
    if (unknown) /* the message names the first */
        for (i = 0; i < nvr; i++)
            if (!real_reference_known(inst, function, vr[i])) return STATUS_ERROR;
    /* Parameters, inputs and states hold what was set: reading only those needs no outputs, and stays
     * STATUS_OK where the outputs are undefined. */
    status = STATUS_OK;
    if (!inst->outputs_valid)
        for (i = 0; i < nvr; i++)
            if (!settable_in(&REAL_VARIABLES[vr[i]])) {
                status = ensure_outputs(inst, function);
                break;
            }
    if (status == STATUS_ERROR) return status;
    if (status == STATUS_OK) {
        for (i = 0; i < nvr; i++) value[i] = inst->s.real[vr[i]];
        return status;
    }
    /* With STATUS_DISCARD, values that are not finite are not handed out: those entries stay as they were. */
    for (i = 0; i < nvr; i++)
        if (isfinite(inst->s.real[vr[i]])) value[i] = inst->s.real[vr[i]];
    return status;
}

Status core_set_real(Instance *inst, const char *function, const unsigned int vr[], size_t nvr, const double value[])
{
    size_t i;
    if (!core_arrays_present(inst, function, nvr, vr, value)) return STATUS_ERROR;
    /* All values are checked before any is stored: a rejected call changes nothing. */
    for (i = 0; i < nvr; i++) {
        if (!real_reference_known(inst, function, vr[i])) return STATUS_ERROR;
        if (!value_acceptable(inst, function, &REAL_VARIABLES[vr[i]], vr[i], value[i], NULL)) return STATUS_ERROR;
    }
    for (i = 0; i < nvr; i++) {
        const int changed = memcmp(&inst->s.real[vr[i]], &value[i], sizeof value[i]) != 0; /* -0.0 is a change */
        inst->s.real[vr[i]] = value[i];
        value_stored(inst, &REAL_VARIABLES[vr[i]], vr[i], changed);
    }
    return STATUS_OK;
}

static int64_t integer_at(const void *values, int width, size_t i)
{
    return width == 4 ? (int64_t)((const int32_t *)values)[i] : ((const int64_t *)values)[i];
}

Status core_get_integer(Instance *inst, const char *function, const unsigned int vr[], size_t nvr, void *value,
                        int width)
{
    const int64_t most = width == 4 ? INT32_MAX : INT64_MAX;
    size_t i;
    if (!core_arrays_present(inst, function, nvr, vr, value)) return STATUS_ERROR;
    for (i = 0; i < nvr; i++)
        if (!integer_reference_known(inst, function, vr[i])) return STATUS_ERROR;
    for (i = 0; i < nvr; i++) {
        const int k = (int)(vr[i] - INTEGER_VR_BASE);
        int64_t number = inst->s.integer[k];
#if N_STATES > 0
        const IntegratorMemory *m = &inst->s.integrator;
        uint64_t counter = 0;
        int is_counter = 1;
        if (k == INT_n_rhs)
            counter = m->n_rhs;
        else if (k == INT_n_steps)
            counter = m->n_steps;
        else if (k == INT_n_rejected)
            counter = m->n_rejected;
        else if (k == INT_n_jacobians)
            counter = m->n_jacobians;
        else if (k == INT_n_iterations)
            counter = m->n_iterations;
#ifdef INT_n_events
        else if (k == INT_n_events)
            counter = m->n_events;
#endif
        else
            is_counter = 0;
        if (is_counter) number = counter > (uint64_t)most ? most : (int64_t)counter; /* saturates */
#else
        (void)most;
#endif
        if (width == 4)
            ((int32_t *)value)[i] = (int32_t)number;
        else
            ((int64_t *)value)[i] = number;
    }
    return STATUS_OK;
}

Status core_set_integer(Instance *inst, const char *function, const unsigned int vr[], size_t nvr, const void *value,
                        int width)
{
    size_t i;
    if (!core_arrays_present(inst, function, nvr, vr, value)) return STATUS_ERROR;
    for (i = 0; i < nvr; i++) {
        if (!integer_reference_known(inst, function, vr[i])) return STATUS_ERROR;
#if N_INTEGER > 0
        const int64_t number = integer_at(value, width, i);
        if (!value_acceptable(inst, function, &INTEGER_VARIABLES[vr[i] - INTEGER_VR_BASE], vr[i], (double)number,
                              &number))
            return STATUS_ERROR;
#endif
    }
#if N_INTEGER > 0
    for (i = 0; i < nvr; i++) { /* within the variable's range, so within int32 */
        const int32_t number = (int32_t)integer_at(value, width, i);
        const int changed = inst->s.integer[vr[i] - INTEGER_VR_BASE] != number;
        inst->s.integer[vr[i] - INTEGER_VR_BASE] = number;
        value_stored(inst, &INTEGER_VARIABLES[vr[i] - INTEGER_VR_BASE], vr[i], changed);
    }
#else
    (void)integer_at;
#endif
    return STATUS_OK;
}

Status core_no_such_variables(Instance *inst, const char *function, size_t nvr, const unsigned int vr[],
                              const char *type)
{
    if (nvr == 0) return STATUS_OK;
    log_error(inst, "%s: unknown value reference %u (this FMU has no %s variables)", function, vr ? vr[0] : 0u, type);
    return STATUS_ERROR;
}

/* ---------------------------------------------------------------- FMU state */

#define STATE_MAGIC 0x4d554650u /* "PFUM" */
#define STATE_FORMAT 1u
#define GUID_SLOT 48

typedef struct {
    uint32_t magic;
    uint32_t format;
    char guid[GUID_SLOT];
    SimState s;
} StoredState;

static int state_is_ours(Instance *inst, const char *function, const StoredState *stored)
{
    if (stored->magic != STATE_MAGIC || stored->format != STATE_FORMAT) {
        log_error(inst, "%s: the FMU state was not made by this FMU (%s)", function, MODEL_IDENTIFIER_STRING);
        return 0;
    }
    if (strncmp(stored->guid, MODEL_GUID, GUID_SLOT) != 0) {
        log_error(inst, "%s: the FMU state belongs to another FMU (GUID %.48s, this FMU is %s)", function, stored->guid,
                  MODEL_GUID);
        return 0;
    }
    return 1;
}

/* Where a state goes: the importer's handle, if it is one of ours, or new zeroed memory; NULL (logged)
 * otherwise. */
static StoredState *state_slot(Instance *inst, const char *function, void *handle)
{
    StoredState *stored = (StoredState *)handle;
    if (stored) return state_is_ours(inst, function, stored) ? stored : NULL;
    stored = (StoredState *)inst->allocate(1, sizeof(StoredState));
    if (!stored) {
        log_error(inst, "%s: out of memory", function);
        return NULL;
    }
    memset(stored, 0, sizeof *stored);
    return stored;
}

Status core_get_state(Instance *inst, const char *function, void **FMUstate)
{
    StoredState *stored;
    if (!FMUstate) {
        log_error(inst, "%s: FMUstate pointer is NULL", function);
        return STATUS_ERROR;
    }
    stored = state_slot(inst, function, *FMUstate);
    if (!stored) return STATUS_ERROR;
    if (!*FMUstate) {
        stored->magic = STATE_MAGIC;
        stored->format = STATE_FORMAT;
        strncpy(stored->guid, MODEL_GUID, GUID_SLOT - 1);
    }
    stored->s = inst->s;
    *FMUstate = stored;
    return STATUS_OK;
}

static int machine_state_fits(const Instance *inst, int32_t state)
{
    const unsigned valid = inst->type == INTERFACE_CO_SIMULATION ? CS_ANY : ME_ANY;
    return state != 0 && (state & (state - 1)) == 0 && ((unsigned)state & valid) && state != MS_INTERMEDIATE;
}

/* A deserialized state passes the setters' checks: every value a user can set (parameters, inputs,
 * states) finite and in range, the parameters consistent together, and the framework's own numbers
 * (time, machine state, integrator memory) sane. Logs the first problem. */
/* The integrator memory of a deserialized state: each field in its range, or a message naming the first that is
 * not. */
static int integrator_memory_refused(Instance *inst, const char *function, const IntegratorMemory *m)
{
#if N_STATES > 0
    const int gbs_columns_ok = m->gbs_columns == 0 || (m->gbs_columns >= 2 && m->gbs_columns < GBS_MAX_COLUMNS);
    const int gbs_top = GBS_MAX_COLUMNS - 1;
#else
    const int gbs_columns_ok = m->gbs_columns == 0, gbs_top = 0;
#endif
    const char *field = NULL, *allowed = "";
    double value = 0.0;
    if (m->ab_count < 0 || m->ab_count > AB_MAX_STEPS)
        field = "Adams-Bashforth history length", value = m->ab_count, allowed = "[0, AB_MAX_STEPS]";
    else if (m->ab_head < 0 || m->ab_head >= AB_MAX_STEPS)
        field = "Adams-Bashforth history position", value = m->ab_head, allowed = "[0, AB_MAX_STEPS - 1]";
    else if (!isfinite(m->ab_step))
        field = "Adams-Bashforth step", value = m->ab_step, allowed = "finite";
    else if (m->ab_restarted != 0 && m->ab_restarted != 1)
        field = "Adams-Bashforth restart flag", value = m->ab_restarted, allowed = "0 or 1";
    else if (!(m->step_proposal >= 0.0) || !isfinite(m->step_proposal))
        field = "step size proposal", value = m->step_proposal, allowed = "[0, inf), finite";
    else if (!gbs_columns_ok)
        field = "gbs column proposal", value = m->gbs_columns, allowed = "0, or [2, GBS_MAX_COLUMNS - 1]";
    else if (m->gbs_rejected != 0 && m->gbs_rejected != 1)
        field = "gbs rejection flag", value = m->gbs_rejected, allowed = "0 or 1";
    if (!field) return 0;
    log_error(inst,
              "%s: the FMU state's integrator memory is invalid: its %s is %g (allowed: %s, AB_MAX_STEPS = %d, "
              "GBS_MAX_COLUMNS - 1 = %d)",
              function, field, value, allowed, AB_MAX_STEPS, gbs_top);
    return 1;
}

static int restored_state_valid(Instance *inst, const char *function, const SimState *s)
{
    char message[1024];
    ModelConst constants;
    int i;
    if (!isfinite(s->time) || !isfinite(s->last_successful_time)) {
        log_error(inst, "%s: the FMU state's %s is %g (allowed: a finite time)", function,
                  isfinite(s->time) ? "last successful time" : "time",
                  isfinite(s->time) ? s->last_successful_time : s->time);
        return 0;
    }
    if (!machine_state_fits(inst, s->machine_state)) {
        log_error(inst, "%s: the FMU state's machine state is %d (allowed: one bit of a %s state, 0x%x)", function,
                  (int)s->machine_state, inst->type == INTERFACE_CO_SIMULATION ? "Co-Simulation" : "Model Exchange",
                  inst->type == INTERFACE_CO_SIMULATION ? (unsigned)CS_ANY : (unsigned)ME_ANY);
        return 0;
    }
    for (i = 0; i < N_REAL; i++)
        if (settable_in(&REAL_VARIABLES[i]) &&
            !value_in_range(inst, function, &REAL_VARIABLES[i], (unsigned int)i, s->real[i], NULL))
            return 0;
#if N_INTEGER > 0
    for (i = 0; i < N_INTEGER; i++)
        if (INTEGER_VARIABLES[i].causality == CAUSALITY_PARAMETER &&
            !value_in_range(inst, function, &INTEGER_VARIABLES[i], (unsigned int)(INTEGER_VR_BASE + i), s->integer[i],
                            &(int64_t){s->integer[i]}))
            return 0;
#endif
    if (s->slopes_set != 0 && s->slopes_set != 1) {
        log_error(inst, "%s: the FMU state's input slope flag is %d (allowed: 0 or 1)", function, (int)s->slopes_set);
        return 0;
    }
#if N_INPUTS > 0
    for (i = 0; i < N_INPUTS; i++)
        if (!isfinite(s->input_derivative[i])) {
            log_error(inst, "%s: the FMU state's derivative of input %s is not finite", function,
                      REAL_VARIABLES[INPUT_VRS[i]].name);
            return 0;
        }
#endif
    if (integrator_memory_refused(inst, function, &s->integrator)) return 0;
    if (first_non_finite(&s->integrator.ab_history[0][0], AB_MAX_STEPS * STATE_SLOTS) >= 0) {
        log_error(inst, "%s: the FMU state's Adams-Bashforth history holds a non-finite value", function);
        return 0;
    }
    if (model_prepare(s->real, s->integer, &constants, message, sizeof message)) {
        log_error(inst, "%s: %s", function, message);
        return 0;
    }
#if N_STATES > 0
    { /* its states checked as initialization checks start values (omega = 1e200 makes E_kin overflow) */
        const SimState kept = inst->s;
        const ModelConst kept_constants = inst->constants;
        const int kept_valid = inst->constants_valid, kept_outputs = inst->outputs_valid;
        int usable;
        inst->s = *s;
        inst->s.machine_state = MS_INITIALIZATION; /* no intermediate-step report from the check */
        inst->constants = constants;
#if N_CONSTRAINTS > 0
        inst->constants.active = &inst->s.active_constraints;
#endif
        inst->constants_valid = 1;
        usable = states_usable(inst, function, "the FMU state's states");
        inst->s = kept;
        inst->constants = kept_constants;
        inst->constants_valid = kept_valid;
        inst->outputs_valid = kept_outputs;
        if (!usable) return 0;
    }
#endif
#if N_CONSTRAINTS > 0
    for (i = 0; i < N_CONSTRAINTS; i++)
        if ((s->active_constraints >> i & 1) && constants.law[i].bilateral) break;
    if (i < N_CONSTRAINTS || (s->active_constraints >> N_CONSTRAINTS) != 0) {
        log_error(inst,
                  "%s: the FMU state's active constraints 0x%x name a constraint that cannot be active (allowed: "
                  "a bit for each of the %d unilateral constraints, rigid or compliant)",
                  function, (unsigned)s->active_constraints, N_CONSTRAINTS);
        return 0;
    }
#else
    if (s->active_constraints != 0) {
        log_error(inst, "%s: the FMU state's active constraints are %d, but this FMU has no constraints", function,
                  (int)s->active_constraints);
        return 0;
    }
#endif
    return 1;
}

Status core_set_state(Instance *inst, const char *function, const void *FMUstate)
{
    const StoredState *stored = (const StoredState *)FMUstate;
    if (!stored) {
        log_error(inst, "%s: FMUstate is NULL", function);
        return STATUS_ERROR;
    }
    if (!state_is_ours(inst, function, stored)) return STATUS_ERROR;
    if (!machine_state_fits(inst, stored->s.machine_state)) {
        log_error(inst, "%s: the FMU state was taken from a %s instance, this one is %s", function,
                  inst->type == INTERFACE_CO_SIMULATION ? "Model Exchange" : "Co-Simulation",
                  inst->type == INTERFACE_CO_SIMULATION ? "Co-Simulation" : "Model Exchange");
        return STATUS_ERROR;
    }
    /* An in-memory state was made by this FMU's core_get_state from checked values: no second check here,
     * where masters roll back every iteration (a deserialized one is checked, it comes from outside). */
    inst->s = stored->s;
    /* A restored state is a good state: a failed step is behind it. */
    if (inst->s.machine_state == MS_STEP_FAILED) inst->s.machine_state = MS_STEP_COMPLETE;
    inst->constants_valid = 0;
    inst->outputs_valid = 0;
    return STATUS_OK;
}

Status core_free_state(Instance *inst, const char *function, void **FMUstate)
{
    if (!FMUstate) {
        log_error(inst, "%s: FMUstate pointer is NULL", function);
        return STATUS_ERROR;
    }
    if (*FMUstate) {
        if (!state_is_ours(inst, function, (const StoredState *)*FMUstate)) return STATUS_ERROR;
        ((StoredState *)*FMUstate)->magic = 0; /* a second free of the same state is caught */
        inst->release(*FMUstate);
        *FMUstate = NULL;
    }
    return STATUS_OK;
}

/* Serialized layout: magic, format, size (8 bytes), GUID (48 bytes), SimState, FNV-1a checksum of all
 * that precedes it (8 bytes). The SimState holds numbers only. */
#define SERIAL_HEADER (4 + 4 + 8 + GUID_SLOT)
#define SERIAL_SIZE (SERIAL_HEADER + sizeof(SimState) + 8)

static uint64_t checksum(const unsigned char *bytes, size_t n)
{
    uint64_t hash = 1469598103934665603ull;
    size_t i;
    for (i = 0; i < n; i++) {
        hash ^= bytes[i];
        hash *= 1099511628211ull;
    }
    return hash;
}

Status core_serialized_size(Instance *inst, const char *function, const void *FMUstate, size_t *size)
{
    if (!FMUstate || !size) {
        log_error(inst, "%s: FMUstate and size must not be NULL", function);
        return STATUS_ERROR;
    }
    if (!state_is_ours(inst, function, (const StoredState *)FMUstate)) return STATUS_ERROR;
    *size = SERIAL_SIZE;
    return STATUS_OK;
}

Status core_serialize(Instance *inst, const char *function, const void *FMUstate, unsigned char *serializedState,
                      size_t size)
{
    const StoredState *stored = (const StoredState *)FMUstate;
    unsigned char *out = (unsigned char *)serializedState;
    uint64_t total = SERIAL_SIZE, sum;
    if (!stored || !serializedState) {
        log_error(inst, "%s: FMUstate and serializedState must not be NULL", function);
        return STATUS_ERROR;
    }
    if (!state_is_ours(inst, function, stored)) return STATUS_ERROR;
    if (size != SERIAL_SIZE) {
        log_error(inst, "%s: size = %lu, but the serialized state takes %lu bytes", function, (unsigned long)size,
                  (unsigned long)SERIAL_SIZE);
        return STATUS_ERROR;
    }
    memcpy(out, &stored->magic, 4);
    memcpy(out + 4, &stored->format, 4);
    memcpy(out + 8, &total, 8);
    memcpy(out + 16, stored->guid, GUID_SLOT);
    memcpy(out + SERIAL_HEADER, &stored->s, sizeof(SimState));
    sum = checksum(out, SERIAL_SIZE - 8);
    memcpy(out + SERIAL_SIZE - 8, &sum, 8);
    return STATUS_OK;
}

Status core_deserialize(Instance *inst, const char *function, const unsigned char *serializedState, size_t size,
                        void **FMUstate)
{
    const unsigned char *in = (const unsigned char *)serializedState;
    StoredState decoded, *target;
    uint64_t total, sum;
    if (!serializedState || !FMUstate) {
        log_error(inst, "%s: serializedState and FMUstate must not be NULL", function);
        return STATUS_ERROR;
    }
    if (size != SERIAL_SIZE) {
        log_error(inst, "%s: size = %lu, but a serialized state of %s takes %lu bytes", function, (unsigned long)size,
                  MODEL_IDENTIFIER_STRING, (unsigned long)SERIAL_SIZE);
        return STATUS_ERROR;
    }
    memcpy(&sum, in + SERIAL_SIZE - 8, 8);
    memcpy(&total, in + 8, 8);
    if (sum != checksum(in, SERIAL_SIZE - 8) || total != SERIAL_SIZE) {
        log_error(inst, "%s: the serialized state is corrupt (checksum mismatch)", function);
        return STATUS_ERROR;
    }
    memset(&decoded, 0, sizeof decoded);
    memcpy(&decoded.magic, in, 4);
    memcpy(&decoded.format, in + 4, 4);
    memcpy(decoded.guid, in + 16, GUID_SLOT);
    decoded.guid[GUID_SLOT - 1] = '\0';
    memcpy(&decoded.s, in + SERIAL_HEADER, sizeof(SimState));
    if (!state_is_ours(inst, function, &decoded)) return STATUS_ERROR;
    if (!restored_state_valid(inst, function, &decoded.s)) return STATUS_ERROR;
    target = state_slot(inst, function, *FMUstate);
    if (!target) return STATUS_ERROR;
    *target = decoded;
    *FMUstate = target;
    return STATUS_OK;
}

/* ---------------------------------------------------------------- Model Exchange */

Status core_set_time(Instance *inst, const char *function, double time)
{
    if (!isfinite(time)) {
        log_error(inst, "%s: time = %g is not a finite number", function, time);
        return STATUS_ERROR;
    }
    inst->s.time = time;
    return STATUS_OK;
}

static int state_count_matches(Instance *inst, const char *function, size_t n, size_t expected, const void *array)
{
    if (n != expected) {
        log_error(inst, "%s: array length %lu, but this FMU has %lu", function, (unsigned long)n,
                  (unsigned long)expected);
        return 0;
    }
    return core_arrays_present(inst, function, n, array, array);
}

Status core_set_continuous_states(Instance *inst, const char *function, const double x[], size_t nx)
{
    size_t i;
    if (!state_count_matches(inst, function, nx, N_STATES, x)) return STATUS_ERROR;
    for (i = 0; i < nx; i++)
        if (!isfinite(x[i])) {
            log_error(inst, "%s: state %s = %g is not a finite number", function, REAL_VARIABLES[i].name, x[i]);
            return STATUS_ERROR;
        }
    for (i = 0; i < nx; i++) inst->s.real[i] = x[i];
    inst->outputs_valid = 0;
    return STATUS_OK;
}

Status core_get_derivatives(Instance *inst, const char *function, double derivatives[], size_t nx)
{
    Status status;
    size_t i;
    if (!state_count_matches(inst, function, nx, N_STATES, derivatives)) return STATUS_ERROR;
    status = ensure_outputs(inst, function);
    if (status == STATUS_ERROR) return status;
    for (i = 0; i < nx; i++)
        if (status == STATUS_OK || isfinite(inst->s.real[N_STATES + i])) derivatives[i] = inst->s.real[N_STATES + i];
    return status;
}

Status core_get_event_indicators(Instance *inst, const char *function, double z[], size_t n)
{
    if (n != N_EVENT_INDICATORS) {
        log_error(inst, "%s: the number of event indicators is %lu, but this FMU has %d", function, (unsigned long)n,
                  N_EVENT_INDICATORS);
        return STATUS_ERROR;
    }
    if (n > 0 && !z) {
        log_error(inst, "%s: the event indicator array is NULL", function);
        return STATUS_ERROR;
    }
#if N_EVENT_INDICATORS > 0
    if (!ensure_constants(inst, function)) return STATUS_ERROR;
#if N_CONSTRAINTS > 0
    {
        double u[INPUT_SLOTS];
        event_indicators(&inst->constants, inst->s.active_constraints, inst->s.time, inst->s.real,
                         acting_inputs(inst, u), z);
    }
#else
    model_event_indicators(&inst->constants, inst->s.time, inst->s.real, z);
#endif
    if (first_non_finite(z, N_EVENT_INDICATORS) >= 0) {
        log_discard(inst, "%s: an event indicator is not finite at the current state", function);
        return STATUS_DISCARD;
    }
#endif
    return STATUS_OK;
}

Status core_new_discrete_states(Instance *inst, const char *function, int *states_changed)
{
    *states_changed = 0;
#if N_CONSTRAINTS > 0
    {
        double u[INPUT_SLOTS], before[N_STATES];
        const int32_t active = inst->s.active_constraints;
        const uint64_t events = inst->s.integrator.n_events;
        if (!ensure_constants(inst, function)) return STATUS_ERROR;
        memcpy(before, inst->s.real, sizeof before);
        if (!handle_event(&inst->constants, &inst->s.active_constraints, inst->s.time, inst->s.real,
                          acting_inputs(inst, u), &inst->s.integrator.n_events) ||
            !model_state_ok(&inst->constants, inst->s.real)) {
            memcpy(inst->s.real, before, sizeof before);
            inst->s.active_constraints = active;
            inst->s.integrator.n_events = events;
            log_error(inst,
                      "%s: the event at t = %.17g cannot be resolved: the constraints are dependent (an impact "
                      "or a contact force has no unique solution) or the state after it is singular; the state is "
                      "left as it was",
                      function, inst->s.time);
            return STATUS_ERROR;
        }
        *states_changed = memcmp(before, inst->s.real, sizeof before) != 0 || active != inst->s.active_constraints;
        inst->outputs_valid = 0;
    }
#else
    (void)inst, (void)function;
#endif
    return STATUS_OK;
}

Status core_get_continuous_states(Instance *inst, const char *function, double x[], size_t nx)
{
    size_t i;
    if (!state_count_matches(inst, function, nx, N_STATES, x)) return STATUS_ERROR;
    for (i = 0; i < nx; i++) x[i] = inst->s.real[i];
    return STATUS_OK;
}

Status core_get_nominals(Instance *inst, const char *function, double x_nominal[], size_t nx)
{
    size_t i;
    if (!state_count_matches(inst, function, nx, N_STATES, x_nominal)) return STATUS_ERROR;
    for (i = 0; i < nx; i++) x_nominal[i] = 1.0;
    return STATUS_OK;
}

/* ---------------------------------------------------------------- Co-Simulation */

/* The arrays of a derivative call are there and every order is 1 (the only one supported). */
static int derivative_call_valid(Instance *inst, const char *function, size_t nvr, const unsigned int vr[],
                                 const int32_t order[], const double value[])
{
    size_t i;
    if (!core_arrays_present(inst, function, nvr, vr, value) || !core_arrays_present(inst, function, nvr, order, order))
        return 0;
    for (i = 0; i < nvr; i++)
        if (order[i] != 1) {
            log_error(inst,
                      "%s: derivative order %d is not supported (allowed range [1, 1]: "
                      "maxOutputDerivativeOrder is 1)",
                      function, order[i]);
            return 0;
        }
    return 1;
}

Status core_set_input_derivatives(Instance *inst, const char *function, const unsigned int vr[], size_t nvr,
                                  const int32_t order[], const double value[])
{
    size_t i;
    if (!derivative_call_valid(inst, function, nvr, vr, order, value)) return STATUS_ERROR;
    for (i = 0; i < nvr; i++) {
        if (!real_reference_known(inst, function, vr[i])) return STATUS_ERROR;
        if (input_index(vr[i]) < 0) {
            log_error(inst, "%s: variable %s (value reference %u) is not a Real input (allowed: the %d Real inputs)",
                      function, REAL_VARIABLES[vr[i]].name, vr[i], N_INPUTS);
            return STATUS_ERROR;
        }
        if (!isfinite(value[i])) {
            log_error(inst,
                      "%s: derivative of %s (value reference %u) = %g is not a finite "
                      "number",
                      function, REAL_VARIABLES[vr[i]].name, vr[i], value[i]);
            return STATUS_ERROR;
        }
    }
    if (!inst->s.slopes_set) /* the last step's slopes no longer hold: only those set now drive the next */
        memset(inst->s.input_derivative, 0, sizeof inst->s.input_derivative);
    for (i = 0; i < nvr; i++) inst->s.input_derivative[input_index(vr[i])] = value[i];
    inst->s.slopes_set = 1;
    return STATUS_OK;
}

Status core_get_output_derivatives(Instance *inst, const char *function, const unsigned int vr[], size_t nvr,
                                   const int32_t order[], double value[])
{
    double rate[N_REAL];
    double *dx = NULL;
    Status status;
    size_t i;
    if (!derivative_call_valid(inst, function, nvr, vr, order, value)) return STATUS_ERROR;
    for (i = 0; i < nvr; i++) {
        if (!real_reference_known(inst, function, vr[i])) return STATUS_ERROR;
        if (REAL_VARIABLES[vr[i]].causality != CAUSALITY_OUTPUT) {
            log_error(inst, "%s: variable %s (value reference %u) is not an output", function,
                      REAL_VARIABLES[vr[i]].name, vr[i]);
            return STATUS_ERROR;
        }
    }
    status = ensure_outputs(inst, function);
    if (status != STATUS_OK) return status;
    memset(rate, 0, sizeof rate);
#if N_STATES > 0
    dx = inst->s.real + N_STATES;
    for (i = 0; i < N_STATES; i++) rate[i] = dx[i];
#endif
    model_output_rates(&inst->constants, inst->s.time, inst->s.real, dx, inst->s.input_derivative, rate);
    for (i = 0; i < nvr; i++)
        if (!isfinite(rate[vr[i]])) { /* in-range values can still overflow (huge parameters, 0 times inf) */
            log_discard(inst,
                        "%s: the derivative of %s (value reference %u) is not finite "
                        "for the current parameters, inputs and states; no value handed out",
                        function, REAL_VARIABLES[vr[i]].name, vr[i]);
            return STATUS_DISCARD;
        }
    for (i = 0; i < nvr; i++) value[i] = rate[vr[i]];
    return STATUS_OK;
}

/* The inputs the importer registered, asked for at the step's end t + H: each then varies along the line from its
 * value now to the one given, as an FMI 2.0 input along the derivative set (FMI 3.0 has no input derivatives). An
 * input not given keeps its value. */
static Status take_requested_inputs(Instance *inst, const char *function, double t, double H)
{
    double start[INPUT_SLOTS], end[INPUT_SLOTS];
    int i;
    gather_inputs(inst, start);
    inst->s.machine_state = MS_INTERMEDIATE;
    inst->asking_inputs = 1;
    inst->request_inputs(inst, t + H);
    inst->asking_inputs = 0;
    inst->s.machine_state = MS_STEP_COMPLETE;
    gather_inputs(inst, end);
    scatter_inputs(inst->s.real, start);
    memset(inst->s.input_derivative, 0, sizeof inst->s.input_derivative);
#if N_INPUTS > 0
    for (i = 0; i < N_INPUTS; i++) {
        const double slope = (end[i] - start[i]) / H;
        if (!inst->inputs_requested[i] || end[i] == start[i]) continue;
        if (!isfinite(slope)) {
            log_error(inst,
                      "%s: input %s goes from %g at t = %.17g to %g at t = %.17g (set in the intermediate "
                      "update): its slope over the step is not finite",
                      function, REAL_VARIABLES[INPUT_VRS[i]].name, start[i], t, end[i], t + H);
            return STATUS_ERROR;
        }
        inst->s.input_derivative[i] = slope;
    }
#else
    (void)i, (void)end, (void)function, (void)t;
#endif
    inst->s.slopes_set = 1;
    return STATUS_OK;
}

Status core_do_step(Instance *inst, const char *function, double t, double H)
{
    Status status;
    if (!isfinite(t) || fabs(t - inst->s.time) > 1e-9 * (fabs(t) > 1.0 ? fabs(t) : 1.0)) {
        log_error(inst,
                  "%s: currentCommunicationPoint = %.17g is not the FMU's time %.17g "
                  "(allowed deviation 1e-9 max(1, |t|))",
                  function, t, inst->s.time);
        return STATUS_ERROR;
    }
    if (!(H > 0.0) || !isfinite(H) || !isfinite(t + H)) {
        log_error(inst, "%s: communicationStepSize = %g is not allowed (allowed range (0, inf), finite)", function, H);
        return STATUS_ERROR;
    }
    if (!(t + H > t)) { /* the state would move while the time stays */
        log_error(inst,
                  "%s: communicationStepSize = %g does not advance the time from "
                  "currentCommunicationPoint = %.17g (its resolution there is %g)",
                  function, H, t, nextafter(t, INFINITY) - t);
        return STATUS_ERROR;
    }
    if (!ensure_constants(inst, function)) return STATUS_ERROR;
    if (inst->request_inputs && take_requested_inputs(inst, function, t, H) != STATUS_OK) return STATUS_ERROR;
    flush_subnormals_begin(inst);
    status = step_to(inst, function, t, H);
    flush_subnormals_end(inst);
    if (status == STATUS_DISCARD) inst->s.machine_state = MS_STEP_FAILED;
    return status;
}

/* ---------------------------------------------------------------- directional derivatives */

/* The index of the continuous state with value reference vr (the states come first), or -1. */
static int state_index(unsigned int vr)
{
#if N_STATES > 0
    return vr < N_STATES ? (int)vr : -1;
#else
    (void)vr;
    return -1;
#endif
}

/* Where a known of a directional derivative goes: a continuous state (its index) or an input. */
static int known_valid(Instance *inst, const char *function, unsigned int vr)
{
    if (!real_reference_known(inst, function, vr)) return 0;
    if (state_index(vr) >= 0 || input_index(vr) >= 0) return 1;
    log_error(inst,
              "%s: known %s (value reference %u) is not a continuous state or a Real input (allowed: "
              "the states and inputs)",
              function, REAL_VARIABLES[vr].name, vr);
    return 0;
}

/* An unknown: a state derivative or a continuous output (the states are outputs too). */
static int unknown_valid(Instance *inst, const char *function, unsigned int vr)
{
    if (!real_reference_known(inst, function, vr)) return 0;
    if (state_index(vr - N_STATES) >= 0 || /* a derivative: the derivatives follow the states */
        (REAL_VARIABLES[vr].causality == CAUSALITY_OUTPUT && REAL_VARIABLES[vr].variability == VARIABILITY_CONTINUOUS))
        return 1;
    log_error(inst,
              "%s: unknown %s (value reference %u) is not a state derivative or a continuous output "
              "(allowed: those)",
              function, REAL_VARIABLES[vr].name, vr);
    return 0;
}

/* The variables at which the Jacobian is taken: the states, parameters and the inputs as they are now,
 * with the derivatives and outputs computed for them (in Co-Simulation the outputs the importer reads
 * belong to the end of the last step, whatever inputs were set since). Discard where they are undefined. */
static Status linearization_point(Instance *inst, const char *function, double point[N_REAL])
{
    if (!ensure_constants(inst, function)) return STATUS_ERROR;
    memcpy(point, inst->s.real, N_REAL * sizeof *point);
    return compute_outputs(inst, function, point);
}

/* Jacobian times the seed (by value reference of the knowns) into change[N_REAL] (by value reference
 * of the unknowns), at `point` (see linearization_point). */
static void jacobian_times(Instance *inst, const double point[N_REAL], const unsigned int known[], size_t nknown,
                           const double seed[], double change[])
{
    double seed_x[STATE_SLOTS] = {0}, seed_u[INPUT_SLOTS] = {0}, ddx[STATE_SLOTS] = {0};
    const double *dx = N_STATES > 0 ? point + N_STATES : NULL;
    size_t k;
    int i;
    for (k = 0; k < nknown; k++) {
        if (state_index(known[k]) >= 0)
            seed_x[state_index(known[k])] += seed[k];
        else
            seed_u[input_index(known[k])] += seed[k];
    }
    memset(change, 0, N_REAL * sizeof *change);
    model_directional(&inst->constants, inst->s.time, point, dx, seed_x, seed_u, ddx, change);
    for (i = 0; i < N_STATES; i++) {
        change[i] = seed_x[i];
        change[N_STATES + i] = ddx[i];
    }
}

static int derivative_arguments_valid(Instance *inst, const char *function, const unsigned int unknown[],
                                      size_t n_unknown, const unsigned int known[], size_t n_known, const double seed[],
                                      size_t n_seed)
{
    size_t i;
    if (!core_arrays_present(inst, function, n_known, known, known) ||
        !core_arrays_present(inst, function, n_unknown, unknown, unknown) ||
        !core_arrays_present(inst, function, n_seed, seed, seed))
        return 0;
    for (i = 0; i < n_known; i++)
        if (!known_valid(inst, function, known[i])) return 0;
    for (i = 0; i < n_unknown; i++)
        if (!unknown_valid(inst, function, unknown[i])) return 0;
    for (i = 0; i < n_seed; i++)
        if (!isfinite(seed[i])) {
            log_error(inst, "%s: seed[%u] = %g is not a finite number", function, (unsigned)i, seed[i]);
            return 0;
        }
    return 1;
}

/* NO_VARIABLE for a combination weighted by the seed. */
#define NO_VARIABLE ((unsigned int)-1)
static Status sensitivity_finite(Instance *inst, const char *function, double value, unsigned int unknown,
                                 unsigned int known)
{
    if (isfinite(value)) return STATUS_OK;
    /* in-range values can still overflow (huge parameters, 0 times inf) */
    log_discard(inst,
                "%s: the derivative of %s with respect to %s is not finite for the current parameters, "
                "inputs and states; no value handed out",
                function, unknown == NO_VARIABLE ? "the seeded unknowns" : REAL_VARIABLES[unknown].name,
                known == NO_VARIABLE ? "the seeded knowns" : REAL_VARIABLES[known].name);
    return STATUS_DISCARD;
}

#if N_CONSTRAINTS > 0
static Status partial_derivatives_refused(Instance *inst, const char *function)
{
    log_error(inst,
              "%s: this FMU has constraints and provides no partial derivatives (providesDirectionalDerivative "
              "= false): the constrained motion's switch at contacts is not differentiated",
              function);
    return STATUS_ERROR;
}
#endif

Status core_get_directional_derivative(Instance *inst, const char *function, const unsigned int unknown[],
                                       size_t n_unknown, const unsigned int known[], size_t n_known,
                                       const double seed[], double sensitivity[])
{
#if N_CONSTRAINTS > 0
    (void)unknown, (void)n_unknown, (void)known, (void)n_known, (void)seed, (void)sensitivity;
    return partial_derivatives_refused(inst, function);
#endif
    double change[N_REAL], point[N_REAL];
    Status status;
    size_t i;
    if (!derivative_arguments_valid(inst, function, unknown, n_unknown, known, n_known, seed, n_known) ||
        !core_arrays_present(inst, function, n_unknown, sensitivity, sensitivity))
        return STATUS_ERROR;
    status = linearization_point(inst, function, point);
    if (status != STATUS_OK) return status;
    jacobian_times(inst, point, known, n_known, seed, change);
    for (i = 0; i < n_unknown; i++) {
        status =
            sensitivity_finite(inst, function, change[unknown[i]], unknown[i], n_known == 1 ? known[0] : NO_VARIABLE);
        if (status != STATUS_OK) return status;
    }
    for (i = 0; i < n_unknown; i++) sensitivity[i] = change[unknown[i]];
    return STATUS_OK;
}

Status core_get_adjoint_derivative(Instance *inst, const char *function, const unsigned int unknown[], size_t n_unknown,
                                   const unsigned int known[], size_t n_known, const double seed[],
                                   double sensitivity[])
{
#if N_CONSTRAINTS > 0
    (void)unknown, (void)n_unknown, (void)known, (void)n_known, (void)seed, (void)sensitivity;
    return partial_derivatives_refused(inst, function);
#endif
    double change[N_REAL], point[N_REAL], result;
    const double unit = 1.0;
    Status status;
    size_t i, j;
    if (!derivative_arguments_valid(inst, function, unknown, n_unknown, known, n_known, seed, n_unknown) ||
        !core_arrays_present(inst, function, n_known, sensitivity, sensitivity))
        return STATUS_ERROR;
    status = linearization_point(inst, function, point);
    if (status != STATUS_OK) return status;
    for (j = 0; j < n_known; j++) { /* one column of J per known: the models are small */
        jacobian_times(inst, point, &known[j], 1, &unit, change);
        result = 0.0;
        for (i = 0; i < n_unknown; i++) {
            status = sensitivity_finite(inst, function, change[unknown[i]], unknown[i], known[j]);
            if (status != STATUS_OK) return status;
            result += seed[i] * change[unknown[i]];
        }
        status = sensitivity_finite(inst, function, result, NO_VARIABLE, known[j]);
        if (status != STATUS_OK) return status;
        sensitivity[j] = result;
    }
    return STATUS_OK;
}
