/*
 * ebb_instance.h -- one instance of the standalone beam FMU, whatever the FMI version that drives it.
 *
 * ebb_instance.c holds what an instance does (the model built from the parameters, the co-simulation step, the
 * model-exchange state and derivatives, the variables' values), ebb_derivatives.c the derivatives of the linear
 * maps, ebb_state.c the saved states, ebb_delay.c the channels' converter delays (delay lines of past outputs);
 * ebb_fmi2.c and ebb_fmi3.c only translate their standard's calls into these.  Functions return 0
 * on success and -1 after logging one error message that names the function and the variable.
 *
 * Variables are addressed by value reference (the generated table of ebb_config.h): a variable has a size
 * (1, or the length of an array variable such as FMI 3.0's deflection field w), and a call's values are the
 * variables' elements one after the other.
 */
#ifndef EBB_INSTANCE_H
#define EBB_INSTANCE_H

#include <stddef.h>

#include "ebb_beam.h"
#include "ebb_config.h"

/* the entry points a host calls, exported from the shared library (ebb_fmi2.c, ebb_fmi3.c) */
#if defined(_WIN32)
#define EBB_EXPORT __declspec(dllexport)
#elif defined(__GNUC__)
#define EBB_EXPORT __attribute__((visibility("default")))
#else
#define EBB_EXPORT
#endif

enum { ROLE_PARAMETER, ROLE_INPUT, ROLE_OUTPUT, ROLE_CONSTANT, ROLE_STATE, ROLE_DERIVATIVE, ROLE_TIME };
enum { TYPE_REAL, TYPE_INTEGER, TYPE_STRING };

typedef struct ebb_instance ebb_instance;
/* a function pointer of any type (the host's logger, whose type is the FMI version's; ISO C converts function
 * pointers to one another, not to void *) */
typedef void (*ebb_any_fn)(void);
/* passes one message to the host's logger (error: 1 for an error, 0 for a debug message) */
typedef void (*ebb_log_fn)(const ebb_instance *c, int error, const char *category, const char *message);

struct ebb_instance {
    ebb_log_fn log;
    ebb_any_fn host_logger;              /* the host's logger and its environment, as the FMI layer keeps them */
    void *env;
    char *name;
    int exchange;                        /* 1: model exchange, 0: co-simulation */
    int debug;
    double p[EBB_NPARAM];
    double u[EBB_NACT];
    ebb_model mdl;
    int have_model, stale, at_start;
    double xi[EBB_NSTATES];              /* co-simulation: causal state xi = x - H u */
    double hist[2 * EBB_NACT + 1];       /* u[k-1], u[k-2] */
    double x[EBB_NSTATES];               /* model exchange: (q, qdot, anti-alias filter states) */
    double g[3 * EBB_NMODES];            /* modal forces of u[k], u[k-1], u[k-2] (per-mode form) */
    double xn[EBB_NSTATES];
    double time;
    double *dline;                       /* co-simulation: the delayed sensors' undelayed outputs, a ring of
                                            EBB_DELAY_LEN past samples each (ebb_delay.c; NULL when none) */
    int dhead;                           /* the ring's slot of the latest sample */
};

/* life */
ebb_instance *ebb_new(const char *name, int exchange, int debug, ebb_log_fn log, ebb_any_fn host_logger,
                      void *env);
void ebb_free(ebb_instance *c);
void ebb_reset(ebb_instance *c);
int ebb_fail(const ebb_instance *c, const char *function, const char *fmt, ...);
const char *ebb_var_name(unsigned vr);
int ebb_ensure_model(ebb_instance *c, const char *function);

/* dx = f(x, u) of model exchange (the modal or nodal ODE, then the anti-alias filters driven by their sensors) */
void ebb_rates(const ebb_model *m, const double *x, const double *u, double *dx);

/* variables: nvalues must equal the elements of the nvr variables */
int ebb_get_real(ebb_instance *c, const char *function, const unsigned vr[], size_t nvr, double value[],
                 size_t nvalues);
int ebb_set_real(ebb_instance *c, const char *function, const unsigned vr[], size_t nvr, const double value[],
                 size_t nvalues);
int ebb_get_integer(ebb_instance *c, const char *function, const unsigned vr[], size_t nvr, int value[],
                    size_t nvalues);
int ebb_get_string(ebb_instance *c, const char *function, const unsigned vr[], size_t nvr, const char *value[],
                   size_t nvalues);
int ebb_refuse(ebb_instance *c, const char *function, const char *what, const unsigned vr[], size_t nvr);

/* co-simulation: a communication step of h = n dt (n >= 1, within STEP_TOLERANCE) from t */
int ebb_do_step(ebb_instance *c, const char *function, double t, double h);

/* model exchange */
int ebb_set_states(ebb_instance *c, const char *function, const double x[], size_t nx);
int ebb_get_states(ebb_instance *c, const char *function, double x[], size_t nx);
int ebb_get_derivatives(ebb_instance *c, const char *function, double dx[], size_t nx);
int ebb_get_nominals(ebb_instance *c, const char *function, double x[], size_t nx);

/* derivatives of the linear maps (outputs and state derivatives in the inputs and, for model exchange, the
 * states): directional  sensitivity = J seed  (seed per known element, sensitivity per unknown element);
 * adjoint  sensitivity = J^T seed  (seed per unknown element, sensitivity per known element) */
int ebb_directional(ebb_instance *c, const char *function, const unsigned unknown[], size_t n_unknown,
                    const unsigned known[], size_t n_known, const double seed[], size_t n_seed,
                    double sensitivity[], size_t n_sensitivity);
int ebb_adjoint(ebb_instance *c, const char *function, const unsigned unknown[], size_t n_unknown,
                const unsigned known[], size_t n_known, const double seed[], size_t n_seed,
                double sensitivity[], size_t n_sensitivity);

/* the channels' converter delays (ebb_delay.c): EBB_NDELAYED sensors, each a ring of EBB_DELAY_LEN past
 * undelayed outputs; ebb_undelayed (ebb_instance.c) is output o of co-simulation before its delay */
double ebb_undelayed(const ebb_instance *c, int o);
int ebb_delay_new(ebb_instance *c);
void ebb_delay_free(ebb_instance *c);
int ebb_delay_refuse_exchange(const ebb_instance *c, const char *function);
void ebb_delay_fill(ebb_instance *c);
void ebb_delay_push(ebb_instance *c);
double ebb_delay_output(const ebb_instance *c, int o, double now);
double ebb_delay_feedthrough(int o, double undelayed);
void ebb_delay_save(const ebb_instance *c, double *line);
void ebb_delay_load(ebb_instance *c, const double *line);
#define EBB_DELAY_STORE ((size_t)EBB_NDELAYED * (size_t)EBB_DELAY_LEN)   /* doubles of the rings */

/* saved states (ebb_state.c): a snapshot is malloc'ed (or `reuse` overwritten); serialised as the GUID and the raw snapshot */
void *ebb_state_get(ebb_instance *c, const char *function, void *reuse);
int ebb_state_set(ebb_instance *c, const char *function, const void *state);
size_t ebb_state_size(void);
int ebb_state_serialize(ebb_instance *c, const char *function, const void *state, unsigned char bytes[],
                        size_t size);
void *ebb_state_deserialize(ebb_instance *c, const char *function, const unsigned char bytes[], size_t size,
                            void *reuse);
int ebb_state_check(ebb_instance *c, const char *function, const void *state);

#endif
