"""The stated worst cases against an independent search (issue 29, must show).

Units: mm and rad.  The values are the ones the report states (classification, then
``assign_values`` as ``hyperstat report`` calls it); the independent search has its own
kinematics, play model, programme and search (:mod:`tests.solver.tolerances.independent`): dense
grids over the actuated box (its edges, faces and interior, the whole turn of a crank), the dead
centres solved by bisection, the three best separate grid points refined by zooming grids on their
edge or face.  A stated assembly value must never exceed that minimum (the search's own round-off,
central differences of step 1e-6, is allowed at 1e-6 relative) and must find it (within 1e-3).
On the Triflex-II, which has no assembly condition, the allocation must hold: the attainable linear
worst case over the workspace and the 512 sign patterns of its nine tolerances, found by the same
kind of independent search, stays within the spec.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from hyperstat.solver.tolerances.workspace import workspace_of

from tests.solver.tolerances.common import classified
from tests.solver.tolerances.independent import OwnModel

NOISE = 1e-6  # relative round-off of the independent central differences


def _stated(name: str):
    """The tolerances with their values, as the report computes them."""
    mech, kin, result, cl = classified(name, values=True)
    own = OwnModel(mech, {j.name: cl.declaration.clearance(j.name, j.type) for j in mech.joints})
    names = [p.name for p in mech.parameters]
    directions = {t.id: {names[i]: float(t.direction[i]) for i in np.nonzero(t.direction)[0]}
                  for t in cl.items}
    return mech, cl, own, directions


def _alone(item) -> float:
    """A condition's value alone (the single-condition worst case the independent search replicates).

    The report then scales the conditions together so that the drawing as a whole assembles
    (:mod:`hyperstat.solver.tolerances.whole_drawing`): the stated value is at most this one.
    """
    alone = float(item.evidence.get("assemblability", {}).get("value_alone", item.value))
    assert item.value <= alone * (1 + 1e-12), (item.statement, item.value, alone)
    return alone


def _check(stated: float, found: float, what: str) -> None:
    assert stated <= found * (1 + NOISE), f"{what}: stated {stated:.8g} exceeds the independent minimum {found:.8g}"
    assert stated >= found * (1 - 1e-3), f"{what}: stated {stated:.8g} far below the independent minimum {found:.8g}"


def _refined(own, q, kind, t, j, directions, box, tops: int = 3, levels: int = 14) -> float:
    """The smallest violation of direction ``j``: the grid's, then zooming grids from its ``tops`` best separate points
    (on their edge, face or in the interior)."""
    lo, hi = box
    order = [int(k) for k in np.argsort(t[:, j]) if np.isfinite(t[k, j])]
    chosen: list = []
    for k in order:
        if all(np.linalg.norm((q[k] - q[c])[own.actuated]) > 1e-3 * np.linalg.norm(hi - lo) for c in chosen):
            chosen.append(k)
        if len(chosen) == tops:
            break
    best = float(t[order[0], j])
    for k in chosen:
        free = kind[k]
        best = min(best, float(own.zoom(q[k], free, lo[free], hi[free], [directions[j]], levels=levels)[0]))
    return best


def test_slider_crank_assembly_values_never_exceed_the_minimum_over_the_crank_turn_dead_centres_included():
    mech, cl, own, directions = _stated("slider_crank")
    items = cl.by_class("assembly")
    dirs = [directions[t.id] for t in items]
    # a bracketing grid over one whole turn (shifted so that no grid point sits on a dead centre)
    found = own.dead_centres(mech.home, [(mech.home[mech.actuated], 0, np.linspace(-math.pi, math.pi, 37) + 0.05)])
    centres = [s for _, s, _ in found]
    # the slider's dead centres (its velocity changes sign) are the crank along the slide: theta1 = 0 and pi
    assert any(abs(s) < 1e-9 for s in centres) and any(abs(s - math.pi) < 1e-9 for s in centres)
    centres = [(s + math.pi) % (2 * math.pi) - math.pi for s in centres]
    s_all = np.r_[np.linspace(-math.pi, math.pi, 181), centres]
    q, ok = own.track(mech.home, s_all[:, None])
    assert ok.all()
    t = own.violations(q, dirs)
    box = (np.array([-math.pi]), np.array([math.pi]))
    for j, item in enumerate(items):
        _check(_alone(item), _refined(own, q, [[0]] * len(q), t, j, dirs, box), item.statement)


def test_tripteor_assembly_values_never_exceed_the_minimum_over_edges_faces_and_dead_centres():
    mech, cl, own, directions = _stated("tripteor_x7")
    items = cl.by_class("assembly")
    dirs = [directions[t.id] for t in items]
    ws = workspace_of(mech)
    legs = [list(mech.actuated).index(mech.joint_index[n]) for n in ("41", "42", "43")]
    lo_a, hi_a = ws.actuated_box(mech)
    lo, hi = lo_a[legs], hi_a[legs]
    home_a = mech.home[mech.actuated].astype(float)

    def actuated(x):
        a = home_a.copy()
        a[legs] = x
        return a

    points, free = [], []  # 9 points on every edge, 3 x 3 inside every face, 3 x 3 x 3 inside the box
    lines = []
    for axis in range(3):
        others = [o for o in range(3) if o != axis]
        for bits in itertools.product((0, 1), repeat=2):
            base = np.zeros(3)
            base[others] = np.where(np.array(bits) == 1, hi[others], lo[others])
            for f in np.linspace(0, 1, 9):
                x = base.copy()
                x[axis] = lo[axis] + f * (hi[axis] - lo[axis])
                points.append(x)
                free.append([legs[axis]])
            lines.append((actuated(base), legs[axis], np.linspace(lo[axis], hi[axis], 9)))
        for side in (lo[axis], hi[axis]):
            for f1, f2 in itertools.product((0.25, 0.5, 0.75), repeat=2):
                x = np.zeros(3)
                x[axis] = side
                x[others] = lo[others] + np.array([f1, f2]) * (hi[others] - lo[others])
                points.append(x)
                free.append([legs[o] for o in others])
    for f in itertools.product((0.25, 0.5, 0.75), repeat=3):
        points.append(lo + np.array(f) * (hi - lo))
        free.append(legs)
    q, ok = own.track(mech.home, np.array([actuated(x) for x in points]))
    # the dead centres along every edge: sign changes of a passive joint's velocity, solved by bisection
    centres = own.dead_centres(mech.home, lines)
    assert centres  # the Tripteor's edges have dead centres (e.g. joint 53 along leg 42)
    q = np.vstack([q[ok], np.array([c for _, _, c in centres])])
    free = [f for f, g in zip(free, ok) if g] + [[lines[li][1]] for li, _, _ in centres]
    t = own.violations(q, dirs)
    box = (lo_a, hi_a)
    # every condition against the grid and the dead centres; the ones the issue names (the relation found on an
    # edge, the ridge of dK51, the interior minimum of dI63) refined by zooming grids too (all 14 were, once: see the
    # commit message)
    refine = {"dK21 - dK23 = 0", "dK51 = 0", "dI63 = 0"}
    for j, item in enumerate(items):
        found = _refined(own, q, free, t, j, dirs, box, tops=2, levels=10) if item.statement in refine else \
            float(np.nanmin(t[:, j]))
        if item.statement in refine:
            _check(_alone(item), found, item.statement)
        else:
            assert _alone(item) <= found * (1 + NOISE), (item.statement, item.value, found)


def test_triflex_allocation_holds_over_the_workspace_and_every_sign_pattern():
    """Nine tolerances at their values: the attainable linear worst case of the position error, over a 7 x 7 x 7 grid
    of the workspace (own kinematics, the passive joints following to first order) and all 512 sign patterns,
    refined by zooming grids from the three worst points, stays within the 0.01 mm spec and within the report's own
    searched value."""
    mech, cl, own, directions = _stated("triflex_ii")
    items = [t for t in cl.items if t.cls in ("accuracy-critical", "compensable")]
    assert len(items) == 9
    spec = cl.declaration.position_mm
    ws = workspace_of(mech)
    lo, hi = ws.actuated_box(mech)
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=len(items))))
    values = np.array([t.value for t in items])

    def worst(q: np.ndarray) -> np.ndarray:
        """Attainable linear worst case of the position error at configurations q (K,), mm."""
        jac = own.task_jacobian(q, [directions[t.id] for t in items])  # (K, 3, 9) mm per unit tolerance
        return np.max(np.linalg.norm(jac @ (signs * values).T, axis=1), axis=1)

    grid = np.array(list(itertools.product(*(np.linspace(l_, h_, 7) for l_, h_ in zip(lo, hi)))))
    q, ok = own.track(mech.home, grid, steps=6)
    inside = ok & ws.inside(q)
    q = q[inside]
    assert len(q) > 100
    w = worst(q)
    found = float(w.max())
    # zooming grids (3 x 3 x 3, the window halving) around the three worst grid points
    for k in np.argsort(-w)[:3]:
        centre, half, best_q = q[k, mech.actuated].copy(), 0.08 * (hi - lo), q[k]
        for _ in range(8):
            pts = np.array([np.clip(centre + np.array(o) * half, lo, hi)
                            for o in itertools.product((-1.0, 0.0, 1.0), repeat=3)])
            qq, ok = own.track(best_q, pts, steps=2)
            keep = ok & ws.inside(qq)
            if keep.any():
                ww = worst(qq[keep])
                j = int(np.argmax(ww))
                if ww[j] > found:
                    found = float(ww[j])
                centre, best_q = pts[keep][j], qq[keep][j]
            half *= 0.5
    assert found <= spec * (1 + NOISE), (found, spec)
    assert found >= 0.5 * spec  # the allocation is not empty: the worst case uses the budget
    # the report's own attainable worst case is the same number (the engine searched it; this grid checks it)
    stated = cl.allocation["uncalibrated"]["bounds"]["attainable_linear_worst_case"]
    assert found <= stated * (1 + 1e-4) and stated <= spec * (1 + NOISE), (found, stated)
