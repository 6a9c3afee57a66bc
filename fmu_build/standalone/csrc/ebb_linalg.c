/*
 * ebb_linalg.c -- the dense linear algebra of the standalone beam FMU (no LAPACK), textbook algorithms:
 *
 *   ebb_cholesky      Cholesky factorisation A = L L^T (Golub & Van Loan, Alg. 4.2.1, outer form); a pivot below
 *                     1e-11 of its diagonal entry counts as failure: a stiffness matrix with rigid-body modes
 *                     (free-free beam) is singular, and round-off may leave a tiny positive pivot that would
 *                     make the inverted eigenproblem meaningless (positive definite grids stay above 3e-9 up
 *                     to 1000 nodes);
 *   ebb_congruence    L^-1 A L^-T by two triangular solves (reduction of K psi = w2 M psi to standard form);
 *   ebb_jacobi        cyclic Jacobi eigenvalue iteration for symmetric matrices (Golub & Van Loan, Sec. 8.5),
 *                     rotation angle from the smaller root of t^2 + 2 theta t - 1 = 0; a rotation is skipped
 *                     once |a_pq| <= 1e-18 sqrt(|a_pp a_qq|) (converged to full relative precision);
 *   ebb_expm          matrix exponential by scaling and squaring with the diagonal [6/6] Pade approximant
 *                     (Golub & Van Loan, Alg. 9.3.1: ||A/2^s||_inf <= 1/2 keeps the approximant's relative
 *                     error below 3.4e-16), the Pade system solved by LU with partial pivoting;
 *   ebb_lu_solve      Gaussian elimination with partial pivoting, several right-hand sides.
 *
 * Matrices are row-major double arrays.  Nothing here allocates except ebb_expm's workspace (malloc).
 */
#include "ebb_beam.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int ebb_cholesky(double *a, int n)
{
    for (int j = 0; j < n; j++) {
        const double diag = a[j * n + j];
        double d = diag;
        for (int k = 0; k < j; k++) d -= a[j * n + k] * a[j * n + k];
        if (!(d > 1e-11 * diag)) return -1;            /* not (numerically) positive definite */
        d = sqrt(d);
        a[j * n + j] = d;
        for (int i = j + 1; i < n; i++) {
            double s = a[i * n + j];
            for (int k = 0; k < j; k++) s -= a[i * n + k] * a[j * n + k];
            a[i * n + j] = s / d;
        }
        for (int i = 0; i < j; i++) a[i * n + j] = 0.0;   /* keep only L */
    }
    return 0;
}

/* x <- L^-1 x for every column of x (n x ncol) */
static void forward_solve(const double *L, double *x, int n, int ncol)
{
    for (int i = 0; i < n; i++) {
        double *xi = x + (size_t)i * ncol;
        for (int k = 0; k < i; k++) {
            const double l = L[i * n + k];
            if (l == 0.0) continue;
            const double *xk = x + (size_t)k * ncol;
            for (int c = 0; c < ncol; c++) xi[c] -= l * xk[c];
        }
        const double d = L[i * n + i];
        for (int c = 0; c < ncol; c++) xi[c] /= d;
    }
}

void ebb_back_transform(const double *L, double *v, int n, int ncol)
{
    for (int i = n - 1; i >= 0; i--) {
        double *vi = v + (size_t)i * ncol;
        for (int k = i + 1; k < n; k++) {
            const double l = L[k * n + i];             /* (L^T)_{ik} */
            if (l == 0.0) continue;
            const double *vk = v + (size_t)k * ncol;
            for (int c = 0; c < ncol; c++) vi[c] -= l * vk[c];
        }
        const double d = L[i * n + i];
        for (int c = 0; c < ncol; c++) vi[c] /= d;
    }
}

void ebb_congruence(const double *L, const double *a, double *out, int n)
{
    double *x = malloc(sizeof(double) * (size_t)n * n);
    memcpy(x, a, sizeof(double) * (size_t)n * n);
    forward_solve(L, x, n, n);                         /* X = L^-1 A */
    for (int i = 0; i < n; i++)                        /* out = X^T */
        for (int j = 0; j < n; j++) out[i * n + j] = x[j * n + i];
    forward_solve(L, out, n, n);                       /* L^-1 (L^-1 A)^T = L^-1 A L^-T */
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++) {
            const double s = 0.5 * (out[i * n + j] + out[j * n + i]);
            out[i * n + j] = out[j * n + i] = s;
        }
    free(x);
}

int ebb_jacobi(double *a, double *v, double *w, int n)
{
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) v[i * n + j] = (i == j) ? 1.0 : 0.0;
    int converged = 0;
    for (int sweep = 0; sweep < 100 && !converged; sweep++) {
        converged = 1;
        for (int p = 0; p < n - 1; p++) {
            for (int q = p + 1; q < n; q++) {
                const double apq = a[p * n + q];
                const double app = a[p * n + p], aqq = a[q * n + q];
                if (apq == 0.0) continue;
                if (fabs(apq) <= 1e-18 * sqrt(fabs(app * aqq)) || fabs(apq) < 1e-300) {
                    a[p * n + q] = a[q * n + p] = 0.0;
                    continue;
                }
                converged = 0;
                const double theta = (aqq - app) / (2.0 * apq);
                double t;
                if (fabs(theta) > 1e150) t = 0.5 / theta;
                else t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                const double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < n; k++) {            /* A J: columns p, q */
                    const double akp = a[k * n + p], akq = a[k * n + q];
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for (int k = 0; k < n; k++) {            /* J^T (A J): rows p, q */
                    const double apk = a[p * n + k], aqk = a[q * n + k];
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
                a[p * n + q] = a[q * n + p] = 0.0;
                for (int k = 0; k < n; k++) {            /* V J */
                    const double vkp = v[k * n + p], vkq = v[k * n + q];
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    for (int i = 0; i < n; i++) w[i] = a[i * n + i];
    return converged ? 0 : -1;
}

static void matmul(const double *a, const double *b, double *c, int n)
{
    memset(c, 0, sizeof(double) * (size_t)n * n);
    for (int i = 0; i < n; i++)
        for (int k = 0; k < n; k++) {
            const double aik = a[i * n + k];
            if (aik == 0.0) continue;
            const double *bk = b + (size_t)k * n;
            double *ci = c + (size_t)i * n;
            for (int j = 0; j < n; j++) ci[j] += aik * bk[j];
        }
}

/* solve d x = b (d n x n, b n x ncol, both overwritten; x in b), LU with partial pivoting; -1 if singular */
int ebb_lu_solve(double *d, double *b, int n, int ncol)
{
    for (int col = 0; col < n; col++) {
        int piv = col;
        for (int i = col + 1; i < n; i++)
            if (fabs(d[i * n + col]) > fabs(d[piv * n + col])) piv = i;
        if (d[piv * n + col] == 0.0 || !isfinite(d[piv * n + col])) return -1;
        if (piv != col) {
            for (int j = 0; j < n; j++) {
                const double t = d[col * n + j]; d[col * n + j] = d[piv * n + j]; d[piv * n + j] = t;
            }
            for (int j = 0; j < ncol; j++) {
                const double t = b[col * ncol + j]; b[col * ncol + j] = b[piv * ncol + j]; b[piv * ncol + j] = t;
            }
        }
        const double inv = 1.0 / d[col * n + col];
        for (int i = col + 1; i < n; i++) {
            const double f = d[i * n + col] * inv;
            if (f == 0.0) continue;
            for (int j = col; j < n; j++) d[i * n + j] -= f * d[col * n + j];
            for (int j = 0; j < ncol; j++) b[i * ncol + j] -= f * b[col * ncol + j];
        }
    }
    for (int i = n - 1; i >= 0; i--) {
        for (int k = i + 1; k < n; k++) {
            const double f = d[i * n + k];
            if (f == 0.0) continue;
            for (int j = 0; j < ncol; j++) b[i * ncol + j] -= f * b[k * ncol + j];
        }
        const double inv = 1.0 / d[i * n + i];
        for (int j = 0; j < ncol; j++) b[i * ncol + j] *= inv;
    }
    return 0;
}

int ebb_expm(const double *a, double *e, int n)
{
    const int q = 6;
    double norm = 0.0;
    for (int i = 0; i < n; i++) {
        double r = 0.0;
        for (int j = 0; j < n; j++) r += fabs(a[i * n + j]);
        if (r > norm) norm = r;
    }
    if (!isfinite(norm)) return -1;
    int s = 0;
    if (norm > 0.5) s = (int)ceil(log2(norm / 0.5));
    if (s > 1000) return -1;
    const double scale = ldexp(1.0, -s);
    const size_t nn = (size_t)n * n;
    double *x = malloc(sizeof(double) * nn), *ax = malloc(sizeof(double) * nn);
    double *num = malloc(sizeof(double) * nn), *den = malloc(sizeof(double) * nn), *tmp = malloc(sizeof(double) * nn);
    for (size_t i = 0; i < nn; i++) ax[i] = a[i] * scale;
    memcpy(x, ax, sizeof(double) * nn);
    memset(num, 0, sizeof(double) * nn);
    memset(den, 0, sizeof(double) * nn);
    for (int i = 0; i < n; i++) num[i * n + i] = den[i * n + i] = 1.0;
    double c = 1.0;
    int sign = 1;
    for (int j = 1; j <= q; j++) {
        c = c * (double)(q - j + 1) / (double)(j * (2 * q - j + 1));
        if (j > 1) {                                     /* x = ax^j */
            matmul(ax, x, tmp, n);
            memcpy(x, tmp, sizeof(double) * nn);
        }
        sign = -sign;
        for (size_t i = 0; i < nn; i++) {
            num[i] += c * x[i];
            den[i] += sign * c * x[i];
        }
    }
    int rc = ebb_lu_solve(den, num, n, n);               /* num <- den^-1 num */
    if (rc == 0) {
        for (int k = 0; k < s; k++) {
            matmul(num, num, tmp, n);
            memcpy(num, tmp, sizeof(double) * nn);
        }
        memcpy(e, num, sizeof(double) * nn);
        for (size_t i = 0; i < nn; i++)
            if (!isfinite(e[i])) { rc = -1; break; }
    }
    free(x); free(ax); free(num); free(den); free(tmp);
    return rc;
}
