"""The fit and its held-out predictions stay on the machine's assembly branch.

Units: mm and rad.

A trial step of a fit that flips a pose's branch does not start the next evaluation (the RSSR below), and a
held-out pose is predicted from the nominal machine's configuration (the Bricard line, last test).

The corpus' RSSR spatial four-bar has two assembly modes for a crank angle (the rocker on either side of the
rod).  Its Gauss-Newton steps move the geometry far enough along weakly determined combinations for the rocker
to assemble about 1.4 rad away at every pose; that configuration used to become the start of every later
evaluation, so the fit's cost depended on its path, the fit never came back and ``identify`` called a sound
campaign "absurd: the inputs are wrong" (sigma 311 on the campaign of ``hyperstat simulate``, 680 on this one).
The campaign here is generated in closed form, with none of hyperstat's kinematics: the rocker angle from the
crank angle by the four-bar's input-output equation ``A cos(phi) + B sin(phi) = C`` on the home branch, the
target at the rocker pin, a tracker turned and moved, Gaussian noise of the stated size.
"""

from __future__ import annotations

import math
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from hyperstat.solver.calibration.identify import BRANCH_JUMP, _Fitter, identify
from hyperstat.solver.calibration.measurements import parse_measurements

CRANK, ROCKER, DISTANCE, HEIGHT, HOME_CRANK, HOME_ROCKER = 50.0, 80.0, 150.0, 60.0, 0.5, 1.2  # the template's
NOISE_MM = 0.005
TRACKER = np.array([218.0, -131.0, -65.0, 0.0, 0.0, 0.4])  # x y z (mm), rotation vector (rad): about z


def _rocker_pin(q1: np.ndarray) -> np.ndarray:
    """The rocker pin (K, 3) at crank angles ``q1``, on the branch of the home configuration (closed form)."""
    pivot = np.array([DISTANCE, 0.0, HEIGHT])

    def pin2(phi):
        return pivot + ROCKER * np.stack([np.zeros_like(phi), np.cos(phi), np.sin(phi)], axis=-1)

    rod = np.linalg.norm(pin2(np.array(HOME_ROCKER)) - CRANK * np.array([math.cos(HOME_CRANK), math.sin(HOME_CRANK),
                                                                         0.0]))

    def branches(q):  # |pivot + r (0, cos phi, sin phi) - c (cos q, sin q, 0)|^2 = rod^2: A cos phi + B sin phi = C
        a, b = -2.0 * ROCKER * CRANK * np.sin(q), 2.0 * ROCKER * HEIGHT
        c = rod ** 2 - (DISTANCE - CRANK * np.cos(q)) ** 2 - (CRANK * np.sin(q)) ** 2 - HEIGHT ** 2 - ROCKER ** 2
        return np.arctan2(b, a), np.arccos(np.clip(c / np.hypot(a, b), -1.0, 1.0))

    base, half = branches(np.array(HOME_CRANK))
    sign = min((1.0, -1.0), key=lambda s: abs(math.remainder(base + s * half - HOME_ROCKER, 2 * math.pi)))
    assert abs(math.remainder(base + sign * half - HOME_ROCKER, 2 * math.pi)) < 1e-9  # home is on it
    base, half = branches(q1)
    return pin2(base + sign * half)


def _campaign(q1: np.ndarray, rng: np.random.Generator, names: str) -> str:
    """A measurement file: the rocker pin seen by the tracker of :data:`TRACKER`, with noise."""
    w = TRACKER[3:]
    th = np.linalg.norm(w)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / th
    rot = np.eye(3) + math.sin(th) * k + (1 - math.cos(th)) * k @ k
    seen = (_rocker_pin(q1) - TRACKER[:3]) @ rot + rng.normal(0.0, NOISE_MM, (len(q1), 3))  # R^T (p - t)
    lines = ["# hyperstat measurements, version 1", "# mechanism: rssr",
             "# units: lengths mm, angles rad (also in every column header)", f"# noise: {NOISE_MM} mm + 0 mm/m",
             "# tracker: " + " ".join(f"{v:g}" for v in TRACKER), "# target: 0 0 0",
             "pose,q1[rad],x[mm],y[mm],z[mm]"]
    lines += [f"{names}{i + 1},{a:.17g},{x:.17g},{y:.17g},{z:.17g}" for i, (a, (x, y, z)) in enumerate(zip(q1, seen))]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def rssr():
    from hyperstat.cad_plugin.templates import build_template
    from hyperstat.solver.analysis.stationarity import analyze
    from hyperstat.solver.kinematics.closure import Kinematics
    from tests.conftest import TEMPLATES

    mech = build_template(TEMPLATES / "corpus" / "rssr.py").mechanism()
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return mech, kin, analyze(mech, n_configurations=24, seed=0, kinematics=kin)


def test_an_rssr_campaign_is_fitted_on_its_branch(rssr):
    mech, kin, analysis = rssr
    rng = np.random.default_rng(3)
    lo, hi = mech.ranges[mech.actuated][0]
    data = parse_measurements(_campaign(rng.uniform(lo, hi, 80), rng, "P"), mech, "id.csv")
    val = parse_measurements(_campaign(rng.uniform(lo, hi, 24), rng, "V"), mech, "val.csv")
    fits = []
    original = _Fitter.residual

    def residual(self, theta, jacobian=True):  # the rocker angle of every evaluation of the fits
        out = original(self, theta, jacobian)
        fits.append(np.abs(out[0].q[:, mech.joint_index["2"]] - _rocker_angle(self.data.q[:, 0])).max())
        return out

    with warnings.catch_warnings(), pytest.MonkeyPatch.context() as mp:
        warnings.simplefilter("ignore")
        mp.setattr(_Fitter, "residual", residual)
        res = identify(mech, analysis, data, val, kinematics=kin)
    # the noise model holds on the fitted poses: sigma of a chi-square with 240 equations less the fitted parameters
    assert 0.8 < res.sigma < 1.2, (res.sigma, res.fit_quality, res.warnings)
    assert res.fit_quality != "inputs wrong" and res.converged, res.warnings
    # the held-out poses on the same branch: within a millimetre (the other branch is tens of millimetres away; the
    # 1-DOF campaign fits its weak combinations from the noise, so not to the noise: identify says so itself)
    assert res.validation["rms"] < 1.0, (res.validation, res.warnings)
    # the last evaluation of the fits: every pose's rocker on the closed form's branch (the fitted defects move it by
    # about 0.02 rad; the other branch is 1.4 rad or more away)
    assert fits and fits[-1] < BRANCH_JUMP, fits[-5:]


def _rocker_angle(q1: np.ndarray) -> np.ndarray:
    pin = _rocker_pin(q1) - np.array([DISTANCE, 0.0, HEIGHT])
    return np.arctan2(pin[:, 2], pin[:, 1])


def test_a_jumped_pose_keeps_its_start_and_the_others_move_on(rssr):
    mech, kin, _ = rssr
    model = SimpleNamespace(mechanism=mech, kin=kin)  # what _Fitter reads of its model here
    q0 = np.tile(np.asarray(mech.home, float), (3, 1))
    fitter = _Fitter(model, None, None, q0)
    q1 = q0.copy()
    q1[0, mech.joint_index["2"]] += 0.5 * BRANCH_JUMP  # moved on
    q1[1, mech.joint_index["2"]] += 1.4  # jumped to the other branch
    got = fitter._continued(q1)
    assert np.array_equal(got[0], q1[0]) and np.array_equal(got[1], q0[1]) and np.array_equal(got[2], q1[2])
    assert np.array_equal(fitter._continued(q0 + 1e-3), q0 + 1e-3)  # every pose moved on: the new configurations


def test_held_out_poses_of_a_bricard_line_are_predicted_on_the_nominal_branch(tmp_path):
    """The corpus' Bricard line moves only by its special geometry; an identified geometry breaks that mobility at
    second order, so its loop closes in the least-squares sense only.  Followed from home, such a geometry left the
    branch: 8 of 30 held-out poses did not assemble and the others were predicted up to 150 mm away ("absurd: the
    inputs are wrong").  Predicted from the nominal configurations, every held-out pose closes and is predicted to
    the noise.  The campaign is ``hyperstat simulate``'s (its defects satisfy the Bricard conditions, so the machine
    moves); what is checked is the prediction's branch, against the stated noise."""
    from hyperstat.cad_plugin.templates import build_template
    from hyperstat.solver.analysis.stationarity import analyze
    from hyperstat.solver.calibration.measurements import read_measurements
    from hyperstat.solver.kinematics.closure import Kinematics
    from tests.conftest import TEMPLATES, run_cli

    src = TEMPLATES / "corpus" / "bricard_line.py"
    assert run_cli(["simulate", src, "--out", tmp_path / "d.csv", "--quiet"])[0] == 0
    mech = build_template(src).mechanism()
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        analysis = analyze(mech, n_configurations=24, seed=0, kinematics=kin)
        data = read_measurements(tmp_path / "d.csv", mech)
        val = read_measurements(tmp_path / "d.validation.csv", mech)
        res = identify(mech, analysis, data, val, kinematics=kin)
    assert 0.8 < res.sigma < 1.2 and res.fit_quality != "inputs wrong", (res.sigma, res.warnings)
    assert not any("did not assemble" in w for w in res.warnings), res.warnings
    held = [v for v in res.noise_ratios["validation"].values() if v is not None]
    assert held and max(held) < 1.5, (res.validation, res.warnings)  # the held-out RMS within 1.5 x the noise


def test_models_sharing_a_kinematics_assemble_the_nominal_machine_once(slider_crank, slider_crank_analysis,
                                                                         monkeypatch):
    """The models of one mechanism that share a :class:`Kinematics` (a diagnosis' pooled fits of every candidate
    effect) assemble the nominal machine at a set of poses once (``MeasurementModel._nominal_assembly``), and each gets
    its own copy: what one caller marks (its lost poses) is not what the next one reads.  The expected assembly is
    ``Kinematics.solve`` itself, called before any model."""
    from hyperstat.solver.calibration.identify import MeasurementModel
    from hyperstat.solver.kinematics.closure import Kinematics

    mech, result = slider_crank, slider_crank_analysis
    kin = Kinematics(mech)
    qa = result.configurations[:6][:, mech.actuated]
    zero = np.zeros(len(mech.parameters))
    expected = kin.solve(qa, zero)
    calls = []
    solve = kin.solve
    monkeypatch.setattr(kin, "solve", lambda *a, **k: calls.append(1) or solve(*a, **k))
    first = MeasurementModel(mech, result, kin)._on_nominal_branch(qa, zero)
    first.q[:] = np.nan  # what predict does to a result it keeps: marks its poses
    first.converged[:] = False
    second = MeasurementModel(mech, result, kin)._on_nominal_branch(qa, zero)
    assert len(calls) == 1
    assert np.allclose(second.q, expected.q, rtol=0, atol=1e-12) and np.array_equal(second.converged, expected.converged)
    # a geometry with a free defect (its loop closes exactly) starts from the same nominal assembly: no second
    # continuation from home, and it closes
    free = next(p.name for p in result.parameters if p.verdict == "free")
    xi = zero.copy()
    xi[[p.name for p in mech.parameters].index(free)] = 1e-3
    moved = MeasurementModel(mech, result, kin)._on_nominal_branch(qa, xi)
    assert len(calls) == 1 and np.all(moved.residual < 1e-9), moved.residual
