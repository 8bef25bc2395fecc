"""Assembly tolerances from joint clearances, confirmed by nonlinear re-assembly with the plays as small joints.

Units: mm and rad.  The linear programme gives the largest violation the plays absorb; the nonlinear
model (every joint free to move within its play, the loops closed by Newton steps, then sequential
linear programming for the largest violation) must agree, and the plays must be physical: a carriage
tilts about itself, a guide at the joint's fixed frame about the guide, two supports cannot both take
their whole radial play in opposite directions and shift at the same time.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from hyperstat.cad_plugin.templates import build_template
from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.tolerances.classification import classify
from hyperstat.solver.tolerances.clearance import (POLYGON_SIDES, assembly_tolerances, clearance_model,
                                                   confirm_nonlinear)
from hyperstat.solver.tolerances.declaration import declaration_of, parse_declaration

from tests.conftest import TEMPLATES
from tests.solver.tolerances.common import classified, recorded_forks


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
        assert v["value"] <= v["sampled_value"]  # the search never states more than its starting configurations
        check = confirm_nonlinear(mech, t.direction, v["value"], v["worst_q"], cl.declaration, model=model)
        below = check["below"]
        # 1 % below the linear value the loops close with every play within its clearance
        assert below["closure_residual_mm"] < 1e-9, (t.statement, below)
        assert below["largest_clearance_use"] <= 1.0 + 1e-9
        # the nonlinear largest violation agrees with the linear one to second order (violations of mrad)
        assert check["relative_difference"] < 5e-3, (t.statement, check)
        assert check["closure_residual_mm"] < 1e-4 * v["value"] * (1000.0 if t.unit == "rad" else 1.0)


def test_more_clearance_gives_a_larger_assembly_tolerance_and_none_gives_zero(slider):
    """Twice every play (the spans held) gives twice every value; no play gives zero."""
    mech, result, cl, items, model, values = slider
    q = result.configurations[:6]
    once = assembly_tolerances(mech, items, cl.declaration, q, search=False)
    twice = parse_declaration({"clearances": {k: {"radial_mm": 2 * c["radial_mm"], "axial_mm": 2 * c["axial_mm"],
                                                  "twist_rad": 2 * c["twist_rad"], "span_mm": c["span_mm"]}
                                              for k, c in (("R", cl.declaration.clearance("", "R")),
                                                           ("P", cl.declaration.clearance("", "P")))}}, "test")
    doubled = assembly_tolerances(mech, items, twice, q, search=False)
    for t in items:
        assert doubled[t.id]["value"] == pytest.approx(2 * once[t.id]["value"], rel=1e-6)
    none = parse_declaration({"clearances": {k: {"radial_mm": 0, "axial_mm": 0, "tilt_rad": 0, "twist_rad": 0}
                                             for k in ("R", "P")}}, "test")
    zero = assembly_tolerances(mech, items, none, q[:4], search=False)
    assert all(zero[t.id]["value"] == 0.0 for t in items)


def test_a_violation_beyond_the_tolerance_does_not_close_with_the_exact_discs(slider):
    """Independent of the programme and of its polygons: the supports' radial plays as exact discs (SLSQP with
    the disc constraints) close the loop 1 % below the value and cannot close it 20 % beyond (the inscribed
    octagon loses at most 1 / cos(pi / 8) - 1 = 8.2 % of the play)."""
    from scipy.optimize import minimize

    mech, result, cl, items, model, values = slider
    t = next(i for i in items if i.statement == "dc2 + dc3 = 0")
    v = values[t.id]
    q0 = v["worst_q"]
    kin = Kinematics(model.mechanism)
    passive = model.mechanism.passive
    d = np.zeros(len(model.mechanism.parameters))
    d[list(model.index_of.values())] = t.direction
    n_p, n_g = len(passive), model.columns.shape[1]
    # each support of a joint: (v1 + s w2, v2 - s w1), s = +-1, in the unit disc (units of the play)
    pads = []
    for kind, cols in model.groups:
        if kind == "pads":
            v1, v2, w1, w2 = cols
            pads += [((v1, w2, 1.0), (v2, w1, -1.0)), ((v1, w2, -1.0), (v2, w1, 1.0))]

    def gap(size: float) -> float:
        def residuals(zs):  # the loop's residual at each row of zs, one batched evaluation
            q = np.repeat(q0[None], len(zs), axis=0)
            q[:, passive] = zs[:, :n_p]
            xi = size * d[None] + zs[:, n_p:] @ model.columns.T
            return kin.scaled(kin.evaluate(q, xi, jacobians=False).residual)

        def residual(z):
            return residuals(z[None])[0]

        def residual_jacobian(z):  # forward differences, as SLSQP's own, in one evaluation instead of one per column
            h = 1.4901161193847656e-08 * np.maximum(1.0, np.abs(z))
            r = residuals(np.vstack([z, z[None] + np.diag(h)]))
            return ((r[1:] - r[0]) / h[:, None]).T

        cons = [{"type": "ineq", "fun": (lambda z, a=a, b=b: 1.0 - (z[n_p + a[0]] + a[2] * z[n_p + a[1]]) ** 2
                                         - (z[n_p + b[0]] + b[2] * z[n_p + b[1]]) ** 2)} for a, b in pads]
        cons.append({"type": "eq", "fun": residual, "jac": residual_jacobian})  # the loop closed
        bounds = [(None, None)] * n_p + [(-1.0, 1.0)] * n_g
        res = minimize(lambda z: float(z[n_p:] @ z[n_p:]), np.r_[q0[passive], np.zeros(n_g)],
                       method="SLSQP", bounds=bounds, constraints=cons, options={"maxiter": 500, "ftol": 1e-14})
        return float(np.linalg.norm(residual(res.x)))

    assert gap(0.99 * v["value"]) < 1e-6
    assert gap(1.2 * v["value"]) > 1e-3  # mm: the plays run out


def test_a_carriage_tilts_about_itself_and_a_guide_about_the_guide():
    """The slider-crank's carriage (moving side, 40 mm) tilts about the slider wherever it is: one unit of tilt moves
    the slider's frame by nothing and a point 20 mm along the guide by the radial play; the Tripteor's legs slide
    in a guide at their base joint (fixed side, 200 mm): the tilt turns the leg about the base joint, so the leg's
    end moves by the tilt times the leg length."""
    for name, joint, frame_of, reach in (("slider_crank", "4", "moving", 20.0), ("tripteor_x7", "41", "fixed", None)):
        mech = build_template(TEMPLATES / f"{name}.py").mechanism()
        decl = declaration_of(mech)
        model = clearance_model(mech, decl)
        kin = Kinematics(model.mechanism)
        c = decl.clearance(joint, "P")
        assert c["side"] == frame_of
        col = model.labels.index(f"joint {joint} tilt about u2")
        q = mech.home[None]
        nominal = kin.evaluate(q, None, jacobians=False)
        tilted = kin.evaluate(q, 1e-3 * model.columns[:, col], jacobians=False)  # 1e-3 of the tilt
        ci = next(i for i, ch in enumerate(model.mechanism.chains) for el in ch.elements if el.name == joint)
        ei = next(i for i, el in enumerate(model.mechanism.chains[ci].elements) if el.name == joint)
        # the moving frame of the joint: the element after it (the play frame) on the moving side, else the joint's
        key = (ci, ei + 1) if frame_of == "moving" else (ci, ei)
        f0, f1 = nominal.element_frames[key][0], tilted.element_frames[key][0]
        turn = 1e-3 * c["tilt_rad"]
        axis = 2 if frame_of == "fixed" else 0  # the tilt about u2 turns both the joint axis and u1
        axis_turn = np.linalg.norm(np.cross(f0[:3, axis], f1[:3, axis]))
        if frame_of == "moving":
            assert np.linalg.norm(f1[:3, 3] - f0[:3, 3]) < 1e-12  # about the carriage itself
            point = f0[:3, :3] @ np.array([0, 0, reach])
            moved = f1[:3, :3] @ np.array([0, 0, reach]) - point
            assert np.linalg.norm(moved) == pytest.approx(1e-3 * c["radial_mm"], rel=1e-6)
            assert axis_turn == pytest.approx(turn, rel=1e-6)
        else:
            assert np.linalg.norm(f1[:3, 3] - f0[:3, 3]) < 1e-12  # about the guide at the base joint
            assert axis_turn == pytest.approx(turn, rel=1e-6)
            length = mech.home[mech.joint_index[joint]]
            end0 = f0[:3, 3] + length * f0[:3, 2]
            end1 = f1[:3, 3] + length * f1[:3, 2]
            assert np.linalg.norm(end1 - end0) == pytest.approx(turn * length, rel=1e-6)


def test_the_supports_polygons_are_inscribed_in_the_discs_of_play(slider):
    """Every vertex of a support's polygon lies on its disc of radial play (safe side), and a support cannot shift
    and tilt fully at once: the largest shift with the largest tilt is zero."""
    from scipy.optimize import linprog

    mech, result, cl, items, model, values = slider
    kind, cols = next(g for g in model.groups if g[0] == "pads")
    n_g = model.columns.shape[1]
    a_ub = np.vstack([model.polygon, -model.polygon])
    b_ub = np.full(len(a_ub), model.limit)
    for phi in np.linspace(0, 2 * np.pi, 37):  # the support's radial play in every direction
        c = np.zeros(n_g)
        c[cols[0]], c[cols[1]] = -np.cos(phi), -np.sin(phi)  # maximise the shift (both supports together)
        res = linprog(c, A_ub=a_ub, b_ub=b_ub, bounds=[(-1, 1)] * n_g, method="highs-ds")
        assert math.cos(math.pi / POLYGON_SIDES) - 1e-9 <= -res.fun <= 1.0 + 1e-9
    c = np.zeros(n_g)
    c[cols[3]] = -1.0  # the largest tilt
    eq = np.zeros((1, n_g))
    eq[0, cols[0]] = 1.0
    res = linprog(c, A_ub=a_ub, b_ub=b_ub, A_eq=eq, b_eq=[0.3], bounds=[(-1, 1)] * n_g, method="highs-ds")
    assert -res.fun <= 0.7 + 1e-9  # shifting by 0.3 of the play leaves at most 0.7 of the tilt


def test_tripteor_relation_and_shift_confirmed_nonlinearly():
    """The out-of-plane relation (with db53) and the forced dc13 of the Tripteor, declared machine-tool bearings."""
    mech, kin, result, cl = classified("tripteor_x7")
    items = [t for t in cl.by_class("assembly") if t.statement == "dc13 = 0" or "db53" in t.terms]
    assert len(items) == 2
    model = clearance_model(mech, cl.declaration)
    values = assembly_tolerances(mech, items, cl.declaration, result.configurations[:12], model, search=False)
    for t in items:
        v = values[t.id]
        check = confirm_nonlinear(mech, t.direction, v["value"], v["worst_q"], cl.declaration, model=model)
        assert check["below"]["closure_residual_mm"] < 1e-9 and check["below"]["largest_clearance_use"] <= 1 + 1e-9
        assert check["relative_difference"] < 1e-2, (t.statement, check)


def test_the_zonotope_programme_gives_the_polygon_programmes_value(slider):
    """The value-only programme works on the play set as a sum of segments (``ClearanceModel.generators``); written
    here independently on the supports' polygons (``|P y| <= limit``, ``|y| <= 1``) with HiGHS, ``t`` in units of
    the block's own scale so that the solver's absolute tolerance does not limit it, the two agree: the same set
    (its support function in 40 directions) and the same largest violation at every configuration."""
    from scipy.optimize import linprog

    from hyperstat.solver.tolerances.clearance import AssemblyConditions, _constraint_blocks, _lift

    mech, result, cl, items, model, values = slider
    gen = model.generators
    n_g = model.columns.shape[1]
    a_ub = np.vstack([model.polygon, -model.polygon])
    b_ub = np.full(len(a_ub), model.limit)
    rng = np.random.default_rng(3)
    for c in rng.normal(size=(40, n_g)):  # support functions: max c.y over the polygons = sum |c . g|
        res = linprog(-c, A_ub=a_ub, b_ub=b_ub, bounds=[(-1, 1)] * n_g, method="highs-ds")
        assert float(np.sum(np.abs(c @ gen))) == pytest.approx(-res.fun, rel=1e-9)
    q = result.configurations[:4]
    objective = AssemblyConditions(model, items)
    got = objective.values(q)
    blocks = _constraint_blocks(model, q)
    assert all(len(av) == 3 for _, av in blocks)  # three rows left: the programme, not the closed form
    for t in items:
        d = _lift(model, t.direction)
        for k, (cg, a) in enumerate(blocks):
            av = a @ d
            unit = np.linalg.norm(cg) / np.linalg.norm(av)  # t = unit * s
            res = linprog(np.r_[np.zeros(n_g), -1.0], A_eq=np.c_[cg, unit * av], b_eq=np.zeros(len(av)),
                          A_ub=np.c_[a_ub, np.zeros(len(a_ub))], b_ub=b_ub, bounds=[(-1, 1)] * n_g + [(0, None)],
                          method="highs-ds", options={"primal_feasibility_tolerance": 1e-10,
                                                      "dual_feasibility_tolerance": 1e-10})
            assert res.success
            assert got[t.id][k] == pytest.approx(unit * res.x[-1], rel=1e-8), (t.statement, k)


def test_many_blocks_are_split_with_a_child_when_a_core_is_idle_with_the_same_values(slider, monkeypatch):
    """clearance._solve gives half its groups of blocks to a forked child when a core is idle: the same groups, so
    the same bits as without the child, and each configuration's values those it has when evaluated alone."""
    from hyperstat.solver import forked
    from hyperstat.solver.tolerances.clearance import LP_GROUP, PARALLEL_GROUPS, AssemblyConditions

    mech, result, cl, items, model, values = slider
    q = np.repeat(result.configurations, 2, axis=0)[: 2 * PARALLEL_GROUPS * LP_GROUP // len(items) + 1]
    assert len(q) * len(items) >= PARALLEL_GROUPS * LP_GROUP  # enough blocks for the split
    objective = AssemblyConditions(model, items)
    started = recorded_forks(monkeypatch)
    got = {}
    for idle in (False, True):
        monkeypatch.setattr(forked, "idle_core", lambda idle=idle: idle)
        which = [t.id for _ in q for t in items]
        got[idle] = objective.plays(np.repeat(q, len(items), axis=0), which, exact=True)
        got[(idle, "values")] = objective.values(q)
    assert started and all(pid is not None for _, pid in started)  # the split happened, in children
    t_true, y_true = got[True]
    t_false, y_false = got[False]
    assert t_true.tobytes() == t_false.tobytes()
    assert all((a is None and b is None) or a.tobytes() == b.tobytes() for a, b in zip(y_true, y_false))
    for t in items:
        assert got[(True, "values")][t.id].tobytes() == got[(False, "values")][t.id].tobytes()
    # every configuration's values as when it is evaluated alone (one group of its own blocks: the same programme
    # up to the solver's round-off), in order
    for k in range(len(q)):
        alone = objective.values(q[k:k + 1])
        for t in items:
            assert got[(True, "values")][t.id][k] == pytest.approx(alone[t.id][0], rel=1e-8, abs=1e-15), (k, t.id)


def test_the_revolute_deltas_programmes_are_within_1e_7_of_an_interior_point_optimum_and_a_dual_bound():
    """The corpus' revolute Delta (47 conditions, 12 closure rows left to 168 segments of the play set): at the
    analysis' first configurations every condition's ``t`` lies between 1 - 1e-7 times the optimum of the same
    programme solved here by HiGHS' interior-point method (on the plays themselves, not the product's orthonormal
    rows) and 1 + 1e-7 times the bound of weak duality, ``sum |(E G)^T u| / |e . u|`` for the ``u`` of the dual
    programme solved here.  (HiGHS' dual simplex, as the product calls it, reads up to 6.7e-8 above that bound here,
    16 of the 188 programmes more than 1e-9: the module docstring of ``hyperstat.solver.tolerances.clearance``.)"""
    from scipy.optimize import linprog

    from hyperstat.solver.tolerances.clearance import AssemblyConditions, _constraint_blocks, _lift

    mech, _, result, cl = classified("corpus/delta_r")
    items = cl.by_class("assembly")
    model = clearance_model(mech, cl.declaration)
    q = result.configurations[:4]
    got = AssemblyConditions(model, items).values(q)
    gen = model.generators
    n = gen.shape[1]
    checked = 0
    for k, (cg, a) in enumerate(_constraint_blocks(model, q)):
        g = cg @ gen
        m = g.shape[0]
        assert m > 2  # the programme, not the closed form of one or two rows
        for t in items:
            av = a @ _lift(model, t.direction)
            primal = linprog(np.r_[np.zeros(n), -1.0], A_eq=np.c_[g, av] / np.abs(g).max(), b_eq=np.zeros(m),
                             bounds=[(-1, 1)] * n + [(0, None)], method="highs-ipm",
                             options={"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10})
            dual = linprog(np.r_[np.zeros(m), np.ones(n)], A_ub=np.block([[g.T, -np.eye(n)], [-g.T, -np.eye(n)]]),
                           b_ub=np.zeros(2 * n), A_eq=np.r_[av, np.zeros(n)][None], b_eq=[-1.0],
                           bounds=[(None, None)] * m + [(0, None)] * n, method="highs-ds")
            assert primal.success and dual.success
            u = dual.x[:m]
            upper = float(np.sum(np.abs(g.T @ u))) / abs(float(av @ u))  # t <= this for any u (weak duality)
            lower = float(primal.x[-1])
            assert lower <= upper * (1 + 1e-12)
            value = got[t.id][k]
            assert lower * (1 - 1e-7) <= value <= upper * (1 + 1e-7), (t.statement, value, lower, upper)
            checked += 1
    assert checked == len(q) * len(items) == 4 * 47
