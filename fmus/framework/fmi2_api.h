/* FMI 2.0 types and function prototypes, as the standard defines them (fmi2TypesPlatform.h,
 * fmi2FunctionTypes.h, fmi2Functions.h). A test compiles the framework against the standard's own
 * headers too (USE_STANDARD_FMI2_HEADERS), so a prototype that drifts from the standard cannot pass. */
#ifndef FMI2_API_H
#define FMI2_API_H

#include <stddef.h>

#ifdef USE_STANDARD_FMI2_HEADERS
#include "fmi2Functions.h"
#else

#define fmi2TypesPlatform "default"
#define fmi2Version "2.0"

typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;

#define fmi2True 1
#define fmi2False 0

typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;

typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);

typedef struct {
    const fmi2CallbackLogger logger;
    const fmi2CallbackAllocateMemory allocateMemory;
    const fmi2CallbackFreeMemory freeMemory;
    const fmi2StepFinished stepFinished;
    const fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

typedef struct {
    fmi2Boolean newDiscreteStatesNeeded;
    fmi2Boolean terminateSimulation;
    fmi2Boolean nominalsOfContinuousStatesChanged;
    fmi2Boolean valuesOfContinuousStatesChanged;
    fmi2Boolean nextEventTimeDefined;
    fmi2Real nextEventTime;
} fmi2EventInfo;

/* An importer that compiles several source FMUs into one program gives each its own prefix
 * (FMI 2.0: FMI2_FUNCTION_PREFIX): every FMI function is then named prefix + name. */
#ifdef FMI2_FUNCTION_PREFIX
#define FMI2_PASTE(a, b) a##b
#define FMI2_PASTE_EXPANDED(a, b) FMI2_PASTE(a, b)
#define FMI2_PREFIXED(name) FMI2_PASTE_EXPANDED(FMI2_FUNCTION_PREFIX, name)
#define fmi2GetTypesPlatform FMI2_PREFIXED(fmi2GetTypesPlatform)
#define fmi2GetVersion FMI2_PREFIXED(fmi2GetVersion)
#define fmi2SetDebugLogging FMI2_PREFIXED(fmi2SetDebugLogging)
#define fmi2Instantiate FMI2_PREFIXED(fmi2Instantiate)
#define fmi2FreeInstance FMI2_PREFIXED(fmi2FreeInstance)
#define fmi2SetupExperiment FMI2_PREFIXED(fmi2SetupExperiment)
#define fmi2EnterInitializationMode FMI2_PREFIXED(fmi2EnterInitializationMode)
#define fmi2ExitInitializationMode FMI2_PREFIXED(fmi2ExitInitializationMode)
#define fmi2Terminate FMI2_PREFIXED(fmi2Terminate)
#define fmi2Reset FMI2_PREFIXED(fmi2Reset)
#define fmi2GetReal FMI2_PREFIXED(fmi2GetReal)
#define fmi2GetInteger FMI2_PREFIXED(fmi2GetInteger)
#define fmi2GetBoolean FMI2_PREFIXED(fmi2GetBoolean)
#define fmi2GetString FMI2_PREFIXED(fmi2GetString)
#define fmi2SetReal FMI2_PREFIXED(fmi2SetReal)
#define fmi2SetInteger FMI2_PREFIXED(fmi2SetInteger)
#define fmi2SetBoolean FMI2_PREFIXED(fmi2SetBoolean)
#define fmi2SetString FMI2_PREFIXED(fmi2SetString)
#define fmi2GetFMUstate FMI2_PREFIXED(fmi2GetFMUstate)
#define fmi2SetFMUstate FMI2_PREFIXED(fmi2SetFMUstate)
#define fmi2FreeFMUstate FMI2_PREFIXED(fmi2FreeFMUstate)
#define fmi2SerializedFMUstateSize FMI2_PREFIXED(fmi2SerializedFMUstateSize)
#define fmi2SerializeFMUstate FMI2_PREFIXED(fmi2SerializeFMUstate)
#define fmi2DeSerializeFMUstate FMI2_PREFIXED(fmi2DeSerializeFMUstate)
#define fmi2GetDirectionalDerivative FMI2_PREFIXED(fmi2GetDirectionalDerivative)
#define fmi2EnterEventMode FMI2_PREFIXED(fmi2EnterEventMode)
#define fmi2NewDiscreteStates FMI2_PREFIXED(fmi2NewDiscreteStates)
#define fmi2EnterContinuousTimeMode FMI2_PREFIXED(fmi2EnterContinuousTimeMode)
#define fmi2CompletedIntegratorStep FMI2_PREFIXED(fmi2CompletedIntegratorStep)
#define fmi2SetTime FMI2_PREFIXED(fmi2SetTime)
#define fmi2SetContinuousStates FMI2_PREFIXED(fmi2SetContinuousStates)
#define fmi2GetDerivatives FMI2_PREFIXED(fmi2GetDerivatives)
#define fmi2GetEventIndicators FMI2_PREFIXED(fmi2GetEventIndicators)
#define fmi2GetContinuousStates FMI2_PREFIXED(fmi2GetContinuousStates)
#define fmi2GetNominalsOfContinuousStates FMI2_PREFIXED(fmi2GetNominalsOfContinuousStates)
#define fmi2SetRealInputDerivatives FMI2_PREFIXED(fmi2SetRealInputDerivatives)
#define fmi2GetRealOutputDerivatives FMI2_PREFIXED(fmi2GetRealOutputDerivatives)
#define fmi2DoStep FMI2_PREFIXED(fmi2DoStep)
#define fmi2CancelStep FMI2_PREFIXED(fmi2CancelStep)
#define fmi2GetStatus FMI2_PREFIXED(fmi2GetStatus)
#define fmi2GetRealStatus FMI2_PREFIXED(fmi2GetRealStatus)
#define fmi2GetIntegerStatus FMI2_PREFIXED(fmi2GetIntegerStatus)
#define fmi2GetBooleanStatus FMI2_PREFIXED(fmi2GetBooleanStatus)
#define fmi2GetStringStatus FMI2_PREFIXED(fmi2GetStringStatus)
#endif

#if defined(_WIN32)
#define FMI2_Export __declspec(dllexport)
#else
#define FMI2_Export __attribute__((visibility("default")))
#endif

/* common */
FMI2_Export const char *fmi2GetTypesPlatform(void);
FMI2_Export const char *fmi2GetVersion(void);
FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component, fmi2Boolean, size_t, const fmi2String[]);
FMI2_Export fmi2Component fmi2Instantiate(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                                          fmi2Boolean, fmi2Boolean);
FMI2_Export void fmi2FreeInstance(fmi2Component);
FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real);
FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component);
FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component);
FMI2_Export fmi2Status fmi2Terminate(fmi2Component);
FMI2_Export fmi2Status fmi2Reset(fmi2Component);
FMI2_Export fmi2Status fmi2GetReal(fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]);
FMI2_Export fmi2Status fmi2GetInteger(fmi2Component, const fmi2ValueReference[], size_t, fmi2Integer[]);
FMI2_Export fmi2Status fmi2GetBoolean(fmi2Component, const fmi2ValueReference[], size_t, fmi2Boolean[]);
FMI2_Export fmi2Status fmi2GetString(fmi2Component, const fmi2ValueReference[], size_t, fmi2String[]);
FMI2_Export fmi2Status fmi2SetReal(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Real[]);
FMI2_Export fmi2Status fmi2SetInteger(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[]);
FMI2_Export fmi2Status fmi2SetBoolean(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Boolean[]);
FMI2_Export fmi2Status fmi2SetString(fmi2Component, const fmi2ValueReference[], size_t, const fmi2String[]);
FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component, fmi2FMUstate *);
FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component, fmi2FMUstate);
FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component, fmi2FMUstate *);
FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component, fmi2FMUstate, size_t *);
FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component, fmi2FMUstate, fmi2Byte[], size_t);
FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component, const fmi2Byte[], size_t, fmi2FMUstate *);
FMI2_Export fmi2Status fmi2GetDirectionalDerivative(fmi2Component, const fmi2ValueReference[], size_t,
                                                    const fmi2ValueReference[], size_t, const fmi2Real[], fmi2Real[]);
/* Model Exchange */
FMI2_Export fmi2Status fmi2EnterEventMode(fmi2Component);
FMI2_Export fmi2Status fmi2NewDiscreteStates(fmi2Component, fmi2EventInfo *);
FMI2_Export fmi2Status fmi2EnterContinuousTimeMode(fmi2Component);
FMI2_Export fmi2Status fmi2CompletedIntegratorStep(fmi2Component, fmi2Boolean, fmi2Boolean *, fmi2Boolean *);
FMI2_Export fmi2Status fmi2SetTime(fmi2Component, fmi2Real);
FMI2_Export fmi2Status fmi2SetContinuousStates(fmi2Component, const fmi2Real[], size_t);
FMI2_Export fmi2Status fmi2GetDerivatives(fmi2Component, fmi2Real[], size_t);
FMI2_Export fmi2Status fmi2GetEventIndicators(fmi2Component, fmi2Real[], size_t);
FMI2_Export fmi2Status fmi2GetContinuousStates(fmi2Component, fmi2Real[], size_t);
FMI2_Export fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component, fmi2Real[], size_t);
/* Co-Simulation */
FMI2_Export fmi2Status fmi2SetRealInputDerivatives(fmi2Component, const fmi2ValueReference[], size_t,
                                                   const fmi2Integer[], const fmi2Real[]);
FMI2_Export fmi2Status fmi2GetRealOutputDerivatives(fmi2Component, const fmi2ValueReference[], size_t,
                                                    const fmi2Integer[], fmi2Real[]);
FMI2_Export fmi2Status fmi2DoStep(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
FMI2_Export fmi2Status fmi2CancelStep(fmi2Component);
FMI2_Export fmi2Status fmi2GetStatus(fmi2Component, const fmi2StatusKind, fmi2Status *);
FMI2_Export fmi2Status fmi2GetRealStatus(fmi2Component, const fmi2StatusKind, fmi2Real *);
FMI2_Export fmi2Status fmi2GetIntegerStatus(fmi2Component, const fmi2StatusKind, fmi2Integer *);
FMI2_Export fmi2Status fmi2GetBooleanStatus(fmi2Component, const fmi2StatusKind, fmi2Boolean *);
FMI2_Export fmi2Status fmi2GetStringStatus(fmi2Component, const fmi2StatusKind, fmi2String *);

#endif /* USE_STANDARD_FMI2_HEADERS */
#endif
