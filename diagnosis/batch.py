"""Many records, one diagnosis each, side by side: ``ebb diagnose CONFIG rec1 rec2 … --each``
(:func:`diagnose_each`).

A lab's campaign is a batch of records — one per test, per day, per specimen — each asking its own question of
the same model.  Each record is diagnosed on its own (its own baseline, its own held-out tail) as an independent
task: on local worker processes, or on a Dask cluster (a scheduler address, or ``local:K``) when one machine is
not enough.  On local processes a record's diagnosis runs in its process, so the batch's parallelism is the
records'; on a cluster a record's fits are tasks of the same cluster too (:mod:`diagnosis.search.workers`), so a long
record's fits spread over the workers the short ones have freed.  Every task is deterministic with one BLAS
thread, so a record's result does not depend on where it ran.

Output: ``OUT/<record stem>/`` per record (``gap.json``, plots, the corrected model), as a single diagnosis writes
it.  Every record is read and checked before the first task starts: a bad one stops the batch before anything is
written; the batch is written into a staged directory renamed onto ``OUT`` at the end, so an error or an
interrupt in any task leaves nothing behind.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Sequence

from ebb_model.config import BeamConfig
from ebb_model.errors import ClusterError, ConfigError
from ebb_model.io.output import check_new_output_dir, staged_dir
from identification.run import load_identification_config, read_data

from .search.workers import DaskExecutor, close_refit_pool, refit_pool, side_by_side, task_cluster

__all__ = ["diagnose_each"]


def _diagnose_one(config: BeamConfig, record: str, out: str, options: dict[str, Any]) -> dict[str, Any]:
    """One record's diagnosis, its ``gap.json`` document: in this process, its fits as tasks of the cluster when
    it runs on one (:func:`diagnosis.search.workers.task_cluster`)."""
    from .run import diagnose

    return diagnose(config, [record], out, workers=1, dask=task_cluster(), **options).document


def diagnose_each(config: BeamConfig | str | Path, data: Sequence[str | Path], out_dir: str | Path, *,
                  workers: int = 2, dask: Any = None, progress: Callable[[str], None] | None = None,
                  **options: Any) -> list[dict[str, Any]]:
    """Diagnose each record of ``data`` on its own, as independent tasks.

    Parameters
    ----------
    config
        Identification config (path or value), as for :func:`diagnosis.run.diagnose`.
    data
        The records, one diagnosis each (their file stems must differ: they name the output directories).
    out_dir
        Directory of the per-record directories; must not exist or be empty.
    workers
        Local processes running the records side by side (default 2; 1: one after the other in this process).
    dask
        Run them on a Dask cluster instead: a scheduler address, ``"local:K"`` or a ``distributed.Client``.
    options
        Further keywords of :func:`diagnosis.run.diagnose` (``holdout_fraction``, ``shortlist``, ``plots``,
        ``export``, ``targets``, ``noise_std``).

    Returns
    -------
    list of dict
        Each record's ``gap.json`` document, in the order of ``data``.

    Raises
    ------
    ConfigError, DataError
        Bad config, a record that cannot be read, two records with the same stem, a bad output directory —
        before anything is written.
    """
    say = progress or (lambda _m: None)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers: must be a whole number >= 1, got {workers!r}")
    bad = sorted(set(options) - {"holdout_fraction", "shortlist", "plots", "export", "targets", "noise_std"})
    if bad:
        raise ConfigError(f"diagnose_each: unknown option(s) {', '.join(bad)}")
    cfg = load_identification_config(config) if not isinstance(config, BeamConfig) else config
    paths = [Path(p) for p in data]
    if not paths:
        raise ConfigError("diagnose_each: no records")
    stems = [p.stem for p in paths]
    twice = sorted({s for s in stems if stems.count(s) > 1})
    if twice:
        raise ConfigError(f"records with the same name {', '.join(twice)}: each names its output directory")
    out = Path(out_dir)
    check_new_output_dir(out)
    for p in paths:
        read_data(cfg, [p])          # every record readable before the first task starts
    if isinstance(dask, str):
        from identification.cluster import parse_local_address

        parse_local_address(dask)
    with staged_dir(out) as staged:     # renamed onto OUT once every record is done: nothing partial is kept
        executor = refit_pool(min(workers, len(paths)), dask)
        where = (f"{executor.workers} Dask workers" if isinstance(executor, DaskExecutor)
                 else f"{min(workers, len(paths))} processes" if executor is not None else "this process")
        say(f"diagnosing {len(paths)} records, one task each, on {where}")
        try:
            docs = side_by_side(executor, _diagnose_one, [(cfg, str(p), str(staged / s), dict(options))
                                                          for p, s in zip(paths, stems)])
            events = executor.events() if isinstance(executor, DaskExecutor) else ()
        except BaseException as exc:
            if executor is not None:
                close_refit_pool(executor, now=True)   # Ctrl-C or a failed record: the others are not waited for
                executor = None
            if isinstance(exc, ClusterError):
                raise ClusterError(f"{exc}; no record's results were kept in {out}") from None
            raise
        finally:
            if executor is not None:
                close_refit_pool(executor, now=False)
    for event in events:
        say(f"note: {event}")
    for p, doc in zip(paths, docs):
        say(f"{p.name}: {doc['verdict']}")
    return docs
