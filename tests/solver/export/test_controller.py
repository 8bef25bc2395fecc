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
    (lambda d: d.__setitem__("version", 1), "reads version 3"),
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
    """The file text with one digit changed: the last digit of the first number after ``after`` that changes its
    value (a 17th significant digit may not: 0.043799127944964204 and ...205 are the same double)."""
    import re

    start = text.index(after)
    m = re.compile(r"-?\d+\.\d+").search(text, start)
    for i in range(m.end() - 1, m.start() - 1, -1):
        if text[i].isdigit():
            changed = text[:i] + str((int(text[i]) + 1) % 10) + text[i + 1:]
            if float(changed[m.start():m.end()]) != float(m.group(0)):
                return changed
    raise AssertionError(f"no digit of {m.group(0)} changes its value")


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


def test_check_controller_prints_the_notes_the_file_carries(exported, tmp_path, capsys):
    """The findings that stopped nothing are passed on in the file; the integrator who checks it reads them too
    (the untouched Tripteor file has none: no note line)."""
    path, _, _ = exported
    assert main(["check-controller", str(path)]) == 0
    assert "note of the calibration" not in capsys.readouterr().out
    message = "the moved geometry displaces the tool frame by up to 0.03 mm against the identified base frame"
    noted = _rehashed(path, tmp_path, lambda doc: doc["calibration"]["findings"].append(
        {"code": "closing-geometry-moved", "refuses": False, "message": message}))
    assert main(["check-controller", str(noted)]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if "note of the calibration" in ln]
    assert lines == [f"{noted}: note of the calibration (closing-geometry-moved): {message}"]
    assert check_controller(noted)["notes"] == [{"code": "closing-geometry-moved", "message": message}]


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
    # a defect the file does not list as identified (one it lists must equal its estimate: refused before)
    name = next(n for n in sorted(doc["defects"]) if n not in {p["name"] for p in doc["identified"]}
                and n.startswith("dc"))
    doc["defects"][name] += 1e-4
    doc["sha256"] = content_hash(doc)
    bad = tmp_path / "machine.json"
    bad.write_text(json.dumps(doc))
    read_controller(bad)  # format, schema, hash and self-consistency are fine
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
    q = vm.poses(80, seed=1)
    meta = workshop_metadata(mech, 80, seed=2)
    # noise-free identification poses: with the tracker's noise, 40 poses left the wrist's harmonics and
    # gravity-side backlash (joints with little load) beyond their plausible magnitudes or physical domain,
    # and the controller file rightly refuses such estimates (tested in test_what_the_version_admits); 70 poses
    # give the 2 equations per parameter the export gate asks (66 parameters with the five effects)
    data = vm.measure(q[:70], seed=3, metadata={k: v[:70] for k, v in meta.items()}, noise=False)
    val = vm.measure(q[70:], seed=4, prefix="V", metadata={k: v[70:] for k, v in meta.items()})
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
    for p in doc["identified"]:  # changed consistently (the identified list must agree with the effect)
        if p["name"] == name:
            p["estimate"] = eff["parameters"][name]
    doc["sha256"] = content_hash(doc)
    bad = tmp_path / "arm.json"
    bad.write_text(json.dumps(doc))
    read_controller(bad)
    assert main(["check-controller", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "effect vector" in err and "angle-harmonic-1" in err


# ---------------------------------------------------------------- a file cannot vouch for itself (issue 31)
def _rehashed(path, tmp_path, change) -> "Path":
    """The file with ``change`` applied to its content and the SHA-256 recomputed (what a forger would do)."""
    doc = json.loads(path.read_text())
    change(doc)
    doc["sha256"] = content_hash(doc)
    bad = tmp_path / "machine.json"
    bad.write_text(json.dumps(doc))
    return bad


def _leg(doc: dict, name: str) -> dict:
    return next(e for ch in doc["model"]["chains"] for e in ch["elements"] if e["name"] == name)


def _refused(bad, capsys, *needles, source=None) -> str:
    argv = ["check-controller", str(bad)] + (["--source", str(source)] if source else [])
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(bad) in err and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    return err


def test_a_raised_tolerance_is_refused(exported, tmp_path, capsys):
    """The issue's forgery: tolerance raised to 1e3, a defect moved by 0.1 mm, hash recomputed.  The version fixes
    the tolerance, so the file is refused before any vector is evaluated."""
    path, _, _ = exported

    def forge(doc):
        doc["test_vectors"]["tolerance"] = {"length_mm": 1e3, "angle_rad": 1e3}
        doc["defects"]["db21"] += 0.1

    _refused(_rehashed(path, tmp_path, forge), capsys, "test_vectors.tolerance", "fixes it at 1e-09",
             "a file cannot set its own tolerance")


def test_an_unknown_defect_is_refused(exported, tmp_path, capsys):
    path, _, _ = exported
    _refused(_rehashed(path, tmp_path, lambda d: d["defects"].__setitem__("dX99", 0.0)), capsys,
             "'dX99', which is not a defect of the model 'tripteor_x7'")


def test_a_changed_joint_range_is_refused(exported, tmp_path, capsys, tripteor):
    """A widened (or narrowed) stroke of leg 42 with the hash recomputed: the test vectors are the version's draws
    from the ranges, so the old vectors give it away; with the vectors drawn again as well (a complete forgery)
    the file is consistent, and only a trusted model can tell: ``--source``."""
    path, _, _ = exported
    for delta in (50.0, -50.0):
        bad = _rehashed(path, tmp_path, lambda d: _leg(d, "42")["range"].__setitem__(1, _leg(d, "42")["range"][1]
                                                                                      + delta))
        _refused(bad, capsys, "were the joint ranges")  # by the vectors, or (narrowed) by the region the poses covered
    from hyperstat.solver.export.controller import build_test_vectors
    from hyperstat.solver.kinematics.modelfile import mechanism_from_dict, save_model

    def forge(doc):
        _leg(doc, "42")["range"][1] += 50.0
        mech = mechanism_from_dict(doc["model"])
        xi = np.array([doc["defects"][p.name] for p in mech.parameters])
        doc["test_vectors"] = json.loads(json.dumps(build_test_vectors(mech, xi, np.array(doc["target"]))))
        doc["test_vectors"]["effect_vectors"] = json.loads(json.dumps(doc["test_vectors"].get("effect_vectors", [])))

    bad = _rehashed(path, tmp_path, forge)
    reference = save_model(tripteor, tmp_path / "tripteor.skel.json")
    _refused(bad, capsys, "range[1]' differs from the reference model 'tripteor_x7' given with --source",
             source=reference)
    assert main(["check-controller", str(path), "--source", str(reference), "--quiet"]) == 0


def test_what_the_version_admits(exported, tmp_path, capsys):
    """Magnitudes, options, effect parameters and keys the format does not hold are refused (hash recomputed)."""
    path, _, _ = exported
    cases = [
        (lambda d: d["defects"].__setitem__("dI21", 0.2), "field 'defects.dI21' is 0.2 rad, beyond the 0.1 rad"),
        (lambda d: d["defects"].__setitem__("da21", 250.0), "field 'defects.da21' is 250 mm, beyond the 100 mm"),
        (lambda d: d.__setitem__("target", [3000.0, 0.0, 0.0]), "field 'target' is 3000 mm from the output frame"),
        (lambda d: d["effects"][0]["options"].__setitem__("gain", 2), "effects[0].options.gain' is not part"),
        (lambda d: d["effects"][0]["parameters"].__setitem__("backlash_X", 0.0), "'backlash_X' is not a parameter"),
        (lambda d: d["statistics"].__setitem__("trust_me", True), "statistics.trust_me' is not part of the format"),
        (lambda d: d["test_vectors"].__setitem__("vectors", d["test_vectors"]["vectors"][:5]),
         "holds 5 drawn vectors; version 3 draws 24 and needs at least 12"),
    ]
    for change, needle in cases:
        _refused(_rehashed(path, tmp_path, change), capsys, needle)
    doc = json.loads(path.read_text())
    name = next(iter(doc["effects"][0]["parameters"]))

    def beyond(d):  # changed consistently in the identified list, which must agree with the effect
        d["effects"][0]["parameters"][name] = 1e3
        next(p for p in d["identified"] if p["name"] == name)["estimate"] = 1e3

    _refused(_rehashed(path, tmp_path, beyond), capsys, f"parameter '{name}' = 1000",
             "physical domain or beyond its plausible magnitude")


def test_a_key_declared_twice_is_refused(exported, tmp_path, capsys):
    """JSON readers keep the last of two equal keys; a controller file that declares one twice is refused."""
    path, _, _ = exported
    text = path.read_text()
    bad = tmp_path / "machine.json"
    bad.write_text(text.replace('"defects": {', '"defects": {"db21": 1.0, ', 1))
    _refused(bad, capsys, "key 'db21' is declared twice")


def test_an_unreachable_range_is_refused():
    """The Triflex II with its first actuated range widened by a quarter of its width at the low end: no
    configuration of the other joints assembles there, so the range cannot be the machine's (the LinuxCNC
    export would make it a joint limit).  The template's own ranges pass."""
    from hyperstat.cad_plugin.templates import build_template
    from hyperstat.solver.export.controller import ControllerModel, check_reachable_ranges
    from hyperstat.solver.kinematics.modelfile import mechanism_to_dict

    from tests.conftest import TEMPLATES

    mech = build_template(TEMPLATES / "triflex_ii.py").mechanism()
    doc = {"model": json.loads(json.dumps(mechanism_to_dict(mech))), "defects": {p.name: 0.0 for p in mech.parameters},
           "target": [0.0, 0.0, 0.0], "effects": []}
    check_reachable_ranges(ControllerModel(doc))
    j = mech.joints[mech.actuated[0]]
    _leg(doc, j.name)["range"][0] -= 0.25 * (j.range[1] - j.range[0])
    with pytest.raises(DataError, match=f"low end .* of actuated joint '{j.name}' is not reachable"):
        check_reachable_ranges(ControllerModel(doc))


# ---------------------------------------------------------------- a file consistent with itself (issue 37)
@pytest.fixture(scope="module")
def exported_fanuc(tmp_path_factory):
    """A FANUC-like 6R with its joint map (J2 sign, J3 = q3 - J2 coupling, J6 offset), three reflectors, 50 + 30
    poses of the independent generator: the controller file ``export-controller`` writes."""
    from tests.solver.calibration.fanuc_like import DH_YAML, Campaign

    tmp = tmp_path_factory.mktemp("ctlfanuc")
    (tmp / "f.dh.yaml").write_text(DH_YAML)
    assert main(["import-robot", str(tmp / "f.dh.yaml"), "--out", str(tmp / "f.skel.json"), "--quiet"]) == 0
    c = Campaign(21)
    (tmp / "d.csv").write_text(c.csv(c.poses(50), "P"))
    (tmp / "v.csv").write_text(c.csv(c.poses(30), "V"))
    out = tmp / "machine.json"
    assert main(["export-controller", str(tmp / "f.skel.json"), str(tmp / "d.csv"), "--validation", str(tmp / "v.csv"),
                 "--out", str(out), "--quiet"]) == 0
    return out


def _identified_mm(doc: dict) -> dict:
    return next(p for p in doc["identified"] if p["kind"] == "geometry" and p["unit"] == "mm")


def _swap_map(doc: dict) -> None:
    joints = doc["model"]["metadata"]["joint_map"]["joints"]
    joints["2"], joints["3"] = joints["3"], joints["2"]


ISSUE_CONTRADICTIONS = [
    ("fanuc", "joint map entries 2 and 3 swapped", _swap_map, "the joint map was changed after export"),
    ("fanuc", "joint map angle unit deg -> rad",
     lambda d: d["model"]["metadata"]["joint_map"]["units"].__setitem__("angle", "rad"),
     "the joint map was changed after export"),
    ("tripteor", "mechanism 'hexapod' on a Tripteor", lambda d: d.__setitem__("mechanism", "hexapod"),
     "field 'mechanism' is 'hexapod', but the embedded model is 'tripteor_x7'"),
    ("tripteor", "12 of 24 test vectors dropped",
     lambda d: d["test_vectors"].__setitem__("vectors", d["test_vectors"]["vectors"][:12]), "were vectors dropped?"),
    ("tripteor", "an identified estimate moved 0.5 mm", lambda d: _identified_mm(d).__setitem__(
        "estimate", _identified_mm(d)["estimate"] + 0.5), "the file contradicts itself"),
    ("tripteor", "a negative RMS", lambda d: d["statistics"]["identification"].__setitem__("rms", -0.01),
     "'statistics.identification.rms' is -0.01 mm"),
    ("tripteor", "rank 99 for its unknowns", lambda d: d["statistics"].__setitem__("rank", 99),
     "'statistics.rank' is 99"),
    ("tripteor", "condition number 1e308", lambda d: d["statistics"].__setitem__("condition_number", 1e308),
     "not marked as written with --force"),
]


@pytest.mark.parametrize("which, what, change, needle", ISSUE_CONTRADICTIONS, ids=[c[1] for c in ISSUE_CONTRADICTIONS])
def test_the_issues_contradictions_are_refused(exported, exported_fanuc, tmp_path, capsys, which, what, change,
                                               needle):
    """The eight controller files of issue 37 (hash recomputed after the change): refused without --source, in one
    sentence naming the field; the untouched files pass."""
    path = exported_fanuc if which == "fanuc" else exported[0]
    _refused(_rehashed(path, tmp_path, change), capsys, needle)


def test_the_vectors_are_every_draw_and_corner_that_assembles(exported, exported_fanuc, tripteor):
    """A serial 6R assembles everywhere: its file holds the 24 draws and all 2^6 corners of the ranges; the
    Tripteor's corners (every actuated joint at one end of its range) and draws (middle 80 %) are read off the model's
    ranges, independently of how the file was written."""
    fan = read_controller(exported_fanuc)
    assert len(fan["test_vectors"]["vectors"]) == 24 + 2 ** 6
    doc = read_controller(exported[0])
    act = tripteor.actuated
    lo, hi = tripteor.ranges[act].T
    corners = draws = 0
    for v in doc["test_vectors"]["vectors"]:
        qa = np.array(v["actuated"])
        at_end = np.isclose(qa, lo, rtol=0, atol=1e-12) | np.isclose(qa, hi, rtol=0, atol=1e-12)
        inside = (qa >= lo + 0.1 * (hi - lo) - 1e-9) & (qa <= hi - 0.1 * (hi - lo) + 1e-9)
        assert at_end.all() or inside.all()
        corners += bool(at_end.all())
        draws += bool(inside.all())
    assert draws >= 12 and corners >= 1 and corners + draws == len(doc["test_vectors"]["vectors"])
    assert check_controller(exported[0])["corners"] == corners


def test_controller_values_are_the_generators_readings(exported_fanuc):
    """Each vector's controller values are what the independent generator's own FANUC convention (its
    ``controller``: J2 sign, J3 = q3 - J2, J4 sign, J6 offset) reads at the vector's model joints."""
    from tests.solver.calibration.fanuc_like import Campaign

    doc = read_controller(exported_fanuc)
    for v in doc["test_vectors"]["vectors"]:
        np.testing.assert_allclose(v["controller"], Campaign.controller(np.array(v["actuated"])), rtol=0, atol=1e-9)


def test_check_controller_and_check_move_name_the_calibrated_region(exported, tmp_path, capsys):
    """The region the poses covered is the file's; check-controller counts the vectors beyond it, and check-move
    says where a move of the wrist joint 6 (world C, in degrees) leaves it: where the line crosses the region's end
    (C moves alone, so that point is known beforehand)."""
    from hyperstat.solver.calibration.measurements import read_measurements

    path, res, _ = exported
    doc = read_controller(path)
    region = doc["calibration"]["region"]
    commanded = read_measurements(path.parent / "d.csv", res.model.mechanism).q  # the poses' actuated values
    np.testing.assert_allclose(region["low"], commanded.min(axis=0), rtol=1e-11)  # the file keeps 12 digits
    np.testing.assert_allclose(region["high"], commanded.max(axis=0), rtol=1e-11)
    qa = np.array([v["actuated"] for v in doc["test_vectors"]["vectors"]])
    beyond = int(np.sum(np.any((qa < np.array(region["low"])) | (qa > np.array(region["high"])), axis=1)))
    assert main(["check-controller", str(path), "--json", str(tmp_path / "check.json")]) == 0
    assert json.loads((tmp_path / "check.json").read_text())["outside_region"] == beyond and beyond > 0
    assert f"{beyond} of the {len(qa)} test vectors lie beyond it" in capsys.readouterr().out
    k = region["joints"].index("6")
    top = np.degrees(region["high"][k])
    c0, c1 = top - 10.0, top + 10.0  # joint 6's range is +-180 degrees, the poses cover less
    out = tmp_path / "move.json"
    code = main(["check-move", "--controller", str(path), "--from", f"X100 Y0 Z-1100 B0 C{c0:.6f}",
                 "--to", f"X100 Y0 Z-1100 B0 C{c1:.6f}", "--json", str(out)])
    text = capsys.readouterr().out
    assert code == 0, text
    cal = json.loads(out.read_text())["calibrated"]
    assert not cal["inside"] and cal["joint"] == "6" and cal["value"] > region["high"][k]
    samples = json.loads(out.read_text())["samples"]
    first = next(i for i in range(1, samples + 1) if c0 + i / samples * (c1 - c0) > top + np.degrees(1e-6))
    assert cal["fraction"] == pytest.approx(first / samples)
    assert "leaves the region the calibration's poses covered" in text and "joint '6'" in text
