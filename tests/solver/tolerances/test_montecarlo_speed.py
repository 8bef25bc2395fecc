"""Monte Carlo re-assembly by a chord iteration (issue 24): the same poses as Gauss-Newton, results
independent of the threads.  Units: mm, rad."""

from __future__ import annotations

import warnings

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.tolerances.accuracy import geometric_parameters, sample_workspace
from hyperstat.solver.tolerances.montecarlo import _Chord, monte_carlo

from tests.conftest import TEMPLATES


def _triflex():
    from hyperstat.cad_plugin.templates import build_template

    return build_template(TEMPLATES / "triflex_ii.py").mechanism()


def test_chord_reassembly_gives_the_gauss_newton_poses():
    """Poses after re-assembly with random defects: chord from the nominal Jacobian vs Kinematics.assemble."""
    mech = _triflex()
    kin = Kinematics(mech)
    q = sample_workspace(mech, 300, seed=7, kinematics=kin, ranges={mech.joints[i].name: tuple(mech.ranges[i])
                                                                    for i in mech.actuated})
    names, matrix = geometric_parameters(mech)
    rng = np.random.default_rng(1)
    idx = rng.integers(0, len(q), 400)
    dg = rng.uniform(-1, 1, (400, len(names))) * np.where([n.startswith("alpha") for n in names], 5e-3, 1e-2)
    df = rng.uniform(-1, 1, (400, len(mech.actuated))) * 1e-3
    xi = dg @ matrix.T
    nominal = kin.evaluate(q, None, jacobians=True)
    ok, pose = _Chord(kin, nominal, matrix).assemble(q, idx, xi, dg, df)
    start = q[idx].copy()
    start[:, mech.actuated] += df
    res = kin.assemble(start, xi)
    ref = kin.evaluate(res.q, xi, jacobians=False).output_pose
    both = ok & res.converged
    assert both.mean() > 0.99
    # both accept a closure residual up to 1e-7 length scales (Kinematics.assemble's test), which a
    # near-singular configuration can amplify in the pose; almost everywhere they agree to 1e-9 mm or better
    diff = np.abs(pose[both] - ref[both]).reshape(both.sum(), -1).max(axis=1)
    assert diff.max() < 1e-6 and np.quantile(diff, 0.99) < 1e-9 and np.median(diff) < 1e-11
    # and the defects moved the platform (the comparison is not between two nominal poses)
    assert np.max(np.linalg.norm(ref[both, :3, 3] - nominal.output_pose[idx[both], :3, 3], axis=1)) > 1e-3


def test_monte_carlo_does_not_depend_on_the_threads():
    mech = _triflex()
    kin = Kinematics(mech)
    q = sample_workspace(mech, 100, seed=2, kinematics=kin)
    tol = {p.name: (2e-3 if p.unit == "rad" else 1e-2) for p in mech.parameters}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        one = monte_carlo(mech, q, tol, 3000, kinematics=kin, chunk=1000, workers=1)
        two = monte_carlo(mech, q, tol, 3000, kinematics=kin, chunk=1000, workers=2)
    np.testing.assert_array_equal(one.converged, two.converged)
    np.testing.assert_allclose(one.position, two.position, rtol=0, atol=1e-15)
    np.testing.assert_allclose(one.orientation_bound, two.orientation_bound, rtol=0, atol=1e-15)
