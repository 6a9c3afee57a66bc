/*
 * ebb_instance.c -- what one instance of the standalone beam FMU does, for either FMI version (ebb_instance.h).
 *
 * Co-simulation: at t_k the master sets u_k; the outputs are y_k = Cy xi_k + Dy u_k; a step of h = n dt applies
 * n samples with the input held.  At the start time the state is "at rest" for the current input (xi = -H u,
 * the input taken as constant before the record).  A delayed sensor's output is its delay line's sum of past
 * undelayed outputs (ebb_delay.c): filled at the rest start, pushed before each sample's step.
 * Model exchange: states x = (q, qdot) of the Richardson modes, qddot = -w2 q - Cm qdot + Fm u (scheme theta: the
 * nodal unknowns, qddot = M^-1 (F u - C qdot - K q)), then the anti-alias filters' states; outputs
 * y = Cc x + Dc u with the host's continuous input.
 */
#include "ebb_instance.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A step h is accepted when |h/dt - n| <= STEP_TOLERANCE for an integer n >= 1; a positive step of at most
 * STEP_TOLERANCE dt (a float-accumulating master's remainder) is accepted as no step. */
#define STEP_TOLERANCE 1e-6

static const ebb_structure STRUCTURE = {
    EBB_LENGTH, EBB_NODES, {EBB_LEFT_KT, EBB_LEFT_KR}, {EBB_RIGHT_KT, EBB_RIGHT_KR}, EBB_DT, EBB_HOLD,
    EBB_SCHEME, EBB_THETA_VALUE, EBB_SUBSTEPS, EBB_NACT, EBB_ACT_X, EBB_NSENS, EBB_SENS_X, EBB_SENS_KIND,
    EBB_NMASS, EBB_MASS_X, EBB_MASS_M, EBB_NSPRING, EBB_SPRING_X, EBB_SPRING_K,
    EBB_NWEAK, EBB_WEAK_X, EBB_WEAK_LEN, EBB_WEAK_FACTOR, EBB_SENS_AA_ORDER, EBB_SENS_AA_CORNER,
};

/* ------------------------------------------------------------------ messages */
int ebb_fail(const ebb_instance *c, const char *function, const char *fmt, ...)
{
    char buf[900];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof(buf), fmt, ap);
    va_end(ap);
    if (c && c->log) {
        char line[1000];
        snprintf(line, sizeof(line), "%s: %s", function, buf);
        for (char *q = line; *q; q++)
            if (*q == '%') *q = ' ';
        c->log(c, 1, "logStatusError", line);
    }
    return -1;
}

const char *ebb_var_name(unsigned vr)
{
    return vr < EBB_NVARS ? EBB_VAR_NAME[vr] : "(unknown)";
}

/* ------------------------------------------------------------------ life */
ebb_instance *ebb_new(const char *name, int exchange, int debug, ebb_log_fn log, ebb_any_fn host_logger,
                      void *env)
{
    ebb_instance *c = calloc(1, sizeof(ebb_instance));
    if (!c) return NULL;
    c->log = log;
    c->host_logger = host_logger;
    c->env = env;
    c->name = malloc(strlen(name ? name : "") + 1);
    if (!c->name) { free(c); return NULL; }
    strcpy(c->name, name ? name : "");
    if (ebb_delay_new(c) != 0) { free(c->name); free(c); return NULL; }
    c->exchange = exchange;
    c->debug = debug;
    ebb_reset(c);
    return c;
}

void ebb_free(ebb_instance *c)
{
    if (!c) return;
    if (c->have_model) ebb_model_free(&c->mdl);
    ebb_delay_free(c);
    free(c->name);
    free(c);
}

void ebb_reset(ebb_instance *c)
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

int ebb_ensure_model(ebb_instance *c, const char *function)
{
    if (c->have_model && !c->stale) return 0;
    ebb_model fresh;
    char msg[600];
    if (ebb_model_build(&STRUCTURE, c->p, &fresh, msg, sizeof(msg)) != 0)
        return ebb_fail(c, function, "no valid model for these parameters: %s", msg);
    if (c->have_model) ebb_model_free(&c->mdl);
    c->mdl = fresh;
    c->have_model = 1;
    c->stale = 0;
    return 0;
}

/* ------------------------------------------------------------------ the model's maps */
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
static void rest_start(ebb_instance *c)
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
    ebb_delay_fill(c);
}

/* one sample with the current input */
static void step(ebb_instance *c)
{
    const ebb_model *m = &c->mdl;
    const int k = m->k, nx = m->nx, ni = m->m;
    ebb_delay_push(c);                            /* this sample's undelayed outputs, before the state advances */
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
static void current_state(ebb_instance *c, double *x)
{
    const ebb_model *m = &c->mdl;
    const int k = m->k, nx = m->nx;
    if (c->exchange) { memcpy(x, c->x, sizeof(double) * (size_t)nx); return; }
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

/* dx = f(x, u): the modal (or nodal) ODE, then the anti-alias filters driven by their sensors */
void ebb_rates(const ebb_model *m, const double *x, const double *u, double *dx)
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
    for (int f = 0; f < m->nf; f++) {
        double acc = 0.0;
        const double *Frow = m->Fx + (size_t)f * m->nx;
        for (int col = 0; col < m->nx; col++) acc += Frow[col] * x[col];
        for (int j = 0; j < m->m; j++) acc += m->Fu[(size_t)f * m->m + j] * u[j];
        dx[2 * k + f] = acc;
    }
}

/* y = C x + D u of one output row, on the model-exchange or the co-simulation realisation */
static double linear_output(const ebb_instance *c, int o)
{
    const ebb_model *m = &c->mdl;
    const int nx = m->nx;
    const double *Crow, *Drow, *state;
    if (c->exchange) {
        Crow = m->Cc + (size_t)o * nx; Drow = m->Dc + (size_t)o * m->m; state = c->x;
    } else {
        Crow = m->Cy + (size_t)o * nx; Drow = m->Dy + (size_t)o * m->m; state = c->xi;
    }
    double acc = 0.0;
    for (int r = 0; r < nx; r++) acc += Crow[r] * state[r];
    for (int j = 0; j < m->m; j++) acc += Drow[j] * c->u[j];
    return acc;
}

double ebb_undelayed(const ebb_instance *c, int o) { return linear_output(c, o); }

static double output(ebb_instance *c, int o)
{
    if (c->exchange) return linear_output(c, o);
    if (c->at_start) rest_start(c);
    return ebb_delay_output(c, o, linear_output(c, o));
}

/* ------------------------------------------------------------------ variables */
static int role_of(unsigned vr, int type)
{
    return vr < EBB_NVARS && EBB_VAR_TYPE[vr] == type ? EBB_VAR_ROLE[vr] : -1;
}

/* the elements of nvr variables of the given type, or -1 (logged) when one is not of that type */
static long elements(const ebb_instance *c, const char *function, const unsigned vr[], size_t nvr, int type,
                     const char *type_name)
{
    long n = 0;
    for (size_t i = 0; i < nvr; i++) {
        if (role_of(vr[i], type) < 0)
            return ebb_fail(c, function, "variable %s (value reference %u) is not a %s variable",
                            ebb_var_name(vr[i]), vr[i], type_name);
        n += EBB_VAR_SIZE[vr[i]];
    }
    return n;
}

static int count_matches(const ebb_instance *c, const char *function, long n, size_t nvalues)
{
    if (n < 0) return -1;
    if ((size_t)n != nvalues)
        return ebb_fail(c, function, "%zu values given for variables of %ld element(s)", nvalues, n);
    return 0;
}

int ebb_get_real(ebb_instance *c, const char *function, const unsigned vr[], size_t nvr, double value[],
                 size_t nvalues)
{
    if (count_matches(c, function, elements(c, function, vr, nvr, TYPE_REAL, "Real"), nvalues) != 0) return -1;
    double x[EBB_NSTATES], dx[EBB_NSTATES];
    int have_x = 0;
    size_t at = 0;
    for (size_t i = 0; i < nvr; i++) {
        const unsigned r = vr[i];
        const int idx = EBB_VAR_INDEX[r], size = EBB_VAR_SIZE[r], role = EBB_VAR_ROLE[r];
        if (role == ROLE_OUTPUT || role == ROLE_STATE || role == ROLE_DERIVATIVE)
            if (ebb_ensure_model(c, function) != 0) { value[at] = NAN; return -1; }
        if ((role == ROLE_STATE || role == ROLE_DERIVATIVE) && !have_x) {
            current_state(c, x);
            ebb_rates(&c->mdl, x, c->u, dx);
            have_x = 1;
        }
        for (int e = 0; e < size; e++, at++) {
            switch (role) {
            case ROLE_PARAMETER: value[at] = c->p[idx + e]; break;
            case ROLE_INPUT: value[at] = c->u[idx + e]; break;
            case ROLE_CONSTANT: value[at] = EBB_VAR_REAL[r]; break;
            case ROLE_TIME: value[at] = c->time; break;
            case ROLE_OUTPUT:
                value[at] = output(c, idx + e);
                if (!isfinite(value[at]))
                    return ebb_fail(c, function, "output %s is not finite (numerical overflow)", ebb_var_name(r));
                break;
            case ROLE_STATE: value[at] = x[idx + e]; break;
            default: value[at] = dx[idx + e];
            }
        }
    }
    return 0;
}

int ebb_set_real(ebb_instance *c, const char *function, const unsigned vr[], size_t nvr, const double value[],
                 size_t nvalues)
{
    long n = 0;
    for (size_t i = 0; i < nvr; i++) n += vr[i] < EBB_NVARS ? EBB_VAR_SIZE[vr[i]] : 1;
    if (count_matches(c, function, n, nvalues) != 0) return -1;
    int status = 0;
    size_t at = 0;
    for (size_t i = 0; i < nvr; i++) {
        const unsigned r = vr[i];
        const int role = role_of(r, TYPE_REAL), size = r < EBB_NVARS ? EBB_VAR_SIZE[r] : 1;
        for (int e = 0; e < size; e++, at++) {
            const double v = value[at];
            const int idx = role >= 0 ? EBB_VAR_INDEX[r] + e : 0;
            if (role == ROLE_INPUT) {
                if (!isfinite(v)) {
                    status = ebb_fail(c, function, "input %s = %g is not a finite number", ebb_var_name(r), v);
                    continue;
                }
                c->u[idx] = v;
            } else if (role == ROLE_PARAMETER) {
                c->p[idx] = v;                            /* checked when the model is (re)built */
                c->stale = 1;
            } else if (role == ROLE_STATE && (c->exchange || (c->at_start && v == 0.0))) {
                /* model exchange: the state (start value 0, initial exact); co-simulation starts at rest only */
                if (!isfinite(v)) {
                    status = ebb_fail(c, function, "state %s = %g is not a finite number", ebb_var_name(r), v);
                    continue;
                }
                if (c->exchange) c->x[idx] = v;
            } else {
                status = ebb_fail(c, function, "variable %s (value reference %u) cannot be set", ebb_var_name(r), r);
            }
        }
    }
    return status;
}

int ebb_get_integer(ebb_instance *c, const char *function, const unsigned vr[], size_t nvr, int value[],
                    size_t nvalues)
{
    if (count_matches(c, function, elements(c, function, vr, nvr, TYPE_INTEGER, "Integer"), nvalues) != 0)
        return -1;
    for (size_t i = 0; i < nvr; i++) value[i] = EBB_VAR_INT[vr[i]];
    return 0;
}

int ebb_get_string(ebb_instance *c, const char *function, const unsigned vr[], size_t nvr, const char *value[],
                   size_t nvalues)
{
    if (count_matches(c, function, elements(c, function, vr, nvr, TYPE_STRING, "String"), nvalues) != 0)
        return -1;
    for (size_t i = 0; i < nvr; i++) value[i] = EBB_VAR_STRING[vr[i]];
    return 0;
}

int ebb_refuse(ebb_instance *c, const char *function, const char *what, const unsigned vr[], size_t nvr)
{
    if (nvr == 0) return 0;
    if (what) return ebb_fail(c, function, "this FMU has no %s variables", what);
    return ebb_fail(c, function, "variable %s (value reference %u) cannot be set", ebb_var_name(vr[0]), vr[0]);
}

/* ------------------------------------------------------------------ co-simulation */
int ebb_do_step(ebb_instance *c, const char *function, double t, double h)
{
    if (c->exchange) return ebb_fail(c, function, "the instance was created for model exchange");
    const double ratio = h / EBB_DT;
    if (isfinite(ratio) && ratio > 0.0 && ratio <= STEP_TOLERANCE) {
        /* a master's rounding remainder (time accumulated in floating point: 2000 steps of 1e-4 s fall 5.7e-15 s
         * short of 0.2 s, and the master steps the rest): no sample to take */
        c->time = t + h;
        return 0;
    }
    const double n = isfinite(ratio) ? floor(ratio + 0.5) : 0.0;
    if (!(n >= 1.0) || fabs(ratio - n) > STEP_TOLERANCE || n > 2e9)
        return ebb_fail(c, function, "communication step size %.17g s is not a positive integer multiple of the "
                        "sample time dt = %.17g s", h, (double)EBB_DT);
    if (ebb_ensure_model(c, function) != 0) return -1;
    if (c->at_start) { rest_start(c); c->at_start = 0; }
    for (long s = 0; s < (long)n; s++) step(c);
    c->time = t + h;
    return 0;
}

/* ------------------------------------------------------------------ model exchange */
static int states_count(const ebb_instance *c, const char *function, const char *what, size_t nx)
{
    if (nx != EBB_NSTATES)
        return ebb_fail(c, function, "expected %d %s, got %zu", EBB_NSTATES, what, nx);
    return 0;
}

int ebb_set_states(ebb_instance *c, const char *function, const double x[], size_t nx)
{
    if (states_count(c, function, "states", nx) != 0) return -1;
    for (size_t i = 0; i < nx; i++)
        if (!isfinite(x[i])) return ebb_fail(c, function, "state %zu is not finite", i);
    memcpy(c->x, x, sizeof(double) * nx);
    return 0;
}

int ebb_get_states(ebb_instance *c, const char *function, double x[], size_t nx)
{
    if (states_count(c, function, "states", nx) != 0) return -1;
    memcpy(x, c->x, sizeof(double) * nx);
    return 0;
}

int ebb_get_derivatives(ebb_instance *c, const char *function, double dx[], size_t nx)
{
    if (states_count(c, function, "derivatives", nx) != 0) return -1;
    if (ebb_ensure_model(c, function) != 0) return -1;
    ebb_rates(&c->mdl, c->x, c->u, dx);
    return 0;
}

int ebb_get_nominals(ebb_instance *c, const char *function, double x[], size_t nx)
{
    if (states_count(c, function, "states", nx) != 0) return -1;
    if (c->have_model && !c->stale) memcpy(x, c->mdl.nominal, sizeof(double) * nx);
    else for (size_t i = 0; i < nx; i++) x[i] = 1.0;
    return 0;
}
