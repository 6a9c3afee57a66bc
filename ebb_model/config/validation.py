"""Reading and validating a beam config: TOML or nested dicts in, :class:`~ebb_model.config.types.BeamConfig` out.

Validation reports **every** problem at once (FMPy's ``validate_fmu`` habit), each naming its field, in one
:class:`~ebb_model.errors.ConfigError`. The TOML layout is described in :mod:`ebb_model.config`.
"""
from __future__ import annotations

import math
import os
import re
import tomllib
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

from ..acquisition.antialias import MAX_ORDER, AntiAlias, channel_problems
from ..acquisition.channel_delay import channel_problems as delay_problems
from ..beam import END_KINDS, PARAMETER_NAMES, SENSOR_KINDS, Actuator, End, PointMass, PointSpring, Sensor, WeakSegment
from .types import (DEFAULT_INPUT, INPUT_HOLDS, MAX_NODES, SCHEMES, BeamConfig, BeamGeometry, ParameterSpec,
                           TimeSettings)
from ..errors import ConfigError, ConfigWarning
from ..parameter_values import NON_NEGATIVE, POSITIVE, range_problem
from .problems import Problems
from ..io.textio import read_text

__all__ = ["load_config", "config_from_dict"]

_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")

#: Beam lengths [m] the model accepts: nanobeams to bridges, far inside the floating-point range of its
#: grid terms (``h⁴`` overflows from about 1e77 m); beyond, a length is a typo, not a beam.
LENGTH_RANGE = (1e-9, 1e6)
#: The longest sample time [s] the model accepts (a record sampled slower than this is a typo).
MAX_DT = 1e3

#: Values of the optional parameters when a config omits them (each switches its effect off).
_DEFAULTS: Mapping[str, float] = MappingProxyType({"c": 0.0, "eta": 0.0, "N": 0.0, "rhoI": 0.0, "kf": 0.0})


def load_config(path: str | os.PathLike[str], *, extra_sections: tuple[str, ...] = ()) -> BeamConfig:
    """Read and validate a TOML config file.

    Parameters
    ----------
    path
        The TOML file.
    extra_sections
        Top-level tables that a higher layer (e.g. identification) reads
        itself; they are kept verbatim in :attr:`BeamConfig.extra`.  Any other
        unknown key is an error.

    Raises
    ------
    ConfigError
        Listing every problem found, each naming its field.
    """
    p = Path(path)
    text = read_text(p, ConfigError, what="config file")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML ({exc})") from None
    return config_from_dict(data, extra_sections=extra_sections)


def _table(pr: Problems, data: Mapping[str, Any], key: str, required: bool = True) -> Mapping[str, Any]:
    v = data.get(key)
    if v is None:
        if required:
            pr.add(f"[{key}]", "missing table")
        return {}
    if not isinstance(v, Mapping):
        pr.add(key, f"must be a table, got {type(v).__name__}")
        return {}
    return v


def _end(pr: Problems, beam: Mapping[str, Any], side: str) -> End | None:
    kind = beam.get(side)
    if kind is None:
        pr.add(f"beam.{side}", f"missing; one of {', '.join(END_KINDS)}")
        return None
    if kind not in END_KINDS:
        pr.add(f"beam.{side}", f"unknown boundary condition {kind!r}; allowed: {', '.join(END_KINDS)}")
        return None
    springs: dict[str, float | None] = {}
    for s in ("kt", "kr"):
        key = f"{side}_{s}"
        if key in beam:
            if kind != "elastic":
                pr.add(f"beam.{key}", f"only allowed when beam.{side} = \"elastic\" (it is {kind!r})")
                continue
            v = pr.number(f"beam.{key}", beam[key], allow_inf=True)
            if v is not None and v < 0:
                pr.add(f"beam.{key}", f"must be >= 0 (0 ... inf), got {v}")
                v = None
            springs[s] = v
        elif kind == "elastic":
            pr.add(f"beam.{key}", f"required when beam.{side} = \"elastic\" (a stiffness in [0, inf])")
    if kind == "elastic":
        if springs.get("kt") is None or springs.get("kr") is None:
            return None
        return End.of("elastic", springs["kt"], springs["kr"])
    return End.of(kind)


def _parameters(pr: Problems, table: Mapping[str, Any]) -> dict[str, ParameterSpec]:
    specs: dict[str, ParameterSpec] = {}
    defaults = _DEFAULTS
    for k in table:
        if k not in PARAMETER_NAMES:
            pr.add(f"parameters.{k}", f"unknown parameter; allowed: {', '.join(PARAMETER_NAMES)}")
    for k in PARAMETER_NAMES:
        where = f"parameters.{k}"
        raw = table.get(k)
        if raw is None:
            if k in defaults:
                specs[k] = ParameterSpec(defaults[k])
            else:
                pr.add(where, "missing (give { value = ... })")
            continue
        if not isinstance(raw, Mapping):
            raw = {"value": raw}
        pr.unknown_keys(where, raw, ("value", "bounds", "identify", "prior_std"))
        value = pr.number(f"{where}.value", raw.get("value")) if "value" in raw else None
        if "value" not in raw:
            pr.add(f"{where}.value", "missing")
        if value is not None and (problem := range_problem(k, value)) is not None:
            pr.add(f"{where}.value", problem)
            value = None
        bounds = None
        if "bounds" in raw:
            b = raw["bounds"]
            if not isinstance(b, (list, tuple)) or len(b) != 2:
                pr.add(f"{where}.bounds", f"must be [lo, hi], got {b!r}")
            else:
                lo = pr.number(f"{where}.bounds[0]", b[0])
                hi = pr.number(f"{where}.bounds[1]", b[1])
                if lo is not None and hi is not None:
                    if not lo < hi:
                        pr.add(f"{where}.bounds", f"lower bound must be < upper bound, got [{lo:g}, {hi:g}]")
                    elif k in POSITIVE and lo <= 0:
                        pr.add(f"{where}.bounds", f"lower bound must be > 0 for {k}, got {lo:g}")
                    elif k in NON_NEGATIVE and lo < 0:
                        pr.add(f"{where}.bounds", f"lower bound must be >= 0 for {k}, got {lo:g}")
                    elif (problem := range_problem(k, lo) or range_problem(k, hi)) is not None:
                        pr.add(f"{where}.bounds", f"each bound {problem}")
                    else:
                        bounds = (lo, hi)
                        if value is not None and not lo <= value <= hi:
                            pr.add(f"{where}.value", f"{value:g} lies outside bounds [{lo:g}, {hi:g}]")
        identify = raw.get("identify", False)
        if not isinstance(identify, bool):
            pr.add(f"{where}.identify", f"must be true or false, got {identify!r}")
            identify = False
        if identify and "bounds" not in raw:
            pr.add(f"{where}.bounds", "required when identify = true")
        prior_std = None
        if "prior_std" in raw:
            prior_std = pr.number(f"{where}.prior_std", raw["prior_std"])
            if prior_std is not None and not prior_std > 0:
                pr.add(f"{where}.prior_std", f"must be > 0 (the prior's standard deviation), got {prior_std:g}")
                prior_std = None
            elif prior_std is not None and not identify:
                pr.add(f"{where}.prior_std", "a prior belongs to an identified parameter (identify = true)")
                prior_std = None
        if value is not None:
            specs[k] = ParameterSpec(value, bounds, identify, prior_std)
    return specs


def _warn_fixed_actuators(actuators: list[Actuator], length: float, left: End, right: End) -> None:
    """A :class:`ConfigWarning` for every actuator on an end whose deflection is held (``kt = inf``: clamped,
    pinned): its force goes straight into the support and every output it drives is zero."""
    import warnings

    for a in actuators:
        for side, end, at in (("left", left, 0.0), ("right", right, length)):
            if math.isinf(end.kt) and abs(a.x - at) <= 1e-12 * length:
                warnings.warn(f"actuator {a.name!r} at x = {a.x:g} m acts on the {end.kind} {side} end, which does "
                              "not move: its force goes into the support and the outputs it drives are all zero",
                              ConfigWarning, stacklevel=2)


def _points(pr: Problems, data: Mapping[str, Any], key: str, length: float | None,
            fields: tuple[str, ...], required: bool) -> list[dict[str, Any]]:
    raw = data.get(key, [])
    if not isinstance(raw, list):
        pr.add(key, f"must be an array of tables ([[{key}]]), got {type(raw).__name__}")
        return []
    if required and not raw:
        pr.add(f"[[{key}]]", "at least one entry is required")
    out = []
    for i, item in enumerate(raw):
        where = f"{key}[{i}]"
        if not isinstance(item, Mapping):
            pr.add(where, "must be a table")
            continue
        pr.unknown_keys(where, item, fields)
        name = item.get("name")
        if name is None:
            pr.add(f"{where}.name", "missing")
        elif not isinstance(name, str) or not _NAME_RE.match(name):
            pr.add(f"{where}.name", f"must be an ASCII identifier (letters A-Z a-z, digits 0-9 and _, not "
                                    f"starting with a digit), got {name!r}")
            name = None
        if "x" not in item:
            pr.add(f"{where}.x", "missing (position along the beam, m)")
            x = None
        else:
            x = pr.number(f"{where}.x", item["x"])
        if x is not None and length is not None and not 0.0 <= x <= length:
            pr.add(f"{where}.x", f"position {x:g} m lies outside the beam [0, {length:g}] m")
            x = None
        out.append({"name": name, "x": x, "raw": item, "where": where})
    return out


def _antialias(pr: Problems, channel: dict[str, Any], dt: float | None, scheme: str) -> AntiAlias | None:
    """A sensor's or actuator's ``antialias = {order, corner}`` (:mod:`ebb_model.acquisition.antialias`), or ``None``;
    every problem added to ``pr``."""
    raw = channel["raw"].get("antialias")
    if raw is None:
        return None
    where = f"{channel['where']}.antialias"
    if not isinstance(raw, Mapping):
        pr.add(where, "must be a table {order = N, corner = Hz} (a Butterworth low-pass before the sampler)")
        return None
    pr.unknown_keys(where, raw, ("order", "corner"))
    order = raw.get("order")
    if isinstance(order, bool) or not isinstance(order, int) or not 1 <= order <= MAX_ORDER:
        pr.add(f"{where}.order", f"must be a whole number from 1 to {MAX_ORDER}, got {order!r}")
        order = None
    corner = None
    if "corner" not in raw:
        pr.add(f"{where}.corner", "missing (the filter's -3 dB corner, Hz)")
    else:
        corner = pr.number(f"{where}.corner", raw["corner"])
        if corner is not None and not corner > 0:
            pr.add(f"{where}.corner", f"must be > 0 Hz, got {corner:g}")
            corner = None
        elif corner is not None and dt is not None and corner * dt > 50.0:
            pr.add(f"{where}.corner", f"{corner:g} Hz is more than 50 times the sample rate {1 / dt:g} Hz "
                                      "(it leaves the record as it is): leave the filter out")
            corner = None
    if scheme == "theta":
        pr.add(where, "needs scheme = \"exact\" (the filter is integrated exactly in time with the beam)")
        return None
    return AntiAlias(order, corner) if order is not None and corner is not None else None


def _delay(pr: Problems, channel: dict[str, Any]) -> float:
    """A channel's ``delay`` [s] (:mod:`ebb_model.acquisition.channel_delay`): finite and ``>= 0``, 0 when absent; every
    problem added to ``pr``."""
    if "delay" not in channel["raw"]:
        return 0.0
    where = f"{channel['where']}.delay"
    d = pr.number(where, channel["raw"]["delay"])
    if d is not None and not d >= 0.0:
        pr.add(where, f"must be >= 0 s (a converter reports a signal late, never early), got {d:g}")
        return 0.0
    return 0.0 if d is None else float(d)


def _attached(pr: Problems, points: list[dict[str, Any]], key: str, unit: str) -> list[tuple[dict[str, Any], float]]:
    """The valid point attachments of ``points`` (``[[masses]]``, ``[[springs]]``) with their value ``key``
    (finite, >= 0, in ``unit``); every problem added to ``pr``."""
    out = []
    for m in points:
        if key not in m["raw"]:
            pr.add(f"{m['where']}.{key}", f"missing ({unit})")
            continue
        v = pr.number(f"{m['where']}.{key}", m["raw"][key])
        if v is not None and v < 0:
            pr.add(f"{m['where']}.{key}", f"must be >= 0, got {v:g}")
        elif v is not None and m["name"] is not None and m["x"] is not None:
            out.append((m, v))
    return out


def _weak_segments(pr: Problems, points: list[dict[str, Any]], length: float | None) -> list[WeakSegment]:
    """The valid ``[[weak_segments]]``: ``length`` > 0 inside the beam, ``factor`` in (0, 1]; every problem added
    to ``pr``."""
    out = []
    for w in points:
        where, raw = w["where"], w["raw"]
        values = {}
        for key, unit in (("length", "m"), ("factor", "remaining fraction of EI")):
            if key not in raw:
                pr.add(f"{where}.{key}", f"missing ({unit})")
            else:
                values[key] = pr.number(f"{where}.{key}", raw[key])
        seg_len, factor = values.get("length"), values.get("factor")
        if seg_len is not None and not seg_len > 0:
            pr.add(f"{where}.length", f"must be > 0 m, got {seg_len:g}")
            seg_len = None
        if factor is not None and not 0.0 < factor <= 1.0:
            pr.add(f"{where}.factor", f"must lie in (0, 1] (the remaining fraction of EI), got {factor:g}")
            factor = None
        if seg_len is not None and w["x"] is not None and length is not None and \
                not (w["x"] - seg_len / 2 >= 0.0 and w["x"] + seg_len / 2 <= length):
            pr.add(f"{where}.length", f"the segment {w['x'] - seg_len / 2:g} … {w['x'] + seg_len / 2:g} m leaves the "
                                      f"beam [0, {length:g}] m")
            seg_len = None
        if seg_len is not None and factor is not None and None not in (w["x"], w["name"]):
            out.append(WeakSegment(w["name"], w["x"], seg_len, factor))
    return out


def _rebuild_config(data: dict[str, Any], extra_sections: tuple[str, ...]) -> BeamConfig:
    return config_from_dict(data, extra_sections=extra_sections)


def config_from_dict(data: Mapping[str, Any], *, extra_sections: tuple[str, ...] = ()) -> BeamConfig:
    """Validate a config given as nested dicts (e.g. parsed TOML or JSON).

    Raises
    ------
    ConfigError
        Listing every problem found, each naming its field.
    """
    pr = Problems()
    if not isinstance(data, Mapping):
        raise ConfigError(f"config: must be a table, got {type(data).__name__}")
    allowed = ("beam", "time", "parameters", "actuators", "sensors", "masses", "springs", "weak_segments") \
        + tuple(extra_sections)
    pr.unknown_keys("", data, allowed)

    beam_t = _table(pr, data, "beam")
    pr.unknown_keys("beam", beam_t, ("length", "nodes", "left", "right",
                                     "left_kt", "left_kr", "right_kt", "right_kr"))
    length = None
    if "length" not in beam_t:
        pr.add("beam.length", "missing (m)")
    else:
        length = pr.number("beam.length", beam_t["length"])
        if length is not None and not LENGTH_RANGE[0] <= length <= LENGTH_RANGE[1]:
            pr.add("beam.length", f"must lie in {LENGTH_RANGE[0]:g} … {LENGTH_RANGE[1]:g} m, got {length:g}")
            length = None
    nodes = beam_t.get("nodes")
    if nodes is None:
        pr.add("beam.nodes", "missing (number of interior grid points, >= 4)")
    elif isinstance(nodes, bool) or not isinstance(nodes, int) or nodes < 4:
        pr.add("beam.nodes", f"must be an integer >= 4, got {nodes!r}")
        nodes = None
    elif nodes > MAX_NODES:
        pr.add("beam.nodes", f"must be <= {MAX_NODES}, got {nodes} (the standalone FMU's limit; the modal analysis "
                             "grows as nodes³)")
        nodes = None
    left = _end(pr, beam_t, "left") if beam_t else None
    right = _end(pr, beam_t, "right") if beam_t else None

    time_t = _table(pr, data, "time")
    pr.unknown_keys("time", time_t, ("dt", "theta", "substeps", "input", "scheme"))
    scheme = time_t.get("scheme", TimeSettings.scheme)
    if not isinstance(scheme, str) or scheme not in SCHEMES:
        pr.add("time.scheme", f"must be one of {', '.join(SCHEMES)}, got {scheme!r}")
        scheme = TimeSettings.scheme
    input_hold = time_t.get("input", DEFAULT_INPUT.get(scheme, "foh"))
    if input_hold not in INPUT_HOLDS:
        pr.add("time.input", "must be \"cubic\" (cubic through the samples, exact scheme), \"bandlimited\" "
                             "(the samples' band-limited interpolant up to 0.4 fs, exact scheme), \"foh\" (straight "
                             f"line between samples) or \"zoh\" (sample held), got {input_hold!r}")
    elif input_hold in ("cubic", "bandlimited") and scheme == "theta":
        pr.add("time.input", f"\"{input_hold}\" needs scheme = \"exact\"; the theta-scheme takes \"foh\" or \"zoh\"")
    dt = None
    if "dt" not in time_t:
        pr.add("time.dt", "missing (sample time, s)")
    else:
        dt = pr.number("time.dt", time_t["dt"])
        if dt is not None and not 0 < dt <= MAX_DT:
            pr.add("time.dt", f"must be > 0 and at most {MAX_DT:g} s, got {dt:g}")
            dt = None
    theta = pr.number("time.theta", time_t.get("theta", 0.25))
    if theta is not None and not 0.0 <= theta <= 1.0:
        pr.add("time.theta", f"must lie in [0, 1], got {theta:g}")
        theta = None
    substeps = time_t.get("substeps", 1)
    if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
        pr.add("time.substeps", f"must be an integer >= 1, got {substeps!r}")
        substeps = None

    params = _parameters(pr, _table(pr, data, "parameters"))

    acts = _points(pr, data, "actuators", length, ("name", "x", "antialias", "delay"), required=True)
    sens = _points(pr, data, "sensors", length, ("name", "x", "kind", "antialias", "delay"), required=True)
    mass = _points(pr, data, "masses", length, ("name", "x", "mass"), required=False)
    spring = _points(pr, data, "springs", length, ("name", "x", "k"), required=False)
    sensors: list[Sensor] = []
    for s in sens:
        kind = s["raw"].get("kind", "displacement")
        if kind not in SENSOR_KINDS:
            pr.add(f"{s['where']}.kind", f"unknown sensor kind {kind!r}; allowed: {', '.join(SENSOR_KINDS)}")
        elif s["name"] is not None and s["x"] is not None:
            sensors.append(Sensor(s["name"], s["x"], kind, _antialias(pr, s, dt, scheme), _delay(pr, s)))
    masses = [PointMass(m["name"], m["x"], v) for m, v in _attached(pr, mass, "mass", "kg")]
    springs = [PointSpring(k["name"], k["x"], v) for k, v in _attached(pr, spring, "k", "N/m")]
    weak = _points(pr, data, "weak_segments", length, ("name", "x", "length", "factor"), required=False)
    weak_segments = _weak_segments(pr, weak, length)
    actuators = [Actuator(a["name"], a["x"], _antialias(pr, a, dt, scheme), _delay(pr, a)) for a in acts
                 if a["name"] is not None and a["x"] is not None]
    for problem in channel_problems(actuators, sensors):
        pr.add(*problem)
    for problem in delay_problems(actuators, sensors, dt, input_hold, scheme):
        pr.add(*problem)

    names = [a["name"] for a in acts] + [s["name"] for s in sens] + [m["name"] for m in mass + spring + weak]
    seen: set[str] = set()
    for n in names:
        if n is None:
            continue
        if n in seen:
            pr.add("names", f"{n!r} is used more than once (actuator, sensor, mass, spring and segment names must "
                            "be unique)")
        seen.add(n)
        if n in PARAMETER_NAMES:
            pr.add("names", f"{n!r} clashes with a parameter name")

    if pr.items:
        raise ConfigError(pr.items)
    assert length is not None and nodes is not None and left is not None and right is not None
    assert dt is not None and theta is not None and substeps is not None
    extra = {k: data[k] for k in extra_sections if k in data}
    _warn_fixed_actuators(actuators, length, left, right)
    return BeamConfig(
        beam=BeamGeometry(length, nodes, left, right),
        time=TimeSettings(dt, theta, substeps, input_hold, scheme),
        parameters=MappingProxyType(params),
        actuators=tuple(actuators),
        sensors=tuple(sensors),
        masses=tuple(masses),
        springs=tuple(springs),
        weak_segments=tuple(weak_segments),
        extra=MappingProxyType(extra),
    )
