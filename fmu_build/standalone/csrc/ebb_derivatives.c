/*
 * ebb_derivatives.c -- directional and adjoint derivatives of the standalone beam FMU (ebb_instance.h).
 *
 * Outputs and state derivatives are linear in (state, input) with the current parameters: the derivative in a
 * direction is the linear map applied to the direction itself -- the discrete realisation's rows Cy, Dy
 * (co-simulation: the outputs from the input at the current communication point; the state xi is not a
 * variable), the continuous ones Cc, Dc and the modal ODE (model exchange).  The adjoint is the transposed map,
 * applied one known element at a time (J^T seed = (e_j . J^T seed)_j = (seed . J e_j)_j): exact, and as cheap as
 * the sizes of an FMU's interface ask.  A delayed sensor's output sees the current input through its lag-0 tap only
 * (ebb_delay.c): its row is w_0 Dy, or 0 when its delay line has no lag 0.
 */
#include <stdlib.h>
#include <string.h>

#include "ebb_instance.h"

static int role_of(unsigned vr)
{
    return vr < EBB_NVARS && EBB_VAR_TYPE[vr] == TYPE_REAL ? EBB_VAR_ROLE[vr] : -1;
}

/* elements of the knowns (inputs; for model exchange also states), or -1 (logged) */
static long known_elements(ebb_instance *c, const char *function, const unsigned known[], size_t n_known)
{
    long n = 0;
    for (size_t i = 0; i < n_known; i++) {
        const int role = role_of(known[i]);
        if (!(role == ROLE_INPUT || (role == ROLE_STATE && c->exchange)))
            return ebb_fail(c, function, "%s (value reference %u) is not a known of this FMU (an input%s)",
                            ebb_var_name(known[i]), known[i], c->exchange ? " or a state" : "");
        n += EBB_VAR_SIZE[known[i]];
    }
    return n;
}

/* elements of the unknowns (outputs; for model exchange also derivatives), or -1 (logged) */
static long unknown_elements(ebb_instance *c, const char *function, const unsigned unknown[], size_t n_unknown)
{
    long n = 0;
    for (size_t i = 0; i < n_unknown; i++) {
        const int role = role_of(unknown[i]);
        if (!(role == ROLE_OUTPUT || (role == ROLE_DERIVATIVE && c->exchange)))
            return ebb_fail(c, function, "%s (value reference %u) is not an unknown of this FMU (an output%s)",
                            ebb_var_name(unknown[i]), unknown[i], c->exchange ? " or a derivative" : "");
        n += EBB_VAR_SIZE[unknown[i]];
    }
    return n;
}

static int sizes_match(ebb_instance *c, const char *function, const char *what, size_t given, long expected)
{
    if (expected < 0) return -1;
    if (given != (size_t)expected)
        return ebb_fail(c, function, "%zu %s values given, the variables have %ld element(s)", given, what,
                        expected);
    return 0;
}

/* the unknowns' elements for an input direction du and a state direction dxs */
static void apply(ebb_instance *c, const unsigned unknown[], size_t n_unknown, const double *du, const double *dxs,
                  double *out)
{
    const ebb_model *m = &c->mdl;
    const int nx = m->nx;
    double ddx[EBB_NSTATES];
    int have_dx = 0;
    size_t at = 0;
    for (size_t i = 0; i < n_unknown; i++) {
        const unsigned r = unknown[i];
        for (int e = 0; e < EBB_VAR_SIZE[r]; e++, at++) {
            const int idx = EBB_VAR_INDEX[r] + e;
            if (EBB_VAR_ROLE[r] == ROLE_OUTPUT) {
                const double *Crow = (c->exchange ? m->Cc : m->Cy) + (size_t)idx * nx;
                const double *Drow = (c->exchange ? m->Dc : m->Dy) + (size_t)idx * m->m;
                double acc = 0.0;
                if (c->exchange) for (int q = 0; q < nx; q++) acc += Crow[q] * dxs[q];
                for (int j = 0; j < m->m; j++) acc += Drow[j] * du[j];
                out[at] = c->exchange ? acc : ebb_delay_feedthrough(idx, acc);
            } else {
                if (!have_dx) { ebb_rates(m, dxs, du, ddx); have_dx = 1; }
                out[at] = ddx[idx];
            }
        }
    }
}

int ebb_directional(ebb_instance *c, const char *function, const unsigned unknown[], size_t n_unknown,
                    const unsigned known[], size_t n_known, const double seed[], size_t n_seed,
                    double sensitivity[], size_t n_sensitivity)
{
    if (sizes_match(c, function, "seed", n_seed, known_elements(c, function, known, n_known)) != 0) return -1;
    if (sizes_match(c, function, "sensitivity", n_sensitivity, unknown_elements(c, function, unknown, n_unknown)))
        return -1;
    if (ebb_ensure_model(c, function) != 0) return -1;
    double du[EBB_NACT + 1], dxs[EBB_NSTATES];
    memset(du, 0, sizeof(du));
    memset(dxs, 0, sizeof(dxs));
    size_t at = 0;
    for (size_t i = 0; i < n_known; i++)
        for (int e = 0; e < EBB_VAR_SIZE[known[i]]; e++, at++) {
            const int idx = EBB_VAR_INDEX[known[i]] + e;
            if (EBB_VAR_ROLE[known[i]] == ROLE_INPUT) du[idx] += seed[at];
            else dxs[idx] += seed[at];
        }
    apply(c, unknown, n_unknown, du, dxs, sensitivity);
    return 0;
}

int ebb_adjoint(ebb_instance *c, const char *function, const unsigned unknown[], size_t n_unknown,
                const unsigned known[], size_t n_known, const double seed[], size_t n_seed,
                double sensitivity[], size_t n_sensitivity)
{
    if (sizes_match(c, function, "seed", n_seed, unknown_elements(c, function, unknown, n_unknown)) != 0) return -1;
    if (sizes_match(c, function, "sensitivity", n_sensitivity, known_elements(c, function, known, n_known)))
        return -1;
    if (ebb_ensure_model(c, function) != 0) return -1;
    double *column = malloc(sizeof(double) * (n_seed + 1));
    if (!column) return ebb_fail(c, function, "out of memory");
    double du[EBB_NACT + 1], dxs[EBB_NSTATES];
    size_t at = 0;
    for (size_t i = 0; i < n_known; i++)
        for (int e = 0; e < EBB_VAR_SIZE[known[i]]; e++, at++) {
            const int idx = EBB_VAR_INDEX[known[i]] + e;
            memset(du, 0, sizeof(du));
            memset(dxs, 0, sizeof(dxs));
            if (EBB_VAR_ROLE[known[i]] == ROLE_INPUT) du[idx] = 1.0;
            else dxs[idx] = 1.0;
            apply(c, unknown, n_unknown, du, dxs, column);
            double acc = 0.0;
            for (size_t q = 0; q < n_seed; q++) acc += seed[q] * column[q];
            sensitivity[at] = acc;
        }
    free(column);
    return 0;
}
