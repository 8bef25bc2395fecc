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


# ---------------------------------------------------------------------------- the one-step certificate (issue 32)
def _certified_nodes(kin, theta):
    """Certified configurations at crank angles ``theta`` (the adaptive path), with B_p, its inverse and tangent."""
    from hyperstat.solver.kinematics.continuation import _correct

    q, cert = assemble_nearest(kin, theta[:, None], options=ContinuationOptions(one_step=False))
    assert cert.certified.all()
    rc = _correct(kin, q.copy(), None, len(kin.mechanism.passive), ContinuationOptions(), tol=1e-12)
    assert rc.ok.all()
    return q, rc


@pytest.mark.parametrize("dims, sigma, crank_range, home", [
    (CRANK_ROCKER, +1, (-np.pi, np.pi), 0.5),
    (CRANK_ROCKER, -1, (-np.pi, np.pi), 3.0),
    (ISOGRAM, +1, LOWER, -1.6),  # crossed: the parallelogram branch meets it at both ends of the range
])
def test_one_step_lands_on_the_closed_form_branch_with_one_jacobian_per_certificate(tmp_path, dims, sigma,
                                                                                     crank_range, home):
    from hyperstat.solver.kinematics.continuation import one_step

    m = _model(tmp_path, dims, home, sigma, crank_range, "loop")
    kin = Kinematics(m)
    lo, hi = crank_range
    rng = np.random.default_rng(4)
    q0, rc = _certified_nodes(kin, rng.uniform(lo + 0.3, hi - 0.3, 200))
    target = q0[:, :1] + rng.uniform(-0.08, 0.08, (200, 1))  # a step of up to 0.08 rad from each node
    jacobian_rows = []
    evaluate = kin.evaluate

    def counting(q, xi=None, jacobians=True):
        if jacobians:
            jacobian_rows.append(len(np.atleast_2d(q)))
        return evaluate(q, xi, jacobians)

    kin.evaluate = counting
    st = one_step(kin, q0, rc.q_b, rc.bp, rc.tangent, rc.pinv, target)
    kin.evaluate = evaluate
    assert st.ok.mean() > 0.9
    ok = st.ok
    # every certified end point is the closed-form configuration of the start's branch, closed to round-off
    assert np.max(_branch_error(st.q[ok], dims, sigma)) < 1e-9
    assert np.max(kin.residual_norm(kin.evaluate(st.q[ok], jacobians=False).residual)) < 1e-9 * kin.length_scale
    # the certificate: Kantorovich number at most 1/2, the branch rules, conditioning bounds below the exact ones
    opt = ContinuationOptions()
    assert np.all(st.kantorovich[ok] <= 0.5) and np.all(st.ratio[ok] <= opt.branch_fraction)
    from hyperstat.solver.kinematics.sampling import passive_conditioning

    assert np.all(st.cond[ok] <= passive_conditioning(kin, st.q[ok]) * (1 + 1e-6))
    # one Jacobian per certificate: rows evaluated with Jacobians beyond one per target only for the rows that
    # needed Newton (outside the Kantorovich region at the first one)
    assert jacobian_rows[0] == len(target) and sum(jacobian_rows[1:]) <= 0.1 * len(target)


def test_one_step_never_certifies_the_other_branch_across_a_change_point(tmp_path):
    from hyperstat.solver.kinematics.continuation import one_step

    # parallelogram isogram: the crossed branch meets it at the flat point 0; nodes just below it, targets beyond
    m = _model(tmp_path, ISOGRAM, -0.5, -1, (-1.0, 1.0), "across")
    kin = Kinematics(m)
    q0, rc = _certified_nodes(kin, np.linspace(-0.3, -0.02, 30))
    target = np.linspace(0.02, 0.3, 30)[:, None]
    st = one_step(kin, q0, rc.q_b, rc.bp, rc.tangent, rc.pinv, target)
    assert not st.ok.any()  # beyond the change point no configuration continues the start's branch
    assert set(st.why.tolist()) <= {2, 3, 4}  # singular, too far, or not converged: a reason each


@pytest.mark.parametrize("name, draws", [("triflex_ii", 3000), ("tripteor_x7", 300)])
def test_one_step_sampler_gives_the_configurations_of_the_continuation(name, draws):
    """The sampler with the one-step corrector against the Newton corrector of issues 18 and 24, draw for draw."""
    from hyperstat.cad_plugin.templates import TEMPLATE_DIR, build_template
    from hyperstat.solver.kinematics.continuation import continue_nearest
    from hyperstat.solver.tolerances.workspace import workspace_of

    mech = build_template(TEMPLATE_DIR / f"{name}.py").mechanism()
    kin = Kinematics(mech)
    ws = workspace_of(mech)
    lo, hi = ws.actuated_box(mech)
    qa = lo + (hi - lo) * np.random.default_rng(5).random((draws, len(lo)))
    new, cn = continue_nearest(kin, qa, None, mech.home, ContinuationOptions(one_step=True), inside=ws.inside)
    old, co = continue_nearest(kin, qa, None, mech.home, ContinuationOptions(one_step=False), inside=ws.inside)
    both = cn.certified & co.certified
    diff = new[both] - old[both]
    rev = np.array([j.type == "R" for j in mech.joints])
    diff[:, rev] = np.angle(np.exp(1j * diff[:, rev]))  # revolute joints modulo 2 pi
    assert np.max(np.abs(diff) / kin.joint_scale) < 1e-8
    # the same draws kept, up to a few at the edge of what either certificate accepts
    assert np.sum(cn.certified != co.certified) <= max(2, 0.005 * co.certified.sum())
    assert np.all(cn.max_branch_ratio[cn.certified] <= ContinuationOptions().branch_fraction)
