"""A FANUC-like 6R calibrated from the files a calibration engineer has (issue 21).

Units: lengths in mm, angles in rad in the code; the files use deg and m where stated.

The campaign is simulated by the generator of :mod:`tests.solver.calibration.fanuc_like`, which shares no code with hyperstat (not
with :mod:`hyperstat.solver.calibration.virtual` either): its own standard-DH forward
kinematics ``T_i = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)`` on a *true* table
(the nominal one perturbed), its own tracker frame, three targets (SMRs) on the tool,
Gaussian noise, and controller joint readings in FANUC's convention (J2 sign flipped,
``J3 = q3 - J2``'s inverse of the coupling ``q3 = J3 + J2``, J4 sign flipped, a J6 zero
offset).  hyperstat reads the DH table, the joint map and the measurement file and must
reach the noise floor on poses never fitted.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.calibration.identify import identify
from hyperstat.solver.calibration.measurements import read_measurements
from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.robot_import import import_robot
from tests.solver.calibration.fanuc_like import (DH_YAML, J6_OFFSET_DEG, NOISE_A, NOISE_B, NOMINAL, TARGETS, Campaign,
                                                  dh_matrix, noise_rms)

# ---------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    path = tmp_path_factory.mktemp("robot") / "fanuc_like.dh.yaml"
    path.write_text(DH_YAML)
    mech = import_robot(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        analysis = analyze(mech, n_configurations=24, seed=0)
    return mech, analysis


def campaign_files(tmp_path, seed: int, n_id: int, n_val: int, **kw):
    c = Campaign(seed)
    q_id, q_val = c.poses(n_id), c.poses(n_val)
    d, v = tmp_path / f"id{seed}.csv", tmp_path / f"val{seed}.csv"
    d.write_text(c.csv(q_id, "P", **kw))
    v.write_text(c.csv(q_val, "V", **{k: val for k, val in kw.items() if k != "stacked"}))
    return c, d, v


# ---------------------------------------------------------------------- tests
def test_dh_import_matches_the_generators_forward_kinematics(robot):
    """The imported model at zero defects is the nominal table's DH product (to round-off)."""
    from hyperstat.solver.kinematics.closure import Kinematics

    mech, _ = robot
    rng = np.random.default_rng(5)
    q = rng.uniform(-1.0, 1.0, (20, 6))
    pose, _ = Kinematics(mech).forward(q)
    for k in range(20):
        t = np.eye(4)
        for (a, al, d, th), qi in zip(NOMINAL, q[k]):
            t = t @ dh_matrix(math.radians(th) + qi, d, a, math.radians(al))
        assert np.abs(t - pose[k]).max() < 1e-9


@pytest.mark.parametrize("seed", [0, 1])
def test_fanuc_like_three_targets_reach_the_noise_floor(robot, tmp_path, seed):
    mech, analysis = robot
    c, d, v = campaign_files(tmp_path, seed, 50, 30)
    data = read_measurements(d, mech)
    val = read_measurements(v, mech)
    assert data.target_names == list(TARGETS) and len(data) == 150
    res = identify(mech, analysis, data, val)
    floor = noise_rms(val)
    assert res.validation["rms"] <= 1.2 * floor, (res.validation, floor)
    assert 0.8 < res.sigma < 1.2
    assert not [w for w in res.warnings if "ABSURD" in w or "WORSE" in w or "CONVERGE" in w]
    # the nominal model (tracker and targets fitted only) is far worse: calibration did something
    assert res.nominal["validation"]["rms"] > 5 * res.validation["rms"]
    # per-observation residuals: one row per (pose, target), no outlier flagged in clean data beyond chance
    assert len(res.residual_table) == 150 and {r["target"] for r in res.residual_table} == set(TARGETS)
    assert sum(r["outlier"] for r in res.residual_table) <= 3
    # one geometry, one offset per target: the distances between targets are frame-free and recovered
    est = res.estimates()
    off = {k: np.array([est[f"target_{k}_{a}"] for a in "xyz"]) for k in TARGETS}
    for a, b in (("SMR1", "SMR2"), ("SMR2", "SMR3"), ("SMR1", "SMR3")):
        true = np.linalg.norm(c.targets[a] - c.targets[b])
        assert abs(np.linalg.norm(off[a] - off[b]) - true) < 0.02, (a, b)


def test_joint_map_applied_when_reading(robot, tmp_path):
    """Controller readings (deg, FANUC convention) become the generator's model joints (rad)."""
    mech, _ = robot
    c = Campaign(3)
    q = c.poses(4)
    path = tmp_path / "m.csv"
    path.write_text(c.csv(q, "P"))
    data = read_measurements(path, mech)
    np.testing.assert_allclose(data.q[::3], q, atol=1e-12)


@pytest.mark.parametrize("seed", [7, 100])
def test_rank_and_estimates_do_not_depend_on_the_target_prior(robot, tmp_path, seed):
    """Same data with and without '# target' priors (+-8 mm off): same rank, same base set, same
    estimates within their std.  Without a prior the targets would start on the wrist axis, where
    the rotation about it is invisible: the start registers the tracker and the targets on the
    nominal model first (the prior only starts that descent), and the set is decided again at the
    solution.  Seed 100 gave rank 31 without the prior and 33 with it before the registration
    (two wrist directions, seen only at the solution, were held back by the nested chi-square
    test)."""
    mech, analysis = robot
    c = Campaign(seed)
    q = c.poses(40)
    state = c.rng.bit_generator.state
    with_prior = tmp_path / "with.csv"
    with_prior.write_text(c.csv(q, "P", priors=True))
    c.rng.bit_generator.state = state  # the same noise draws
    without = tmp_path / "without.csv"
    without.write_text(c.csv(q, "P", priors=False))
    a = identify(mech, analysis, read_measurements(with_prior, mech))
    b = identify(mech, analysis, read_measurements(without, mech))
    assert a.rank == b.rank and a.base == b.base
    assert a.base_rounds == b.base_rounds and a.held_back is None and b.held_back is None
    ea, eb = a.estimates(), b.estimates()
    std = {p["name"]: p["std"] for p in a.parameters if p["identifiable"]}
    for name in a.base:
        assert abs(ea[name] - eb[name]) <= 0.1 * std[name] + 1e-9, name
    assert abs(a.sigma - b.sigma) < 1e-6


def test_stacked_targets_and_a_missing_coupling_warn_loudly(robot, tmp_path):
    """Three SMRs stacked in one x, y, z column (rows differing only by encoder jitter), or the
    raw controller J3 read without the FANUC coupling: absurd fits, each says so."""
    mech, analysis = robot
    c = Campaign(4)
    q = c.poses(30)
    stacked = tmp_path / "stacked.csv"
    stacked.write_text(c.csv(q, "P", stacked=True))
    # with the SMRs' priors left in the header, the reader already sees the conflict: priors of targets
    # that have no columns (issue 31); without them, the fit is the witness
    with pytest.raises(DataError, match=r"prior for a target that has no columns.*not stacked in x, y, z"):
        read_measurements(stacked, mech)
    stacked.write_text(c.csv(q, "P", stacked=True, priors=False))
    res = identify(mech, analysis, read_measurements(stacked, mech))
    assert res.sigma > 3
    assert any(w.startswith("ABSURD FIT: sigma = ") for w in res.warnings), res.warnings
    # the same rows without the jitter repeat a pose: refused with a hint at the per-target columns
    text = stacked.read_text().splitlines()
    hdr = next(i for i, line in enumerate(text) if line.startswith("pose,"))
    first = text[hdr + 1].split(",")
    second = text[hdr + 2].split(",")
    second[1:7] = first[1:7]
    text[hdr + 2] = ",".join(second)
    stacked.write_text("\n".join(text) + "\n")
    with pytest.raises(DataError, match=r"repeat the same pose.*x_<target>"):
        read_measurements(stacked, mech)
    # a joint map without the coupling (raw J3 taken as the elbow angle)
    from hyperstat.solver.kinematics.joint_map import joint_map_from_dict

    raw = joint_map_from_dict({"units": {"angle": "deg"}, "joints": {
        "1": {"J1": 1}, "2": {"J2": -1}, "3": {"J3": 1}, "4": {"J4": -1}, "5": {"J5": 1},
        "6": {"J6": 1, "offset": J6_OFFSET_DEG}}}, {str(i): "R" for i in range(1, 7)})
    q = q[np.abs(q[:, 1] + q[:, 2]) < math.radians(65)]  # raw J3 = q3 + q2 must stay inside joint 3's range
    assert len(q) >= 15
    good = tmp_path / "good.csv"
    good.write_text(c.csv(q, "P"))
    from hyperstat.solver.calibration.measurements import parse_measurements

    wrong = parse_measurements(good.read_text(), mech, str(good), joint_map=raw)
    res = identify(mech, analysis, wrong)
    assert res.sigma > 3 and any("ABSURD FIT" in w and "q3 = J3 + J2" in w for w in res.warnings)


@pytest.fixture(scope="module")
def calibrated(robot, tmp_path_factory):
    mech, analysis = robot
    tmp = tmp_path_factory.mktemp("cal")
    c, d, v = campaign_files(tmp, 11, 50, 20)
    res = identify(mech, analysis, read_measurements(d, mech), read_measurements(v, mech))
    return c, res, res.model.defects(res.theta)


def test_exported_urdf_forward_kinematics_by_yourdfpy_equals_the_calibrated_model(robot, calibrated, tmp_path):
    """yourdfpy (not hyperstat) computes the exported URDF's tool pose: equal to 1e-9 mm."""
    import yourdfpy

    from hyperstat.solver.export.robot_export import urdf_text
    from hyperstat.solver.kinematics.closure import Kinematics

    mech, _ = robot
    _, res, xi = calibrated
    assert np.abs(xi).max() > 1e-4  # a calibrated geometry, not the nominal one
    path = tmp_path / "fanuc_like.urdf"
    path.write_text(urdf_text(mech, xi))
    urdf = yourdfpy.URDF.load(str(path), load_meshes=False)
    rng = np.random.default_rng(2)
    lo, hi = mech.ranges.T
    q = lo + rng.random((25, 6)) * (hi - lo)
    ours, _ = Kinematics(mech).forward(q, xi)
    names = [j.name for j in mech.joints]
    for k in range(len(q)):
        urdf.update_cfg(dict(zip(names, q[k])))
        theirs = urdf.get_transform("tool", "base_link")
        assert np.abs(theirs[:3, 3] * 1000.0 - ours[k, :3, 3]).max() < 1e-9  # mm
        assert np.abs(theirs[:3, :3] - ours[k, :3, :3]).max() < 1e-12
    # and the URDF reads back into hyperstat as the same chain
    from hyperstat.solver.kinematics.robot_import import read_urdf

    back = read_urdf(path)
    again, _ = Kinematics(back).forward(q)
    assert np.abs(again[:, :3, 3] - ours[:, :3, 3]).max() < 1e-9


def test_corrected_dh_table_follows_the_calibrated_model(robot, calibrated, tmp_path):
    """The corrected table, re-read and evaluated by the test's own DH product, matches the
    calibrated model to the deviation it states, and the mastering offsets it reports are the
    generator's."""
    from hyperstat.solver.export.robot_export import corrected_dh, dh_text
    from hyperstat.solver.kinematics.closure import Kinematics
    from hyperstat.solver.kinematics.robot_import import read_dh_table

    mech, _ = robot
    c, res, xi = calibrated
    table = corrected_dh(mech, xi)
    # what DH cannot hold (an out-of-plane tilt of the parallel J2/J3 pair, here estimated from
    # noise) stays below the noise of the campaign (about 0.05 mm RMS)
    assert table["max_deviation_mm"] < 0.03
    # mastering offsets and link lengths of joints 2-5 are the generator's (rows 1 and 6 share
    # their redundant parts with the base and tool frames; d2 and d3 only as their sum)
    for r, (a, al, d, th), (na, nal, nd, nth) in zip(table["rows"][1:5], c.table[1:5], NOMINAL[1:5]):
        assert abs(r["delta_a"] - (a - na)) < 0.02
        assert abs(r["delta_theta"] - (th - math.radians(nth))) < 2e-4
    path = tmp_path / "corrected.dh.yaml"
    path.write_text(dh_text(mech, table))
    back = read_dh_table(path)
    assert back.joint_map is not None
    rng = np.random.default_rng(9)
    lo, hi = mech.ranges.T
    q = lo + rng.random((30, 6)) * (hi - lo)
    ours, _ = Kinematics(mech).forward(q, xi)
    for k in range(len(q)):
        t = back.base.copy()
        for j, qi in zip(back.joints, q[k]):
            t = t @ dh_matrix(j.theta + qi, j.d, j.a, j.alpha)
        t = t @ back.tool
        assert np.linalg.norm(t[:3, 3] - ours[k, :3, 3]) < table["max_deviation_mm"] * 1.5 + 1e-6


@pytest.mark.parametrize("seed", [0, 1])
def test_small_data_warns_and_picks_a_smaller_parameter_set(robot, tmp_path, seed):
    """12 poses of one SMR, geometric errors (a fiftieth of the main campaign's) below the noise's
    effect (the UR10 situation of the issue; seeds 0-5 all pass, 0-1 kept for time): the full fit predicts held-out poses worse than the nominal model and says so
    loudly; the information criterion keeps fewer parameters and predicts better, as well as the nominal model within
    what the noise explains (said in a note, not a refusal)."""
    mech, analysis = robot
    c = Campaign(seed, errors=0.02, noise=(0.1, 0.0))
    d, v = tmp_path / "d.csv", tmp_path / "v.csv"
    d.write_text(c.csv(c.poses(12), "P", only=("SMR1",)))
    v.write_text(c.csv(c.poses(40), "V", only=("SMR1",)))
    data, val = read_measurements(d, mech), read_measurements(v, mech)
    full = identify(mech, analysis, data, val, select_size="none")
    assert full.validation["rms"] > full.nominal["validation"]["rms"]
    assert any(w.startswith("CALIBRATION MAKES HELD-OUT POSES WORSE") for w in full.warnings)
    small = identify(mech, analysis, data, val, select_size="auto")
    sel = small.model_selection
    assert sel is not None and sel["chosen"] < sel["sizes"][-1]
    assert len(small.base) < len(full.base)
    assert any(w.startswith("small data") for w in small.warnings)
    assert small.validation["rms"] < full.validation["rms"]
    # worse than the nominal model beyond chance (a paired test of the held-out errors): loud, and it stops an export;
    # worse by what the noise explains: a note that the calibration brings nothing measurable, no refusal
    worse = small.validation["rms"] > small.nominal["validation"]["rms"]
    loud = any("CALIBRATION MAKES HELD-OUT POSES WORSE" in w for w in small.warnings)
    quiet = [f for f in small.findings if f["code"] == "no-gain-over-nominal"]
    assert (loud or bool(quiet)) == worse and not (loud and quiet)
    assert all(not f["refuses"] for f in quiet)
    assert [f["refuses"] for f in full.findings if f["code"] == "worse-than-nominal"] == [True]


def test_six_d_measurements_enter_the_fit_with_their_own_noise(robot, tmp_path):
    """One 6-D target (position + quaternion, orientation noise 50 urad): the target rotation is
    identified (rank + 3 over positions alone), and positions and orientations both reach their
    noise floors on held-out poses."""
    mech, analysis = robot
    c = Campaign(13)
    sig = 5e-5

    def file(q, prefix):
        lines = ["# hyperstat measurements, version 1", f"# noise: {NOISE_A} mm + {NOISE_B} mm/m",
                 "# orientation noise: 0.05 mrad",
                 "pose," + ",".join(f"J{i}[deg]" for i in range(1, 7)) + ",x[mm],y[mm],z[mm],quat_w,quat_x,quat_y,quat_z"]
        for i, qi in enumerate(q):
            p, quat = c.measure_pose(qi, "SMR1", sig)
            lines.append(",".join([f"{prefix}{i + 1}"] + [repr(float(v)) for v in c.controller(qi)]
                                  + [repr(float(v)) for v in p] + [repr(float(v)) for v in quat]))
        return "\n".join(lines) + "\n"

    d, v = tmp_path / "d6.csv", tmp_path / "v6.csv"
    d.write_text(file(c.poses(40), "P"))
    v.write_text(file(c.poses(30), "V"))
    data, val = read_measurements(d, mech), read_measurements(v, mech)
    assert data.rotation is not None and data.rotation_noise == pytest.approx(5e-5)
    six = identify(mech, analysis, data, val)
    data.rotation = None
    pos = identify(mech, analysis, data, val)
    assert six.rank == pos.rank + 3
    assert six.validation["rms"] <= 1.2 * noise_rms(val)
    assert six.orientation["validation"]["rms"] <= 1.2 * six.orientation["noise_rms"]
    assert 0.8 < six.sigma < 1.2


def test_a_one_target_step_refuses_a_multi_target_file(robot, tmp_path):
    """Steps that model one target (e.g. an effect model built without targets) say so instead of
    silently mixing three SMRs into one."""
    from hyperstat.solver.calibration.identify import MeasurementModel

    mech, analysis = robot
    c = Campaign(5)
    path = tmp_path / "m.csv"
    path.write_text(c.csv(c.poses(3), "P"))
    data = read_measurements(path, mech)
    model = MeasurementModel(mech, analysis)
    with pytest.raises(DataError, match=r"models one target per pose, the file has 3 \(SMR1, SMR2, SMR3\)"):
        model.predict(model.initial(), data)
