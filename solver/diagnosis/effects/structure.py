"""Effects of a machine's structure: guide straightness, clearance of the platform joints, base deformation.

Units: lengths in mm, angles in rad, forces in N, compliances in rad/(N mm).

These are the effects a parallel kinematic machine (PKM) has beside those of its actuators
(:mod:`.actuator`: screw pitch and periodic error, leg thermal growth, compliance, backlash):

* :class:`GuideStraightness`: the moving frame of a prismatic joint follows a bowed guide;
  the rest of the machine follows it through the loop closures;
* :class:`JointClearance`: the joints that carry a leg's force sit on the side of their
  clearance the force pushes them to;
* :class:`BaseDeformation`: the frame that carries the base joints tilts under the moment of
  the moving masses' weight.

A pose-dependent defect enters the model through the output twist per unit defect, the
machine closing its loops with the passive joints and, for a direction they cannot absorb (an
over-constrained machine), the least-energy elastic deformation
(:func:`~.other.deformation_twists`, as the violated-constraint effect; paper 1 eq. 3),
evaluated on the nominal geometry (first order): the effect moves the measured point; the
rotation it gives a 6-D target is not modelled.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from hyperstat.solver.diagnosis.effects.actuator import (_actuators, _gravity_side, _require_gravity, gravity_loads,
                                                         gravity_moment)
from hyperstat.solver.diagnosis.effects.base import Effect
from hyperstat.solver.diagnosis.effects.other import deformation_twists
from hyperstat.solver.diagnosis.effects.priors import PRIORS

__all__ = ["GuideStraightness", "JointClearance", "BaseDeformation", "gravity_plane"]

_DEFECTS = ("a", "b", "c", "I", "J", "K", "G")


def _cache_key(q: np.ndarray) -> tuple:
    return (q.shape, q.tobytes()[:512], float(q.sum()), float(np.abs(q).sum()))


class GuideStraightness(Effect):
    """Straightness of the guide of each prismatic actuator: the carriage follows a bowed guide.

    The moving frame of prismatic joint ``j`` (the carriage, or a strut sliding in its guide)
    deviates from the straight line by a bow in the joint frame's x and y directions,
    ``c_x (1 - s^2)`` and ``c_y (1 - s^2)`` (mm), ``s = (q_j - q_mid) / h`` the travel scaled to
    [-1, 1] over the joint's declared range (``q_mid`` its middle, ``h`` half its length), and
    turns with the guide's slope (``c_x f'(q)`` about y, ``-c_y f'(q)`` about x, ``f' = -2 s / h``).
    ``c`` is the deviation of the middle of the stroke from the chord through its ends.  The
    displacement is carried by the element after the joint (its origin and axis defects, and a
    turn about its own axis as that joint's motion), through the loop closures to the output.  On
    a serial chain whose next element has no origin defects (a gantry's X axis carrying its Y
    axis, prismatic on prismatic) the carriage's motion is taken at the joint's own frame after
    its travel and carried rigidly to the output.
    Parameters ``straightness_<joint>_x``, ``_y`` (mm); realistic 0.005 mm, plausible up to
    0.05 mm for the bow ``sqrt(c_x^2 + c_y^2)`` (ISO 230-1, linear-guide running parallelism).
    A leg whose both ends are spherical or universal joints (a hexapod's UPS legs) absorbs it to
    first order: its signature is then zero and it is not tried.
    """

    name = "guide-straightness"
    domain_note = "a guide bowed by more than 0.05 mm over the stroke is bent, not a straightness error"

    def __init__(self, mechanism, kin=None, magnitude: float = 0.005, joints: list | None = None) -> None:
        from hyperstat.solver.kinematics.closure import Kinematics

        self.kin = kin or Kinematics(mechanism)
        acts = _actuators(mechanism, prismatic_only=True, joints=joints, name=self.name)
        self._dirs = []  # (actuator index, joint name, carried element, q_mid, h, direction 0 = x / 1 = y)
        for a, joint in acts:
            carried = self._next_element(mechanism, joint.name)
            if carried is None and not mechanism.closures:
                carried = self._own_frame(mechanism, joint.name)
            if carried is None:
                continue
            lo, hi = joint.range
            for d in (0, 1):
                self._dirs.append((a, joint.name, carried, 0.5 * (lo + hi), max(0.5 * (hi - lo), 1e-9), d))
        self._cache: dict = {}
        self._dirs = self._seen(mechanism)
        self.axes = sorted({d[0] for d in self._dirs})
        self.joints = list(dict.fromkeys(d[1] for d in self._dirs))
        names = [f"straightness_{d[1]}_{'xy'[d[5]]}" for d in self._dirs]
        groups = [[i for i, d in enumerate(self._dirs) if d[1] == j] for j in self.joints]
        p = PRIORS["guide-straightness"]
        super().__init__(names, ["mm"] * len(names), [magnitude] * len(names), plausible=p.plausible, what=p.what,
                         source=p.source, groups=groups)
        self.param_joints = [d[1] for d in self._dirs]

    def _seen(self, mechanism) -> list:
        """The bow directions the machine does not absorb to first order (at home and two other configurations).

        A displacement the joints of the leg take up (a UPS leg's ends, or the bow of a UPR leg in the plane
        its platform revolute turns in) moves nothing: that direction is left out.
        """
        if not self._dirs:
            return []
        seen = self.kin.__dict__.setdefault("_straightness_seen", {})  # one evaluation per model and joint
        if all(d[1] in seen for d in self._dirs):
            return [d for d in self._dirs if (d[1], d[5]) in seen[d[1]]]
        rng = np.random.default_rng(0)
        lo, hi = mechanism.ranges[mechanism.actuated].T
        qa = np.vstack([mechanism.home[mechanism.actuated], lo + (hi - lo) * rng.uniform(0.3, 0.7, (2, len(lo)))])
        q = self.kin.solve(qa).q
        twist = self._twists(SimpleNamespace(mechanism=mechanism), q)
        size = np.linalg.norm(twist[:, 3:, :], axis=1) + self.kin.length_scale * np.linalg.norm(twist[:, :3, :], axis=1)
        keep = size.max(axis=0) > 1e-6
        self._cache = {}
        for d, k in zip(self._dirs, keep):
            seen.setdefault(d[1], set())
            if k:
                seen[d[1]].add((d[1], d[5]))
        return [d for d, k in zip(self._dirs, keep) if k]

    @staticmethod
    def _next_element(mechanism, joint: str):
        """The element after prismatic ``joint`` in its chain: its defect indices, origin, axis and joint index.

        None when it cannot carry the carriage's displacement (no origin defects a, b).
        """
        for ch in mechanism.chains:
            names = [el.name for el in ch.elements]
            if joint not in names:
                continue
            i = names.index(joint)
            if i + 1 >= len(ch.elements):
                return None
            el = ch.elements[i + 1]
            comps = {d.component: mechanism.parameter_index[d.name] for d in getattr(el, "defects", ())}
            if "a" not in comps or "b" not in comps:
                return None
            placement = el.placement
            jidx = mechanism.joint_index.get(el.name) if getattr(el, "kind", "") == "joint" else None
            revolute = jidx is not None and mechanism.joints[jidx].type == "R"
            return {"defects": comps, "origin": np.asarray(placement.origin, float),
                    "axis": np.asarray(placement.z_axis, float), "joint": jidx if revolute else None}
        return None

    @staticmethod
    def _own_frame(mechanism, joint: str):
        """A serial chain's prismatic ``joint`` whose next element has no origin defects (a gantry's X carrying its
        Y axis, prismatic on prismatic): the carriage's motion is taken at the joint's own frame after its travel,
        ``{"frame": (chain index, element index)}``, and carried to the output as a rigid motion of everything after
        it (no loop to close)."""
        for c, ch in enumerate(mechanism.chains):
            names = [el.name for el in ch.elements]
            if joint in names:
                return {"frame": (c, names.index(joint)), "own_joint": mechanism.joint_index[joint]}
        return None

    def _frame_twists(self, q: np.ndarray, state, out: np.ndarray) -> None:
        """Fill the columns of the directions carried at a joint's own frame (:meth:`_own_frame`): output twist
        ``(omega, v of the output origin)`` of the carriage's translation ``t`` and turn ``w`` (joint frame) about
        the joint frame's origin after its travel."""
        frames = (((1, 0, 0), (0, 1, 0)), ((0, 1, 0), (-1, 0, 0)))  # x bow: turn about +y; y bow: about -x
        out_origin = state.output_pose[:, :3, 3]
        for e, (a, _, carried, mid, half, d) in enumerate(self._dirs):
            if "frame" not in carried:
                continue
            f = state.element_frames[carried["frame"]]  # (K, 4, 4): the joint's frame before its travel
            rot = f[:, :3, :3]
            qj = q[:, carried["own_joint"]]
            origin = f[:, :3, 3] + qj[:, None] * rot[:, :, 2]  # after its travel along its z axis
            s = (q[:, self.mechanism_actuated[a]] - mid) / half
            bow, slope = 1.0 - s**2, -2.0 * s / half
            t = rot @ np.asarray(frames[d][0], float) * bow[:, None]
            w = rot @ np.asarray(frames[d][1], float) * slope[:, None]
            out[:, :3, e] = w
            out[:, 3:, e] = t + np.cross(w, out_origin - origin)

    def _twists(self, model, q: np.ndarray) -> np.ndarray:
        """Output twist per unit parameter at configurations ``q`` (K, 6, n_e), nominal geometry."""
        from hyperstat.solver.tolerances.accuracy import output_twist_maps

        key = _cache_key(q)
        if key in self._cache:
            return self._cache[key]
        m = model.mechanism
        self.mechanism_actuated = m.actuated
        used = sorted({i for d in self._dirs for i in d[2].get("defects", {}).values()})
        k_xi = np.zeros((len(q), 6, len(m.parameters)))
        if used:
            k_xi[:, :, used] = deformation_twists(self.kin, q, used)  # (K, 6, n): loops closed by the least energy
        k_a = output_twist_maps(self.kin, self.kin.evaluate(q, None, jacobians=True))[1] \
            if any(d[2].get("joint") is not None for d in self._dirs) else None
        act = list(m.actuated)
        k = len(q)
        out = np.zeros((k, 6, len(self._dirs)))
        frames = (((1, 0, 0), (0, 1, 0)), ((0, 1, 0), (-1, 0, 0)))  # x bow: turn about +y; y bow: about -x
        if any("frame" in d[2] for d in self._dirs):
            self._frame_twists(q, self.kin.evaluate(q, None, jacobians=False), out)
        for e, (a, _, carried, mid, half, d) in enumerate(self._dirs):
            if "frame" in carried:
                continue
            s = (q[:, m.actuated[a]] - mid) / half
            bow, slope = 1.0 - s**2, -2.0 * s / half
            t = np.outer(bow, frames[d][0])  # (K, 3) carriage translation per unit c, joint frame
            w = np.outer(slope, frames[d][1])  # (K, 3) carriage rotation per unit c
            shift = t + np.cross(w, carried["origin"])  # the next element's origin
            tilt = np.cross(w, carried["axis"])  # its axis (tangent part: the minimal rotation)
            roll = w @ carried["axis"]  # turn about its own axis
            col = np.zeros((k, 6))
            for comps, values in (("abc", shift), ("IJK", tilt)):
                for c, v in zip(comps, values.T):
                    if c in carried["defects"]:
                        col += k_xi[:, :, carried["defects"][c]] * v[:, None]
            if k_a is not None and carried["joint"] is not None and carried["joint"] in act:
                col += k_a[:, :, act.index(carried["joint"])] * roll[:, None]
            elif "G" in carried["defects"]:
                col += k_xi[:, :, carried["defects"]["G"]] * roll[:, None]
            out[:, :, e] = col
        self._cache = {key: out}
        return out

    def output_correction(self, model, theta, data, q, state, world, jacobian):
        twist = self._twists(model, q)
        arm = world - state.output_pose[:, :3, 3]
        point = twist[:, 3:, :] + np.cross(twist[:, :3, :], arm[:, :, None], axis=1)
        return point @ theta, point


class JointClearance(Effect):
    """Clearance of the joints between each leg and the platform of a parallel machine (gravity side).

    The joints that carry a leg's force (its platform joint, and its base joint) sit on the side
    of their clearance the force pushes them to: along the leg, by half the clearance, with the
    sign of the leg's force under the weight of the moving masses (tension or compression),
    ``dq_j = beta_j / 2 * sign(f_j)`` on the leg's actuated length, ``f_j`` the actuator force of
    :func:`~.actuator.gravity_loads` (declared ``moving_mass`` and the ``payload[kg]`` column).
    Parameters ``clearance_<joint>`` (mm, the leg's actuated joint), ``beta >= 0``; realistic
    0.01 mm, plausible up to 0.15 mm (ISO 12240-1 spherical plain bearings, ISO 5753-1).  On a
    leg whose force is axial (UPS, SPS: a two-force member) its signature is that of the leg
    screw's ``backlash-gravity``: the two form one equivalence set, which only a measurement of
    the joint's play itself separates.
    """

    name = "joint-clearance"
    sign_of_load = True  # its columns are steps with the sign of the leg's force (screening prior: the bound)
    domain_note = "a clearance is never negative (beta >= 0), and above 0.15 mm the joint is worn out"

    def __init__(self, mechanism, magnitude: float = 0.01, joints: list | None = None) -> None:
        _require_gravity(mechanism, self.name)
        acts = _actuators(mechanism, prismatic_only=True, joints=joints, name=self.name)
        self.axes = [a for a, _ in acts]
        self.joints = [j.name for _, j in acts]
        p = PRIORS["joint-clearance"]
        names = [f"clearance_{j}" for j in self.joints]
        super().__init__(names, ["mm"] * len(names), [magnitude] * len(names), lower=0.0, plausible=p.plausible,
                         what=p.what, source=p.source)
        self.param_joints = list(self.joints)
        self._cache: dict = {}

    def actuator_correction(self, model, theta, data):
        payload = data.metadata.get("payload", np.zeros(len(data)))
        tau = gravity_loads(model.mechanism, model.kin, data.q, payload, self._cache)
        return _gravity_side(tau, self.axes, theta)


def gravity_plane(mechanism) -> np.ndarray:
    """Two orthonormal base-frame directions perpendicular to gravity (``metadata.gravity``, default -z), (2, 3).

    >>> from types import SimpleNamespace
    >>> gravity_plane(SimpleNamespace(metadata={})).tolist()
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    """
    g = np.asarray(mechanism.metadata.get("gravity", (0.0, 0.0, -1.0)), dtype=float)
    g = g / np.linalg.norm(g)
    e1 = np.eye(3)[0] - g[0] * g
    if np.linalg.norm(e1) < 1e-6:
        e1 = np.eye(3)[1] - g[1] * g
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(-g, e1)]) + 0.0  # + 0.0: no negative zeros


class BaseDeformation(Effect):
    """The frame carrying the base joints tilts under the moment of the moving masses' weight.

    ``theta_tilt = c_1 (M . e_1) e_1 + c_2 (M . e_2) e_2`` (rad), ``M = sum_b (x_b - o) x m_b g`` the
    moment of the moving masses' weight about the base origin ``o`` (N mm; the link masses at the
    pose, a declared ``moving_mass`` and the ``payload[kg]`` column at the output), ``e_1, e_2`` the
    base directions perpendicular to gravity (x and y for gravity along -z).  The measured point
    moves by ``theta_tilt x p`` (``p`` in the base frame): the machine turns about the base origin
    with its frame, the tracker stands on the floor.  Parameters ``base_tilt_1``, ``base_tilt_2``
    (rad/(N mm)), ``c >= 0`` (a frame yields in the sense of the moment); realistic 2e-11
    (5e7 N m/rad), plausible up to 1e-9 (1e6 N m/rad; Weck and Brecher 2006).  On a serial arm it
    is the pedestal's tilt under the arm's moment.
    """

    name = "base-deformation"
    domain_note = "a tilt compliance is never negative, and beyond 1e-9 rad/(N mm) (1e6 N m/rad) the frame is loose"

    def __init__(self, mechanism, kin=None, magnitude: float = 2e-11) -> None:
        from hyperstat.solver.kinematics.closure import Kinematics

        _require_gravity(mechanism, self.name)
        self.kin = kin or Kinematics(mechanism)
        self.plane = gravity_plane(mechanism)
        p = PRIORS["base-deformation"]
        super().__init__(["base_tilt_1", "base_tilt_2"], ["rad/(N mm)"] * 2, [magnitude] * 2, lower=0.0,
                         plausible=p.plausible, what=p.what, source=p.source)
        self._cache: dict = {}

    def moments(self, model, data) -> np.ndarray:
        """Components of the gravity moment about the base origin along ``e_1, e_2`` (N mm), (K, 2)."""
        payload = data.metadata.get("payload", np.zeros(len(data)))
        key = _cache_key(np.c_[data.q, payload])
        if key not in self._cache:
            self._cache = {key: gravity_moment(model.mechanism, self.kin, data.q, payload) @ self.plane.T}
        return self._cache[key]

    def output_correction(self, model, theta, data, q, state, world, jacobian):
        m = self.moments(model, data)
        point = np.stack([m[:, i, None] * np.cross(self.plane[i][None, :], world) for i in range(2)], axis=2)
        return point @ theta, point
