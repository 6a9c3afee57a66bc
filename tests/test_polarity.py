"""The measured force's sign as evidence (:mod:`diagnosis.baseline.polarity`).

The blind bench at its truth (the independent generator, 1 % noise, no effect) with the load cell's sign
reversed in the file: the diagnosis fits its baseline both ways, takes the reversed force (decisive odds), and
then finds nothing to explain; with the sign as it should be, it keeps it.
"""
from __future__ import annotations

import json

import pytest

from ebb_cli import main

from test_diagnose_cli import _toml
from test_noise_model import truth_config, truth_records


@pytest.mark.parametrize("gain", [-1.0, 1.0], ids=["reversed", "as-read"])
def test_a_reversed_force_is_found_and_used(tmp_path, gain):
    cfg = truth_config()
    (tmp_path / "bench.toml").write_text(_toml(cfg))
    files = truth_records(tmp_path, cfg, gain=gain)
    out = tmp_path / "gap"
    assert main(["diagnose", str(tmp_path / "bench.toml"), str(files[0]), "--holdout", str(files[1]), "--out",
                 str(out), "--quiet", "--no-plots", "--workers", "1"]) == 0
    doc = json.loads((out / "gap.json").read_text())
    sign = doc["force_sign"]
    assert sign["decided"] and sign["reversed"] == (gain < 0), sign
    # the wrong sign leaves a gap thousands of noise variances wide; the right one sits at the noise floor
    right, wrong = ("reversed", "as_read") if gain < 0 else ("as_read", "reversed")
    assert sign["fit_gap_ratio"][right] < 1.25 < 100 < sign["fit_gap_ratio"][wrong], sign
    assert doc["verdict"] == "none", doc["reason"]
    assert ("REVERSED" in doc["reason"]) == (gain < 0)
