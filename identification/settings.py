"""The config's ``[identification]`` table, read and checked in one place.

.. code-block:: toml

    [identification]
    per = "sensor"            # objectives per sensor (default) or per experiment
    stabilising = false       # add the seed's stabilising objective (default: with the theta scheme only)
    noise_std = [1e-6, 1e-6]  # one per sensor; default estimated from the data
    positions = { F1 = [0.2, 0.4] }   # identify an actuator/sensor position within bounds [m]
    sizes = { roller = [1e5, 1e9] }   # identify a spring's stiffness [N/m] or a point mass's mass [kg]

    [identification.modes]    # measured natural frequencies (identification.modal_data)
    frequencies_hz = [6.64, 41.35]
    std_hz = [0.1, 0.3]

    [identification.geometry] # EI and rhoA's prior from the section (identification.geometry)
    E = { value = 200e9, std = 5e9 }
    ...

    [identification.data]     # options of identification.data.load_experiments
    mapping = { F1 = "force" }
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError

__all__ = ["CONFIG_SECTIONS", "SECTION", "IdentificationSettings", "identification_settings", "identification_table"]

#: Name of the config table this layer owns.
SECTION = "identification"
#: The config tables kept beside the model's: this layer's and the diagnosis' (checked by each).
CONFIG_SECTIONS = (SECTION, "diagnosis", "setups")
_KEYS = ("positions", "sizes", "data", "noise_std", "per", "stabilising", "modes", "geometry")
_DATA_KEYS = ("mapping", "units", "gains", "remove_offset", "pre_trigger", "band", "resample", "format")


@dataclass(frozen=True)
class IdentificationSettings:
    """The entries of ``[identification]`` (``None`` or empty where the table does not give them).

    Attributes
    ----------
    positions
        ``{actuator, sensor, point mass or spring name: [lo, hi]}``, checked by
        :func:`identification.parameters.parameter_space`.
    sizes
        ``{spring or point mass name: [lo, hi]}`` (its stiffness [N/m] or mass [kg]), checked there too.
    data
        Keyword options of :func:`identification.data.load_experiments`.
    noise_std
        Noise standard deviation per sensor, as given.
    per
        ``"sensor"`` or ``"experiment"``, as given.
    stabilising
        Whether to add the stabilising objective, as given.
    """

    positions: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    sizes: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    data: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    noise_std: Any = None
    per: str | None = None
    stabilising: bool | None = None


def identification_table(config: BeamConfig, key: str, shape: str) -> Mapping[str, Any] | None:
    """The ``[identification.<key>]`` table of ``config``; ``None`` when it has none.

    Raises
    ------
    ConfigError
        Present but not a table (``shape`` says what it should be).
    """
    ident = config.extra.get(SECTION, {}) or {}
    table = ident.get(key) if isinstance(ident, Mapping) else None
    if table is not None and not isinstance(table, Mapping):
        raise ConfigError(f"{SECTION}.{key}: must be a table {shape}")
    return table


def identification_settings(config: BeamConfig) -> IdentificationSettings:
    """Read the ``[identification]`` table of ``config`` (kept by
    :func:`identification.config_file.load_identification_config`).

    Raises
    ------
    ConfigError
        The table (or its ``data`` table) is not a table, or has unknown keys — every problem at once.
    """
    ident = config.extra.get(SECTION, {}) or {}
    if not isinstance(ident, Mapping):
        raise ConfigError(f"{SECTION}: must be a table")
    bad = [f"{SECTION}.{k}: unknown key; allowed: {', '.join(_KEYS)}" for k in ident if k not in _KEYS]
    data = ident.get("data", {})
    if not isinstance(data, Mapping):
        bad.append(f"{SECTION}.data: must be a table")
    else:
        bad += [f"{SECTION}.data.{k}: unknown key; allowed: {', '.join(_DATA_KEYS)}"
                for k in data if k not in _DATA_KEYS]
    positions, sizes = ident.get("positions", {}), ident.get("sizes", {})
    for key, table in (("positions", positions), ("sizes", sizes)):
        if not isinstance(table, Mapping):
            bad.append(f"{SECTION}.{key}: must be a table {{name = [lo, hi]}}, got {table!r}")
    if not isinstance(ident.get("stabilising", False), bool):
        bad.append(f"{SECTION}.stabilising: must be true or false, got {ident['stabilising']!r}")
    if not isinstance(ident.get("per", ""), str):
        bad.append(f"{SECTION}.per: must be \"sensor\" or \"experiment\", got {ident['per']!r}")
    if bad:
        raise ConfigError(bad)
    return IdentificationSettings(
        positions=MappingProxyType(dict(positions)), sizes=MappingProxyType(dict(sizes)),
        data=MappingProxyType(dict(data)), noise_std=ident.get("noise_std"), per=ident.get("per"),
        stabilising=ident.get("stabilising"))
