/*
 * modal_recursion.c -- the modal recursion of ebb_model.simulate, compiled for one input, tap and output count.
 *
 *   z[k+1]_b = T_b z[k]_b + sum_i G_{b,i} u_i[k],   y[k]_o = sum_b C_{o,b} z[k]_b + sum_i D_{o,i} u_i[k]
 *
 * for nb 2x2 real blocks b, NI = M * TAPS input columns i = j M + l (input l at sample k - j, u[-j] = u[0]; the
 * cubic's taps are j = 0, 1, 2) and NO outputs.  M, TAPS and NO are compile-time constants (-DM=... on the
 * compiler's command line): the loops over inputs and outputs have known trip counts and are unrolled.  The first
 * nb1 blocks read u[k] only -- the caller has moved their past samples' share into the outputs' feedthrough
 * (ebb_model.exact.recursion) and their other columns are not read --, the other nb - nb1 blocks every column.
 *
 * Layout: each group's blocks are regrouped in tiles of VL lanes (-DVL=4 or 8: the faster on the machine is
 * chosen when the library is built), each tile's coefficients and states contiguous and 64-byte aligned, a group's
 * last tile padded with zero blocks (a zero block has T = G = C = 0: its state stays zero and adds nothing).  One
 * pass over the tiles per sample reads a block's state once for the outputs and the update; the lanes are one
 * SIMD loop.
 *
 * The sums are re-associated (compiled with -fassociative-math, as numba's fastmath kernel): outputs agree
 * with the strict order to ~1e-15 relative.  No finite-math assumption: a diverging run still shows inf/nan.
 */
#include <stdlib.h>

#define NI (M * TAPS)

#define TILE(name, COLS)                              \
    typedef struct {                                  \
        double t00[VL], t01[VL], t10[VL], t11[VL];    \
        double g0[COLS][VL], g1[COLS][VL];            \
        double c0[NO][VL], c1[NO][VL];                \
        double z0[VL], z1[VL];                        \
    } name

TILE(tile1, M);     /* a block reading u[k] only */
TILE(tilen, NI);    /* a block reading every column */

/* the outputs' share of one tile's states (into acc), then the tile's update */
#define STEP(p, COLS)                                                                       \
    _Pragma("omp simd") for (int l = 0; l < VL; ++l) {                                      \
        double a = (p)->z0[l], c = (p)->z1[l];                                              \
        for (int o = 0; o < NO; ++o) acc[o][l] += (p)->c0[o][l] * a + (p)->c1[o][l] * c;    \
        double v0 = (p)->t00[l] * a + (p)->t01[l] * c;                                      \
        double v1 = (p)->t10[l] * a + (p)->t11[l] * c;                                      \
        for (int i = 0; i < (COLS); ++i) {                                                  \
            v0 += (p)->g0[i][l] * uk[i];                                                    \
            v1 += (p)->g1[i][l] * uk[i];                                                    \
        }                                                                                   \
        (p)->z0[l] = v0;                                                                    \
        (p)->z1[l] = v1;                                                                    \
    }

/* one sample: y[k] from z[k] and the input columns uk, then z[k+1] */
static inline void sample(tile1 *restrict w1, int nt1, tilen *restrict wn, int ntn, const double *restrict D,
                          const double *restrict uk, double *restrict yk)
{
    double acc[NO][VL];
    for (int o = 0; o < NO; ++o)
        for (int l = 0; l < VL; ++l) acc[o][l] = 0.0;
    for (int q = 0; q < nt1; ++q) {
        tile1 *restrict p = w1 + q;
        STEP(p, M)
    }
    for (int q = 0; q < ntn; ++q) {
        tilen *restrict p = wn + q;
        STEP(p, NI)
    }
    for (int o = 0; o < NO; ++o) {
        double s = 0.0;
        for (int l = 0; l < VL; ++l) s += acc[o][l];
        for (int i = 0; i < NI; ++i) s += D[o * NI + i] * uk[i];
        yk[o] = s;
    }
}

/* block b (of nb) of the caller's arrays into lane l of tile p, with the first `cols` of its input columns */
#define SCATTER(p, l, b, cols)                                  \
    do {                                                        \
        (p)->t00[l] = T[4 * (b)];                               \
        (p)->t01[l] = T[4 * (b) + 1];                           \
        (p)->t10[l] = T[4 * (b) + 2];                           \
        (p)->t11[l] = T[4 * (b) + 3];                           \
        for (int i = 0; i < (cols); ++i) {                      \
            (p)->g0[i][l] = G[(2 * (b)) * NI + i];              \
            (p)->g1[i][l] = G[(2 * (b) + 1) * NI + i];          \
        }                                                       \
        for (int o = 0; o < NO; ++o) {                          \
            (p)->c0[o][l] = C[(o * nb + (b)) * 2];              \
            (p)->c1[o][l] = C[(o * nb + (b)) * 2 + 1];          \
        }                                                       \
        (p)->z0[l] = z[2 * (b)];                                \
        (p)->z1[l] = z[2 * (b) + 1];                            \
    } while (0)

/*
 * Run ns samples from the block state z.  Row-major arrays: T (nb x 2 x 2), G (nb x 2 x NI), C (NO x nb x 2),
 * D (NO x NI), u (ns x M), y (ns x NO, written), z (nb x 2); the first nb1 blocks read u[k] only.
 * Returns 0, or -1 when the work space cannot be allocated (nothing written to y then).
 */
int modal_recursion(const double *restrict T, const double *restrict G, const double *restrict C,
                    const double *restrict D, const double *restrict u, double *restrict y,
                    const double *restrict z, long ns, int nb1, int nb)
{
    int nt1 = (nb1 + VL - 1) / VL, ntn = (nb - nb1 + VL - 1) / VL;
    tile1 *w1 = aligned_alloc(64, (nt1 > 0 ? nt1 : 1) * sizeof(tile1));
    tilen *wn = aligned_alloc(64, (ntn > 0 ? ntn : 1) * sizeof(tilen));
    if (!w1 || !wn) {
        free(w1);
        free(wn);
        return -1;
    }
    for (int q = 0; q < nt1; ++q) w1[q] = (tile1){0};      /* the padding: zero blocks */
    for (int q = 0; q < ntn; ++q) wn[q] = (tilen){0};
    for (int b = 0; b < nb1; ++b) SCATTER(w1 + b / VL, b % VL, b, M);
    for (int b = nb1; b < nb; ++b) SCATTER(wn + (b - nb1) / VL, (b - nb1) % VL, b, NI);
    double uk[NI];
    long head = ns < TAPS - 1 ? ns : TAPS - 1;     /* samples whose taps reach before the record: u[-j] = u[0] */
    for (long k = 0; k < head; ++k) {
        for (int j = 0; j < TAPS; ++j)
            for (int l = 0; l < M; ++l) uk[j * M + l] = u[(k < j ? 0 : k - j) * M + l];
        sample(w1, nt1, wn, ntn, D, uk, y + k * NO);
    }
    for (long k = head; k < ns; ++k) {
        for (int j = 0; j < TAPS; ++j)
            for (int l = 0; l < M; ++l) uk[j * M + l] = u[(k - j) * M + l];
        sample(w1, nt1, wn, ntn, D, uk, y + k * NO);
    }
    free(w1);
    free(wn);
    return 0;
}
