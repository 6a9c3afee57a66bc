"""The modal recursion: compiled C for the model's input, tap and output counts, numba where no C compiler is found.

The fast path's work per sample is ``O(n)`` over 2×2 blocks (:class:`~ebb_model.theta.modal_form.ModalStateSpace`):
``z[k+1]_b = T_b z[k]_b + Σ_j G_{b,j} u[k − j]``, ``y[k] = Σ_b C_b z[k]_b + D u[k]``.  It is inherently
sequential in ``k``, so its speed is how many multiply-adds a block costs per sample and how well the loop over
blocks is vectorised.

**One input tap per block.**  The exact scheme's cubic input reads ``u[k]``, ``u[k−1]`` and ``u[k−2]``: a block
pays ``2 m`` multiply-adds per tap.  For a block whose poles lie away from the origin (``|λ| ≥``
:data:`ONE_TAP_RADIUS`) the past samples' share moves out of the block, exactly (:func:`one_tap_form`): with
``ξ = z − Σ_{j≥1} P_j u[k − j]``, ``P_d = −T⁻¹G_d`` and ``P_j = T⁻¹(P_{j+1} − G_j)``, ``ξ⁺ = T ξ + (G_0 − P_1)
u[k]`` and ``y = C ξ + D u[k] + Σ_j (Σ_b C_b P_{j,b}) u[k − j]`` — the taps summed once per output instead of once
per block (14 → 10 multiply-adds per block and sample for one force and two sensors).  ``T⁻¹`` amplifies rounding
by at most ``1/|λ|²`` (4); blocks nearer the origin — heavily damped modes, the anti-alias filters — keep their
taps.

**Compiled.**  The C source (``csrc/modal_recursion.c``) is compiled with the input, tap and output counts as
compile-time constants (``gcc -O3 -march=native``, re-association allowed as for numba's fastmath, no finite-math
assumption) into a per-user cache directory, on first use of the counts, and loaded with :mod:`ctypes`.  Its
blocks are regrouped in tiles of SIMD lanes, 4 or 8: which is faster depends on the processor (on an AMD EPYC,
which runs AVX-512 on 256-bit units, 4 lanes took 50 blocks 11 % faster; the previous benchmark machine ran 8 lanes
at 0.27 ns per block and sample), so both are built and timed once (:func:`compiled_recursion`) and the faster is
kept — once per machine and counts; every process then loads it.  Measured on the benchmark's cases (AMD EPYC,
20,000 samples) against the previous kernel (compiled per block count, 8 lanes, every tap in every block): 50
blocks and two sensors 0.69 → 0.51 ms, 200 blocks and three sensors 2.75 → 2.14 ms.

Where no compiler is found or compiling fails (a warning says why), the numba kernel below runs the recursion in
its original form (outputs equal to ~1e-15 relative; tested).

Cache directory: ``$EBB_MODEL_CACHE``, else ``$XDG_CACHE_HOME/ebb-model``, else ``~/.cache/ebb-model``; the
libraries are keyed by the source, the flags, the compiler's version and the processor (``-march=native``), built
under a lock (another process wanting the same library waits for it and then loads it) and written atomically.
"""
from __future__ import annotations

import ctypes
import fcntl
import functools
import hashlib
import math
import os
import platform
import shutil
import subprocess
import tempfile
import time
import warnings
from pathlib import Path
from typing import Callable

import numba
import numpy as np

__all__ = ["run_modal_recursion", "compiled_recursion", "one_tap_form", "cache_directory", "ONE_TAP_RADIUS"]

SOURCE = Path(__file__).with_name("csrc") / "modal_recursion.c"

#: re-association and contraction as numba's ``fastmath={"reassoc", "contract", "nsz", "arcp"}``; no
#: ``-ffinite-math-only``, so a diverging simulation still shows inf/nan
CFLAGS = ("-std=gnu11", "-O3", "-march=native", "-fassociative-math", "-fno-signed-zeros", "-fno-trapping-math",
          "-ffp-contract=fast", "-fopenmp-simd", "-shared", "-fPIC")

#: Tile widths (SIMD lanes) the compiled recursion is built with; the faster on the machine is kept.
LANES = (4, 8)

#: Smallest pole radius ``|λ|`` of a block whose past input samples move to the outputs (module docstring).
ONE_TAP_RADIUS = 0.5

#: the numba kernels' fastmath flags: re-association lets LLVM vectorise the sums (outputs agree with the strict
#: order to ~1e-15 relative); no-NaN/no-Inf assumptions, so a diverging simulation still shows inf/nan
FASTMATH = {"reassoc", "contract", "nsz", "arcp"}

Kernel = Callable[..., None]


def cache_directory() -> Path:
    """Where the compiled recursions are kept (``$EBB_MODEL_CACHE``, ``$XDG_CACHE_HOME/ebb-model`` or
    ``~/.cache/ebb-model``)."""
    explicit = os.environ.get("EBB_MODEL_CACHE")
    if explicit:
        return Path(explicit)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "ebb-model"


def _processor() -> str:
    """The processor's identity for ``-march=native`` (model and feature flags where Linux tells them)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            lines = [ln for ln in fh.read().splitlines() if ln.startswith(("model name", "flags", "Features"))]
        return "\n".join(sorted(set(lines)))
    except OSError:
        return platform.processor() + platform.machine()


@functools.lru_cache(maxsize=1)
def _toolchain() -> tuple[str, Path] | None:
    """The compiler and this machine's library directory, or ``None`` (a warning says why)."""
    cc = shutil.which("gcc")
    if cc is None:
        warnings.warn("no C compiler (gcc) found: the modal recursion runs on its numba kernel", RuntimeWarning,
                      stacklevel=3)
        return None
    try:
        version = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=60).stdout
    except (OSError, subprocess.SubprocessError) as exc:
        warnings.warn(f"the C compiler {cc} does not run ({exc}): the modal recursion runs on its numba kernel",
                      RuntimeWarning, stacklevel=3)
        return None
    key = hashlib.sha256("\0".join([SOURCE.read_text(), " ".join(CFLAGS), version, _processor()]).encode())
    return cc, cache_directory() / f"recursion-{key.hexdigest()[:16]}"


def _compile(cc: str, directory: Path, inputs: int, taps: int, outputs: int, lanes: int) -> Path:
    """Build the recursion for the counts with ``lanes`` SIMD lanes per tile into a new file in ``directory``."""
    fd, tmp = tempfile.mkstemp(suffix=".so", dir=directory)
    os.close(fd)
    try:
        subprocess.run([cc, *CFLAGS, f"-DVL={lanes}", f"-DM={inputs}", f"-DTAPS={taps}", f"-DNO={outputs}",
                        "-o", tmp, str(SOURCE)], check=True, capture_output=True, text=True, timeout=300)
    except BaseException:
        os.unlink(tmp)
        raise
    return Path(tmp)


def _load(lib: Path) -> Kernel:
    """The kernel of the library ``lib``, its argument types declared."""
    fn = ctypes.CDLL(str(lib)).modal_recursion
    fn.argtypes = [ctypes.c_void_p] * 7 + [ctypes.c_long, ctypes.c_int, ctypes.c_int]
    fn.restype = ctypes.c_int
    return fn


def _seconds(fn: Kernel, inputs: int, taps: int, outputs: int) -> float:
    """The kernel's best time over repeats on a synthetic model of a benchmark's size (64 blocks, 48 of them
    reading one tap, 4,000 samples)."""
    rng = np.random.default_rng(0)
    nb, ni, ns = 64, inputs * taps, 4000
    angle = rng.uniform(0.0, math.pi, nb)                 # lightly damped blocks, as a beam's modes
    T = 0.99 * np.stack([np.cos(angle), -np.sin(angle), np.sin(angle), np.cos(angle)], axis=1).reshape(nb, 2, 2)
    arrays = [np.ascontiguousarray(a) for a in (
        T, rng.standard_normal((nb, 2, ni)), rng.standard_normal((outputs, nb, 2)), rng.standard_normal((outputs, ni)),
        rng.standard_normal((ns, inputs)), np.empty((ns, outputs)), np.zeros((nb, 2)))]
    args = [a.ctypes.data for a in arrays]
    best = math.inf
    for _ in range(7):
        t0 = time.perf_counter()
        fn(*args, ns, 48, nb)
        best = min(best, time.perf_counter() - t0)
    return best


@functools.lru_cache(maxsize=64)
def compiled_recursion(inputs: int, taps: int, outputs: int) -> Kernel | None:
    """The compiled recursion for the counts, or ``None`` when it cannot be built (a warning says why).

    Built on first use on the machine — both tile widths of :data:`LANES`, the faster kept —, under a lock in the
    cache directory, so that concurrent processes build it once and load the same library.

    Parameters
    ----------
    inputs, taps, outputs
        Number of inputs, of input taps (``delays + 1``) and of outputs.

    Returns
    -------
    callable or None
        ``f(T, G, C, D, u, y, z, ns, nb1, nb)`` on the addresses of row-major float arrays — the blocks (nb, 2, 2),
        input matrices (nb, 2, inputs·taps), output rows (outputs, nb, 2), feedthrough (outputs, inputs·taps), the
        input samples (ns, inputs), the outputs (ns, outputs, written) and the initial block state (nb, 2); the
        first ``nb1`` blocks read their first ``inputs`` columns only (:func:`one_tap_form`) —, returning 0 (or -1
        when its work space cannot be allocated).
    """
    tools = _toolchain()
    if tools is None:
        return None
    cc, directory = tools
    lib = directory / f"modal_{inputs}_{taps}_{outputs}.so"
    try:
        if not lib.exists():
            directory.mkdir(parents=True, exist_ok=True)
            with open(directory / f"{lib.name}.lock", "w") as lock:
                fcntl.flock(lock, fcntl.LOCK_EX)
                if not lib.exists():                      # not built meanwhile by the process holding the lock
                    built: list[Path] = []
                    try:
                        for lanes in LANES:
                            built.append(_compile(cc, directory, inputs, taps, outputs, lanes))
                        times = [_seconds(_load(b), inputs, taps, outputs) for b in built]
                        os.replace(built[int(np.argmin(times))], lib)
                    finally:
                        for b in built:
                            if b.exists():
                                b.unlink()
    except (OSError, subprocess.SubprocessError) as exc:
        detail = getattr(exc, "stderr", None) or exc
        warnings.warn(f"the modal recursion could not be compiled in {directory} ({str(detail).strip()}): it "
                      "runs on its numba kernel", RuntimeWarning, stacklevel=2)
        return None
    return _load(lib)


@numba.njit(cache=True, nogil=True)
def _one_tap(T, G, Cm, D, z, u0, m, delays, radius, T1, G1, C1, D1, z1):  # pragma: no cover - compiled
    nb, p = T.shape[0], Cm.shape[0]
    D1[:, :m] = D                           # D1 comes zeroed (one_tap_form)
    ok = np.empty(nb, dtype=np.bool_)
    for b in range(nb):
        a, bb, c, d = T[b, 0, 0], T[b, 0, 1], T[b, 1, 0], T[b, 1, 1]
        det = a * d - bb * c
        half = 0.5 * (a + d)
        disc = half * half - det
        if disc < 0.0:                          # a complex pair: |λ|² = det
            rmin = math.sqrt(det)
        else:                                   # real: the smaller modulus is det over the larger (no cancellation;
            big = abs(half) + math.sqrt(disc)   # an overflowing disc gives 0, not a finite det's inverse of 0)
            rmin = abs(det) / big if big > 0.0 else 0.0
        ok[b] = rmin >= radius and det != 0.0   # NaN (a diverged candidate) keeps its taps
    n1 = 0
    for b in range(nb):
        if ok[b]:
            n1 += 1
    q, r1 = 0, n1                               # the one-tap blocks first, each group in its order
    P = np.zeros((2, m))
    X = np.empty((2, m))
    for b in range(nb):
        k = q if ok[b] else r1
        T1[k] = T[b]
        for o in range(p):
            C1[o, k, 0], C1[o, k, 1] = Cm[o, b, 0], Cm[o, b, 1]
        z1[k, 0], z1[k, 1] = z[b, 0], z[b, 1]
        if not ok[b]:
            G1[k] = G[b]
            r1 += 1
            continue
        a, bb, c, d = T[b, 0, 0], T[b, 0, 1], T[b, 1, 0], T[b, 1, 1]
        det = a * d - bb * c
        P[:, :] = 0.0
        for j in range(delays, 0, -1):          # P_j = T⁻¹ (P_{j+1} − G_j), P_{d+1} = 0
            for l in range(m):
                X[0, l] = P[0, l] - G[b, 0, j * m + l]
                X[1, l] = P[1, l] - G[b, 1, j * m + l]
            for l in range(m):
                P[0, l] = (d * X[0, l] - bb * X[1, l]) / det
                P[1, l] = (a * X[1, l] - c * X[0, l]) / det
            for l in range(m):                  # the outputs read P_j u[k − j]; the start is ξ = z − Σ_j P_j u[0]
                for o in range(p):
                    D1[o, j * m + l] += Cm[o, b, 0] * P[0, l] + Cm[o, b, 1] * P[1, l]
                z1[k, 0] -= P[0, l] * u0[l]
                z1[k, 1] -= P[1, l] * u0[l]
        G1[k, :, :] = 0.0
        for l in range(m):                      # ξ⁺ = T ξ + (G_0 − P_1) u[k]
            G1[k, 0, l] = G[b, 0, l] - P[0, l]
            G1[k, 1, l] = G[b, 1, l] - P[1, l]
        q += 1
    return n1


def one_tap_form(T: np.ndarray, G: np.ndarray, Cm: np.ndarray, D: np.ndarray, z: np.ndarray, u0: np.ndarray,
                 delays: int, radius: float = ONE_TAP_RADIUS
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """The recursion with the past input samples of every block of pole radius ``≥ radius`` moved to the outputs
    (module docstring), the same outputs to rounding: ``(T, G, C, D, z, nb1)`` with those ``nb1`` blocks first
    (their past samples' columns of ``G`` zero), ``D`` (p, m·(delays + 1)) reading the past samples too and ``z``
    the start ``ξ`` for ``u[−j] = u[0]`` (``u0``).  Contiguous float arrays in and out."""
    m, p, nb = D.shape[1], D.shape[0], T.shape[0]
    D1 = np.zeros((p, m * (delays + 1)))      # the past samples' columns start at zero
    if nb == 0 or delays == 0:
        D1[:, :m] = D
        return T, G, Cm, D1, z, nb
    T1, G1, C1, z1 = np.empty_like(T), np.empty_like(G), np.empty_like(Cm), np.empty_like(z)
    n1 = _one_tap(T, G, Cm, D, z, u0, m, delays, radius, T1, G1, C1, D1, z1)
    return T1, G1, C1, D1, z1, int(n1)


def run_modal_recursion(T: np.ndarray, G: np.ndarray, Cm: np.ndarray, D: np.ndarray, u: np.ndarray,
                        delays: int, z: np.ndarray, *, compiled: bool = True,
                        D_taps: np.ndarray | None = None) -> np.ndarray:
    """Outputs of the modal recursion from the block state ``z`` for the input samples ``u``.

    Parameters
    ----------
    T, G, Cm, D
        Blocks (nb, 2, 2), input matrices (nb, 2, m·(delays + 1)) — column ``j m + l`` is input ``l`` at sample
        ``k − j`` —, output rows (p, nb, 2) and feedthrough (p, m).
    u
        Input samples (ns, m); ``u[−j] = u[0]``.
    delays
        Past samples the input taps read.
    z
        Initial block state (nb, 2).
    compiled
        ``False`` runs the numba kernel even where the compiled one is available (for comparison).
    D_taps
        The feedthrough on every tap (p, m·(delays + 1)), ``D`` its first ``m`` columns (a reconstruction that
        reads ahead: :meth:`~ebb_model.theta.modal_form.ModalStateSpace.feedthrough_taps`); ``None``: ``D`` alone.

    Returns
    -------
    numpy.ndarray
        ``y`` (ns, p).
    """
    nb, m, p, taps = T.shape[0], D.shape[1], D.shape[0], delays + 1
    y = np.empty((u.shape[0], p))
    fn = compiled_recursion(m, taps, p) if compiled else None
    if fn is None:
        # unpacked by name: mypy rejects f(*a_list, x), the list's length being unknown to it
        t00, t01, t10, t11, g0, g1, c0, c1, d_taps, u_c = [np.ascontiguousarray(a, dtype=float) for a in (
            T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1], G[:, 0, :].T, G[:, 1, :].T, Cm[:, :, 0], Cm[:, :, 1],
            np.hstack([D, np.zeros((p, m * delays))]) if D_taps is None else D_taps, u)]
        _modal_kernel(t00, t01, t10, t11, g0, g1, c0, c1, d_taps, u_c, delays, y, np.array(z[:, 0], dtype=float),
                      np.array(z[:, 1], dtype=float))
        return y
    T, G, Cm, D, z = (np.ascontiguousarray(a, dtype=float) for a in (T, G, Cm, D, z))
    u = np.ascontiguousarray(u, dtype=float)
    u0 = np.ascontiguousarray(u[0] if u.shape[0] else np.zeros(m))
    # a block's past samples move to the outputs when T⁻¹ amplifies rounding by at most 4 over all of them
    radius = ONE_TAP_RADIUS if delays <= 2 else ONE_TAP_RADIUS ** (2.0 / delays)
    T, G, Cm, D, z, nb1 = one_tap_form(T, G, Cm, D, z, u0, delays, radius)
    if D_taps is not None:
        D[:, m:] += D_taps[:, m:]
    if fn(*(a.ctypes.data for a in (T, G, Cm, D, u, y, z)), u.shape[0], nb1, nb) != 0:
        raise MemoryError("the modal recursion's work space could not be allocated")
    return y


@numba.njit(cache=True, nogil=True, fastmath=FASTMATH)
def _modal_kernel(t00, t01, t10, t11, g0, g1, c0, c1, D, u, delays, y, z0, z1):  # pragma: no cover - compiled
    # input columns i = j m + l: input l at sample k − j (u[−j] = u[0]), j = 0 … delays, gathered per sample
    nb = t00.shape[0]
    ns, m = u.shape
    ni = m * (delays + 1)
    no = D.shape[0]
    a0 = np.empty(nb)
    a1 = np.empty(nb)
    uk = np.empty(ni)
    for k in range(ns):
        for i in range(ni):
            uk[i] = u[max(k - i // m, 0), i % m]
        for o in range(no):
            acc = 0.0
            for b in range(nb):
                acc += c0[o, b] * z0[b] + c1[o, b] * z1[b]
            for i in range(ni):
                acc += D[o, i] * uk[i]
            y[k, o] = acc
        for b in range(nb):
            a0[b] = t00[b] * z0[b] + t01[b] * z1[b]
            a1[b] = t10[b] * z0[b] + t11[b] * z1[b]
        for i in range(ni):
            ui = uk[i]
            for b in range(nb):
                a0[b] += g0[i, b] * ui
                a1[b] += g1[i, b] * ui
        for b in range(nb):
            z0[b] = a0[b]
            z1[b] = a1[b]
