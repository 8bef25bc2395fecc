"""One verdict per tolerance: the classes checked against the nonlinear model and against each other.

Units: mm and rad.  Expected facts come from re-assembly of the full nonlinear model
(:meth:`Kinematics.assemble`), never from the classifier's own numbers.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hyperstat.cad_plugin.templates import build_template
from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.errors import ModelError
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.tolerances.classification import CLASSES, classify
from hyperstat.solver.tolerances.declaration import parse_declaration

from tests.conftest import TEMPLATES


def _setup(name: str):
    mech = build_template(TEMPLATES / f"{name}.py").mechanism()
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, kinematics=kin)
    return mech, kin, result


@pytest.fixture(scope="module")
def slider():
    mech, kin, result = _setup("slider_crank")
    return mech, kin, result, classify(mech, result, kin)


def _gap(kin, mech, xi, q):
    """Closure residual (mm) after re-assembly with defects ``xi`` at configurations ``q``."""
    return kin.assemble(q.copy(), xi).residual


def test_slider_crank_shows_dc2_plus_dc3_and_no_gauge(slider):
    mech, kin, result, cl = slider
    statements = [t.statement for t in cl.items]
    assert "dc2 + dc3 = 0" in statements
    assert all(t.cls in CLASSES for t in cl.items)
    doc = cl.to_dict()
    assert "gauge" not in {v["class"] for v in doc["parameters"].values()}
    # one class per parameter: dc2 is merged with dc3 (class 'redundant'), and shares its tolerance
    assert doc["parameters"]["dc2"]["class"] == "redundant" and doc["parameters"]["dc2"]["equivalent"] == "dc3"
    assert doc["parameters"]["dc3"]["class"] == "assembly"
    assert doc["parameters"]["dc2"]["tolerance_id"] == doc["parameters"]["dc3"]["tolerance_id"]
    # the physics behind the statement: dc2 alone opens a gap; dc2 = -dc3 closes
    index = mech.parameter_index
    q = result.configurations[:4]
    alone = np.zeros(len(index))
    alone[index["dc2"]] = 0.1
    both = alone.copy()
    both[index["dc3"]] = -0.1
    assert np.min(_gap(kin, mech, alone, q)) > 0.05  # mm: a 0.1 mm shift leaves a 0.1 mm class gap
    assert np.max(_gap(kin, mech, both, q)) < 1e-9


def test_normalisation_components_are_not_tolerances(slider):
    mech, kin, result, cl = slider
    normal = {a["name"] for a in cl.appendix}
    assert normal == {"dK2", "dK3", "dI4"}
    for t in cl.items:
        assert not normal & set(t.parameters)


def test_every_assembly_condition_opens_a_gap_and_every_direction_closes():
    mech, kin, result = _setup("tripteor_x7")
    cl = classify(mech, result, kin)
    q = result.configurations[:3]
    for t in cl.items:
        xi = 1e-3 * t.direction / max(np.max(np.abs(t.direction)), 1e-300)
        gap = np.max(_gap(kin, mech, xi, q))
        if t.cls == "assembly":
            assert gap > 1e-4, (t.statement, gap)  # mm: violating the condition deforms the loop
        else:
            assert gap < 1e-7, (t.statement, gap)  # an admissible direction assembles
    # the out-of-plane relation keeps the redundant db53 (it is the same shift as dc63)
    rel = [t for t in cl.items if t.kind == "relation" and "dc63" in t.terms]
    assert rel and "db53" in rel[0].terms


def _task_residual_after_actuators(mech, kin, cl, t, q, size):
    """Nonlinear: move the actuators to cancel the task error of a defect of ``size`` along ``t``."""
    from scipy.optimize import least_squares

    from hyperstat.solver.tolerances.declaration import task_rows

    xi = size * t.direction
    nominal = kin.evaluate(q[None], None, jacobians=False).output_pose[0]
    act = mech.actuated
    sel = task_rows(cl.declaration.task, nominal[None])[0]

    def err(da):
        qq = q.copy()
        qq[act] += da
        res = kin.assemble(qq[None], xi)
        pose = kin.evaluate(res.q, xi, jacobians=False).output_pose[0]
        from hyperstat.solver.kinematics.frames import so3_log

        w = so3_log((pose[:3, :3] @ nominal[:3, :3].T)[None])[0]
        return sel @ np.r_[w * kin.length_scale, pose[:3, 3] - nominal[:3, 3]]

    before = float(np.linalg.norm(err(np.zeros(len(act)))))
    after = float(np.linalg.norm(least_squares(err, np.zeros(len(act)), xtol=1e-15, ftol=1e-15).fun))
    return before, after


def test_compensable_is_cancelled_by_the_actuators_and_critical_is_not():
    """Second method: nonlinear re-assembly with the actuators moved to cancel the task error."""
    mech, kin, result = _setup("slider_crank")
    decl = parse_declaration({"task": ["x", "z"]}, "test")  # z: the slide's height, which the crank cannot move
    cl = classify(mech, result, kin, decl)
    by = {t.statement: t for t in cl.items}
    q = result.configurations[1]
    size = 1e-4
    b, a = _task_residual_after_actuators(mech, kin, cl, by["da2"], q, size)
    assert by["da2"].cls == "compensable" and a < 1e-3 * b
    crit = [t for t in cl.items if t.cls == "accuracy-critical"]
    assert crit, "a tilt of the slide moves its height, which one actuator cannot cancel"
    b, a = _task_residual_after_actuators(mech, kin, cl, crit[0], q, size)
    assert a > 0.1 * b


def test_declaration_errors_name_the_field():
    with pytest.raises(ModelError, match="tolerancing.task component 'speed'"):
        parse_declaration({"task": ["speed"]}, "m.json")
    with pytest.raises(ModelError, match="tolerancing.clearances.R.radial_mm must be a non-negative number"):
        parse_declaration({"clearances": {"R": {"radial_mm": -1}}}, "m.json")


def test_five_bar_planar_loop_conditions():
    """The planar five-bar: its axes must stay parallel and its joints in one plane (nonlinear re-assembly)."""
    mech, kin, result = _setup("five_bar")
    cl = classify(mech, result, kin)
    assert result.mobility == 2 and result.overconstraint == 3
    counts = cl.counts()
    assert counts["assembly"] == len(result.by_verdict("forced")) + len(result.relations) == 10
    # the out-of-plane relation keeps every shift along the parallel axes (dc5 ≡ dc4 ≡ dc6 resolved)
    rel = [t for t in cl.items if t.kind == "relation" and "dc6" in t.terms]
    assert len(rel) == 1 and {"dc2", "dc3", "dc4", "dc5", "dc6"} <= set(rel[0].terms)
    q = result.configurations[:3]
    for t in cl.items:
        gap = np.max(_gap(kin, mech, 1e-3 * t.direction / np.max(np.abs(t.direction)), q))
        assert (gap > 1e-4) if t.cls == "assembly" else (gap < 1e-7), (t.statement, gap)
    # out-of-plane defects move nothing in the plane: non-influent for the task (x, y)
    for t in cl.by_class("non-influent"):
        xi = 1e-5 * t.direction  # a first-order effect would move C by about 1e-5 x 100 mm = 1e-3 mm
        res = kin.assemble(q.copy(), xi)
        moved = kin.evaluate(res.q, xi, jacobians=False).output_pose[:, :2, 3] - \
            kin.evaluate(q, None, jacobians=False).output_pose[:, :2, 3]
        assert np.max(np.abs(moved)) < 1e-6, t.statement  # mm: second order only


def test_declaration_travels_from_template_to_model_file_and_back(tmp_path, capsys):
    """The template's TOLERANCING reaches the model file (optional field) and a model file gives the same classes."""
    import json

    from hyperstat.cad_plugin.cli import main

    model = tmp_path / "m.json"
    assert main(["build", str(TEMPLATES / "tripteor_x7.py"), "--model", str(model)]) == 0
    doc = json.loads(model.read_text())
    assert doc["tolerancing"]["task"] == ["position", "tool-axis"]
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    assert main(["analyze", str(TEMPLATES / "tripteor_x7.py"), "--json", str(a), "--quiet"]) == 0
    assert main(["analyze", str(model), "--json", str(b), "--quiet"]) == 0
    ta, tb = json.loads(a.read_text())["tolerances"], json.loads(b.read_text())["tolerances"]
    assert ta["counts"] == tb["counts"] and ta["parameters"] == tb["parameters"]
    # a bad declaration in a model file: one sentence naming the field, exit 2, nothing written
    doc["tolerancing"]["spec"] = {"position_mm": -1}
    model.write_text(json.dumps(doc))
    out = tmp_path / "c.json"
    capsys.readouterr()
    assert main(["analyze", str(model), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert "tolerancing.spec.position_mm" in err and err.count("\n") == 1 and not out.exists()


def test_bad_template_declaration_is_one_sentence(tmp_path, capsys):
    from hyperstat.cad_plugin.cli import main

    src = (TEMPLATES / "slider_crank.py").read_text().replace('"task": ["x"]', '"task": ["speed"]')
    bad = tmp_path / "bad.py"
    bad.write_text(src)
    assert main(["analyze", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "TOLERANCING" in err and "task component 'speed' is unknown" in err and err.count("\n") == 1


@pytest.fixture(scope="module")
def tripteor():
    mech, kin, result = _setup("tripteor_x7")
    return mech, kin, result, classify(mech, result, kin)


def test_tripteor_accuracy_critical_db7_is_indistinguishable_from_the_target_offsets(tripteor):
    """Second method: finite differences of the re-assembled model, not the classifier's twist maps."""
    mech, kin, result, cl = tripteor
    t = next(i for i in cl.items if i.statement == "db7")
    assert t.cls == "accuracy-critical"
    q = result.configurations
    targets = np.array(cl.declaration.targets_mm)
    size = 1e-4

    def measured(xi):
        res = kin.assemble(q.copy(), xi)
        pose = kin.evaluate(res.q, xi, jacobians=False).output_pose
        return np.concatenate([pose[:, :3, 3] + pose[:, :3, :3] @ tt for tt in targets], axis=1), pose

    y0, pose0 = measured(np.zeros(len(mech.parameters)))
    y1, pose1 = measured(size * t.direction)
    signature = ((y1 - y0) / size).ravel()
    # columns of the unknown target offsets (each target moves with the output frame)
    offsets = np.zeros((len(q), 3 * len(targets), 3 * len(targets)))
    for k in range(len(targets)):
        offsets[:, 3 * k:3 * k + 3, 3 * k:3 * k + 3] = pose0[:, :3, :3]
    cols = offsets.reshape(-1, 3 * len(targets))
    coef, *_ = np.linalg.lstsq(cols, signature, rcond=None)
    assert np.linalg.norm(cols @ coef - signature) < 1e-4 * np.linalg.norm(signature)  # first order: O(size)
    # ... yet it moves the tool tip, which the task uses
    assert np.max(np.linalg.norm(pose1[:, :3, 3] - pose0[:, :3, 3], axis=1)) > 0.5 * size


def test_tripteor_compensable_tilt_is_cancelled_by_the_five_actuators(tripteor):
    mech, kin, result, cl = tripteor
    t = next(i for i in cl.items if i.statement == "dJ62")
    assert t.cls == "compensable"
    b, a = _task_residual_after_actuators(mech, kin, cl, t, result.configurations[2], 1e-4)
    assert b > 1e-3 and a < 1e-3 * b  # tool tip and tool axis restored (second order left)
