/*
 * The FMI 3.0 functions our co-simulation models do not provide: model exchange, scheduled
 * execution, event mode, clocks, other variable types, derivatives, dependencies. Each one
 * exists (an importer resolves every fmi3* symbol when it loads the binary, and fmpy fails with
 * "undefined symbol" otherwise), logs what is missing and returns fmi3Error.
 */
#include <stddef.h>

#include "fmi3_instance.h"

static fmi3Status unsupported(fmi3Instance instance, const char *function) {
    LOG_ERROR((Instance *)instance, "%s is not provided by %s (co-simulation only, Float64, "
              "Int32 and Boolean variables)", function, MODEL_IDENTIFIER_STRING);
    return fmi3Error;
}

/* Instantiation of the other interface types: refused (NULL, nothing to log to). */
fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible;
    (void)loggingOn, (void)instanceEnvironment, (void)logMessage;
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible;
    (void)loggingOn, (void)instanceEnvironment, (void)logMessage, (void)clockUpdate;
    (void)lockPreemption, (void)unlockPreemption;
    return NULL;
}

/* Typed access for the types our tables never produce. */
#define NO_TYPE(Name, T)                                                                        \
    fmi3Status fmi3Get##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, \
                             T values[], size_t nValues) {                                      \
        (void)vr, (void)nvr, (void)values, (void)nValues;                                       \
        return unsupported(instance, "fmi3Get" #Name);                                          \
    }                                                                                           \
    fmi3Status fmi3Set##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, \
                             const T values[], size_t nValues) {                                \
        (void)vr, (void)nvr, (void)values, (void)nValues;                                       \
        return unsupported(instance, "fmi3Set" #Name);                                          \
    }

NO_TYPE(Float32, fmi3Float32)
NO_TYPE(Int8, fmi3Int8)
NO_TYPE(UInt8, fmi3UInt8)
NO_TYPE(Int16, fmi3Int16)
NO_TYPE(UInt16, fmi3UInt16)
NO_TYPE(UInt32, fmi3UInt32)
NO_TYPE(Int64, fmi3Int64)
NO_TYPE(UInt64, fmi3UInt64)
NO_TYPE(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    (void)vr, (void)nvr, (void)valueSizes, (void)values, (void)nValues;
    return unsupported(instance, "fmi3GetBinary");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    (void)vr, (void)nvr, (void)valueSizes, (void)values, (void)nValues;
    return unsupported(instance, "fmi3SetBinary");
}

/* Functions with only an instance argument, or only pointers we leave alone. */
#define NO_FUNCTION(Name, ...)                                                                  \
    fmi3Status fmi3##Name(fmi3Instance instance, __VA_ARGS__) {                                 \
        return unsupported(instance, "fmi3" #Name);                                             \
    }
#define NO_PLAIN_FUNCTION(Name)                                                                 \
    fmi3Status fmi3##Name(fmi3Instance instance) { return unsupported(instance, "fmi3" #Name); }

#define VRS const fmi3ValueReference vr[], size_t nvr
NO_PLAIN_FUNCTION(EnterEventMode)
NO_PLAIN_FUNCTION(EnterStepMode)
NO_PLAIN_FUNCTION(EnterConfigurationMode)
NO_PLAIN_FUNCTION(ExitConfigurationMode)
NO_PLAIN_FUNCTION(EvaluateDiscreteStates)
NO_PLAIN_FUNCTION(EnterContinuousTimeMode)
NO_FUNCTION(GetClock, VRS, fmi3Clock values[])
NO_FUNCTION(SetClock, VRS, const fmi3Clock values[])
NO_FUNCTION(GetIntervalDecimal, VRS, fmi3Float64 intervals[], fmi3IntervalQualifier q[])
NO_FUNCTION(GetIntervalFraction, VRS, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
            fmi3IntervalQualifier q[])
NO_FUNCTION(GetShiftDecimal, VRS, fmi3Float64 shifts[])
NO_FUNCTION(GetShiftFraction, VRS, fmi3UInt64 counters[], fmi3UInt64 resolutions[])
NO_FUNCTION(SetIntervalDecimal, VRS, const fmi3Float64 intervals[])
NO_FUNCTION(SetIntervalFraction, VRS, const fmi3UInt64 counters[],
            const fmi3UInt64 resolutions[])
NO_FUNCTION(SetShiftDecimal, VRS, const fmi3Float64 shifts[])
NO_FUNCTION(SetShiftFraction, VRS, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
NO_FUNCTION(ActivateModelPartition, fmi3ValueReference clockReference, fmi3Float64 time)
NO_FUNCTION(GetNumberOfVariableDependencies, fmi3ValueReference vr, size_t *n)
NO_FUNCTION(GetVariableDependencies, fmi3ValueReference dependent, size_t elements[],
            fmi3ValueReference independents[], size_t independent_elements[],
            fmi3DependencyKind kinds[], size_t n)
NO_FUNCTION(GetDirectionalDerivative, const fmi3ValueReference unknowns[], size_t nUnknowns,
            const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
            size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
NO_FUNCTION(GetAdjointDerivative, const fmi3ValueReference unknowns[], size_t nUnknowns,
            const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
            size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
NO_FUNCTION(GetOutputDerivatives, VRS, const fmi3Int32 orders[], fmi3Float64 values[],
            size_t nValues)
NO_FUNCTION(UpdateDiscreteStates, fmi3Boolean *needUpdate, fmi3Boolean *terminate,
            fmi3Boolean *nominalsChanged, fmi3Boolean *valuesChanged,
            fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime)
NO_FUNCTION(CompletedIntegratorStep, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
            fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
NO_FUNCTION(SetTime, fmi3Float64 time)
NO_FUNCTION(SetContinuousStates, const fmi3Float64 states[], size_t n)
NO_FUNCTION(GetContinuousStateDerivatives, fmi3Float64 derivatives[], size_t n)
NO_FUNCTION(GetEventIndicators, fmi3Float64 indicators[], size_t n)
NO_FUNCTION(GetContinuousStates, fmi3Float64 states[], size_t n)
NO_FUNCTION(GetNominalsOfContinuousStates, fmi3Float64 nominals[], size_t n)
NO_FUNCTION(GetNumberOfEventIndicators, size_t *n)
NO_FUNCTION(GetNumberOfContinuousStates, size_t *n)
