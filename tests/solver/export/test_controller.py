"""Controller parameter file: round trip, tamper detection, test vectors, ``check-controller``, the reference model.

Units: lengths in mm, angles in rad.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from hyperstat.solver.cli import main
from hyperstat.solver.export.controller import (ControllerModel, check_controller, content_hash, controller_document,
                                                read_controller, write_controller)
from hyperstat.solver.diagnosis.effects import make_effect
from hyperstat.solver.errors import DataError
from hyperstat.solver.calibration.identify import identify
from hyperstat.solver.calibration.measurements import write_measurements
from hyperstat.solver.calibration.virtual import VirtualMachine, workshop_metadata


@pytest.fixture(scope="module")
def exported(tripteor, tripteor_analysis, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ctl")
    rng = np.random.default_rng(0)
    truth = make_effect("backlash", tripteor, tripteor_analysis).draw_truth(rng)
    vm = VirtualMachine.random(tripteor, tripteor_analysis, seed=0, effects=(truth,))
    q = vm.poses(80, seed=1)
    meta = workshop_metadata(tripteor, 80, seed=2)
    data = vm.measure(q[:60], seed=3, metadata={k: v[:60] for k, v in meta.items()})
    val = vm.measure(q[60:], seed=4, prefix="V", metadata={k: v[60:] for k, v in meta.items()})
    path = write_measurements(tmp / "d.csv", data, tripteor)
    effect = make_effect("backlash", tripteor, tripteor_analysis, data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify(tripteor, tripteor_analysis, data, val, effects=(effect,))
    doc = controller_document(tripteor, res, (effect,), {"source": "tripteor_x7.py"}, (path,))
    out = write_controller(tmp / "machine.json", doc)
    return out, res, val


def test_round_trip_and_determinism(exported, tripteor, tripteor_analysis):
    path, res, _ = exported
    doc = read_controller(path)
    assert doc["units"] == {"length": "mm", "angle": "rad"}
    assert [e["effect"] for e in doc["effects"]] == ["backlash"]
    assert len(doc["provenance"]["data"][0]["sha256"]) == 64
    again = controller_document(tripteor, res, tuple(res.model.effects), {"source": "tripteor_x7.py"},
                                (path.parent / "d.csv",))
    assert json.dumps(again, sort_keys=True) == json.dumps(doc, sort_keys=True)


@pytest.mark.parametrize("tamper, message", [
    (lambda d: d["defects"].__setitem__("db21", d["defects"]["db21"] + 1e-9), "SHA-256 does not match"),
    (lambda d: d.__setitem__("version", 1), "reads version 2"),
    (lambda d: d.__setitem__("format", "other"), "field 'format'"),
    (lambda d: d.pop("target"), "field 'target' is missing"),
    (lambda d: d["effects"].append({"effect": "gravity", "parameters": {}, "options": {}}), "effects"),
])
def test_tampered_files_are_refused(exported, tmp_path, tamper, message):
    path, _, _ = exported
    doc = json.loads(path.read_text())
    tamper(doc)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(DataError, match=message):
        read_controller(bad)


def test_reference_model_reproduces_the_solver(exported):
    """Forward model from the file only vs the identification's model: 1e-9 mm."""
    path, res, val = exported
    model = ControllerModel(read_controller(path))
    point, pose = model.forward(val.q, val.metadata)
    solver_world = res.model.predict(res.theta, val).world
    assert np.abs(point - solver_world).max() < 1e-9
    # and the inverse model recovers the actuated values of the rigid geometry
    _, rigid_pose = model.forward(val.q, with_effects=False)
    back = model.inverse(rigid_pose, q_start=val.q + 0.3)
    assert np.abs(back - val.q).max() < 1e-9


def test_the_file_carries_the_tolerance_classes(exported, tripteor, tripteor_analysis, tmp_path):
    from hyperstat.solver.tolerances.classification import classify

    path, res, _ = exported
    cl = classify(tripteor, tripteor_analysis)
    doc = controller_document(tripteor, res, tuple(res.model.effects), {"source": "tripteor_x7.py"},
                              (path.parent / "d.csv",), cl.to_dict())
    back = read_controller(write_controller(tmp_path / "m.json", doc))  # schema and hash accept it
    assert back["tolerances"]["counts"] == cl.counts()
    assert {n: e["class"] for n, e in back["tolerances"]["parameters"].items()} == \
           {n: e["class"] for n, e in cl.to_dict()["parameters"].items()}


def _one_digit_changed(text: str, after: str) -> str:
    """The file text with one digit changed: the last digit of the first number after ``after``."""
    import re

    start = text.index(after)
    m = re.compile(r"-?\d+\.\d+").search(text, start)
    i = m.end() - 1
    return text[:i] + str((int(text[i]) + 1) % 10) + text[i + 1:]


def test_file_carries_test_vectors_across_the_workspace(exported, tripteor):
    path, _, _ = exported
    doc = read_controller(path)
    vec = doc["test_vectors"]["vectors"]
    assert len(vec) >= 20
    qa = np.array([v["actuated"] for v in vec])
    lo, hi = tripteor.ranges[tripteor.actuated].T
    assert np.all(qa.max(0) - qa.min(0) > 0.5 * (hi - lo))  # spread over the strokes, not one corner
    # each vector is a closed configuration of the identified geometry (an independent check: the
    # closure residual of the stored joints, not the solver that produced them)
    from hyperstat.solver.kinematics.closure import Kinematics

    model = ControllerModel(doc)
    st = Kinematics(tripteor).evaluate(np.array([v["joints"] for v in vec]), model.xi, jacobians=False)
    assert np.abs(st.residual).max() < 1e-3  # least-squares closure of the identified (hyperstatic) geometry
    assert np.allclose(st.output_pose[:, :3, 3], [v["position"] for v in vec], atol=1e-9)


def test_check_controller_accepts_the_untouched_file(exported, capsys):
    path, _, _ = exported
    assert main(["check-controller", str(path)]) == 0
    out = capsys.readouterr().out
    assert "test vectors re-evaluated" in out and "SHA-256 valid" in out
    res = check_controller(path)
    assert res["count"] >= 20 and res["inverse_mm"] < 1e-9 and res["inverse_rad"] < 1e-9
    assert res["inverse_other_branch"] == 0  # every pose back to the file's own actuated values


@pytest.mark.parametrize("where", ['"defects"', '"test_vectors"', '"target"'])
def test_check_controller_refuses_a_changed_digit(exported, tmp_path, capsys, where):
    path, _, _ = exported
    bad = tmp_path / "machine.json"
    bad.write_text(_one_digit_changed(path.read_text(), where))
    assert bad.read_text() != path.read_text()
    assert main(["check-controller", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "SHA-256 does not match" in err and str(bad) in err


def test_check_controller_re_evaluates_the_vectors(exported, tmp_path, capsys):
    """A defect changed with the hash recomputed passes the hash, not the test vectors."""
    path, _, _ = exported
    doc = json.loads(path.read_text())
    doc["defects"]["db21"] += 1e-4
    doc["sha256"] = content_hash(doc)
    bad = tmp_path / "machine.json"
    bad.write_text(json.dumps(doc))
    read_controller(bad)  # format, schema and hash are fine
    assert main(["check-controller", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "test vector" in err and "tolerance" in err


@pytest.fixture(scope="module")
def exported_serial(tmp_path_factory):
    """A serial 6R arm with declared link masses, identified with the revolute effects of issue 20."""
    from hyperstat.solver.analysis.stationarity import analyze
    from hyperstat.solver.kinematics.modelfile import load_model

    from tests.solver.diagnosis import independent_generator as gen

    mech = load_model(gen.ARM_6R)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        analysis = analyze(mech, n_configurations=24, seed=0)
    names = ("angle-scale", "angle-harmonic-1", "angle-harmonic-2", "backlash-gravity", "compliance")
    truth = tuple(make_effect(n, mech, analysis).draw_truth(np.random.default_rng(i)) for i, n in enumerate(names))
    vm = VirtualMachine.random(mech, analysis, seed=0, effects=truth)
    q = vm.poses(50, seed=1)
    meta = workshop_metadata(mech, 50, seed=2)
    data = vm.measure(q[:40], seed=3, metadata={k: v[:40] for k, v in meta.items()})
    val = vm.measure(q[40:], seed=4, prefix="V", metadata={k: v[40:] for k, v in meta.items()})
    effects = tuple(make_effect(n, mech, analysis, data) for n in names)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify(mech, analysis, data, val, effects=effects)
    doc = controller_document(mech, res, effects, {"source": "arm_6r.skel.json"}, ())
    out = write_controller(tmp_path_factory.mktemp("ctl6r") / "arm.json", doc)
    return out, res, val


def test_revolute_and_gravity_effects_go_into_the_controller(exported_serial):
    """Angle scale, harmonics, gravity-side backlash and compliance over the links: exported, and the
    reference model built from the file alone gives the identification model's tool point (a second
    code path: MeasurementModel.predict) at the validation poses with their metadata, within 1e-9 mm."""
    path, res, val = exported_serial
    doc = read_controller(path)
    assert [e["effect"] for e in doc["effects"]] == ["angle-scale", "angle-harmonic-1", "angle-harmonic-2",
                                                      "backlash-gravity", "compliance"]
    model = ControllerModel(doc)
    point, _ = model.forward(val.q, val.metadata)
    assert np.abs(point - res.model.predict(res.theta, val).world).max() < 1e-9
    # the effects move the point (else the comparison above proves nothing about them)
    rigid, _ = model.forward(val.q, with_effects=False)
    assert np.abs(point - rigid).max() > 1e-3
    ev = doc["test_vectors"]["effect_vectors"]
    assert len(ev) >= 8 and {"temperature", "payload"} <= set(ev[0]["metadata"])
    assert check_controller(path)["effect_vectors"] == len(ev)


def test_check_controller_re_evaluates_the_effect_vectors(exported_serial, tmp_path, capsys):
    """An effect parameter changed with the hash recomputed passes the hash and the rigid vectors, not the
    effect vectors."""
    path, _, _ = exported_serial
    doc = json.loads(path.read_text())
    eff = next(e for e in doc["effects"] if e["effect"] == "angle-harmonic-1")
    name = next(iter(eff["parameters"]))
    eff["parameters"][name] += 1e-5  # rad: about 10 um at a 1 m reach
    doc["sha256"] = content_hash(doc)
    bad = tmp_path / "arm.json"
    bad.write_text(json.dumps(doc))
    read_controller(bad)
    assert main(["check-controller", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "effect vector" in err and "angle-harmonic-1" in err
