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
interrupt in any task leaves nothing behind — except when the cluster's scheduler goes away: then the records
finished before are kept in ``OUT`` with ``batch.json`` (the digests of the config and the records, the options,
the records done), and ``resume=True`` (``--resume``) diagnoses the others — refused in one line when the config, a
record or an option differs from the checkpoint's.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path
from typing import Any, Callable, Sequence

from ebb_model.config import BeamConfig
from ebb_model.errors import ClusterError, ConfigError
from ebb_model.io.jsonio import write_json
from ebb_model.io.output import check_new_output_dir, make_dir, staged_dir
from identification.run import load_identification_config, read_data

from .run import GAP_FILE
from .search.workers import DaskExecutor, close_refit_pool, refit_pool, side_by_side, task_cluster

__all__ = ["diagnose_each", "BATCH_FILE"]

#: The checkpoint of a batch whose scheduler went away, in ``OUT``.
BATCH_FILE = "batch.json"


def _diagnose_one(config: BeamConfig, record: str, out: str, options: dict[str, Any]) -> dict[str, Any]:
    """One record's diagnosis, its ``gap.json`` document: in this process, its fits as tasks of the cluster when
    it runs on one (:func:`diagnosis.search.workers.task_cluster`)."""
    from .run import diagnose

    return diagnose(config, [record], out, workers=1, dask=task_cluster(), **options).document


def _checkpoint(cfg: BeamConfig, paths: Sequence[Path], options: dict[str, Any]) -> dict[str, Any]:
    """What a batch is made of: the config's and each record's digest (by stem), and the options."""
    def digest(data: bytes) -> str:
        return hashlib.sha256(data).hexdigest()

    return {"config": digest(json.dumps(cfg.to_dict(), sort_keys=True, default=str).encode()),
            "records": {p.stem: digest(p.read_bytes()) for p in paths},
            "options": json.loads(json.dumps(options, sort_keys=True, default=str))}


def _keep_finished(staged: Path, out: Path, stems: Sequence[str], made: dict[str, Any], before: Sequence[str]
                   ) -> list[str]:
    """Move the records finished in ``staged`` (their ``gap.json`` written) into ``out`` and write the checkpoint
    beside them; every record done (``before`` these)."""
    done = [s for s in stems if (staged / s / GAP_FILE).is_file()]
    make_dir(out, exist_ok=True, parents=True)
    for s in done:
        os.replace(staged / s, out / s)
    every = [s for s in stems if s in set(done) | set(before)]
    write_json(out / BATCH_FILE, made | {"done": every})
    return every


def _resumed(out: Path, made: dict[str, Any]) -> list[str]:
    """The records a checkpoint in ``out`` has done, after checking that it was made of the same config, records
    and options (one line naming what differs)."""
    try:
        kept = json.loads((out / BATCH_FILE).read_text())
    except (OSError, ValueError):
        raise ConfigError(f"`resume`: no batch checkpoint {out / BATCH_FILE} to resume from") from None
    for key, what in (("config", "the config"), ("records", "the records"), ("options", "the options")):
        if kept.get(key) != made[key]:
            raise ConfigError(f"`resume`: {what} differ from those of the checkpoint in {out}")
    return [s for s in kept.get("done", []) if (out / s / GAP_FILE).is_file()]


def diagnose_each(config: BeamConfig | str | Path, data: Sequence[str | Path], out_dir: str | Path, *,
                  workers: int = 2, dask: Any = None, progress: Callable[[str], None] | None = None,
                  resume: bool = False, **options: Any) -> list[dict[str, Any]]:
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
    resume
        Continue a batch whose scheduler went away (``OUT`` holds its checkpoint): diagnose the records not done.
    options
        Further keywords of :func:`diagnosis.run.diagnose` (``holdout_fraction``, ``shortlist``, ``plots``,
        ``export``, ``targets``, ``noise_std``).

    Returns
    -------
    list of dict
        Each record's ``gap.json`` document, in the order of ``data`` (a record done before a resume: as read
        back from its file).

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
    if not resume:
        check_new_output_dir(out)
    for p in paths:
        read_data(cfg, [p])          # every record readable before the first task starts
    made = _checkpoint(cfg, paths, options)
    done = _resumed(out, made) if resume else []
    if isinstance(dask, str):
        from identification.cluster import parse_local_address

        parse_local_address(dask)
    todo = [(p, s) for p, s in zip(paths, stems) if s not in done]
    target = out / ".resumed" if resume else out
    if resume:
        shutil.rmtree(target, ignore_errors=True)   # a resumed run's own leftovers, if it was stopped itself
    with staged_dir(target) as staged:     # renamed onto OUT once every record is done: nothing partial is kept
        executor = refit_pool(min(workers, max(len(todo), 1)), dask)
        where = (f"{executor.workers} Dask workers" if isinstance(executor, DaskExecutor)
                 else f"{min(workers, len(todo))} processes" if executor is not None else "this process")
        say(f"diagnosing {len(todo)} records, one task each, on {where}"
            + (f" ({len(done)} done before the resume)" if done else ""))
        try:
            fresh = side_by_side(executor, _diagnose_one, [(cfg, str(p), str(staged / s), dict(options))
                                                           for p, s in todo])
            events = executor.events() if isinstance(executor, DaskExecutor) else ()
        except BaseException as exc:
            if executor is not None:
                close_refit_pool(executor, now=True)   # Ctrl-C or a failed record: the others are not waited for
                executor = None
            if isinstance(exc, ClusterError):
                kept = _keep_finished(staged, out, stems, made, done)
                raise ClusterError(f"{exc}; {len(kept)} of {len(paths)} records are done and kept in {out}: "
                                   "continue with `resume` on a running cluster") from None
            raise
        finally:
            if executor is not None:
                close_refit_pool(executor, now=False)
    if resume:
        for _, s in todo:
            os.replace(target / s, out / s)
        shutil.rmtree(target, ignore_errors=True)
        (out / BATCH_FILE).unlink(missing_ok=True)
    by_stem = dict(zip([s for _, s in todo], fresh))
    docs = [by_stem[s] if s in by_stem else json.loads((out / s / GAP_FILE).read_text()) for s in stems]
    for event in events:
        say(f"note: {event}")
    for p, doc in zip(paths, docs):
        say(f"{p.name}: {doc['verdict']}")
    return docs
