"""The modal recursion compiled for its input, tap and output counts (ebb_model.exact.recursion) against a strict-order
NumPy loop and against its numba kernel, its one-tap form, its cache and its fallback where no compiler can be used."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from ebb_model.exact.recursion import ONE_TAP_RADIUS, compiled_recursion, one_tap_form, run_modal_recursion

ROOT = Path(__file__).resolve().parents[1]

#: Error budget of the compiled kernel against the strict-order loop: both sum O(nb + ni) products per output
#: and sample in a different order (re-association, fused multiply-adds), and the recursion carries the
#: differences along its lightly damped blocks.  Measured largest relative difference over the cases below:
#: 3e-15 (nb ≤ 50), 2e-14 on the benchmark's 200 blocks; the bound leaves a factor 50 above that.
RTOL = 1e-12


def system(nb: int, m: int, taps: int, p: int, seed: int = 0, radii: tuple[float, float] = (0.95, 0.999)):
    """Random blocks (by default lightly damped: radius 0.95-0.999), input taps, outputs and a non-zero initial
    state."""
    rng = np.random.default_rng(seed)
    r, th = rng.uniform(*radii, nb), rng.uniform(0.0, np.pi, nb)
    T = np.empty((nb, 2, 2))
    T[:, 0, 0] = T[:, 1, 1] = r * np.cos(th)
    T[:, 0, 1], T[:, 1, 0] = -r * np.sin(th), r * np.sin(th)
    G = rng.standard_normal((nb, 2, m * taps))
    Cm = rng.standard_normal((p, nb, 2))
    D = rng.standard_normal((p, m))
    z = rng.standard_normal((nb, 2))
    return T, G, Cm, D, z


def strict(T, G, Cm, D, u, delays, z):
    """The recursion sample by sample in NumPy, the input taps gathered explicitly (``u[−j] = u[0]``)."""
    ns, m = u.shape
    z = z.copy()
    y = np.empty((ns, D.shape[0]))
    for k in range(ns):
        uk = np.concatenate([u[max(k - j, 0)] for j in range(delays + 1)])
        y[k] = np.einsum("pbi,bi->p", Cm, z) + D @ uk[:m]
        z = np.einsum("bij,bj->bi", T, z) + np.einsum("bim,m->bi", G, uk)
    return y


@pytest.mark.parametrize("nb, m, taps, p, ns", [
    (1, 1, 1, 1, 300), (7, 1, 3, 2, 300), (8, 2, 2, 1, 300), (9, 1, 3, 3, 300), (50, 3, 1, 2, 300),
    (17, 1, 3, 2, 1), (17, 1, 3, 2, 2), (17, 1, 3, 2, 0)])
def test_compiled_equals_strict_order_and_numba(nb, m, taps, p, ns):
    if compiled_recursion(m, taps, p) is None:
        pytest.fail("no compiled recursion on a machine with gcc (the suite's own requirement)")
    T, G, Cm, D, z = system(nb, m, taps, p)
    u = np.random.default_rng(1).standard_normal((ns, m))
    y_c = run_modal_recursion(T, G, Cm, D, u, taps - 1, z)
    y_n = run_modal_recursion(T, G, Cm, D, u, taps - 1, z, compiled=False)
    y_s = strict(T, G, Cm, D, u, taps - 1, z)
    assert y_c.shape == y_s.shape == (ns, p)
    if ns:
        scale = np.max(np.abs(y_s))
        assert np.max(np.abs(y_c - y_s)) <= RTOL * scale
        assert np.max(np.abs(y_n - y_s)) <= RTOL * scale


@pytest.mark.parametrize("radii", [(0.05, 0.999), (0.0, 0.3), (0.49, 0.51)])
def test_blocks_near_the_origin_keep_their_taps(radii):
    # the one-tap form moves a block's past samples to the outputs through T⁻¹ only for |λ| >= ONE_TAP_RADIUS;
    # blocks nearer the origin (a heavily damped mode, a filter, λ = 0) keep their taps, in the same kernel
    T, G, Cm, D, z = system(37, 2, 3, 2, seed=3, radii=radii)
    u = np.random.default_rng(4).standard_normal((400, 2))
    _, _, _, _, _, nb1 = one_tap_form(T, G, Cm, D, z, u[0], 2)
    radius = np.hypot(T[:, 0, 0], T[:, 1, 0])
    assert nb1 == np.count_nonzero(radius >= ONE_TAP_RADIUS)
    y_c = run_modal_recursion(T, G, Cm, D, u, 2, z)
    y_s = strict(T, G, Cm, D, u, 2, z)
    assert np.max(np.abs(y_c - y_s)) <= RTOL * np.max(np.abs(y_s))


def test_divergence_shows_as_inf_not_garbage():
    T, G, Cm, D, z = system(5, 1, 3, 1)
    T *= 3.0                                          # every block's radius above 2.8: diverges
    y = run_modal_recursion(T, G, Cm, D, np.ones((2000, 1)), 2, z)
    assert not np.all(np.isfinite(y))
    assert np.all(np.isfinite(y[:100]))               # finite until it overflows, then inf/nan


#: Blocks a search can reach at its bounds: a pole at the origin, a zero lag (a block with one eigenvalue 0),
#: coincident poles (a Jordan block), a huge real pole beside a zero one (the discriminant overflows: this one
#: raised ZeroDivisionError from the one-tap form), a block of one repeated eigenvalue at the test's radius,
#: denormals, and the non-finite blocks of a diverged candidate.
EDGE_BLOCKS = [np.zeros((2, 2)), np.diag([0.9, 0.0]), np.array([[0.9, 1.0], [0.0, 0.9]]), np.diag([1e200, 0.0]),
               np.diag([1e160, 1e-170]), np.eye(2) * ONE_TAP_RADIUS, np.diag([5e-324, 5e-324]),
               np.array([[np.inf, 0.0], [0.0, 0.0]]), np.array([[np.nan, 1.0], [1.0, 0.5]]),
               np.array([[0.0, 1e300], [1e-300, 0.0]]), np.array([[0.5, 1.0], [-0.25, 0.5]])]


@pytest.mark.parametrize("compiled", [True, False])
def test_no_block_a_search_can_reach_raises(compiled):
    """Every edge block, alone and among ordinary ones, with every tap count: the recursion returns (non-finite
    numbers where the block diverges), never raises; where the blocks are finite and not huge it equals the strict
    loop."""
    rng = np.random.default_rng(7)
    for taps in (1, 2, 3, 32):
        for edge in EDGE_BLOCKS:
            T, G, Cm, D, z = system(4, 1, taps, 2, seed=taps)
            T[1] = edge
            u = rng.standard_normal((60, 1))
            y = run_modal_recursion(T, G, Cm, D, u, taps - 1, z, compiled=compiled)
            assert y.shape == (60, 2)
            if np.all(np.isfinite(edge)) and np.max(np.abs(edge)) <= 1.0:
                y_s = strict(T, G, Cm, D, u, taps - 1, z)
                assert np.max(np.abs(y - y_s)) <= RTOL * np.max(np.abs(y_s)), (taps, edge)


def _run(code: str, env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=600)


PROBE = """
    import warnings, numpy as np
    import ebb_model as em
    cfg = em.load_config("examples/seed_clamped.toml")
    u = np.random.default_rng(0).standard_normal((3000, 1))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        y = em.simulate(em.fast_model(cfg), u).outputs
    np.save("{out}", y)
    print("WARN:" + " | ".join(str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)))
"""


def test_cache_is_built_once_and_reused(tmp_path):
    env = dict(os.environ, EBB_MODEL_CACHE=str(tmp_path / "cache"))
    first = _run(PROBE.format(out=tmp_path / "a.npy"), env)
    assert first.returncode == 0, first.stderr
    libs = list((tmp_path / "cache").rglob("modal_*.so"))
    assert len(libs) == 1
    stamp = libs[0].stat().st_mtime_ns
    second = _run(PROBE.format(out=tmp_path / "b.npy"), env)
    assert second.returncode == 0, second.stderr
    assert libs[0].stat().st_mtime_ns == stamp        # loaded, not rebuilt
    assert list((tmp_path / "cache").rglob("*.so")) == libs   # no temporary file left beside it
    assert first.stdout.strip() == second.stdout.strip() == "WARN:"
    assert np.array_equal(np.load(tmp_path / "a.npy"), np.load(tmp_path / "b.npy"))


@pytest.mark.parametrize("broken", ["no compiler", "cache not writable"])
def test_falls_back_to_numba_with_one_warning(tmp_path, broken):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a directory")
    if broken == "no compiler":
        env = dict(os.environ, EBB_MODEL_CACHE=str(tmp_path / "cache"), PATH=str(tmp_path))
        expected = "no C compiler"
    else:
        env = dict(os.environ, EBB_MODEL_CACHE=str(blocker / "cache"))
        expected = "could not be compiled"
    reference = _run(PROBE.format(out=tmp_path / "ref.npy"), dict(os.environ))
    fallback = _run(PROBE.format(out=tmp_path / "fallback.npy"), env)
    assert reference.returncode == 0 and fallback.returncode == 0, fallback.stderr
    warning = fallback.stdout.strip().removeprefix("WARN:")
    assert expected in warning and "numba" in warning and "|" not in warning
    y_ref, y_fb = np.load(tmp_path / "ref.npy"), np.load(tmp_path / "fallback.npy")
    assert np.max(np.abs(y_fb - y_ref)) <= RTOL * np.max(np.abs(y_ref))
