"""'≡' only for identical shifts; a shift along a skew axis printed as the relation it is (issue 36 item 6).

Units: mm and rad.

A Bennett linkage (four revolutes on skew axes, built here from its Denavit-Hartenberg closure, solved by
this test) has shifts along a joint's own axis that are gauges: they build the same mechanism as a
combination of shifts of the next element, not one identical shift.  The statement must print that
combination with its coefficients, and the combination must build the same mechanism in the independent
model (``tests/solver/tolerances/independent.py``): every chain's end frame equal at several configurations.
"""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest
from scipy.optimize import least_squares

from hyperstat.cad_plugin.skeleton import Skeleton
from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.tolerances.classification import classify

from tests.solver.tolerances.independent import OwnModel


def _dh(theta: float, a: float, alpha: float) -> np.ndarray:
    c, s, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[c, -s * ca, s * sa, a * c], [s, c * ca, -c * sa, a * s], [0, sa, ca, 0], [0, 0, 0, 1.0]])


def _bennett(a: float = 100.0, alpha: float = math.radians(60), beta: float = math.radians(40), theta1: float = 1.0):
    """Joint frames of a Bennett linkage (a / sin alpha = b / sin beta, opposite links equal), its loop closed."""
    b = a * math.sin(beta) / math.sin(alpha)
    links = [(a, alpha), (b, beta), (a, alpha), (b, beta)]

    def gap(t):
        m = np.eye(4)
        for q, (ln, al) in zip([theta1, *t], links):
            m = m @ _dh(q, ln, al)
        return np.r_[(m[:3, :3] - np.eye(3)).ravel() * a, m[:3, 3]]

    # the closed-form branch (Bennett): tan(t1/2) tan(t2/2) = sin((b+a)/2) / sin((b-a)/2), t3 = -t1, t4 = -t2
    t2 = 2 * math.atan(math.sin((beta + alpha) / 2) / math.sin((beta - alpha) / 2) / math.tan(theta1 / 2))
    t = least_squares(gap, [t2, -theta1, -t2], xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    frames, m = [], np.eye(4)
    for q, (ln, al) in zip([theta1, *t], links):
        frames.append(m.copy())
        m = m @ _dh(q, ln, al)
    assert np.allclose(m, np.eye(4), atol=1e-9)  # the loop closes: a Bennett linkage
    return frames


@pytest.fixture(scope="module")
def bennett():
    frames = _bennett()
    sk = Skeleton("bennett_test", base="R0")
    for k, f in enumerate(frames):
        sk.revolute(str(k + 1), f[:3, 3], f[:3, 2], role="actuated" if k == 0 else "passive", x_axis=f[:3, 0],
                    defects="" if k == 0 else "IJKabc", range=(-0.5, 0.5) if k == 0 else (-math.pi, math.pi))
    sk.fixed("5", target="R3")
    sk.chain("a", "R0", "R3", ["1", "2", "3"])
    sk.chain("b", "R0", "R3", ["4", "5"])
    sk.output = "R3"
    mech = sk.mechanism()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech)
        cl = classify(mech, result)
    return mech, result, cl


def test_the_bennett_moves_once_and_is_over_constrained_three_times(bennett):
    mech, result, cl = bennett
    assert result.mobility == 1
    assert result.overconstraint == 3  # 6 closure equations, 3 passive joints, mobility 1


def test_a_shift_along_a_skew_axis_is_printed_with_its_coefficients(bennett):
    mech, result, cl = bennett
    skew = {g: r for g, r in cl.redundant.items() if len(r["coefficients"]) > 1}
    assert skew, "the Bennett has shifts along skew axes"
    for g, r in skew.items():
        item = next(t for t in cl.items if t.kind == "direction" and g in t.parameters)
        assert f"≡ {g}" not in item.statement and f"≡ -{g}" not in item.statement, item.statement
        m = re.search(rf"\({g} acts as ([^:]+):", item.statement)
        assert m, item.statement
        printed = {name: float(c.replace("*", "") or 1.0) * (-1 if sgn == "-" else 1)
                   for sgn, c, name in re.findall(r"(-|\+)?\s*([0-9.e/-]*\*?)(d[IJKabcG]\d+)", " + " + m.group(1))}
        for name, c in r["coefficients"].items():
            assert printed[name] == pytest.approx(c, rel=1e-5), (g, name, printed, r["coefficients"])


def test_the_printed_combination_builds_the_same_mechanism(bennett):
    """The gauge ``g`` and its printed combination give the independent model the same chain-end frames."""
    mech, result, cl = bennett
    own = OwnModel(mech, {j.name: {"radial_mm": 0.0, "axial_mm": 0.0, "tilt_rad": 0.0, "twist_rad": 0.0,
                                   "span_mm": float("inf"), "side": "fixed", "centre_mm": 0.0} for j in mech.joints})
    home = np.asarray(mech.home, float)
    qs = np.stack([home + d for d in (0.0, 0.3, -0.4)])
    for g, r in cl.redundant.items():
        size = 0.5  # mm: exact for a shift
        a = [{g: size}] * len(qs)
        b = [{k: size * v for k, v in r["coefficients"].items()}] * len(qs)
        ends_a, close_a = own.frames(qs, a)
        ends_b, close_b = own.frames(qs, b)
        for key in ends_a:
            assert np.allclose(ends_a[key], ends_b[key], atol=1e-8), (g, key)
        for key in close_a:
            assert np.allclose(close_a[key], close_b[key], atol=1e-8), (g, key)


def test_the_identical_sign_is_only_for_identical_shifts(bennett):
    """Every '≡' in a statement stands for one coefficient of +-1 (the slider-crank, the Tripteor)."""
    from tests.solver.tolerances.common import classified

    for name in ("slider_crank", "tripteor_x7"):
        mech, _, _, cl = classified(name)
        for t in cl.items:
            for sign, g in re.findall(r"≡ (-?)(d[IJKabcG]\d+)", t.statement):
                coeffs = cl.redundant[g]["coefficients"]
                assert len(coeffs) == 1 and abs(abs(next(iter(coeffs.values()))) - 1) < 1e-12, (name, t.statement)
                assert (next(iter(coeffs.values())) < 0) == (sign == "-"), (name, t.statement)
