"""Stationarity analysis: slider-crank verdicts proven three ways, serial chains against eq. (1)."""

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hyperstat.solver import Kinematics, MechanismBuilder, analyze, exact_check, verify
from hyperstat.solver.analysis.stationarity import gauge_parameters
from hyperstat.solver.analysis.verify import gauge_equivalent, reassembly_residual


def _planar_screw_prediction(mech, normal):
    """Forced defects of a planar single-loop mechanism, from screw theory alone.

    All passive joints of the slider-crank are planar (revolutes along the plane
    normal, a slide in the plane), so together they generate exactly the planar
    twists (omega parallel to the normal, v perpendicular to it); three of them span
    that 3-dimensional space at a non-singular configuration.  A defect is absorbed
    iff its unit twist is planar.  With no two non-planar defect twists proportional,
    a non-gauge defect is forced iff its twist has a non-planar part.
    """
    kin = Kinematics(mech)
    st_ = kin.evaluate(mech.home[None, :])
    gauges = gauge_parameters(mech)
    out = set()
    for j, p in enumerate(mech.parameters):
        if p.name in gauges:
            continue
        col = st_.closure_xi[0, :, j]  # (omega, v at the closure frame)
        w, v = col[:3], col[3:]
        nonplanar = np.linalg.norm(np.cross(w, normal)) + abs(v @ normal)
        if nonplanar > 1e-9:
            out.add(p.name)
    return out


def test_slider_crank_has_fifteen_parameters_with_a_verdict_each(slider_crank_analysis):
    names = [p.name for p in slider_crank_analysis.parameters]
    assert len(names) == 15
    assert names[:6] == ["dI2", "dJ2", "dK2", "da2", "db2", "dc2"]
    assert {p.verdict for p in slider_crank_analysis.parameters} <= {"gauge", "forced", "coupled", "free"}


def test_slider_crank_forced_set_matches_planar_screw_theory(slider_crank, slider_crank_analysis):
    predicted = _planar_screw_prediction(slider_crank, normal=np.array([0.0, 1.0, 0.0]))
    assert set(slider_crank_analysis.by_verdict("forced")) == predicted
    assert slider_crank_analysis.by_verdict("coupled") == []
    assert slider_crank_analysis.relations == []


def test_slider_crank_gauges_follow_the_normalisation_and_along_axis_rules(slider_crank, slider_crank_analysis):
    # axes of joints 2 and 3 are z of their previous frame (Table 1: K = 1), joint 4's is x (I = 1);
    # joint 2 is followed by joint 3 which carries a full position defect, joint 3 by T_R3^RF.
    assert set(slider_crank_analysis.by_verdict("gauge")) == {"dK2", "dK3", "dI4", "dc2"}


def test_slider_crank_mobility_and_overconstraint(slider_crank_analysis):
    # planar loop R-R-R-P written with 6 spatial closure equations: rank 3, 4 joints
    assert slider_crank_analysis.mobility == 1
    assert slider_crank_analysis.overconstraint == 3
    assert slider_crank_analysis.gap > 1e8


def test_every_slider_crank_verdict_is_confirmed_by_nonlinear_reassembly(slider_crank, slider_crank_analysis):
    checks = verify(slider_crank, slider_crank_analysis)
    non_gauge = [p.name for p in slider_crank_analysis.parameters if p.verdict != "gauge"]
    assert sorted(c.subject for c in checks if c.kind == "parameter") == sorted(non_gauge)
    assert sorted(c.subject for c in checks if c.kind == "gauge") == ["dI4", "dK2", "dK3", "dc2"]
    failed = [(c.subject, c.note) for c in checks if not c.confirmed]
    assert not failed
    for c in checks:
        if c.expected == "does not assemble":
            # a forced defect leaves a residual of the size the linear model predicts (first order)
            assert c.residual == pytest.approx(c.predicted, rel=0.05)
            assert 8.0 < c.residual / c.residual_small < 12.0
        else:
            assert c.residual < 1e-6 * c.delta * 100


def test_gauge_dc2_is_the_forced_dc3_under_another_name(slider_crank, slider_crank_analysis):
    """dc2 alone does not assemble, exactly as dc3 alone: the gauge check compares with dc3, not with nothing."""
    kin = Kinematics(slider_crank)
    q0 = slider_crank_analysis.configurations[:4]
    index = slider_crank.parameter_index
    shift = 1e-3  # mm
    equivalent = gauge_equivalent(slider_crank, "dc2", shift)
    assert equivalent[index["dc2"]] == 0.0 and equivalent[index["dc3"]] == pytest.approx(shift)
    alone = np.zeros(kin.n_xi)
    alone[index["dc2"]] = shift
    r_alone, _ = reassembly_residual(kin, q0, alone)
    r_equivalent, _ = reassembly_residual(kin, q0, equivalent)
    assert r_alone > 0.5 * shift and r_alone == pytest.approx(r_equivalent, rel=1e-9)


def test_every_gauge_of_the_tripteor_is_equivalent_to_the_other_parameters(tripteor, tripteor_analysis):
    """22 gauges; most move the tool when applied alone, yet the rebuilt equivalent matches to round-off."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        checks = [c for c in verify(tripteor, tripteor_analysis) if c.kind == "gauge"]
    assert len(checks) == len(tripteor_analysis.by_verdict("gauge")) == 22
    floor = 1e-9 * Kinematics(tripteor).length_scale
    assert all(c.confirmed and c.residual < floor for c in checks), [c.note for c in checks if not c.confirmed]
    moving = [c.subject for c in checks if c.output_change > 1e3 * floor]
    assert len(moving) >= 5  # a comparison with the nominal mechanism would have failed for these
    with pytest.raises(ValueError, match="not a gauge"):
        gauge_equivalent(tripteor, "dK13", 1e-4)


def test_non_influent_verdict_is_second_order_in_the_nonlinear_model(slider_crank, slider_crank_analysis):
    checks = {c.subject: c for c in verify(slider_crank, slider_crank_analysis)}
    for p in slider_crank_analysis.parameters:
        if p.verdict == "free":
            moved = checks[p.name].output_change / (checks[p.name].delta * Kinematics(slider_crank).length_scale)
            assert (moved > 1e-2) == p.influential, p.name


def test_exact_rank_with_sympy_agrees(slider_crank, slider_crank_analysis):
    ex = exact_check(slider_crank)
    assert ex.available
    assert ex.rank == slider_crank_analysis.rank
    assert sorted(ex.forced) == sorted(slider_crank_analysis.by_verdict("forced"))


@pytest.mark.parametrize("seed,n", [(1, 12), (2, 40), (3, 24)])
def test_verdicts_are_stable_across_seeds_and_sample_sizes(slider_crank, slider_crank_analysis, seed, n):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        other = analyze(slider_crank, n_configurations=n, seed=seed)
    assert [p.verdict for p in other.parameters] == [p.verdict for p in slider_crank_analysis.parameters]
    assert [p.influential for p in other.parameters] == [p.influential for p in slider_crank_analysis.parameters]


def test_coupled_relation_appears_when_the_along_axis_gauge_cannot_apply(slider_crank):
    """Without da3/db3 the shift dc2 is no longer a gauge: dc2 + dc3 = 0 must appear."""
    import dataclasses

    from hyperstat.solver.kinematics.model import Defect

    crank = slider_crank.chains[0]
    j3 = crank.elements[2]
    j3b = dataclasses.replace(j3, defects=tuple(d for d in j3.defects if d.component in "IJKc"))
    chains = (dataclasses.replace(crank, elements=crank.elements[:2] + (j3b,) + crank.elements[3:]),) + slider_crank.chains[1:]
    mech = dataclasses.replace(slider_crank, chains=chains)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = analyze(mech)
    assert [r.terms for r in res.relations] == [{"dc2": 1.0, "dc3": 1.0}]
    assert res.verdict_of("dc2").verdict == "coupled" and res.verdict_of("dc3").verdict == "coupled"
    checks = verify(mech, res)
    kinds = {c.kind: c for c in checks if c.kind.startswith("relation")}
    assert kinds["relation satisfied"].confirmed and kinds["relation violated"].confirmed
    assert Defect  # imported for readers: the defects are plain (component, name) pairs


# ---------------------------------------------------------------------------- serial chains
def _serial(types, seed, roll=True):
    rng = np.random.default_rng(seed)
    b = MechanismBuilder("serial")
    names = []
    for i, t in enumerate(types):
        axis, point = rng.normal(size=3), 100.0 * rng.normal(size=3)
        name = str(i + 1)
        names.append(name)
        if t == "R":
            b.revolute(name, point, axis, role="actuated", range=(-np.pi, np.pi))
        else:
            b.prismatic(name, point, axis, role="actuated", range=(-50.0, 50.0))
    b.fixed("tool", 100.0 * rng.normal(size=3), rng.normal(size=3), defects="IJKabcG" if roll else "IJKabc")
    b.chain("arm", "R0", "T", names + ["tool"])
    return b.build()


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(types=st.text(alphabet="RP", min_size=1, max_size=6), seed=st.integers(0, 2**31 - 1))
def test_random_serial_chains_force_nothing_and_follow_eq_1(types, seed):
    """Paper 1, eq. (1): C = 4R + 2P + 6 independent parameters for a full-pose output."""
    mech = _serial(types, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = analyze(mech, n_configurations=30, seed=seed % 1000)
    assert res.by_verdict("forced") == [] and res.by_verdict("coupled") == []
    expected = 4 * types.count("R") + 2 * types.count("P") + 6
    assert res.influential_rank == expected
    assert res.influential_gap > 1e6


def test_without_a_roll_defect_on_the_last_frame_eq_1_loses_one():
    """The paper's six defects of a fixed transform hold one normalisation: 5 dof, not 6.

    The rotation of the tool frame about its own z axis is then missing, and no joint
    can stand in for it unless that axis is parallel to the last joint axis.
    """
    mech = _serial("RRPR", 11, roll=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = analyze(mech, n_configurations=30)
    assert res.influential_rank == 4 * 3 + 2 * 1 + 6 - 1


def test_a_gauge_without_an_equivalent_is_reported_not_confirmed(slider_crank, slider_crank_analysis, monkeypatch):
    import importlib

    verify_module = importlib.import_module("hyperstat.solver.analysis.verify")  # the package re-exports the function under that name

    def no_equivalent(mechanism, name, size):
        raise ValueError("needs component 'J', which its element does not carry.")

    monkeypatch.setattr(verify_module, "gauge_equivalent", no_equivalent)
    checks = [c for c in verify(slider_crank, slider_crank_analysis) if c.kind == "gauge"]
    assert len(checks) == 4 and not any(c.confirmed for c in checks)
    assert all("no equivalent" in c.note for c in checks)
