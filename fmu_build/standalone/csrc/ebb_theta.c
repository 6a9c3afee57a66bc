/*
 * ebb_theta.c -- the seed's theta-scheme of the standalone FMU's model (ebb_beam.h; scheme "theta"), built by
 * ebb_model_build (ebb_model.c) on the finite-difference beam of ebb_fd.c.
 */
#include "ebb_beam.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

int ebb_build_theta(const ebb_structure *s, const double *p, ebb_model *out, char *msg, size_t msglen)
{
    fd_beam b = {0};
    int rc = -1;
    double *L = NULL, *R = NULL, *S = NULL, *G = NULL, *G0 = NULL, *G1 = NULL, *T1 = NULL, *T2 = NULL;
    double *psi = NULL, *w2 = NULL;
    if (ebb_fd_assemble(s, s->nodes, p, &b) != 0) { snprintf(msg, msglen, "out of memory"); goto done; }
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
    if (ebb_fd_lowest_modes(&b, n, w2, psi) != 0) {
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
    ebb_fd_free(&b);
    free(L); free(R); free(S); free(G); free(G0); free(G1); free(T1); free(T2); free(psi); free(w2);
    if (rc != 0) ebb_model_free(out);
    return rc;
}
