/*
 * loader3.c -- the FMI 3.0 entry library of a Python beam FMU built by fmu_build (build_fmu(..., fmi=3)).
 *
 * pythonfmu3's export library (binaries/x86_64-linux/<inner>) is, like pythonfmu's, not linked against
 * libpython: a host without Python in its process cannot load it ("undefined symbol: _Py_NoneStruct").  This
 * loader is the library a master opens (binaries/x86_64-linux/<modelIdentifier>.so); what it shares with the
 * FMI 2.0 loader (loader.c) is in loader_common.h: on the first fmi3InstantiateCoSimulation it brings the build
 * interpreter's libpython when the process has no Python, loads pythonfmu3's library, and sets PYTHONHOME and
 * PYTHONPATH for the moment Python starts.
 *
 * What it adds to pythonfmu3's calls:
 *
 *   - status: the slave reports recoverable problems (invalid parameters, a step size that is not a multiple
 *     of dt, NaN inputs) by logging a message of status fmi3Error, because pythonfmu3 turns a Python exception
 *     into fmi3Fatal.  The loader passes its own logger to pythonfmu3, notes the worst status logged during a
 *     call and returns at least that status (capped at fmi3Error);
 *   - logging: messages of status fmi3Error and above always reach the host, others when the host enabled debug
 *     logging (and named their category, if it named any); a message without a category (pythonfmu3 logs its
 *     own failures so) gets its status's, e.g. logStatusFatal;
 *   - checks pythonfmu3's library leaves out: the instantiation token, and the number of values of every
 *     fmi3Get/SetFloat64 (the array elements, EBB_ARRAYS) and fmi3Get/SetInt32, Boolean, String call --
 *     pythonfmu3 reads nValues values from the slave's answer whatever its length;
 *   - the functions pythonfmu3 leaves unimplemented (they throw a C++ exception into the host) or this FMU does
 *     not offer (model exchange, FMU states, derivatives, clocks, the other types) answer fmi3Error with a logged
 *     message naming the function.
 *
 * Build-time constants come from loader_config.h, written by loader.py: those of loader.c (EBB_GUID the
 * instantiation token) and EBB_ARRAYS / EBB_N_ARRAYS, the {value reference, elements} of the array variables.
 * Compiled against the standard's fmi3Functions.h (pythonfmu3 ships it), so every definition is checked
 * against the standard's declaration.
 */
#define _GNU_SOURCE
#include "loader_config.h"
#include "loader_common.h"
#include "fmi3Functions.h"

typedef struct {
    fmi3InstantiateCoSimulationTYPE *InstantiateCoSimulation;
    fmi3FreeInstanceTYPE *FreeInstance;
    fmi3EnterInitializationModeTYPE *EnterInitializationMode;
    fmi3ExitInitializationModeTYPE *ExitInitializationMode;
    fmi3TerminateTYPE *Terminate;
    fmi3ResetTYPE *Reset;
    fmi3GetFloat64TYPE *GetFloat64;
    fmi3SetFloat64TYPE *SetFloat64;
    fmi3GetInt32TYPE *GetInt32;
    fmi3SetInt32TYPE *SetInt32;
    fmi3GetBooleanTYPE *GetBoolean;
    fmi3SetBooleanTYPE *SetBoolean;
    fmi3GetStringTYPE *GetString;
    fmi3SetStringTYPE *SetString;
    fmi3DoStepTYPE *DoStep;
} InnerApi;

static InnerApi g_api;

typedef struct {
    fmi3ValueReference vr;
    size_t n;
} ArraySize;

static const ArraySize g_arrays[EBB_N_ARRAYS + 1] = EBB_ARRAYS;

/* One instance as the host sees it: wraps pythonfmu3's. */
typedef struct {
    fmi3Instance inner;
    fmi3InstanceEnvironment env;  /* the host's */
    fmi3LogMessageCallback logger; /* the host's */
    LogSwitch log;
} Instance;

static void load_inner(void)
{
    if (load_python_and_inner()) return;
    RESOLVE(InstantiateCoSimulation, "fmi3InstantiateCoSimulation");
    RESOLVE(FreeInstance, "fmi3FreeInstance");
    RESOLVE(EnterInitializationMode, "fmi3EnterInitializationMode");
    RESOLVE(ExitInitializationMode, "fmi3ExitInitializationMode");
    RESOLVE(Terminate, "fmi3Terminate");
    RESOLVE(Reset, "fmi3Reset");
    RESOLVE(GetFloat64, "fmi3GetFloat64");
    RESOLVE(SetFloat64, "fmi3SetFloat64");
    RESOLVE(GetInt32, "fmi3GetInt32");
    RESOLVE(SetInt32, "fmi3SetInt32");
    RESOLVE(GetBoolean, "fmi3GetBoolean");
    RESOLVE(SetBoolean, "fmi3SetBoolean");
    RESOLVE(GetString, "fmi3GetString");
    RESOLVE(SetString, "fmi3SetString");
    RESOLVE(DoStep, "fmi3DoStep");
    keep_inner();
}

/* ---- logging and status -------------------------------------------------------------------------------------- */

static void emit(const Instance *inst, fmi3Status status, fmi3String category, fmi3String message)
{
    static const char *const by_status[] = {"logAll", "logStatusWarning", "logStatusDiscard", "logStatusError",
                                            "logStatusFatal"};
    if (!inst->logger) return;
    if (!category || !*category) category = by_status[(unsigned)status <= fmi3Fatal ? (unsigned)status : 4u];
    inst->logger(inst->env, status, category, message ? message : "");
}

static void relay_log(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message)
{
    Instance *inst = (Instance *)env;
    if (inst && log_switch_passes(&inst->log, (int)status, category)) emit(inst, status, category, message);
}

/* An error of the loader's own, logged as the slave's are (so that the call's status is at least an error). */
static fmi3Status refuse(Instance *inst, const char *function, const char *fmt, size_t a, size_t b)
{
    char msg[512];
    int n = snprintf(msg, sizeof msg, "%s: ", function);
    snprintf(msg + n, sizeof msg - (size_t)n, fmt, a, b);
    if (inst) relay_log(inst, fmi3Error, "logStatusError", msg);
    return fmi3Error;
}

static fmi3Status unsupported(fmi3Instance c, const char *function, const char *why)
{
    return refuse((Instance *)c, function, why, 0, 0);
}

/* The number of values the references stand for (an array its elements, else one each). */
static size_t elements(const fmi3ValueReference vr[], size_t nvr, int arrays)
{
    size_t total = 0;
    for (size_t i = 0; i < nvr; ++i) {
        size_t n = 1;
        for (size_t j = 0; arrays && j < EBB_N_ARRAYS; ++j) {
            if (g_arrays[j].vr == vr[i]) n = g_arrays[j].n;
        }
        total += n;
    }
    return total;
}

#define BEGIN(c)                                     \
    Instance *inst = (Instance *)(c);                \
    if (!inst || !inst->inner) return fmi3Error;     \
    inst->log.worst = fmi3OK

#define FORWARD(call) return (fmi3Status)log_switch_settle(&inst->log, (int)g_api.call)

/* A get/set of type T forwarded once the number of values is checked (Float64: arrays count their elements). */
#define VALUES(Name, T, constness, arrays)                                                                      \
    fmi3Status fmi3##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, constness T values[], \
                          size_t nValues)                                                                        \
    {                                                                                                            \
        BEGIN(instance);                                                                                         \
        size_t expected = elements(vr, nvr, arrays);                                                             \
        if (nValues != expected)                                                                                 \
            return refuse(inst, "fmi3" #Name, "%zu values given for variables of %zu element(s)", nValues,       \
                          expected);                                                                             \
        FORWARD(Name(inst->inner, vr, nvr, values, nValues));                                                    \
    }

/* ---- FMI 3.0 functions ----------------------------------------------------------------------------------------- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    Instance *inst = calloc(1, sizeof *inst);
    if (!inst) return NULL;
    inst->env = instanceEnvironment;
    inst->logger = logMessage;
    inst->log.on = loggingOn;
    pthread_once(&g_once, load_inner);
    if (g_error[0]) {
        emit(inst, fmi3Fatal, "logStatusFatal", g_error);
        free(inst);
        return NULL;
    }
    if (instantiationToken && strcmp(instantiationToken, EBB_GUID) != 0) {
        char msg[512];
        snprintf(msg, sizeof msg, "fmi3InstantiateCoSimulation: instantiation token %s does not match this FMU's %s",
                 instantiationToken, EBB_GUID);
        emit(inst, fmi3Error, "logStatusError", msg);
        free(inst);
        return NULL;
    }
    /* pythonfmu3 always logs to us (debug messages too); the host's switch is applied in relay_log. */
    int set = begin_python_start();
    inst->inner = g_api.InstantiateCoSimulation(instanceName, instantiationToken, resourcePath, visible, fmi3True,
                                                eventModeUsed, earlyReturnAllowed, requiredIntermediateVariables,
                                                nRequiredIntermediateVariables, inst, relay_log, intermediateUpdate);
    end_python_start(set);
    if (!inst->inner) {
        log_switch_clear(&inst->log);
        free(inst);
        return NULL;
    }
    return inst;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                               "fmi3InstantiateModelExchange: this FMU supports co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption)
{
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                               "fmi3InstantiateScheduledExecution: this FMU supports co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance)
{
    Instance *inst = (Instance *)instance;
    if (!inst) return;
    if (inst->inner) g_api.FreeInstance(inst->inner);
    log_switch_clear(&inst->log);
    free(inst);
}

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    BEGIN(instance);
    return (fmi3Status)log_switch_set(&inst->log, loggingOn, nCategories, categories);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    BEGIN(instance);
    FORWARD(EnterInitializationMode(inst->inner, toleranceDefined, tolerance, startTime, stopTimeDefined,
                                    stopTime));
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    BEGIN(instance);
    FORWARD(ExitInitializationMode(inst->inner));
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    BEGIN(instance);
    FORWARD(Terminate(inst->inner));
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    BEGIN(instance);
    FORWARD(Reset(inst->inner));
}

VALUES(GetFloat64, fmi3Float64, , 1)
VALUES(SetFloat64, fmi3Float64, const, 1)
VALUES(GetInt32, fmi3Int32, , 0)
VALUES(SetInt32, fmi3Int32, const, 0)
VALUES(GetBoolean, fmi3Boolean, , 0)
VALUES(SetBoolean, fmi3Boolean, const, 0)
VALUES(GetString, fmi3String, , 0)
VALUES(SetString, fmi3String, const, 0)

fmi3Status fmi3EnterStepMode(fmi3Instance instance)
{
    BEGIN(instance);
    return fmi3OK; /* no event mode: the instance is in step mode once initialised */
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime)
{
    BEGIN(instance);
    fmi3Boolean event = fmi3False, terminate = fmi3False, early = fmi3False;
    fmi3Float64 last = currentCommunicationPoint;
    int status = (int)g_api.DoStep(inst->inner, currentCommunicationPoint, communicationStepSize,
                                   noSetFMUStatePriorToCurrentPoint, &event, &terminate, &early, &last);
    if (eventHandlingNeeded) *eventHandlingNeeded = event;
    if (terminateSimulation) *terminateSimulation = terminate;
    if (earlyReturn) *earlyReturn = early;
    if (lastSuccessfulTime) *lastSuccessfulTime = last;
    return (fmi3Status)log_switch_settle(&inst->log, status);
}

/* ---- what this FMU does not offer --------------------------------------------------------------------------- */

#define UNSUPPORTED(Name, why, params) \
    fmi3Status fmi3##Name params { return unsupported(instance, "fmi3" #Name, why); }

#define NO_TYPE(T, type)                                                                                        \
    UNSUPPORTED(Get##T, "this FMU has no " #T " variables", (fmi3Instance instance, const fmi3ValueReference vr[], \
                size_t nvr, type values[], size_t nValues))                                                       \
    UNSUPPORTED(Set##T, "this FMU has no " #T " variables", (fmi3Instance instance, const fmi3ValueReference vr[], \
                size_t nvr, const type values[], size_t nValues))

NO_TYPE(Float32, fmi3Float32)
NO_TYPE(Int8, fmi3Int8)
NO_TYPE(UInt8, fmi3UInt8)
NO_TYPE(Int16, fmi3Int16)
NO_TYPE(UInt16, fmi3UInt16)
NO_TYPE(UInt32, fmi3UInt32)
NO_TYPE(Int64, fmi3Int64)
NO_TYPE(UInt64, fmi3UInt64)

#define NO_BINARY "this FMU has no Binary variables"
#define NO_CLOCK "this FMU has no clocks"
#define NO_STATE "this FMU cannot get or set its state (canGetAndSetFMUState is false)"
#define NO_DERIVATIVES "this FMU provides no derivatives"
#define NO_ME "this FMU supports co-simulation only"
#define NO_EVENTS "this FMU has no event mode"
UNSUPPORTED(GetBinary, NO_BINARY, (fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
            size_t valueSizes[], fmi3Binary values[], size_t nValues))
UNSUPPORTED(SetBinary, NO_BINARY, (fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
            const size_t valueSizes[], const fmi3Binary values[], size_t nValues))
UNSUPPORTED(GetClock, NO_CLOCK, (fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
            fmi3Clock values[]))
UNSUPPORTED(SetClock, NO_CLOCK, (fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
            const fmi3Clock values[]))
UNSUPPORTED(GetIntervalDecimal, NO_CLOCK, (fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
            fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]))
UNSUPPORTED(GetIntervalFraction, NO_CLOCK, (fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
            fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]))
UNSUPPORTED(GetShiftDecimal, NO_CLOCK, (fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
            fmi3Float64 shifts[]))
UNSUPPORTED(GetShiftFraction, NO_CLOCK, (fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
            fmi3UInt64 counters[], fmi3UInt64 resolutions[]))
UNSUPPORTED(SetIntervalDecimal, NO_CLOCK, (fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
            const fmi3Float64 intervals[]))
UNSUPPORTED(SetIntervalFraction, NO_CLOCK, (fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
            const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]))
UNSUPPORTED(SetShiftDecimal, NO_CLOCK, (fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
            const fmi3Float64 shifts[]))
UNSUPPORTED(SetShiftFraction, NO_CLOCK, (fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
            const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]))
UNSUPPORTED(ActivateModelPartition, NO_CLOCK, (fmi3Instance instance, fmi3ValueReference clockReference,
            fmi3Float64 activationTime))
UNSUPPORTED(GetNumberOfVariableDependencies, "the dependencies are in the model description",
            (fmi3Instance instance, fmi3ValueReference vr, size_t *nDependencies))
UNSUPPORTED(GetVariableDependencies, "the dependencies are in the model description",
            (fmi3Instance instance, fmi3ValueReference dependent, size_t elementIndicesOfDependent[],
             fmi3ValueReference independents[], size_t elementIndicesOfIndependents[],
             fmi3DependencyKind dependencyKinds[], size_t nDependencies))
UNSUPPORTED(GetFMUState, NO_STATE, (fmi3Instance instance, fmi3FMUState *FMUState))
UNSUPPORTED(SetFMUState, NO_STATE, (fmi3Instance instance, fmi3FMUState FMUState))
UNSUPPORTED(FreeFMUState, NO_STATE, (fmi3Instance instance, fmi3FMUState *FMUState))
UNSUPPORTED(SerializedFMUStateSize, NO_STATE, (fmi3Instance instance, fmi3FMUState FMUState, size_t *size))
UNSUPPORTED(SerializeFMUState, NO_STATE, (fmi3Instance instance, fmi3FMUState FMUState,
            fmi3Byte serializedState[], size_t size))
UNSUPPORTED(DeserializeFMUState, NO_STATE, (fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
            fmi3FMUState *FMUState))
UNSUPPORTED(GetDirectionalDerivative, NO_DERIVATIVES, (fmi3Instance instance, const fmi3ValueReference unknowns[],
            size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
            size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity))
UNSUPPORTED(GetAdjointDerivative, NO_DERIVATIVES, (fmi3Instance instance, const fmi3ValueReference unknowns[],
            size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
            size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity))
UNSUPPORTED(GetOutputDerivatives, NO_DERIVATIVES, (fmi3Instance instance, const fmi3ValueReference vr[],
            size_t nvr, const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues))
UNSUPPORTED(EnterConfigurationMode, "this FMU has no structural parameters", (fmi3Instance instance))
UNSUPPORTED(ExitConfigurationMode, "this FMU has no structural parameters", (fmi3Instance instance))
UNSUPPORTED(EnterEventMode, NO_EVENTS, (fmi3Instance instance))
UNSUPPORTED(EvaluateDiscreteStates, NO_EVENTS, (fmi3Instance instance))
UNSUPPORTED(UpdateDiscreteStates, NO_EVENTS, (fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
            fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
            fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
            fmi3Float64 *nextEventTime))
UNSUPPORTED(EnterContinuousTimeMode, NO_ME, (fmi3Instance instance))
UNSUPPORTED(CompletedIntegratorStep, NO_ME, (fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
            fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation))
UNSUPPORTED(SetTime, NO_ME, (fmi3Instance instance, fmi3Float64 time))
UNSUPPORTED(SetContinuousStates, NO_ME, (fmi3Instance instance, const fmi3Float64 continuousStates[],
            size_t nContinuousStates))
UNSUPPORTED(GetContinuousStateDerivatives, NO_ME, (fmi3Instance instance, fmi3Float64 derivatives[],
            size_t nContinuousStates))
UNSUPPORTED(GetEventIndicators, NO_ME, (fmi3Instance instance, fmi3Float64 eventIndicators[],
            size_t nEventIndicators))
UNSUPPORTED(GetContinuousStates, NO_ME, (fmi3Instance instance, fmi3Float64 continuousStates[],
            size_t nContinuousStates))
UNSUPPORTED(GetNominalsOfContinuousStates, NO_ME, (fmi3Instance instance, fmi3Float64 nominals[],
            size_t nContinuousStates))
UNSUPPORTED(GetNumberOfEventIndicators, NO_ME, (fmi3Instance instance, size_t *nEventIndicators))
UNSUPPORTED(GetNumberOfContinuousStates, NO_ME, (fmi3Instance instance, size_t *nContinuousStates))
