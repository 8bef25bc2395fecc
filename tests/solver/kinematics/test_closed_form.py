"""The Triflex-II's declared closed form against the certified continuation and the paper's reachable set
(units: mm, rad; the template's length unit is 1 mm)."""

from __future__ import annotations

import copy
import warnings

import numpy as np
import pytest

from hyperstat.solver.kinematics.closed_form import UNREACHABLE, assemble_closed_form, closed_form_of
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.continuation import continue_nearest
from hyperstat.solver.tolerances.accuracy import sample_workspace
from hyperstat.solver.tolerances.workspace import workspace_of

from tests.conftest import TEMPLATES


@pytest.fixture(scope="module")
def triflex():
    from hyperstat.cad_plugin.templates import build_template

    mech = build_template(TEMPLATES / "triflex_ii.py").mechanism()
    return mech, Kinematics(mech)


@pytest.fixture(scope="module")
def draws(triflex):
    mech, kin = triflex
    ws = workspace_of(mech)
    lo, hi = ws.actuated_box(mech)
    qa = lo + (hi - lo) * np.random.default_rng(5).random((2000, len(lo)))
    form = closed_form_of(mech, kin)
    assert form is not None
    q, cert, generic = assemble_closed_form(kin, form, qa, ws.inside)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        qg, cg = continue_nearest(kin, qa, None, mech.home, inside=ws.inside)  # the generic path
    return qa, q, cert, generic, qg, cg


def test_the_closed_form_gives_the_configurations_of_the_certified_continuation(triflex, draws):
    mech, kin = triflex
    qa, q, cert, generic, qg, cg = draws
    both = cert.certified & cg.certified
    assert both.sum() > 1200
    diff = q[both] - qg[both]
    rev = np.array([j.type == "R" for j in mech.joints])
    diff[:, rev] = np.mod(diff[:, rev] + np.pi, 2 * np.pi) - np.pi  # the same angle, counted from home either way
    assert np.max(np.abs(diff)) < 1e-9
    # every configuration the continuation certifies, the closed form gives too; the few it adds are draws
    # where the continuation's path gave up near the fold (elbow almost straight), all closing to round-off
    assert not np.any(cg.certified & ~cert.certified)
    extra = cert.certified & ~cg.certified
    assert extra.sum() <= 0.02 * cg.certified.sum()
    st = kin.evaluate(q[cert.certified], None, jacobians=False)
    assert np.max(kin.residual_norm(st.residual)) < 1e-9 * kin.length_scale
    assert not generic.any()  # nothing within reach failed to close on the Triflex-II


def test_a_draw_out_of_reach_is_rejected_without_a_newton_step(triflex, draws):
    """Out of reach = outside one of the paper's three cylinders (paper 2, section 5.3), computed here from the
    template's data, independently of the closed form; the continuation certifies none of them."""
    mech, _ = triflex
    qa, q, cert, generic, qg, cg = draws
    p = mech.metadata["parameters"]
    names = [mech.joints[i].name for i in mech.actuated]
    z, x, y = qa[:, names.index("1")], qa[:, names.index("5")], qa[:, names.index("10")] - p["d_s"]
    out = ((np.hypot(x - p["a_p"], y) >= p["a2"] + p["a3"])  # A3 = O_p - a_p i_b around the z axis
           | (np.hypot(y - p["d_p"] + p["a_b"], z) >= p["a6"] + p["a7"])  # A1 around the line of the x slide
           | (np.hypot(x, z) >= p["a11"] + p["a12"]))  # A2 around the y axis
    unreachable = np.array([r == UNREACHABLE for r in cert.reason])
    assert out.sum() > 300 and np.array_equal(unreachable, out)
    assert not np.any(cg.certified & out)


def test_sample_workspace_takes_the_closed_form_and_falls_back_without_it(triflex):
    mech, kin = triflex
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fast = sample_workspace(mech, 400, seed=2, kinematics=kin, closed_form=True)
        slow = sample_workspace(mech, 400, seed=2, kinematics=kin)  # small: the continuation by default
        assert np.array_equal(slow, sample_workspace(mech, 400, seed=2, kinematics=kin, closed_form=False))
    assert len(slow) <= len(fast) <= len(slow) + 8
    # a declaration that does not fit the model (a joint left out) is not used: the generic path, same answer
    broken = copy.deepcopy(mech)
    broken.metadata["closed_form"]["legs"][2]["fixed"] = ["13"]
    assert closed_form_of(broken, Kinematics(broken)) is None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        again = sample_workspace(broken, 400, seed=2, kinematics=Kinematics(broken), closed_form=True)
    assert np.array_equal(again, slow)
