/*
 * ebb_fmi2.c -- FMI 2.0 interface of the standalone beam FMU: co-simulation and model exchange in one binary.
 *
 * Each call is translated into the version-independent instance of ebb_instance.c (the model, the step, the
 * variables, saved states, derivatives).  The structure of the beam (grid, ends, positions, scheme, dt, start
 * values, the variable table) comes from the generated ebb_config.h; the model is built from the parameter
 * values when initialisation ends, and rebuilt before the next step or evaluation after a parameter changes
 * (the state is kept).
 *
 * Co-simulation (as the pythonfmu FMU of the project): at t_k the master sets u_k; fmi2GetReal returns
 * y_k = Cy xi_k + Dy u_k; fmi2DoStep(t, h) needs h = n dt (n a positive integer, within 1e-6 dt) and applies n
 * samples with the input held.  At the start time the state is "at rest" for the current input.
 * Model exchange: the states of the Richardson modes and the anti-alias filters (ebb_instance.c); refused at
 * instantiation when a sensor's converter delay is carried (a delay line is no continuous-time state).
 * Errors (invalid or unstable parameters, a step that is not a multiple of dt, non-finite inputs, setting a
 * variable that cannot be set) return fmi2Error with a logged message that names the variable; never fmi2Fatal.
 */
#include <stdlib.h>
#include <string.h>

#include "ebb_instance.h"

/* ---- FMI 2.0 types (as the standard defines them) ---- */
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

#define ST(call) ((call) == 0 ? fmi2OK : fmi2Error)
#define INST(comp) ((ebb_instance *)(comp))

static void to_host(const ebb_instance *c, int error, const char *category, const char *message)
{
    const fmi2CallbackLogger logger = (fmi2CallbackLogger)c->host_logger;
    logger(c->env, c->name, error ? fmi2Error : fmi2OK, category, message);
}

/* ------------------------------------------------------------------ common functions */
EBB_EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EBB_EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EBB_EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t n, const fmi2String cats[])
{
    (void)n; (void)cats;
    if (!comp) return fmi2Error;
    INST(comp)->debug = loggingOn ? 1 : 0;
    return fmi2OK;
}

EBB_EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                         fmi2String resourceLocation, const fmi2CallbackFunctions *functions,
                                         fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)resourceLocation; (void)visible;
    ebb_instance tmp;
    memset(&tmp, 0, sizeof(tmp));
    tmp.host_logger = functions ? (ebb_any_fn)functions->logger : NULL;
    tmp.log = tmp.host_logger ? to_host : NULL;
    tmp.env = functions ? functions->componentEnvironment : NULL;
    tmp.name = (char *)(instanceName ? instanceName : "");
    if (!fmuGUID || strcmp(fmuGUID, EBB_GUID) != 0) {
        ebb_fail(&tmp, "fmi2Instantiate", "GUID %s does not match this FMU's %s", fmuGUID ? fmuGUID : "(null)",
                 EBB_GUID);
        return NULL;
    }
    if (fmuType != fmi2ModelExchange && fmuType != fmi2CoSimulation) {
        ebb_fail(&tmp, "fmi2Instantiate", "unknown FMU type %d", (int)fmuType);
        return NULL;
    }
    if (fmuType == fmi2ModelExchange && ebb_delay_refuse_exchange(&tmp, "fmi2Instantiate") != 0) return NULL;
    return ebb_new(tmp.name, fmuType == fmi2ModelExchange, loggingOn ? 1 : 0, tmp.log, tmp.host_logger, tmp.env);
}

EBB_EXPORT void fmi2FreeInstance(fmi2Component comp) { ebb_free(comp); }

EBB_EXPORT fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean tolDefined, fmi2Real tol,
                                          fmi2Real startTime, fmi2Boolean stopDefined, fmi2Real stopTime)
{
    (void)tolDefined; (void)tol; (void)stopDefined; (void)stopTime;
    if (!comp) return fmi2Error;
    INST(comp)->time = startTime;
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component comp) { return comp ? fmi2OK : fmi2Error; }

EBB_EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component comp)
{
    if (!comp) return fmi2Error;
    INST(comp)->stale = 1;
    return ST(ebb_ensure_model(comp, "fmi2ExitInitializationMode"));
}

EBB_EXPORT fmi2Status fmi2Terminate(fmi2Component comp) { return comp ? fmi2OK : fmi2Error; }

EBB_EXPORT fmi2Status fmi2Reset(fmi2Component comp)
{
    if (!comp) return fmi2Error;
    ebb_reset(comp);
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    if (!comp) return fmi2Error;
    return ST(ebb_get_real(comp, "fmi2GetReal", vr, nvr, value, nvr));
}

EBB_EXPORT fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    if (!comp) return fmi2Error;
    return ST(ebb_get_integer(comp, "fmi2GetInteger", vr, nvr, value, nvr));
}

EBB_EXPORT fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    (void)value;
    if (!comp) return fmi2Error;
    return ST(ebb_refuse(comp, "fmi2GetBoolean", "Boolean", vr, nvr));
}

EBB_EXPORT fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    if (!comp) return fmi2Error;
    return ST(ebb_get_string(comp, "fmi2GetString", vr, nvr, value, nvr));
}

EBB_EXPORT fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    if (!comp) return fmi2Error;
    return ST(ebb_set_real(comp, "fmi2SetReal", vr, nvr, value, nvr));
}

EBB_EXPORT fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                     const fmi2Integer value[])
{
    (void)value;
    if (!comp) return fmi2Error;
    return ST(ebb_refuse(comp, "fmi2SetInteger", NULL, vr, nvr));
}

EBB_EXPORT fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                     const fmi2Boolean value[])
{
    (void)value;
    if (!comp) return fmi2Error;
    return ST(ebb_refuse(comp, "fmi2SetBoolean", NULL, vr, nvr));
}

EBB_EXPORT fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                    const fmi2String value[])
{
    (void)value;
    if (!comp) return fmi2Error;
    return ST(ebb_refuse(comp, "fmi2SetString", NULL, vr, nvr));
}

/* ------------------------------------------------------------------ FMU state */
EBB_EXPORT fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *state)
{
    if (!comp) return fmi2Error;
    if (!state) return ST(ebb_fail(comp, "fmi2GetFMUstate", "no place for the state (NULL)"));
    void *s = ebb_state_get(comp, "fmi2GetFMUstate", *state);
    if (!s) return fmi2Error;
    *state = s;
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate state)
{
    if (!comp) return fmi2Error;
    return ST(ebb_state_set(comp, "fmi2SetFMUstate", state));
}

EBB_EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *state)
{
    if (!comp) return fmi2Error;
    if (state) { free(*state); *state = NULL; }
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate state, size_t *size)
{
    if (!comp) return fmi2Error;
    if (ebb_state_check(comp, "fmi2SerializedFMUstateSize", state) != 0) return fmi2Error;
    *size = ebb_state_size();
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate state, fmi2Byte bytes[], size_t size)
{
    if (!comp) return fmi2Error;
    return ST(ebb_state_serialize(comp, "fmi2SerializeFMUstate", state, (unsigned char *)bytes, size));
}

EBB_EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte bytes[], size_t size,
                                              fmi2FMUstate *state)
{
    if (!comp) return fmi2Error;
    void *s = ebb_state_deserialize(comp, "fmi2DeSerializeFMUstate", (const unsigned char *)bytes, size, *state);
    if (!s) return fmi2Error;
    *state = s;
    return fmi2OK;
}

/* ------------------------------------------------------------------ directional derivatives */
EBB_EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference unknown[],
                                                   size_t n_unknown, const fmi2ValueReference known[],
                                                   size_t n_known, const fmi2Real dv_known[], fmi2Real dv_unknown[])
{
    if (!comp) return fmi2Error;
    return ST(ebb_directional(comp, "fmi2GetDirectionalDerivative", unknown, n_unknown, known, n_known, dv_known,
                              n_known, dv_unknown, n_unknown));
}

/* ------------------------------------------------------------------ model exchange */
EBB_EXPORT fmi2Status fmi2EnterEventMode(fmi2Component comp) { return comp ? fmi2OK : fmi2Error; }

EBB_EXPORT fmi2Status fmi2NewDiscreteStates(fmi2Component comp, fmi2EventInfo *info)
{
    if (!comp) return fmi2Error;
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.0;
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2EnterContinuousTimeMode(fmi2Component comp) { return comp ? fmi2OK : fmi2Error; }

EBB_EXPORT fmi2Status fmi2CompletedIntegratorStep(fmi2Component comp, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                                  fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!comp) return fmi2Error;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2SetTime(fmi2Component comp, fmi2Real time)
{
    if (!comp) return fmi2Error;
    INST(comp)->time = time;
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2SetContinuousStates(fmi2Component comp, const fmi2Real x[], size_t nx)
{
    if (!comp) return fmi2Error;
    return ST(ebb_set_states(comp, "fmi2SetContinuousStates", x, nx));
}

EBB_EXPORT fmi2Status fmi2GetDerivatives(fmi2Component comp, fmi2Real dx[], size_t nx)
{
    if (!comp) return fmi2Error;
    return ST(ebb_get_derivatives(comp, "fmi2GetDerivatives", dx, nx));
}

EBB_EXPORT fmi2Status fmi2GetEventIndicators(fmi2Component comp, fmi2Real ind[], size_t ni)
{
    (void)ind;
    if (!comp) return fmi2Error;
    return ni == 0 ? fmi2OK : ST(ebb_fail(comp, "fmi2GetEventIndicators", "this FMU has no event indicators"));
}

EBB_EXPORT fmi2Status fmi2GetContinuousStates(fmi2Component comp, fmi2Real x[], size_t nx)
{
    if (!comp) return fmi2Error;
    return ST(ebb_get_states(comp, "fmi2GetContinuousStates", x, nx));
}

EBB_EXPORT fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component comp, fmi2Real x_nominal[], size_t nx)
{
    if (!comp) return fmi2Error;
    return ST(ebb_get_nominals(comp, "fmi2GetNominalsOfContinuousStates", x_nominal, nx));
}

/* ------------------------------------------------------------------ co-simulation */
EBB_EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                                  const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    return ST(ebb_fail(comp, "fmi2SetRealInputDerivatives", "not supported (canInterpolateInputs is false)"));
}

EBB_EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                                   const fmi2Integer order[], fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    return ST(ebb_fail(comp, "fmi2GetRealOutputDerivatives", "not supported (maxOutputDerivativeOrder is 0)"));
}

EBB_EXPORT fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint,
                                 fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!comp) return fmi2Error;
    return ST(ebb_do_step(comp, "fmi2DoStep", currentCommunicationPoint, communicationStepSize));
}

EBB_EXPORT fmi2Status fmi2CancelStep(fmi2Component comp)
{ return ST(ebb_fail(comp, "fmi2CancelStep", "steps are never asynchronous")); }

EBB_EXPORT fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value)
{ (void)s; (void)value; return ST(ebb_fail(comp, "fmi2GetStatus", "no asynchronous status")); }
EBB_EXPORT fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value)
{
    if (comp && s == fmi2LastSuccessfulTime) { *value = INST(comp)->time; return fmi2OK; }
    return ST(ebb_fail(comp, "fmi2GetRealStatus", "no such status"));
}
EBB_EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Integer *value)
{ (void)s; (void)value; return ST(ebb_fail(comp, "fmi2GetIntegerStatus", "no such status")); }
EBB_EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value)
{
    if (comp && s == fmi2Terminated) { *value = fmi2False; return fmi2OK; }
    return ST(ebb_fail(comp, "fmi2GetBooleanStatus", "no such status"));
}
EBB_EXPORT fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s, fmi2String *value)
{ (void)s; (void)value; return ST(ebb_fail(comp, "fmi2GetStringStatus", "no such status")); }
