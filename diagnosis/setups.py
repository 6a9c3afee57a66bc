"""Evidence belongs to a set-up: which rig parts were on the bench when each kind of evidence was measured.

A bench is often measured in more than one set-up — a hammer test of the bare beam for its modes, then the shaker
bolted on for the time records.  Read as one structure, the two disagree, and the shaker's attachment (which
changes the structure at the drive point) is vetoed by modes measured without it.  The config says which parts
were present where::

    [[setups]]
    name = "shaker on"
    parts = ["shaker", "transducer"]   # rig parts on the bench: "shaker", "transducer"
    evidence = ["records"]             # the time records were made in it

    [[setups]]
    name = "hammer test"
    parts = []
    evidence = ["modes"]               # the measured modes ([identification.modes] or --modes FILE)

An effect that models a rig part declares it (:attr:`diagnosis.effects.Effect.rig_part`: a shaker's armature at
its actuator, a transducer's mass at its sensor).  It is a candidate only when the records' set-up has the part,
and it is off in the measured modes when theirs does not; every other effect — and the beam's own parameters —
is shared by all set-ups.  Without a ``[[setups]]`` table every kind of evidence is one set-up with every part.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError

__all__ = ["RIG_PARTS", "SECTION", "EVIDENCE", "Setups", "setups_from_config"]

#: The config's list of set-ups.
SECTION = "setups"
#: The rig parts a set-up can have, each the rig part an effect of the catalogue models.
RIG_PARTS = ("shaker", "transducer")
#: The kinds of evidence a set-up can hold.
EVIDENCE = ("records", "modes")


@dataclass(frozen=True)
class Setups:
    """The set-up of each kind of evidence: its name and the rig parts it had."""

    names: dict[str, str]                  # evidence kind -> set-up name
    parts: dict[str, frozenset[str]]       # evidence kind -> rig parts present
    #: inferred by the diagnosis (:mod:`diagnosis.judgement.apart`), not declared
    inferred: bool = False

    @classmethod
    def apart(cls, lacking: frozenset[str]) -> "Setups":
        """The set-ups the diagnosis infers: the records with every rig part, the measured modes without
        ``lacking``."""
        every = frozenset(RIG_PARTS)
        return cls({"records": "the records' (inferred)", "modes": "the measured modes' (inferred)"},
                   {"records": every, "modes": every - lacking}, inferred=True)

    def modes_lack(self) -> frozenset[str]:
        """The rig parts of the records' set-up that the measured modes' set-up did not have."""
        return self.parts.get("records", frozenset(RIG_PARTS)) - self.parts.get("modes", frozenset(RIG_PARTS))

    def records_have(self, part: str) -> bool:
        """Whether the records' set-up had rig part ``part``."""
        return part in self.parts.get("records", frozenset(RIG_PARTS))

    def describe(self) -> str:
        """One line: which evidence comes from which set-up with which parts."""
        return "; ".join(f"{kind}: set-up '{self.names[kind]}' ({', '.join(sorted(self.parts[kind])) or 'no rig part'})"
                         for kind in EVIDENCE if kind in self.names)

    def to_dict(self) -> dict[str, Any]:
        """JSON values (``gap.json``'s ``setups``)."""
        out: dict[str, Any] = {kind: {"setup": self.names[kind], "parts": sorted(self.parts[kind])}
                               for kind in self.names}
        if self.inferred:
            out["inferred"] = True
        return out


def setups_from_config(config: BeamConfig) -> Setups | None:
    """The config's ``[[setups]]`` (module docstring), checked; ``None`` when it has none.

    Raises
    ------
    ConfigError
        One line per problem: not a list of tables, a set-up without a name or with an unknown key, an unknown
        rig part or kind of evidence, evidence in two set-ups, a name used twice.
    """
    raw = config.extra.get(SECTION)
    if raw is None:
        return None
    if not isinstance(raw, (list, tuple)) or not all(isinstance(s, dict) for s in raw) or not raw:
        raise ConfigError(f"{SECTION}: must be a list of tables ([[setups]] with name, parts, evidence)")
    bad: list[str] = []
    names: dict[str, str] = {}
    parts: dict[str, frozenset[str]] = {}
    seen: set[str] = set()
    for i, s in enumerate(raw):
        where = f"{SECTION}[{i}]"
        name = s.get("name")
        if not isinstance(name, str) or not name.strip():
            bad.append(f"{where}.name: must be a non-empty string, got {name!r}")
            continue
        where = f"{SECTION} '{name}'"
        if name in seen:
            bad.append(f"{where}: the name is used twice")
        seen.add(name)
        bad += [f"{where}.{k}: unknown key; allowed: name, parts, evidence" for k in s
                if k not in ("name", "parts", "evidence")]
        got_parts, evidence = s.get("parts", []), s.get("evidence", [])
        if not isinstance(got_parts, (list, tuple)) or not all(isinstance(p, str) for p in got_parts):
            bad.append(f"{where}.parts: must be a list of rig parts ({', '.join(RIG_PARTS)}), got {got_parts!r}")
            got_parts = []
        bad += [f"{where}.parts: unknown rig part {p!r}; known: {', '.join(RIG_PARTS)}" for p in got_parts
                if p not in RIG_PARTS]
        if not isinstance(evidence, (list, tuple)) or not all(isinstance(e, str) for e in evidence):
            bad.append(f"{where}.evidence: must be a list of {', '.join(EVIDENCE)}, got {evidence!r}")
            evidence = []
        for kind in evidence:
            if kind not in EVIDENCE:
                bad.append(f"{where}.evidence: unknown kind {kind!r}; known: {', '.join(EVIDENCE)}")
            elif kind in names:
                bad.append(f"{where}.evidence: {kind} belongs to set-up '{names[kind]}' already")
            else:
                names[kind] = name
                parts[kind] = frozenset(p for p in got_parts if p in RIG_PARTS)
    if "records" not in names and not bad:
        bad.append(f"{SECTION}: no set-up holds the records (evidence = [\"records\"])")
    if bad:
        raise ConfigError(bad)
    return Setups(names, parts)
