"""Worst cases found, not sampled (issue 24): the Triflex-II's declared workspace, the nearest-neighbour
sampler, and the refined extremes against the closed forms of paper 2, eq. (27).

Units: lengths in mm (1 l.u. = 1 mm in the template), angles in rad.  Expected values come from the
paper's geometry (section 5.3), not from hyperstat's output: the cylinders that bound the workspace,
the elbow angles measured on the frames, sqrt(3) and a_p + a3 = 70/47 (eq. 27).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from hyperstat.solver.errors import HyperstatError
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.tolerances.accuracy import accuracy_maps, allocate, sample_workspace
from hyperstat.solver.kinematics.continuation import continue_nearest
from hyperstat.solver.tolerances.workspace import workspace_of
from hyperstat.solver.tolerances.worst_case import refine_extremes

from tests.conftest import ROOT, TEMPLATES

# Triflex-II data of paper 2, section 5.3 (l.u.)
AB, AP, DP, DS = 20 / 47, 30 / 47, 45 / 94, 40 / 47
A3 = 40 / 47
R_PRRR, R_PRRU, R_PRRS = 80 / 47, 72 / 47, 2.0


@pytest.fixture(scope="module")
def triflex():
    from hyperstat.cad_plugin.templates import build_template

    return build_template(TEMPLATES / "triflex_ii.py").mechanism()


@pytest.fixture(scope="module")
def sampled(triflex):
    kin = Kinematics(triflex)
    q = sample_workspace(triflex, 1500, seed=0, kinematics=kin)
    return kin, q, accuracy_maps(triflex, q, kinematics=kin)


def reach_margin(qa):
    """Distance inside the intersection of the three cylinders (positive inside), from d1 = z, d5 = x, d10 = y + d_s."""
    z, x, y = qa[:, 0], qa[:, 1], qa[:, 2] - DS
    return np.minimum.reduce([R_PRRR - np.hypot(x - AP, y), R_PRRU - np.hypot(y - (DP - AB), z),
                              R_PRRS - np.hypot(x, z)])


def points(mech, kin, q):
    st = kin.evaluate(q, None, jacobians=False)
    where = {mech.chains[ci].elements[ei].name: f[:, :3, 3] for (ci, ei), f in st.element_frames.items()}
    return where, st.output_pose[:, :3, 3]


def elbows(mech, kin, q):
    """theta3 (i2 to i3 about z_b) and theta7 (u6 to u7 about x_b) measured on the frames, in [0, 2 pi)."""
    w, _ = points(mech, kin, q)
    i2, i3 = w["3"] - w["2"], w["4"] - w["3"]
    u6, u7 = w["7"] - w["6"], w["8"] - w["7"]
    t3 = np.arctan2(np.cross(i2, i3)[:, 2], np.sum(i2 * i3, axis=1))
    t7 = np.arctan2(np.cross(u6, u7)[:, 0], np.sum(u6 * u7, axis=1))
    return np.mod(t3, 2 * np.pi), np.mod(t7, 2 * np.pi)


def eq27(mech, kin, q):
    """delta_gR and epsilon_gR by the closed form of paper 2, eq. (27)."""
    w, op = points(mech, kin, q)
    o1, o2, a3, o5, o6, a1 = (w[n] for n in ("2", "3", "4", "6", "7", "8"))
    unit = lambda v: v / np.linalg.norm(v, axis=1, keepdims=True)  # noqa: E731
    i2, i3, u6, u7 = unit(o2 - o1), unit(a3 - o2), unit(o6 - o5), unit(a1 - o6)
    k = np.array([0.0, 0.0, 1.0])

    def dist(p, a, u):
        return np.linalg.norm(np.cross(p - a, u), axis=1)

    delta = np.maximum(np.sqrt(1 + np.abs(np.sum(i2 * i3, axis=1))), np.sqrt(1 + (u6 @ k) ** 2 + (u7 @ k) ** 2))
    eps = np.maximum(np.hypot(dist(op, o1, i2), dist(op, o2, i3)),
                     np.sqrt(dist(op, o5, u6) ** 2 + dist(op, o6, u7) ** 2
                             + dist(op, a1, np.broadcast_to(k, a1.shape)) ** 2))
    return delta, eps


def test_declared_workspace_is_the_papers(triflex):
    """Actuated box = bounding box of the cylinders' intersection; passive ranges = elbows in [0, pi]."""
    ws = workspace_of(triflex)
    lo, hi = ws.actuated_box(triflex)
    np.testing.assert_allclose(lo, [-R_PRRU, AP - R_PRRR, max(-R_PRRR, DP - AB - R_PRRU) + DS], atol=1e-12)
    np.testing.assert_allclose(hi, [R_PRRU, R_PRRS, min(R_PRRR, DP - AB + R_PRRU) + DS], atol=1e-12)
    kin = Kinematics(triflex)
    t3, t7 = elbows(triflex, kin, triflex.home[None])
    j3, j7 = triflex.joint_index["3"], triflex.joint_index["7"]
    # joint values count from home: the range [-theta_home, pi - theta_home] is the elbow in [0, pi]
    np.testing.assert_allclose([ws.lower[j3], ws.upper[j3]], [-t3[0], np.pi - t3[0]], atol=1e-12)
    np.testing.assert_allclose([ws.lower[j7], ws.upper[j7]], [-t7[0], np.pi - t7[0]], atol=1e-12)


def test_bad_workspace_declaration_names_the_joint(triflex):
    import dataclasses

    bad = dataclasses.replace(triflex, metadata={**triflex.metadata, "workspace": {"ranges": {"99": (0, 1)}}})
    with pytest.raises(HyperstatError, match="'99', which is not a joint"):
        workspace_of(bad)
    with pytest.raises(HyperstatError, match="joint '1' must have finite lo < hi"):
        workspace_of(triflex, {"1": (1.0, -1.0)})


def test_nearest_neighbour_sampler_finds_the_reachable_set_on_the_papers_branch(triflex):
    """Every kept sample is certified, closes, lies inside the three cylinders with both elbows in [0, pi]; almost
    every reachable draw is kept (the reachable set from the cylinders, not from the solver)."""
    kin = Kinematics(triflex)
    ws = workspace_of(triflex)
    lo, hi = ws.actuated_box(triflex)
    qa = lo + (hi - lo) * np.random.default_rng(3).random((3000, 3))
    q, cert = continue_nearest(kin, qa, None, triflex.home, inside=ws.inside)
    ok = cert.certified
    assert all(r == "" for r, c in zip(cert.reason, ok) if c) and all(r for r, c in zip(cert.reason, ok) if not c)
    margin = reach_margin(qa)
    assert np.all(margin[ok] > -1e-9)  # nothing outside the reachable set
    missed = (margin > 1e-6) & ~ok
    assert missed.sum() <= 0.005 * (margin > 1e-6).sum()
    st = kin.evaluate(q[ok], None, jacobians=False)
    assert kin.residual_norm(st.residual).max() < 1e-7 * kin.length_scale  # Kinematics.assemble's test
    t3, t7 = elbows(triflex, kin, q[ok])
    assert np.all(t3 <= np.pi + 1e-9) and np.all(t7 <= np.pi + 1e-9)
    np.testing.assert_allclose(q[ok][:, triflex.actuated], qa[ok])  # actuated values held


def test_refined_maxima_reach_the_closed_forms_of_eq_27(triflex, sampled):
    """The refined maximum is at least the sampled one and within the optimiser's stated tolerance (and
    1e-6) of the closed-form maxima: delta_gR -> sqrt(3), a supremum on the boundary (PRRU leg stretched
    or folded along k_b), epsilon_gR = a_p + a3 = 70/47 attained inside with theta3 = 90 deg."""
    kin, q, maps = sampled
    ex = refine_extremes(triflex, maps, kinematics=kin, kinds=("max",), names=("delta_gR", "epsilon_gR"))
    d, e = ex[("delta_gR", "max")], ex[("epsilon_gR", "max")]
    for x, closed in ((d, math.sqrt(3)), (e, AP + A3)):
        assert x.value >= x.sampled
        assert x.value <= closed + 1e-12  # the closed form is the supremum: never exceeded
        assert closed - x.value <= max(x.tolerance, 1e-12) + 1e-9 and closed - x.value < 1e-6
        # the configuration reported closes, and eq. (27) evaluated there gives the reported value
        st = kin.evaluate(x.q[None], None, jacobians=False)
        assert kin.residual_norm(st.residual)[0] < 1e-9
    delta, _ = eq27(triflex, kin, d.q[None])
    _, eps = eq27(triflex, kin, e.q[None])
    assert abs(delta[0] - d.value) < 1e-7 and abs(eps[0] - e.value) < 1e-7
    assert d.supremum and d.singular and d.location == "boundary" and any("joint 7" in b for b in d.bounds)
    t3, t7 = elbows(triflex, kin, d.q[None])
    assert min(t7[0], np.pi - t7[0]) < 2e-4  # the PRRU leg aligned (stretched or folded)
    w, op = points(triflex, kin, d.q[None])
    u6 = (w["7"] - w["6"])[0] / np.linalg.norm((w["7"] - w["6"])[0])
    assert abs(abs(u6[2]) - 1) < 1e-6  # along k_b, orthogonal to A1 O_p (paper 2, after eq. 27)
    assert not e.supremum and e.location == "interior" and e.agreeing >= 2
    t3, _ = elbows(triflex, kin, e.q[None])
    assert abs(t3[0] - np.pi / 2) < 1e-4  # theta3 = 90 deg


def test_allocation_with_refined_maxima_is_never_looser(triflex, sampled):
    kin, q, maps = sampled
    ex = refine_extremes(triflex, maps, kinematics=kin, kinds=("max",), names=("delta_gR",))
    sampled_alloc = allocate(maps, orientation_max=0.026180)
    refined = allocate(maps, orientation_max=0.026180, maxima={"delta_gR": ex[("delta_gR", "max")].value})
    assert refined["alpha_T"] <= sampled_alloc["alpha_T"]
    assert abs(refined["alpha_T"] - 0.026180 / math.sqrt(15)) < 1e-9  # eqs. (30)-(31) with delta_gR = sqrt(3)


def test_accuracy_command_gives_the_papers_numbers_with_no_flags(tmp_path):
    """The must-show of issue 24: the default command on the Triflex-II, in a new process."""
    out = tmp_path / "acc.json"
    proc = subprocess.run([sys.executable, "-m", "hyperstat.cad_plugin.cli", "accuracy",
                           str(TEMPLATES / "triflex_ii.py"), "--orientation-accuracy", "0.026180", "--json", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(out.read_text())
    c = doc["coefficients"]
    assert abs(c["delta_gR"]["max"] - math.sqrt(3)) < 1e-4
    assert abs(c["epsilon_gR"]["max"] - 70 / 47) < 1e-4 and abs(c["epsilon_gR"]["max"] - 1.48936) < 1e-4
    assert abs(doc["allocation"]["alpha_T"] - 0.00675965) < 1e-7
    where = doc["extremes"]["delta_gR"]["max"]
    assert where["supremum_on_boundary"] and where["location"] == "boundary"
    assert doc["extremes"]["epsilon_gR"]["max"]["location"] == "interior"
    assert "supremum on the boundary" in proc.stdout and "interior at" in proc.stdout


def test_sampler_on_an_over_constrained_mechanism_lands_where_continuation_from_home_does(tripteor):
    """Tripteor X7 (more closure rows than passive joints: the least-squares path): the nearest-neighbour
    sampler gives the configurations of Kinematics.solve from home, draw for draw (a second method)."""
    kin = Kinematics(tripteor)
    q = sample_workspace(tripteor, 300, seed=0, kinematics=kin)
    lo, hi = tripteor.ranges[tripteor.actuated].T
    qa = lo + (hi - lo) * np.random.default_rng(0).random((300, len(lo)))  # the sampler's draws
    ref = kin.solve(qa, steps=6)
    assert ref.converged.all() and len(q) == 300
    np.testing.assert_allclose(q, ref.q, atol=1e-8)


def test_template_loader_passes_the_workspace_through_and_rejects_a_bad_one(tmp_path):
    """The declaration reaches the mechanism and survives a model file; a bad one is one clear sentence."""
    from hyperstat.cad_plugin.templates import build_template
    from hyperstat.solver.errors import TemplateError
    from hyperstat.solver.kinematics.modelfile import load_model, save_model

    mech = build_template(TEMPLATES / "triflex_ii.py", {"length_unit": 2.0}).mechanism()
    again = load_model(save_model(mech, tmp_path / "triflex.json"))
    ws, ws2 = workspace_of(mech), workspace_of(again)
    np.testing.assert_allclose(ws2.lower, ws.lower)
    np.testing.assert_allclose(ws.upper[mech.joint_index["1"]], 2.0 * R_PRRU)  # scales with the length unit
    source = (TEMPLATES / "slider_crank.py").read_text()
    bad = tmp_path / "bad_workspace.py"
    bad.write_text(source + "\n\ndef workspace(p):\n    return [1, 2]\n")
    with pytest.raises(TemplateError, match=r"workspace\(\) must return"):
        build_template(bad)


def test_the_pools_extent_is_numpys_ptp_of_the_scaled_columns():
    """The searches' box extent read column by column (issue 39: no (K, n_a) copy of the sample) is ``numpy.ptp`` of
    the scaled columns bit for bit: the largest and smallest of q / s are those of q divided by s > 0; NaN propagates;
    a scale that is not positive takes numpy's own path."""
    from hyperstat.solver.tolerances.worst_case import _Pool

    rng = np.random.default_rng(7)
    for trial in range(200):
        sample = rng.normal(size=(int(rng.integers(1, 60)), 5)) * 10.0 ** rng.integers(-6, 6, size=5)
        extra = rng.normal(size=(int(rng.integers(0, 4)), 5)) * 1e3
        if trial % 7 == 0:
            sample[rng.integers(len(sample)), rng.integers(5)] = np.nan
        cols = np.array([0, 2, 4])
        scale = rng.uniform(1e-3, 1e3, size=3) if trial % 11 else np.array([1.0, -2.0, 3.0])
        pool = _Pool(sample, extra, ["corner"] * len(extra))
        expected = np.ptp(pool.columns(cols, scale), axis=0)
        np.testing.assert_array_equal(pool.extent(cols, scale), expected)
        for i in (0, len(pool) - 1):
            np.testing.assert_array_equal(pool.row(i)[cols] / scale, pool.columns(cols, scale)[i])
    assert _Pool(np.zeros((0, 5)), np.zeros((0, 5)), []).extent(np.array([0, 1]), np.ones(2)).tolist() == [0.0, 0.0]


def test_the_coefficients_in_blocks_of_configurations_are_the_same_bit_for_bit(tripteor, monkeypatch):
    """The searches' coefficients are evaluated block by block of configurations (issue 39): uneven blocks give the
    values of one block of everything, to the bit, for both objectives."""
    import hyperstat.solver.tolerances.worst_case as wc
    from hyperstat.solver.kinematics.closure import Kinematics
    from hyperstat.solver.tolerances.accuracy import sample_workspace

    kin = Kinematics(tripteor)
    q = sample_workspace(tripteor, 23, seed=1, kinematics=kin)
    dirs = np.eye(kin.n_xi)[:, ::7] * kin.parameter_scale[:, None]
    objectives = (wc.Coefficients(kin), wc.TaskCoefficients(kin, ("position", "orientation"), dirs,
                                                            kin.parameter_scale[::7] > 1.0))
    monkeypatch.setattr(wc, "EVALUATION_BLOCK", 10**9)
    whole = [o.values(q) for o in objectives]
    monkeypatch.setattr(wc, "EVALUATION_BLOCK", 5)
    for o, w in zip(objectives, whole):
        blocks = o.values(q)
        assert blocks.keys() == w.keys() and len(q) > 20
        assert all(np.array_equal(blocks[n], w[n]) for n in w) and max(float(v.max()) for v in w.values()) > 0


def test_the_passive_velocities_by_lu_are_the_pseudo_inverses_to_the_round_off():
    """``_pinv_apply`` (the dead centres' passive velocities, issue 39): a square, regular matrix solved by LU gives the
    pseudo-inverse's vector to the round-off; a singular one (a passive joint's dead centre) and a non-square one
    go through ``numpy.linalg.pinv`` itself, the same bits."""
    from hyperstat.solver.tolerances.worst_case import _pinv_apply

    rng = np.random.default_rng(5)
    a = rng.normal(size=(12, 6, 6))
    a[3, :, 5] = a[3, :, 4]  # singular: rank 5
    v = rng.normal(size=(12, 6))
    ref = np.einsum("kpr,kr->kp", np.linalg.pinv(a, rcond=1e-10), v)
    out = _pinv_apply(a, v, 1e-10)
    assert np.array_equal(out[3], ref[3])
    regular = np.arange(12) != 3
    assert np.abs(out[regular] - ref[regular]).max() <= 1e-12 * np.abs(ref[regular]).max()
    tall = rng.normal(size=(4, 8, 6))
    w = rng.normal(size=(4, 8))
    assert np.array_equal(_pinv_apply(tall, w, 1e-10), np.einsum("kpr,kr->kp", np.linalg.pinv(tall, rcond=1e-10), w))


def test_candidates_searched_by_a_child_are_remembered_here_bit_for_bit(monkeypatch):
    """remember_candidates keeps what a forked child's workspace_candidates handed back (calibrated_values' dead
    centres): the next call here returns those arrays, equal to the bit to searching them here, without searching."""
    from hyperstat.cad_plugin.templates import build_template
    from hyperstat.solver import forked
    from hyperstat.solver.tolerances import worst_case

    mech = build_template(TEMPLATES / "tripteor_x7.py").mechanism()
    kin = Kinematics(mech)
    q = sample_workspace(mech, 40, seed=0, kinematics=kin)
    monkeypatch.setattr(worst_case, "_CANDIDATES", {})
    job = forked.Forked(worst_case.workspace_candidates, kin, workspace_of(mech), q)
    assert job._pid is not None
    found = job.result()
    assert not worst_case._CANDIDATES  # searched by the child only
    worst_case.remember_candidates(kin, workspace_of(mech), q, found)

    def no_search(*a, **k):
        raise AssertionError("searched again")
    monkeypatch.setattr("hyperstat.solver.kinematics.continuation.continue_nearest", no_search)
    cq, labels = worst_case.workspace_candidates(kin, workspace_of(mech), q)
    monkeypatch.undo()
    monkeypatch.setattr(worst_case, "_CANDIDATES", {})
    here_q, here_labels = worst_case.workspace_candidates(kin, workspace_of(mech), q)
    assert len(here_q) > 100 and any(lab.startswith("dead centre") for lab in here_labels)
    assert cq.tobytes() == here_q.tobytes() and cq.shape == here_q.shape and labels == here_labels
