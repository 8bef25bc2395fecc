"""Branch-safe assembly on planar four-bar loops, checked against their closed-form branches.

Units: mm, rad.  The model files are written from the geometry (tests/solver/kinematics/fourbar.py),
the expected joint values come from the intersection of two circles on the branch of the home
configuration (``sigma``), never from hyperstat.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.continuation import ContinuationOptions
from hyperstat.solver.kinematics.modelfile import load_model
from hyperstat.solver.kinematics.sampling import assemble_nearest, continue_to, sample_configurations
from tests.solver.kinematics.fourbar import fourbar_angles, write_fourbar

ISOGRAM = (100.0, 300.0, 100.0, 300.0)  # crank, coupler, rocker, ground (mm)
CRANK_ROCKER = (40.0, 120.0, 80.0, 100.0)  # Grashof: the 40 mm crank turns fully
LOWER = (-np.pi, 0.0)  # crank range between the two flat (change) points of an isogram
# on the lower half turn, sigma = -1 is the parallelogram (B = A + (d, 0)), +1 the crossed isogram


def _model(tmp_path, dims, home, sigma, crank_range, name):
    return load_model(write_fourbar(tmp_path / f"{name}.json", *dims, home, sigma, crank_range, name=name))


def _branch_error(q, dims, sigma):
    """Largest joint difference (rad) from the closed form of branch ``sigma`` at the same crank angles."""
    ref = fourbar_angles(*dims, q[:, 0], sigma)
    return np.max(np.abs(np.angle(np.exp(1j * (q - ref)))), axis=1)


def _old_six_equal_steps(kin, qa, steps=6):
    """The assembly of hyperstat before issue 18: actuators in equal steps from home, Gauss-Newton follows."""
    act = kin.mechanism.actuated
    q = np.array(np.broadcast_to(kin.mechanism.home, (len(qa), kin.n_q)), dtype=float)
    a0 = q[:, act].copy()
    for s in range(1, steps + 1):
        q[:, act] = a0 + (qa - a0) * (s / steps)
        q = kin.assemble(q, None, max_iter=40 if s == steps else 12).q
    return q


def test_the_old_six_step_path_jumps_branch_near_the_change_point_and_the_new_one_does_not(tmp_path):
    # crossed isogram, home 0.2 rad from the flat point at 0, targets down to 0.1 rad from the flat point at -pi
    m = _model(tmp_path, ISOGRAM, -0.2, +1, LOWER, "crossed")
    kin = Kinematics(m)
    theta = np.linspace(-np.pi + 0.1, -0.1, 30)
    old = _old_six_equal_steps(kin, theta[:, None])
    # the old path closes the loop, but on the other branch (the parallelogram) for some targets
    closes = kin.residual_norm(kin.evaluate(old, jacobians=False).residual) < 1e-9
    on_other = _branch_error(old, ISOGRAM, -1) < 1e-9
    assert np.sum(closes & on_other) >= 1
    new = kin.solve(theta[:, None])
    assert new.converged.all() and new.certificate.certified.all()
    assert np.max(_branch_error(new.q, ISOGRAM, +1)) < 1e-9
    assert np.max(new.residual) < 1e-9


@pytest.mark.parametrize(
    "dims, sigma, crank_range, home",
    [
        (ISOGRAM, +1, LOWER, -0.15),  # crossed, within 0.3 rad of the flat point at 0
        (ISOGRAM, +1, LOWER, -np.pi + 0.25),  # crossed, within 0.3 rad of the flat point at -pi
        (ISOGRAM, +1, LOWER, -1.6),
        (ISOGRAM, -1, LOWER, -0.2),  # parallelogram
        (ISOGRAM, -1, LOWER, -np.pi + 0.28),
        (CRANK_ROCKER, +1, (-np.pi, np.pi), 0.5),  # both assembly modes of the crank-rocker
        (CRANK_ROCKER, -1, (-np.pi, np.pi), 0.5),
        (CRANK_ROCKER, +1, (-np.pi, np.pi), -2.8),
        (CRANK_ROCKER, -1, (-np.pi, np.pi), 3.0),
    ],
)
def test_solve_stays_on_the_branch_of_home_with_a_certificate(tmp_path, dims, sigma, crank_range, home):
    m = _model(tmp_path, dims, home, sigma, crank_range, "loop")
    kin = Kinematics(m)
    lo, hi = crank_range
    theta = np.linspace(lo + 0.1, hi - 0.1, 25)
    res = kin.solve(theta[:, None])
    cert = res.certificate
    opt = ContinuationOptions()
    assert cert.certified.all(), cert.summary()
    assert np.max(_branch_error(res.q, dims, sigma)) < 1e-9
    assert np.max(res.residual) < 1e-9 * kin.length_scale
    # what the certificate states holds for every configuration
    assert np.all(cert.min_condition >= opt.cond_tol)
    assert np.all(cert.max_branch_ratio <= opt.branch_fraction)
    assert np.all(cert.max_contraction <= opt.theta_max)
    assert "all 25 configuration(s) certified" in cert.summary()


@pytest.mark.parametrize("seed", range(5))
def test_nearest_neighbour_assembly_matches_the_closed_form(tmp_path, seed):
    m = _model(tmp_path, ISOGRAM, -np.pi + 0.2, +1, LOWER, "crossed")
    kin = Kinematics(m)
    rng = np.random.default_rng(seed)
    theta = -np.pi + 0.08 + rng.random(60) * (np.pi - 0.16)
    q, cert = assemble_nearest(kin, theta[:, None])
    assert cert.certified.all(), cert.summary()
    assert np.max(_branch_error(q, ISOGRAM, +1)) < 1e-9
    # a path from an assembled configuration gives the same configurations
    q2, c2 = continue_to(kin, q[0], theta[1:6, None])
    assert c2.certified.all() and np.max(np.abs(q2 - q[1:6])) < 1e-9


def test_a_path_through_the_change_point_is_not_certified(tmp_path):
    # parallelogram crank range across the flat point at 0: the branches cross there (B_p singular)
    m = _model(tmp_path, ISOGRAM, -0.5, -1, (-1.0, 1.0), "across")
    kin = Kinematics(m)
    q, cert = continue_to(kin, m.home, np.array([[-0.3], [0.5]]))
    assert cert.certified[0] and not cert.certified[1]
    assert cert.reason[1]
    assert np.max(_branch_error(q[:1], ISOGRAM, -1)) < 1e-9
    res = kin.solve(np.array([[0.5]]))
    assert not res.converged[0]  # a best-effort configuration is never reported converged
    assert "could not be certified" in res.certificate.summary()


def test_sampling_leaves_out_uncertifiable_draws_and_says_how_many_and_why(tmp_path):
    m = _model(tmp_path, ISOGRAM, -0.5, -1, (-1.0, 1.0), "across")
    kin = Kinematics(m)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sample = sample_configurations(kin, 12, seed=3)
    lost = sample.rejected["uncertified"]
    assert lost > 0
    notes = [str(w.message) for w in caught if "could not be certified" in str(w.message)]
    assert len(notes) == 1 and notes[0].startswith(f"{lost} drawn configuration(s)")
    assert "singularity" in notes[0] or "stalled" in notes[0]
    # every kept configuration is on the home branch (parallelogram, crank below the flat point)
    assert len(sample.q) and np.all(sample.q[:, 0] < 0)
    assert np.max(_branch_error(sample.q, ISOGRAM, -1)) < 1e-9
    assert sample.certificate.certified.all()


def test_conditioning_bounds_of_the_sampler_never_exceed_the_singular_values():
    """The Frobenius bounds of continue_nearest's certificate: sigma_n(B) >= 1 / ||B^-1||_F (square) or
    sqrt(1 / ||(B^T B)^-1||_F) (tall), sigma_1 <= ||B||_F; checked against LAPACK's SVD, down to near-singular."""
    from hyperstat.solver.kinematics.continuation import _inverse_parts

    rng = np.random.default_rng(0)
    for shape in ((200, 6, 6), (200, 12, 10)):
        u, _ = np.linalg.qr(rng.normal(size=(shape[0], shape[1], shape[1])))
        v, _ = np.linalg.qr(rng.normal(size=(shape[0], shape[2], shape[2])))
        s = 10.0 ** rng.uniform(-7, 1, size=(shape[0], shape[2]))
        b = (u[:, :, : shape[2]] * s[:, None, :]) @ np.swapaxes(v, 1, 2)
        pinv, sig, cond = _inverse_parts(b, shape[2])
        exact = np.linalg.svd(b, compute_uv=False)
        assert np.all(sig <= exact[:, -1] * (1 + 1e-6)) and np.all(cond <= exact[:, -1] / exact[:, 0] * (1 + 1e-6))
        assert np.all(sig >= exact[:, -1] / np.sqrt(shape[2]) * (1 - 1e-6))  # at most sqrt(n) below (Frobenius)
        good = exact[:, -1] > 1e-3 * exact[:, 0]  # normal equations: rounding about eps / cond^2 = 1e-10
        np.testing.assert_allclose((pinv @ b)[good], np.broadcast_to(np.eye(shape[2]), (good.sum(),) + (shape[2],) * 2),
                                   atol=1e-9)


def test_every_configuration_of_the_sampler_meets_the_rules_of_its_certificate(tmp_path):
    m = _model(tmp_path, CRANK_ROCKER, 0.5, +1, (-np.pi, np.pi), "cr")
    kin = Kinematics(m)
    theta = np.random.default_rng(1).uniform(-np.pi, np.pi, 300)
    q, cert = assemble_nearest(kin, theta[:, None])
    opt = ContinuationOptions()
    ok = cert.certified
    assert ok.all(), cert.summary()
    assert np.max(_branch_error(q, CRANK_ROCKER, +1)) < 1e-9  # the closed-form branch of home
    assert np.all(cert.max_branch_ratio <= opt.branch_fraction) and np.all(cert.max_contraction <= opt.theta_max)
    # the certificate's end conditioning is a lower bound of the exact inverse condition number
    from hyperstat.solver.kinematics.sampling import passive_conditioning

    assert np.all(cert.end_condition <= passive_conditioning(kin, q) * (1 + 1e-6))
    assert np.all(cert.end_condition >= opt.cond_tol)
