"""Benchmark of the model core (issue: fast simulation).

Reference case R1: 50 interior nodes (clamped–clamped seed case), 20,000 samples,
1 force, 2 sensors.  One *evaluation* = assemble the model for a new parameter
set + simulate it — what the identification does per candidate.

Printed (medians over repeats, all measured in this one run):

* fast path (modal realisation + compiled recursion), split into assembly and simulation;
* ``scipy.signal.dlsim`` on the same (Φ, Γ, C, D) (assembly excluded — only its simulation);
* the ratio dlsim / fast;
* the *compiled floor*: the same modal recursion (the fast model's own blocks, input taps and outputs) on arrays
  prepared beforehand, the faster of two plain-C versions — a textbook two-pass loop compiled with
  ``gcc -O3 -march=native`` (the re-association the kernels are allowed, no more) in this run, and the library's
  own compiled kernel called directly (on the one-tap form it gives the arrays) —, each checked equal to the fast
  path, and the evaluation's and the simulation's ratios to it;
* the part of an evaluation no faster recursion removes: the Richardson pair's eigenproblems for new parameters
  (the fine grid's values and mode shapes, the coarse grid's values) as the model solves them (LAPACK's dense
  ``eigh`` of the inverted pencil), and by LAPACK's banded solver on the same pencil (``M`` is diagonal) — the
  fastest LAPACK route measured, though it resolves the lowest ``ω²`` only to ``eps·‖K‖`` (its difference from
  the model's values is printed) —, and the ratio ``(floor + modes) / floor``: a lower bound of the evaluation's
  ratio for any realisation that takes its mode shapes from LAPACK;
* within one family: the evaluation and its assembly, and the ratio to the floor; the same two evaluations and
  the floor for 200 interior nodes and 3 sensors;
* growth exponents when the number of samples doubles and when the number of nodes doubles:
  ``log2(t(2x) / t(x))``.

Run: ``python benchmarks/bench_core.py [--repeats R] [--json PATH]``.
"""
from __future__ import annotations

import argparse
import ctypes
import math
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import scipy.linalg as sla
import scipy.signal as ss
from threadpoolctl import threadpool_limits

import ebb_model as em
from ebb_model.space.richardson_pair import companion_config, lowest_modes
from ebb_model.exact.recursion import compiled_recursion, one_tap_form

from figures import add_json_argument, write_figures  # benchmarks/figures.py
from timing import interleaved_medians, median_time  # benchmarks/timing.py

ROOT = Path(__file__).resolve().parents[1]


def config(nodes: int, sensors: int = 2) -> em.BeamConfig:
    d = em.load_config(ROOT / "examples" / "seed_clamped.toml").to_dict()
    d["beam"]["nodes"] = nodes
    if sensors == 3:
        d["sensors"].append({"name": "y3", "x": 0.9, "kind": "displacement"})
    return em.config_from_dict(d)


def evaluation(cfg: em.BeamConfig, u: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A new member of the modes' family each time (``N`` and ``EI`` move ``N/EI``): one eigen-decomposition."""
    p = {"EI": rng.uniform(8, 12), "rhoA": rng.uniform(0.9, 1.1), "N": rng.uniform(0, 100)}
    return em.simulate(em.fast_model(cfg, p), u).outputs


def family_evaluation(cfg: em.BeamConfig, u: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Within one family of the modes (``N = 0`` known; ``EI``, ``ρA``, ``c`` move): the decomposition scaled."""
    p = {"EI": rng.uniform(8, 12), "rhoA": rng.uniform(0.9, 1.1), "c": rng.uniform(0.1, 1.0), "N": 0.0}
    return em.simulate(em.fast_model(cfg, p), u).outputs


def against_floor(cfg: em.BeamConfig, u: np.ndarray, rng: np.random.Generator, repeats: int,
                  workdir: Path) -> dict[str, float]:
    """Median evaluation times [s] of ``cfg`` — a new member of the family, and within one family — with the
    compiled floor of its recursion and the floor's relative difference from the fast path."""
    evaluation(cfg, u, rng)
    family_evaluation(cfg, u, rng)
    fm = em.fast_model(cfg)
    y = em.simulate(fm, u).outputs
    # the floor: the faster of two plain-C recursions on arrays prepared beforehand, each checked equal to the
    # fast path — the textbook two-pass loop below, and the library's own compiled kernel called directly
    floors = {"two_pass": compiled_floor(fm, u, workdir), "kernel": kernel_floor(fm, u)}
    out: dict[str, float] = {}
    for name, run in floors.items():
        difference = float(np.linalg.norm(run() - y) / np.linalg.norm(y))
        if not difference < 1e-9:
            raise SystemExit(f"the compiled floor ({name}) differs from the fast path by {difference:.1e}")
        out["floor_difference"] = max(out.get("floor_difference", 0.0), difference)
    # one call of each per round, so that a drift of the machine's speed moves the evaluations and the floor alike
    times = interleaved_medians({"member": lambda: evaluation(cfg, u, rng),
                                 "family": lambda: family_evaluation(cfg, u, rng), **floors}, repeats)
    out["member"], out["family"] = times.pop("member"), times.pop("family")
    out["floor"] = min(times.values())
    out["floor_two_pass"] = times["two_pass"]
    return out


def kernel_floor(fm: em.ModalStateSpace, u: np.ndarray):
    """A callable running the library's compiled recursion for ``fm`` directly on arrays prepared once (the
    model's arrays in the one-tap form the library gives them, :func:`ebb_model.exact.recursion.one_tap_form`)."""
    fn = compiled_recursion(fm.D.shape[1], fm.delays + 1, fm.D.shape[0])
    if fn is None:
        raise SystemExit("the benchmark needs the compiled recursion (a C compiler)")
    z = np.zeros((fm.nblocks, 2)) if fm.hold is None else -np.einsum("bim,m->bi", fm.hold, u[0])
    T, G, C, D, z, nb1 = one_tap_form(*(np.ascontiguousarray(a, dtype=float) for a in (fm.T, fm.G, fm.Cm, fm.D, z)),
                                      np.ascontiguousarray(u[0], dtype=float), fm.delays)
    y = np.empty((u.shape[0], fm.D.shape[0]))
    arrays = (T, G, C, D, np.ascontiguousarray(u, dtype=float), y, z)
    args = [a.ctypes.data for a in arrays]    # addresses: the arrays are kept alive below

    def run() -> np.ndarray:
        fn(*args, u.shape[0], nb1, fm.nblocks)
        return y

    run.arrays = arrays                       # type: ignore[attr-defined]
    return run


#: The modal recursion of :func:`ebb_model.simulate` written as plain C, compiled for the case's sizes (``NB``
#: 2×2 blocks, ``NI`` input columns — the cubic's taps included —, ``NO`` outputs as compile-time constants, so
#: the compiler unrolls and vectorises what it can); row-major arrays as the numba kernel receives them.
FLOOR_C = r"""
void modal_floor(const double *restrict t00, const double *restrict t01, const double *restrict t10,
                 const double *restrict t11, const double *restrict g0, const double *restrict g1,
                 const double *restrict c0, const double *restrict c1, const double *restrict D,
                 const double *restrict u, double *restrict y, double *restrict z0, double *restrict z1, long ns)
{
    for (long k = 0; k < ns; ++k) {
        const double *uk = u + k * NI;
        for (int o = 0; o < NO; ++o) {
            double acc = 0.0;
            for (int b = 0; b < NB; ++b) acc += c0[o * NB + b] * z0[b] + c1[o * NB + b] * z1[b];
            for (int i = 0; i < NI; ++i) acc += D[o * NI + i] * uk[i];
            y[k * NO + o] = acc;
        }
        for (int b = 0; b < NB; ++b) {
            double v0 = t00[b] * z0[b] + t01[b] * z1[b];
            double v1 = t10[b] * z0[b] + t11[b] * z1[b];
            for (int i = 0; i < NI; ++i) {
                v0 += g0[i * NB + b] * uk[i];
                v1 += g1[i * NB + b] * uk[i];
            }
            z0[b] = v0;
            z1[b] = v1;
        }
    }
}
"""


def compiled_floor(fm: em.ModalStateSpace, u: np.ndarray, workdir: Path):
    """A callable running the fast model's recursion in compiled C on ``u`` (returns the outputs)."""
    # the input columns the kernel reads: u[k], u[k−1], … for the cubic's taps (u[−j] = u[0])
    cols = [np.vstack([np.repeat(u[:1], j, axis=0), u[:u.shape[0] - j]]) for j in range(fm.delays + 1)]
    U = np.ascontiguousarray(np.hstack(cols))
    D = np.ascontiguousarray(np.hstack([fm.D, np.zeros((fm.D.shape[0], fm.D.shape[1] * fm.delays))]))
    T, G, Cm = fm.T, fm.G, fm.Cm
    arrays = [np.ascontiguousarray(a) for a in (T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1], G[:, 0, :].T,
                                                G[:, 1, :].T, Cm[:, :, 0], Cm[:, :, 1], D, U)]
    nb, (ns, ni), no = fm.nblocks, U.shape, D.shape[0]
    # one library per size: the loader keeps a library it has loaded under the same path
    src, lib = workdir / "floor.c", workdir / f"floor_{nb}_{ni}_{no}.so"
    src.write_text(FLOOR_C)
    subprocess.run(["gcc", "-O3", "-march=native", "-fassociative-math", "-fno-signed-zeros", "-fno-trapping-math",
                    "-ffp-contract=fast", f"-DNB={nb}", f"-DNI={ni}", f"-DNO={no}", "-shared", "-fPIC", "-o",
                    str(lib), str(src)], check=True)
    fn = ctypes.CDLL(str(lib)).modal_floor
    y = np.empty((ns, no))
    z = [np.zeros(nb), np.zeros(nb)]
    # at rest as em.simulate starts it: zero, or −Γ₁ u[0] for a first-order-hold realisation
    z_start = np.zeros((nb, 2)) if fm.hold is None else -np.einsum("bim,m->bi", fm.hold, u[0])
    ptr = ctypes.POINTER(ctypes.c_double)
    fn.argtypes = [ptr] * 13 + [ctypes.c_long]
    args = [a.ctypes.data_as(ptr) for a in (*arrays, y, *z)]

    def run() -> np.ndarray:
        z[0][:], z[1][:] = z_start[:, 0], z_start[:, 1]
        fn(*args, ns)
        return y

    return run


def mode_times(cfg: em.BeamConfig, repeats: int) -> dict[str, float]:
    """Times [s] of the eigenproblems an evaluation of ``cfg`` solves (its Richardson pair), by the model's route
    and by LAPACK's banded solver, and the banded route's largest relative difference in ``ω²``."""
    own, other = em.discretise(cfg), em.discretise(companion_config(cfg))
    coarse, fine = sorted((own, other), key=lambda b: b.n_unknowns)
    k = own.n_unknowns
    t_dense = median_time(lambda: (lowest_modes(fine, k), lowest_modes(coarse, k, vectors=False)), repeats)

    def band(beam: em.SemiDiscreteBeam) -> np.ndarray:   # M^-1/2 K M^-1/2 in LAPACK's upper band storage
        m = np.diag(beam.M)
        if np.count_nonzero(beam.M - np.diag(m)):
            raise ValueError("the banded comparison needs a diagonal mass matrix")
        A = beam.K / np.sqrt(np.outer(m, m))
        rows, cols = np.nonzero(A)
        u = int(np.max(np.abs(rows - cols)))
        ab = np.zeros((u + 1, A.shape[0]))
        for d in range(u + 1):
            ab[u - d, d:] = np.diagonal(A, d)
        return ab

    ab_f, ab_c = band(fine), band(coarse)
    t_banded = median_time(lambda: (sla.eig_banded(ab_f), sla.eig_banded(ab_c, eigvals_only=True)), repeats)
    w2 = lowest_modes(fine, k, vectors=False)
    deviation = float(np.max(np.abs(sla.eig_banded(ab_f, eigvals_only=True)[:k] / w2 - 1.0)))
    return {"modes_dense": t_dense, "modes_banded": t_banded, "banded_deviation": deviation}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=31)
    add_json_argument(ap)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    with threadpool_limits(limits=1, user_api="blas"):
        cfg = config(50)
        u = rng.standard_normal((20_000, 1))
        with tempfile.TemporaryDirectory() as tmp:    # the evaluations and the floor, one after the other
            r1 = against_floor(cfg, u, rng, args.repeats, Path(tmp))
            big = against_floor(config(200, sensors=3), u, rng, max(5, args.repeats // 3), Path(tmp))
        t_fast, t_floor, rel_floor = r1["member"], r1["floor"], r1["floor_difference"]
        t_asm = median_time(lambda: em.fast_model(cfg, {"EI": rng.uniform(8, 12)}), args.repeats)
        fm = em.fast_model(cfg)
        t_sim = median_time(lambda: em.simulate(fm, u), args.repeats)
        sys = em.assemble(cfg)
        t_dlsim = median_time(lambda: ss.dlsim((sys.A, sys.B, sys.C, sys.D, sys.dt), u),
                              max(5, args.repeats // 4))
        y_fast = em.simulate(fm, u).outputs
        _, y_dl, _ = ss.dlsim((sys.A, sys.B, sys.C, sys.D, sys.dt), u)
        rel = np.linalg.norm(y_fast - y_dl) / np.linalg.norm(y_dl)

        modes = mode_times(cfg, args.repeats)
        t_fam_asm = median_time(lambda: em.fast_model(cfg, {"EI": rng.uniform(8, 12), "N": 0.0}), args.repeats)

        u2 = rng.standard_normal((40_000, 1))
        t_fast_2s = median_time(lambda: evaluation(cfg, u2, rng), args.repeats)
        cfg2 = config(100)
        evaluation(cfg2, u, rng)
        t_fast_2n = median_time(lambda: evaluation(cfg2, u, rng), args.repeats)

    print("R1: 50 interior nodes, 20,000 samples, 1 force, 2 sensors (medians)")
    print(f"  fast evaluation (assemble + simulate): {t_fast * 1e3:8.3f} ms")
    print(f"    of which assembly (modal form):      {t_asm * 1e3:8.3f} ms")
    print(f"    of which compiled modal recursion:   {t_sim * 1e3:8.3f} ms")
    print(f"  scipy.signal.dlsim, same matrices:     {t_dlsim * 1e3:8.3f} ms")
    print(f"  ratio dlsim / fast evaluation:         {t_dlsim / t_fast:8.1f} x   (target >= 40)")
    print(f"  relative difference fast vs dlsim:     {rel:8.2e}")
    print(f"  compiled floor (the same recursion in C, {fm.nblocks} blocks = {2 * fm.nblocks} states): "
          f"{t_floor * 1e3:8.3f} ms  (its outputs vs the fast path's: {rel_floor:.1e}; the two-pass C loop "
          f"{r1['floor_two_pass'] * 1e3:.3f} ms)")
    print(f"  ratio fast evaluation / floor:         {t_fast / t_floor:8.2f} x   (target <= 1.5)")
    print(f"  within one family of the modes (N = 0 known; EI, rhoA, c new): evaluation {r1['family'] * 1e3:8.3f} ms "
          f"(assembly {t_fam_asm * 1e3:.3f} ms), {r1['family'] / r1['floor']:.2f} x its floor")
    print(f"  200 nodes, 3 sensors: new member {big['member'] * 1e3:8.3f} ms, within a family "
          f"{big['family'] * 1e3:8.3f} ms, floor {big['floor'] * 1e3:8.3f} ms -> "
          f"{big['member'] / big['floor']:.2f} x and {big['family'] / big['floor']:.2f} x  (target <= 1.5)")
    print(f"  ratio simulation alone / floor:        {t_sim / t_floor:8.2f} x")
    t_modes = min(modes["modes_dense"], modes["modes_banded"])
    print(f"  the Richardson pair's eigenproblems for new parameters, as the model solves them: "
          f"{modes['modes_dense'] * 1e3:8.3f} ms")
    print(f"    by LAPACK's banded solver instead:   {modes['modes_banded'] * 1e3:8.3f} ms  "
          f"(its omega^2 differ by up to {modes['banded_deviation']:.1e} relative)")
    print(f"  (floor + the faster of the two) / floor: {(t_floor + t_modes) / t_floor:6.2f} x   "
          "(no evaluation that takes its mode shapes from LAPACK is below this)")
    print(f"  samples x2 (40,000): {t_fast_2s * 1e3:8.3f} ms -> growth exponent "
          f"{math.log2(t_fast_2s / t_fast):.2f} (target <= 1.1)")
    print(f"  nodes x2 (100):      {t_fast_2n * 1e3:8.3f} ms -> growth exponent "
          f"{math.log2(t_fast_2n / t_fast):.2f} (target <= 1.5)")
    write_figures(args.json, {
        "states": 2 * fm.nblocks, "samples": int(u.shape[0]), "repeats": args.repeats,
        "evaluation_ms": t_fast * 1e3, "assembly_ms": t_asm * 1e3, "simulation_ms": t_sim * 1e3,
        "dlsim_ms": t_dlsim * 1e3, "dlsim_ratio": t_dlsim / t_fast, "dlsim_relative_difference": rel,
        "floor_ms": t_floor * 1e3, "floor_relative_difference": rel_floor,
        "floor_two_pass_ms": r1["floor_two_pass"] * 1e3, "big_floor_two_pass_ms": big["floor_two_pass"] * 1e3,
        "floor_ratio": t_fast / t_floor, "simulation_floor_ratio": t_sim / t_floor,
        "family_evaluation_ms": r1["family"] * 1e3, "family_assembly_ms": t_fam_asm * 1e3,
        "family_floor_ratio": r1["family"] / r1["floor"],
        "big_member_ms": big["member"] * 1e3, "big_family_ms": big["family"] * 1e3, "big_floor_ms": big["floor"] * 1e3,
        "big_member_floor_ratio": big["member"] / big["floor"], "big_family_floor_ratio": big["family"] / big["floor"],
        "big_floor_difference": big["floor_difference"],
        "modes_dense_ms": modes["modes_dense"] * 1e3, "modes_banded_ms": modes["modes_banded"] * 1e3,
        "modes_banded_deviation": modes["banded_deviation"],
        "modes_floor_ratio": (t_floor + t_modes) / t_floor,
        "samples_x2_ms": t_fast_2s * 1e3, "samples_exponent": math.log2(t_fast_2s / t_fast),
        "nodes_x2_ms": t_fast_2n * 1e3, "nodes_exponent": math.log2(t_fast_2n / t_fast)})


if __name__ == "__main__":
    main()
