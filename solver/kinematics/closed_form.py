"""Closed-form assembly of a parallel mechanism whose template declares its legs' inverse kinematics.

Units: lengths in mm, angles in rad.

Workspace sampling (:func:`hyperstat.solver.tolerances.accuracy.sample_workspace`) draws actuated
values and assembles each draw by certified continuation (a Newton corrector from the nearest
certified configuration).  For a mechanism whose platform pose follows from the actuated values
in closed form and whose legs are solved from the platform pose in closed form, that is work
done twice, and a third of the Triflex-II's box lies outside the reachable set, where the
corrector walks to the fold before it gives up.  A template declares such a structure in its
mechanism's metadata (``metadata["closed_form"]``, JSON, so that it travels in the model file);
this module evaluates it over all draws at once:

* the **platform**: a translational platform whose displacement from home is linear in the
  actuated values, ``p - p_home = M (q_a - q_a,home)`` (the Triflex-II: each slide moves the
  platform point along its own axis, paper 2, section 5);
* **planar two-link legs** (``"planar-2r"``): the leg's first joint moves with its slide, its two
  revolutes (lengths ``l1``, ``l2`` from the model's home frames) turn about the plane's normal
  ``n``, the elbow keeps the side it has at home (the assembly branch of home), and the joints
  after the elbow that turn about ``n`` (``follow``) undo the arm's rotation, so that the platform
  keeps its orientation; ``fixed`` joints stay at home.  A draw whose leg tip is out of the arm's
  reach (``r > l1 + l2`` or ``r < |l1 - l2|``) is **unreachable**: rejected before any Newton step.

Every joint angle is measured about the declared normal with the sign of the joint's own axis
at home, and counted from home (in ``(-pi, pi]``).  Nothing is trusted blindly: the caller
(:func:`assemble_closed_form`) evaluates the loop closures at every configuration the formulas
give and keeps only those that close to round-off, with a well-conditioned passive Jacobian;
the others go to the generic corrector.  ``tests/solver/kinematics/test_closed_form.py`` checks
the closed form against the certified continuation (same configurations, same branch).

Examples
--------
The declaration of the Triflex-II (``templates/triflex_ii.py``)::

    {"platform": {"actuated": {"1": [0, 0, 1], "5": [1, 0, 0], "10": [0, 1, 0]}},
     "legs": [{"type": "planar-2r", "normal": [0, 0, 1], "slide": "1", "joints": ["2", "3"],
               "tip": "4", "follow": ["4"]}, ...]}
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.kinematics.model import Mechanism

__all__ = ["ClosedForm", "closed_form_of", "assemble_closed_form", "UNREACHABLE"]


def _angle(v: np.ndarray, n: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Angle (rad, in (-pi, pi]) about unit ``n`` from ``ref`` (3,) to each ``v`` (K, 3), both in the plane of ``n``."""
    cross = np.cross(ref, v)
    return np.arctan2(cross @ n, v @ ref)


def _wrap(a: np.ndarray) -> np.ndarray:
    return np.mod(a + np.pi, 2 * np.pi) - np.pi


class ClosedForm:
    """The declared closed form of a mechanism, set up at its home configuration.

    Parameters
    ----------
    mechanism : Mechanism
        With ``metadata["closed_form"]`` (see the module docstring).
    frames : dict
        ``(chain, element)`` -> (4, 4) absolute frame of every element at home (the model's
        ``element_frames`` at home).

    Raises
    ------
    ValueError
        When the declaration does not fit the mechanism (unknown joint, a joint declared twice,
        a joint of the mechanism left out): the caller then uses the generic corrector.
    """

    def __init__(self, mechanism: Mechanism, frames: dict) -> None:
        m = mechanism
        spec = m.metadata["closed_form"]
        index = m.joint_index
        at = {}  # joint name -> (origin, z axis) at home
        for (ci, ei), f in frames.items():
            el = m.chains[ci].elements[ei]
            if el.name in index:
                at[el.name] = (np.asarray(f)[:3, 3].copy(), np.asarray(f)[:3, 2].copy())
        self.n_q = len(m.joints)
        self.home = np.asarray(m.home, dtype=float)
        act_names = [m.joints[i].name for i in m.actuated]
        plat = spec["platform"]["actuated"]
        if sorted(plat) != sorted(act_names):
            raise ValueError("the platform's map must name every actuated joint")
        self.act = np.asarray(m.actuated)
        self.map = np.array([plat[name] for name in act_names], dtype=float).T  # (3, n_a)
        covered = set(act_names)
        self.legs = []
        for leg in spec["legs"]:
            if leg.get("type") != "planar-2r":
                raise ValueError(f"unknown leg type {leg.get('type')!r}")
            n = np.asarray(leg["normal"], dtype=float)
            n = n / np.linalg.norm(n)
            first, second = leg["joints"]
            names = [first, second] + list(leg.get("follow", [])) + list(leg.get("fixed", []))
            if any(j not in index for j in names + [leg["tip"], leg["slide"]]) or covered & set(names):
                raise ValueError("a leg names an unknown joint or one already solved")
            covered |= set(names)
            s0, e0, t0 = at[first][0], at[second][0], at[leg["tip"]][0]
            l1, l2 = float(np.linalg.norm(e0 - s0)), float(np.linalg.norm(t0 - e0))
            u0 = (e0 - s0) / l1
            w0 = (t0 - e0) / l2
            side = float(np.sign(np.cross(u0, w0) @ n)) or 1.0  # the elbow's side at home (its branch)
            slide = index[leg["slide"]]
            self.legs.append({
                "n": n, "s0": s0, "t0": t0, "l1": l1, "l2": l2, "u0": u0, "w0": w0, "side": side,
                "slide": slide, "slide_axis": at[leg["slide"]][1], "slide_home": float(self.home[slide]),
                "first": (index[first], float(np.sign(at[first][1] @ n))),
                "second": (index[second], float(np.sign(at[second][1] @ n))),
                "follow": [(index[j], float(np.sign(at[j][1] @ n))) for j in leg.get("follow", [])],
                "fixed": [index[j] for j in leg.get("fixed", [])]})
        if covered != {j.name for j in m.joints}:
            raise ValueError("the legs leave joints of the mechanism out")

    def assemble(self, qa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Configurations at actuated values ``qa`` (K, n_a), and which draws are within every leg's reach.

        Returns
        -------
        q : ndarray, (K, n_q)
            Joint values (rad / mm); rows out of reach hold the home values of the passive joints.
        reachable : ndarray of bool, (K,)
        """
        qa = np.atleast_2d(np.asarray(qa, dtype=float))
        k = len(qa)
        q = np.tile(self.home, (k, 1))
        q[:, self.act] = qa
        move = (qa - self.home[self.act]) @ self.map.T  # platform displacement (K, 3)
        reachable = np.ones(k, dtype=bool)
        for leg in self.legs:
            n = leg["n"]
            start = leg["s0"] + np.outer(q[:, leg["slide"]] - leg["slide_home"], leg["slide_axis"])
            d = leg["t0"] + move - start
            d = d - np.outer(d @ n, n)  # in the arm's plane (the slide keeps the tip in it)
            r = np.linalg.norm(d, axis=1)
            l1, l2 = leg["l1"], leg["l2"]
            ok = (r > abs(l1 - l2)) & (r < l1 + l2)
            reachable &= ok
            rs = np.where(ok, r, 0.5 * (abs(l1 - l2) + l1 + l2))
            a = (l1**2 - l2**2 + rs**2) / (2 * rs)
            h = np.sqrt(np.maximum(l1**2 - a**2, 0.0))
            u = d / rs[:, None]
            perp = np.cross(n, u)
            elbow = a[:, None] * u - leg["side"] * h[:, None] * perp  # E - S
            upper = elbow / l1
            lower = (d - elbow) / l2
            turn1 = _angle(upper, n, leg["u0"])  # the first link's rotation about n from home
            turn2 = _angle(lower, n, leg["w0"])  # the second link's
            j1, s1 = leg["first"]
            j2, s2 = leg["second"]
            q[:, j1] = self.home[j1] + s1 * turn1
            q[:, j2] = self.home[j2] + s2 * _wrap(turn2 - turn1)
            for j, sj in leg["follow"]:
                q[:, j] = self.home[j] - sj * turn2
            for j in leg["fixed"]:
                q[:, j] = self.home[j]
        return q, reachable


def closed_form_of(mechanism: Mechanism, kin) -> ClosedForm | None:
    """The mechanism's declared closed form, or None (none declared, or a declaration that does not fit)."""
    if not isinstance(mechanism.metadata.get("closed_form"), dict):
        return None
    try:
        frames = kin.evaluate(mechanism.home[None, :], jacobians=False).element_frames
        return ClosedForm(mechanism, {key: f[0] for key, f in frames.items()})
    except (KeyError, ValueError, TypeError, IndexError, ZeroDivisionError):
        return None


#: configurations checked per block (the closure Jacobian of 8,192 Triflex-II configurations: 12 MB)
BLOCK = 8192
#: the largest dimensionless closure residual of a configuration the closed form gives (round-off: about 1e-15)
CLOSES = 1e-11
UNREACHABLE = "outside the reachable set (the legs' closed form: a leg cannot reach the platform)"
OUTSIDE = "outside the workspace's declared ranges"


def assemble_closed_form(kin, form: ClosedForm, qa: np.ndarray, inside=None, cond_tol: float = 1e-6):
    """Configurations at actuated draws ``qa`` from the closed form, certified by their closure and conditioning.

    Every configuration the formulas give is evaluated (closure residual and Jacobian, in blocks of
    :data:`BLOCK`): it is kept when it closes to round-off (dimensionless residual at most
    :data:`CLOSES`) with a lower bound of the inverse condition number of the dimensionless ``B_p``
    (:func:`hyperstat.solver.kinematics.continuation._inverse_parts`, the bound the continuation
    certifies with) of at least ``cond_tol``, and lies in the workspace (``inside``).  Its branch is
    the home one by construction: every elbow keeps its home side, and the elbows' ranges of the
    declared workspace keep them off the fold where the two sides meet.

    Returns
    -------
    q : ndarray, (K, n_q)
    certificate : BranchCertificate
        ``certified`` for the kept draws (no path: zero steps); the reason of the others.
    generic : ndarray of bool, (K,)
        Draws within reach whose configuration did not close or is ill-conditioned: for the
        generic corrector (:func:`hyperstat.solver.kinematics.continuation.continue_nearest`).
    """
    from hyperstat.solver.kinematics.continuation import (BranchCertificate, ContinuationOptions,
                                                          _dimensionless_state, _inverse_parts)

    q, reach = form.assemble(qa)
    k = len(q)
    pas = np.asarray(kin.mechanism.passive)
    closes = np.zeros(k, dtype=bool)
    sigma = np.full(k, np.inf)
    cond = np.ones(k)
    for start in range(0, k, BLOCK):
        rows = np.arange(start, min(start + BLOCK, k))
        rows = rows[reach[rows]]
        if not len(rows):
            continue
        r, b = _dimensionless_state(kin, q[rows], None)
        closes[rows] = np.max(np.abs(r), axis=1) <= CLOSES
        _, sigma[rows], cond[rows] = _inverse_parts(b[:, :, pas], len(pas))
    good = reach & closes & (cond >= cond_tol)
    inn = np.ones(k, dtype=bool) if inside is None else np.asarray(inside(q), bool)
    certified = good & inn
    reason = [""] * k
    for i in np.nonzero(~reach)[0]:
        reason[i] = UNREACHABLE
    for i in np.nonzero(good & ~inn)[0]:
        reason[i] = OUTSIDE
    generic = reach & ~good
    for i in np.nonzero(generic)[0]:
        reason[i] = "not reached"
    z = np.zeros(k)
    cert = BranchCertificate(certified, reason, np.where(reach, cond, 1.0), sigma, z.copy(), z.copy(),
                             np.zeros(k, int), np.zeros(k, int), z.copy(), np.where(reach, cond, 1.0),
                             ContinuationOptions(cond_tol=cond_tol))
    return q, cert, generic
