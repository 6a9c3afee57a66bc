"""A config file as this layer reads it: the model's tables checked, and the tables kept beside them
(``[identification]``, ``[diagnosis]``) kept; the identification tables read later checked now, so that a bad
one stops a run before its first simulation.

Its own module so that the tables' readers (:mod:`.settings`, :mod:`.geometry`, :mod:`.modal_data`) import one
another in one direction only.
"""
from __future__ import annotations

from pathlib import Path

from ebb_model import load_config
from ebb_model.config import BeamConfig

from .geometry import geometry_prior
from .modal_data import modal_data
from .settings import CONFIG_SECTIONS, identification_settings

__all__ = ["load_identification_config"]


def load_identification_config(path: str | Path) -> BeamConfig:
    """Load a config whose ``[identification]`` table is kept for this layer (and checked), and whose
    ``[diagnosis]`` table is kept for the diagnosis (checked there: :func:`diagnosis.settings.thresholds_from_config`).

    Raises
    ------
    ConfigError
        Invalid config, or an invalid ``[identification]`` table.
    """
    cfg = load_config(path, extra_sections=CONFIG_SECTIONS)
    identification_settings(cfg)
    # the tables read later are checked now: a bad one stops the run before its first simulation
    modal_data(cfg)
    geometry_prior(cfg)
    return cfg
