"""One FMU, many parameter sets (issue 33): ``ebb export --ssp`` writes an SSP package that libcosim loads.

Reference: the package's own FMU through fmpy with each set's parameter values set by hand ("after" protocol,
as libcosim's observer reads).  libcosim runs the FMU from the package with nothing set but the inputs: the
parameters reach it only through the SSP's parameter binding.
"""
from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from ebb_cli import main
from ebb_model.beam import PARAMETER_NAMES

HOSTS = Path(__file__).resolve().parent / "fmu_hosts"
sys.path.insert(0, str(HOSTS))
from fmu_loops import fmpy_outputs  # noqa: E402

SSV = "{http://ssp-standard.org/SSP1/SystemStructureParameterValues}"
SSD = "{http://ssp-standard.org/SSP1/SystemStructureDescription}"
OSP = "{http://opensimulationplatform.com/SSP/OSPAnnotations}"
OMS = "{https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd}"


def _set(archive: zipfile.ZipFile, stem: str) -> dict[str, float]:
    root = ET.fromstring(archive.read(f"resources/{stem}.ssv"))
    return {p.get("name"): float(p.find(f"{SSV}Real").get("value")) for p in root.iter(f"{SSV}Parameter")}


def test_export_ssp_is_loaded_by_libcosim_with_each_parameter_set(identify_case, tmp_path, capsys):
    cfg, data, _ = identify_case
    out = tmp_path / "run"
    assert main(["identify", str(cfg), str(data), "--out", str(out), "--pop", "8", "--generations", "2",
                 "--no-progress", "--target", "statespace"]) == 0
    capsys.readouterr()
    assert main(["export", str(out), "--ssp", "--target", "statespace"]) == 0
    ssp = out / "export" / "cfg.ssp"
    assert f"wrote {ssp}" in capsys.readouterr().out
    doc = json.loads((out / "pareto.json").read_text())
    with zipfile.ZipFile(ssp) as z:
        names = set(z.namelist())
        stems = [f"point_{i}" for i in range(len(doc["points"]))] + [f"polished_{j}"
                                                                       for j in range(len(doc["polished"]))]
        assert {"SystemStructure.ssd", "resources/beam.fmu"} | {f"resources/{s}.ssv" for s in stems} <= names
        assert {f"{s}.ssd" for s in stems if s != "polished_0"} <= names     # the other sets as variants
        sets = {s: _set(z, s) for s in stems}
        z.extractall(tmp_path / "ssp")
    # every set is complete, and the default binding is the identified model
    assert all(set(v) == set(PARAMETER_NAMES) for v in sets.values())
    for k, v in doc["identified"]["parameters"].items():
        assert sets["polished_0"][k] == pytest.approx(v, rel=1e-12)
    fmu = tmp_path / "ssp" / "resources" / "beam.fmu"
    u = np.random.default_rng(7).standard_normal((300, 1))
    np.save(tmp_path / "u.npy", u)
    far = max((s for s in stems if s != "polished_0"),
              key=lambda s: abs(sets[s]["EI"] - sets["polished_0"]["EI"]))
    results = {}
    for stem, ssd in (("polished_0", "SystemStructure.ssd"), (far, f"{far}.ssd")):
        # as a user loads it: the file alone (its default experiment gives the base step; a crash — libcosim
        # segfaulted on a package without it — must not take the session down: its own process)
        proc = subprocess.run([sys.executable, str(HOSTS / "fmu_loops.py"), "ssp", str(tmp_path / "ssp" / ssd),
                               str(fmu), str(tmp_path / "u.npy"), str(tmp_path / f"{stem}.npy")],
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr[-2000:]
        results[stem] = np.load(tmp_path / f"{stem}.npy")
        ref = fmpy_outputs(fmu, u, params=sets[stem], protocol="after")
        # the same binary under two masters: round-off only
        np.testing.assert_allclose(results[stem], ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert np.abs(results[far] - results["polished_0"]).max() > 1e-6 * np.abs(results[far]).max()
    # every system carries its experiment: start, stop, and the base step where libcosim and OMSimulator read it
    ssd = ET.parse(tmp_path / "ssp" / "SystemStructure.ssd").getroot()
    experiment = ssd.find(f"{SSD}DefaultExperiment")
    assert float(experiment.get("startTime")) == 0.0 and float(experiment.get("stopTime")) > 0.0
    assert float(experiment.find(f".//{OSP}FixedStepAlgorithm").get("baseStepSize")) == 1e-4
    assert float(ssd.find(f".//{OMS}FixedStepMaster").get("stepSize")) == 1e-4
    # fmpy's SSP route, called as a user calls it (no stop time, no step): it runs (before, it stopped on an input
    # connector no connection fed: UnboundLocalError)
    from fmpy.ssp.simulation import simulate_ssp

    rows = simulate_ssp(str(ssp))
    assert len(rows) > 1 and all(np.isfinite(list(r)).all() for r in rows)
    # the same package with its FMU in FMI 3.0 (and the points as FMI 3.0 FMUs): the systems and parameter sets
    # unchanged to the byte (they name the variables both versions share), the FMU the same instance behind the
    # other API — its outputs under each set those of the FMI 2.0 package's FMU to the last bit
    with zipfile.ZipFile(ssp) as z:
        texts2 = {n: z.read(n) for n in z.namelist() if not n.endswith(".fmu")}
    capsys.readouterr()
    assert main(["export", str(out), "--ssp", "--ssp-fmi", "3", "--target", "standalone_fmi3"]) == 0
    with zipfile.ZipFile(ssp) as z:
        assert {n: z.read(n) for n in z.namelist() if not n.endswith(".fmu")} == texts2
        z.extract("resources/beam.fmu", tmp_path / "ssp3")
    fmu3 = tmp_path / "ssp3" / "resources" / "beam.fmu"
    assert fmpy.read_model_description(str(fmu3)).fmiVersion == "3.0"
    for stem in ("polished_0", far):
        np.testing.assert_array_equal(fmpy_outputs(fmu3, u, params=sets[stem], protocol="after"),
                                      fmpy_outputs(fmu, u, params=sets[stem], protocol="after"))
    point = out / "export" / "point_0_standalone_fmi3.fmu"
    assert f"wrote {point}" in capsys.readouterr().out
    assert fmpy.read_model_description(str(point)).fmiVersion == "3.0" and validate_fmu(str(point)) == []
    # a cut-off that is no frequency: one line naming the flag, exit 2, nothing written
    before = {p: p.stat().st_mtime_ns for p in (out / "export").iterdir()}
    capsys.readouterr()
    assert main(["export", str(out), "--modes-up-to", "0"]) == 2
    assert "--modes-up-to: must be > 0 Hz, got 0.0" in capsys.readouterr().err
    assert {p: p.stat().st_mtime_ns for p in (out / "export").iterdir()} == before


def test_export_ssp_refuses_identified_positions(identify_case, tmp_path, capsys):
    """A result whose sensor position was identified: every point has its own grid of sensors, which one FMU
    cannot take as a parameter — exit 2 naming the position, no package written."""
    cfg, data, _ = identify_case
    cfg.write_text(cfg.read_text() + "[identification]\npositions = { y1 = [0.45, 0.55] }\n")
    out = tmp_path / "run"
    assert main(["identify", str(cfg), str(data), "--out", str(out), "--pop", "8", "--generations", "1",
                 "--polish", "0", "--no-progress", "--target", "statespace"]) == 0
    capsys.readouterr()
    before = {p: p.stat().st_mtime_ns for p in (out / "export").iterdir()}
    assert main(["export", str(out), "--ssp", "--target", "statespace"]) == 2
    assert "the positions of y1 were identified" in capsys.readouterr().err
    assert {p: p.stat().st_mtime_ns for p in (out / "export").iterdir()} == before     # nothing written
