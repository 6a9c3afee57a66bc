/*
 * ebb_fmi2.c -- FMI 2.0 interface of the standalone beam FMU: co-simulation and model exchange in one binary.
 *
 * The structure of the beam (grid, ends, positions, scheme, dt, start values, the variable table) comes from
 * the generated ebb_config.h; the model is built from the parameter values when initialisation ends
 * (ebb_model.c), and rebuilt before the next step or evaluation after a parameter changes (the state is kept).
 *
 * Co-simulation (as the pythonfmu FMU of the project): at t_k the master sets u_k; fmi2GetReal returns
 * y_k = Cy xi_k + Dy u_k; fmi2DoStep(t, h) needs h = n dt (n a positive integer, within 1e-6 dt) and applies n
 * samples with the input held.  At the start time the state is "at rest" for the current input (xi = -H u,
 * the input taken as constant before the record).
 * Model exchange: states x = (q, qdot) of the Richardson modes, qddot = -w2 q - Cm qdot + Fm u (scheme theta: the
 * nodal unknowns, qddot = M^-1 (F u - C qdot - K q)); outputs y = Cc x + Dc u with the host's continuous input.
 * Errors (invalid or unstable parameters, a step that is not a multiple of dt, non-finite inputs, setting a
 * variable that cannot be set) return fmi2Error with a logged message that names the variable; never fmi2Fatal.
 */
#include "ebb_beam.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ebb_config.h"

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

#if defined(_WIN32)
#define EBB_EXPORT __declspec(dllexport)
#elif defined(__GNUC__)
#define EBB_EXPORT __attribute__((visibility("default")))
#else
#define EBB_EXPORT
#endif

enum { ROLE_PARAMETER, ROLE_INPUT, ROLE_OUTPUT, ROLE_CONSTANT, ROLE_STATE, ROLE_DERIVATIVE };
enum { TYPE_REAL, TYPE_INTEGER, TYPE_STRING };

/* A step h is accepted when |h/dt - n| <= STEP_TOLERANCE for an integer n >= 1; a positive step of at most
 * STEP_TOLERANCE dt (a float-accumulating master's remainder) is accepted as no step; FMI 2.0 has no step of 0. */
#define STEP_TOLERANCE 1e-6

static const ebb_structure STRUCTURE = {
    EBB_LENGTH, EBB_NODES, {EBB_LEFT_KT, EBB_LEFT_KR}, {EBB_RIGHT_KT, EBB_RIGHT_KR}, EBB_DT, EBB_HOLD,
    EBB_SCHEME, EBB_THETA_VALUE, EBB_SUBSTEPS, EBB_NACT, EBB_ACT_X, EBB_NSENS, EBB_SENS_X, EBB_SENS_KIND,
    EBB_NMASS, EBB_MASS_X, EBB_MASS_M, EBB_NSPRING, EBB_SPRING_X, EBB_SPRING_K,
    EBB_NWEAK, EBB_WEAK_X, EBB_WEAK_LEN, EBB_WEAK_FACTOR, EBB_SENS_AA_ORDER, EBB_SENS_AA_CORNER,
};

typedef struct {
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    char *name;
    fmi2Type type;
    int debug;
    double p[EBB_NPARAM];
    double u[EBB_NACT];
    ebb_model mdl;
    int have_model, stale, at_start;
    double xi[EBB_NSTATES];               /* co-simulation: causal state xi = x - H u */
    double hist[2 * EBB_NACT + 1];        /* u[k-1], u[k-2] */
    double x[EBB_NSTATES];                /* model exchange: (q, qdot, anti-alias filter states) */
    double g[3 * EBB_NMODES];             /* modal forces of u[k], u[k-1], u[k-2] (per-mode form) */
    double xn[EBB_NSTATES];
    double time;
} Instance;

static void log_msg(Instance *c, fmi2Status status, const char *category, const char *fmt, ...)
{
    if (!c || !c->logger) return;
    if (status < fmi2Error && !c->debug) return;
    char buf[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof(buf), fmt, ap);
    va_end(ap);
    for (char *q = buf; *q; q++)                   /* the master treats the message as a format string */
        if (*q == '%') *q = ' ';
    c->logger(c->env, c->name ? c->name : "", status, category, buf);
}

static fmi2Status fail(Instance *c, const char *function, const char *fmt, ...)
{
    char buf[900];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof(buf), fmt, ap);
    va_end(ap);
    log_msg(c, fmi2Error, "logStatusError", "%s: %s", function, buf);
    return fmi2Error;
}

static const char *var_name(fmi2ValueReference vr)
{
    return vr < EBB_NVARS ? EBB_VAR_NAME[vr] : "(unknown)";
}

static int ensure_model(Instance *c, const char *function)
{
    if (c->have_model && !c->stale) return 0;
    ebb_model fresh;
    char msg[600];
    if (ebb_model_build(&STRUCTURE, c->p, &fresh, msg, sizeof(msg)) != 0) {
        fail(c, function, "no valid model for these parameters: %s", msg);
        return -1;
    }
    if (c->have_model) ebb_model_free(&c->mdl);
    c->mdl = fresh;
    c->have_model = 1;
    c->stale = 0;
    return 0;
}

/* modal forces g = Fm v (per-mode form) */
static void modal_force(const ebb_model *m, const double *v, double *g)
{
    for (int i = 0; i < m->k; i++) {
        double acc = 0.0;
        for (int j = 0; j < m->m; j++) acc += m->Fm[i * m->m + j] * v[j];
        g[i] = acc;
    }
}

/* the state at rest for the current input: xi = -H u, the input constant before the record */
static void rest_start(Instance *c)
{
    const ebb_model *m = &c->mdl;
    const int k = m->k, nx = m->nx;
    if (!m->dense) {
        modal_force(m, c->u, c->g);
        for (int i = 0; i < k; i++) {
            c->xi[i] = -m->H[i * 2] * c->g[i];
            c->xi[k + i] = -m->H[i * 2 + 1] * c->g[i];
        }
    } else {
        for (int r = 0; r < nx; r++) {
            double acc = 0.0;
            for (int j = 0; j < m->m; j++) acc += m->H[r * m->m + j] * c->u[j];
            c->xi[r] = -acc;
        }
    }
    for (int d = 0; d < m->delays; d++)
        for (int j = 0; j < m->m; j++) c->hist[d * m->m + j] = c->u[j];
}

/* one sample with the current input */
static void step(Instance *c)
{
    const ebb_model *m = &c->mdl;
    const int k = m->k, nx = m->nx, ni = m->m;
    if (!m->dense) {
        modal_force(m, c->u, c->g);
        for (int d = 0; d < m->delays; d++) modal_force(m, c->hist + d * ni, c->g + (d + 1) * k);
        for (int i = 0; i < k; i++) {
            const double *P = m->Phi + (size_t)i * 4;
            const double x0 = c->xi[i], x1 = c->xi[k + i];
            double a0 = P[0] * x0 + P[1] * x1, a1 = P[2] * x0 + P[3] * x1;
            for (int d = 0; d <= m->delays; d++) {
                const double *Q = m->Q + ((size_t)d * k + i) * 2;
                const double g = c->g[d * k + i];
                a0 += Q[0] * g;
                a1 += Q[1] * g;
            }
            c->xi[i] = a0;
            c->xi[k + i] = a1;
        }
    } else {
        for (int r = 0; r < nx; r++) {
            double acc = 0.0;
            const double *P = m->Phi + (size_t)r * nx;
            for (int col = 0; col < nx; col++) acc += P[col] * c->xi[col];
            for (int d = 0; d <= m->delays; d++) {
                const double *Q = m->Q + ((size_t)d * nx + r) * ni;
                const double *v = d == 0 ? c->u : c->hist + (d - 1) * ni;
                for (int j = 0; j < ni; j++) acc += Q[j] * v[j];
            }
            c->xn[r] = acc;
        }
        memcpy(c->xi, c->xn, sizeof(double) * (size_t)nx);
    }
    for (int d = m->delays - 1; d > 0; d--)
        for (int j = 0; j < ni; j++) c->hist[d * ni + j] = c->hist[(d - 1) * ni + j];
    if (m->delays > 0)
        for (int j = 0; j < ni; j++) c->hist[j] = c->u[j];
}

/* the modal state x = (q, qdot) now: xi + H u (co-simulation) or the integrator's state (model exchange) */
static void current_state(Instance *c, double *x)
{
    const ebb_model *m = &c->mdl;
    const int k = m->k, nx = m->nx;
    if (c->type == fmi2ModelExchange) { memcpy(x, c->x, sizeof(double) * (size_t)nx); return; }
    if (c->at_start) rest_start(c);
    if (!m->dense) {
        modal_force(m, c->u, c->g);
        for (int i = 0; i < k; i++) {
            x[i] = c->xi[i] + m->H[i * 2] * c->g[i];
            x[k + i] = c->xi[k + i] + m->H[i * 2 + 1] * c->g[i];
        }
    } else {
        for (int r = 0; r < nx; r++) {
            double acc = c->xi[r];
            for (int j = 0; j < m->m; j++) acc += m->H[r * m->m + j] * c->u[j];
            x[r] = acc;
        }
    }
}

static void derivatives_of(const ebb_model *m, const double *x, const double *u, double *dx);

static void derivatives(Instance *c, const double *x, double *dx)
{
    derivatives_of(&c->mdl, x, c->u, dx);
}

static double output(Instance *c, int o)
{
    const ebb_model *m = &c->mdl;
    const int nx = m->nx;
    const double *Crow, *Drow, *state;
    if (c->type == fmi2ModelExchange) {
        Crow = m->Cc + (size_t)o * nx; Drow = m->Dc + (size_t)o * m->m; state = c->x;
    } else {
        if (c->at_start) rest_start(c);
        Crow = m->Cy + (size_t)o * nx; Drow = m->Dy + (size_t)o * m->m; state = c->xi;
    }
    double acc = 0.0;
    for (int r = 0; r < nx; r++) acc += Crow[r] * state[r];
    for (int j = 0; j < m->m; j++) acc += Drow[j] * c->u[j];
    return acc;
}

static void reset_instance(Instance *c)
{
    memcpy(c->p, EBB_PARAM_START, sizeof(c->p));
    memset(c->u, 0, sizeof(c->u));
    memset(c->xi, 0, sizeof(c->xi));
    memset(c->hist, 0, sizeof(c->hist));
    memset(c->x, 0, sizeof(c->x));
    if (c->have_model) ebb_model_free(&c->mdl);
    c->have_model = 0;
    c->stale = 1;
    c->at_start = 1;
    c->time = 0.0;
}

/* ------------------------------------------------------------------ common functions */
EBB_EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EBB_EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EBB_EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t n, const fmi2String cats[])
{
    (void)n; (void)cats;
    if (!comp) return fmi2Error;
    ((Instance *)comp)->debug = loggingOn ? 1 : 0;
    return fmi2OK;
}

EBB_EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                         fmi2String resourceLocation, const fmi2CallbackFunctions *functions,
                                         fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)resourceLocation; (void)visible;
    Instance tmp;
    memset(&tmp, 0, sizeof(tmp));
    tmp.logger = functions ? functions->logger : NULL;
    tmp.env = functions ? functions->componentEnvironment : NULL;
    tmp.name = (char *)(instanceName ? instanceName : "");
    if (!fmuGUID || strcmp(fmuGUID, EBB_GUID) != 0) {
        fail(&tmp, "fmi2Instantiate", "GUID %s does not match this FMU's %s", fmuGUID ? fmuGUID : "(null)", EBB_GUID);
        return NULL;
    }
    if (fmuType != fmi2ModelExchange && fmuType != fmi2CoSimulation) {
        fail(&tmp, "fmi2Instantiate", "unknown FMU type %d", (int)fmuType);
        return NULL;
    }
    Instance *c = calloc(1, sizeof(Instance));
    if (!c) return NULL;
    c->logger = tmp.logger;
    c->env = tmp.env;
    c->name = malloc(strlen(tmp.name) + 1);
    if (!c->name) { free(c); return NULL; }
    strcpy(c->name, tmp.name);
    c->type = fmuType;
    c->debug = loggingOn ? 1 : 0;
    reset_instance(c);
    return c;
}

EBB_EXPORT void fmi2FreeInstance(fmi2Component comp)
{
    Instance *c = comp;
    if (!c) return;
    if (c->have_model) ebb_model_free(&c->mdl);
    free(c->name);
    free(c);
}

EBB_EXPORT fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean tolDefined, fmi2Real tol,
                                          fmi2Real startTime, fmi2Boolean stopDefined, fmi2Real stopTime)
{
    (void)tolDefined; (void)tol; (void)stopDefined; (void)stopTime;
    if (!comp) return fmi2Error;
    ((Instance *)comp)->time = startTime;
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component comp) { return comp ? fmi2OK : fmi2Error; }

EBB_EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component comp)
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    c->stale = 1;
    return ensure_model(c, "fmi2ExitInitializationMode") == 0 ? fmi2OK : fmi2Error;
}

EBB_EXPORT fmi2Status fmi2Terminate(fmi2Component comp) { return comp ? fmi2OK : fmi2Error; }

EBB_EXPORT fmi2Status fmi2Reset(fmi2Component comp)
{
    if (!comp) return fmi2Error;
    reset_instance(comp);
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    double x[EBB_NSTATES], dx[EBB_NSTATES];
    int have_x = 0;
    for (size_t i = 0; i < nvr; i++) {
        const fmi2ValueReference r = vr[i];
        if (r >= EBB_NVARS || EBB_VAR_TYPE[r] != TYPE_REAL) {
            value[i] = NAN;
            return fail(c, "fmi2GetReal", "variable %s (value reference %u) is not a Real variable", var_name(r), r);
        }
        const int idx = EBB_VAR_INDEX[r];
        switch (EBB_VAR_ROLE[r]) {
        case ROLE_PARAMETER: value[i] = c->p[idx]; break;
        case ROLE_INPUT: value[i] = c->u[idx]; break;
        case ROLE_CONSTANT: value[i] = EBB_VAR_REAL[r]; break;
        case ROLE_OUTPUT:
            if (ensure_model(c, "fmi2GetReal") != 0) { value[i] = NAN; return fmi2Error; }
            value[i] = output(c, idx);
            if (!isfinite(value[i]))
                return fail(c, "fmi2GetReal", "output %s is not finite (numerical overflow)", var_name(r));
            break;
        default:                                       /* states and derivatives */
            if (ensure_model(c, "fmi2GetReal") != 0) { value[i] = NAN; return fmi2Error; }
            if (!have_x) { current_state(c, x); derivatives(c, x, dx); have_x = 1; }
            value[i] = EBB_VAR_ROLE[r] == ROLE_STATE ? x[idx] : dx[idx];
        }
    }
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= EBB_NVARS || EBB_VAR_TYPE[vr[i]] != TYPE_INTEGER)
            return fail(c, "fmi2GetInteger", "variable %s (value reference %u) is not an Integer variable",
                        var_name(vr[i]), vr[i]);
        value[i] = EBB_VAR_INT[vr[i]];
    }
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    (void)vr; (void)value;
    if (nvr == 0) return fmi2OK;
    return fail(comp, "fmi2GetBoolean", "this FMU has no Boolean variables");
}

EBB_EXPORT fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= EBB_NVARS || EBB_VAR_TYPE[vr[i]] != TYPE_STRING)
            return fail(c, "fmi2GetString", "variable %s (value reference %u) is not a String variable",
                        var_name(vr[i]), vr[i]);
        value[i] = EBB_VAR_STRING[vr[i]];
    }
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    fmi2Status status = fmi2OK;
    for (size_t i = 0; i < nvr; i++) {
        const fmi2ValueReference r = vr[i];
        const int role = r < EBB_NVARS && EBB_VAR_TYPE[r] == TYPE_REAL ? EBB_VAR_ROLE[r] : -1;
        if (role == ROLE_INPUT) {
            if (!isfinite(value[i])) {
                status = fail(c, "fmi2SetReal", "input %s = %g is not a finite number", var_name(r), value[i]);
                continue;
            }
            c->u[EBB_VAR_INDEX[r]] = value[i];
        } else if (role == ROLE_PARAMETER) {
            c->p[EBB_VAR_INDEX[r]] = value[i];          /* checked when the model is (re)built */
            c->stale = 1;
        } else if (role == ROLE_STATE && (c->type == fmi2ModelExchange || (c->at_start && value[i] == 0.0))) {
            /* model exchange: the state (start value 0, initial exact); co-simulation starts at rest only */
            if (!isfinite(value[i])) {
                status = fail(c, "fmi2SetReal", "state %s = %g is not a finite number", var_name(r), value[i]);
                continue;
            }
            if (c->type == fmi2ModelExchange) c->x[EBB_VAR_INDEX[r]] = value[i];
        } else {
            status = fail(c, "fmi2SetReal", "variable %s (value reference %u) cannot be set", var_name(r), r);
        }
    }
    return status;
}

static fmi2Status refuse_set(fmi2Component comp, const char *function, const fmi2ValueReference vr[], size_t nvr)
{
    if (nvr == 0) return fmi2OK;
    return fail(comp, function, "variable %s (value reference %u) cannot be set", var_name(vr[0]), vr[0]);
}

EBB_EXPORT fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                     const fmi2Integer value[])
{
    (void)value;
    return refuse_set(comp, "fmi2SetInteger", vr, nvr);
}

EBB_EXPORT fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                     const fmi2Boolean value[])
{
    (void)value;
    return refuse_set(comp, "fmi2SetBoolean", vr, nvr);
}

EBB_EXPORT fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                    const fmi2String value[])
{
    (void)value;
    return refuse_set(comp, "fmi2SetString", vr, nvr);
}

/* ------------------------------------------------------------------ FMU state */
/* A saved state: everything a continuation depends on (the model follows from p, rebuilt when p differs).
 * Serialised as the GUID and the raw snapshot: restorable by this FMU on this platform. */
#define EBB_STATE_MAGIC 0x45424253u                /* "EBBS" */
typedef struct {
    unsigned magic;
    int type, at_start;
    double p[EBB_NPARAM];
    double u[EBB_NACT];
    double xi[EBB_NSTATES];
    double hist[2 * EBB_NACT + 1];
    double x[EBB_NSTATES];
    double time;
} Snapshot;

static void snapshot_take(const Instance *c, Snapshot *s)
{
    memset(s, 0, sizeof(*s));
    s->magic = EBB_STATE_MAGIC;
    s->type = (int)c->type;
    s->at_start = c->at_start;
    memcpy(s->p, c->p, sizeof(s->p));
    memcpy(s->u, c->u, sizeof(s->u));
    memcpy(s->xi, c->xi, sizeof(s->xi));
    memcpy(s->hist, c->hist, sizeof(s->hist));
    memcpy(s->x, c->x, sizeof(s->x));
    s->time = c->time;
}

EBB_EXPORT fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *state)
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    if (!state) return fail(c, "fmi2GetFMUstate", "no place for the state (NULL)");
    Snapshot *s = *state ? (Snapshot *)*state : malloc(sizeof(Snapshot));
    if (!s) return fail(c, "fmi2GetFMUstate", "out of memory");
    snapshot_take(c, s);
    *state = s;
    return fmi2OK;
}

static int snapshot_valid(Instance *c, const char *function, const Snapshot *s)
{
    if (!s || s->magic != EBB_STATE_MAGIC) { fail(c, function, "not a state of this FMU"); return 0; }
    if (s->type != (int)c->type) {
        fail(c, function, "the state is of a %s instance, this one is %s",
             s->type == fmi2ModelExchange ? "model-exchange" : "co-simulation",
             c->type == fmi2ModelExchange ? "model-exchange" : "co-simulation");
        return 0;
    }
    return 1;
}

EBB_EXPORT fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate state)
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    const Snapshot *s = state;
    if (!snapshot_valid(c, "fmi2SetFMUstate", s)) return fmi2Error;
    if (memcmp(c->p, s->p, sizeof(c->p)) != 0) c->stale = 1;   /* another parameter set: rebuilt when used */
    memcpy(c->p, s->p, sizeof(c->p));
    memcpy(c->u, s->u, sizeof(c->u));
    memcpy(c->xi, s->xi, sizeof(c->xi));
    memcpy(c->hist, s->hist, sizeof(c->hist));
    memcpy(c->x, s->x, sizeof(c->x));
    c->at_start = s->at_start;
    c->time = s->time;
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *state)
{
    if (!comp) return fmi2Error;
    if (state) { free(*state); *state = NULL; }
    return fmi2OK;
}

static size_t serialized_size(void) { return sizeof(EBB_GUID) + sizeof(Snapshot); }

EBB_EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate state, size_t *size)
{
    if (!comp) return fmi2Error;
    if (!snapshot_valid(comp, "fmi2SerializedFMUstateSize", state)) return fmi2Error;
    *size = serialized_size();
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate state, fmi2Byte bytes[], size_t size)
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    if (!snapshot_valid(c, "fmi2SerializeFMUstate", state)) return fmi2Error;
    if (size < serialized_size())
        return fail(c, "fmi2SerializeFMUstate", "%zu bytes given, the state takes %zu", size, serialized_size());
    memcpy(bytes, EBB_GUID, sizeof(EBB_GUID));
    memcpy(bytes + sizeof(EBB_GUID), state, sizeof(Snapshot));
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte bytes[], size_t size,
                                              fmi2FMUstate *state)
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    if (!bytes || size != serialized_size() || memcmp(bytes, EBB_GUID, sizeof(EBB_GUID)) != 0)
        return fail(c, "fmi2DeSerializeFMUstate", "the %zu bytes are not a serialised state of this FMU (GUID %s)",
                    size, EBB_GUID);
    Snapshot tmp;
    memcpy(&tmp, bytes + sizeof(EBB_GUID), sizeof(Snapshot));
    if (!snapshot_valid(c, "fmi2DeSerializeFMUstate", &tmp)) return fmi2Error;
    Snapshot *s = *state ? (Snapshot *)*state : malloc(sizeof(Snapshot));
    if (!s) return fail(c, "fmi2DeSerializeFMUstate", "out of memory");
    *s = tmp;
    *state = s;
    return fmi2OK;
}

/* ------------------------------------------------------------------ directional derivatives */
/* Outputs and state derivatives are linear in (state, input) with the current parameters: the derivative in
 * a direction is the linear map applied to the direction itself — the discrete realisation's rows Cy, Dy
 * (co-simulation: the outputs from the input at the current communication point; the state xi is not a
 * variable), the continuous ones Cc, Dc and the modal ODE (model exchange). */
static void derivatives_of(const ebb_model *m, const double *x, const double *u, double *dx)
{
    const int k = m->k;
    for (int i = 0; i < k; i++) {
        double acc = 0.0;
        if (m->Kd) for (int j = 0; j < k; j++) acc -= m->Kd[i * k + j] * x[j];
        else acc -= m->w2[i] * x[i];
        if (m->dense) for (int j = 0; j < k; j++) acc -= m->Cm[i * k + j] * x[k + j];
        else acc -= m->Cm[i * k + i] * x[k + i];
        for (int j = 0; j < m->m; j++) acc += m->Fm[i * m->m + j] * u[j];
        dx[i] = x[k + i];
        dx[k + i] = acc;
    }
    for (int f = 0; f < m->nf; f++) {             /* the anti-alias filters, driven by their sensors */
        double acc = 0.0;
        const double *Frow = m->Fx + (size_t)f * m->nx;
        for (int col = 0; col < m->nx; col++) acc += Frow[col] * x[col];
        for (int j = 0; j < m->m; j++) acc += m->Fu[(size_t)f * m->m + j] * u[j];
        dx[2 * k + f] = acc;
    }
}

EBB_EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference unknown[],
                                                   size_t n_unknown, const fmi2ValueReference known[],
                                                   size_t n_known, const fmi2Real dv_known[], fmi2Real dv_unknown[])
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    if (ensure_model(c, "fmi2GetDirectionalDerivative") != 0) return fmi2Error;
    const ebb_model *m = &c->mdl;
    const int nx = m->nx;
    double du[EBB_NACT], dxs[EBB_NSTATES], ddx[EBB_NSTATES];
    memset(du, 0, sizeof(du));
    memset(dxs, 0, sizeof(dxs));
    for (size_t i = 0; i < n_known; i++) {
        const fmi2ValueReference r = known[i];
        const int role = r < EBB_NVARS && EBB_VAR_TYPE[r] == TYPE_REAL ? EBB_VAR_ROLE[r] : -1;
        if (role == ROLE_INPUT) du[EBB_VAR_INDEX[r]] += dv_known[i];
        else if (role == ROLE_STATE && c->type == fmi2ModelExchange) dxs[EBB_VAR_INDEX[r]] += dv_known[i];
        else
            return fail(c, "fmi2GetDirectionalDerivative", "%s (value reference %u) is not a known of this FMU "
                        "(an input%s)", var_name(r), r, c->type == fmi2ModelExchange ? " or a state" : "");
    }
    int have_dx = 0;
    for (size_t i = 0; i < n_unknown; i++) {
        const fmi2ValueReference r = unknown[i];
        const int role = r < EBB_NVARS && EBB_VAR_TYPE[r] == TYPE_REAL ? EBB_VAR_ROLE[r] : -1;
        if (role == ROLE_OUTPUT) {
            const int o = EBB_VAR_INDEX[r];
            const int me = c->type == fmi2ModelExchange;
            const double *Crow = (me ? m->Cc : m->Cy) + (size_t)o * nx, *Drow = (me ? m->Dc : m->Dy) + (size_t)o * m->m;
            double acc = 0.0;
            if (me) for (int q = 0; q < nx; q++) acc += Crow[q] * dxs[q];
            for (int j = 0; j < m->m; j++) acc += Drow[j] * du[j];
            dv_unknown[i] = acc;
        } else if (role == ROLE_DERIVATIVE && c->type == fmi2ModelExchange) {
            if (!have_dx) { derivatives_of(m, dxs, du, ddx); have_dx = 1; }
            dv_unknown[i] = ddx[EBB_VAR_INDEX[r]];
        } else {
            return fail(c, "fmi2GetDirectionalDerivative", "%s (value reference %u) is not an unknown of this FMU "
                        "(an output%s)", var_name(r), r, c->type == fmi2ModelExchange ? " or a derivative" : "");
        }
    }
    return fmi2OK;
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
    ((Instance *)comp)->time = time;
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2SetContinuousStates(fmi2Component comp, const fmi2Real x[], size_t nx)
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    if (nx != EBB_NSTATES)
        return fail(c, "fmi2SetContinuousStates", "expected %d states, got %u", EBB_NSTATES, (unsigned)nx);
    for (size_t i = 0; i < nx; i++)
        if (!isfinite(x[i])) return fail(c, "fmi2SetContinuousStates", "state %u is not finite", (unsigned)i);
    memcpy(c->x, x, sizeof(double) * nx);
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2GetDerivatives(fmi2Component comp, fmi2Real dx[], size_t nx)
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    if (nx != EBB_NSTATES)
        return fail(c, "fmi2GetDerivatives", "expected %d derivatives, got %u", EBB_NSTATES, (unsigned)nx);
    if (ensure_model(c, "fmi2GetDerivatives") != 0) return fmi2Error;
    derivatives(c, c->x, dx);
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2GetEventIndicators(fmi2Component comp, fmi2Real ind[], size_t ni)
{
    (void)ind;
    if (!comp) return fmi2Error;
    return ni == 0 ? fmi2OK : fail(comp, "fmi2GetEventIndicators", "this FMU has no event indicators");
}

EBB_EXPORT fmi2Status fmi2GetContinuousStates(fmi2Component comp, fmi2Real x[], size_t nx)
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    if (nx != EBB_NSTATES)
        return fail(c, "fmi2GetContinuousStates", "expected %d states, got %u", EBB_NSTATES, (unsigned)nx);
    memcpy(x, c->x, sizeof(double) * nx);
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component comp, fmi2Real x_nominal[], size_t nx)
{
    Instance *c = comp;
    if (!c) return fmi2Error;
    if (nx != EBB_NSTATES)
        return fail(c, "fmi2GetNominalsOfContinuousStates", "expected %d states, got %u", EBB_NSTATES,
                    (unsigned)nx);
    if (c->have_model && !c->stale) memcpy(x_nominal, c->mdl.nominal, sizeof(double) * nx);
    else for (size_t i = 0; i < nx; i++) x_nominal[i] = 1.0;
    return fmi2OK;
}

/* ------------------------------------------------------------------ co-simulation */
EBB_EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                                  const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    return fail(comp, "fmi2SetRealInputDerivatives", "not supported (canInterpolateInputs is false)");
}

EBB_EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                                   const fmi2Integer order[], fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    return fail(comp, "fmi2GetRealOutputDerivatives", "not supported (maxOutputDerivativeOrder is 0)");
}

EBB_EXPORT fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint,
                                 fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    Instance *c = comp;
    if (!c) return fmi2Error;
    if (c->type != fmi2CoSimulation)
        return fail(c, "fmi2DoStep", "the instance was created for model exchange");
    const double ratio = communicationStepSize / EBB_DT;
    if (isfinite(ratio) && ratio > 0.0 && ratio <= STEP_TOLERANCE) {
        /* a master's rounding remainder (time accumulated in floating point: 2000 steps of 1e-4 s fall 5.7e-15 s
         * short of 0.2 s, and the master steps the rest): no sample to take */
        c->time = currentCommunicationPoint + communicationStepSize;
        return fmi2OK;
    }
    const double n = isfinite(ratio) ? floor(ratio + 0.5) : 0.0;
    if (!(n >= 1.0) || fabs(ratio - n) > STEP_TOLERANCE || n > 2e9)
        return fail(c, "fmi2DoStep", "communication step size %.17g s is not a positive integer multiple of the "
                    "sample time dt = %.17g s", communicationStepSize, (double)EBB_DT);
    if (ensure_model(c, "fmi2DoStep") != 0) return fmi2Error;
    if (c->at_start) { rest_start(c); c->at_start = 0; }
    for (long s = 0; s < (long)n; s++) step(c);
    c->time = currentCommunicationPoint + communicationStepSize;
    return fmi2OK;
}

EBB_EXPORT fmi2Status fmi2CancelStep(fmi2Component comp)
{ return fail(comp, "fmi2CancelStep", "steps are never asynchronous"); }

EBB_EXPORT fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value)
{ (void)s; (void)value; return fail(comp, "fmi2GetStatus", "no asynchronous status"); }
EBB_EXPORT fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value)
{
    Instance *c = comp;
    if (c && s == fmi2LastSuccessfulTime) { *value = c->time; return fmi2OK; }
    return fail(comp, "fmi2GetRealStatus", "no such status");
}
EBB_EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Integer *value)
{ (void)s; (void)value; return fail(comp, "fmi2GetIntegerStatus", "no such status"); }
EBB_EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value)
{
    if (comp && s == fmi2Terminated) { *value = fmi2False; return fmi2OK; }
    return fail(comp, "fmi2GetBooleanStatus", "no such status");
}
EBB_EXPORT fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s, fmi2String *value)
{ (void)s; (void)value; return fail(comp, "fmi2GetStringStatus", "no such status"); }
