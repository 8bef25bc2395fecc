"""The link-bending alternatives of the equivalence check against Euler-Bernoulli beam theory.

Units: lengths in mm, moments in N mm, compliances in 1/(N mm).

``BEAM_BENDING`` states the joint rotations equivalent to a bending link as fractions of the
root moment ``tau_a`` and of the end moment ``tau_b``.  Here they are recomputed by numerical
integration of the beam's curvature ``M(s) / EI`` (end slope and end deflection), for the two
moment distributions the table names, and for arbitrary root and end moments.
"""

import numpy as np
import pytest

from hyperstat.solver.diagnosis.equivalence import BEAM_BENDING


def _joint_rotations(moment, length: float, ei: float) -> tuple[float, float]:
    """Root rotation (end deflection / L) and the rest of the end slope, by the trapezoid rule."""
    s = np.linspace(0.0, length, 200_001)
    curvature = moment(s) / ei
    slope = np.trapezoid(curvature, s)
    deflection = np.trapezoid(curvature * (length - s), s)
    return deflection / length, slope - deflection / length


@pytest.mark.parametrize("tau_a, tau_b", [(1.0e5, 0.0), (1.0e5, 4.0e4), (-3.0e5, 2.5e5), (2.0e5, 2.0e5)])
def test_fractions_are_the_beam_rotations(tau_a, tau_b):
    length, ei = 700.0, 2.1e5 * 3.0e6  # mm, N mm^2 (steel tube)
    c = length / ei
    u = lambda s: s / length  # noqa: E731
    moments = {
        "linear": lambda s: tau_a * (1 - u(s)) + tau_b * u(s),  # weights beyond the end: a force and a couple
        "parabolic": lambda s: tau_b + (tau_a - tau_b) * (1 - u(s)) ** 2,  # the link's own weight and a couple
    }
    for words, ((ra, rb), (na, nb)) in BEAM_BENDING.items():
        kind = "linear" if "linear" in words else "parabolic"
        root, nxt = _joint_rotations(moments[kind], length, ei)
        assert root == pytest.approx(c * (ra * tau_a + rb * tau_b), rel=1e-8, abs=1e-15)
        assert nxt == pytest.approx(c * (na * tau_a + nb * tau_b), rel=1e-8, abs=1e-15)
