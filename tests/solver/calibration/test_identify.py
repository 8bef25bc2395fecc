"""Identification on simulated data: recovery of the truth within the reported uncertainty.

Units: lengths in mm, angles in rad.  The expected values are the virtual machine's
true parameters; the base parameters that absorb an unidentifiable one are expected
at ``true_base + coefficient * (true_other - prior_other)`` (the combination the
identification reports).  Each estimate must lie within 4.5 of its reported standard
deviations of that value, and the mean squared z-score must be near one (the
reported uncertainties are neither inflated nor too small).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.stats import chi2

from hyperstat.solver.calibration.identify import MeasurementModel, identify
from hyperstat.solver.calibration.measurements import MeasurementSet
from hyperstat.solver.calibration.virtual import VirtualMachine


def simulate(mech, analysis, seed: int, n_id: int, n_val: int):
    vm = VirtualMachine.random(mech, analysis, seed=seed)
    q = vm.poses(n_id + n_val, seed=seed + 10)
    return vm, vm.measure(q[:n_id], seed=seed + 20), vm.measure(q[n_id:], seed=seed + 30, prefix="V")


def expected_estimates(result, truth: dict) -> dict:
    """True value of every base parameter, plus what it absorbs of the unidentifiable ones."""
    estimates = result.estimates()
    expected = {name: truth.get(name, 0.0) for name in result.base}
    for u in result.unidentifiable:
        for name, coefficient in u["combination"].items():
            expected[name] += coefficient * (truth.get(u["name"], 0.0) - estimates[u["name"]])
    return expected


def z_scores(result, truth: dict, kinds: tuple) -> tuple[np.ndarray, np.ndarray]:
    """(estimate - expected) / std for the base parameters of the given kinds, and their correlation matrix."""
    expected = expected_estimates(result, truth)
    kind = {p["name"]: p["kind"] for p in result.parameters}
    rows = [i for i, name in enumerate(result.base) if kind[name] in kinds]
    cov = result.covariance[np.ix_(rows, rows)]
    std = np.sqrt(np.diag(cov))
    est = result.estimates()
    z = np.array([(est[result.base[i]] - expected[result.base[i]]) for i in rows]) / std
    return z, cov / np.outer(std, std)


def run(mech, analysis, seed, n_id, n_val):
    vm, data, val = simulate(mech, analysis, seed, n_id, n_val)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return vm, identify(mech, analysis, data, val)


def assert_recovered(zc: tuple) -> None:
    z, corr = zc
    assert np.abs(z).max() < 4.5, f"largest |z| {np.abs(z).max():.2f}"
    # sum of z^2 of correlated unit normals = sum(lambda_i chi2_1), lambda the eigenvalues of the
    # correlation matrix; Satterthwaite's scaled chi-square g * chi2(h) matches its mean and variance
    lam = np.linalg.eigvalsh(corr)
    g, h = np.sum(lam**2) / np.sum(lam), np.sum(lam) ** 2 / np.sum(lam**2)
    total = float(np.sum(z**2))
    assert g * chi2.ppf(0.0005, h) < total < g * chi2.ppf(0.9995, h), f"sum z^2 {total:.2f}, g {g:.2f}, h {h:.1f}"


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tripteor_recovers_truth_in_the_papers_setting(tripteor, tripteor_analysis, seed):
    vm, res = run(tripteor, tripteor_analysis, seed, 107, 30)
    assert_recovered(z_scores(res, vm.truth(), ("geometry", "tracker", "target")))
    assert res.validation["rms"] <= 1.2 * res.noise_rms
    assert res.validation["n"] == 30 and res.identification["n"] == 107
    assert 0.8 < res.sigma < 1.2  # the weighted residuals match the noise model


@pytest.mark.parametrize("seed", [0, 1])
def test_scara_rank_is_eq1_count_minus_what_positions_cannot_see(scara, scara_analysis, seed):
    vm, res = run(scara, scara_analysis, seed, 60, 30)
    n_r = sum(j.type == "R" for j in scara.joints)
    n_p = sum(j.type == "P" for j in scara.joints)
    independent = 4 * n_r + 2 * n_p + 6  # eq. (1): base and tool frames included
    # the base frame duplicates the tracker frame (counted once already in eq. 1); a position-only
    # measurement of a point cannot see the three orientation parameters of the tool frame
    assert res.rank == independent - 3
    assert_recovered(z_scores(res, vm.truth(), ("geometry", "tracker", "target")))
    assert res.validation["rms"] <= 1.2 * res.noise_rms


@pytest.mark.parametrize("seed", [0, 1])
def test_slider_crank_identification(slider_crank, slider_crank_analysis, seed):
    vm, res = run(slider_crank, slider_crank_analysis, seed, 40, 20)
    model = res.model
    n_geometry = sum(k == "geometry" for k in model.kinds)
    # the target moves on a straight line without rotating: the tracker's rotation about that line
    # is invisible (1) and the target offset is a tracker translation (3)
    assert res.rank == n_geometry + 6 + 3 - 1 - 3
    # the tracker's orientation about the line is arbitrary: compare the machine's defects only
    zc = z_scores(res, vm.truth(), ("geometry",))
    assert len(zc[0]) == n_geometry
    assert_recovered(zc)
    assert res.validation["rms"] <= 1.2 * res.noise_rms


def test_jacobian_matches_finite_differences(tripteor, tripteor_analysis):
    vm, data, _ = simulate(tripteor, tripteor_analysis, 3, 12, 0)
    model = MeasurementModel(tripteor, tripteor_analysis)
    theta = model.initial(data.tracker, data.target)
    theta[model.sl_geometry] = np.random.default_rng(0).uniform(-1, 1, model.sl_geometry.stop) * 1e-4
    ref = model.predict(theta, data, jacobian=True)
    for j in range(model.n):
        h = 1e-6 if model.units[j] == "rad" else 1e-4
        plus, minus = theta.copy(), theta.copy()
        plus[j] += h
        minus[j] -= h
        fd = (model.predict(plus, data, q_start=ref.q).position - model.predict(minus, data, q_start=ref.q).position) / (2 * h)
        scale = max(np.abs(fd).max(), 1e-9)
        floor = 1e-7 * (model.kin.length_scale if model.units[j] == "rad" else 1.0)  # assembly round-off / h
        assert np.abs(fd - ref.jacobian[:, :, j]).max() <= 1e-5 * scale + floor, model.names[j]


def test_noise_free_estimate_is_the_truth(tripteor, tripteor_analysis):
    """Without noise the identification lands on the truth, through the reported combinations."""
    vm, data, _ = simulate(tripteor, tripteor_analysis, 5, 60, 0)
    clean = vm.measure(data.q, noise=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        noisy = identify(tripteor, tripteor_analysis, data)
        res = identify(tripteor, tripteor_analysis, clean, base=noisy.base)
    assert res.identification["max"] < 1e-5  # mm: noise-free data are reproduced
    expected = expected_estimates(res, vm.truth())
    est = res.estimates()
    std = {p["name"]: p["std"] for p in noisy.parameters}
    for name in res.base:  # the linearised combinations hold to a small fraction of the noise-level std
        assert abs(est[name] - expected[name]) <= 0.05 * std[name], name


def test_too_few_poses_is_a_clear_error(tripteor, tripteor_analysis):
    from hyperstat.solver.errors import DataError

    vm, data, _ = simulate(tripteor, tripteor_analysis, 0, 8, 0)
    with pytest.raises(DataError, match=r"8 poses \(24 equations\), too few .* give at least \d+ poses"):
        identify(tripteor, tripteor_analysis, data)


def test_unweighted_data_still_identify(slider_crank, slider_crank_analysis):
    vm, data, _ = simulate(slider_crank, slider_crank_analysis, 0, 30, 0)
    plain = MeasurementSet(data.pose, data.joints, data.q, data.position)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify(slider_crank, slider_crank_analysis, plain)
    assert res.noise_rms is None
    assert res.identification["rms"] < 3 * vm.noise.sigma(np.array([0.0]))[0] * np.sqrt(3) + 0.01
