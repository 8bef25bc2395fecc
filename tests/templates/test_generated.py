"""Generated families of the corpus: random planar four-bars and random 3-RRR proportions (hypothesis).

Units: lengths in mm, angles in rad.

The theory of every drawn member is computed here, independently of the solver: the mobility from the
planar Chebychev-Grubler-Kutzbach count (3 (bodies - 1) - 2 joints, the dimension of a planar motion
space), the degree of over-constraint as that mobility less the spatial count (6 (bodies - 1) -
5 joints), and both again, with the assembly conditions, from the screw computation of
:mod:`tests.templates.screw_theory`.  ``hyperstat analyze`` (in this process) must agree with both.
The 3-RRR members are the guide's own example (docs/authoring.md) built with drawn proportions.
"""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from hyperstat.cad_plugin.skeleton import Skeleton
from hyperstat.cad_plugin.templates import build_template
from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.errors import HyperstatError
from hyperstat.solver.tolerances.classification import classify

from tests.conftest import ROOT
from tests.templates.screw_theory import screw_model

CHEAP = settings(max_examples=3, deadline=None, derandomize=True,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


def planar_counts(bodies: int, joints: int) -> tuple[int, int]:
    """(mobility, degree of over-constraint) of a planar linkage of one-freedom joints, from Kutzbach's counts."""
    mobility = 3 * (bodies - 1) - 2 * joints
    return mobility, mobility - (6 * (bodies - 1) - 5 * joints)


def four_bar(ground: float, crank: float, coupler: float, rocker: float, angle: float) -> Skeleton:
    """A planar four-bar O-A-B-Q drawn at crank angle ``angle`` (elbow up), as a template would."""
    o, q = np.zeros(3), np.array([ground, 0.0, 0.0])
    for t in (angle - 0.3, angle, angle + 0.3):  # assembled, away from a dead centre, over the whole range
        d = float(np.linalg.norm(q - crank * np.array([math.cos(t), math.sin(t), 0.0])))
        if not abs(coupler - rocker) + 5.0 < d < coupler + rocker - 5.0:
            raise HyperstatError("no assembly over the crank's range")
    a = crank * np.array([math.cos(angle), math.sin(angle), 0.0])
    d = float(np.linalg.norm(q - a))
    along = (coupler**2 - rocker**2 + d**2) / (2 * d)
    up = math.sqrt(coupler**2 - along**2)
    u = (q - a) / d
    b = a + along * u + up * np.array([-u[1], u[0], 0.0])
    z = (0.0, 0.0, 1.0)
    sk = Skeleton("four_bar", marker_size=5.0)
    sk.revolute("1", o, z, role="actuated", x_axis=(1, 0, 0), defects="", home=angle,
                range=(angle - 0.3, angle + 0.3))
    sk.revolute("2", a, z)
    sk.revolute("4", q, z)
    sk.revolute("3", b, z)
    sk.fixed("5", target="R2")
    sk.chain("crank", "R0", "R2", ["1", "2"])
    sk.chain("rocker", "R0", "R2", ["4", "3", "5"])
    return sk


def _analysed(skeleton) -> tuple[int, int, int]:
    mech = skeleton.mechanism()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, n_configurations=16, seed=0)
    return result.mobility, result.overconstraint, classify(mech, result).counts()["assembly"]


def _screw(skeleton) -> tuple[int, int, int]:
    t = screw_model(skeleton).theory(configurations=10)
    assert t["condition_gap"] > 1e4, t
    return t["mobility"], t["overconstraint"], t["conditions"] + t["overconstraint"]


@CHEAP
@given(ground=st.floats(80.0, 160.0), crank=st.floats(20.0, 60.0), coupler=st.floats(90.0, 180.0),
       rocker=st.floats(60.0, 140.0), angle=st.floats(0.3, 2.8))
def test_random_planar_four_bars(ground, crank, coupler, rocker, angle):
    try:
        sk = four_bar(ground, crank, coupler, rocker, angle)
    except HyperstatError:
        assume(False)
    mobility, overconstraint = planar_counts(bodies=4, joints=4)
    screw = _screw(sk)
    assert screw[:2] == (mobility, overconstraint) == (1, 3)
    assert _analysed(sk) == screw


@pytest.fixture(scope="module")
def guide_3rrr(tmp_path_factory):
    """The guide's planar 3-RRR, written to a file as a reader would."""
    guide = (ROOT / "docs" / "authoring.md").read_text(encoding="utf-8")
    body = re.search(r"```python file=planar_3rrr\.py\n(.*?)```", guide, flags=re.S).group(1)
    path = tmp_path_factory.mktemp("guide") / "planar_3rrr.py"
    path.write_text(body, encoding="utf-8")
    return path


@CHEAP
@given(base=st.floats(150.0, 260.0), platform=st.floats(30.0, 80.0), proximal=st.floats(90.0, 170.0),
       distal=st.floats(90.0, 170.0))
def test_random_3rrr_proportions(guide_3rrr, base, platform, proximal, distal):
    try:
        sk = build_template(guide_3rrr, {"base_radius": base, "platform_radius": platform, "proximal": proximal,
                                         "distal": distal})
    except HyperstatError:
        assume(False)
    mobility, overconstraint = planar_counts(bodies=8, joints=9)
    screw = _screw(sk)
    assert screw[:2] == (mobility, overconstraint) == (3, 6)
    assert _analysed(sk) == screw
