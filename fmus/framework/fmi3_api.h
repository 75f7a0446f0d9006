/* FMI 3.0 types and function prototypes, as the standard defines them (fmi3PlatformTypes.h,
 * fmi3FunctionTypes.h, fmi3Functions.h). A test compiles the FMI 3.0 layer against the standard's own
 * headers too (USE_STANDARD_FMI3_HEADERS), so a prototype that drifts from the standard cannot pass. */
#ifndef FMI3_API_H
#define FMI3_API_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef USE_STANDARD_FMI3_HEADERS
#include "fmi3Functions.h"
#else

#define fmi3Version "3.0"

typedef void *fmi3Instance;
typedef void *fmi3InstanceEnvironment;
typedef void *fmi3FMUState;
typedef uint32_t fmi3ValueReference;
typedef float fmi3Float32;
typedef double fmi3Float64;
typedef int8_t fmi3Int8;
typedef uint8_t fmi3UInt8;
typedef int16_t fmi3Int16;
typedef uint16_t fmi3UInt16;
typedef int32_t fmi3Int32;
typedef uint32_t fmi3UInt32;
typedef int64_t fmi3Int64;
typedef uint64_t fmi3UInt64;
typedef bool fmi3Boolean;
typedef char fmi3Char;
typedef const fmi3Char *fmi3String;
typedef uint8_t fmi3Byte;
typedef const fmi3Byte *fmi3Binary;
typedef bool fmi3Clock;

#define fmi3True true
#define fmi3False false

typedef enum { fmi3OK, fmi3Warning, fmi3Discard, fmi3Error, fmi3Fatal } fmi3Status;
typedef enum { fmi3Independent, fmi3Constant, fmi3Fixed, fmi3Tunable, fmi3Discrete, fmi3Dependent } fmi3DependencyKind;
typedef enum { fmi3IntervalNotYetKnown, fmi3IntervalUnchanged, fmi3IntervalChanged } fmi3IntervalQualifier;

typedef void (*fmi3LogMessageCallback)(fmi3InstanceEnvironment, fmi3Status, fmi3String, fmi3String);
typedef void (*fmi3ClockUpdateCallback)(fmi3InstanceEnvironment);
typedef void (*fmi3IntermediateUpdateCallback)(fmi3InstanceEnvironment, fmi3Float64, fmi3Boolean, fmi3Boolean,
                                               fmi3Boolean, fmi3Boolean, fmi3Boolean *, fmi3Float64 *);
typedef void (*fmi3LockPreemptionCallback)(void);
typedef void (*fmi3UnlockPreemptionCallback)(void);

/* An importer that compiles several source FMUs into one program gives each its own prefix
 * (FMI 3.0: FMI3_FUNCTION_PREFIX): every FMI function is then named prefix + name. */
#ifdef FMI3_FUNCTION_PREFIX
#define FMI3_PASTE(a, b) a##b
#define FMI3_PASTE_EXPANDED(a, b) FMI3_PASTE(a, b)
#define FMI3_PREFIXED(name) FMI3_PASTE_EXPANDED(FMI3_FUNCTION_PREFIX, name)
#define fmi3GetVersion FMI3_PREFIXED(fmi3GetVersion)
#define fmi3SetDebugLogging FMI3_PREFIXED(fmi3SetDebugLogging)
#define fmi3InstantiateModelExchange FMI3_PREFIXED(fmi3InstantiateModelExchange)
#define fmi3InstantiateCoSimulation FMI3_PREFIXED(fmi3InstantiateCoSimulation)
#define fmi3InstantiateScheduledExecution FMI3_PREFIXED(fmi3InstantiateScheduledExecution)
#define fmi3FreeInstance FMI3_PREFIXED(fmi3FreeInstance)
#define fmi3EnterInitializationMode FMI3_PREFIXED(fmi3EnterInitializationMode)
#define fmi3ExitInitializationMode FMI3_PREFIXED(fmi3ExitInitializationMode)
#define fmi3EnterEventMode FMI3_PREFIXED(fmi3EnterEventMode)
#define fmi3Terminate FMI3_PREFIXED(fmi3Terminate)
#define fmi3Reset FMI3_PREFIXED(fmi3Reset)
#define fmi3GetFloat32 FMI3_PREFIXED(fmi3GetFloat32)
#define fmi3GetFloat64 FMI3_PREFIXED(fmi3GetFloat64)
#define fmi3GetInt8 FMI3_PREFIXED(fmi3GetInt8)
#define fmi3GetUInt8 FMI3_PREFIXED(fmi3GetUInt8)
#define fmi3GetInt16 FMI3_PREFIXED(fmi3GetInt16)
#define fmi3GetUInt16 FMI3_PREFIXED(fmi3GetUInt16)
#define fmi3GetInt32 FMI3_PREFIXED(fmi3GetInt32)
#define fmi3GetUInt32 FMI3_PREFIXED(fmi3GetUInt32)
#define fmi3GetInt64 FMI3_PREFIXED(fmi3GetInt64)
#define fmi3GetUInt64 FMI3_PREFIXED(fmi3GetUInt64)
#define fmi3GetBoolean FMI3_PREFIXED(fmi3GetBoolean)
#define fmi3GetString FMI3_PREFIXED(fmi3GetString)
#define fmi3GetBinary FMI3_PREFIXED(fmi3GetBinary)
#define fmi3GetClock FMI3_PREFIXED(fmi3GetClock)
#define fmi3SetFloat32 FMI3_PREFIXED(fmi3SetFloat32)
#define fmi3SetFloat64 FMI3_PREFIXED(fmi3SetFloat64)
#define fmi3SetInt8 FMI3_PREFIXED(fmi3SetInt8)
#define fmi3SetUInt8 FMI3_PREFIXED(fmi3SetUInt8)
#define fmi3SetInt16 FMI3_PREFIXED(fmi3SetInt16)
#define fmi3SetUInt16 FMI3_PREFIXED(fmi3SetUInt16)
#define fmi3SetInt32 FMI3_PREFIXED(fmi3SetInt32)
#define fmi3SetUInt32 FMI3_PREFIXED(fmi3SetUInt32)
#define fmi3SetInt64 FMI3_PREFIXED(fmi3SetInt64)
#define fmi3SetUInt64 FMI3_PREFIXED(fmi3SetUInt64)
#define fmi3SetBoolean FMI3_PREFIXED(fmi3SetBoolean)
#define fmi3SetString FMI3_PREFIXED(fmi3SetString)
#define fmi3SetBinary FMI3_PREFIXED(fmi3SetBinary)
#define fmi3SetClock FMI3_PREFIXED(fmi3SetClock)
#define fmi3GetNumberOfVariableDependencies FMI3_PREFIXED(fmi3GetNumberOfVariableDependencies)
#define fmi3GetVariableDependencies FMI3_PREFIXED(fmi3GetVariableDependencies)
#define fmi3GetFMUState FMI3_PREFIXED(fmi3GetFMUState)
#define fmi3SetFMUState FMI3_PREFIXED(fmi3SetFMUState)
#define fmi3FreeFMUState FMI3_PREFIXED(fmi3FreeFMUState)
#define fmi3SerializedFMUStateSize FMI3_PREFIXED(fmi3SerializedFMUStateSize)
#define fmi3SerializeFMUState FMI3_PREFIXED(fmi3SerializeFMUState)
#define fmi3DeserializeFMUState FMI3_PREFIXED(fmi3DeserializeFMUState)
#define fmi3GetDirectionalDerivative FMI3_PREFIXED(fmi3GetDirectionalDerivative)
#define fmi3GetAdjointDerivative FMI3_PREFIXED(fmi3GetAdjointDerivative)
#define fmi3EnterConfigurationMode FMI3_PREFIXED(fmi3EnterConfigurationMode)
#define fmi3ExitConfigurationMode FMI3_PREFIXED(fmi3ExitConfigurationMode)
#define fmi3GetIntervalDecimal FMI3_PREFIXED(fmi3GetIntervalDecimal)
#define fmi3GetIntervalFraction FMI3_PREFIXED(fmi3GetIntervalFraction)
#define fmi3GetShiftDecimal FMI3_PREFIXED(fmi3GetShiftDecimal)
#define fmi3GetShiftFraction FMI3_PREFIXED(fmi3GetShiftFraction)
#define fmi3SetIntervalDecimal FMI3_PREFIXED(fmi3SetIntervalDecimal)
#define fmi3SetIntervalFraction FMI3_PREFIXED(fmi3SetIntervalFraction)
#define fmi3SetShiftDecimal FMI3_PREFIXED(fmi3SetShiftDecimal)
#define fmi3SetShiftFraction FMI3_PREFIXED(fmi3SetShiftFraction)
#define fmi3EvaluateDiscreteStates FMI3_PREFIXED(fmi3EvaluateDiscreteStates)
#define fmi3UpdateDiscreteStates FMI3_PREFIXED(fmi3UpdateDiscreteStates)
#define fmi3EnterContinuousTimeMode FMI3_PREFIXED(fmi3EnterContinuousTimeMode)
#define fmi3CompletedIntegratorStep FMI3_PREFIXED(fmi3CompletedIntegratorStep)
#define fmi3SetTime FMI3_PREFIXED(fmi3SetTime)
#define fmi3SetContinuousStates FMI3_PREFIXED(fmi3SetContinuousStates)
#define fmi3GetContinuousStateDerivatives FMI3_PREFIXED(fmi3GetContinuousStateDerivatives)
#define fmi3GetEventIndicators FMI3_PREFIXED(fmi3GetEventIndicators)
#define fmi3GetContinuousStates FMI3_PREFIXED(fmi3GetContinuousStates)
#define fmi3GetNominalsOfContinuousStates FMI3_PREFIXED(fmi3GetNominalsOfContinuousStates)
#define fmi3GetNumberOfEventIndicators FMI3_PREFIXED(fmi3GetNumberOfEventIndicators)
#define fmi3GetNumberOfContinuousStates FMI3_PREFIXED(fmi3GetNumberOfContinuousStates)
#define fmi3EnterStepMode FMI3_PREFIXED(fmi3EnterStepMode)
#define fmi3GetOutputDerivatives FMI3_PREFIXED(fmi3GetOutputDerivatives)
#define fmi3DoStep FMI3_PREFIXED(fmi3DoStep)
#define fmi3ActivateModelPartition FMI3_PREFIXED(fmi3ActivateModelPartition)
#endif

#if defined(_WIN32)
#define FMI3_Export __declspec(dllexport)
#else
#define FMI3_Export __attribute__((visibility("default")))
#endif

#define FMI3_VALUES(type) (fmi3Instance, const fmi3ValueReference[], size_t, type[], size_t)
#define FMI3_CONST_VALUES(type) (fmi3Instance, const fmi3ValueReference[], size_t, const type[], size_t)

/* common */
FMI3_Export const char *fmi3GetVersion(void);
FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance, fmi3Boolean, size_t, const fmi3String[]);
FMI3_Export fmi3Instance fmi3InstantiateModelExchange(fmi3String, fmi3String, fmi3String, fmi3Boolean, fmi3Boolean,
                                                      fmi3InstanceEnvironment, fmi3LogMessageCallback);
FMI3_Export fmi3Instance fmi3InstantiateCoSimulation(fmi3String, fmi3String, fmi3String, fmi3Boolean, fmi3Boolean,
                                                     fmi3Boolean, fmi3Boolean, const fmi3ValueReference[], size_t,
                                                     fmi3InstanceEnvironment, fmi3LogMessageCallback,
                                                     fmi3IntermediateUpdateCallback);
FMI3_Export fmi3Instance fmi3InstantiateScheduledExecution(fmi3String, fmi3String, fmi3String, fmi3Boolean, fmi3Boolean,
                                                           fmi3InstanceEnvironment, fmi3LogMessageCallback,
                                                           fmi3ClockUpdateCallback, fmi3LockPreemptionCallback,
                                                           fmi3UnlockPreemptionCallback);
FMI3_Export void fmi3FreeInstance(fmi3Instance);
FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance, fmi3Boolean, fmi3Float64, fmi3Float64, fmi3Boolean,
                                                   fmi3Float64);
FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance);
FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance);
FMI3_Export fmi3Status fmi3Terminate(fmi3Instance);
FMI3_Export fmi3Status fmi3Reset(fmi3Instance);
FMI3_Export fmi3Status fmi3GetFloat32 FMI3_VALUES(fmi3Float32);
FMI3_Export fmi3Status fmi3GetFloat64 FMI3_VALUES(fmi3Float64);
FMI3_Export fmi3Status fmi3GetInt8 FMI3_VALUES(fmi3Int8);
FMI3_Export fmi3Status fmi3GetUInt8 FMI3_VALUES(fmi3UInt8);
FMI3_Export fmi3Status fmi3GetInt16 FMI3_VALUES(fmi3Int16);
FMI3_Export fmi3Status fmi3GetUInt16 FMI3_VALUES(fmi3UInt16);
FMI3_Export fmi3Status fmi3GetInt32 FMI3_VALUES(fmi3Int32);
FMI3_Export fmi3Status fmi3GetUInt32 FMI3_VALUES(fmi3UInt32);
FMI3_Export fmi3Status fmi3GetInt64 FMI3_VALUES(fmi3Int64);
FMI3_Export fmi3Status fmi3GetUInt64 FMI3_VALUES(fmi3UInt64);
FMI3_Export fmi3Status fmi3GetBoolean FMI3_VALUES(fmi3Boolean);
FMI3_Export fmi3Status fmi3GetString FMI3_VALUES(fmi3String);
FMI3_Export fmi3Status fmi3GetBinary(fmi3Instance, const fmi3ValueReference[], size_t, size_t[], fmi3Binary[], size_t);
FMI3_Export fmi3Status fmi3GetClock(fmi3Instance, const fmi3ValueReference[], size_t, fmi3Clock[]);
FMI3_Export fmi3Status fmi3SetFloat32 FMI3_CONST_VALUES(fmi3Float32);
FMI3_Export fmi3Status fmi3SetFloat64 FMI3_CONST_VALUES(fmi3Float64);
FMI3_Export fmi3Status fmi3SetInt8 FMI3_CONST_VALUES(fmi3Int8);
FMI3_Export fmi3Status fmi3SetUInt8 FMI3_CONST_VALUES(fmi3UInt8);
FMI3_Export fmi3Status fmi3SetInt16 FMI3_CONST_VALUES(fmi3Int16);
FMI3_Export fmi3Status fmi3SetUInt16 FMI3_CONST_VALUES(fmi3UInt16);
FMI3_Export fmi3Status fmi3SetInt32 FMI3_CONST_VALUES(fmi3Int32);
FMI3_Export fmi3Status fmi3SetUInt32 FMI3_CONST_VALUES(fmi3UInt32);
FMI3_Export fmi3Status fmi3SetInt64 FMI3_CONST_VALUES(fmi3Int64);
FMI3_Export fmi3Status fmi3SetUInt64 FMI3_CONST_VALUES(fmi3UInt64);
FMI3_Export fmi3Status fmi3SetBoolean FMI3_CONST_VALUES(fmi3Boolean);
FMI3_Export fmi3Status fmi3SetString FMI3_CONST_VALUES(fmi3String);
FMI3_Export fmi3Status fmi3SetBinary(fmi3Instance, const fmi3ValueReference[], size_t, const size_t[],
                                     const fmi3Binary[], size_t);
FMI3_Export fmi3Status fmi3SetClock(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3Clock[]);
FMI3_Export fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance, fmi3ValueReference, size_t *);
FMI3_Export fmi3Status fmi3GetVariableDependencies(fmi3Instance, fmi3ValueReference, size_t[], fmi3ValueReference[],
                                                   size_t[], fmi3DependencyKind[], size_t);
FMI3_Export fmi3Status fmi3GetFMUState(fmi3Instance, fmi3FMUState *);
FMI3_Export fmi3Status fmi3SetFMUState(fmi3Instance, fmi3FMUState);
FMI3_Export fmi3Status fmi3FreeFMUState(fmi3Instance, fmi3FMUState *);
FMI3_Export fmi3Status fmi3SerializedFMUStateSize(fmi3Instance, fmi3FMUState, size_t *);
FMI3_Export fmi3Status fmi3SerializeFMUState(fmi3Instance, fmi3FMUState, fmi3Byte[], size_t);
FMI3_Export fmi3Status fmi3DeserializeFMUState(fmi3Instance, const fmi3Byte[], size_t, fmi3FMUState *);
FMI3_Export fmi3Status fmi3GetDirectionalDerivative(fmi3Instance, const fmi3ValueReference[], size_t,
                                                    const fmi3ValueReference[], size_t, const fmi3Float64[], size_t,
                                                    fmi3Float64[], size_t);
FMI3_Export fmi3Status fmi3GetAdjointDerivative(fmi3Instance, const fmi3ValueReference[], size_t,
                                                const fmi3ValueReference[], size_t, const fmi3Float64[], size_t,
                                                fmi3Float64[], size_t);
FMI3_Export fmi3Status fmi3EnterConfigurationMode(fmi3Instance);
FMI3_Export fmi3Status fmi3ExitConfigurationMode(fmi3Instance);
FMI3_Export fmi3Status fmi3GetIntervalDecimal(fmi3Instance, const fmi3ValueReference[], size_t, fmi3Float64[],
                                              fmi3IntervalQualifier[]);
FMI3_Export fmi3Status fmi3GetIntervalFraction(fmi3Instance, const fmi3ValueReference[], size_t, fmi3UInt64[],
                                               fmi3UInt64[], fmi3IntervalQualifier[]);
FMI3_Export fmi3Status fmi3GetShiftDecimal(fmi3Instance, const fmi3ValueReference[], size_t, fmi3Float64[]);
FMI3_Export fmi3Status fmi3GetShiftFraction(fmi3Instance, const fmi3ValueReference[], size_t, fmi3UInt64[],
                                            fmi3UInt64[]);
FMI3_Export fmi3Status fmi3SetIntervalDecimal(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3Float64[]);
FMI3_Export fmi3Status fmi3SetIntervalFraction(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3UInt64[],
                                               const fmi3UInt64[]);
FMI3_Export fmi3Status fmi3SetShiftDecimal(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3Float64[]);
FMI3_Export fmi3Status fmi3SetShiftFraction(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3UInt64[],
                                            const fmi3UInt64[]);
FMI3_Export fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance);
FMI3_Export fmi3Status fmi3UpdateDiscreteStates(fmi3Instance, fmi3Boolean *, fmi3Boolean *, fmi3Boolean *,
                                                fmi3Boolean *, fmi3Boolean *, fmi3Float64 *);
/* Model Exchange */
FMI3_Export fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance);
FMI3_Export fmi3Status fmi3CompletedIntegratorStep(fmi3Instance, fmi3Boolean, fmi3Boolean *, fmi3Boolean *);
FMI3_Export fmi3Status fmi3SetTime(fmi3Instance, fmi3Float64);
FMI3_Export fmi3Status fmi3SetContinuousStates(fmi3Instance, const fmi3Float64[], size_t);
FMI3_Export fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance, fmi3Float64[], size_t);
FMI3_Export fmi3Status fmi3GetEventIndicators(fmi3Instance, fmi3Float64[], size_t);
FMI3_Export fmi3Status fmi3GetContinuousStates(fmi3Instance, fmi3Float64[], size_t);
FMI3_Export fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance, fmi3Float64[], size_t);
FMI3_Export fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance, size_t *);
FMI3_Export fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance, size_t *);
/* Co-Simulation */
FMI3_Export fmi3Status fmi3EnterStepMode(fmi3Instance);
FMI3_Export fmi3Status fmi3GetOutputDerivatives(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3Int32[],
                                                fmi3Float64[], size_t);
FMI3_Export fmi3Status fmi3DoStep(fmi3Instance, fmi3Float64, fmi3Float64, fmi3Boolean, fmi3Boolean *, fmi3Boolean *,
                                  fmi3Boolean *, fmi3Float64 *);
/* Scheduled Execution */
FMI3_Export fmi3Status fmi3ActivateModelPartition(fmi3Instance, fmi3ValueReference, fmi3Float64);

#endif /* USE_STANDARD_FMI3_HEADERS */
#endif
