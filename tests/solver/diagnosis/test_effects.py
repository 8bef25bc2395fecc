"""Effects library: every effect's derivative against finite differences through the nonlinear model.

Units: lengths in mm, angles in rad.  The expected values are central differences of
the full prediction (assembly included); each effect's parameters are set at 70 % of
their realistic magnitude.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hyperstat.solver.diagnosis.effects import EFFECT_NAMES, applicable_effects, make_effect
from hyperstat.solver.errors import DataError
from hyperstat.solver.calibration.identify import MeasurementModel
from hyperstat.solver.calibration.virtual import VirtualMachine, workshop_metadata


@pytest.fixture(scope="module")
def tripteor_data(tripteor, tripteor_analysis):
    vm = VirtualMachine.random(tripteor, tripteor_analysis, seed=0)
    q = vm.poses(10, seed=1)
    return vm.measure(q, metadata=workshop_metadata(tripteor, 10, seed=2), noise=False)


@pytest.mark.parametrize("name", [n for n in EFFECT_NAMES if n != "link-bending"] + ["angle-harmonic-2.75"])
def test_effect_jacobian_matches_finite_differences(tripteor, tripteor_analysis, tripteor_data, name):
    from hyperstat.solver.diagnosis.validation_suite import with_declared_mass

    data = tripteor_data
    options = {"only": ["dK13"]} if name == "violated-constraint" else {}
    tripteor = with_declared_mass(tripteor)  # the gravity-driven effects need a declared mass (none is assumed)
    effect = make_effect(name, tripteor, tripteor_analysis, data, **options)
    model = MeasurementModel(tripteor, tripteor_analysis, effects=(effect,))
    theta = model.initial(data.tracker, data.target)
    theta[model.sl_geometry] = np.random.default_rng(0).uniform(-1, 1, model.sl_geometry.stop) * 1e-4
    sl = model._effect_slices[0]
    theta[sl] = 0.7 * effect.magnitude
    _check_against_central_differences(model, theta, data, sl, "position")


def _check_against_central_differences(model, theta, data, sl: slice, what: str) -> None:
    """Every effect column of ``what`` ("position" or "rotation") against central differences (relative 1e-5)."""
    from hyperstat.solver.kinematics.frames import so3_log

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = model.predict(theta, data, jacobian=True)
        analytic = ref.jacobian if what == "position" else ref.rotation_jacobian
        for j in range(sl.start, sl.stop):
            h = 1e-3 * abs(theta[j])
            plus, minus = theta.copy(), theta.copy()
            plus[j] += h
            minus[j] -= h
            p, m = model.predict(plus, data, q_start=ref.q), model.predict(minus, data, q_start=ref.q)
            if what == "position":
                fd = (p.position - m.position) / (2 * h)
            else:  # tracker-frame angular velocity: log(R(theta + h) R(theta - h)^T) / 2h
                fd = so3_log(p.rotation @ np.swapaxes(m.rotation, -1, -2)) / (2 * h)
            assert np.abs(fd).max() > 0, model.names[j]
            assert np.abs(fd - analytic[:, :, j]).max() <= 1e-5 * np.abs(fd).max(), model.names[j]


def test_violated_constraint_deformation_closes_the_loops(tripteor, tripteor_analysis):
    """The minimum-energy deformation closes every loop to first order: A (e_v + d) + B dq_p = 0."""
    from hyperstat.solver.kinematics.closure import Kinematics

    kin = Kinematics(tripteor)
    effect = make_effect("violated-constraint", tripteor, tripteor_analysis)
    model = MeasurementModel(tripteor, tripteor_analysis, kin)
    q = kin.solve(np.array([tripteor.home[tripteor.actuated]])).q
    st = kin.evaluate(q, None, jacobians=True)
    # a second method: the deformation as the minimum of the energy by a KKT system, dense
    a = kin.scaled_rows(st.closure_xi)[0]
    b = kin.scaled_rows(st.closure_q[:, :, tripteor.passive])[0]
    w = np.array([kin.length_scale**2 if p.unit == "rad" else 1.0 for p in tripteor.parameters])
    twist = effect.deformation_twists(model, q)[0]
    n_xi, n_p = a.shape[1], b.shape[1]
    kkt = np.zeros((n_xi + n_p + a.shape[0],) * 2)
    kkt[:n_xi, :n_xi] = np.diag(2 * w)
    kkt[:n_xi, n_xi + n_p:] = a.T
    kkt[n_xi:n_xi + n_p, n_xi + n_p:] = b.T
    kkt[n_xi + n_p:, :n_xi] = a
    kkt[n_xi + n_p:, n_xi:n_xi + n_p] = b
    # the KKT matrix is the same for every defect: one SVD gives its pseudo-inverse (the
    # minimum-norm least-squares solution lstsq(rcond=1e-12) returns) and its condition number
    u, sv, vt = np.linalg.svd(kkt)
    keep = sv > 1e-12 * sv[0]
    pinv = (vt[keep].T / sv[keep]) @ u[:, keep].T
    cond = sv[0] / sv[-1]
    for e, name in enumerate(effect.defects):
        ev = np.zeros(a.shape[1])
        ev[tripteor.parameter_index[name]] = 1.0
        rhs = np.r_[np.zeros(n_xi + n_p), -a @ ev]
        sol = pinv @ rhs
        d, dq = sol[:n_xi], sol[n_xi:n_xi + n_p]
        # the loops close to round-off: relative residual within eps times the KKT condition number
        tolerance = 10 * np.finfo(float).eps * cond * np.linalg.norm(a @ ev)
        assert np.linalg.norm(a @ (ev + d) + b @ dq) < tolerance
        expected = st.output_xi[0] @ (ev + d) + st.output_q[0][:, tripteor.passive] @ dq
        np.testing.assert_allclose(twist[:, e], expected, atol=1e-8 * max(1.0, np.abs(expected).max()))


def test_applicability_and_errors(scara, scara_analysis):
    from hyperstat.solver.calibration.measurements import MeasurementSet

    bare = MeasurementSet(["a", "b"], [], np.zeros((2, len(scara.actuated))), np.zeros((2, 3)))
    reasons = applicable_effects(scara, scara_analysis, bare)
    assert "violated-constraint" in reasons  # a serial SCARA has no forced defect
    assert {"thermal", "backlash", "tracker-drift"} <= set(reasons)
    with pytest.raises(DataError, match="unknown effect 'gravity'"):
        make_effect("gravity", scara)
    with pytest.raises(DataError, match="needs the column"):
        make_effect("backlash", scara).actuator_correction(None, np.zeros(len(scara.actuated)), bare)


@pytest.mark.parametrize("name", ["angle-scale", "backlash"])
def test_effect_turns_the_measured_orientation_as_its_jacobian_says(tripteor, tripteor_analysis, tripteor_data, name):
    """6-D rows: the orientation Jacobian of an effect (tracker-frame angular velocity per unit parameter) against
    central differences of the predicted orientation."""
    effect = make_effect(name, tripteor, tripteor_analysis, tripteor_data)
    model = MeasurementModel(tripteor, tripteor_analysis, effects=(effect,), orientation=True)
    theta = model.initial(tripteor_data.tracker, tripteor_data.target)
    sl = model._effect_slices[0]
    theta[sl] = 0.7 * effect.magnitude
    _check_against_central_differences(model, theta, tripteor_data, sl, "rotation")
