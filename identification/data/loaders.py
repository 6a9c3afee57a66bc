"""Loading experiments from files: pick the configured signals, convert units, check, resample.

Pipeline of :func:`load_experiment` (every format goes through the same
steps, so every format gives the same errors)::

    file --reader--> RawTable --mapping--> time + one column per actuator/sensor
         --checks--> lengths, finite values, increasing time (naming file, column, sample)
         --units---> SI (lbf -> N, g -> m/s2, ...)
         --gains---> optional per-signal factor (sign convention, calibration)
         --time----> printed times snapped to their uniform grid (see timebase)
         --offset--> optional removal of the static offset
         --band----> optional zero-phase band limitation (same filter on every signal)
         --resample> optional, to the config's dt
         --check---> Experiment.check_against(config): names and dt

Supported formats (by extension, or ``format=``):

=========  ==============  ===================================================
format     extensions      channels named by
=========  ==============  ===================================================
``csv``    .csv            header row; time column ``time``
``npz``    .npz            array names; time array ``time``
``mat``    .mat            variable names; time variable ``time``
``lvm``    .lvm            column headings (``X_Value``, ...) or column index;
                           time = column 0 (the X column)
``uff58``  .uff, .unv      record ID line 1 (``id1``) or record index;
                           time = the records' abscissa
=========  ==============  ===================================================
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Literal, Mapping

import numpy as np

from ebb_model.beam import SENSOR_UNITS
from ebb_model.config import BeamConfig
from ebb_model.errors import DataError
from ebb_model.io.signals_io import check_time_vector
from ebb_model.io.textio import printable

from .binary_formats import read_mat, read_npz
from .csv_format import read_csv
from .experiment import Experiment
from .filtering import condition
from .lvm import read_lvm
from .text_table import read_text_table
from .table import RawTable
from .timebase import regularise_time, resample_uniform
from .units import to_si_factor

__all__ = ["load_experiment", "load_experiments", "DataFormat", "FORMATS", "EXTENSIONS", "OFFSET_MODES"]


def _read_uff58(path: Path) -> RawTable:
    from .uff import read_uff58      # pyuff is imported only when a universal file is read
    return read_uff58(path)


@dataclass(frozen=True)
class DataFormat:
    """A data format: its reader (a file to a :class:`RawTable`) and the file extensions that select it."""

    read: Callable[[Path], RawTable]
    extensions: tuple[str, ...]


#: The data formats by name — a new format is its reader module and one line here.
FORMATS: Mapping[str, DataFormat] = {
    "csv": DataFormat(read_csv, (".csv",)),
    "npz": DataFormat(read_npz, (".npz",)),
    "mat": DataFormat(read_mat, (".mat",)),
    "lvm": DataFormat(read_lvm, (".lvm",)),
    "uff58": DataFormat(_read_uff58, (".uff", ".unv")),
    "txt": DataFormat(read_text_table, (".txt", ".tsv", ".dat")),
}
#: file extension -> format name
EXTENSIONS: Mapping[str, str] = {ext: name for name, f in FORMATS.items() for ext in f.extensions}
#: a format may also be named by one of its extensions without the dot (``format = "unv"``)
_FORMAT_ALIASES = {ext[1:]: name for ext, name in EXTENSIONS.items()}
#: accepted values of ``remove_offset`` (``True`` means ``"mean"``, ``None`` means ``False``)
OFFSET_MODES = (False, "mean", "pre-trigger")

Key = str | int
_Role = tuple[str, str, str]     # (signal name, "actuator" | "sensor", quantity)


def _format_of(path: Path, fmt: str | None) -> str:
    f: str | None
    if fmt is not None:
        f = _FORMAT_ALIASES.get(str(fmt).lower(), str(fmt).lower())
        if f not in FORMATS:
            raise DataError(f"{path}: unknown format {fmt!r}; allowed: {', '.join(FORMATS)}")
        return f
    f = EXTENSIONS.get(path.suffix.lower())
    if f is None:
        raise DataError(f"{path}: cannot tell the format from the extension {path.suffix!r}; "
                        f"known: {', '.join(EXTENSIONS)} (or name the format, one of {', '.join(FORMATS)}: "
                        "format = ... under [identification.data], format= in the API)")
    return f


def _offset_mode(path: Path, remove_offset: Any, pre_trigger: float | None) -> str | bool:
    mode: str | bool
    if remove_offset is None or remove_offset is False:
        mode = False
    elif remove_offset is True:
        mode = "mean"
    elif isinstance(remove_offset, str) and remove_offset in ("mean", "pre-trigger"):
        mode = remove_offset
    else:
        raise DataError(f"{path}: remove_offset={remove_offset!r}; allowed: False, 'mean' (or True), "
                        f"'pre-trigger'")
    if mode == "pre-trigger":
        if pre_trigger is None or not np.isfinite(pre_trigger) or pre_trigger <= 0:
            raise DataError(f"{path}: remove_offset='pre-trigger' needs pre_trigger > 0 (seconds of quiet "
                            f"record before the excitation), got {pre_trigger!r}")
    elif pre_trigger is not None:
        raise DataError(f"{path}: pre_trigger is only used with remove_offset='pre-trigger'")
    return mode


def _check_options(path: Path, config: BeamConfig, mapping: Mapping[str, Key] | None,
                   units: Mapping[str, str] | None, gains: Mapping[str, float] | None = None
                   ) -> tuple[dict[str, Key], dict[str, str], dict[str, float]]:
    signals = config.input_names + config.output_names
    problems: list[str] = []
    tables: dict[str, Mapping[str, Any] | None] = {"mapping": mapping, "units": units, "gains": gains}
    for name, table in tables.items():
        if table is not None and not isinstance(table, Mapping):
            problems.append(f"{name}: must be a table {{signal = ...}}, got {table!r}")
            tables[name] = None
    mapping, units, gains = tables["mapping"], tables["units"], tables["gains"]
    m = dict(mapping or {})
    v: Any  # a value as the caller gave it (checked here)
    for k, v in m.items():
        if k not in signals and k != "time":
            problems.append(f"mapping: {k!r} is not a signal of the config; allowed: time, {', '.join(signals)}")
        elif isinstance(v, bool) or not isinstance(v, (str, int, np.integer)):
            problems.append(f"mapping[{k!r}]: must be a column name or index, got {v!r}")
    u = dict(units or {})
    for k in u:
        if k not in signals:
            problems.append(f"units: {k!r} is not a signal of the config; allowed: {', '.join(signals)}")
    g: dict[str, float] = {}
    for k, v in dict(gains or {}).items():
        if k not in signals:
            problems.append(f"gains: {k!r} is not a signal of the config; allowed: {', '.join(signals)}")
        elif isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) \
                or not np.isfinite(v) or v == 0:
            problems.append(f"gains[{k!r}]: must be a finite, non-zero number, got {v!r}")
        else:
            g[k] = float(v)
    if problems:
        raise DataError(f"{path}: " + problems[0] if len(problems) == 1 else
                        f"{path}: {len(problems)} problems:\n" + "\n".join(f"  - {p}" for p in problems))
    return m, u, g


def _lookup(table: RawTable, key: Key) -> int | None:
    if isinstance(key, str) and table.names.count(key) > 1:
        raise DataError(f"{table.source}: {table.kind} name {key!r} occurs {table.names.count(key)} times; "
                        f"map the signal by index instead")
    return table.index(key)


def _vector(table: RawTable, i: int, n: int | None, what: str) -> np.ndarray:
    """Channel ``i`` as a float vector of length ``n``, or a DataError naming file and channel."""
    src, label = table.source, table.label(i)
    why = table.why_unusable(i)
    if why is not None:
        raise DataError(f"{src}: {label} ({what}) {why}")
    a = np.asarray(table.columns[i])
    if a.ndim == 2 and 1 in a.shape:
        a = a.reshape(-1)
    if a.ndim != 1:
        raise DataError(f"{src}: {label} ({what}) has shape {a.shape}; expected a vector")
    if a.dtype.kind not in "biuf":
        raise DataError(f"{src}: {label} ({what}) is not real numeric data (dtype {a.dtype})")
    if n is not None and a.size != n:
        raise DataError(f"{src}: {label} ({what}) has {a.size} samples but time has {n} -- mismatched lengths")
    return a.astype(float)


def _check_finite(a: np.ndarray, t: np.ndarray, where: str) -> None:
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        i = int(bad[0])
        raise DataError(f"{where}: non-finite value {float(a[i])!r} at sample {i} (t = {t[i]:.9g} s)"
                        + (f"; {bad.size} non-finite samples in all" if bad.size > 1 else ""))


def _time_vector(table: RawTable, cmap: Mapping[str, Key]) -> tuple[np.ndarray, str, float, dict[int, str]]:
    """The record's time: the mapped (or the format's) time channel, or the time the file's headers define.

    Parameters
    ----------
    table, cmap
        The file's channels and the checked ``mapping`` (its ``"time"`` entry names the time channel).

    Returns
    -------
    t, time_label, tol, used
        Times (checked finite and increasing), their origin for messages, their tolerance for
        :func:`regularise_time`, ``{channel index: "time"}`` if a channel is the time (else empty).

    Raises
    ------
    DataError
        A missing or unusable time channel; non-finite or non-increasing times.
    """
    src = table.source
    if "time" in cmap or table.time is None:
        key = cmap.get("time", table.time_key)
        ti = _lookup(table, key)
        if ti is None:
            raise DataError(f"{src}: missing time {table.kind} {key!r}; found {printable(', '.join(table.names))}"
                            + ("" if "time" in cmap else
                               " (name it with mapping = { time = ... } under [identification.data])"))
        t = _vector(table, ti, None, "time")
        time_label = f"{src}: time ({table.label(ti)})"
        tol = 0.5 * table.resolution[ti]
        used = {ti: "time"}
    else:
        t = np.asarray(table.time, dtype=float)
        time_label, tol, used = f"{src}: time", table.time_tolerance, {}
    check_time_vector(t, where=time_label)
    return t, time_label, tol, used


def _signal_channels(table: RawTable, roles: list[_Role], cmap: Mapping[str, Key],
                     used: Mapping[int, str]) -> dict[str, int]:
    """The file channel of every config signal, by ``cmap`` or by the signal's own name.

    Parameters
    ----------
    table, roles, cmap, used
        The file's channels, ``(signal, role, quantity)`` of every actuator and sensor, the checked
        ``mapping``, the channel taken by the time.

    Returns
    -------
    dict
        Signal name -> channel index.

    Raises
    ------
    DataError
        A channel used as time and signal; missing channels (all listed).
    """
    src = table.source
    idx: dict[str, int] = {}
    missing = []
    for sig, role, _ in roles:
        key = cmap.get(sig, sig)
        i = _lookup(table, key)
        if i is None:
            missing.append(f"{key!r} ({role} {sig})" if key != sig else repr(sig))
            continue
        if used.get(i) == "time":
            raise DataError(f"{src}: {table.label(i)} is used both as the time and as {role} {sig!r}")
        idx[sig] = i
    if missing:
        raise DataError(f"{src}: missing {table.kind}(s) {', '.join(missing)}; found "
                        f"{printable(', '.join(table.names))} (name the file's channels with mapping = {{ ... }} "
                        "under [identification.data])")
    return idx


def _signal_in_si(table: RawTable, i: int, role: _Role, t: np.ndarray, cunits: Mapping[str, str],
                  cgains: Mapping[str, float]) -> np.ndarray:
    """Channel ``i`` as the config signal ``role``: checked, converted to SI, times its gain.

    Parameters
    ----------
    table, i, role
        The file's channels, the signal's channel and its ``(signal, role, quantity)``.
    t
        The record's time (its length and the instants named in messages).
    cunits, cgains
        The checked ``units`` and ``gains``.

    Returns
    -------
    numpy.ndarray
        The signal in SI units.

    Raises
    ------
    DataError
        Wrong length or type, a non-finite value, an unknown or unfitting unit.
    """
    src = table.source
    sig, role_name, quantity = role
    what = f"{role_name} {sig!r}"
    a = _vector(table, i, t.size, what)
    _check_finite(a, t, f"{src}: {table.label(i)} ({what})")
    unit = cunits.get(sig)
    declared = unit is None and table.units[i] is not None
    if declared:
        unit = table.units[i]
    if unit is not None:
        try:
            a = a * to_si_factor(unit, quantity, where=f"{src}: {table.label(i)} ({what})")
        except DataError as exc:
            hint = (f" -- the file declares this unit; override it with units = {{ {sig} = ... }} under "
                    "[identification.data]"
                    if declared else "")
            raise DataError(f"{exc}{hint}") from None
    if sig in cgains:
        a = a * cgains[sig]
    return a


def _checked_experiment(config: BeamConfig, name: str, t: np.ndarray, x: np.ndarray, si_units: dict[str, str],
                        src: str, resample: bool) -> Experiment:
    """The :class:`Experiment` of the signals ``x`` (inputs, then outputs), checked against ``config``.

    Parameters
    ----------
    config, name, src
        The beam config, the experiment's name, the file.
    t, x, si_units
        Sample times, signals (config order) and their SI units.
    resample
        Whether the record was resampled (else the error message suggests it).

    Returns
    -------
    Experiment

    Raises
    ------
    DataError
        The experiment does not fit ``config`` (names, sample time).
    """
    n_in = len(config.actuators)
    exp = Experiment(name=name, time=t, inputs=x[:, :n_in], outputs=x[:, n_in:],
                     input_names=config.input_names, output_names=config.output_names, units=si_units,
                     source=src)
    try:
        exp.check_against(config)
    except DataError as exc:
        if resample:
            raise
        raise DataError(f"{exc} (to resample the record to the config's dt: resample = true under "
                        "[identification.data], resample=True in the API)") from None
    return exp


def load_experiment(path: str | Path, config: BeamConfig, *, format: str | None = None,
                    mapping: Mapping[str, Key] | None = None, units: Mapping[str, str] | None = None,
                    gains: Mapping[str, float] | None = None,
                    remove_offset: Literal[False, "mean", "pre-trigger"] | bool | None = False,
                    pre_trigger: float | None = None, band: Any = None, resample: bool = False,
                    name: str | None = None) -> Experiment:
    """Read one experiment and tie it to ``config``.

    Parameters
    ----------
    path
        The data file.
    config
        The beam config: every actuator becomes an input, every sensor an
        output, in the config's order.
    format
        ``"csv"``, ``"npz"``, ``"mat"``, ``"lvm"`` or ``"uff58"``; default from
        the extension (see :data:`EXTENSIONS`).
    mapping
        Config signal name (or ``"time"``) -> file channel, as a name or a
        0-based index, e.g. ``{"force": 2, "accel": 3}`` for the ARTS-Lab
        ``.lvm`` or ``{"F1": "load_cell"}`` for a CSV.  Unmapped signals are
        looked up by their own name.
    units
        Config signal name -> unit of the values *in the file*, e.g.
        ``{"force": "lbf", "accel": "g"}``; converted to SI with exact
        factors (:mod:`identification.data.units`).  Without an entry, the
        unit the file declares (LVM ``Y_Unit_Label``, UFF58 ordinate units
        label, ``to_npz`` metadata) is used, else SI is assumed.
    gains
        Config signal name -> factor applied after the unit conversion, for a
        transducer whose sign convention or calibration differs from the
        model's: e.g. ``{"force": -1.0}`` for a load cell that reads the
        force pushing on the beam as negative.  Finite and non-zero.
    remove_offset
        ``False`` (default); ``"mean"`` (or ``True``): subtract each signal's
        mean over the record; ``"pre-trigger"``: subtract each signal's mean
        over the first ``pre_trigger`` seconds (a quiet stretch before the
        excitation).
    pre_trigger
        Length [s] of the quiet stretch, for ``remove_offset="pre-trigger"``.
    band
        ``[f_lo, f_hi]`` in Hz: filter every signal (inputs and outputs alike)
        to this band, zero phase (:mod:`identification.data.filtering`) --
        for records excited only in a band, whose input channel carries
        broadband noise the model would answer at resonances the excitation
        never reached.  Applied at the file's sample time, before resampling.
    resample
        If ``True``, resample to ``config.time.dt`` (see
        :func:`~identification.data.timebase.resample_uniform`: polyphase
        for rational rate ratios, anti-aliased spline otherwise).  If
        ``False``, the data must already be sampled at ``config.time.dt``.
    name
        Name of the experiment; default the file stem.

    Returns
    -------
    Experiment
        SI units, checked against ``config``.

    Raises
    ------
    DataError
        One clear message per problem kind, naming file, column and sample:
        unknown format/unit/mapping key; missing columns (all listed);
        mismatched lengths; NaN/inf; non-monotonic time; sample time
        inconsistent with the config.
    """
    p = Path(path)
    fmt = _format_of(p, format)
    mode = _offset_mode(p, remove_offset, pre_trigger)
    cmap, cunits, cgains = _check_options(p, config, mapping, units, gains)
    if not isinstance(resample, (bool, np.bool_)):
        raise DataError(f"{p}: resample must be true or false, got {resample!r}")
    table = FORMATS[fmt].read(p)
    src = table.source
    t, time_label, tol, used = _time_vector(table, cmap)
    roles: list[_Role] = [(a.name, "actuator", "force") for a in config.actuators] + \
        [(s.name, "sensor", s.kind) for s in config.sensors]
    idx = _signal_channels(table, roles, cmap, used)
    cols = {sig: _signal_in_si(table, idx[sig], (sig, role, quantity), t, cunits, cgains)
            for sig, role, quantity in roles}
    si_units = {sig: "N" if role == "actuator" else SENSOR_UNITS[quantity] for sig, role, quantity in roles}
    t = regularise_time(t, tol, config.time.dt, where=time_label)
    x = np.column_stack([cols[s] for s, _, _ in roles])
    x = condition(x, t, mode=mode, pre_trigger=pre_trigger, band=band, dt=config.time.dt, src=src)
    if resample:
        t, x, _ = resample_uniform(t, x, config.time.dt, where=time_label)
    return _checked_experiment(config, name if name is not None else p.stem, t, x, si_units, src, resample)


def load_experiments(paths: Iterable[str | Path] | str | Path, config: BeamConfig, *,
                     names: Iterable[str] | None = None, **kwargs: Any) -> tuple[Experiment, ...]:
    """Load several experiments (to be fitted together) with the same options.

    Parameters
    ----------
    paths
        Data files (a single path is accepted too).
    config
        The beam config shared by all experiments.
    names
        Names of the experiments; default the file stems, which must then be
        unique.
    **kwargs
        Options of :func:`load_experiment` (``format``, ``mapping``,
        ``units``, ``gains``, ``remove_offset``, ``band``, ``pre_trigger``, ``resample``).

    Returns
    -------
    tuple of Experiment
        In the order of ``paths``.

    Raises
    ------
    DataError
        No paths; duplicate names; anything :func:`load_experiment` raises.
    """
    if "name" in kwargs:
        raise DataError("load_experiments: use names=[...] (one per file), not name=")
    plist = [Path(paths)] if isinstance(paths, (str, Path)) else [Path(q) for q in paths]
    if not plist:
        raise DataError("load_experiments: no data files given")
    nlist = [q.stem for q in plist] if names is None else [str(s) for s in names]
    if len(nlist) != len(plist):
        raise DataError(f"load_experiments: {len(nlist)} names for {len(plist)} files")
    dup = sorted({s for s in nlist if nlist.count(s) > 1})
    if dup:
        raise DataError(f"load_experiments: experiment name(s) {', '.join(dup)} used more than once; "
                        "pass names=[...]")
    return tuple(load_experiment(q, config, name=s, **kwargs) for q, s in zip(plist, nlist))
