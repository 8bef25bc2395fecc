"""The FANUC-like workflow in commands (docs/identification.md): DH table -> model file ->
measurements with 3 targets and a joint map -> identify -> URDF and DH export; bad robot files
exit 2 with one sentence and write nothing (units: mm, rad; files in deg and m where stated)."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from hyperstat.cad_plugin.cli import main
from tests.solver.calibration.fanuc_like import DH_YAML, NOMINAL, Campaign, dh_matrix


@pytest.fixture(scope="module")
def workflow(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("wf")
    (tmp / "fanuc_like.dh.yaml").write_text(DH_YAML)
    c = Campaign(21)
    (tmp / "meas.csv").write_text(c.csv(c.poses(50), "P"))
    (tmp / "meas.validation.csv").write_text(c.csv(c.poses(20), "V"))
    return tmp


def test_workflow_in_commands(workflow, capsys):
    t = workflow
    model = t / "fanuc_like.skel.json"
    assert main(["import-robot", str(t / "fanuc_like.dh.yaml"), "--out", str(model)]) == 0
    assert "with a joint map" in capsys.readouterr().out
    assert json.loads(model.read_text())["metadata"]["joint_map"]["joints"]["3"] == {"J3": 1, "J2": 1}
    out, res = t / "id.json", t / "residuals.csv"
    assert main(["identify", str(model), str(t / "meas.csv"), "--validation", str(t / "meas.validation.csv"),
                 "--json", str(out), "--residuals", str(res)]) == 0
    text = capsys.readouterr().out
    assert "sigma" in text and "nominal model" in text and "outliers" in text
    doc = json.loads(out.read_text())
    assert doc["validation"]["rms"] <= 1.2 * doc["noise_rms"] * 1.05
    assert doc["nominal"]["validation"]["rms"] > 5 * doc["validation"]["rms"]
    rows = list(csv.DictReader(res.open()))
    assert len(rows) == 3 * 50 + 3 * 20 and {r["target"] for r in rows} == {"SMR1", "SMR2", "SMR3"}
    assert all(r["outlier"] in ("0", "1") for r in rows)
    assert abs(float(rows[0]["norm[mm]"]) - np.linalg.norm([float(rows[0][k]) for k in ("dx[mm]", "dy[mm]", "dz[mm]")])) < 1e-8
    urdf, dh = t / "fanuc_like.urdf", t / "fanuc_like.corrected.dh.yaml"
    assert main(["export-urdf", str(model), str(t / "meas.csv"), "--out", str(urdf), "--quiet"]) == 0
    assert main(["export-dh", str(model), str(t / "meas.csv"), "--out", str(dh)]) == 0
    assert "DH table reproduces the calibrated model" in capsys.readouterr().out
    assert "<robot" in urdf.read_text() and "convention: dh" in dh.read_text()
    # the corrected table is itself a robot file
    assert main(["import-robot", str(dh), "--out", str(t / "again.skel.json"), "--quiet"]) == 0
    assert main(["import-robot", str(urdf), "--out", str(t / "from_urdf.skel.json"), "--quiet"]) == 0


@pytest.mark.parametrize("edit, message", [
    (("units: {length: mm, angle: deg}", "units: {length: mm}"), "field 'units' must state both"),
    (("units: {length: mm, angle: deg}", "units: {length: in, angle: deg}"), "unit 'in' is not a length unit"),
    (("convention: dh", "convention: craig"), "field 'convention' must be 'dh' or 'modified-dh'"),
    (("a: 1075", "a: ten"), r"joints\[1\].a must be a number"),
    (('"3": {J3: 1, J2: 1}', '"3": {J3: 1, J2: 1, J9: .nan}'), r"joint_map.joints.3.J9 must be a finite number"),
    (('"3": {J3: 1, J2: 1}', '"3": {J2: -1}'), "the joint map is singular"),
    (('"6": {J6: 1, offset: 0.5}', '"7": {J6: 1}'), "no entry for model joint '6'"),
])
def test_bad_robot_file_exits_2_without_output(tmp_path, capsys, edit, message):
    bad = tmp_path / "bad.dh.yaml"
    assert edit[0] in DH_YAML
    bad.write_text(DH_YAML.replace(edit[0], edit[1]))
    out = tmp_path / "m.skel.json"
    assert main(["import-robot", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "bad.dh.yaml" in err and err.count("\n") == 1
    import re

    assert re.search(message, err), err
    assert not out.exists()


def test_measurements_without_the_controller_columns_are_refused(workflow, tmp_path, capsys):
    t = workflow
    model = tmp_path / "m.skel.json"
    assert main(["import-robot", str(t / "fanuc_like.dh.yaml"), "--out", str(model), "--quiet"]) == 0
    bad = tmp_path / "bad.csv"
    bad.write_text((t / "meas.csv").read_text().replace("J3[deg]", "q3[rad]"))
    assert main(["identify", str(model), str(bad), "--json", str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err
    assert "column 'J3[deg]' (controller joint J3) is missing" in err
    assert not (tmp_path / "o.json").exists()


def test_joint_map_option_overrides_the_models(workflow, tmp_path, capsys):
    """--joint-map MAP.yaml replaces the model's map: a map without the FANUC coupling gives an
    absurd fit that says so (joint values kept inside the ranges by taking poses with small J3)."""
    t = workflow
    model = tmp_path / "m.skel.json"
    assert main(["import-robot", str(t / "fanuc_like.dh.yaml"), "--out", str(model), "--quiet"]) == 0
    raw = tmp_path / "raw.map.yaml"
    raw.write_text("joint_map:\n  units: {angle: deg}\n  joints:\n    '1': {J1: 1}\n    '2': {J2: -1}\n"
                   "    '3': {J3: 1}\n    '4': {J4: -1}\n    '5': {J5: 1}\n    '6': {J6: 1, offset: 0.5}\n")
    lines = (t / "meas.csv").read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("pose,"))
    keep = [line for line in lines[head + 1:] if abs(float(line.split(",")[3])) < 60.0]
    assert len(keep) >= 15
    data = tmp_path / "d.csv"
    data.write_text("\n".join(lines[:head + 1] + keep) + "\n")
    assert main(["identify", str(model), str(data), "--joint-map", str(raw)]) == 0
    out = capsys.readouterr().out
    assert "warning: ABSURD FIT: sigma = " in out and "q3 = J3 + J2" in out


def test_controller_file_with_three_targets(workflow, tmp_path, capsys):
    """export-controller on the 3-SMR campaign: one tool point (the output frame's origin) and the
    three named target offsets; check-controller re-evaluates every target point of the test
    vectors; the exported points reproduce the *true* robot's geometry (the generator's DH
    product) to the calibration's accuracy, checked on frame-free distances between SMRs at two
    configurations; a target offset edited after export (hash recomputed) is refused by name."""
    import hashlib

    from hyperstat.solver.export.controller import content_hash

    t = workflow
    model = tmp_path / "m.skel.json"
    assert main(["import-robot", str(t / "fanuc_like.dh.yaml"), "--out", str(model), "--quiet"]) == 0
    out = tmp_path / "machine.json"
    assert main(["export-controller", str(model), str(t / "meas.csv"), "--validation", str(t / "meas.validation.csv"),
                 "--out", str(out), "--quiet"]) == 0
    doc = json.loads(out.read_text())
    assert doc["target"] == [0.0, 0.0, 0.0] and set(doc["targets"]) == {"SMR1", "SMR2", "SMR3"}
    # the offsets are the identification's (same data, same deterministic fit)
    assert main(["identify", str(model), str(t / "meas.csv"), "--json", str(tmp_path / "id.json"), "--quiet"]) == 0
    est = {p["name"]: p["estimate"] for p in json.loads((tmp_path / "id.json").read_text())["parameters"]}
    for name, off in doc["targets"].items():
        assert np.allclose(off, [est[f"target_{name}_{a}"] for a in "xyz"], atol=1e-9)
    assert main(["check-controller", str(out)]) == 0
    assert "test vectors re-evaluated" in capsys.readouterr().out
    # against the truth: distances between target points at two configurations do not depend on the
    # base frame (which the tracker frame absorbs); the generator's true robot gives them too
    c = Campaign(21)
    vec = doc["test_vectors"]["vectors"]
    true, nominal = {}, {}
    for k, v in enumerate(vec):
        q = np.array(v["actuated"])
        f = c.flange(q)
        n = np.eye(4)
        for (a, al, d, th), qi in zip(NOMINAL, q):
            n = n @ dh_matrix(math.radians(th) + qi, d, a, math.radians(al))
        for name, off in doc["targets"].items():
            true[k, name] = f[:3, :3] @ c.targets[name] + f[:3, 3]
            nominal[k, name] = n[:3, :3] @ np.array(off) + n[:3, 3]
    errors, nominal_errors = [], []
    for k in range(len(vec)):
        j = (k + 1) % len(vec)
        for a, b in (("SMR1", "SMR2"), ("SMR2", "SMR3"), ("SMR3", "SMR1")):
            d_true = np.linalg.norm(true[k, a] - true[j, b])
            errors.append(abs(np.linalg.norm(np.subtract(vec[k]["targets"][a], vec[j]["targets"][b])) - d_true))
            nominal_errors.append(abs(np.linalg.norm(nominal[k, a] - nominal[j, b]) - d_true))
    # mm: each point carries the calibration's prediction error (noise 3-D RMS about 0.054 mm here,
    # 150 observations for 33 parameters), a distance two of them
    assert max(errors) < 0.1, max(errors)
    assert np.median(errors) < 0.05
    assert np.median(nominal_errors) > 10 * np.median(errors)  # the nominal geometry is far off
    # an offset edited after export, hash recomputed: it no longer equals its identified estimate (the file
    # contradicts itself); edited there too, the test vectors no longer match; named both times
    doc["targets"]["SMR2"][0] += 0.01
    doc["sha256"] = content_hash(doc)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    assert main(["check-controller", str(bad)]) == 2
    assert "differs from 'targets.SMR2[0]'" in capsys.readouterr().err
    next(p for p in doc["identified"] if p["name"] == "target_SMR2_x")["estimate"] = doc["targets"]["SMR2"][0]
    doc["sha256"] = content_hash(doc)
    bad.write_text(json.dumps(doc))
    assert main(["check-controller", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "target 'SMR2' is 0.01 mm from the file's" in err
    assert hashlib.sha256(out.read_bytes()).hexdigest() != hashlib.sha256(bad.read_bytes()).hexdigest()
