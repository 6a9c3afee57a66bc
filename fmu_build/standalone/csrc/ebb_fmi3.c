/*
 * ebb_fmi3.c -- FMI 3.0 interface of the standalone beam FMU: co-simulation and model exchange in one binary.
 *
 * The same instance as the FMI 2.0 interface (ebb_instance.c: model, step, variables, saved states,
 * derivatives), with what FMI 3.0 adds: the deflection field w as one array variable (its elements in one
 * fmi3GetFloat64 call), the independent variable time, and adjoint derivatives (fmi3GetAdjointDerivative).
 * Co-simulation as FMI 2.0: a communication step of h = n dt applies n samples with the input held; no event
 * mode, no early return, no intermediate update.  Scheduled execution is not provided (refused at
 * instantiation with a logged message).  Every call that is not supported returns fmi3Error with a message
 * naming the function; never fmi3Fatal.
 */
#include <stdlib.h>
#include <string.h>

#include "ebb_fmi3.h"
#include "ebb_instance.h"

#define ST(call) ((call) == 0 ? fmi3OK : fmi3Error)
#define INST(comp) ((ebb_instance *)(comp))
/* the value references are 32-bit unsigned in both versions: the instance reads them as unsigned */
typedef char ebb_vr_is_unsigned[sizeof(fmi3ValueReference) == sizeof(unsigned) ? 1 : -1];

static void to_host(const ebb_instance *c, int error, const char *category, const char *message)
{
    ((fmi3LogMessageCallback)c->host_logger)(c->env, error ? fmi3Error : fmi3OK, category, message);
}

/* an instance that only carries the host's logger: what a refused instantiation logs its reason through */
static ebb_instance messenger(fmi3String name, fmi3InstanceEnvironment env, fmi3LogMessageCallback logger)
{
    ebb_instance tmp;
    memset(&tmp, 0, sizeof(tmp));
    tmp.host_logger = (ebb_any_fn)logger;
    tmp.log = logger ? to_host : NULL;
    tmp.env = env;
    tmp.name = (char *)(name ? name : "");
    return tmp;
}

static fmi3Instance instantiate(const char *function, fmi3String name, fmi3String token, int exchange,
                                fmi3Boolean loggingOn, fmi3InstanceEnvironment env, fmi3LogMessageCallback logger)
{
    ebb_instance tmp = messenger(name, env, logger);
    if (!token || strcmp(token, EBB_GUID) != 0) {
        ebb_fail(&tmp, function, "instantiation token %s does not match this FMU's %s", token ? token : "(null)",
                 EBB_GUID);
        return NULL;
    }
    if (exchange && ebb_delay_refuse_exchange(&tmp, function) != 0) return NULL;   /* a delay line: past samples */
    return ebb_new(tmp.name, exchange, loggingOn ? 1 : 0, tmp.log, tmp.host_logger, env);
}

/* ------------------------------------------------------------------ common functions */
EBB_EXPORT const char *fmi3GetVersion(void) { return "3.0"; }

EBB_EXPORT fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t n,
                                          const fmi3String categories[])
{
    (void)n; (void)categories;
    if (!instance) return fmi3Error;
    INST(instance)->debug = loggingOn ? 1 : 0;
    return fmi3OK;
}

EBB_EXPORT fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                                     fmi3String resourcePath, fmi3Boolean visible,
                                                     fmi3Boolean loggingOn, fmi3InstanceEnvironment env,
                                                     fmi3LogMessageCallback logMessage)
{
    (void)resourcePath; (void)visible;
    return instantiate("fmi3InstantiateModelExchange", instanceName, instantiationToken, 1, loggingOn, env,
                       logMessage);
}

EBB_EXPORT fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                                    fmi3String resourcePath, fmi3Boolean visible,
                                                    fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                                    fmi3Boolean earlyReturnAllowed,
                                                    const fmi3ValueReference requiredIntermediateVariables[],
                                                    size_t nRequiredIntermediateVariables,
                                                    fmi3InstanceEnvironment env, fmi3LogMessageCallback logMessage,
                                                    fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)resourcePath; (void)visible; (void)eventModeUsed; (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables; (void)intermediateUpdate;
    return instantiate("fmi3InstantiateCoSimulation", instanceName, instantiationToken, 0, loggingOn, env,
                       logMessage);
}

EBB_EXPORT fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                                          fmi3String resourcePath, fmi3Boolean visible,
                                                          fmi3Boolean loggingOn, fmi3InstanceEnvironment env,
                                                          fmi3LogMessageCallback logMessage,
                                                          fmi3ClockUpdateCallback clockUpdate,
                                                          fmi3LockPreemptionCallback lockPreemption,
                                                          fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn; (void)clockUpdate;
    (void)lockPreemption; (void)unlockPreemption;
    ebb_instance tmp = messenger(instanceName, env, logMessage);
    ebb_fail(&tmp, "fmi3InstantiateScheduledExecution", "this FMU provides model exchange and co-simulation only");
    return NULL;
}

EBB_EXPORT void fmi3FreeInstance(fmi3Instance instance) { ebb_free(instance); }

EBB_EXPORT fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                                  fmi3Float64 tolerance, fmi3Float64 startTime,
                                                  fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (!instance) return fmi3Error;
    INST(instance)->time = startTime;
    return fmi3OK;
}

EBB_EXPORT fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    if (!instance) return fmi3Error;
    INST(instance)->stale = 1;
    return ST(ebb_ensure_model(instance, "fmi3ExitInitializationMode"));
}

EBB_EXPORT fmi3Status fmi3EnterEventMode(fmi3Instance instance) { return instance ? fmi3OK : fmi3Error; }
EBB_EXPORT fmi3Status fmi3Terminate(fmi3Instance instance) { return instance ? fmi3OK : fmi3Error; }

EBB_EXPORT fmi3Status fmi3Reset(fmi3Instance instance)
{
    if (!instance) return fmi3Error;
    ebb_reset(instance);
    return fmi3OK;
}

/* ------------------------------------------------------------------ variables */
EBB_EXPORT fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                     fmi3Float64 values[], size_t nValues)
{
    if (!instance) return fmi3Error;
    return ST(ebb_get_real(instance, "fmi3GetFloat64", vr, nvr, values, nValues));
}

EBB_EXPORT fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                     const fmi3Float64 values[], size_t nValues)
{
    if (!instance) return fmi3Error;
    return ST(ebb_set_real(instance, "fmi3SetFloat64", vr, nvr, values, nValues));
}

EBB_EXPORT fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3Int32 values[], size_t nValues)
{
    if (!instance) return fmi3Error;
    return ST(ebb_get_integer(instance, "fmi3GetInt32", vr, nvr, values, nValues));
}

EBB_EXPORT fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    fmi3String values[], size_t nValues)
{
    if (!instance) return fmi3Error;
    return ST(ebb_get_string(instance, "fmi3GetString", vr, nvr, values, nValues));
}

/* the types this FMU has no variables of: a call with value references is an error naming the type */
#define NO_VARIABLES(Name, Type)                                                                              \
    EBB_EXPORT fmi3Status fmi3Get##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,   \
                                        Type values[], size_t nValues)                                      \
    {                                                                                                       \
        (void)values; (void)nValues;                                                                        \
        if (!instance) return fmi3Error;                                                                    \
        return ST(ebb_refuse(instance, "fmi3Get" #Name, #Name, vr, nvr));                                   \
    }                                                                                                       \
    EBB_EXPORT fmi3Status fmi3Set##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,   \
                                        const Type values[], size_t nValues)                                \
    {                                                                                                       \
        (void)values; (void)nValues;                                                                        \
        if (!instance) return fmi3Error;                                                                    \
        return ST(ebb_refuse(instance, "fmi3Set" #Name, #Name, vr, nvr));                                   \
    }
NO_VARIABLES(Float32, fmi3Float32)
NO_VARIABLES(Int8, fmi3Int8)
NO_VARIABLES(UInt8, fmi3UInt8)
NO_VARIABLES(Int16, fmi3Int16)
NO_VARIABLES(UInt16, fmi3UInt16)
NO_VARIABLES(UInt32, fmi3UInt32)
NO_VARIABLES(Int64, fmi3Int64)
NO_VARIABLES(UInt64, fmi3UInt64)
NO_VARIABLES(Boolean, fmi3Boolean)

EBB_EXPORT fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3Int32 values[], size_t nValues)
{
    (void)values; (void)nValues;
    if (!instance) return fmi3Error;
    return ST(ebb_refuse(instance, "fmi3SetInt32", NULL, vr, nvr));
}

EBB_EXPORT fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3String values[], size_t nValues)
{
    (void)values; (void)nValues;
    if (!instance) return fmi3Error;
    return ST(ebb_refuse(instance, "fmi3SetString", NULL, vr, nvr));
}

EBB_EXPORT fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    (void)valueSizes; (void)values; (void)nValues;
    if (!instance) return fmi3Error;
    return ST(ebb_refuse(instance, "fmi3GetBinary", "Binary", vr, nvr));
}

EBB_EXPORT fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    (void)valueSizes; (void)values; (void)nValues;
    if (!instance) return fmi3Error;
    return ST(ebb_refuse(instance, "fmi3SetBinary", "Binary", vr, nvr));
}

EBB_EXPORT fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3Clock values[])
{
    (void)values;
    if (!instance) return fmi3Error;
    return ST(ebb_refuse(instance, "fmi3GetClock", "Clock", vr, nvr));
}

EBB_EXPORT fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3Clock values[])
{
    (void)values;
    if (!instance) return fmi3Error;
    return ST(ebb_refuse(instance, "fmi3SetClock", "Clock", vr, nvr));
}

EBB_EXPORT fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference vr,
                                                          size_t *nDependencies)
{
    (void)vr; (void)nDependencies;
    return ST(ebb_fail(instance, "fmi3GetNumberOfVariableDependencies", "not provided (the model description's "
                       "dependencies are the whole of it)"));
}

EBB_EXPORT fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                                  size_t elementIndicesOfDependent[],
                                                  fmi3ValueReference independents[],
                                                  size_t elementIndicesOfIndependents[],
                                                  fmi3DependencyKind dependencyKinds[], size_t nDependencies)
{
    (void)dependent; (void)elementIndicesOfDependent; (void)independents; (void)elementIndicesOfIndependents;
    (void)dependencyKinds; (void)nDependencies;
    return ST(ebb_fail(instance, "fmi3GetVariableDependencies", "not provided (the model description's "
                       "dependencies are the whole of it)"));
}

/* ------------------------------------------------------------------ FMU state */
EBB_EXPORT fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *state)
{
    if (!instance) return fmi3Error;
    if (!state) return ST(ebb_fail(instance, "fmi3GetFMUState", "no place for the state (NULL)"));
    void *s = ebb_state_get(instance, "fmi3GetFMUState", *state);
    if (!s) return fmi3Error;
    *state = s;
    return fmi3OK;
}

EBB_EXPORT fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState state)
{
    if (!instance) return fmi3Error;
    return ST(ebb_state_set(instance, "fmi3SetFMUState", state));
}

EBB_EXPORT fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *state)
{
    if (!instance) return fmi3Error;
    if (state) { free(*state); *state = NULL; }
    return fmi3OK;
}

EBB_EXPORT fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState state, size_t *size)
{
    if (!instance) return fmi3Error;
    if (ebb_state_check(instance, "fmi3SerializedFMUStateSize", state) != 0) return fmi3Error;
    *size = ebb_state_size();
    return fmi3OK;
}

EBB_EXPORT fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState state, fmi3Byte bytes[],
                                            size_t size)
{
    if (!instance) return fmi3Error;
    return ST(ebb_state_serialize(instance, "fmi3SerializeFMUState", state, bytes, size));
}

EBB_EXPORT fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte bytes[], size_t size,
                                              fmi3FMUState *state)
{
    if (!instance) return fmi3Error;
    void *s = ebb_state_deserialize(instance, "fmi3DeserializeFMUState", bytes, size, *state);
    if (!s) return fmi3Error;
    *state = s;
    return fmi3OK;
}

/* ------------------------------------------------------------------ derivatives */
EBB_EXPORT fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                                   size_t nUnknowns, const fmi3ValueReference knowns[],
                                                   size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                                   fmi3Float64 sensitivity[], size_t nSensitivity)
{
    if (!instance) return fmi3Error;
    return ST(ebb_directional(instance, "fmi3GetDirectionalDerivative", unknowns, nUnknowns, knowns, nKnowns,
                              seed, nSeed, sensitivity, nSensitivity));
}

EBB_EXPORT fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                               size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns,
                                               const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[],
                                               size_t nSensitivity)
{
    if (!instance) return fmi3Error;
    return ST(ebb_adjoint(instance, "fmi3GetAdjointDerivative", unknowns, nUnknowns, knowns, nKnowns, seed, nSeed,
                          sensitivity, nSensitivity));
}

/* ------------------------------------------------------------------ clocks and configuration: none */
EBB_EXPORT fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance)
{ return ST(ebb_fail(instance, "fmi3EnterConfigurationMode", "this FMU has no structural parameters")); }
EBB_EXPORT fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance)
{ return ST(ebb_fail(instance, "fmi3ExitConfigurationMode", "this FMU has no structural parameters")); }

static fmi3Status no_clocks(fmi3Instance instance, const char *function, const fmi3ValueReference vr[], size_t nvr)
{
    if (!instance) return fmi3Error;
    return ST(ebb_refuse(instance, function, "Clock", vr, nvr));
}

EBB_EXPORT fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                             fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
{ (void)intervals; (void)qualifiers; return no_clocks(instance, "fmi3GetIntervalDecimal", vr, nvr); }
EBB_EXPORT fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                              fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
{ (void)counters; (void)resolutions; (void)qualifiers; return no_clocks(instance, "fmi3GetIntervalFraction", vr, nvr); }
EBB_EXPORT fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                          fmi3Float64 shifts[])
{ (void)shifts; return no_clocks(instance, "fmi3GetShiftDecimal", vr, nvr); }
EBB_EXPORT fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                           fmi3UInt64 counters[], fmi3UInt64 resolutions[])
{ (void)counters; (void)resolutions; return no_clocks(instance, "fmi3GetShiftFraction", vr, nvr); }
EBB_EXPORT fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                             const fmi3Float64 intervals[])
{ (void)intervals; return no_clocks(instance, "fmi3SetIntervalDecimal", vr, nvr); }
EBB_EXPORT fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                              const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
{ (void)counters; (void)resolutions; return no_clocks(instance, "fmi3SetIntervalFraction", vr, nvr); }
EBB_EXPORT fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                          const fmi3Float64 shifts[])
{ (void)shifts; return no_clocks(instance, "fmi3SetShiftDecimal", vr, nvr); }
EBB_EXPORT fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                           const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
{ (void)counters; (void)resolutions; return no_clocks(instance, "fmi3SetShiftFraction", vr, nvr); }

EBB_EXPORT fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { return instance ? fmi3OK : fmi3Error; }

EBB_EXPORT fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                               fmi3Boolean *terminateSimulation,
                                               fmi3Boolean *nominalsOfContinuousStatesChanged,
                                               fmi3Boolean *valuesOfContinuousStatesChanged,
                                               fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime)
{
    if (!instance) return fmi3Error;
    *discreteStatesNeedUpdate = false;
    *terminateSimulation = false;
    *nominalsOfContinuousStatesChanged = false;
    *valuesOfContinuousStatesChanged = false;
    *nextEventTimeDefined = false;
    *nextEventTime = 0.0;
    return fmi3OK;
}

/* ------------------------------------------------------------------ model exchange */
EBB_EXPORT fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { return instance ? fmi3OK : fmi3Error; }

EBB_EXPORT fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                                  fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!instance) return fmi3Error;
    *enterEventMode = false;
    *terminateSimulation = false;
    return fmi3OK;
}

EBB_EXPORT fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    if (!instance) return fmi3Error;
    INST(instance)->time = time;
    return fmi3OK;
}

EBB_EXPORT fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t nx)
{
    if (!instance) return fmi3Error;
    return ST(ebb_set_states(instance, "fmi3SetContinuousStates", x, nx));
}

EBB_EXPORT fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 dx[], size_t nx)
{
    if (!instance) return fmi3Error;
    return ST(ebb_get_derivatives(instance, "fmi3GetContinuousStateDerivatives", dx, nx));
}

EBB_EXPORT fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 ind[], size_t ni)
{
    (void)ind;
    if (!instance) return fmi3Error;
    return ni == 0 ? fmi3OK : ST(ebb_fail(instance, "fmi3GetEventIndicators", "this FMU has no event indicators"));
}

EBB_EXPORT fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t nx)
{
    if (!instance) return fmi3Error;
    return ST(ebb_get_states(instance, "fmi3GetContinuousStates", x, nx));
}

EBB_EXPORT fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nx)
{
    if (!instance) return fmi3Error;
    return ST(ebb_get_nominals(instance, "fmi3GetNominalsOfContinuousStates", nominals, nx));
}

EBB_EXPORT fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *n)
{
    if (!instance) return fmi3Error;
    *n = 0;
    return fmi3OK;
}

EBB_EXPORT fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *n)
{
    if (!instance) return fmi3Error;
    *n = EBB_NSTATES;
    return fmi3OK;
}

/* ------------------------------------------------------------------ co-simulation */
EBB_EXPORT fmi3Status fmi3EnterStepMode(fmi3Instance instance) { return instance ? fmi3OK : fmi3Error; }

EBB_EXPORT fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                               const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues)
{
    (void)vr; (void)nvr; (void)orders; (void)values; (void)nValues;
    return ST(ebb_fail(instance, "fmi3GetOutputDerivatives", "not supported (maxOutputDerivativeOrder is 0)"));
}

EBB_EXPORT fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                                 fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                 fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                                 fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!instance) return fmi3Error;
    const int rc = ebb_do_step(instance, "fmi3DoStep", currentCommunicationPoint, communicationStepSize);
    if (eventHandlingNeeded) *eventHandlingNeeded = false;
    if (terminateSimulation) *terminateSimulation = false;
    if (earlyReturn) *earlyReturn = false;
    if (lastSuccessfulTime) *lastSuccessfulTime = INST(instance)->time;
    return ST(rc);
}

/* ------------------------------------------------------------------ scheduled execution: not provided */
EBB_EXPORT fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                                 fmi3Float64 activationTime)
{
    (void)clockReference; (void)activationTime;
    return ST(ebb_fail(instance, "fmi3ActivateModelPartition", "scheduled execution is not provided"));
}
