/* The FMI 3.0 layer: the standard's function signatures, its state machine (the table below) and its
 * types, over the version-neutral core (core.c), which does the work. The FMU has Model Exchange and
 * Co-Simulation without event mode (returning early at an event where the importer allows it), scalar
 * variables only (Float64, the UInt64 counters and the
 * enumerations, which FMI 3.0 reads and writes as Int64), no clocks and no structural parameters;
 * in Co-Simulation it reports every accepted internal step to an importer that provides the
 * intermediate-update callback. */
#include <stdlib.h>
#include <string.h>

#include "fmi3_api.h"
#include "framework.h"

/* FMI 3.0 declares the independent variable; it takes the value reference after all others. */
#define TIME_VR ((unsigned int)(N_REAL + N_INTEGER))

/* ---------------------------------------------------------------- state machine */

#define CS_READABLE (MS_INITIALIZATION | MS_STEP_COMPLETE | MS_STEP_FAILED | MS_TERMINATED | MS_ERROR | MS_INTERMEDIATE)
#define ME_READABLE (MS_INITIALIZATION | MS_EVENT | MS_CONTINUOUS | MS_TERMINATED | MS_ERROR)
#define CS_SETTABLE (MS_INSTANTIATED | MS_INITIALIZATION | MS_STEP_COMPLETE | MS_INTERMEDIATE)
#define ME_SETTABLE (MS_INSTANTIATED | MS_INITIALIZATION | MS_EVENT | MS_CONTINUOUS)
#define CS_OUTSIDE_CALLBACKS (CS_ANY & ~MS_INTERMEDIATE)

typedef enum {
    FN_SET_DEBUG_LOGGING,
    FN_ENTER_INITIALIZATION_MODE,
    FN_EXIT_INITIALIZATION_MODE,
    FN_ENTER_EVENT_MODE,
    FN_TERMINATE,
    FN_RESET,
    FN_GET,
    FN_SET,
    FN_CLOCKS,
    FN_GET_NUMBER_OF_VARIABLE_DEPENDENCIES,
    FN_GET_VARIABLE_DEPENDENCIES,
    FN_GET_FMU_STATE,
    FN_SET_FMU_STATE,
    FN_FREE_FMU_STATE,
    FN_SERIALIZED_SIZE,
    FN_SERIALIZE,
    FN_DESERIALIZE,
    FN_GET_DIRECTIONAL_DERIVATIVE,
    FN_GET_ADJOINT_DERIVATIVE,
    FN_ENTER_CONFIGURATION_MODE,
    FN_EXIT_CONFIGURATION_MODE,
    FN_EVALUATE_DISCRETE_STATES,
    FN_UPDATE_DISCRETE_STATES,
    FN_ENTER_CONTINUOUS_TIME_MODE,
    FN_COMPLETED_INTEGRATOR_STEP,
    FN_SET_TIME,
    FN_SET_CONTINUOUS_STATES,
    FN_GET_CONTINUOUS_STATE_DERIVATIVES,
    FN_GET_EVENT_INDICATORS,
    FN_GET_CONTINUOUS_STATES,
    FN_GET_NOMINALS,
    FN_GET_NUMBER_OF_EVENT_INDICATORS,
    FN_GET_NUMBER_OF_CONTINUOUS_STATES,
    FN_ENTER_STEP_MODE,
    FN_GET_OUTPUT_DERIVATIVES,
    FN_DO_STEP,
    FN_ACTIVATE_MODEL_PARTITION,
    FN_COUNT
} Function;

/* For each function (or family of functions), the states it may be called in: Co-Simulation, Model
 * Exchange (FMI 3.0 sections 3.2 and 4.2). A zero mask means the function does not belong to that
 * interface. The getters and setters of every type share one rule. */
static const struct {
    unsigned cs, me;
} CALL_RULES[FN_COUNT] = {
    [FN_SET_DEBUG_LOGGING] = {CS_ANY, ME_ANY},
    [FN_ENTER_INITIALIZATION_MODE] = {MS_INSTANTIATED, MS_INSTANTIATED},
    [FN_EXIT_INITIALIZATION_MODE] = {MS_INITIALIZATION, MS_INITIALIZATION},
    [FN_ENTER_EVENT_MODE] = {0, MS_EVENT | MS_CONTINUOUS}, /* Co-Simulation without event mode */
    [FN_TERMINATE] = {MS_STEP_COMPLETE | MS_STEP_FAILED, MS_EVENT | MS_CONTINUOUS},
    [FN_RESET] = {CS_OUTSIDE_CALLBACKS, ME_ANY},
    [FN_GET] = {CS_READABLE, ME_READABLE},
    [FN_SET] = {CS_SETTABLE, ME_SETTABLE},
    [FN_CLOCKS] = {CS_ANY, ME_ANY},
    [FN_GET_NUMBER_OF_VARIABLE_DEPENDENCIES] = {CS_ANY, ME_ANY},
    [FN_GET_VARIABLE_DEPENDENCIES] = {CS_ANY, ME_ANY},
    [FN_GET_FMU_STATE] = {CS_OUTSIDE_CALLBACKS, ME_ANY},
    [FN_SET_FMU_STATE] = {CS_OUTSIDE_CALLBACKS, ME_ANY},
    [FN_FREE_FMU_STATE] = {CS_OUTSIDE_CALLBACKS, ME_ANY},
    [FN_SERIALIZED_SIZE] = {CS_OUTSIDE_CALLBACKS, ME_ANY},
    [FN_SERIALIZE] = {CS_OUTSIDE_CALLBACKS, ME_ANY},
    [FN_DESERIALIZE] = {CS_OUTSIDE_CALLBACKS, ME_ANY},
    [FN_GET_DIRECTIONAL_DERIVATIVE] = {CS_READABLE & ~MS_INTERMEDIATE, ME_READABLE},
    [FN_GET_ADJOINT_DERIVATIVE] = {CS_READABLE & ~MS_INTERMEDIATE, ME_READABLE},
    [FN_ENTER_CONFIGURATION_MODE] = {MS_INSTANTIATED | MS_STEP_COMPLETE, MS_INSTANTIATED | MS_EVENT},
    [FN_EXIT_CONFIGURATION_MODE] = {0, 0}, /* no configuration mode without structural parameters */
    [FN_EVALUATE_DISCRETE_STATES] = {0, MS_EVENT},
    [FN_UPDATE_DISCRETE_STATES] = {0, MS_EVENT},
    [FN_ENTER_CONTINUOUS_TIME_MODE] = {0, MS_EVENT},
    [FN_COMPLETED_INTEGRATOR_STEP] = {0, MS_CONTINUOUS},
    [FN_SET_TIME] = {0, MS_EVENT | MS_CONTINUOUS},
    [FN_SET_CONTINUOUS_STATES] = {0, MS_CONTINUOUS},
    [FN_GET_CONTINUOUS_STATE_DERIVATIVES] = {0, ME_READABLE},
    [FN_GET_EVENT_INDICATORS] = {0, ME_READABLE},
    [FN_GET_CONTINUOUS_STATES] = {0, ME_READABLE},
    [FN_GET_NOMINALS] = {0, ME_READABLE},
    [FN_GET_NUMBER_OF_EVENT_INDICATORS] = {0, ME_ANY},
    [FN_GET_NUMBER_OF_CONTINUOUS_STATES] = {0, ME_ANY},
    [FN_ENTER_STEP_MODE] = {MS_EVENT, 0}, /* Event Mode, which this FMU's Co-Simulation never enters */
    [FN_GET_OUTPUT_DERIVATIVES] = {MS_STEP_COMPLETE | MS_STEP_FAILED | MS_TERMINATED | MS_ERROR, 0},
    [FN_DO_STEP] = {MS_STEP_COMPLETE, 0},
    [FN_ACTIVATE_MODEL_PARTITION] = {0, 0}, /* Scheduled Execution only */
};

/* The state names of FMI 3.0, by bit position of the MS_ states. */
static const char *const STATE_NAMES[] = {
    "Instantiated",         "Initialization Mode", "Step Mode", "Step Mode after a discarded step", "Event Mode",
    "Continuous-Time Mode", "Terminated",          "Error",     "Intermediate Update Mode"};

/* The instance, checked against the state machine for `function`: NULL means return fmi3Error. */
static Instance *enter(fmi3Instance instance, Function fn, const char *function)
{
    Instance *inst = (Instance *)instance;
    if (!inst) return NULL;
    return core_call_allowed(inst, function, CALL_RULES[fn].cs, CALL_RULES[fn].me) ? inst : NULL;
}

#define CALL(fn, expression) \
    do { \
        Instance *inst = enter(instance, fn, __func__); \
        if (!inst) return fmi3Error; \
        return (fmi3Status)(expression); \
    } while (0)

static void emit_fmi3(const Instance *inst, Status status, const char *category, const char *message)
{
    const fmi3LogMessageCallback logger = (fmi3LogMessageCallback)inst->api_logger;
    if (logger) logger(inst->environment, (fmi3Status)status, category, message);
}

/* The importer's intermediate-update callback at t; this FMU never returns early. */
static void call_intermediate_update(Instance *inst, double t, fmi3Boolean set_requested, fmi3Boolean get_allowed,
                                     fmi3Boolean step_finished)
{
    const fmi3IntermediateUpdateCallback callback = (fmi3IntermediateUpdateCallback)inst->api_intermediate;
    fmi3Boolean early_return_requested = fmi3False;
    fmi3Float64 early_return_time = t;
    callback(inst->environment, t, set_requested, get_allowed, step_finished, fmi3False, &early_return_requested,
             &early_return_time);
}

/* At an accepted internal step: the outputs may be read (they are the variables with intermediateUpdate = true),
 * nothing may be set. */
static void report_fmi3(Instance *inst, double t) { call_intermediate_update(inst, t, fmi3False, fmi3True, fmi3True); }

/* At the start of a step, asking for the inputs the importer registered at t, the step's end
 * (intermediateStepFinished = false: a point the step will pass, as a stage of a Runge-Kutta step is); they may be
 * set, nothing may be read. */
static void request_fmi3(Instance *inst, double t)
{
    call_intermediate_update(inst, t, fmi3True, fmi3False, fmi3False);
}

/* FMI 3.0 gives every array its length: for scalar variables it must equal the number of references. */
static int one_value_each(Instance *inst, const char *function, size_t nvr, size_t n_values)
{
    if (nvr == n_values) return 1;
    log_error(inst, "%s: nValues = %lu, but the %lu variables are scalars (nValues must equal nValueReferences)",
              function, (unsigned long)n_values, (unsigned long)nvr);
    return 0;
}

/* ---------------------------------------------------------------- instantiation */

static Instance *instantiate(const char *function, Interface type, fmi3String name, fmi3String token,
                             fmi3Boolean logging_on, fmi3InstanceEnvironment environment, fmi3LogMessageCallback logger)
{
    Instance *inst = core_instantiate(function, type, name, token, emit_fmi3, (void (*)(void))logger, environment,
                                      calloc, free, logging_on);
    if (inst) inst->state_names = STATE_NAMES;
    return inst;
}

/* Logs through the importer's logger before an instance exists. */
static void refuse(const char *name, fmi3InstanceEnvironment environment, fmi3LogMessageCallback logger,
                   const char *message)
{
    Instance reporter;
    memset(&reporter, 0, sizeof reporter);
    reporter.emit = emit_fmi3;
    reporter.api_logger = (void (*)(void))logger;
    reporter.environment = environment;
    reporter.name = (char *)(name ? name : "?");
    log_error(&reporter, "%s", message);
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    (void)resourcePath;
    (void)visible;
    return instantiate(__func__, INTERFACE_MODEL_EXCHANGE, instanceName, instantiationToken, loggingOn,
                       instanceEnvironment, logMessage);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    Instance *inst;
    size_t i;
    int asks_inputs = 0, reports_outputs = 0;
    (void)resourcePath;
    (void)visible;
    if (eventModeUsed) {
        refuse(instanceName, instanceEnvironment, logMessage,
               "fmi3InstantiateCoSimulation: eventModeUsed = true, but this FMU has no event mode (hasEventMode is "
               "false): instantiate with eventModeUsed = false");
        return NULL;
    }
    inst = instantiate(__func__, INTERFACE_CO_SIMULATION, instanceName, instantiationToken, loggingOn,
                       instanceEnvironment, logMessage);
    if (!inst) return NULL;
    inst->return_at_events = earlyReturnAllowed ? 1 : 0;
    if (nRequiredIntermediateVariables > 0 && !requiredIntermediateVariables) {
        log_error(inst, "fmi3InstantiateCoSimulation: requiredIntermediateVariables is NULL for %lu variables",
                  (unsigned long)nRequiredIntermediateVariables);
        core_free(inst);
        return NULL;
    }
    for (i = 0; i < nRequiredIntermediateVariables; i++) {
        const fmi3ValueReference vr = requiredIntermediateVariables[i];
        const int input = vr < N_REAL ? core_input_index(vr) : -1;
        if (input >= 0) {
            inst->inputs_requested[input] = 1;
            asks_inputs = 1;
        } else if (vr < N_REAL && core_variable(vr)->causality == CAUSALITY_OUTPUT) {
            reports_outputs = 1;
        } else {
            log_error(inst,
                      "fmi3InstantiateCoSimulation: requiredIntermediateVariables[%lu] = %u is not a Float64 "
                      "output or input (only those have intermediateUpdate = true)",
                      (unsigned long)i, vr);
            core_free(inst);
            return NULL;
        }
    }
    if (intermediateUpdate) {
        inst->api_intermediate = (void (*)(void))intermediateUpdate;
        /* an importer that registered only inputs is asked for them, not told of every internal step */
        if (reports_outputs || !asks_inputs) inst->report_step = report_fmi3;
        if (asks_inputs) inst->request_inputs = request_fmi3;
    }
    return inst;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    refuse(instanceName, instanceEnvironment, logMessage,
           "fmi3InstantiateScheduledExecution: this FMU has Model Exchange and Co-Simulation, not Scheduled Execution");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) { core_free((Instance *)instance); }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    CALL(FN_SET_DEBUG_LOGGING, core_set_logging(inst, __func__, loggingOn, nCategories, categories));
}

/* ---------------------------------------------------------------- life cycle */

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    Instance *inst = enter(instance, FN_ENTER_INITIALIZATION_MODE, __func__);
    Status status;
    (void)toleranceDefined;
    (void)tolerance;
    if (!inst) return fmi3Error;
    status = core_setup(inst, __func__, startTime, stopTimeDefined, stopTime);
    if (status == STATUS_OK) inst->s.machine_state = MS_INITIALIZATION;
    return (fmi3Status)status;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    CALL(FN_EXIT_INITIALIZATION_MODE, core_exit_initialization(inst, __func__));
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    Instance *inst = enter(instance, FN_ENTER_EVENT_MODE, __func__);
    if (!inst) return fmi3Error;
    inst->s.machine_state = MS_EVENT;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    Instance *inst = enter(instance, FN_TERMINATE, __func__);
    if (!inst) return fmi3Error;
    inst->s.machine_state = MS_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    Instance *inst = enter(instance, FN_RESET, __func__);
    if (!inst) return fmi3Error;
    core_reset(inst);
    return fmi3OK;
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance)
{
    Instance *inst = enter(instance, FN_ENTER_CONFIGURATION_MODE, __func__);
    if (!inst) return fmi3Error;
    log_error(inst, "fmi3EnterConfigurationMode: this FMU has no structural parameters to configure");
    return fmi3Error;
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance)
{
    return enter(instance, FN_EXIT_CONFIGURATION_MODE, __func__) ? fmi3OK : fmi3Error;
}

/* ---------------------------------------------------------------- Float64 */

/* In Intermediate Update Mode only the outputs (and time) may be read. */
static int readable_now(Instance *inst, const char *function, const fmi3ValueReference vr[], size_t n)
{
    size_t i;
    if (inst->s.machine_state != MS_INTERMEDIATE) return 1;
    if (inst->asking_inputs) {
        log_error(inst,
                  "%s: the FMU asks for inputs at the step's end (intermediateVariableGetAllowed = false): "
                  "nothing can be read until it reports a step",
                  function);
        return 0;
    }
    i = core_first_not_output(vr, n, TIME_VR);
    if (i == n) return 1;
    if (core_variable(vr[i]) == NULL)
        log_error(inst,
                  "%s: unknown value reference %u: in Intermediate Update Mode only the outputs "
                  "(intermediateUpdate = true) can be read",
                  function, vr[i]);
    else
        log_error(inst,
                  "%s: variable %s (value reference %u) is not an output: in Intermediate Update Mode only the "
                  "outputs (intermediateUpdate = true) can be read",
                  function, core_variable(vr[i])->name, vr[i]);
    return 0;
}

/* In Intermediate Update Mode only the registered inputs, and only when the FMU asks for them. */
static int settable_now(Instance *inst, const fmi3ValueReference vr[], size_t n)
{
    size_t i;
    if (inst->s.machine_state != MS_INTERMEDIATE) return 1;
    for (i = 0; i < n; i++) {
        const int input = vr[i] < N_REAL ? core_input_index(vr[i]) : -1;
        if (!inst->asking_inputs || input < 0 || !inst->inputs_requested[input]) {
            log_error(inst,
                      "fmi3SetFloat64: %s (value reference %u) cannot be set here: in Intermediate Update Mode "
                      "only the inputs registered in requiredIntermediateVariables, when the FMU asks for them "
                      "(intermediateVariableSetRequested = true)",
                      vr[i] < N_REAL ? core_variable(vr[i])->name : "?", vr[i]);
            return 0;
        }
    }
    return 1;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues)
{
    Instance *inst = enter(instance, FN_GET, __func__);
    size_t i, start = 0;
    if (!inst) return fmi3Error;
    if (!one_value_each(inst, __func__, nvr, nValues) || !core_arrays_present(inst, __func__, nvr, vr, values) ||
        !readable_now(inst, __func__, vr, nvr))
        return fmi3Error;
    for (i = 0; i < nvr && vr[i] != TIME_VR; i++) continue;
    if (i == nvr) return (fmi3Status)core_get_real(inst, __func__, vr, nvr, values); /* time not asked for */
    /* time is not among the core's variables: the runs between its references go to the core */
    for (i = 0; i <= nvr; i++) {
        if (i == nvr || vr[i] == TIME_VR) {
            if (i > start) {
                const Status status = core_get_real(inst, __func__, vr + start, i - start, values + start);
                if (status != STATUS_OK) return (fmi3Status)status;
            }
            if (i < nvr) values[i] = inst->s.time;
            start = i + 1;
        }
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 values[],
                          size_t nValues)
{
    Instance *inst = enter(instance, FN_SET, __func__);
    size_t i;
    if (!inst) return fmi3Error;
    if (!one_value_each(inst, __func__, nvr, nValues) || !core_arrays_present(inst, __func__, nvr, vr, values))
        return fmi3Error;
    if (!settable_now(inst, vr, nvr)) return fmi3Error;
    for (i = 0; i < nvr; i++)
        if (vr[i] == TIME_VR) {
            log_error(inst,
                      "fmi3SetFloat64: variable time (value reference %u) is the independent variable: it moves "
                      "with fmi3SetTime (Model Exchange) or fmi3DoStep (Co-Simulation)",
                      vr[i]);
            return fmi3Error;
        }
    return (fmi3Status)core_set_real(inst, __func__, vr, nvr, values);
}

/* ---------------------------------------------------------------- Int64 and UInt64 */

/* The enumerations, taylor_order and gbs_columns are parameters accessed as Int64, the counters outputs accessed as
 * UInt64: each variable through the function of its own type. */
static int integer_type_matches(Instance *inst, const char *function, const fmi3ValueReference vr[], size_t n,
                                int counters)
{
    size_t i;
    for (i = 0; i < n; i++) {
        const VariableInfo *v = vr[i] >= N_REAL ? core_variable(vr[i]) : NULL; /* the core names unknown ones */
        if (v && (v->causality == CAUSALITY_OUTPUT) != counters) {
            log_error(inst, "%s: variable %s (value reference %u) is %s: use %s", function, v->name, vr[i],
                      counters ? "an Int64 parameter" : "a UInt64 counter",
                      counters ? "fmi3GetInt64 or fmi3SetInt64" : "fmi3GetUInt64");
            return 0;
        }
    }
    return 1;
}

static fmi3Status get_integers(fmi3Instance instance, const char *function, const fmi3ValueReference vr[], size_t nvr,
                               void *values, size_t nValues, int counters)
{
    Instance *inst = enter(instance, FN_GET, function);
    if (!inst) return fmi3Error;
    if (!one_value_each(inst, function, nvr, nValues) || !core_arrays_present(inst, function, nvr, vr, values) ||
        !readable_now(inst, function, vr, nvr) || !integer_type_matches(inst, function, vr, nvr, counters))
        return fmi3Error;
    return (fmi3Status)core_get_integer(inst, function, vr, nvr, values, 8);
}

fmi3Status fmi3GetInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Int64 values[],
                        size_t nValues)
{
    return get_integers(instance, __func__, vr, nvr, values, nValues, 0);
}

fmi3Status fmi3GetUInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 values[],
                         size_t nValues)
{
    return get_integers(instance, __func__, vr, nvr, values, nValues, 1);
}

fmi3Status fmi3SetInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int64 values[],
                        size_t nValues)
{
    Instance *inst = enter(instance, FN_SET, __func__);
    if (!inst) return fmi3Error;
    if (!one_value_each(inst, __func__, nvr, nValues) || !core_arrays_present(inst, __func__, nvr, vr, values) ||
        !integer_type_matches(inst, __func__, vr, nvr, 0))
        return fmi3Error;
    return (fmi3Status)core_set_integer(inst, __func__, vr, nvr, values, 8);
}

fmi3Status fmi3SetUInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 values[],
                         size_t nValues)
{
    Instance *inst = enter(instance, FN_SET, __func__);
    const VariableInfo *v;
    (void)values;
    if (!inst) return fmi3Error;
    if (!one_value_each(inst, __func__, nvr, nValues) || !core_arrays_present(inst, __func__, nvr, vr, values) ||
        !integer_type_matches(inst, __func__, vr, nvr, 1))
        return fmi3Error;
    if (nvr == 0) return fmi3OK;
    v = core_variable(vr[0]);
    if (v) { /* every UInt64 variable is a counter, which only the FMU sets */
        log_error(inst,
                  "fmi3SetUInt64: variable %s (value reference %u) is a calculated output (a counter): only the "
                  "FMU sets it",
                  v->name, vr[0]);
        return fmi3Error;
    }
    return (fmi3Status)core_no_such_variables(inst, __func__, nvr, vr, "UInt64");
}

/* ---------------------------------------------------------------- the types this FMU has no variables of */

#define NO_VARIABLES(function, rule, type, qualifier, type_name) \
    fmi3Status function(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, qualifier type values[], \
                        size_t nValues) \
    { \
        Instance *inst = enter(instance, rule, __func__); \
        (void)values; \
        if (!inst || !one_value_each(inst, __func__, nvr, nValues)) return fmi3Error; \
        return (fmi3Status)core_no_such_variables(inst, __func__, nvr, vr, type_name); \
    }

NO_VARIABLES(fmi3GetFloat32, FN_GET, fmi3Float32, , "Float32")
NO_VARIABLES(fmi3GetInt8, FN_GET, fmi3Int8, , "Int8")
NO_VARIABLES(fmi3GetUInt8, FN_GET, fmi3UInt8, , "UInt8")
NO_VARIABLES(fmi3GetInt16, FN_GET, fmi3Int16, , "Int16")
NO_VARIABLES(fmi3GetUInt16, FN_GET, fmi3UInt16, , "UInt16")
NO_VARIABLES(fmi3GetInt32, FN_GET, fmi3Int32, , "Int32")
NO_VARIABLES(fmi3GetUInt32, FN_GET, fmi3UInt32, , "UInt32")
NO_VARIABLES(fmi3GetBoolean, FN_GET, fmi3Boolean, , "Boolean")
NO_VARIABLES(fmi3GetString, FN_GET, fmi3String, , "String")
NO_VARIABLES(fmi3SetFloat32, FN_SET, fmi3Float32, const, "Float32")
NO_VARIABLES(fmi3SetInt8, FN_SET, fmi3Int8, const, "Int8")
NO_VARIABLES(fmi3SetUInt8, FN_SET, fmi3UInt8, const, "UInt8")
NO_VARIABLES(fmi3SetInt16, FN_SET, fmi3Int16, const, "Int16")
NO_VARIABLES(fmi3SetUInt16, FN_SET, fmi3UInt16, const, "UInt16")
NO_VARIABLES(fmi3SetInt32, FN_SET, fmi3Int32, const, "Int32")
NO_VARIABLES(fmi3SetUInt32, FN_SET, fmi3UInt32, const, "UInt32")
NO_VARIABLES(fmi3SetBoolean, FN_SET, fmi3Boolean, const, "Boolean")
NO_VARIABLES(fmi3SetString, FN_SET, fmi3String, const, "String")

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nValues)
{
    Instance *inst = enter(instance, FN_GET, __func__);
    (void)valueSizes, (void)values;
    if (!inst || !one_value_each(inst, __func__, nvr, nValues)) return fmi3Error;
    return (fmi3Status)core_no_such_variables(inst, __func__, nvr, vr, "Binary");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues)
{
    Instance *inst = enter(instance, FN_SET, __func__);
    (void)valueSizes, (void)values;
    if (!inst || !one_value_each(inst, __func__, nvr, nValues)) return fmi3Error;
    return (fmi3Status)core_no_such_variables(inst, __func__, nvr, vr, "Binary");
}

/* Clocks: this FMU has none, so every clock function refers to unknown variables. */
#define NO_CLOCKS(function, ...) \
    fmi3Status function(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, __VA_ARGS__) \
    { \
        Instance *inst = enter(instance, FN_CLOCKS, __func__); \
        if (!inst) return fmi3Error; \
        return (fmi3Status)core_no_such_variables(inst, __func__, nvr, vr, "Clock"); \
    }

NO_CLOCKS(fmi3GetClock, fmi3Clock values[])
NO_CLOCKS(fmi3SetClock, const fmi3Clock values[])
NO_CLOCKS(fmi3GetIntervalDecimal, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
NO_CLOCKS(fmi3GetIntervalFraction, fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
NO_CLOCKS(fmi3GetShiftDecimal, fmi3Float64 shifts[])
NO_CLOCKS(fmi3GetShiftFraction, fmi3UInt64 counters[], fmi3UInt64 resolutions[])
NO_CLOCKS(fmi3SetIntervalDecimal, const fmi3Float64 intervals[])
NO_CLOCKS(fmi3SetIntervalFraction, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
NO_CLOCKS(fmi3SetShiftDecimal, const fmi3Float64 shifts[])
NO_CLOCKS(fmi3SetShiftFraction, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime)
{
    (void)clockReference;
    (void)activationTime;
    return enter(instance, FN_ACTIVATE_MODEL_PARTITION, __func__) ? fmi3OK : fmi3Error;
}

/* ---------------------------------------------------------------- what this FMU does not provide */

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies)
{
    Instance *inst = enter(instance, FN_GET_NUMBER_OF_VARIABLE_DEPENDENCIES, __func__);
    (void)valueReference, (void)nDependencies;
    if (!inst) return fmi3Error;
    log_error(inst, "fmi3GetNumberOfVariableDependencies: not provided (providesPerElementDependencies is false; the "
                    "model description's ModelStructure lists the dependencies)");
    return fmi3Error;
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies)
{
    Instance *inst = enter(instance, FN_GET_VARIABLE_DEPENDENCIES, __func__);
    (void)dependent, (void)elementIndicesOfDependent, (void)independents, (void)elementIndicesOfIndependents;
    (void)dependencyKinds, (void)nDependencies;
    if (!inst) return fmi3Error;
    log_error(inst, "fmi3GetVariableDependencies: not provided (providesPerElementDependencies is false; the model "
                    "description's ModelStructure lists the dependencies)");
    return fmi3Error;
}

/* The seed and sensitivity arrays hold one value per scalar variable of their side. */
static int derivative_sizes_match(Instance *inst, const char *function, size_t nSeed, size_t seeded, const char *side,
                                  size_t nSensitivity, size_t sensed, const char *other)
{
    if (nSeed == seeded && nSensitivity == sensed) return 1;
    log_error(inst,
              "%s: nSeed = %lu and nSensitivity = %lu, but there are %lu %s and %lu %s, all scalars "
              "(nSeed must equal n%s, nSensitivity n%s)",
              function, (unsigned long)nSeed, (unsigned long)nSensitivity, (unsigned long)seeded, side,
              (unsigned long)sensed, other, side[0] == 'k' ? "Knowns" : "Unknowns",
              side[0] == 'k' ? "Unknowns" : "Knowns");
    return 0;
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    Instance *inst = enter(instance, FN_GET_DIRECTIONAL_DERIVATIVE, __func__);
    if (!inst) return fmi3Error;
    if (!derivative_sizes_match(inst, __func__, nSeed, nKnowns, "knowns", nSensitivity, nUnknowns, "unknowns"))
        return fmi3Error;
    return (fmi3Status)core_get_directional_derivative(inst, __func__, unknowns, nUnknowns, knowns, nKnowns, seed,
                                                       sensitivity);
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    Instance *inst = enter(instance, FN_GET_ADJOINT_DERIVATIVE, __func__);
    if (!inst) return fmi3Error;
    if (!derivative_sizes_match(inst, __func__, nSeed, nUnknowns, "unknowns", nSensitivity, nKnowns, "knowns"))
        return fmi3Error;
    return (fmi3Status)core_get_adjoint_derivative(inst, __func__, unknowns, nUnknowns, knowns, nKnowns, seed,
                                                   sensitivity);
}

/* ---------------------------------------------------------------- FMU state */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    CALL(FN_GET_FMU_STATE, core_get_state(inst, __func__, FMUState));
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    CALL(FN_SET_FMU_STATE, core_set_state(inst, __func__, FMUState));
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    CALL(FN_FREE_FMU_STATE, core_free_state(inst, __func__, FMUState));
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size)
{
    CALL(FN_SERIALIZED_SIZE, core_serialized_size(inst, __func__, FMUState, size));
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[], size_t size)
{
    CALL(FN_SERIALIZE, core_serialize(inst, __func__, FMUState, serializedState, size));
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState)
{
    CALL(FN_DESERIALIZE, core_deserialize(inst, __func__, serializedState, size, FMUState));
}

/* ---------------------------------------------------------------- events (Model Exchange: the constraints') */

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance)
{
    return enter(instance, FN_EVALUATE_DISCRETE_STATES, __func__) ? fmi3OK : fmi3Error;
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime)
{
    Instance *inst = enter(instance, FN_UPDATE_DISCRETE_STATES, __func__);
    if (!inst) return fmi3Error;
    if (!discreteStatesNeedUpdate || !terminateSimulation || !nominalsOfContinuousStatesChanged ||
        !valuesOfContinuousStatesChanged || !nextEventTimeDefined || !nextEventTime) {
        log_error(inst, "fmi3UpdateDiscreteStates: every result pointer must be non-NULL");
        return fmi3Error;
    }
    {
        int changed;
        const Status status = core_new_discrete_states(inst, __func__, &changed);
        *discreteStatesNeedUpdate = fmi3False;
        *terminateSimulation = fmi3False;
        *nominalsOfContinuousStatesChanged = fmi3False;
        *valuesOfContinuousStatesChanged = changed ? fmi3True : fmi3False;
        *nextEventTimeDefined = fmi3False;
        *nextEventTime = 0.0;
        return (fmi3Status)status;
    }
}

/* ---------------------------------------------------------------- Model Exchange */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance)
{
    Instance *inst = enter(instance, FN_ENTER_CONTINUOUS_TIME_MODE, __func__);
    if (!inst) return fmi3Error;
    inst->s.machine_state = MS_CONTINUOUS;
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
{
    Instance *inst = enter(instance, FN_COMPLETED_INTEGRATOR_STEP, __func__);
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!inst) return fmi3Error;
    if (!enterEventMode || !terminateSimulation) {
        log_error(inst, "fmi3CompletedIntegratorStep: enterEventMode and terminateSimulation must not be NULL");
        return fmi3Error;
    }
    *enterEventMode = fmi3False;
    *terminateSimulation = fmi3False;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    CALL(FN_SET_TIME, core_set_time(inst, __func__, time));
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates)
{
    CALL(FN_SET_CONTINUOUS_STATES, core_set_continuous_states(inst, __func__, continuousStates, nContinuousStates));
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[], size_t nContinuousStates)
{
    CALL(FN_GET_CONTINUOUS_STATE_DERIVATIVES, core_get_derivatives(inst, __func__, derivatives, nContinuousStates));
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators)
{
    CALL(FN_GET_EVENT_INDICATORS, core_get_event_indicators(inst, __func__, eventIndicators, nEventIndicators));
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates)
{
    CALL(FN_GET_CONTINUOUS_STATES, core_get_continuous_states(inst, __func__, continuousStates, nContinuousStates));
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates)
{
    CALL(FN_GET_NOMINALS, core_get_nominals(inst, __func__, nominals, nContinuousStates));
}

/* Writes `count` through `out` after checking it. */
static fmi3Status number_of(fmi3Instance instance, Function fn, const char *function, size_t *out, size_t count)
{
    Instance *inst = enter(instance, fn, function);
    if (!inst) return fmi3Error;
    if (!out) {
        log_error(inst, "%s: the result pointer is NULL", function);
        return fmi3Error;
    }
    *out = count;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators)
{
    return number_of(instance, FN_GET_NUMBER_OF_EVENT_INDICATORS, __func__, nEventIndicators,
                     (size_t)N_EVENT_INDICATORS);
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates)
{
    return number_of(instance, FN_GET_NUMBER_OF_CONTINUOUS_STATES, __func__, nContinuousStates, (size_t)N_STATES);
}

/* ---------------------------------------------------------------- Co-Simulation */

fmi3Status fmi3EnterStepMode(fmi3Instance instance)
{
    return enter(instance, FN_ENTER_STEP_MODE, __func__) ? fmi3OK : fmi3Error;
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues)
{
    Instance *inst = enter(instance, FN_GET_OUTPUT_DERIVATIVES, __func__);
    if (!inst) return fmi3Error;
    if (!one_value_each(inst, __func__, nvr, nValues)) return fmi3Error;
    return (fmi3Status)core_get_output_derivatives(inst, __func__, vr, nvr, orders, values);
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    Instance *inst = enter(instance, FN_DO_STEP, __func__);
    Status status;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!inst) return fmi3Error;
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime) {
        log_error(inst, "fmi3DoStep: eventHandlingNeeded, terminateSimulation, earlyReturn and lastSuccessfulTime "
                        "must not be NULL");
        return fmi3Error;
    }
    status = core_do_step(inst, __func__, currentCommunicationPoint, communicationStepSize);
    *eventHandlingNeeded = fmi3False; /* the FMU handled its events inside the step */
    *terminateSimulation = fmi3False;
    /* stopped at an event it handled, where the importer allowed that */
    *earlyReturn = status == STATUS_OK && inst->s.time < currentCommunicationPoint + communicationStepSize;
    *lastSuccessfulTime = inst->s.last_successful_time;
    return (fmi3Status)status;
}
