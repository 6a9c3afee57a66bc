"""One BLAS thread wherever the model's small dense algebra runs (:func:`ebb_model.threads.single_blas_thread`).

numpy and scipy each load their own OpenBLAS, and a thread limit reaches only the libraries loaded when it is set:
a diagnosis worker limited at its start, before scipy was imported, ran scipy's OpenBLAS with every core's thread
beside the other worker — its ``eigh`` 30 times slower, the default two-worker diagnosis of a record slower than one
process (measured: 103 s against 46 s; 32 s once both libraries are limited).
"""
from __future__ import annotations

from diagnosis.search.workers import close_refit_pool, refit_pool


def _blas_threads() -> dict[str, int]:
    """In a worker: the thread count of every BLAS library loaded once scipy's linear algebra is imported."""
    import scipy.linalg  # noqa: F401 - what the model's modes use
    from threadpoolctl import threadpool_info

    return {i["filepath"]: i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


def test_a_diagnosis_worker_runs_numpys_and_scipys_blas_with_one_thread():
    pool = refit_pool(2)
    try:
        found = [pool.submit(_blas_threads).result(timeout=120) for _ in range(2)]
    finally:
        close_refit_pool(pool, now=False)
    for threads in found:
        assert len(threads) >= 2, threads            # numpy's and scipy's own OpenBLAS, both loaded
        assert set(threads.values()) == {1}, threads


def test_the_limit_reaches_scipys_blas_loaded_after_it_is_set():
    import subprocess
    import sys

    code = ("from ebb_model.threads import single_blas_thread\n"
            "single_blas_thread()\n"
            "import scipy.linalg\n"
            "from threadpoolctl import threadpool_info\n"
            "print(sorted({i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas'}))\n")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout
    assert out.strip() == "[1]", out
