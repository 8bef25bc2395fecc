"""Tolerance values on worst cases over the declared workspace, not on sampled maxima (issue 19, issue 24 item 1).

Units: mm and rad.  Expected values come from the paper's geometry (Triflex-II, paper 2 section
5.3: epsilon_gR max = a_p + a3 at theta3 = 90 deg, eq. 27; the length errors shift the translating
platform along the slide axes), from a second method (issue 24's SLSQP refinement, the LP solved
per configuration) and from inequalities that must hold whatever the numbers (a refined maximum is
at least the sampled one, so its value is at most the sampled value).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from hyperstat.cad_plugin.templates import build_template, template_parameters, load_template
from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.tolerances.accuracy import sample_workspace
from hyperstat.solver.tolerances.classification import classify
from hyperstat.solver.tolerances.clearance import AssemblyConditions, _solve, _constraint_blocks, _lift, \
    assembly_tolerances, clearance_model
from hyperstat.solver.tolerances.values import assign_values

from tests.conftest import TEMPLATES
from tests.solver.tolerances.common import classified, recorded_forks


def _setup(name: str, n: int = 200):
    mech = build_template(TEMPLATES / name).mechanism()
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, kinematics=kin)
        q = sample_workspace(mech, n, seed=0, kinematics=kin)
    return mech, kin, result, q


@pytest.fixture(scope="module")
def triflex():
    return _setup("triflex_ii.py")


def _values(mech, kin, result, q, refine):
    cl = classify(mech, result, kin)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assign_values(cl, mech, kin, q, assembly=False, refine=refine)
    return cl


def test_triflex_values_equal_the_closed_form_of_the_papers_maxima(triflex):
    mech, kin, result, q = triflex
    cl = _values(mech, kin, result, q, True)
    p = template_parameters(load_template(TEMPLATES / "triflex_ii.py"))()
    spec = cl.declaration.position_mm  # the template's position spec; no orientation spec (translational task)
    influential = [t for t in cl.items if t.cls in ("accuracy-critical", "compensable")]
    lengths = [t for t in influential if t.unit == "mm"]
    angles = [t for t in influential if t.unit == "rad"]
    assert len(lengths) == 4 and len(angles) == 5  # the paper's nine errors (section 5.1)
    assert all(t.cls == "compensable" for t in influential)  # so the uncalibrated allocation gives the values
    # epsilon_gP: d2, d3 shift along the PRRR axes (z), d6, d7 along the PRRU axes (x); the platform only
    # translates, so each moves O_p by its own shift: E_gP = [z z x x], whose largest singular value is
    e_gp = np.linalg.svd(np.array([[0, 0, 1], [0, 0, 1], [1, 0, 0], [1, 0, 0]], float).T, compute_uv=False)[0]
    e_gr = (p.a_p + p.a3) * p.length_unit  # eq. 27: a_p + a3 at theta3 = 90 deg
    # equal allocation (eqs. 30-31): two classes share the position spec, each over sqrt(n) parameters
    d_t = (spec / 2) / (e_gp * math.sqrt(4))
    alpha_t = (spec / 2) / (e_gr * math.sqrt(5))
    for t in lengths:
        assert t.value == pytest.approx(d_t, rel=1e-7)
    for t in angles:
        assert t.value == pytest.approx(alpha_t, rel=1e-7)  # the refined maximum's tolerance is ~1e-8
    worst = cl.allocation["uncalibrated"]["worst_cases"]
    assert worst["epsilon_gR"]["sampled_max"] < worst["epsilon_gR"]["max"]  # the sample is low: the refinement moved
    assert worst["epsilon_gR"]["location"] == "interior" and "O_p" in worst["epsilon_gR"]["where"]
    assert math.isfinite(worst["epsilon_gR"]["optimiser_tolerance"])
    assert "worst case over the declared workspace" in angles[0].value_source


def test_refined_values_are_never_looser_than_sampled_ones(triflex):
    mech, kin, result, q = triflex
    for cl_s, cl_r in ((_values(mech, kin, result, q[:60], False), _values(mech, kin, result, q[:60], True)),):
        for a, b in zip(cl_s.items, cl_r.items):
            if a.value is not None and a.cls in ("accuracy-critical", "compensable"):
                assert b.value <= a.value * (1 + 1e-12), (a.id, a.value, b.value)
        assert any(b.value < a.value * (1 - 1e-4) for a, b in zip(cl_s.items, cl_r.items) if a.value)


def test_the_tripteor_refinement_finds_maxima_above_the_sample_and_says_where():
    mech, kin, result, q = _setup("tripteor_x7.py")
    cl = _values(mech, kin, result, q, True)
    worst = cl.allocation["uncalibrated"]["worst_cases"]
    assert worst["epsilon_gR"]["max"] > worst["epsilon_gR"]["sampled_max"]
    for name, w in worst.items():
        assert w["max"] >= w["sampled_max"] and w["where"], name
    # the verdicts hold at the worst cases too (compensable: cancellable at every configuration of the workspace)
    assert cl.checked["worst_cases"] >= 1 and cl.checked["worst_cases_agree"] is True
    assert cl.checked["margin"] > 1 and cl.checked["of"]["workspace_sample"] > 0


def test_the_dual_evaluation_equals_one_programme_per_configuration():
    """Where one or two closure constraints are left (the Tripteor), the violation comes from the dual without a
    solver; it equals the programme solved for each configuration alone (HiGHS dual simplex)."""
    mech, kin, result, q = _setup("tripteor_x7.py", 30)
    cl = classify(mech, result, kin)
    items = cl.by_class("assembly")
    model = clearance_model(mech, cl.declaration)
    objective = AssemblyConditions(model, items)
    fast = objective.values(q)
    blocks = _constraint_blocks(model, q)
    assert all(len(av) == 2 for _, av in blocks)  # the dual path is the one taken
    for t in items[::3]:
        d = _lift(model, t.direction)
        each = np.array([_solve(model, [(cg, a @ d)])[0][0] for cg, a in blocks])
        np.testing.assert_allclose(fast[t.id], each, rtol=1e-8, err_msg=t.statement)


def test_tripteor_workspace_assembly_values_are_confirmed_nonlinearly_at_their_worst_configuration():
    """The search finds worst cases the analysis configurations miss; re-assembled there with the plays as small
    joints, the loops close 1 % below the value and not beyond it."""
    from hyperstat.solver.tolerances.classification import workspace_checkpoints
    from hyperstat.solver.tolerances.clearance import confirm_nonlinear

    mech, kin, result, cl = classified("tripteor_x7")
    sample, corners = workspace_checkpoints(mech, kin)
    qa = np.vstack([result.configurations[:8], sample, corners])
    model = clearance_model(mech, cl.declaration)
    items = {t.statement: t for t in cl.by_class("assembly")}
    chosen = [items["dK13 = 0"], items["dK21 - dK23 = 0"]]
    values = assembly_tolerances(mech, chosen, cl.declaration, qa, model, reference=8)
    for t in chosen:
        v = values[t.id]
        assert v["reference_value"] > v["value"] and v["sampled_value"] >= v["value"]
        check = confirm_nonlinear(mech, t.direction, v["value"], v["worst_q"], cl.declaration, model=model)
        assert check["below"]["closure_residual_mm"] < 1e-9 and check["below"]["largest_clearance_use"] <= 1 + 1e-9
        assert check["relative_difference"] < 5e-3, (t.statement, check)


@pytest.mark.parametrize("name", ["tripteor_x7.py", "hexapod.py", "scara.py"])
def test_machine_tool_templates_declare_the_sourced_clearances(name):
    """The ISO 5753-1 C2 revolute play (+-5 um: half of 0-10 um; tilt 10 um over 50 mm), the prismatic play assumed."""
    from hyperstat.solver.tolerances.declaration import MACHINE_TOOL_CLEARANCES, parse_declaration

    declared = load_template(TEMPLATES / name).TOLERANCING["clearances"]
    assert declared == MACHINE_TOOL_CLEARANCES
    r = parse_declaration({"clearances": declared}, name).clearance("21", "R")
    assert r["radial_mm"] == pytest.approx(0.010 / 2) and r["tilt_rad"] == pytest.approx(2 * 0.005 / 50.0)
    assert r["span_mm"] == 50.0 and r["side"] == "fixed"
    assert "ISO 5753-1" in r["source"] and "assumed" in declared["P"]["source"]


def test_the_bounds_by_a_child_beside_the_drawing_are_the_same_bits(triflex, monkeypatch):
    """When a core is idle, the attainable and triangle bounds are searched by a forked child while the drawing
    values are computed (:func:`hyperstat.solver.forked.when_idle`): every value, bound and word the same."""
    import json

    from hyperstat.solver import forked

    mech, kin, result, q = triflex
    started = recorded_forks(monkeypatch)
    out = {}
    for idle in (False, True):
        monkeypatch.setattr(forked, "idle_core", lambda idle=idle: idle)
        cl = _values(mech, kin, result, q[:60], refine=True)
        out[idle] = json.dumps({"items": cl.to_dict(), "allocation": cl.allocation}, sort_keys=True, default=repr)
        if not idle:
            assert "_bounds" not in [n for n, _ in started]
    bounds = [pid for n, pid in started if n == "_bounds"]
    assert len(bounds) == 1 and bounds[0] is not None  # searched by a child
    assert '"attainable_linear_worst_case": null' not in out[True]
    assert json.loads(out[True])["allocation"]["uncalibrated"]["bounds"]["triangle_bound"] > 0
    assert out[True] == out[False]
