"""Controller parameter file: round trip, tamper detection, and the reference model from the file alone.

Units: lengths in mm, angles in rad.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from hyperstat.solver.export.controller import ControllerModel, controller_document, read_controller, write_controller
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
    (lambda d: d.__setitem__("version", 2), "reads version 1"),
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
