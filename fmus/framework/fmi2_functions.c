/* The FMI 2.0 API, once for every model: state machine, argument checks, variable access, FMU state,
 * Model Exchange and Co-Simulation (the step itself in stepper.c, logging in instance.c). Models
 * supply only physics (see framework.h). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#define MODEL_DESCRIPTION_TABLES
#include "framework.h"

/* ---------------------------------------------------------------- state machine */

#define CS_ANY (MS_INSTANTIATED | MS_INITIALIZATION | MS_STEP_COMPLETE | MS_STEP_FAILED | MS_TERMINATED | MS_ERROR)
#define ME_ANY (MS_INSTANTIATED | MS_INITIALIZATION | MS_EVENT | MS_CONTINUOUS | MS_TERMINATED | MS_ERROR)
#define CS_READABLE (MS_INITIALIZATION | MS_STEP_COMPLETE | MS_STEP_FAILED | MS_TERMINATED | MS_ERROR)
#define ME_READABLE (MS_INITIALIZATION | MS_EVENT | MS_CONTINUOUS | MS_TERMINATED | MS_ERROR)

typedef enum {
    FN_SET_DEBUG_LOGGING, FN_SETUP_EXPERIMENT, FN_ENTER_INITIALIZATION_MODE, FN_EXIT_INITIALIZATION_MODE,
    FN_TERMINATE, FN_RESET, FN_GET_REAL, FN_GET_INTEGER, FN_GET_BOOLEAN, FN_GET_STRING, FN_SET_REAL,
    FN_SET_INTEGER, FN_SET_BOOLEAN, FN_SET_STRING, FN_GET_FMU_STATE, FN_SET_FMU_STATE, FN_FREE_FMU_STATE,
    FN_SERIALIZED_SIZE, FN_SERIALIZE, FN_DESERIALIZE, FN_GET_DIRECTIONAL_DERIVATIVE, FN_ENTER_EVENT_MODE,
    FN_NEW_DISCRETE_STATES, FN_ENTER_CONTINUOUS_TIME_MODE, FN_COMPLETED_INTEGRATOR_STEP, FN_SET_TIME,
    FN_SET_CONTINUOUS_STATES, FN_GET_DERIVATIVES, FN_GET_EVENT_INDICATORS, FN_GET_CONTINUOUS_STATES,
    FN_GET_NOMINALS, FN_SET_REAL_INPUT_DERIVATIVES, FN_GET_REAL_OUTPUT_DERIVATIVES, FN_DO_STEP, FN_CANCEL_STEP,
    FN_GET_STATUS, FN_GET_REAL_STATUS, FN_GET_INTEGER_STATUS, FN_GET_BOOLEAN_STATUS, FN_GET_STRING_STATUS,
    FN_COUNT
} Function;

/* For each function, the states it may be called in: Co-Simulation, Model Exchange (FMI 2.0
 * sections 3.2.3 and 4.2.4). A zero mask means the function does not belong to that interface. */
static const struct {
    const char *name;
    unsigned cs, me;
} CALL_RULES[FN_COUNT] = {
    [FN_SET_DEBUG_LOGGING] = {"fmi2SetDebugLogging", CS_ANY, ME_ANY},
    [FN_SETUP_EXPERIMENT] = {"fmi2SetupExperiment", MS_INSTANTIATED, MS_INSTANTIATED},
    [FN_ENTER_INITIALIZATION_MODE] = {"fmi2EnterInitializationMode", MS_INSTANTIATED, MS_INSTANTIATED},
    [FN_EXIT_INITIALIZATION_MODE] = {"fmi2ExitInitializationMode", MS_INITIALIZATION, MS_INITIALIZATION},
    [FN_TERMINATE] = {"fmi2Terminate", MS_STEP_COMPLETE | MS_STEP_FAILED, MS_EVENT | MS_CONTINUOUS},
    [FN_RESET] = {"fmi2Reset", CS_ANY, ME_ANY},
    [FN_GET_REAL] = {"fmi2GetReal", CS_READABLE, ME_READABLE},
    [FN_GET_INTEGER] = {"fmi2GetInteger", CS_READABLE, ME_READABLE},
    [FN_GET_BOOLEAN] = {"fmi2GetBoolean", CS_READABLE, ME_READABLE},
    [FN_GET_STRING] = {"fmi2GetString", CS_READABLE, ME_READABLE},
    [FN_SET_REAL] = {"fmi2SetReal", MS_INSTANTIATED | MS_INITIALIZATION | MS_STEP_COMPLETE,
                     MS_INSTANTIATED | MS_INITIALIZATION | MS_EVENT | MS_CONTINUOUS},
    [FN_SET_INTEGER] = {"fmi2SetInteger", MS_INSTANTIATED | MS_INITIALIZATION | MS_STEP_COMPLETE,
                        MS_INSTANTIATED | MS_INITIALIZATION | MS_EVENT},
    [FN_SET_BOOLEAN] = {"fmi2SetBoolean", MS_INSTANTIATED | MS_INITIALIZATION | MS_STEP_COMPLETE,
                        MS_INSTANTIATED | MS_INITIALIZATION | MS_EVENT},
    [FN_SET_STRING] = {"fmi2SetString", MS_INSTANTIATED | MS_INITIALIZATION | MS_STEP_COMPLETE,
                       MS_INSTANTIATED | MS_INITIALIZATION | MS_EVENT},
    [FN_GET_FMU_STATE] = {"fmi2GetFMUstate", CS_ANY, ME_ANY},
    [FN_SET_FMU_STATE] = {"fmi2SetFMUstate", CS_ANY, ME_ANY},
    [FN_FREE_FMU_STATE] = {"fmi2FreeFMUstate", CS_ANY, ME_ANY},
    [FN_SERIALIZED_SIZE] = {"fmi2SerializedFMUstateSize", CS_ANY, ME_ANY},
    [FN_SERIALIZE] = {"fmi2SerializeFMUstate", CS_ANY, ME_ANY},
    [FN_DESERIALIZE] = {"fmi2DeSerializeFMUstate", CS_ANY, ME_ANY},
    [FN_GET_DIRECTIONAL_DERIVATIVE] = {"fmi2GetDirectionalDerivative", CS_READABLE, ME_READABLE},
    [FN_ENTER_EVENT_MODE] = {"fmi2EnterEventMode", 0, MS_EVENT | MS_CONTINUOUS},
    [FN_NEW_DISCRETE_STATES] = {"fmi2NewDiscreteStates", 0, MS_EVENT},
    [FN_ENTER_CONTINUOUS_TIME_MODE] = {"fmi2EnterContinuousTimeMode", 0, MS_EVENT},
    [FN_COMPLETED_INTEGRATOR_STEP] = {"fmi2CompletedIntegratorStep", 0, MS_CONTINUOUS},
    [FN_SET_TIME] = {"fmi2SetTime", 0, MS_EVENT | MS_CONTINUOUS},
    [FN_SET_CONTINUOUS_STATES] = {"fmi2SetContinuousStates", 0, MS_CONTINUOUS},
    [FN_GET_DERIVATIVES] = {"fmi2GetDerivatives", 0, ME_READABLE},
    [FN_GET_EVENT_INDICATORS] = {"fmi2GetEventIndicators", 0, ME_READABLE},
    [FN_GET_CONTINUOUS_STATES] = {"fmi2GetContinuousStates", 0, ME_READABLE},
    [FN_GET_NOMINALS] = {"fmi2GetNominalsOfContinuousStates", 0, ME_READABLE},
    [FN_SET_REAL_INPUT_DERIVATIVES] = {"fmi2SetRealInputDerivatives",
                                       MS_INSTANTIATED | MS_INITIALIZATION | MS_STEP_COMPLETE, 0},
    [FN_GET_REAL_OUTPUT_DERIVATIVES] = {"fmi2GetRealOutputDerivatives",
                                        MS_STEP_COMPLETE | MS_STEP_FAILED | MS_TERMINATED | MS_ERROR, 0},
    [FN_DO_STEP] = {"fmi2DoStep", MS_STEP_COMPLETE, 0},
    [FN_CANCEL_STEP] = {"fmi2CancelStep", 0, 0}, /* only in stepInProgress, which never happens here */
    [FN_GET_STATUS] = {"fmi2GetStatus", MS_STEP_COMPLETE | MS_STEP_FAILED | MS_TERMINATED, 0},
    [FN_GET_REAL_STATUS] = {"fmi2GetRealStatus", MS_STEP_COMPLETE | MS_STEP_FAILED | MS_TERMINATED, 0},
    [FN_GET_INTEGER_STATUS] = {"fmi2GetIntegerStatus", MS_STEP_COMPLETE | MS_STEP_FAILED | MS_TERMINATED, 0},
    [FN_GET_BOOLEAN_STATUS] = {"fmi2GetBooleanStatus", MS_STEP_COMPLETE | MS_STEP_FAILED | MS_TERMINATED, 0},
    [FN_GET_STRING_STATUS] = {"fmi2GetStringStatus", MS_STEP_COMPLETE | MS_STEP_FAILED | MS_TERMINATED, 0},
};

static const char *state_name(int state)
{
    switch (state) {
    case MS_INSTANTIATED: return "instantiated";
    case MS_INITIALIZATION: return "initializationMode";
    case MS_STEP_COMPLETE: return "stepComplete";
    case MS_STEP_FAILED: return "stepFailed";
    case MS_EVENT: return "eventMode";
    case MS_CONTINUOUS: return "continuousTimeMode";
    case MS_TERMINATED: return "terminated";
    case MS_ERROR: return "error";
    default: return "unknown";
    }
}

static void describe_states(unsigned mask, char *text, size_t size)
{
    unsigned bit;
    text[0] = '\0';
    for (bit = 1; bit <= MS_ERROR; bit <<= 1) {
        if (mask & bit) {
            size_t used = strlen(text);
            snprintf(text + used, size - used, "%s%s", used ? ", " : "", state_name((int)bit));
        }
    }
    if (!text[0]) snprintf(text, size, "none");
}

/* Checks the call against the state machine; logs and returns 0 when it is illegal. */
static int call_allowed(Instance *inst, Function fn)
{
    const unsigned mask = inst->type == fmi2CoSimulation ? CALL_RULES[fn].cs : CALL_RULES[fn].me;
    char allowed[256];
    if (mask & (unsigned)inst->s.machine_state) return 1;
    describe_states(mask, allowed, sizeof allowed);
    log_error(inst, "%s: illegal call sequence: not allowed in state %s for %s (allowed in: %s)", CALL_RULES[fn].name,
              state_name(inst->s.machine_state), inst->type == fmi2CoSimulation ? "Co-Simulation" : "Model Exchange",
              allowed);
    return 0;
}

/* The instance behind c, checked against the state machine: NULL means return fmi2Error. */
static Instance *enter(fmi2Component c, Function fn)
{
    Instance *inst = (Instance *)c;
    if (!inst) return NULL;
    return call_allowed(inst, fn) ? inst : NULL;
}

static int arrays_present(Instance *inst, const char *function, size_t n, const void *a, const void *b)
{
    if (n > 0 && (!a || !b)) {
        log_error(inst, "%s: NULL array for %lu values", function, (unsigned long)n);
        return 0;
    }
    return 1;
}

/* ---------------------------------------------------------------- start values and derived data */

static void set_start_values(Instance *inst)
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
}

/* model_prepare guarded by the cross-parameter checks, so that no output can become NaN. */
static int ensure_constants(Instance *inst, const char *function)
{
    char message[256];
    if (inst->constants_valid) return 1;
    if (model_prepare(inst->s.real, inst->s.integer, &inst->constants, message, sizeof message)) {
        log_error(inst, "%s: %s", function, message);
        return 0;
    }
    inst->constants_valid = 1;
    return 1;
}

/* Calculated outputs and state derivatives, computed only when someone reads them. */
static fmi2Status ensure_outputs(Instance *inst, const char *function)
{
    double *dx = NULL;
    if (inst->outputs_valid) return fmi2OK;
    if (!ensure_constants(inst, function)) return fmi2Error;
#if N_STATES > 0
    {
        double u[INPUT_SLOTS];
        gather_inputs(inst, u);
        dx = inst->s.real + N_STATES; /* der(x) follow the states (checked by the code generator) */
        model_derivatives(&inst->constants, inst->s.time, inst->s.real, u, dx);
        /* In Model Exchange these are the importer's solver's evaluations; in Co-Simulation the
           integrator counts its own and this one only serves the outputs. */
        if (inst->type == fmi2ModelExchange) inst->s.integrator.n_rhs++;
    }
#endif
    if (!model_outputs(&inst->constants, inst->s.time, dx, inst->s.real)) {
        log_discard(inst, "%s: the outputs are undefined in the current (singular) configuration", function);
        return fmi2Discard;
    }
    {
        const int bad = first_non_finite(inst->s.real, N_REAL);
        if (bad >= 0) {
            log_discard(inst, "%s: %s is not finite for the current inputs and states", function,
                        REAL_VARIABLES[bad].name);
            return fmi2Discard;
        }
    }
    inst->outputs_valid = 1;
    return fmi2OK;
}

static int input_index(fmi2ValueReference vr)
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

/* ---------------------------------------------------------------- common functions */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    Instance *inst;
    Instance reporter; /* logs before an instance exists */
    size_t length;
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions) return NULL;
    memset(&reporter, 0, sizeof reporter);
    reporter.logger = functions->logger;
    reporter.environment = functions->componentEnvironment;
    reporter.name = (char *)(instanceName ? instanceName : "?");
    if (!functions->allocateMemory || !functions->freeMemory) {
        log_error(&reporter, "fmi2Instantiate: callback functions allocateMemory and freeMemory are required");
        return NULL;
    }
    if (!instanceName || !instanceName[0]) {
        log_error(&reporter, "fmi2Instantiate: instanceName must be a non-empty string");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, MODEL_GUID) != 0) {
        log_error(&reporter, "fmi2Instantiate: fmuGUID = %s does not match this FMU (%s, GUID %s)",
                  fmuGUID ? fmuGUID : "NULL", MODEL_IDENTIFIER_STRING, MODEL_GUID);
        return NULL;
    }
    if (fmuType != fmi2ModelExchange && fmuType != fmi2CoSimulation) {
        log_error(&reporter, "fmi2Instantiate: fmuType = %d is neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)",
                  (int)fmuType);
        return NULL;
    }
    inst = (Instance *)functions->allocateMemory(1, sizeof(Instance));
    if (!inst) {
        log_error(&reporter, "fmi2Instantiate: out of memory");
        return NULL;
    }
    memset(inst, 0, sizeof *inst);
    length = strlen(instanceName) + 1;
    inst->name = (char *)functions->allocateMemory(length, 1);
    if (!inst->name) {
        functions->freeMemory(inst);
        log_error(&reporter, "fmi2Instantiate: out of memory");
        return NULL;
    }
    memcpy(inst->name, instanceName, length);
    inst->type = fmuType;
    inst->logger = functions->logger;
    inst->allocate = functions->allocateMemory;
    inst->release = functions->freeMemory;
    inst->environment = functions->componentEnvironment;
    inst->logging_on = loggingOn ? 1 : 0;
    set_start_values(inst);
    return inst;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (!inst) return;
    inst->release(inst->name);
    inst->release(inst);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    static const char *const known[] = {"logStatusError", "logStatusWarning", "logStatusDiscard", "logAll"};
    Instance *inst = enter(c, FN_SET_DEBUG_LOGGING);
    size_t i, k;
    if (!inst) return fmi2Error;
    if (!arrays_present(inst, "fmi2SetDebugLogging", nCategories, categories, categories)) return fmi2Error;
    for (i = 0; i < nCategories; i++) {
        int found = 0;
        for (k = 0; k < sizeof known / sizeof known[0]; k++)
            if (categories[i] && strcmp(categories[i], known[k]) == 0) found = 1;
        if (!found) {
            log_error(inst, "fmi2SetDebugLogging: unknown log category %s (known: logStatusError, logStatusWarning, "
                      "logStatusDiscard, logAll)", categories[i] ? categories[i] : "NULL");
            return fmi2Error;
        }
    }
    inst->logging_on = loggingOn ? 1 : 0;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Instance *inst = enter(c, FN_SETUP_EXPERIMENT);
    (void)toleranceDefined;
    (void)tolerance;
    if (!inst) return fmi2Error;
    if (!isfinite(startTime)) {
        log_error(inst, "fmi2SetupExperiment: startTime = %g must be a finite number", startTime);
        return fmi2Error;
    }
    if (stopTimeDefined && !(stopTime >= startTime)) {
        log_error(inst, "fmi2SetupExperiment: stopTime = %g must not be before startTime = %g", stopTime, startTime);
        return fmi2Error;
    }
    inst->s.time = startTime;
    inst->s.last_successful_time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    Instance *inst = enter(c, FN_ENTER_INITIALIZATION_MODE);
    if (!inst) return fmi2Error;
    inst->s.machine_state = MS_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Instance *inst = enter(c, FN_EXIT_INITIALIZATION_MODE);
    if (!inst) return fmi2Error;
    inst->constants_valid = 0;
    if (!ensure_constants(inst, "fmi2ExitInitializationMode")) return fmi2Error;
#if N_STATES > 0
    if (!state_acceptable(inst, inst->s.time, inst->s.real)) {
        char reason[256];
        if (model_explain_singularity(&inst->constants, inst->s.time, inst->s.real, reason, sizeof reason))
            log_error(inst, "fmi2ExitInitializationMode: the start values of the states give a singular "
                      "configuration: %s", reason);
        else
            log_error(inst, "fmi2ExitInitializationMode: the start values of the states give a singular configuration "
                      "or non-finite derivatives or outputs");
        return fmi2Error;
    }
#else
    {   /* without states, the outputs decide: the same promise as the models with states */
        double real[N_REAL];
        memcpy(real, inst->s.real, sizeof real);
        if (!model_outputs(&inst->constants, inst->s.time, NULL, real) || first_non_finite(real, N_REAL) >= 0) {
            log_error(inst, "fmi2ExitInitializationMode: the start values of the inputs give a singular configuration "
                      "or non-finite outputs");
            return fmi2Error;
        }
    }
#endif
    memset(&inst->s.integrator, 0, sizeof inst->s.integrator); /* counters count from here */
    restart_integrator(inst);
    inst->s.last_successful_time = inst->s.time;
    inst->outputs_valid = 0;
    inst->s.machine_state = inst->type == fmi2CoSimulation ? MS_STEP_COMPLETE : MS_EVENT;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    Instance *inst = enter(c, FN_TERMINATE);
    if (!inst) return fmi2Error;
    inst->s.machine_state = MS_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    Instance *inst = enter(c, FN_RESET);
    if (!inst) return fmi2Error;
    set_start_values(inst);
    return fmi2OK;
}

/* ---------------------------------------------------------------- variable access */

static unsigned settable_in(const VariableInfo *v)
{
    if (v->causality == CAUSALITY_PARAMETER) {
        return v->variability == VARIABILITY_TUNABLE
                   ? MS_INSTANTIATED | MS_INITIALIZATION | MS_STEP_COMPLETE | MS_EVENT
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

/* A finite value within the variable's range; logs and returns 0 otherwise. */
static int value_in_range(Instance *inst, const char *function, const VariableInfo *v, fmi2ValueReference vr,
                          double value)
{
    if (!isfinite(value)) {
        log_error(inst, "%s: variable %s (value reference %u) = %g is not a finite number (allowed range [%g, %g])",
                  function, v->name, vr, value, v->min, v->max);
        return 0;
    }
    if (value < v->min || value > v->max) {
        log_error(inst, "%s: variable %s (value reference %u) = %.17g is out of its allowed range [%g, %g]", function,
                  v->name, vr, value, v->min, v->max);
        return 0;
    }
    return 1;
}

/* Every check a value must pass before it is stored; logs and returns 0 on the first failure. */
static int value_acceptable(Instance *inst, const char *function, const VariableInfo *v, fmi2ValueReference vr,
                            double value)
{
    const unsigned allowed = settable_in(v);
    char states[256];
    if (!(allowed & (unsigned)inst->s.machine_state)) {
        describe_states(allowed, states, sizeof states);
        log_error(inst, "%s: variable %s (value reference %u) is %s and cannot be set in state %s (settable in: %s)",
                  function, v->name, vr, kind_of(v), state_name(inst->s.machine_state), states);
        return 0;
    }
    return value_in_range(inst, function, v, vr, value);
}

/* What follows from a stored value: derived constants, integrator history, cached outputs. */
static void value_stored(Instance *inst, const VariableInfo *v, fmi2ValueReference vr)
{
    if (v->causality == CAUSALITY_PARAMETER) {
        inst->constants_valid = 0;
        restart_integrator(inst); /* solver, h or tol may have changed */
    } else if (v->causality == CAUSALITY_INPUT) {
        const int k = input_index(vr);
        if (k >= 0) inst->s.input_derivative[k] = 0.0; /* setting the input again clears its slope */
        /* After a step the outputs stay those of the step's end until the next step. */
        if (inst->s.machine_state == MS_STEP_COMPLETE) return;
    } else {
        restart_integrator(inst);
    }
    inst->outputs_valid = 0;
}

static int real_reference_known(Instance *inst, const char *function, fmi2ValueReference vr)
{
    if (vr < N_REAL) return 1;
    log_error(inst, "%s: unknown value reference %u (this FMU's Real variables are 0..%d)", function, vr, N_REAL - 1);
    return 0;
}

static int integer_reference_known(Instance *inst, const char *function, fmi2ValueReference vr)
{
    if (vr >= INTEGER_VR_BASE && vr < INTEGER_VR_BASE + N_INTEGER) return 1;
    if (N_INTEGER > 0)
        log_error(inst, "%s: unknown value reference %u (this FMU's Integer variables are %d..%d)", function, vr,
                  INTEGER_VR_BASE, INTEGER_VR_BASE + N_INTEGER - 1);
    else
        log_error(inst, "%s: unknown value reference %u (this FMU has no Integer variables)", function, vr);
    return 0;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    Instance *inst = enter(c, FN_GET_REAL);
    fmi2Status status;
    size_t i;
    if (!inst || !arrays_present(inst, "fmi2GetReal", nvr, vr, value)) return fmi2Error;
    for (i = 0; i < nvr; i++)
        if (!real_reference_known(inst, "fmi2GetReal", vr[i])) return fmi2Error;
    /* Parameters, inputs and states hold what was set: reading only those needs no outputs, and stays
     * fmi2OK where the outputs are undefined. */
    status = fmi2OK;
    for (i = 0; i < nvr; i++)
        if (!settable_in(&REAL_VARIABLES[vr[i]])) {
            status = ensure_outputs(inst, "fmi2GetReal");
            break;
        }
    if (status == fmi2Error) return status;
    /* With fmi2Discard, values that are not finite are not handed out: those entries stay as they were. */
    for (i = 0; i < nvr; i++)
        if (status == fmi2OK || isfinite(inst->s.real[vr[i]])) value[i] = inst->s.real[vr[i]];
    return status;
}

static int32_t saturated(uint64_t count) { return count > 2147483647u ? 2147483647 : (int32_t)count; }

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    Instance *inst = enter(c, FN_GET_INTEGER);
    size_t i;
    if (!inst || !arrays_present(inst, "fmi2GetInteger", nvr, vr, value)) return fmi2Error;
    for (i = 0; i < nvr; i++)
        if (!integer_reference_known(inst, "fmi2GetInteger", vr[i])) return fmi2Error;
#if N_STATES > 0
    inst->s.integer[INT_n_rhs] = saturated(inst->s.integrator.n_rhs);
    inst->s.integer[INT_n_steps] = saturated(inst->s.integrator.n_steps);
    inst->s.integer[INT_n_rejected] = saturated(inst->s.integrator.n_rejected);
#else
    (void)saturated;
#endif
    for (i = 0; i < nvr; i++) value[i] = inst->s.integer[vr[i] - INTEGER_VR_BASE];
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    Instance *inst = enter(c, FN_SET_REAL);
    size_t i;
    if (!inst || !arrays_present(inst, "fmi2SetReal", nvr, vr, value)) return fmi2Error;
    /* All values are checked before any is stored: a rejected call changes nothing. */
    for (i = 0; i < nvr; i++) {
        if (!real_reference_known(inst, "fmi2SetReal", vr[i])) return fmi2Error;
        if (!value_acceptable(inst, "fmi2SetReal", &REAL_VARIABLES[vr[i]], vr[i], value[i])) return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        inst->s.real[vr[i]] = value[i];
        value_stored(inst, &REAL_VARIABLES[vr[i]], vr[i]);
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    Instance *inst = enter(c, FN_SET_INTEGER);
    size_t i;
    if (!inst || !arrays_present(inst, "fmi2SetInteger", nvr, vr, value)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (!integer_reference_known(inst, "fmi2SetInteger", vr[i])) return fmi2Error;
#if N_INTEGER > 0
        if (!value_acceptable(inst, "fmi2SetInteger", &INTEGER_VARIABLES[vr[i] - INTEGER_VR_BASE], vr[i], value[i]))
            return fmi2Error;
#endif
    }
#if N_INTEGER > 0
    for (i = 0; i < nvr; i++) {
        inst->s.integer[vr[i] - INTEGER_VR_BASE] = value[i];
        value_stored(inst, &INTEGER_VARIABLES[vr[i] - INTEGER_VR_BASE], vr[i]);
    }
#endif
    return fmi2OK;
}

static fmi2Status no_such_variables(fmi2Component c, Function fn, size_t nvr, const fmi2ValueReference vr[],
                                    const char *type)
{
    Instance *inst = enter(c, fn);
    if (!inst) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    log_error(inst, "%s: unknown value reference %u (this FMU has no %s variables)", CALL_RULES[fn].name,
              vr ? vr[0] : 0u, type);
    return fmi2Error;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    (void)value;
    return no_such_variables(c, FN_GET_BOOLEAN, nvr, vr, "Boolean");
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    (void)value;
    return no_such_variables(c, FN_GET_STRING, nvr, vr, "String");
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    (void)value;
    return no_such_variables(c, FN_SET_BOOLEAN, nvr, vr, "Boolean");
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    (void)value;
    return no_such_variables(c, FN_SET_STRING, nvr, vr, "String");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    Instance *inst = enter(c, FN_GET_DIRECTIONAL_DERIVATIVE);
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown, (void)dvUnknown;
    if (!inst) return fmi2Error;
    log_error(inst, "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative is false)");
    return fmi2Error;
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
        log_error(inst, "%s: the FMU state belongs to another FMU (GUID %.48s, this FMU is %s)", function,
                  stored->guid, MODEL_GUID);
        return 0;
    }
    return 1;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    Instance *inst = enter(c, FN_GET_FMU_STATE);
    StoredState *stored;
    if (!inst) return fmi2Error;
    if (!FMUstate) {
        log_error(inst, "fmi2GetFMUstate: FMUstate pointer is NULL");
        return fmi2Error;
    }
    stored = (StoredState *)*FMUstate;
    if (stored) {
        if (!state_is_ours(inst, "fmi2GetFMUstate", stored)) return fmi2Error;
    } else {
        stored = (StoredState *)inst->allocate(1, sizeof(StoredState));
        if (!stored) {
            log_error(inst, "fmi2GetFMUstate: out of memory");
            return fmi2Error;
        }
        memset(stored, 0, sizeof *stored);
        stored->magic = STATE_MAGIC;
        stored->format = STATE_FORMAT;
        strncpy(stored->guid, MODEL_GUID, GUID_SLOT - 1);
    }
    stored->s = inst->s;
    *FMUstate = stored;
    return fmi2OK;
}

static int machine_state_fits(const Instance *inst, int32_t state)
{
    const unsigned valid = inst->type == fmi2CoSimulation ? CS_ANY : ME_ANY;
    return state != 0 && (state & (state - 1)) == 0 && ((unsigned)state & valid);
}

/* A deserialized state passes the setters' checks: every value a user can set (parameters, inputs,
 * states) finite and in range, the parameters consistent together, and the framework's own numbers
 * (time, machine state, integrator memory) sane. Logs the first problem. */
static int restored_state_valid(Instance *inst, const char *function, const SimState *s)
{
    char message[256];
    ModelConst constants;
    int i;
    if (!isfinite(s->time) || !isfinite(s->last_successful_time) || !machine_state_fits(inst, s->machine_state)) {
        log_error(inst, "%s: the FMU state's time %g or machine state %d is invalid", function, s->time,
                  (int)s->machine_state);
        return 0;
    }
    for (i = 0; i < N_REAL; i++)
        if (settable_in(&REAL_VARIABLES[i]) && !value_in_range(inst, function, &REAL_VARIABLES[i], (fmi2ValueReference)i,
                                                               s->real[i]))
            return 0;
#if N_INTEGER > 0
    for (i = 0; i < N_INTEGER; i++)
        if (INTEGER_VARIABLES[i].causality == CAUSALITY_PARAMETER &&
            !value_in_range(inst, function, &INTEGER_VARIABLES[i], (fmi2ValueReference)(INTEGER_VR_BASE + i),
                            s->integer[i]))
            return 0;
#endif
#if N_INPUTS > 0
    for (i = 0; i < N_INPUTS; i++)
        if (!isfinite(s->input_derivative[i])) {
            log_error(inst, "%s: the FMU state's derivative of input %s is not finite", function,
                      REAL_VARIABLES[INPUT_VRS[i]].name);
            return 0;
        }
#endif
    if (s->integrator.ab_count < 0 || s->integrator.ab_count > AB_MAX_STEPS || s->integrator.ab_head < 0 ||
        s->integrator.ab_head >= AB_MAX_STEPS || !isfinite(s->integrator.ab_step) ||
        !(s->integrator.rkf_proposal >= 0.0) || !isfinite(s->integrator.rkf_proposal)) {
        log_error(inst, "%s: the FMU state's integrator memory is invalid", function);
        return 0;
    }
    if (model_prepare(s->real, s->integer, &constants, message, sizeof message)) {
        log_error(inst, "%s: %s", function, message);
        return 0;
    }
    return 1;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    Instance *inst = enter(c, FN_SET_FMU_STATE);
    const StoredState *stored = (const StoredState *)FMUstate;
    if (!inst) return fmi2Error;
    if (!stored) {
        log_error(inst, "fmi2SetFMUstate: FMUstate is NULL");
        return fmi2Error;
    }
    if (!state_is_ours(inst, "fmi2SetFMUstate", stored)) return fmi2Error;
    if (!machine_state_fits(inst, stored->s.machine_state)) {
        log_error(inst, "fmi2SetFMUstate: the FMU state was taken from a %s instance, this one is %s",
                  inst->type == fmi2CoSimulation ? "Model Exchange" : "Co-Simulation",
                  inst->type == fmi2CoSimulation ? "Co-Simulation" : "Model Exchange");
        return fmi2Error;
    }
    /* An in-memory state was made by this FMU's fmi2GetFMUstate from checked values: no second check here,
     * where masters roll back every iteration (a deserialized one is checked, it comes from outside). */
    inst->s = stored->s;
    /* A restored state is a good state: a failed step is behind it. */
    if (inst->s.machine_state == MS_STEP_FAILED) inst->s.machine_state = MS_STEP_COMPLETE;
    inst->constants_valid = 0;
    inst->outputs_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    Instance *inst = enter(c, FN_FREE_FMU_STATE);
    if (!inst) return fmi2Error;
    if (!FMUstate) {
        log_error(inst, "fmi2FreeFMUstate: FMUstate pointer is NULL");
        return fmi2Error;
    }
    if (*FMUstate) {
        if (!state_is_ours(inst, "fmi2FreeFMUstate", (const StoredState *)*FMUstate)) return fmi2Error;
        ((StoredState *)*FMUstate)->magic = 0; /* a second free of the same state is caught */
        inst->release(*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
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

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    Instance *inst = enter(c, FN_SERIALIZED_SIZE);
    if (!inst) return fmi2Error;
    if (!FMUstate || !size) {
        log_error(inst, "fmi2SerializedFMUstateSize: FMUstate and size must not be NULL");
        return fmi2Error;
    }
    if (!state_is_ours(inst, "fmi2SerializedFMUstateSize", (const StoredState *)FMUstate)) return fmi2Error;
    *size = SERIAL_SIZE;
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size)
{
    Instance *inst = enter(c, FN_SERIALIZE);
    const StoredState *stored = (const StoredState *)FMUstate;
    unsigned char *out = (unsigned char *)serializedState;
    uint64_t total = SERIAL_SIZE, sum;
    if (!inst) return fmi2Error;
    if (!stored || !serializedState) {
        log_error(inst, "fmi2SerializeFMUstate: FMUstate and serializedState must not be NULL");
        return fmi2Error;
    }
    if (!state_is_ours(inst, "fmi2SerializeFMUstate", stored)) return fmi2Error;
    if (size != SERIAL_SIZE) {
        log_error(inst, "fmi2SerializeFMUstate: size = %lu, but the serialized state takes %lu bytes",
                  (unsigned long)size, (unsigned long)SERIAL_SIZE);
        return fmi2Error;
    }
    memcpy(out, &stored->magic, 4);
    memcpy(out + 4, &stored->format, 4);
    memcpy(out + 8, &total, 8);
    memcpy(out + 16, stored->guid, GUID_SLOT);
    memcpy(out + SERIAL_HEADER, &stored->s, sizeof(SimState));
    sum = checksum(out, SERIAL_SIZE - 8);
    memcpy(out + SERIAL_SIZE - 8, &sum, 8);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    Instance *inst = enter(c, FN_DESERIALIZE);
    const unsigned char *in = (const unsigned char *)serializedState;
    StoredState decoded, *target;
    uint64_t total, sum;
    if (!inst) return fmi2Error;
    if (!serializedState || !FMUstate) {
        log_error(inst, "fmi2DeSerializeFMUstate: serializedState and FMUstate must not be NULL");
        return fmi2Error;
    }
    if (size != SERIAL_SIZE) {
        log_error(inst, "fmi2DeSerializeFMUstate: size = %lu, but a serialized state of %s takes %lu bytes",
                  (unsigned long)size, MODEL_IDENTIFIER_STRING, (unsigned long)SERIAL_SIZE);
        return fmi2Error;
    }
    memcpy(&sum, in + SERIAL_SIZE - 8, 8);
    memcpy(&total, in + 8, 8);
    if (sum != checksum(in, SERIAL_SIZE - 8) || total != SERIAL_SIZE) {
        log_error(inst, "fmi2DeSerializeFMUstate: the serialized state is corrupt (checksum mismatch)");
        return fmi2Error;
    }
    memset(&decoded, 0, sizeof decoded);
    memcpy(&decoded.magic, in, 4);
    memcpy(&decoded.format, in + 4, 4);
    memcpy(decoded.guid, in + 16, GUID_SLOT);
    decoded.guid[GUID_SLOT - 1] = '\0';
    memcpy(&decoded.s, in + SERIAL_HEADER, sizeof(SimState));
    if (!state_is_ours(inst, "fmi2DeSerializeFMUstate", &decoded)) return fmi2Error;
    if (!restored_state_valid(inst, "fmi2DeSerializeFMUstate", &decoded.s)) return fmi2Error;
    target = (StoredState *)*FMUstate;
    if (target) {
        if (!state_is_ours(inst, "fmi2DeSerializeFMUstate", target)) return fmi2Error;
    } else {
        target = (StoredState *)inst->allocate(1, sizeof(StoredState));
        if (!target) {
            log_error(inst, "fmi2DeSerializeFMUstate: out of memory");
            return fmi2Error;
        }
    }
    *target = decoded;
    *FMUstate = target;
    return fmi2OK;
}

/* ---------------------------------------------------------------- Model Exchange */

fmi2Status fmi2EnterEventMode(fmi2Component c)
{
    Instance *inst = enter(c, FN_ENTER_EVENT_MODE);
    if (!inst) return fmi2Error;
    inst->s.machine_state = MS_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info)
{
    Instance *inst = enter(c, FN_NEW_DISCRETE_STATES);
    if (!inst) return fmi2Error;
    if (!info) {
        log_error(inst, "fmi2NewDiscreteStates: fmi2EventInfo pointer is NULL");
        return fmi2Error;
    }
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c)
{
    Instance *inst = enter(c, FN_ENTER_CONTINUOUS_TIME_MODE);
    if (!inst) return fmi2Error;
    inst->s.machine_state = MS_CONTINUOUS;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    Instance *inst = enter(c, FN_COMPLETED_INTEGRATOR_STEP);
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!inst) return fmi2Error;
    if (!enterEventMode || !terminateSimulation) {
        log_error(inst, "fmi2CompletedIntegratorStep: enterEventMode and terminateSimulation must not be NULL");
        return fmi2Error;
    }
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time)
{
    Instance *inst = enter(c, FN_SET_TIME);
    if (!inst) return fmi2Error;
    if (!isfinite(time)) {
        log_error(inst, "fmi2SetTime: time = %g is not a finite number", time);
        return fmi2Error;
    }
    inst->s.time = time;
    return fmi2OK;
}

static int state_count_matches(Instance *inst, const char *function, size_t n, size_t expected, const void *array)
{
    if (n != expected) {
        log_error(inst, "%s: array length %lu, but this FMU has %lu", function, (unsigned long)n,
                  (unsigned long)expected);
        return 0;
    }
    return arrays_present(inst, function, n, array, array);
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{
    Instance *inst = enter(c, FN_SET_CONTINUOUS_STATES);
    size_t i;
    if (!inst || !state_count_matches(inst, "fmi2SetContinuousStates", nx, N_STATES, x)) return fmi2Error;
    for (i = 0; i < nx; i++)
        if (!isfinite(x[i])) {
            log_error(inst, "fmi2SetContinuousStates: state %s = %g is not a finite number", REAL_VARIABLES[i].name,
                      x[i]);
            return fmi2Error;
        }
    for (i = 0; i < nx; i++) inst->s.real[i] = x[i];
    inst->outputs_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx)
{
    Instance *inst = enter(c, FN_GET_DERIVATIVES);
    fmi2Status status;
    size_t i;
    if (!inst || !state_count_matches(inst, "fmi2GetDerivatives", nx, N_STATES, derivatives)) return fmi2Error;
    status = ensure_outputs(inst, "fmi2GetDerivatives");
    if (status == fmi2Error) return status;
    for (i = 0; i < nx; i++)
        if (status == fmi2OK || isfinite(inst->s.real[N_STATES + i])) derivatives[i] = inst->s.real[N_STATES + i];
    return status;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni)
{
    Instance *inst = enter(c, FN_GET_EVENT_INDICATORS);
    (void)eventIndicators;
    if (!inst) return fmi2Error;
    if (ni != 0) {
        log_error(inst, "fmi2GetEventIndicators: ni = %lu, but this FMU has no event indicators", (unsigned long)ni);
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{
    Instance *inst = enter(c, FN_GET_CONTINUOUS_STATES);
    size_t i;
    if (!inst || !state_count_matches(inst, "fmi2GetContinuousStates", nx, N_STATES, x)) return fmi2Error;
    for (i = 0; i < nx; i++) x[i] = inst->s.real[i];
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx)
{
    Instance *inst = enter(c, FN_GET_NOMINALS);
    size_t i;
    if (!inst || !state_count_matches(inst, "fmi2GetNominalsOfContinuousStates", nx, N_STATES, x_nominal))
        return fmi2Error;
    for (i = 0; i < nx; i++) x_nominal[i] = 1.0;
    return fmi2OK;
}

/* ---------------------------------------------------------------- Co-Simulation */

static int first_order_only(Instance *inst, const char *function, size_t nvr, const fmi2Integer order[])
{
    size_t i;
    for (i = 0; i < nvr; i++)
        if (order[i] != 1) {
            log_error(inst, "%s: derivative order %d is not supported (allowed range [1, 1]: "
                      "maxOutputDerivativeOrder is 1)", function, order[i]);
            return 0;
        }
    return 1;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    Instance *inst = enter(c, FN_SET_REAL_INPUT_DERIVATIVES);
    size_t i;
    if (!inst || !arrays_present(inst, "fmi2SetRealInputDerivatives", nvr, vr, value) ||
        !arrays_present(inst, "fmi2SetRealInputDerivatives", nvr, order, order) ||
        !first_order_only(inst, "fmi2SetRealInputDerivatives", nvr, order))
        return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (input_index(vr[i]) < 0) {
            log_error(inst, "fmi2SetRealInputDerivatives: value reference %u is not a Real input", vr[i]);
            return fmi2Error;
        }
        if (!isfinite(value[i])) {
            log_error(inst, "fmi2SetRealInputDerivatives: derivative of %s (value reference %u) = %g is not a finite "
                      "number", REAL_VARIABLES[vr[i]].name, vr[i], value[i]);
            return fmi2Error;
        }
    }
    for (i = 0; i < nvr; i++) inst->s.input_derivative[input_index(vr[i])] = value[i];
    return fmi2OK;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    Instance *inst = enter(c, FN_GET_REAL_OUTPUT_DERIVATIVES);
    double rate[N_REAL];
    double *dx = NULL;
    fmi2Status status;
    size_t i;
    if (!inst || !arrays_present(inst, "fmi2GetRealOutputDerivatives", nvr, vr, value) ||
        !arrays_present(inst, "fmi2GetRealOutputDerivatives", nvr, order, order) ||
        !first_order_only(inst, "fmi2GetRealOutputDerivatives", nvr, order))
        return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (!real_reference_known(inst, "fmi2GetRealOutputDerivatives", vr[i])) return fmi2Error;
        if (REAL_VARIABLES[vr[i]].causality != CAUSALITY_OUTPUT) {
            log_error(inst, "fmi2GetRealOutputDerivatives: variable %s (value reference %u) is not an output",
                      REAL_VARIABLES[vr[i]].name, vr[i]);
            return fmi2Error;
        }
    }
    status = ensure_outputs(inst, "fmi2GetRealOutputDerivatives");
    if (status != fmi2OK) return status;
    memset(rate, 0, sizeof rate);
#if N_STATES > 0
    dx = inst->s.real + N_STATES;
    for (i = 0; i < N_STATES; i++) rate[i] = dx[i];
#endif
    model_output_rates(&inst->constants, inst->s.time, inst->s.real, dx, inst->s.input_derivative, rate);
    for (i = 0; i < nvr; i++)
        if (!isfinite(rate[vr[i]])) { /* in-range values can still overflow (huge parameters, 0 times inf) */
            log_discard(inst, "fmi2GetRealOutputDerivatives: the derivative of %s (value reference %u) is not finite "
                        "for the current parameters, inputs and states; no value handed out",
                        REAL_VARIABLES[vr[i]].name, vr[i]);
            return fmi2Discard;
        }
    for (i = 0; i < nvr; i++) value[i] = rate[vr[i]];
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *inst = enter(c, FN_DO_STEP);
    const double t = currentCommunicationPoint, H = communicationStepSize;
    fmi2Status status;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!inst) return fmi2Error;
    if (!isfinite(t) || fabs(t - inst->s.time) > 1e-9 * fmax(1.0, fabs(t))) {
        log_error(inst, "fmi2DoStep: currentCommunicationPoint = %.17g is not the FMU's time %.17g "
                  "(allowed deviation 1e-9 max(1, |t|))", t, inst->s.time);
        return fmi2Error;
    }
    if (!(H > 0.0) || !isfinite(H) || !isfinite(t + H)) {
        log_error(inst, "fmi2DoStep: communicationStepSize = %g is not allowed (allowed range (0, inf), finite)", H);
        return fmi2Error;
    }
    if (!(t + H > t)) { /* the state would move while the time stays */
        log_error(inst, "fmi2DoStep: communicationStepSize = %g does not advance the time from "
                  "currentCommunicationPoint = %.17g (its resolution there is %g)", H, t, nextafter(t, INFINITY) - t);
        return fmi2Error;
    }
    if (!ensure_constants(inst, "fmi2DoStep")) return fmi2Error;
    status = step_to(inst, t, H);
    if (status == fmi2Discard) inst->s.machine_state = MS_STEP_FAILED;
    return status;
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    Instance *inst = enter(c, FN_CANCEL_STEP);
    (void)inst;
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    Instance *inst = enter(c, FN_GET_STATUS);
    (void)s;
    (void)value;
    if (!inst) return fmi2Error;
    return fmi2Discard; /* fmi2DoStep never returns fmi2Pending, so there is no asynchronous status */
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    Instance *inst = enter(c, FN_GET_REAL_STATUS);
    if (!inst) return fmi2Error;
    if (!value) {
        log_error(inst, "fmi2GetRealStatus: value pointer is NULL");
        return fmi2Error;
    }
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = inst->s.last_successful_time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    Instance *inst = enter(c, FN_GET_INTEGER_STATUS);
    (void)s;
    (void)value;
    return inst ? fmi2Discard : fmi2Error;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    Instance *inst = enter(c, FN_GET_BOOLEAN_STATUS);
    if (!inst) return fmi2Error;
    if (!value) {
        log_error(inst, "fmi2GetBooleanStatus: value pointer is NULL");
        return fmi2Error;
    }
    if (s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    Instance *inst = enter(c, FN_GET_STRING_STATUS);
    (void)s;
    (void)value;
    return inst ? fmi2Discard : fmi2Error;
}
