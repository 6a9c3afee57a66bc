/*
 * loader.c -- the FMI 2.0 entry library of a beam FMU built by fmu_build.
 *
 * pythonfmu's export library (shipped in the FMU as binaries/linux64/<inner>)
 * calls the Python C API but is not linked against libpython: it only works in
 * a process that already contains a Python interpreter.  This loader is the
 * library a master opens (binaries/linux64/<modelIdentifier>.so).  On the first
 * fmi2Instantiate it
 *
 *   1. looks whether the Python C API is already visible in the process (a
 *      Python host such as fmpy or libcosimpy).  If not, it dlopens the
 *      libpython of the interpreter the FMU was built with, RTLD_GLOBAL, so
 *      that pythonfmu *and* the extension modules numpy imports later resolve
 *      their Python symbols;
 *   2. dlopens pythonfmu's library from its own directory (RTLD_LOCAL) and
 *      resolves every fmi2 function it forwards to.
 *
 * pythonfmu starts the interpreter inside its fmi2Instantiate.  While that
 * can happen (libpython loaded here, Py_IsInitialized() false) the loader
 * points PYTHONHOME and PYTHONPATH at the build interpreter -- only those the
 * host has not set -- for the duration of that one call, then removes them
 * again: the host's environment is left as it was.
 *
 * Every fmi2 call is forwarded unchanged, with one addition: the Python slave
 * reports recoverable problems (invalid parameters, a step size that is not a
 * multiple of dt, NaN inputs) by logging a message of status fmi2Error and
 * returning normally, because pythonfmu turns any Python exception into
 * fmi2Fatal.  The loader passes its own logger to pythonfmu, notes the worst
 * status logged during a call and returns at least that status (capped at
 * fmi2Error).  It also owns the host's debug-logging switch: messages of
 * status fmi2Error and above always reach the host's logger, others only when
 * the host enabled debug logging (and the category, if the host named any).
 *
 * Build-time constants come from loader_config.h, written by loader.py:
 *   EBB_PYTHON      the build interpreter (checked, with EBB_PYTHONPATH, before Python starts)
 *   EBB_LIBPYTHON   absolute path of the shared libpython
 *   EBB_PYTHONHOME  value for PYTHONHOME ("prefix" or "prefix:exec_prefix")
 *   EBB_PYTHONPATH  value for PYTHONPATH (site-packages of the build interpreter)
 *   EBB_INNER_LIB   file name of pythonfmu's library next to this one
 *   EBB_GUID        the FMU's GUID, checked in fmi2Instantiate
 */
#define _GNU_SOURCE
#include <stdarg.h>

#include "loader_config.h"
#include "loader_common.h"

/* ---- FMI 2.0 types (fmi2TypesPlatform.h / fmi2FunctionTypes.h) ---------- */

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

typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;

typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);

typedef struct {
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2StepFinished stepFinished;
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

/* ---- the forwarded API --------------------------------------------------- */

typedef struct {
    fmi2Component (*Instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                 const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
    void (*FreeInstance)(fmi2Component);
    fmi2Status (*SetDebugLogging)(fmi2Component, fmi2Boolean, size_t, const fmi2String[]);
    fmi2Status (*SetupExperiment)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real);
    fmi2Status (*EnterInitializationMode)(fmi2Component);
    fmi2Status (*ExitInitializationMode)(fmi2Component);
    fmi2Status (*Terminate)(fmi2Component);
    fmi2Status (*Reset)(fmi2Component);
    fmi2Status (*GetReal)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]);
    fmi2Status (*GetInteger)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Integer[]);
    fmi2Status (*GetBoolean)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Boolean[]);
    fmi2Status (*GetString)(fmi2Component, const fmi2ValueReference[], size_t, fmi2String[]);
    fmi2Status (*SetReal)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Real[]);
    fmi2Status (*SetInteger)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[]);
    fmi2Status (*SetBoolean)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Boolean[]);
    fmi2Status (*SetString)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2String[]);
    fmi2Status (*GetFMUstate)(fmi2Component, fmi2FMUstate *);
    fmi2Status (*SetFMUstate)(fmi2Component, fmi2FMUstate);
    fmi2Status (*FreeFMUstate)(fmi2Component, fmi2FMUstate *);
    fmi2Status (*SerializedFMUstateSize)(fmi2Component, fmi2FMUstate, size_t *);
    fmi2Status (*SerializeFMUstate)(fmi2Component, fmi2FMUstate, fmi2Byte[], size_t);
    fmi2Status (*DeSerializeFMUstate)(fmi2Component, const fmi2Byte[], size_t, fmi2FMUstate *);
    fmi2Status (*GetDirectionalDerivative)(fmi2Component, const fmi2ValueReference[], size_t,
                                           const fmi2ValueReference[], size_t, const fmi2Real[], fmi2Real[]);
    fmi2Status (*SetRealInputDerivatives)(fmi2Component, const fmi2ValueReference[], size_t,
                                          const fmi2Integer[], const fmi2Real[]);
    fmi2Status (*GetRealOutputDerivatives)(fmi2Component, const fmi2ValueReference[], size_t,
                                           const fmi2Integer[], fmi2Real[]);
    fmi2Status (*DoStep)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
    fmi2Status (*CancelStep)(fmi2Component);
    fmi2Status (*GetStatus)(fmi2Component, const fmi2StatusKind, fmi2Status *);
    fmi2Status (*GetRealStatus)(fmi2Component, const fmi2StatusKind, fmi2Real *);
    fmi2Status (*GetIntegerStatus)(fmi2Component, const fmi2StatusKind, fmi2Integer *);
    fmi2Status (*GetBooleanStatus)(fmi2Component, const fmi2StatusKind, fmi2Boolean *);
    fmi2Status (*GetStringStatus)(fmi2Component, const fmi2StatusKind, fmi2String *);
} InnerApi;

static InnerApi g_api;

/* One instance as the host sees it: wraps pythonfmu's component. */
typedef struct {
    fmi2Component inner;
    fmi2CallbackFunctions host;  /* the host's callbacks (copied) */
    fmi2CallbackFunctions relay; /* what pythonfmu gets: our logger, env = this */
    char *name;
    LogSwitch log; /* the host's logging switch; the worst status logged during the current call */
} Instance;

/* ---- loading ------------------------------------------------------------- */

/*
 * pythonfmu keeps its interpreter state in a global std::shared_ptr and resets
 * it in a function marked __attribute__((destructor)).  Its library cannot be
 * unloaded (it carries GNU_UNIQUE symbols, so dlclose leaves it mapped) and is
 * therefore still loaded when the process exits.  The exit handlers then run
 * the shared_ptr's static destructor, and the ELF destructor afterwards
 * releases the same, already freed, control block a second time: a
 * use-after-free that aborts the process at exit now and then ("corrupted
 * double-linked list").  The loader calls pythonfmu's own reset first, so
 * that both later releases see an empty pointer:
 *   - from unload_inner (loader_common.h), when the host unloads this loader (fmpy, libcosim);
 *   - from an exit handler registered right after pythonfmu's static
 *     initialisers ran (so it runs before their destructors), when the loader
 *     is still loaded at exit -- always the case when it started Python
 *     itself, because it then pins itself (the interpreter must outlive any
 *     reload of the FMU, numpy cannot be initialised twice).
 */
static void load_inner(void)
{
    if (load_python_and_inner()) return;
    RESOLVE(Instantiate, "fmi2Instantiate");
    RESOLVE(FreeInstance, "fmi2FreeInstance");
    RESOLVE(SetDebugLogging, "fmi2SetDebugLogging");
    RESOLVE(SetupExperiment, "fmi2SetupExperiment");
    RESOLVE(EnterInitializationMode, "fmi2EnterInitializationMode");
    RESOLVE(ExitInitializationMode, "fmi2ExitInitializationMode");
    RESOLVE(Terminate, "fmi2Terminate");
    RESOLVE(Reset, "fmi2Reset");
    RESOLVE(GetReal, "fmi2GetReal");
    RESOLVE(GetInteger, "fmi2GetInteger");
    RESOLVE(GetBoolean, "fmi2GetBoolean");
    RESOLVE(GetString, "fmi2GetString");
    RESOLVE(SetReal, "fmi2SetReal");
    RESOLVE(SetInteger, "fmi2SetInteger");
    RESOLVE(SetBoolean, "fmi2SetBoolean");
    RESOLVE(SetString, "fmi2SetString");
    RESOLVE(GetFMUstate, "fmi2GetFMUstate");
    RESOLVE(SetFMUstate, "fmi2SetFMUstate");
    RESOLVE(FreeFMUstate, "fmi2FreeFMUstate");
    RESOLVE(SerializedFMUstateSize, "fmi2SerializedFMUstateSize");
    RESOLVE(SerializeFMUstate, "fmi2SerializeFMUstate");
    RESOLVE(DeSerializeFMUstate, "fmi2DeSerializeFMUstate");
    RESOLVE(GetDirectionalDerivative, "fmi2GetDirectionalDerivative");
    RESOLVE(SetRealInputDerivatives, "fmi2SetRealInputDerivatives");
    RESOLVE(GetRealOutputDerivatives, "fmi2GetRealOutputDerivatives");
    RESOLVE(DoStep, "fmi2DoStep");
    RESOLVE(CancelStep, "fmi2CancelStep");
    RESOLVE(GetStatus, "fmi2GetStatus");
    RESOLVE(GetRealStatus, "fmi2GetRealStatus");
    RESOLVE(GetIntegerStatus, "fmi2GetIntegerStatus");
    RESOLVE(GetBooleanStatus, "fmi2GetBooleanStatus");
    RESOLVE(GetStringStatus, "fmi2GetStringStatus");
    keep_inner(); /* see finalize_inner */
}

/* ---- logging and status ---------------------------------------------------- */

/* Messages are passed on as printf formats: double every '%'.  A NULL instance name or category (pythonfmu logs
 * some fatal errors with a NULL category) is passed on as "": hosts build strings from them (OMSimulator's
 * std::string aborts the process on NULL). */
static void emit(const Instance *inst, fmi2String name, fmi2Status status,
                 fmi2String category, fmi2String message)
{
    if (!inst->host.logger) return;
    if (!message) message = "";
    if (!name) name = inst->name ? inst->name : "";
    if (!category) category = "";
    if (!strchr(message, '%')) {
        inst->host.logger(inst->host.componentEnvironment, name, status, category, message);
        return;
    }
    size_t n = strlen(message);
    char *escaped = malloc(2 * n + 1);
    if (!escaped) return;
    char *p = escaped;
    for (const char *q = message; *q; ++q) {
        *p++ = *q;
        if (*q == '%') *p++ = '%';
    }
    *p = '\0';
    inst->host.logger(inst->host.componentEnvironment, name, status, category, escaped);
    free(escaped);
}

static void relay_log(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                      fmi2String category, fmi2String message, ...)
{
    Instance *inst = (Instance *)env;
    if (inst && log_switch_passes(&inst->log, (int)status, category)) emit(inst, name, status, category, message);
}

#define BEGIN(c)                               \
    Instance *inst = (Instance *)(c);          \
    if (!inst || !inst->inner) return fmi2Error; \
    inst->log.worst = fmi2OK

#define FORWARD(call) return (fmi2Status)log_switch_settle(&inst->log, (int)g_api.call)

/* ---- FMI 2.0 functions ------------------------------------------------------ */

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }

EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

static void free_instance(Instance *inst)
{
    log_switch_clear(&inst->log);
    free(inst->name);
    free(inst);
}

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                     fmi2Boolean visible, fmi2Boolean loggingOn)
{
    Instance *inst = calloc(1, sizeof *inst);
    if (!inst) return NULL;
    if (functions) inst->host = *functions;
    inst->name = strdup(instanceName ? instanceName : "");
    inst->log.on = loggingOn;
    inst->relay.logger = relay_log;
    inst->relay.allocateMemory = inst->host.allocateMemory ? inst->host.allocateMemory : calloc;
    inst->relay.freeMemory = inst->host.freeMemory ? inst->host.freeMemory : free;
    inst->relay.stepFinished = NULL;
    inst->relay.componentEnvironment = inst;

    pthread_once(&g_once, load_inner);
    if (g_error[0]) {
        emit(inst, inst->name, fmi2Fatal, "logStatusFatal", g_error);
        free_instance(inst);
        return NULL;
    }
    if (fmuGUID && strcmp(fmuGUID, EBB_GUID) != 0) {
        char msg[512];
        snprintf(msg, sizeof msg, "fmi2Instantiate: GUID %s does not match this FMU's %s", fmuGUID, EBB_GUID);
        emit(inst, inst->name, fmi2Error, "logStatusError", msg);
        free_instance(inst);
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        emit(inst, inst->name, fmi2Error, "logStatusError",
             "fmi2Instantiate: this FMU supports co-simulation only");
        free_instance(inst);
        return NULL;
    }
    /* pythonfmu always logs to us; the host's switch is applied in relay_log. */
    int set = begin_python_start(); /* when this loader brought Python, it may start in this call */
    inst->inner = g_api.Instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation,
                                    &inst->relay, visible, 1);
    end_python_start(set);
    if (!inst->inner) {
        free_instance(inst);
        return NULL;
    }
    return inst;
}

EXPORT void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (!inst) return;
    if (inst->inner) g_api.FreeInstance(inst->inner);
    free_instance(inst);
}

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                                      const fmi2String categories[])
{
    BEGIN(c);
    return (fmi2Status)log_switch_set(&inst->log, loggingOn, nCategories, categories);
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                      fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    BEGIN(c);
    FORWARD(SetupExperiment(inst->inner, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime));
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    BEGIN(c);
    FORWARD(EnterInitializationMode(inst->inner));
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    BEGIN(c);
    FORWARD(ExitInitializationMode(inst->inner));
}

EXPORT fmi2Status fmi2Terminate(fmi2Component c)
{
    BEGIN(c);
    FORWARD(Terminate(inst->inner));
}

EXPORT fmi2Status fmi2Reset(fmi2Component c)
{
    BEGIN(c);
    FORWARD(Reset(inst->inner));
}

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    BEGIN(c);
    FORWARD(GetReal(inst->inner, vr, nvr, value));
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    BEGIN(c);
    FORWARD(GetInteger(inst->inner, vr, nvr, value));
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    BEGIN(c);
    FORWARD(GetBoolean(inst->inner, vr, nvr, value));
}

EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    BEGIN(c);
    FORWARD(GetString(inst->inner, vr, nvr, value));
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    BEGIN(c);
    FORWARD(SetReal(inst->inner, vr, nvr, value));
}

EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 const fmi2Integer value[])
{
    BEGIN(c);
    FORWARD(SetInteger(inst->inner, vr, nvr, value));
}

EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 const fmi2Boolean value[])
{
    BEGIN(c);
    FORWARD(SetBoolean(inst->inner, vr, nvr, value));
}

EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                const fmi2String value[])
{
    BEGIN(c);
    FORWARD(SetString(inst->inner, vr, nvr, value));
}

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    BEGIN(c);
    FORWARD(GetFMUstate(inst->inner, state));
}

EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state)
{
    BEGIN(c);
    FORWARD(SetFMUstate(inst->inner, state));
}

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    BEGIN(c);
    FORWARD(FreeFMUstate(inst->inner, state));
}

EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
{
    BEGIN(c);
    FORWARD(SerializedFMUstateSize(inst->inner, state, size));
}

EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size)
{
    BEGIN(c);
    FORWARD(SerializeFMUstate(inst->inner, state, bytes, size));
}

EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                          fmi2FMUstate *state)
{
    BEGIN(c);
    FORWARD(DeSerializeFMUstate(inst->inner, bytes, size, state));
}

EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown[],
                                               size_t nUnknown, const fmi2ValueReference vKnown[],
                                               size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    BEGIN(c);
    FORWARD(GetDirectionalDerivative(inst->inner, vUnknown, nUnknown, vKnown, nKnown, dvKnown, dvUnknown));
}

EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                              const fmi2Integer order[], const fmi2Real value[])
{
    BEGIN(c);
    FORWARD(SetRealInputDerivatives(inst->inner, vr, nvr, order, value));
}

EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                               const fmi2Integer order[], fmi2Real value[])
{
    BEGIN(c);
    FORWARD(GetRealOutputDerivatives(inst->inner, vr, nvr, order, value));
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                             fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    BEGIN(c);
    FORWARD(DoStep(inst->inner, currentCommunicationPoint, communicationStepSize,
                   noSetFMUStatePriorToCurrentPoint));
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component c)
{
    BEGIN(c);
    FORWARD(CancelStep(inst->inner));
}

EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    BEGIN(c);
    FORWARD(GetStatus(inst->inner, s, value));
}

EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    BEGIN(c);
    FORWARD(GetRealStatus(inst->inner, s, value));
}

EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    BEGIN(c);
    FORWARD(GetIntegerStatus(inst->inner, s, value));
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    BEGIN(c);
    FORWARD(GetBooleanStatus(inst->inner, s, value));
}

EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    BEGIN(c);
    FORWARD(GetStringStatus(inst->inner, s, value));
}
