/*
 * ebb_model.c -- the beam model of ebb_model (scheme "exact"), assembled from the physical parameters.
 *
 * 1. Space: central finite differences with ghost nodes (port of ebb_model/space/discretisation.py): on a grid of
 *    n interior points, spacing h = L/(n+1), the semi-discrete beam M q'' + C q' + K q = F u with
 *      K = diag(V)(EI D4 - N D2)E + kf diag(V) + sum_s k_s phi(a_s) phi(a_s)^T,  C = c diag(V) + eta EI diag(V) D4 E,
 *      M = rhoA diag(V) + rhoI h (GP)^T(GP) + sum_m m_m phi(a_m) phi(a_m)^T,
 *    E the extension by the ghost nodes of the moment and shear conditions (elastic ends kt, kr in [0, inf]),
 *    forces, sensors, point masses and springs to ground on the grid's hat functions; with weak segments the
 *    bending term is D2 (e D2 w) with e the cells' compliance-averaged relative EI (ghost nodes: their end's).
 * 2. Richardson modes (ebb_model/exact/exact_modal.py): the beam on the config's grid and on its companion grid
 *    (2n+1 nodes up to 201, else (n-1)/2); the lowest w2 of both, extrapolated as
 *    w2_f + weight (w2_f - w2_c)/((h_c/h_f)^2 - 1) (weight 1 for the lower half of the coarse grid's modes,
 *    fading to 0), mass-normalised shapes and damping from the finer grid; as many modes as the config's grid
 *    has unknowns.  The eigenproblems: with K positive definite the inverted problem M psi = mu K psi (each w2
 *    to a few eps relatively, as ebb_model does), else K psi = w2 M psi; both reduced by Cholesky and solved
 *    by cyclic Jacobi (ebb_linalg.c).
 * 3. Time, exact: the modal system q'' + Cm q' + w2 q = Fm u under the polynomial through the input samples
 *    (cubic through k-2..k+1, straight line, or held) integrated exactly over a sample by one matrix
 *    exponential of the system augmented with the chain of the polynomial's derivatives (Van Loan) -- per
 *    mode (2 + taps) when the damping is proportional (Psi^T C Psi diagonal to 1e-10), else for the whole
 *    modal system.  Each mode's coordinates are scaled by max(w, 1/dt) for the exponential (a diagonal
 *    similarity: exact, and it keeps the scaled matrix's norm near w dt).  The sample ahead is made causal by
 *    xi = x - H u (H the lookahead's weights), exactly as ebb_model's realisation.
 * The seed's theta-scheme (scheme "theta") is at the end of the file (build_theta).
 */
#include "ebb_beam.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    int n, nu, first;                 /* interior nodes, unknowns, grid index of the first unknown */
    double h;
    double *M, *C, *K;                /* nu x nu */
    double *F;                        /* nu x n_act */
    double *S;                        /* n_sens x nu */
} fd_beam;

static const char *PARAM_NAMES[EBB_NPARAM] = {"EI", "rhoA", "c", "eta", "N", "rhoI", "kf"};

static void fd_free(fd_beam *b)
{
    free(b->M); free(b->C); free(b->K); free(b->F); free(b->S);
    memset(b, 0, sizeof(*b));
}

static int translation_fixed(const ebb_end *e) { return isinf(e->kt); }
static int rotation_fixed(const ebb_end *e) { return isinf(e->kr); }

int ebb_n_modes(const ebb_structure *s)
{
    const int first = translation_fixed(&s->left) ? 1 : 0;
    const int last = translation_fixed(&s->right) ? s->nodes : s->nodes + 1;
    return last - first + 1;
}

/* hat-function weights of x on the grid, restricted to the unknowns (row of length nu) */
static void hat_row(double x, double length, int n, int first, int nu, double *row)
{
    const double h = length / (n + 1);
    memset(row, 0, sizeof(double) * (size_t)nu);
    const double sx = x / h;
    int i = (int)floor(sx);
    if (i > n) i = n;
    const double t = sx - i;
    if (i - first >= 0 && i - first < nu) row[i - first] += 1.0 - t;
    if (i + 1 - first >= 0 && i + 1 - first < nu) row[i + 1 - first] += t;
}

/* ghost rows of one end on the extension E ((n+6) x nu, row of grid node k is k+2) */
static void ghosts(double *E, int nu, const ebb_end *end, int b, int s, double h, double EI, double N)
{
#define ROW(k) (E + (size_t)((k) + 2) * nu)
    const double *w0 = ROW(b), *w1 = ROW(b + s), *w2 = ROW(b + 2 * s);
    double *g1 = ROW(b - s);
    if (rotation_fixed(end)) {
        for (int j = 0; j < nu; j++) g1[j] = w1[j];
    } else {
        const double r = end->kr * h / (2.0 * EI);
        for (int j = 0; j < nu; j++) g1[j] = (2.0 * w0[j] + (r - 1.0) * w1[j]) / (1.0 + r);
    }
    if (!translation_fixed(end)) {
        double *g2 = ROW(b - 2 * s);
        const double a = N * h * h / EI, kt = 2.0 * pow(h, 3) * end->kt / EI;   /* ebb_model's order of operations */
        for (int j = 0; j < nu; j++)
            g2[j] = w2[j] - 2.0 * w1[j] + 2.0 * g1[j] - a * (w1[j] - g1[j]) + kt * w0[j];
    }
#undef ROW
}

static int fd_assemble(const ebb_structure *s, int n, const double *p, fd_beam *b)
{
    const double EI = p[EBB_EI], rhoA = p[EBB_RHOA], c = p[EBB_C], eta = p[EBB_ETA], N = p[EBB_N];
    const double rhoI = p[EBB_RHOI], kf = p[EBB_KF];
    const double L = s->length, h = L / (n + 1);
    const int first = translation_fixed(&s->left) ? 1 : 0;
    const int last = translation_fixed(&s->right) ? n : n + 1;
    const int nu = last - first + 1, next = n + 6;
    b->n = n; b->nu = nu; b->first = first; b->h = h;
    b->M = calloc((size_t)nu * nu, sizeof(double));
    b->C = calloc((size_t)nu * nu, sizeof(double));
    b->K = calloc((size_t)nu * nu, sizeof(double));
    b->F = calloc((size_t)nu * (s->n_act ? s->n_act : 1), sizeof(double));
    b->S = calloc((size_t)(s->n_sens ? s->n_sens : 1) * nu, sizeof(double));
    double *E = calloc((size_t)next * nu, sizeof(double));
    double *B4 = calloc((size_t)nu * nu, sizeof(double));
    double *B2 = calloc((size_t)nu * nu, sizeof(double));
    double *V = malloc(sizeof(double) * (size_t)nu), *row = malloc(sizeof(double) * (size_t)nu);
    if (!b->M || !b->C || !b->K || !b->F || !b->S || !E || !B4 || !B2 || !V || !row) {
        free(E); free(B4); free(B2); free(V); free(row);
        return -1;
    }
    for (int j = 0; j < nu; j++) E[(size_t)(first + j + 2) * nu + j] = 1.0;
    ghosts(E, nu, &s->left, 0, +1, h, EI, N);
    ghosts(E, nu, &s->right, n + 1, -1, h, EI, N);
    for (int j = 0; j < nu; j++) V[j] = h;
    if (!translation_fixed(&s->left)) V[0] = h / 2.0;
    if (!translation_fixed(&s->right)) V[nu - 1] = h / 2.0;
    static const double d4[5] = {1.0, -4.0, 6.0, -4.0, 1.0}, d2[3] = {1.0, -2.0, 1.0};
    const double h4 = pow(h, 4), h2 = pow(h, 2);
    double *ext = NULL;                                /* weak segments: the cells' relative EI, nodes -2 … n+3 */
    if (s->n_weak > 0) {
        ext = malloc(sizeof(double) * (size_t)next);
        if (!ext) { free(E); free(B4); free(B2); free(V); free(row); return -1; }
        for (int i = 0; i <= n + 1; i++) {
            const double xi = i * h, lo = fmax(xi - h / 2.0, 0.0), hi = fmin(xi + h / 2.0, L);
            double compliance = 1.0;
            for (int w = 0; w < s->n_weak; w++) {
                const double a = s->weak_x[w] - 0.5 * s->weak_len[w], b = s->weak_x[w] + 0.5 * s->weak_len[w];
                const double covered = fmax(fmin(hi, b) - fmax(lo, a), 0.0) / (hi - lo);
                compliance += covered * (1.0 / s->weak_factor[w] - 1.0);
            }
            ext[i + 2] = 1.0 / compliance;
        }
        ext[0] = ext[next - 1] = 1.0;
        ext[1] = ext[2];
        ext[next - 2] = ext[next - 3];
    }
    for (int j = 0; j < nu; j++) {
        const int r = first + j + 2;                   /* extended row of unknown j */
        for (int col = 0; col < nu; col++) {
            double a4 = 0.0, a2 = 0.0;
            if (ext) {                                 /* D2 (e D2 w): moments at rows r-1, r, r+1 */
                for (int t = 0; t < 3; t++) {
                    const int k = r - 1 + t;
                    double curv = 0.0;
                    for (int q = 0; q < 3; q++) curv += d2[q] * E[(size_t)(k - 1 + q) * nu + col];
                    a4 += d2[t] * ext[k] * curv;
                }
                a4 /= h4;
            } else {
                for (int t = 0; t < 5; t++) a4 += (d4[t] / h4) * E[(size_t)(r - 2 + t) * nu + col];
            }
            for (int t = 0; t < 3; t++) a2 += (d2[t] / h2) * E[(size_t)(r - 1 + t) * nu + col];
            B4[j * nu + col] = V[j] * a4;
            B2[j * nu + col] = V[j] * a2;
        }
    }
    free(ext);
    for (int i = 0; i < nu * nu; i++) {
        b->K[i] = EI * B4[i] - N * B2[i];
        b->C[i] = eta * EI * B4[i];
    }
    for (int j = 0; j < nu; j++) {
        b->K[j * nu + j] += kf * V[j];
        b->C[j * nu + j] += c * V[j];
        b->M[j * nu + j] = rhoA * V[j];
    }
    if (rhoI != 0.0) {                                 /* h (GP)^T (GP): 1/h times the grid's graph Laplacian */
        for (int j = 0; j < nu; j++) {
            const int node = first + j;
            const double cells = (node == 0 || node == n + 1) ? 1.0 : 2.0;
            b->M[j * nu + j] += rhoI * (cells / h);
            if (j + 1 < nu) {
                b->M[j * nu + j + 1] += rhoI * (-1.0 / h);
                b->M[(j + 1) * nu + j] += rhoI * (-1.0 / h);
            }
        }
    }
    for (int m = 0; m < s->n_mass; m++) {
        hat_row(s->mass_x[m], L, n, first, nu, row);
        for (int i = 0; i < nu; i++)
            for (int j = 0; j < nu; j++) b->M[i * nu + j] += s->mass_m[m] * (row[i] * row[j]);
    }
    for (int k = 0; k < s->n_spring; k++) {
        hat_row(s->spring_x[k], L, n, first, nu, row);
        for (int i = 0; i < nu; i++)
            for (int j = 0; j < nu; j++) b->K[i * nu + j] += s->spring_k[k] * (row[i] * row[j]);
    }
    for (int i = 0; i < nu; i++)                       /* symmetrise away round-off */
        for (int j = i + 1; j < nu; j++) {
            double t = 0.5 * (b->K[i * nu + j] + b->K[j * nu + i]);
            b->K[i * nu + j] = b->K[j * nu + i] = t;
            t = 0.5 * (b->C[i * nu + j] + b->C[j * nu + i]);
            b->C[i * nu + j] = b->C[j * nu + i] = t;
        }
    for (int a = 0; a < s->n_act; a++) {
        hat_row(s->act_x[a], L, n, first, nu, row);
        for (int i = 0; i < nu; i++) b->F[i * s->n_act + a] = row[i];
    }
    for (int o = 0; o < s->n_sens; o++) hat_row(s->sens_x[o], L, n, first, nu, b->S + (size_t)o * nu);
    free(E); free(B4); free(B2); free(V); free(row);
    return 0;
}

/* order of w (n) descending (desc = 1) or ascending, into idx */
static void order(const double *w, int *idx, int n, int desc)
{
    for (int i = 0; i < n; i++) idx[i] = i;
    for (int i = 1; i < n; i++) {                      /* insertion sort: n is a few hundred at most */
        const int v = idx[i];
        int j = i - 1;
        while (j >= 0 && (desc ? w[idx[j]] < w[v] : w[idx[j]] > w[v])) { idx[j + 1] = idx[j]; j--; }
        idx[j + 1] = v;
    }
}

/* Rayleigh quotients psi^T K psi / psi^T M psi in extended precision, as the eigenvalues.
 * Both reductions leave each w2 with an error of about eps |psi|^T |K| |psi| / psi^T K psi (the backward error
 * of the Cholesky factor: a cancellation factor that grows as kappa(K) for the smooth low modes), and the
 * inverted one eps mu_max / mu_i for the high modes.  The quotient is second order in the vectors' error and,
 * summed in long double, carries the cancellation with eps of long double: every w2 then is the eigenvalue of
 * the assembled (double) K and M to about 1e-13.  Used where long double is wider than double (x86-64 gcc);
 * elsewhere the solver's values stand. */
static void rayleigh_refine(const fd_beam *b, int nm, double *w2, const double *psi)
{
    const int nu = b->nu;
    for (int i = 0; i < nm; i++) {
        long double num = 0.0L, den = 0.0L;
        for (int r = 0; r < nu; r++) {
            long double kr = 0.0L, mr = 0.0L;
            for (int c = 0; c < nu; c++) {
                const long double pc = psi[c * nm + i];
                kr += (long double)b->K[r * nu + c] * pc;
                mr += (long double)b->M[r * nu + c] * pc;
            }
            num += (long double)psi[r * nm + i] * kr;
            den += (long double)psi[r * nm + i] * mr;
        }
        w2[i] = (double)(num / den);
    }
}

/* the nm lowest w2 and the mass-normalised modes (nu x nm) of K psi = w2 M psi */
static int lowest_modes(const fd_beam *b, int nm, double *w2, double *psi)
{
    const int nu = b->nu;
    const size_t nn = (size_t)nu * nu;
    double *L = malloc(sizeof(double) * nn), *A = malloc(sizeof(double) * nn), *V = malloc(sizeof(double) * nn);
    double *mu = malloc(sizeof(double) * (size_t)nu);
    int *idx = malloc(sizeof(int) * (size_t)nu);
    int rc = -1, inverted = 0;
    if (!L || !A || !V || !mu || !idx) goto done;
    memcpy(L, b->K, sizeof(double) * nn);
    if (ebb_cholesky(L, nu) == 0) {                    /* inverted problem: M psi = mu K psi, mu = 1/w2 */
        ebb_congruence(L, b->M, A, nu);
        if (ebb_jacobi(A, V, mu, nu) != 0) goto done;
        order(mu, idx, nu, 1);
        inverted = 1;
        for (int i = 0; i < nm; i++)
            if (!(mu[idx[i]] > 0.0)) inverted = 0;
    }
    if (!inverted) {                                   /* direct problem: K psi = w2 M psi */
        memcpy(L, b->M, sizeof(double) * nn);
        if (ebb_cholesky(L, nu) != 0) goto done;
        ebb_congruence(L, b->K, A, nu);
        if (ebb_jacobi(A, V, mu, nu) != 0) goto done;
        order(mu, idx, nu, 0);
    }
    for (int i = 0; i < nm; i++) w2[i] = inverted ? 1.0 / mu[idx[i]] : mu[idx[i]];
    {
        for (int r = 0; r < nu; r++)
            for (int i = 0; i < nm; i++) psi[r * nm + i] = V[r * nu + idx[i]];
        ebb_back_transform(L, psi, nu, nm);            /* psi = L^-T v */
        for (int i = 0; i < nm; i++) {                 /* mass-normalise */
            double s = 0.0;
            for (int r = 0; r < nu; r++) {
                double mr = 0.0;
                for (int c = 0; c < nu; c++) mr += b->M[r * nu + c] * psi[c * nm + i];
                s += psi[r * nm + i] * mr;
            }
            s = sqrt(s);
            for (int r = 0; r < nu; r++) psi[r * nm + i] /= s;
        }
        if (LDBL_MANT_DIG > DBL_MANT_DIG) rayleigh_refine(b, nm, w2, psi);
    }
    rc = 0;
done:
    free(L); free(A); free(V); free(mu); free(idx);
    return rc;
}

/* Lagrange basis of the taps: coef[j][q] is the sigma^q coefficient of l_j(sigma) */
static void lagrange(const int *taps, int nt, double coef[4][4])
{
    for (int j = 0; j < nt; j++) {
        double poly[5] = {1.0, 0.0, 0.0, 0.0, 0.0};
        double denom = 1.0;
        int deg = 0;
        for (int i = 0; i < nt; i++) {
            if (i == j) continue;
            for (int q = deg + 1; q >= 0; q--)          /* poly *= (sigma - t_i) */
                poly[q] = (q > 0 ? poly[q - 1] : 0.0) - taps[i] * poly[q];
            deg++;
            denom *= (double)(taps[j] - taps[i]);
        }
        for (int q = 0; q < nt; q++) coef[j][q] = poly[q] / denom;
    }
}

static double pole_radius(double w2, double d, double T)
{
    const double disc = d * d / 4.0 - w2;
    const double re = disc > 0.0 ? -d / 2.0 + sqrt(disc) : -d / 2.0;
    return exp(re * T);
}

static int check_parameters(const double *p, char *msg, size_t msglen)
{
    for (int i = 0; i < EBB_NPARAM; i++) {
        if (!isfinite(p[i])) {
            snprintf(msg, msglen, "parameter %s = %g is not a finite number", PARAM_NAMES[i], p[i]);
            return -1;
        }
        if ((i == EBB_EI || i == EBB_RHOA) && !(p[i] > 0.0)) {
            snprintf(msg, msglen, "parameter %s = %g is invalid: must be > 0", PARAM_NAMES[i], p[i]);
            return -1;
        }
        if ((i == EBB_C || i == EBB_ETA || i == EBB_RHOI || i == EBB_KF) && p[i] < 0.0) {
            snprintf(msg, msglen, "parameter %s = %g is invalid: must be >= 0", PARAM_NAMES[i], p[i]);
            return -1;
        }
        if ((i == EBB_EI || i == EBB_RHOA) && p[i] < EBB_MIN_POSITIVE) {
            snprintf(msg, msglen, "parameter %s = %g is invalid: must be at least %g (far below any physical "
                     "beam)", PARAM_NAMES[i], p[i], EBB_MIN_POSITIVE);
            return -1;
        }
        if (fabs(p[i]) > EBB_MAX_MAGNITUDE) {
            snprintf(msg, msglen, "parameter %s = %g is invalid: must be at most %g in magnitude (far beyond any "
                     "physical beam)", PARAM_NAMES[i], p[i], EBB_MAX_MAGNITUDE);
            return -1;
        }
    }
    return 0;
}

void ebb_model_free(ebb_model *mdl)
{
    free(mdl->w2); free(mdl->Kd); free(mdl->Cm); free(mdl->Fm); free(mdl->Cc); free(mdl->Dc);
    free(mdl->Phi); free(mdl->Q); free(mdl->H); free(mdl->Cy); free(mdl->Dy); free(mdl->nominal);
    free(mdl->Fx); free(mdl->Fu);
    memset(mdl, 0, sizeof(*mdl));
}

/* exact discretisation of x' = A x + B v over T (n states, nv inputs; A, B already times T and scaled);
 * returns Phi (n x n) and Pq[q] (n x nv) = q! times the response to sigma^q/q!'s chain entry, q = 0..deg */
static int van_loan(const double *AT, const double *BT, int n, int nv, int deg, double *Phi, double *Pq)
{
    const int na = n + (deg + 1) * nv;
    double *aug = calloc((size_t)na * na, sizeof(double)), *E = malloc(sizeof(double) * (size_t)na * na);
    if (!aug || !E) { free(aug); free(E); return -1; }
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) aug[i * na + j] = AT[i * n + j];
        for (int j = 0; j < nv; j++) aug[i * na + n + j] = BT[i * nv + j];
    }
    for (int q = 0; q < deg; q++)
        for (int j = 0; j < nv; j++) aug[(n + q * nv + j) * na + n + (q + 1) * nv + j] = 1.0;
    int rc = ebb_expm(aug, E, na);
    if (rc == 0) {
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++) Phi[i * n + j] = E[i * na + j];
        double fact = 1.0;
        for (int q = 0; q <= deg; q++) {
            if (q > 1) fact *= q;
            for (int i = 0; i < n; i++)
                for (int j = 0; j < nv; j++) Pq[((size_t)q * n + i) * nv + j] = E[i * na + n + q * nv + j] * fact;
        }
    }
    free(aug); free(E);
    return rc;
}

static int build_theta(const ebb_structure *s, const double *p, ebb_model *out, char *msg, size_t msglen);

/* The anti-alias filter of order n and corner fc [Hz] (ebb_model/acquisition/antialias.py): the Butterworth low-pass as a
 * cascade of unit-DC-gain sections, w^2/(s^2 + 2 sig s + w^2) on the states (y, y'/w) and a/(s + a) on y, each
 * driven by the previous one's output.  Writes A (n x n, row-major), b (n) and c (n). */
static void butterworth(int n, double fc, double *A, double *b, double *c)
{
    const double wc = 2.0 * EBB_PI * fc;
    memset(A, 0, sizeof(double) * (size_t)n * n);
    memset(b, 0, sizeof(double) * (size_t)n);
    memset(c, 0, sizeof(double) * (size_t)n);
    int at = 0, prev = -1;
    for (int kk = 1; kk <= n / 2 + n % 2; kk++) {
        const int len = kk <= n / 2 ? 2 : 1;
        if (len == 2) {                          /* poles wc e^{+-i theta}, theta = pi (2kk + n - 1)/(2n) */
            const double sig = -wc * cos(EBB_PI * (2.0 * kk + n - 1.0) / (2.0 * n));
            A[at * n + at + 1] = wc;
            A[(at + 1) * n + at] = -wc;
            A[(at + 1) * n + at + 1] = -2.0 * sig;
        } else {
            A[at * n + at] = -wc;
        }
        const double drive0 = len == 2 ? 0.0 : wc, drive1 = len == 2 ? wc : 0.0;
        if (prev < 0) { b[at] = drive0; if (len == 2) b[at + 1] = drive1; }
        else {                                   /* driven by the previous section's output, its first state */
            A[at * n + prev] += drive0;
            if (len == 2) A[(at + 1) * n + prev] += drive1;
        }
        prev = at;
        at += len;
    }
    c[prev] = 1.0;
}

/* The filters' ODE fdot = Fx x + Fu u (each driven by its sensor's continuous output Cc x + Dc u), and the
 * filtered sensors' outputs moved onto their filter's last section: Cc row = c_f, Dc row = 0.  Needs out->Cc,
 * out->Dc (the beam's rows), out->nf, out->nx.  Returns -1 when out of memory. */
static int filter_rows(const ebb_structure *s, ebb_model *out)
{
    const int nx = out->nx, m = out->m, base = nx - out->nf;
    out->Fx = calloc((size_t)out->nf * nx, sizeof(double));
    out->Fu = calloc((size_t)out->nf * m + 1, sizeof(double));
    double A[EBB_MAX_FILTER * EBB_MAX_FILTER], b[EBB_MAX_FILTER], c[EBB_MAX_FILTER];
    if (!out->Fx || !out->Fu) return -1;
    int at = 0;
    for (int o = 0; o < out->p; o++) {
        const int n = s->sens_aa_order[o];
        if (n <= 0) continue;
        butterworth(n, s->sens_aa_corner[o], A, b, c);
        double *Crow = out->Cc + (size_t)o * nx, *Drow = out->Dc + (size_t)o * m;
        for (int i = 0; i < n; i++) {
            double *Frow = out->Fx + (size_t)(at + i) * nx;
            for (int j = 0; j < n; j++) Frow[base + at + j] = A[i * n + j];
            for (int col = 0; col < base; col++) Frow[col] = b[i] * Crow[col];
            for (int j = 0; j < m; j++) out->Fu[(size_t)(at + i) * m + j] = b[i] * Drow[j];
        }
        for (int col = 0; col < nx; col++) Crow[col] = 0.0;
        for (int j = 0; j < n; j++) Crow[base + at + j] = c[j];
        for (int j = 0; j < m; j++) Drow[j] = 0.0;
        at += n;
    }
    return 0;
}

/* Model-exchange nominals of the filter states: the scale of the sensor's output they carry (their DC gain is
 * 1), from the modal nominals: the filter's input row is b_f times the sensor's row, b_f = 2 pi fc. */
static void filter_nominals(const ebb_structure *s, ebb_model *out)
{
    const int nx = out->nx, base = nx - out->nf;
    int at = 0;
    for (int o = 0; o < out->p; o++) {
        const int n = s->sens_aa_order[o];
        if (n <= 0) continue;
        double scale = 0.0;
        for (int i = 0; i < n; i++) {
            const double *Frow = out->Fx + (size_t)(at + i) * nx;
            double acc = 0.0;
            for (int col = 0; col < base; col++) acc += fabs(Frow[col]) * out->nominal[col];
            scale = fmax(scale, acc / (2.0 * EBB_PI * s->sens_aa_corner[o]));
        }
        for (int i = 0; i < n; i++) out->nominal[base + at + i] = scale > 0.0 ? scale : 1.0;
        at += n;
    }
}

int ebb_model_build(const ebb_structure *s, const double *p, ebb_model *out, char *msg, size_t msglen)
{
    memset(out, 0, sizeof(*out));
    if (check_parameters(p, msg, msglen) != 0) return -1;
    if (s->scheme == EBB_THETA) return build_theta(s, p, out, msg, msglen);
    const int n = s->nodes;
    const int n2 = (2 * n + 1 <= 201) ? 2 * n + 1 : (n - 1) / 2;
    fd_beam a = {0}, b = {0};
    double *psi = NULL, *psic = NULL, *w2c = NULL, *Cd = NULL, *work = NULL;
    int rc = -1;
    if (fd_assemble(s, n, p, &a) != 0 || fd_assemble(s, n2, p, &b) != 0) {
        snprintf(msg, msglen, "out of memory");
        goto done;
    }
    const fd_beam *fine = (b.nu > a.nu) ? &b : &a, *coarse = (b.nu > a.nu) ? &a : &b;
    const int k = a.nu, m = s->n_act, np = s->n_sens, nuf = fine->nu;
    const int mc = coarse->nu < k ? coarse->nu : k;
    out->k = k; out->m = m; out->p = np;
    out->w2 = malloc(sizeof(double) * (size_t)k);
    psi = malloc(sizeof(double) * (size_t)nuf * k);
    w2c = malloc(sizeof(double) * (size_t)mc);
    psic = malloc(sizeof(double) * (size_t)coarse->nu * mc);
    if (!out->w2 || !psi || !w2c || !psic) { snprintf(msg, msglen, "out of memory"); goto done; }
    if (lowest_modes(fine, k, out->w2, psi) != 0 || lowest_modes(coarse, mc, w2c, psic) != 0) {
        snprintf(msg, msglen, "the eigenvalue problem of the beam failed (mass matrix not positive definite "
                 "or no convergence): check rhoA, rhoI and the point masses");
        goto done;
    }
    const double ratio = coarse->h / fine->h, denom = ratio * ratio - 1.0;
    for (int i = 0; i < mc; i++) {
        double wgt = 2.0 * (1.0 - (double)i / mc);
        wgt = wgt < 0.0 ? 0.0 : (wgt > 1.0 ? 1.0 : wgt);
        out->w2[i] += wgt * (out->w2[i] - w2c[i]) / denom;
    }
    /* modal damping, forcing and sensor rows on the fine grid */
    out->Cm = calloc((size_t)k * k, sizeof(double));
    out->Fm = calloc((size_t)k * (m ? m : 1), sizeof(double));
    Cd = calloc((size_t)nuf * k, sizeof(double));
    if (!out->Cm || !out->Fm || !Cd) { snprintf(msg, msglen, "out of memory"); goto done; }
    for (int r = 0; r < nuf; r++)                      /* Cd = C psi */
        for (int c = 0; c < nuf; c++) {
            const double v = fine->C[r * nuf + c];
            if (v == 0.0) continue;
            for (int i = 0; i < k; i++) Cd[r * k + i] += v * psi[c * k + i];
        }
    for (int i = 0; i < k; i++)
        for (int j = 0; j < k; j++) {
            double acc = 0.0;
            for (int r = 0; r < nuf; r++) acc += psi[r * k + i] * Cd[r * k + j];
            out->Cm[i * k + j] = acc;
        }
    double dmax = 0.0, offmax = 0.0;
    for (int i = 0; i < k; i++) {
        if (fabs(out->Cm[i * k + i]) > dmax) dmax = fabs(out->Cm[i * k + i]);
        for (int j = 0; j < k; j++)
            if (i != j && fabs(out->Cm[i * k + j]) > offmax) offmax = fabs(out->Cm[i * k + j]);
    }
    out->dense = !(offmax <= 1e-10 * (dmax > 1e-300 ? dmax : 1e-300));
    for (int i = 0; i < k; i++)
        for (int j = 0; j < k; j++) {
            if (!out->dense) { if (i != j) out->Cm[i * k + j] = 0.0; }
            else if (j > i) {
                const double t = 0.5 * (out->Cm[i * k + j] + out->Cm[j * k + i]);
                out->Cm[i * k + j] = out->Cm[j * k + i] = t;
            }
        }
    for (int i = 0; i < k; i++)
        for (int j = 0; j < m; j++) {
            double acc = 0.0;
            for (int r = 0; r < nuf; r++) acc += psi[r * k + i] * fine->F[r * m + j];
            out->Fm[i * m + j] = acc;
        }
    /* the sensors' anti-alias filters: their states after the modal ones, the whole system then dense */
    int nf = 0;
    for (int o = 0; o < np; o++) nf += s->sens_aa_order ? s->sens_aa_order[o] : 0;
    out->nf = nf;
    out->nx = 2 * k + nf;
    if (nf > 0) out->dense = 1;
    const int nx = out->nx;
    out->Cc = calloc((size_t)np * nx + 1, sizeof(double));
    out->Dc = calloc((size_t)np * m + 1, sizeof(double));
    if (!out->Cc || !out->Dc) { snprintf(msg, msglen, "out of memory"); goto done; }
    for (int o = 0; o < np; o++) {
        double *Crow = out->Cc + (size_t)o * nx;
        for (int i = 0; i < k; i++) {
            double P = 0.0;
            for (int r = 0; r < nuf; r++) P += fine->S[o * nuf + r] * psi[r * k + i];
            if (s->sens_kind[o] == EBB_DISPLACEMENT) Crow[i] = P;
            else if (s->sens_kind[o] == EBB_VELOCITY) Crow[k + i] = P;
            else {                                     /* q'' = -w2 q - Cm q' + Fm u */
                Crow[i] = -P * out->w2[i];
                for (int j = 0; j < k; j++) Crow[k + j] -= P * out->Cm[i * k + j];
                for (int j = 0; j < m; j++) out->Dc[o * m + j] += P * out->Fm[i * m + j];
            }
        }
    }
    if (nf > 0 && filter_rows(s, out) != 0) { snprintf(msg, msglen, "out of memory"); goto done; }
    /* time: exact integration of the modal system under the input polynomial */
    static const int taps_zoh[1] = {0}, taps_foh[2] = {0, 1}, taps_cubic[4] = {-2, -1, 0, 1};
    const int *taps = s->hold == EBB_CUBIC ? taps_cubic : (s->hold == EBB_FOH ? taps_foh : taps_zoh);
    const int nt = s->hold == EBB_CUBIC ? 4 : (s->hold == EBB_FOH ? 2 : 1), deg = nt - 1;
    out->delays = s->hold == EBB_CUBIC ? 2 : 0;
    double coef[4][4] = {{0}};
    lagrange(taps, nt, coef);
    const double T = s->dt;
    const int nd = out->delays + 1;
    double *scale = malloc(sizeof(double) * (size_t)k);
    if (!scale) { snprintf(msg, msglen, "out of memory"); goto done; }
    for (int i = 0; i < k; i++) {
        const double w = sqrt(fabs(out->w2[i]));
        scale[i] = w > 1.0 / T ? w : 1.0 / T;
    }
    out->spectral_radius = 0.0;
    for (int i = 0; i < k; i++) {                      /* closed form per mode (diagonal of Cm when coupled) */
        const double r = pole_radius(out->w2[i], out->Cm[i * k + i], T);
        if (r > out->spectral_radius) out->spectral_radius = r;
    }
    if (!out->dense) {
        out->Phi = malloc(sizeof(double) * (size_t)k * 4);
        out->Q = calloc((size_t)nd * k * 2, sizeof(double));
        out->H = calloc((size_t)k * 2, sizeof(double));
        if (!out->Phi || !out->Q || !out->H) { free(scale); snprintf(msg, msglen, "out of memory"); goto done; }
        for (int i = 0; i < k; i++) {
            const double sc = scale[i], d = out->Cm[i * k + i];
            /* the input column is scaled to 1 (the response is linear in it): the expm's absolute error is
             * relative to the augmented matrix's norm, so a column of T/sc would lose digits in P */
            const double AT[4] = {0.0, sc * T, -out->w2[i] * T / sc, -d * T}, BT[2] = {0.0, 1.0};
            const double beta = T / sc;
            double Ph[4], Pq[8];
            if (van_loan(AT, BT, 2, 1, deg, Ph, Pq) != 0) {
                free(scale);
                snprintf(msg, msglen, "the matrix exponential of mode %d is not finite", i + 1);
                goto done;
            }
            double *Pi = out->Phi + (size_t)i * 4;
            Pi[0] = Ph[0]; Pi[1] = Ph[1] / sc; Pi[2] = Ph[2] * sc; Pi[3] = Ph[3];
            double Pt[4][2] = {{0}};
            for (int j = 0; j < nt; j++)
                for (int q = 0; q <= deg; q++) {
                    Pt[j][0] += coef[j][q] * (Pq[q * 2 + 0] * beta);
                    Pt[j][1] += coef[j][q] * (Pq[q * 2 + 1] * beta * sc);
                }
            /* tap offsets: Q_0 <- tap 0 (+ Phi H), Q_1 <- tap -1, Q_2 <- tap -2; H <- tap +1 */
            for (int j = 0; j < nt; j++) {
                if (taps[j] == 1) { out->H[i * 2] = Pt[j][0]; out->H[i * 2 + 1] = Pt[j][1]; }
            }
            for (int j = 0; j < nt; j++) {
                if (taps[j] == 1) continue;
                double *Qd = out->Q + ((size_t)(-taps[j]) * k + i) * 2;
                Qd[0] += Pt[j][0];
                Qd[1] += Pt[j][1];
            }
            double *Q0 = out->Q + (size_t)i * 2;
            const double h0 = out->H[i * 2], h1 = out->H[i * 2 + 1];
            Q0[0] += Pi[0] * h0 + Pi[1] * h1;
            Q0[1] += Pi[2] * h0 + Pi[3] * h1;
        }
    } else {
        const size_t nxx = (size_t)nx * nx;
        double *AT = calloc(nxx, sizeof(double)), *BT = calloc((size_t)nx * m + 1, sizeof(double));
        double *Ph = malloc(sizeof(double) * nxx), *Pq = malloc(sizeof(double) * (size_t)(deg + 1) * nx * m + 1);
        double *sx = malloc(sizeof(double) * (size_t)nx);   /* the state scaling: 1 on q, sc on qdot, sf on f */
        out->Phi = malloc(sizeof(double) * nxx);
        out->Q = calloc((size_t)nd * nx * m + 1, sizeof(double));
        out->H = calloc((size_t)nx * m + 1, sizeof(double));
        if (!AT || !BT || !Ph || !Pq || !sx || !out->Phi || !out->Q || !out->H) {
            free(AT); free(BT); free(Ph); free(Pq); free(sx); free(scale);
            snprintf(msg, msglen, "out of memory");
            goto done;
        }
        /* scaled coordinates x' = (q, q'/sc, f): A' = [[0, Sc], [-w2/Sc, -Sc^-1 Cm Sc]], B' = [0; Sc^-1 Fm];
         * the filter rows f' = Fx x + Fu u in the same coordinates, the filter states scaled by sf below */
        for (int i = 0; i < k; i++) { sx[i] = 1.0; sx[k + i] = scale[i]; }
        for (int i = 0; i < k; i++) {
            AT[i * nx + k + i] = scale[i] * T;
            AT[(k + i) * nx + i] = -out->w2[i] / scale[i] * T;
            for (int j = 0; j < k; j++) AT[(k + i) * nx + k + j] = -out->Cm[i * k + j] * scale[j] / scale[i] * T;
            for (int j = 0; j < m; j++) BT[(k + i) * m + j] = out->Fm[i * m + j] / scale[i] * T;
        }
        /* a filter's states scaled by sf (one factor per filter, its own dynamics unchanged) so that its drive
         * by the modal states is of order 1: an acceleration's row carries w2, and left unscaled it would
         * dominate the exponential's norm and swamp the beam's entries with its round-off */
        for (int f = 0; f < nf; f++) sx[2 * k + f] = 1.0;
        for (int o = 0, at = 2 * k; o < np; o++) {
            const int n = s->sens_aa_order[o];
            if (n <= 0) continue;
            double big = 1.0;
            for (int f = at; f < at + n; f++)
                for (int c = 0; c < 2 * k; c++)
                    big = fmax(big, fabs(out->Fx[(size_t)(f - 2 * k) * nx + c] * sx[c] * T));
            for (int f = at; f < at + n; f++) sx[f] = big;
            at += n;
        }
        for (int f = 2 * k; f < nx; f++) {
            for (int c = 0; c < nx; c++)
                AT[f * nx + c] = out->Fx[(size_t)(f - 2 * k) * nx + c] * sx[c] / sx[f] * T;
            for (int j = 0; j < m; j++) BT[f * m + j] = out->Fu[(size_t)(f - 2 * k) * m + j] / sx[f] * T;
        }
        double bmax = 0.0;                             /* input block scaled to 1 (see the per-mode case) */
        for (size_t e = 0; e < (size_t)nx * m; e++) bmax = fmax(bmax, fabs(BT[e]));
        const double beta = bmax > 0.0 ? bmax : 1.0;
        for (size_t e = 0; e < (size_t)nx * m; e++) BT[e] /= beta;
        if (van_loan(AT, BT, nx, m, deg, Ph, Pq) != 0) {
            free(AT); free(BT); free(Ph); free(Pq); free(sx); free(scale);
            snprintf(msg, msglen, "the matrix exponential of the modal system is not finite");
            goto done;
        }
        for (int r = 0; r < nx; r++) {                 /* back from the scaled coordinates */
            const double sr = sx[r];
            for (int c = 0; c < nx; c++) {
                const double sc = sx[c];
                out->Phi[r * nx + c] = Ph[r * nx + c] * sr / sc;
            }
            for (int q = 0; q <= deg; q++)
                for (int j = 0; j < m; j++) Pq[((size_t)q * nx + r) * m + j] *= sr * beta;
        }
        for (int t = 0; t < nt; t++) {
            double *dst = taps[t] == 1 ? out->H : out->Q + (size_t)(-taps[t]) * nx * m;
            for (int q = 0; q <= deg; q++)
                for (size_t e = 0; e < (size_t)nx * m; e++) dst[e] += coef[t][q] * Pq[(size_t)q * nx * m + e];
        }
        for (int r = 0; r < nx; r++)                   /* Q_0 += Phi H */
            for (int j = 0; j < m; j++) {
                double acc = 0.0;
                for (int c = 0; c < nx; c++) acc += out->Phi[r * nx + c] * out->H[c * m + j];
                out->Q[r * m + j] += acc;
            }
        free(AT); free(BT); free(Ph); free(Pq); free(sx);
    }
    free(scale);
    /* outputs on xi: y = Cc (xi + Hfull u) + Dc u */
    out->Cy = malloc(sizeof(double) * ((size_t)np * nx + 1));
    out->Dy = malloc(sizeof(double) * ((size_t)np * m + 1));
    work = calloc((size_t)nx * m + 1, sizeof(double));  /* Hfull (nx x m) */
    out->nominal = malloc(sizeof(double) * (size_t)nx);
    if (!out->Cy || !out->Dy || !work || !out->nominal) { snprintf(msg, msglen, "out of memory"); goto done; }
    if (out->dense) memcpy(work, out->H, sizeof(double) * (size_t)nx * m);
    else for (int i = 0; i < k; i++)
        for (int j = 0; j < m; j++) {
            work[i * m + j] = out->H[i * 2] * out->Fm[i * m + j];
            work[(k + i) * m + j] = out->H[i * 2 + 1] * out->Fm[i * m + j];
        }
    memcpy(out->Cy, out->Cc, sizeof(double) * (size_t)np * nx);
    for (int o = 0; o < np; o++)
        for (int j = 0; j < m; j++) {
            double acc = out->Dc[o * m + j];
            for (int r = 0; r < nx; r++) acc += out->Cc[o * nx + r] * work[r * m + j];
            out->Dy[o * m + j] = acc;
        }
    /* model-exchange nominals: each mode's static response to a unit force (floored at 1e-3 of the largest);
     * a filter's states: its sensor's output scale from those (filter_nominals) */
    double qmax = 0.0, vmax = 0.0;
    for (int i = 0; i < k; i++) {
        double f = 0.0;
        for (int j = 0; j < m; j++) f = fmax(f, fabs(out->Fm[i * m + j]));
        const double w = sqrt(fabs(out->w2[i]));
        out->nominal[i] = f / fmax(w * w, 1.0);
        out->nominal[k + i] = f / fmax(w, 1.0);
        qmax = fmax(qmax, out->nominal[i]);
        vmax = fmax(vmax, out->nominal[k + i]);
    }
    for (int i = 0; i < k; i++) {
        out->nominal[i] = qmax > 0.0 ? fmax(out->nominal[i], 1e-3 * qmax) : 1.0;
        out->nominal[k + i] = vmax > 0.0 ? fmax(out->nominal[k + i], 1e-3 * vmax) : 1.0;
    }
    filter_nominals(s, out);
    if (!(out->spectral_radius <= 1.0 + 1e-9)) {
        if (p[EBB_N] < 0.0)
            snprintf(msg, msglen, "unstable model (spectral radius %.9g > 1): N = %g N is beyond the buckling "
                     "load of the discretised beam", out->spectral_radius, p[EBB_N]);
        else
            snprintf(msg, msglen, "unstable model (spectral radius %.9g > 1) for EI = %g, N = %g",
                     out->spectral_radius, p[EBB_EI], p[EBB_N]);
        goto done;
    }
    for (size_t i = 0; i < (size_t)np * nx; i++)
        if (!isfinite(out->Cy[i])) { snprintf(msg, msglen, "the output matrix is not finite"); goto done; }
    rc = 0;
done:
    fd_free(&a); fd_free(&b);
    free(psi); free(psic); free(w2c); free(Cd); free(work);
    if (rc != 0) ebb_model_free(out);
    return rc;
}

/* ---------------------------------------------------------------------------------------------------------
 * The seed's theta-scheme ([time] scheme = "theta"), port of ebb_model/theta/theta_scheme.py on the config's grid:
 * L' = M/tau + C/2 + theta tau K, Kt = L'^-1 K, Ct = L'^-1 C, Bt = L'^-1 F (tau = dt/substeps); one sub-step
 * on x = (q^j, v^{j-1/2}):  v+ = (I - Ct) v - Kt q + Bt f,  q+ = q + tau v+;  per sample Phi = S^m and the
 * hold sums G0, G1 of the force at the sub-step levels (straight line or held), made causal on xi = x - G1 u;
 * outputs from the scheme's own central differences.  Stability: the spectral radius of each undamped mode's
 * sub-step block with its modal damping (exact for proportional damping), from the Jacobi eigen-solution.
 * Model exchange: the nodal semi-discrete system q'' = M^-1 (F u - C q' - K q).
 * --------------------------------------------------------------------------------------------------------- */
static void matmul_rect(const double *a, const double *b, double *c, int n, int kk, int m)
{
    memset(c, 0, sizeof(double) * (size_t)n * m);
    for (int i = 0; i < n; i++)
        for (int l = 0; l < kk; l++) {
            const double v = a[i * kk + l];
            if (v == 0.0) continue;
            for (int j = 0; j < m; j++) c[i * m + j] += v * b[l * m + j];
        }
}

static double block_radius(double a, double b, double c, double d)
{
    const double tr = a + d, det = a * d - b * c, disc = tr * tr / 4.0 - det;
    if (disc >= 0.0) return fmax(fabs(tr / 2.0 + sqrt(disc)), fabs(tr / 2.0 - sqrt(disc)));
    return sqrt(det);
}

static int build_theta(const ebb_structure *s, const double *p, ebb_model *out, char *msg, size_t msglen)
{
    fd_beam b = {0};
    int rc = -1;
    double *L = NULL, *R = NULL, *S = NULL, *G = NULL, *G0 = NULL, *G1 = NULL, *T1 = NULL, *T2 = NULL;
    double *psi = NULL, *w2 = NULL;
    if (fd_assemble(s, s->nodes, p, &b) != 0) { snprintf(msg, msglen, "out of memory"); goto done; }
    const int n = b.nu, m = s->n_act, np = s->n_sens, nx = 2 * n, ms = s->substeps, nr = 2 * n + m;
    const double tau = s->dt / ms, th = s->theta;
    out->k = n; out->m = m; out->p = np; out->dense = 1; out->delays = 0; out->nx = nx; out->nf = 0;
    L = malloc(sizeof(double) * (size_t)n * n);
    R = malloc(sizeof(double) * (size_t)n * nr);
    S = calloc((size_t)nx * nx, sizeof(double));
    G = calloc((size_t)nx * m, sizeof(double));
    G0 = malloc(sizeof(double) * (size_t)nx * m);
    G1 = calloc((size_t)nx * m, sizeof(double));
    T1 = malloc(sizeof(double) * (size_t)nx * nx);
    T2 = malloc(sizeof(double) * (size_t)nx * nx);
    psi = malloc(sizeof(double) * (size_t)n * n);
    w2 = malloc(sizeof(double) * (size_t)n);
    out->Phi = malloc(sizeof(double) * (size_t)nx * nx);
    out->Q = malloc(sizeof(double) * (size_t)nx * m);
    out->H = G1;
    G1 = NULL;
    out->Cy = calloc((size_t)np * nx, sizeof(double));
    out->Dy = calloc((size_t)np * m, sizeof(double));
    out->Cc = calloc((size_t)np * nx, sizeof(double));
    out->Dc = calloc((size_t)np * m, sizeof(double));
    out->Kd = malloc(sizeof(double) * (size_t)n * n);
    out->Cm = malloc(sizeof(double) * (size_t)n * n);
    out->Fm = malloc(sizeof(double) * (size_t)n * m);
    out->nominal = malloc(sizeof(double) * (size_t)nx);
    if (!L || !R || !S || !G || !G0 || !T1 || !T2 || !psi || !w2 || !out->Phi || !out->Q || !out->H || !out->Cy ||
        !out->Dy || !out->Cc || !out->Dc || !out->Kd || !out->Cm || !out->Fm || !out->nominal) {
        snprintf(msg, msglen, "out of memory");
        goto done;
    }
    /* Kt, Ct, Bt */
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) {
            L[i * n + j] = b.M[i * n + j] / tau + b.C[i * n + j] / 2 + (th * tau) * b.K[i * n + j];
            R[i * nr + j] = b.K[i * n + j];
            R[i * nr + n + j] = b.C[i * n + j];
        }
        for (int a = 0; a < m; a++) R[i * nr + 2 * n + a] = b.F[i * m + a];
    }
    if (ebb_lu_solve(L, R, n, nr) != 0) {
        snprintf(msg, msglen, "the implicit matrix M/tau + C/2 + theta tau K is singular (theta = %g)", th);
        goto done;
    }
    /* one sub-step S and G; Kt = R[:, :n], Ct = R[:, n:2n], Bt = R[:, 2n:] */
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) {
            const double kt = R[i * nr + j], ct = R[i * nr + n + j], eye = i == j ? 1.0 : 0.0;
            S[i * nx + j] = eye - tau * kt;
            S[i * nx + n + j] = tau * (eye - ct);
            S[(n + i) * nx + j] = -kt;
            S[(n + i) * nx + n + j] = eye - ct;
        }
        for (int a = 0; a < m; a++) {
            G[i * m + a] = tau * R[i * nr + 2 * n + a];
            G[(n + i) * m + a] = R[i * nr + 2 * n + a];
        }
    }
    /* hold sums: Phi = S^m, G0 = sum (1 - w_i) S^(m-1-i) G, G1 = sum w_i S^(m-1-i) G */
    memcpy(out->Phi, S, sizeof(double) * (size_t)nx * nx);
    memcpy(G0, G, sizeof(double) * (size_t)nx * m);
    for (int i = 1; i < ms; i++) {
        const double w = s->hold == EBB_FOH ? (double)i / ms : 0.0;
        matmul_rect(S, G0, T1, nx, nx, m);
        for (int e = 0; e < nx * m; e++) G0[e] = T1[e] + (1.0 - w) * G[e];
        matmul_rect(S, out->H, T1, nx, nx, m);
        for (int e = 0; e < nx * m; e++) out->H[e] = T1[e] + w * G[e];
        matmul_rect(S, out->Phi, T2, nx, nx, nx);
        memcpy(out->Phi, T2, sizeof(double) * (size_t)nx * nx);
    }
    /* outputs on (q, v): displacement P q; velocity P (v+ + v-)/2; acceleration P (v+ - v-)/tau */
    for (int o = 0; o < np; o++) {
        const double *P = b.S + (size_t)o * n;
        double *Crow = out->Cy + (size_t)o * nx, *Drow = out->Dy + (size_t)o * m;
        const int kind = s->sens_kind[o];
        for (int j = 0; j < n; j++) {
            double pk = 0.0, pc = 0.0;
            for (int r = 0; r < n; r++) { pk += P[r] * R[r * nr + j]; pc += P[r] * R[r * nr + n + j]; }
            if (kind == EBB_DISPLACEMENT) Crow[j] = P[j];
            else if (kind == EBB_VELOCITY) { Crow[j] = -pk / 2; Crow[n + j] = P[j] - pc / 2; }
            else { Crow[j] = -pk / tau; Crow[n + j] = -pc / tau; }
        }
        for (int a = 0; a < m; a++) {
            double pb = 0.0;
            for (int r = 0; r < n; r++) pb += P[r] * R[r * nr + 2 * n + a];
            if (kind == EBB_VELOCITY) Drow[a] = pb / 2;
            else if (kind == EBB_ACCELERATION) Drow[a] = pb / tau;
        }
    }
    /* causal realisation: Q0 = G0 + Phi G1, Dy += Cy G1 */
    matmul_rect(out->Phi, out->H, T1, nx, nx, m);
    for (int e = 0; e < nx * m; e++) out->Q[e] = G0[e] + T1[e];
    matmul_rect(out->Cy, out->H, T1, np, nx, m);
    for (int e = 0; e < np * m; e++) out->Dy[e] += T1[e];
    /* model exchange: M^-1 [K C F] */
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) {
            L[i * n + j] = b.M[i * n + j];
            R[i * nr + j] = b.K[i * n + j];
            R[i * nr + n + j] = b.C[i * n + j];
        }
        for (int a = 0; a < m; a++) R[i * nr + 2 * n + a] = b.F[i * m + a];
    }
    if (ebb_lu_solve(L, R, n, nr) != 0) { snprintf(msg, msglen, "the mass matrix is singular"); goto done; }
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) {
            out->Kd[i * n + j] = R[i * nr + j];
            out->Cm[i * n + j] = R[i * nr + n + j];
        }
        for (int a = 0; a < m; a++) out->Fm[i * m + a] = R[i * nr + 2 * n + a];
    }
    for (int o = 0; o < np; o++) {
        const double *P = b.S + (size_t)o * n;
        double *Crow = out->Cc + (size_t)o * nx;
        for (int j = 0; j < n; j++) {
            if (s->sens_kind[o] == EBB_DISPLACEMENT) Crow[j] = P[j];
            else if (s->sens_kind[o] == EBB_VELOCITY) Crow[n + j] = P[j];
            else {
                for (int r = 0; r < n; r++) {
                    Crow[j] -= P[r] * out->Kd[r * n + j];
                    Crow[n + j] -= P[r] * out->Cm[r * n + j];
                }
            }
        }
        if (s->sens_kind[o] == EBB_ACCELERATION)
            for (int a = 0; a < m; a++)
                for (int r = 0; r < n; r++) out->Dc[o * m + a] += P[r] * out->Fm[r * m + a];
    }
    /* stability and nominals from the undamped modes of the grid */
    if (lowest_modes(&b, n, w2, psi) != 0) {
        snprintf(msg, msglen, "the eigenvalue problem of the beam failed: check rhoA, rhoI and the point masses");
        goto done;
    }
    double radius = 0.0, qn = 0.0, vn = 0.0, w2max = 0.0;
    for (int i = 0; i < n; i++) {
        double d = 0.0, f = 0.0, amp = 0.0;
        for (int r = 0; r < n; r++) {
            double cr = 0.0;
            for (int c = 0; c < n; c++) cr += b.C[r * n + c] * psi[c * n + i];
            d += psi[r * n + i] * cr;
            amp = fmax(amp, fabs(psi[r * n + i]));
        }
        for (int a = 0; a < m; a++) {
            double fa = 0.0;
            for (int r = 0; r < n; r++) fa += psi[r * n + i] * b.F[r * m + a];
            f = fmax(f, fabs(fa));
        }
        const double ell = 1.0 / tau + d / 2 + th * tau * w2[i], kt = w2[i] / ell, ct = d / ell;
        const double r1 = pow(block_radius(1.0 - tau * kt, tau * (1.0 - ct), -kt, 1.0 - ct), ms);
        radius = fmax(radius, isfinite(r1) ? r1 : INFINITY);
        qn = fmax(qn, f * amp / fmax(fabs(w2[i]), 1.0));
        vn = fmax(vn, f * amp / fmax(sqrt(fabs(w2[i])), 1.0));
        w2max = fmax(w2max, w2[i]);
    }
    for (int i = 0; i < n; i++) {
        out->nominal[i] = qn > 0.0 ? qn : 1.0;
        out->nominal[n + i] = vn > 0.0 ? vn : 1.0;
    }
    out->spectral_radius = radius;
    if (!(radius <= 1.0 + 1e-9)) {
        if (p[EBB_N] < 0.0 && w2[0] < 0.0)
            snprintf(msg, msglen, "unstable theta-scheme (spectral radius %.9g > 1): N = %g N is beyond the buckling "
                     "load of the discretised beam", radius, p[EBB_N]);
        else if (th < 0.25)
            snprintf(msg, msglen, "unstable theta-scheme (spectral radius %.9g > 1): theta = %g < 1/4 needs "
                     "tau^2 w2max (1 - 4 theta) <= 4, and EI = %g, rhoA = %g, N = %g give w2max = %.6g at tau = %g",
                     radius, th, p[EBB_EI], p[EBB_RHOA], p[EBB_N], w2max, tau);
        else
            snprintf(msg, msglen, "unstable theta-scheme (spectral radius %.9g > 1) for EI = %g, N = %g", radius,
                     p[EBB_EI], p[EBB_N]);
        goto done;
    }
    for (int e = 0; e < np * nx; e++)
        if (!isfinite(out->Cy[e])) { snprintf(msg, msglen, "the output matrix is not finite"); goto done; }
    rc = 0;
done:
    fd_free(&b);
    free(L); free(R); free(S); free(G); free(G0); free(G1); free(T1); free(T2); free(psi); free(w2);
    if (rc != 0) ebb_model_free(out);
    return rc;
}
