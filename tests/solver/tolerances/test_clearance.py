"""Assembly tolerances from joint clearances, confirmed by nonlinear re-assembly with the clearances as small joints.

Units: mm and rad.  The linear programme gives the largest violation the clearances absorb;
the nonlinear model (every joint frame free to move within its clearance, the loops closed
by Newton steps, then sequential linear programming for the largest violation) must agree.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hyperstat.cad_plugin.templates import build_template
from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.tolerances.classification import classify
from hyperstat.solver.tolerances.clearance import assembly_tolerances, clearance_model, confirm_nonlinear
from hyperstat.solver.tolerances.declaration import parse_declaration

from tests.conftest import TEMPLATES


@pytest.fixture(scope="module")
def slider():
    mech = build_template(TEMPLATES / "slider_crank.py").mechanism()
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, kinematics=kin)
    cl = classify(mech, result, kin)
    items = cl.by_class("assembly")
    model = clearance_model(mech, cl.declaration)
    values = assembly_tolerances(mech, items, cl.declaration, result.configurations, model)
    return mech, result, cl, items, model, values


def test_every_assembly_condition_of_the_slider_crank_is_confirmed_nonlinearly(slider):
    mech, result, cl, items, model, values = slider
    assert [t.statement for t in items] == ["dI2 = 0", "dJ2 = 0", "dI3 = 0", "dJ3 = 0", "dc2 + dc3 = 0", "dJ4 = 0"]
    for t in items:
        v = values[t.id]
        assert v["value"] is not None and v["value"] > 0
        q = result.configurations[v["worst_configuration"]]
        check = confirm_nonlinear(mech, t.direction, v["value"], q, cl.declaration, model=model)
        below = check["below"]
        # 1 % below the linear value the loops close with every play within its clearance
        assert below["closure_residual_mm"] < 1e-9, (t.statement, below)
        assert below["largest_clearance_use"] <= 1.0 + 1e-9
        # the nonlinear largest violation agrees with the linear one to second order (violations of mrad)
        assert check["relative_difference"] < 5e-3, (t.statement, check)
        assert check["closure_residual_mm"] < 1e-4 * v["value"] * (1000.0 if t.unit == "rad" else 1.0)


def test_more_clearance_gives_a_larger_assembly_tolerance_and_none_gives_zero(slider):
    """Monotone in the clearances, and proportional: the linear programme scales with them."""
    mech, result, cl, items, model, values = slider
    twice = parse_declaration({"clearances": {k: {kk: 2 * vv for kk, vv in c.items() if kk != "source"}
                                              for k, c in cl.declaration.to_dict()["clearances"].items()
                                              if k in ("R", "P")}}, "test")
    doubled = assembly_tolerances(mech, items, twice, result.configurations)
    for t in items:
        assert doubled[t.id]["value"] == pytest.approx(2 * values[t.id]["value"], rel=1e-6)
    none = parse_declaration({"clearances": {k: {"radial_mm": 0, "axial_mm": 0, "tilt_rad": 0, "twist_rad": 0}
                                             for k in ("R", "P")}}, "test")
    zero = assembly_tolerances(mech, items, none, result.configurations[:4])
    assert all(zero[t.id]["value"] == 0.0 for t in items)


def test_a_violation_beyond_the_tolerance_does_not_close(slider):
    """Independent of the programme: bounded least squares over the plays cannot close 20 % beyond."""
    from scipy.optimize import least_squares

    mech, result, cl, items, model, values = slider
    t = next(i for i in items if i.statement == "dc2 + dc3 = 0")
    v = values[t.id]
    q0 = result.configurations[v["worst_configuration"]]
    kin = Kinematics(model.mechanism)
    passive = model.mechanism.passive
    d = np.zeros(len(model.mechanism.parameters))
    d[list(model.index_of.values())] = t.direction

    def smallest_gap(size: float) -> float:
        def fun(z):
            q = q0.copy()
            q[passive] = z[: len(passive)]
            xi = size * d + model.columns @ (z[len(passive):] * model.bounds)
            return kin.scaled(kin.evaluate(q[None], xi, jacobians=False).residual)[0]

        n_g = model.columns.shape[1]
        lo = np.r_[np.full(len(passive), -np.inf), -np.ones(n_g)]
        hi = np.r_[np.full(len(passive), np.inf), np.ones(n_g)]
        res = least_squares(fun, np.r_[q0[passive], np.zeros(n_g)], bounds=(lo, hi), max_nfev=400)
        return float(np.linalg.norm(res.fun))

    assert smallest_gap(1.2 * v["value"]) > 1e-3  # mm: the plays run out


def test_tripteor_relation_and_shift_confirmed_nonlinearly():
    """The out-of-plane relation (with db53) and the forced dc13 of the Tripteor, declared machine-tool bearings."""
    mech = build_template(TEMPLATES / "tripteor_x7.py").mechanism()
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, kinematics=kin)
    cl = classify(mech, result, kin)
    items = [t for t in cl.by_class("assembly") if t.statement == "dc13 = 0" or "db53" in t.terms]
    assert len(items) == 2
    model = clearance_model(mech, cl.declaration)
    values = assembly_tolerances(mech, items, cl.declaration, result.configurations[:12], model)
    for t in items:
        v = values[t.id]
        check = confirm_nonlinear(mech, t.direction, v["value"], result.configurations[v["worst_configuration"]],
                                  cl.declaration, model=model)
        assert check["below"]["closure_residual_mm"] < 1e-9 and check["below"]["largest_clearance_use"] <= 1 + 1e-9
        assert check["relative_difference"] < 1e-2, (t.statement, check)
