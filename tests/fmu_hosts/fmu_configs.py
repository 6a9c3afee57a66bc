"""Configs shared by the FMU tests (plain dicts; ``config_from_dict`` turns them into BeamConfigs)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]

#: Benchmark case R1 / the seed: clamped-clamped, 50 nodes, dt 1e-4, one force, two displacement sensors.
SEED_TOML = ROOT / "examples" / "seed_clamped.toml"


def mixed_config() -> dict[str, Any]:
    """Two forces; displacement, velocity and acceleration sensors; damping, a point mass, a spring to ground, a
    weak segment, an elastic end."""
    return {
        "beam": {"length": 1.0, "nodes": 30, "left": "pinned", "right": "elastic",
                 "right_kt": 5000.0, "right_kr": 20.0},
        "time": {"dt": 2e-4, "theta": 0.25, "substeps": 1},
        "parameters": {"EI": {"value": 12.0}, "rhoA": {"value": 1.5}, "c": {"value": 0.3},
                       "eta": {"value": 1e-4}, "N": {"value": 20.0}},
        "actuators": [{"name": "F1", "x": 0.3}, {"name": "F2", "x": 0.8}],
        "sensors": [{"name": "d1", "x": 0.5, "kind": "displacement"},
                    {"name": "v1", "x": 0.6, "kind": "velocity"},
                    {"name": "a1", "x": 0.3, "kind": "acceleration"}],
        "masses": [{"name": "m1", "x": 0.9, "mass": 0.05}],
        "springs": [{"name": "k1", "x": 0.45, "k": 3000.0}],
        "weak_segments": [{"name": "crack", "x": 0.62, "length": 0.05, "factor": 0.5}],
    }


def substep_config() -> dict[str, Any]:
    """The seed's θ-scheme: a cantilever with sub-steps (dense transition matrix) and an acceleration sensor."""
    return {
        "beam": {"length": 0.8, "nodes": 20, "left": "clamped", "right": "free"},
        "time": {"dt": 5e-4, "theta": 0.25, "substeps": 2, "scheme": "theta"},
        "parameters": {"EI": {"value": 50.0}, "rhoA": {"value": 2.0}, "c": {"value": 0.5},
                       "eta": {"value": 0.0}, "N": {"value": 0.0}},
        "actuators": [{"name": "force", "x": 0.7}],
        "sensors": [{"name": "tip", "x": 0.8, "kind": "displacement"},
                    {"name": "accel", "x": 0.6, "kind": "acceleration"}],
    }
