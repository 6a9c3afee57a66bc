/*
 * ebb_beam.h -- the axially loaded Euler-Bernoulli beam of ebb_model, in plain C99 (libm only).
 *
 * Shared declarations of the standalone FMU's model code:
 *   ebb_linalg.c  dense linear algebra written for this FMU (Cholesky, cyclic Jacobi, LU, Pade expm);
 *   ebb_fd.c      finite-difference assembly from the physical parameters, the lowest modes of a grid;
 *   ebb_model.c   Richardson modes on two grids, exact-in-time discretisation of the modal system (Van Loan),
 *                 one communication sample;
 *   ebb_theta.c   the seed's theta-scheme (scheme "theta") on the config's grid;
 *   ebb_fmi2.c    the FMI 2.0 interface (co-simulation and model exchange), reading the generated
 *                 ebb_config.h (the structure: grid, ends, positions, scheme, dt -- never matrices).
 */
#ifndef EBB_BEAM_H
#define EBB_BEAM_H

#include <stddef.h>

/* parameter order, as ebb_model.beam.PARAMETER_NAMES */
enum { EBB_EI, EBB_RHOA, EBB_C, EBB_ETA, EBB_N, EBB_RHOI, EBB_KF, EBB_NPARAM };

/* accepted magnitudes of the parameters, as ebb_model.parameter_values.MAX_MAGNITUDE and MIN_POSITIVE
   (EI and rhoA); a test compares them */
#define EBB_MAX_MAGNITUDE 1e30
#define EBB_MIN_POSITIVE 1e-30

/* the highest anti-alias filter order (ebb_model.acquisition.antialias.MAX_ORDER; a test compares them) */
#define EBB_MAX_FILTER 10
#define EBB_PI 3.14159265358979323846

/* sensor kinds */
enum { EBB_DISPLACEMENT = 0, EBB_VELOCITY = 1, EBB_ACCELERATION = 2 };

/* force between samples ([time] input) */
enum { EBB_ZOH = 0, EBB_FOH = 1, EBB_CUBIC = 2 };

/* time schemes ([time] scheme) */
enum { EBB_EXACT = 0, EBB_THETA = 1 };

typedef struct {
    double kt, kr;            /* springs to ground, INFINITY = constrained */
} ebb_end;

/* The structural set-up (what the generated config header holds). */
typedef struct {
    double length;
    int nodes;                /* interior grid points of the config's grid */
    ebb_end left, right;
    double dt;
    int hold;                 /* EBB_ZOH, EBB_FOH, EBB_CUBIC */
    int scheme;               /* EBB_EXACT, EBB_THETA */
    double theta;             /* theta of the three-level scheme (EBB_THETA) */
    int substeps;             /* sub-steps per sample (EBB_THETA) */
    int n_act;
    const double *act_x;
    int n_sens;
    const double *sens_x;
    const int *sens_kind;
    int n_mass;
    const double *mass_x;
    const double *mass_m;
    int n_spring;             /* springs to ground: K += k phi(x) phi(x)^T */
    const double *spring_x;
    const double *spring_k;
    int n_weak;               /* weak segments: EI x factor over [x - len/2, x + len/2] (compliance-averaged) */
    const double *weak_x;
    const double *weak_len;
    const double *weak_factor;
    const int *sens_aa_order; /* per sensor: order of its anti-alias Butterworth (0: none) */
    const double *sens_aa_corner;  /* per sensor: its -3 dB corner [Hz] */
} ebb_structure;

/* The discrete model of one parameter set, in the causal "xi" form of ebb_model
 * (scheme exact: x = (q, qdot) of the Richardson modes; scheme theta: x = (q^j, v^{j-1/2}) of the nodal
 * unknowns, dense, and for model exchange the nodal (q, qdot) with Kd = M^-1 K, Cm = M^-1 C, Fm = M^-1 F):
 *   xi[k+1] = Phi xi[k] + sum_j Q_j u[k-j]   (j = 0 .. delays),   y[k] = Cy xi[k] + Dy u[k],
 * with xi = x - H u (x = (q, qdot) of the Richardson modes, then the sensors' anti-alias filter states, which
 * make the form dense: each filter in series after its sensor's continuous output, integrated with the beam).
 * Mode-wise (proportional damping): 2x2 blocks per mode acting on the modal force g = Fm u; dense otherwise.  The continuous-time modal system
 * (model exchange) is kept too: qddot = -w2 q - Cm qdot + Fm u, y = Cc x + Dc u. */
typedef struct {
    int k, m, p;              /* modes, inputs, outputs */
    int nf, nx;               /* anti-alias filter states (after the 2k modal ones; dense form), all states */
    double *Fx, *Fu;          /* (nf x nx), (nf x m): the filters' ODE, fdot = Fx x + Fu u (NULL when nf = 0) */
    int dense;                /* 0: proportional damping, per-mode blocks; 1: coupled, dense */
    int delays;               /* past samples the input reconstruction reads (2 for the cubic) */
    double *w2;               /* (k) extrapolated omega^2 */
    double *Kd;               /* (k x k) stiffness of the ODE when not modal (theta: M^-1 K), else NULL */
    double *Cm;               /* (k x k) modal damping */
    double *Fm;               /* (k x m) modal forcing */
    double *Cc, *Dc;          /* (p x nx), (p x m) continuous outputs on x = (q, qdot, filter states) */
    /* per-mode form: Phi (k x 4), Q (delays+1) x (k x 2), H (k x 2) acting on g = Fm u */
    /* dense form:    Phi (nx x nx), Q (delays+1) x (nx x m), H (nx x m) acting on u     */
    double *Phi, *Q, *H;
    double *Cy, *Dy;          /* (p x nx), (p x m): outputs from xi and u */
    double *nominal;          /* (nx) state nominals for model exchange */
    double spectral_radius;
} ebb_model;

/* ---- linear algebra (ebb_linalg.c); matrices row-major, n x n unless said ---- */
int ebb_cholesky(double *a, int n);                         /* a = L L^T in place (lower); 0 ok, -1 not PD */
void ebb_congruence(const double *L, const double *a, double *out, int n);  /* out = L^-1 a L^-T */
void ebb_back_transform(const double *L, double *v, int n, int ncol);     /* v <- L^-T v (n x ncol) */
int ebb_jacobi(double *a, double *v, double *w, int n);     /* symmetric eigen: a destroyed, v vectors (cols) */
int ebb_expm(const double *a, double *e, int n);            /* e = exp(a), scaling and squaring, Pade [6/6] */
int ebb_lu_solve(double *a, double *b, int n, int ncol);    /* b <- a^-1 b (a destroyed); -1 if singular */

/* ---- model (ebb_model.c) ---- */
/* Build the model for parameters p; on failure return nonzero with a message naming the parameter. */
int ebb_model_build(const ebb_structure *s, const double *p, ebb_model *out, char *msg, size_t msglen);
void ebb_model_free(ebb_model *mdl);

/* ---- finite differences (ebb_fd.c): the semi-discrete beam M q'' + C q' + K q = F u on a grid ---- */
typedef struct {
    int n, nu, first;                 /* interior nodes, unknowns, grid index of the first unknown */
    double h;
    double *M, *C, *K;                /* nu x nu */
    double *F;                        /* nu x n_act */
    double *S;                        /* n_sens x nu */
} fd_beam;

int ebb_n_modes(const ebb_structure *s);                    /* unknowns of the config's grid */
/* n interior nodes; -1 no memory */
int ebb_fd_assemble(const ebb_structure *s, int n, const double *p, fd_beam *b);
void ebb_fd_free(fd_beam *b);
/* the nm lowest w2 and mass-normalised modes (nu x nm); -1 failed */
int ebb_fd_lowest_modes(const fd_beam *b, int nm, double *w2, double *psi);

/* ---- theta-scheme (ebb_theta.c), the model of scheme "theta" (called by ebb_model_build) ---- */
int ebb_build_theta(const ebb_structure *s, const double *p, ebb_model *out, char *msg, size_t msglen);

#endif
