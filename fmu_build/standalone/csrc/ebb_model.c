/*
 * ebb_model.c -- the beam model of ebb_model (scheme "exact"), assembled from the physical parameters.
 *
 * 1. Space: central finite differences with ghost nodes, the semi-discrete beam M q'' + C q' + K q = F u
 *    (ebb_fd_assemble, ebb_fd.c).
 * 2. Richardson modes (ebb_model/exact/exact_modal.py): the beam on the config's grid and on its companion grid
 *    (2n+1 nodes up to 201, else (n-1)/2); the lowest w2 of both, extrapolated as
 *    w2_f + weight (w2_f - w2_c)/((h_c/h_f)^2 - 1) (weight 1 for the lower half of the coarse grid's modes,
 *    fading to 0), mass-normalised shapes and damping from the finer grid; as many modes as the config's grid
 *    has unknowns (the eigenproblems: ebb_fd_lowest_modes, ebb_fd.c).
 * 3. Time, exact: the modal system q'' + Cm q' + w2 q = Fm u under the polynomial through the input samples
 *    (cubic through k-2..k+1, straight line, or held) integrated exactly over a sample by one matrix
 *    exponential of the system augmented with the chain of the polynomial's derivatives (Van Loan) -- per
 *    mode (2 + taps) when the damping is proportional (Psi^T C Psi diagonal to 1e-10), else for the whole
 *    modal system.  Each mode's coordinates are scaled by max(w, 1/dt) for the exponential (a diagonal
 *    similarity: exact, and it keeps the scaled matrix's norm near w dt).  The sample ahead is made causal by
 *    xi = x - H u (H the lookahead's weights), exactly as ebb_model's realisation.
 * The seed's theta-scheme (scheme "theta") is in ebb_theta.c (ebb_build_theta).
 */
#include "ebb_beam.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *PARAM_NAMES[EBB_NPARAM] = {"EI", "rhoA", "c", "eta", "N", "rhoI", "kf"};

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
    if (s->scheme == EBB_THETA) return ebb_build_theta(s, p, out, msg, msglen);
    const int n = s->nodes;
    const int n2 = (2 * n + 1 <= 201) ? 2 * n + 1 : (n - 1) / 2;
    fd_beam a = {0}, b = {0};
    double *psi = NULL, *psic = NULL, *w2c = NULL, *Cd = NULL, *work = NULL;
    int rc = -1;
    if (ebb_fd_assemble(s, n, p, &a) != 0 || ebb_fd_assemble(s, n2, p, &b) != 0) {
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
    if (ebb_fd_lowest_modes(fine, k, out->w2, psi) != 0 || ebb_fd_lowest_modes(coarse, mc, w2c, psic) != 0) {
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
    ebb_fd_free(&a); ebb_fd_free(&b);
    free(psi); free(psic); free(w2c); free(Cd); free(work);
    if (rc != 0) ebb_model_free(out);
    return rc;
}
