/*
 * ebb_fd.c -- the finite-difference beam of the standalone FMU's model (ebb_beam.h) and its lowest modes.
 *
 * Space: central finite differences with ghost nodes (port of ebb_model/space/discretisation.py): on a grid of
 *    n interior points, spacing h = L/(n+1), the semi-discrete beam M q'' + C q' + K q = F u with
 *      K = diag(V)(EI D4 - N D2)E + kf diag(V) + sum_s k_s phi(a_s) phi(a_s)^T,  C = c diag(V) + eta EI diag(V) D4 E,
 *      M = rhoA diag(V) + rhoI h (GP)^T(GP) + sum_m m_m phi(a_m) phi(a_m)^T,
 *    E the extension by the ghost nodes of the moment and shear conditions (elastic ends kt, kr in [0, inf]),
 *    forces, sensors, point masses and springs to ground on the grid's hat functions; with weak segments the
 *    bending term is D2 (e D2 w) with e the cells' compliance-averaged relative EI (ghost nodes: their end's)
 *    (ebb_fd_assemble).
 * Modes: the lowest w2 and mass-normalised shapes of K psi = w2 M psi (ebb_fd_lowest_modes).  The eigenproblems: with
 *    K positive definite the inverted problem M psi = mu K psi (each w2 to a few eps relatively, as ebb_model
 *    does), else K psi = w2 M psi; both reduced by Cholesky and solved by cyclic Jacobi (ebb_linalg.c).
 * Used by ebb_model.c (scheme "exact": the config's grid and its companion) and ebb_theta.c (scheme "theta").
 */
#include "ebb_beam.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

void ebb_fd_free(fd_beam *b)
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

int ebb_fd_assemble(const ebb_structure *s, int n, const double *p, fd_beam *b)
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
int ebb_fd_lowest_modes(const fd_beam *b, int nm, double *w2, double *psi)
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
