"""The diagnosis' thresholds as one settings object (issue 52): read from the config's ``[diagnosis]`` table, checked
like the rest of the config, written whole to ``gap.json`` with the reason for each value, and the verdict moves
when one of them does."""
from __future__ import annotations

import json

import pytest

from diagnosis.settings import Thresholds, thresholds_from_config
from ebb_cli import main
from ebb_model.errors import ConfigError

from test_diagnose_cli import _toml
from test_diagnosis_blind import DT, bench_config
from test_effect_catalogue import blind_bench_records


def _records(tmp_path):
    """Two records of the blind bench, sensor y2 read 15 % high."""
    return blind_bench_records(tmp_path, (31, 32), "y2", lambda v: v * 1.15)


def test_a_threshold_set_in_the_config_moves_the_verdict(tmp_path, capsys):
    """Default thresholds: the gain error is named; with ``[diagnosis] gap_threshold`` raised above the record's
    gap (the user declares such gaps noise) the verdict is ``none`` — and ``gap.json`` says which value ran, with
    every other threshold and its reason."""
    cfg, files = _records(tmp_path)
    docs = {}
    for name, table in (("default", ""), ("lenient", "\n[diagnosis]\ngap_threshold = 1e6\nshortlist = 3\n")):
        (tmp_path / f"{name}.toml").write_text(_toml(cfg) + table)
        rc = main(["diagnose", str(tmp_path / f"{name}.toml"), str(files[0]), "--holdout", str(files[1]),
                   "--out", str(tmp_path / name), "--quiet", "--workers", "1", "--no-plots", "--no-export"])
        assert rc == 0, capsys.readouterr().err
        docs[name] = json.loads((tmp_path / name / "gap.json").read_text())
    assert docs["default"]["verdict"] == "sensor_gain[y2]", docs["default"]["reason"]
    assert docs["lenient"]["verdict"] == "none", docs["lenient"]["reason"]
    default, lenient = docs["default"]["settings"], docs["lenient"]["settings"]
    assert (lenient["gap_threshold"], lenient["shortlist"]) == (1e6, 3)
    assert default == {"holdout": default["holdout"], "holdout_fraction": None} | Thresholds().to_dict()
    assert set(default["reasons"]) == set(Thresholds().to_dict()) - {"reasons"}
    assert all(len(r) > 20 for r in default["reasons"].values())


@pytest.mark.parametrize("table, message", [
    ("[diagnosis]\nbic_margni = 6.0\n", "diagnosis.bic_margni: unknown setting"),
    ("[diagnosis]\nnamed_closure = 1.5\n", "diagnosis.named_closure: must be a number in 0 … 1"),
    ("[diagnosis]\nshortlist = 2.5\n", "diagnosis.shortlist: must be a whole number"),
    ("[diagnosis]\ndecisive_odds = true\n", "diagnosis.decisive_odds: must be a number"),
    ("diagnosis = 3\n", "diagnosis: must be a table"),
])
def test_a_bad_diagnosis_table_is_one_line_and_exit_2(tmp_path, capsys, table, message):
    cfg = bench_config()
    (tmp_path / "c.toml").write_text(table + _toml(cfg) if not table.startswith("[") else _toml(cfg) + table)
    rec = tmp_path / "r.csv"
    rec.write_text("time,F1,y1,y2\n" + "".join(f"{i * DT},0.1,0.0,0.0\n" for i in range(50)))
    assert main(["diagnose", str(tmp_path / "c.toml"), str(rec), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err
    assert not (tmp_path / "o").exists()


def test_api_overrides_and_checks():
    cfg = bench_config()
    assert thresholds_from_config(cfg) == Thresholds()
    assert thresholds_from_config(cfg, shortlist=2, bic_margin=None).shortlist == 2
    with pytest.raises(ConfigError, match="shortlist"):
        thresholds_from_config(cfg, shortlist=0)
