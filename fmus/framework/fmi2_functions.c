/* The FMI 2.0 layer: the standard's function signatures, its state machine (the table below) and its
 * types, over the version-neutral core (core.c), which does the work. Models supply only physics
 * (see framework.h). */
#include <string.h>

#include "fmi2_api.h"
#include "framework.h"

/* ---------------------------------------------------------------- state machine */

#define CS_READABLE (MS_INITIALIZATION | MS_STEP_COMPLETE | MS_STEP_FAILED | MS_TERMINATED | MS_ERROR)
#define ME_READABLE (MS_INITIALIZATION | MS_EVENT | MS_CONTINUOUS | MS_TERMINATED | MS_ERROR)

typedef enum {
    FN_SET_DEBUG_LOGGING,
    FN_SETUP_EXPERIMENT,
    FN_ENTER_INITIALIZATION_MODE,
    FN_EXIT_INITIALIZATION_MODE,
    FN_TERMINATE,
    FN_RESET,
    FN_GET_REAL,
    FN_GET_INTEGER,
    FN_GET_BOOLEAN,
    FN_GET_STRING,
    FN_SET_REAL,
    FN_SET_INTEGER,
    FN_SET_BOOLEAN,
    FN_SET_STRING,
    FN_GET_FMU_STATE,
    FN_SET_FMU_STATE,
    FN_FREE_FMU_STATE,
    FN_SERIALIZED_SIZE,
    FN_SERIALIZE,
    FN_DESERIALIZE,
    FN_GET_DIRECTIONAL_DERIVATIVE,
    FN_ENTER_EVENT_MODE,
    FN_NEW_DISCRETE_STATES,
    FN_ENTER_CONTINUOUS_TIME_MODE,
    FN_COMPLETED_INTEGRATOR_STEP,
    FN_SET_TIME,
    FN_SET_CONTINUOUS_STATES,
    FN_GET_DERIVATIVES,
    FN_GET_EVENT_INDICATORS,
    FN_GET_CONTINUOUS_STATES,
    FN_GET_NOMINALS,
    FN_SET_REAL_INPUT_DERIVATIVES,
    FN_GET_REAL_OUTPUT_DERIVATIVES,
    FN_DO_STEP,
    FN_CANCEL_STEP,
    FN_GET_STATUS,
    FN_GET_REAL_STATUS,
    FN_GET_INTEGER_STATUS,
    FN_GET_BOOLEAN_STATUS,
    FN_GET_STRING_STATUS,
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

/* The instance behind c, checked against the state machine: NULL means return fmi2Error. */
static Instance *enter(fmi2Component c, Function fn)
{
    Instance *inst = (Instance *)c;
    if (!inst) return NULL;
    return core_call_allowed(inst, CALL_RULES[fn].name, CALL_RULES[fn].cs, CALL_RULES[fn].me) ? inst : NULL;
}

#define NAME(fn) CALL_RULES[fn].name
#define CALL(fn, expression) \
    do { \
        Instance *inst = enter(c, fn); \
        if (!inst) return fmi2Error; \
        return (fmi2Status)(expression); \
    } while (0)

/* The importer's logger gets the message as its format's only argument: a '%' in it is never read. */
static void emit_fmi2(const Instance *inst, Status status, const char *category, const char *message)
{
    const fmi2CallbackLogger logger = (fmi2CallbackLogger)inst->api_logger;
    if (logger) logger(inst->environment, inst->name, (fmi2Status)status, category, message);
}

/* ---------------------------------------------------------------- common functions */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions) return NULL;
    if (fmuType != fmi2ModelExchange && fmuType != fmi2CoSimulation) {
        Instance reporter;
        memset(&reporter, 0, sizeof reporter);
        reporter.emit = emit_fmi2;
        reporter.api_logger = (void (*)(void))functions->logger;
        reporter.environment = functions->componentEnvironment;
        reporter.name = (char *)(instanceName ? instanceName : "?");
        log_error(&reporter, "fmi2Instantiate: fmuType = %d is neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)",
                  (int)fmuType);
        return NULL;
    }
    return core_instantiate(
        "fmi2Instantiate", fmuType == fmi2CoSimulation ? INTERFACE_CO_SIMULATION : INTERFACE_MODEL_EXCHANGE,
        instanceName, fmuGUID, emit_fmi2, (void (*)(void))functions->logger, functions->componentEnvironment,
        functions->allocateMemory, functions->freeMemory, loggingOn);
}

void fmi2FreeInstance(fmi2Component c) { core_free((Instance *)c); }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    CALL(FN_SET_DEBUG_LOGGING, core_set_logging(inst, NAME(FN_SET_DEBUG_LOGGING), loggingOn, nCategories, categories));
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    (void)toleranceDefined;
    (void)tolerance;
    CALL(FN_SETUP_EXPERIMENT, core_setup(inst, NAME(FN_SETUP_EXPERIMENT), startTime, stopTimeDefined, stopTime));
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
    CALL(FN_EXIT_INITIALIZATION_MODE, core_exit_initialization(inst, NAME(FN_EXIT_INITIALIZATION_MODE)));
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
    core_reset(inst);
    return fmi2OK;
}

/* ---------------------------------------------------------------- variable access */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    CALL(FN_GET_REAL, core_get_real(inst, NAME(FN_GET_REAL), vr, nvr, value));
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    CALL(FN_GET_INTEGER, core_get_integer(inst, NAME(FN_GET_INTEGER), vr, nvr, value, (int)sizeof(fmi2Integer)));
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    CALL(FN_SET_REAL, core_set_real(inst, NAME(FN_SET_REAL), vr, nvr, value));
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    CALL(FN_SET_INTEGER, core_set_integer(inst, NAME(FN_SET_INTEGER), vr, nvr, value, (int)sizeof(fmi2Integer)));
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    (void)value;
    CALL(FN_GET_BOOLEAN, core_no_such_variables(inst, NAME(FN_GET_BOOLEAN), nvr, vr, "Boolean"));
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    (void)value;
    CALL(FN_GET_STRING, core_no_such_variables(inst, NAME(FN_GET_STRING), nvr, vr, "String"));
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    (void)value;
    CALL(FN_SET_BOOLEAN, core_no_such_variables(inst, NAME(FN_SET_BOOLEAN), nvr, vr, "Boolean"));
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    (void)value;
    CALL(FN_SET_STRING, core_no_such_variables(inst, NAME(FN_SET_STRING), nvr, vr, "String"));
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[])
{
    CALL(FN_GET_DIRECTIONAL_DERIVATIVE,
         core_get_directional_derivative(inst, NAME(FN_GET_DIRECTIONAL_DERIVATIVE), vUnknown_ref, nUnknown, vKnown_ref,
                                         nKnown, dvKnown, dvUnknown));
}

/* ---------------------------------------------------------------- FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    CALL(FN_GET_FMU_STATE, core_get_state(inst, NAME(FN_GET_FMU_STATE), FMUstate));
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    CALL(FN_SET_FMU_STATE, core_set_state(inst, NAME(FN_SET_FMU_STATE), FMUstate));
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    CALL(FN_FREE_FMU_STATE, core_free_state(inst, NAME(FN_FREE_FMU_STATE), FMUstate));
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    CALL(FN_SERIALIZED_SIZE, core_serialized_size(inst, NAME(FN_SERIALIZED_SIZE), FMUstate, size));
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size)
{
    CALL(FN_SERIALIZE, core_serialize(inst, NAME(FN_SERIALIZE), FMUstate, (unsigned char *)serializedState, size));
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    CALL(FN_DESERIALIZE,
         core_deserialize(inst, NAME(FN_DESERIALIZE), (const unsigned char *)serializedState, size, FMUstate));
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
    {
        int changed;
        const Status status = core_new_discrete_states(inst, "fmi2NewDiscreteStates", &changed);
        info->newDiscreteStatesNeeded = fmi2False;
        info->terminateSimulation = fmi2False;
        info->nominalsOfContinuousStatesChanged = fmi2False;
        info->valuesOfContinuousStatesChanged = changed ? fmi2True : fmi2False;
        info->nextEventTimeDefined = fmi2False;
        info->nextEventTime = 0.0;
        return (fmi2Status)status;
    }
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
    CALL(FN_SET_TIME, core_set_time(inst, NAME(FN_SET_TIME), time));
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{
    CALL(FN_SET_CONTINUOUS_STATES, core_set_continuous_states(inst, NAME(FN_SET_CONTINUOUS_STATES), x, nx));
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx)
{
    CALL(FN_GET_DERIVATIVES, core_get_derivatives(inst, NAME(FN_GET_DERIVATIVES), derivatives, nx));
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni)
{
    CALL(FN_GET_EVENT_INDICATORS, core_get_event_indicators(inst, NAME(FN_GET_EVENT_INDICATORS), eventIndicators, ni));
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{
    CALL(FN_GET_CONTINUOUS_STATES, core_get_continuous_states(inst, NAME(FN_GET_CONTINUOUS_STATES), x, nx));
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx)
{
    CALL(FN_GET_NOMINALS, core_get_nominals(inst, NAME(FN_GET_NOMINALS), x_nominal, nx));
}

/* ---------------------------------------------------------------- Co-Simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    CALL(FN_SET_REAL_INPUT_DERIVATIVES,
         core_set_input_derivatives(inst, NAME(FN_SET_REAL_INPUT_DERIVATIVES), vr, nvr, order, value));
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    CALL(FN_GET_REAL_OUTPUT_DERIVATIVES,
         core_get_output_derivatives(inst, NAME(FN_GET_REAL_OUTPUT_DERIVATIVES), vr, nvr, order, value));
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    CALL(FN_DO_STEP, core_do_step(inst, NAME(FN_DO_STEP), currentCommunicationPoint, communicationStepSize));
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
