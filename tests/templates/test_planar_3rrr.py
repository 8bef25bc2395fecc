"""Planar 3-RRR: mobility, degree of over-constraint and its known conditions, computed here independently.

Units: mm and rad.

The expected numbers come from the mechanism's theory (the template's docstring) and from this test's own
computation with the independent model of ``tests/solver/tolerances/independent.py`` (its own element matrices,
closure residuals and central differences), never from the analysis' output: the Grübler counts give mobility
3 and over-constraint 6; the rank of the closure's joint Jacobian gives them again; the admissible
out-of-plane defect is the planar mechanism turned into a spherical one (every axis through one point); every
in-plane defect is admissible.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hyperstat.cad_plugin import build_template
from hyperstat.solver import analyze

from tests.conftest import TEMPLATES
from tests.solver.tolerances.independent import OwnModel


@pytest.fixture(scope="module")
def rrr():
    mech = build_template(TEMPLATES / "planar_3rrr.py").mechanism()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech)
    own = OwnModel(mech, {j.name: {"radial_mm": 0.0, "axial_mm": 0.0, "tilt_rad": 0.0, "twist_rad": 0.0,
                                   "span_mm": float("inf"), "side": "fixed", "centre_mm": 0.0} for j in mech.joints})
    return mech, result, own


def _jacobian(own, q: np.ndarray, defects: dict | None = None, h: float = 1e-6) -> np.ndarray:
    """Closure residual per unit of every joint, central differences of the independent model, (rows, n_q)."""
    cols = []
    for i in range(len(q)):
        a, b = q.copy(), q.copy()
        a[i] += h
        b[i] -= h
        r = own.residual(np.stack([a, b]), [defects or {}] * 2)
        cols.append((r[0] - r[1]) / (2 * h))
    return np.array(cols).T


def test_grubler_counts():
    n_bodies, joints, loops = 8, 9, 9 - 8 + 1
    assert 3 * (n_bodies - 1) - 2 * joints == 3  # planar mobility
    assert 6 * (n_bodies - 1) - 5 * joints == -3  # spatial count
    assert 3 - (6 * (n_bodies - 1) - 5 * joints) == 6 == 3 * loops  # over-constraint: 3 out-of-plane rows per loop


def test_mobility_and_overconstraint_from_the_closure_rank(rrr):
    mech, result, own = rrr
    home = np.asarray(mech.home, float)
    assert np.max(np.abs(own.residual(home[None]))) < 1e-9  # the home configuration closes
    rng = np.random.default_rng(3)
    ranks = []
    for _ in range(3):  # generic configurations: the actuators moved a little, the loops closed by the own model
        q = home.copy()
        q[own.actuated] += rng.uniform(-0.1, 0.1, len(own.actuated))
        q, res = own.assemble(q[None])
        assert res[0] < 1e-9
        ranks.append(np.linalg.matrix_rank(_jacobian(own, q[0]), tol=1e-7))
    rank = max(ranks)
    rows = 6 * len(own.closing)
    assert len(own.closing) == 2 and rows == 12
    assert len(home) - rank == 3 == result.mobility
    assert rows - rank == 6 == result.overconstraint


def test_every_in_plane_defect_is_admissible_and_no_out_of_plane_one_alone(rrr):
    """In-plane defects (shifts across the axes, ``da``, ``db``) never enter an assembly condition; each
    condition is made of out-of-plane defects (tilts ``dI``, ``dJ`` of the axes, shifts ``dc`` along them)."""
    mech, result, own = rrr
    comp = {p.name: p.component for p in mech.parameters}
    forced = [p.name for p in result.parameters if p.verdict == "forced"]
    in_relations = {n for r in result.relations for n in r.terms}
    for name in forced + sorted(in_relations):
        assert comp[name] in "IJc", name
    assert not any(comp[n] in "ab" for n in forced + sorted(in_relations))
    assert result.rank == len(forced) + len(result.relations)


def test_the_admissible_out_of_plane_defect_makes_the_axes_meet_at_one_point(rrr):
    """The one out-of-plane combination that assembles turns the planar 3-RRR into a spherical one: applied with
    a small size to the independent model, the nine axes (lines at the home configuration) pass within second
    order of one common point; it closes the loops to second order too."""
    mech, result, own = rrr
    from hyperstat.solver import Kinematics

    names = [p.name for p in mech.parameters]
    basis = result.admissible_basis * Kinematics(mech).parameter_scale[:, None]  # mm and rad
    comp = np.array([p.component in "IJ" for p in mech.parameters])
    # the admissible directions with out-of-plane tilts: one independent combination of tilts
    tilts = basis[comp]
    u, s, vt = np.linalg.svd(tilts, full_matrices=False)
    k = int(np.sum(s > 1e-8 * s[0]))
    assert k == 1
    d = basis @ vt[0]  # that admissible direction (mm, rad)
    d = d / np.max(np.abs(d[comp])) * 1e-4  # its largest tilt 1e-4 rad
    defects = {n: float(v) for n, v in zip(names, d)}
    home = np.asarray(mech.home, float)
    q, res = own.assemble(home[None], [defects])
    assert res[0] < 1e-9  # the loops close with the passive joints (an admissible defect, nonlinear)
    # the axes' lines at that configuration: each joint's frame L from the own model's chain walk
    frames = _joint_lines(own, q[0], defects)
    pts = np.array([p for p, _ in frames])
    dirs = np.array([n for _, n in frames])
    # the point closest to every line (least squares) and the distances of the lines to it
    a = sum(np.eye(3) - np.outer(n, n) for n in dirs)
    b = sum((np.eye(3) - np.outer(n, n)) @ p for p, n in zip(pts, dirs))
    centre = np.linalg.solve(a, b)
    dist = [np.linalg.norm((np.eye(3) - np.outer(n, n)) @ (centre - p)) for p, n in zip(pts, dirs)]
    tilt = max(np.linalg.norm(np.cross(n, dirs[0])) for n in dirs)
    assert tilt > 1e-6  # the axes do turn
    assert max(dist) < 1e-3 * np.linalg.norm(centre)  # and meet at one far point (a sphere's centre)


def _joint_lines(own, q: np.ndarray, defects: dict) -> list:
    """(point, direction) of every joint axis, base frame, from the independent model's own chain walk."""
    from tests.solver.tolerances.independent import _element, _rot_z

    m = own.m
    out = []
    ends = {m.base: np.eye(4)}
    for ci in own.order + own.closing:
        ch = m.chains[ci]
        t = ends[ch.start].copy()
        for el in ch.elements:
            if el.kind == "frame":
                from tests.solver.tolerances.independent import _placement

                t = t @ _placement(el.placement)
                continue
            vals = np.zeros((1, 7))
            for dfc in getattr(el, "defects", ()):
                vals[0, "IJKabcG".index(dfc.component)] = defects.get(dfc.name, 0.0)
            t = t @ _element(el.placement, vals)[0]
            if el.kind == "joint":
                out.append((t[:3, 3].copy(), t[:3, 2].copy()))
                t = t @ _rot_z(np.array(q[own.index[el.name]]))
        if ci not in own.closing:
            ends[ch.end] = t
    return out
