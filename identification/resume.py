"""What a checkpoint was made with, so that ``resume`` continues the same run or refuses (:class:`RunRecord`).

A run writes ``run.json`` beside its checkpoint: a digest of the config, one of each record (its name, inputs and
outputs) and the GA's options.  ``resume`` reads it back: the config and the records must be those the checkpoint
was made with (the GA's front belongs to them: resumed on a record scaled by 1000 it would polish the new data
from the old front), and an option given again must have its old value — one not given takes the checkpoint's.
A mismatch is one line naming what differs.  A checkpoint without ``run.json`` (an older version's) is resumed
unchecked.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError
from ebb_model.io.jsonio import write_json

from .data import Experiment

__all__ = ["RUN_FILE", "OPTIONS", "RunRecord"]

#: The run's record, beside its checkpoint.
RUN_FILE = "run.json"
#: The GA's options and their defaults for a new run (a resumed run takes the checkpoint's).
OPTIONS: dict[str, Any] = {"pop": 40, "generations": 30, "seed": 1, "algorithm": "nsga2"}


def _digest(*parts: bytes) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(len(p).to_bytes(8, "little"))
        h.update(p)
    return h.hexdigest()


@dataclass(frozen=True)
class RunRecord:
    """The digests of a run's config and records, and its GA options."""

    config: str
    records: dict[str, str]
    options: dict[str, Any]

    @classmethod
    def of(cls, config: BeamConfig, experiments: Sequence[Experiment], options: Mapping[str, Any]) -> "RunRecord":
        """The record of a run of ``config`` on ``experiments`` with ``options``."""
        cfg = json.dumps(config.to_dict(), sort_keys=True, default=str).encode()
        recs = {e.name: _digest(np.ascontiguousarray(e.inputs, dtype=float).tobytes(),
                                np.ascontiguousarray(e.outputs, dtype=float).tobytes(),
                                json.dumps([list(e.input_names), list(e.output_names)]).encode())
                for e in experiments}
        return cls(_digest(cfg), recs, dict(options))

    def write(self, out: Path) -> None:
        """``out/run.json``."""
        write_json(out / RUN_FILE, {"config": self.config, "records": self.records, "options": self.options})

    @staticmethod
    def read(out: Path) -> "RunRecord | None":
        """The record in ``out`` (``None`` when the checkpoint has none)."""
        path = out / RUN_FILE
        if not path.is_file():
            return None
        try:
            doc = json.loads(path.read_text())
            return RunRecord(str(doc["config"]), dict(doc["records"]), dict(doc["options"]))
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ConfigError(f"`resume`: {path} is unreadable ({exc}); run afresh in a new directory") from None

    @staticmethod
    def options_for(stored: "RunRecord | None", given: Mapping[str, Any]) -> dict[str, Any]:
        """The GA options of the run: the given ones, the others from ``stored`` (a resume) or the defaults.

        Raises
        ------
        ConfigError
            A given option that differs from the checkpoint's, all named in one line.
        """
        base = OPTIONS if stored is None else {**OPTIONS, **stored.options}
        if stored is not None:
            bad = [f"{k} {stored.options[k]!r} (now {v!r})" for k, v in given.items()
                   if v is not None and k in stored.options and v != stored.options[k]]
            if bad:
                raise ConfigError("`resume`: the checkpoint was made with " + ", ".join(bad)
                                  + "; resume without them or run afresh in a new directory")
        return {k: (given.get(k) if given.get(k) is not None else base[k]) for k in OPTIONS}

    def check(self, current: "RunRecord", out: Path) -> None:
        """Refuse to resume the checkpoint in ``out`` with another config or other records (one line).

        Raises
        ------
        ConfigError
            Naming what differs.
        """
        what = []
        if current.config != self.config:
            what.append("a different config (its beam, parameters, bounds or settings differ)")
        if set(current.records) != set(self.records):
            what.append(f"different records ({', '.join(sorted(self.records))}; now "
                        f"{', '.join(sorted(current.records))})")
        else:
            changed = sorted(n for n in self.records if current.records[n] != self.records[n])
            if changed:
                what.append(f"different data in {', '.join(changed)}")
        if what:
            raise ConfigError(f"`resume`: the checkpoint in {out} belongs to " + " and ".join(what)
                              + "; resume with what it was made with, or run afresh in a new directory")
