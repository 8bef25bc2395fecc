"""Effects of the fifth blind generator, written from their physical description.

In-library effects follow the physics the effects library of docs/diagnosis.md names (a gear's
eccentricity, a bowed guide, a clearance taken up by a force, ...), implemented here on the
machine's own kinematics, not from hyperstat's formulas; out-of-library effects are physical
mechanisms the library has no model for.  Each effect acts through the hooks of
``families.Family`` (joint errors, link deformations, whole-structure displacements, target
offsets, tracker effects).  Magnitudes are drawn per campaign as ``size x U[0.7, 1]`` with a
random sign or phase where the physics allows one.

Units: mm, rad, N, N mm, kg, degC, s.
"""

from __future__ import annotations

import numpy as np

from . import geom

G = 9.81


class Effect:
    kind = "in"            # in / out (of the library)
    library = None         # library name (in-library)
    order = None           # periodic order (angle-harmonic-<k>)
    joints = ()            # principal joints (model names)
    cover = ()             # out-of-library: library names whose physics covers it

    def __init__(self, **params):
        self.params = params
        self.p = {}

    def draw(self, fam, machine, rng):
        pass

    def prepare(self, fam, machine, q_all, meta):
        pass

    def joint_error(self, fam, machine, q, pose):
        return None

    def post(self, fam, machine, q, pose):
        return None

    def world(self, fam, machine, q, pose, t_out, pts, rots):
        return pts, rots

    def offsets(self, fam, machine, q, pose, t_out, offs, roffs):
        return offs, roffs

    def tracker(self, fam, machine, pose, pts, rots):
        return pts, rots

    def truth(self):
        """What the answer should name (in-library): list of dicts."""
        return [{"effect": self.library, "joints": list(self.joints), "order": self.order}]

    def describe(self):
        vals = ", ".join(f"{k}={_fmt(v)}" for k, v in self.p.items())
        return f"{type(self).__name__}({vals})"


def _fmt(v):
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_fmt(x) for x in np.ravel(v)) + "]"
    if isinstance(v, (float, np.floating)):
        return f"{v:.3g}"
    return str(v)


def _mag(rng, size):
    return size * rng.uniform(0.7, 1.0)


def _sign(rng):
    return 1.0 if rng.uniform() < 0.5 else -1.0


def _idx(fam, joint):
    return fam.actuated.index(joint)


# ============================================================================ joint errors (library)
class Harmonic(Effect):
    """A transmission error periodic in the joint's angle: eccentricity of a gear (1 per
    revolution), ellipticity of a strain-wave flexspline (2), an intermediate gear stage whose
    ratio to the joint is not an integer (1.5 for a 3:2 stage).  dq = A sin(k q + phase)."""

    library = "angle-harmonic"

    def __init__(self, joint, order, amplitude):
        super().__init__()
        self.joints = (joint,)
        self.order = order
        self.amp = amplitude

    def draw(self, fam, machine, rng):
        self.p = {"joint": self.joints[0], "order": self.order, "A": _mag(rng, self.amp),
                  "phase": rng.uniform(0, 2 * np.pi)}

    def joint_error(self, fam, machine, q, pose):
        dq = np.zeros(len(q))
        i = _idx(fam, self.joints[0])
        dq[i] = self.p["A"] * np.sin(self.order * q[i] + self.p["phase"])
        return dq

    def truth(self):
        k = self.order
        name = f"angle-harmonic-{k:g}"
        return [{"effect": name, "joints": list(self.joints), "order": k}]


class Scale(Effect):
    """A gear-ratio or encoder-scale error: the joint turns (1 + s) times what the encoder
    counts from its mastering zero."""

    library = "angle-scale"

    def __init__(self, joint, size):
        super().__init__()
        self.joints = (joint,)
        self.size = size

    def draw(self, fam, machine, rng):
        self.p = {"joint": self.joints[0], "s": _sign(rng) * _mag(rng, self.size)}

    def joint_error(self, fam, machine, q, pose):
        dq = np.zeros(len(q))
        i = _idx(fam, self.joints[0])
        dq[i] = self.p["s"] * q[i]
        return dq


class Compliance(Effect):
    """Joint (or leg) elasticity under gravity: each actuated joint yields by its compliance
    times the generalized gravity force on it (the declared link masses, or the moving mass of
    a parallel machine, and the payload at the output frame)."""

    library = "compliance"

    def __init__(self, compliances, joints=None):
        super().__init__()
        self.c = np.asarray(compliances, dtype=float)
        self.joints = tuple(joints or ())

    def draw(self, fam, machine, rng):
        self.p = {"c": self.c * rng.uniform(0.7, 1.0, len(self.c))}
        if not self.joints:
            self.joints = tuple(fam.actuated)

    def joint_error(self, fam, machine, q, pose):
        tau = fam.gravity(machine, q, pose["payload"], key=pose["index"])
        return self.p["c"] * tau


class Backlash(Effect):
    """Lost motion in a transmission: the load lags the drive by (about) half the play, on
    the side the last motion came from (the dir<joint> column)."""

    library = "backlash"

    def __init__(self, joints, plays):
        super().__init__()
        self.joints = tuple(joints)
        self.plays = plays

    def draw(self, fam, machine, rng):
        self.p = {"joints": list(self.joints), "beta": [_mag(rng, b) for b in self.plays]}

    def joint_error(self, fam, machine, q, pose):
        dq = np.zeros(len(q))
        for j, b in zip(self.joints, self.p["beta"]):
            i = _idx(fam, j)
            hold = pose["rng"].uniform(0.85, 1.0)      # friction holds the load near the flank
            dq[i] = -0.5 * b * hold * pose["dir"][i]
        return dq


class GravitySide(Effect):
    """Play taken up by gravity: the load rests on the flank its gravity torque (or a leg's
    force: the clearance of its joints) pushes it to; where that load is nearly zero, the
    load sits anywhere in the play."""

    library = "backlash-gravity"

    def __init__(self, joints, plays, library="backlash-gravity"):
        super().__init__()
        self.joints = tuple(joints)
        self.plays = plays
        self.library = library

    def draw(self, fam, machine, rng):
        self.p = {"joints": list(self.joints), "beta": [_mag(rng, b) for b in self.plays]}
        self._tmax = None

    def prepare(self, fam, machine, q_all, meta):
        taus = np.array([fam.gravity(machine, q, meta["payload"][k], key=k) for k, q in enumerate(q_all)])
        self._tmax = np.max(np.abs(taus), axis=0) + 1e-12
        self._taus = taus
        signs = {j: (int(np.sum(taus[:, _idx(fam, j)] > 0)), int(np.sum(taus[:, _idx(fam, j)] < 0))) for j in self.joints}
        self.p["load_signs(+,-)"] = str(signs).replace(",", ";")

    def joint_error(self, fam, machine, q, pose):
        tau = self._taus[pose["index"]]
        dq = np.zeros(len(q))
        for j, b in zip(self.joints, self.p["beta"]):
            i = _idx(fam, j)
            if abs(tau[i]) < 0.02 * self._tmax[i]:
                dq[i] = 0.5 * b * pose["rng"].uniform(-1, 1)
            else:
                dq[i] = 0.5 * b * np.sign(tau[i]) * pose["rng"].uniform(0.9, 1.0)
        return dq


class LegThermal(Effect):
    """Each leg's ball screw (fixed bearing at the base joint) grows with its temperature by its
    own length: the leg is longer than the encoder says by kappa (T - 20 degC) q."""

    library = "leg-thermal"

    def __init__(self, kappa):
        super().__init__()
        self.kappa = kappa

    def draw(self, fam, machine, rng):
        self.p = {"kappa": _mag(rng, self.kappa)}
        self.joints = tuple(j for j in fam.actuated if fam.mech.elements[j].type == "P")

    def joint_error(self, fam, machine, q, pose):
        dq = np.zeros(len(q))
        for j in self.joints:
            i = _idx(fam, j)
            dq[i] = self.p["kappa"] * (pose["temperature"] - 20.0) * q[i]
        return dq


class ScrewPitch(Effect):
    """Lead error of a ball screw: the nut travels (1 + s) times what the encoder counts from
    the retracted end of the stroke."""

    library = "screw-pitch"

    def __init__(self, joint, size):
        super().__init__()
        self.joints = (joint,)
        self.size = size

    def draw(self, fam, machine, rng):
        self.p = {"joint": self.joints[0], "s": _sign(rng) * _mag(rng, self.size)}

    def joint_error(self, fam, machine, q, pose):
        dq = np.zeros(len(q))
        i = _idx(fam, self.joints[0])
        lo = fam.mech.elements[self.joints[0]].range[0]
        dq[i] = self.p["s"] * (q[i] - lo)
        return dq


class ScrewPeriodic(Effect):
    """Periodic lead deviation of a ball screw, once per turn of the screw (its lead)."""

    library = "screw-periodic"

    def __init__(self, joint, amplitude, lead):
        super().__init__()
        self.joints = (joint,)
        self.amp = amplitude
        self.lead = lead

    def draw(self, fam, machine, rng):
        self.p = {"joint": self.joints[0], "A": _mag(rng, self.amp), "lead": self.lead,
                  "phase": rng.uniform(0, 2 * np.pi)}

    def joint_error(self, fam, machine, q, pose):
        dq = np.zeros(len(q))
        i = _idx(fam, self.joints[0])
        lo = fam.mech.elements[self.joints[0]].range[0]
        dq[i] = self.p["A"] * np.sin(2 * np.pi * (q[i] - lo) / self.lead + self.p["phase"])
        return dq


class JointClearance(GravitySide):
    """Clearance of the joints at both ends of each leg, taken up along the leg on the side the
    leg's force (tension or compression under the moving mass and the payload) pushes them to."""

    def __init__(self, plays_by_leg):
        super().__init__(list(plays_by_leg), list(plays_by_leg.values()), library="joint-clearance")


# ============================================================================ deformations (library)
class LinkBending(Effect):
    """A link between two parallel joints bends as an Euler-Bernoulli cantilever whose root
    moment is the first joint's gravity torque: end slope theta = c tau_a, end deflection
    2/3 L theta across the link in the plane of its motion (applied as a deformation of the
    link's end frame, not as joint angles)."""

    library = "link-bending"

    def __init__(self, pair, c):
        super().__init__()
        self.pair = pair            # (index of joint a, index of joint b)
        self.c = c

    def draw(self, fam, machine, rng):
        self.p = {"link": f"{fam.actuated[self.pair[0]]}-{fam.actuated[self.pair[1]]}", "c": _mag(rng, self.c)}
        self.joints = (fam.actuated[self.pair[0]],)

    def post(self, fam, machine, q, pose):
        a, b = self.pair
        tau = fam.gravity(machine, q, pose["payload"], key=pose["index"])
        theta = self.p["c"] * tau[a]
        fb = machine["F"][b]
        d = -fb[:3, :3].T @ fb[:3, 3]           # from the end frame back to the link's root
        d = -d                                  # root -> end, in the end frame
        d[2] = 0.0
        length = np.linalg.norm(d)
        n = np.cross([0.0, 0.0, 1.0], d / length)
        w = 2.0 / 3.0 * length * theta
        delta_end = geom.trans(*(w * n)) @ geom.rot_z(theta)
        return {a: fb @ delta_end @ geom.inv(fb)}


class GuideBow(Effect):
    """A leg bar that is not straight (a parabolic bow of sagitta c over its stroke) slides in
    its guide: its end is offset across the guide line by -4 c (u / S)^2 and turned by the
    slope -8 c u / S^2 (u the travel from the retracted end, S the stroke), in the bow's plane.
    Where the joints cannot follow, the loops close with the least elastic energy."""

    library = "guide-straightness"

    def __init__(self, joint, sagitta, side=1):
        super().__init__()
        self.joints = (joint,)
        self.sag = sagitta
        self.side = side

    def draw(self, fam, machine, rng):
        # the bow lies along the axis of the leg's platform revolute (+-0.3 rad), on the given
        # side: the direction the leg's joints cannot follow (across it, the joints turn and
        # nothing moves)
        j = self.joints[0]
        m = fam.mech
        ch = m.chains[m.elements[j].chain]
        nxt = ch.elements[m.elements[j].index + 1]
        ax = nxt.D[:3, 2]
        base = np.arctan2(ax[1], ax[0])
        self.p = {"joint": j, "sagitta": _mag(rng, self.sag),
                  "plane": base + rng.uniform(-0.3, 0.3) + (np.pi if self.side < 0 else 0.0)}

    def post(self, fam, machine, q, pose):
        j = self.joints[0]
        lo, hi = fam.mech.elements[j].range
        s_len = hi - lo
        c = self.p["sagitta"]
        b = np.array([np.cos(self.p["plane"]), np.sin(self.p["plane"]), 0.0])
        axis = np.cross([0.0, 0.0, 1.0], b)

        def bow(qd):
            u = qd[j] - lo
            off = -4.0 * c * (u / s_len) ** 2
            slope = -8.0 * c * u / s_len ** 2
            return geom.trans(*(off * b)) @ geom.hom(geom.rotvec_to_matrix(slope * axis))

        return {j: bow}


class BaseTilt(Effect):
    """The base (pedestal, machine frame) tilts about the base origin under the moment of the
    moving masses' weight and the payload, with its own stiffness about x and y; the tracker
    stands on the floor, so every measured point turns with it."""

    library = "base-deformation"

    def __init__(self, c1, c2):
        super().__init__()
        self.c = (c1, c2)

    def draw(self, fam, machine, rng):
        self.p = {"c_x": _mag(rng, self.c[0]), "c_y": _mag(rng, self.c[1])}

    def world(self, fam, machine, q, pose, t_out, pts, rots):
        m = fam.base_moment(machine, q, pose["payload"], key=pose["index"])
        theta = np.array([self.p["c_x"] * m[0], self.p["c_y"] * m[1], 0.0])
        r = geom.rotvec_to_matrix(theta)
        return ({k: r @ v for k, v in pts.items()}, {k: (r @ v if v is not None else None) for k, v in rots.items()})


class Thermal(Effect):
    """The whole structure (links, legs, screws, tool and reflector fixture) grows with its
    temperature about the base origin: every measured point moves by alpha (T - 20) p."""

    library = "thermal"

    def __init__(self, alpha):
        super().__init__()
        self.alpha = alpha

    def draw(self, fam, machine, rng):
        self.p = {"alpha": _mag(rng, self.alpha)}

    def world(self, fam, machine, q, pose, t_out, pts, rots):
        s = 1.0 + self.p["alpha"] * (pose["temperature"] - 20.0)
        return {k: s * v for k, v in pts.items()}, rots


class TrackerDrift(Effect):
    """The tracker's tripod settled during the break: in the second session the station stands
    a few hundredths of a millimetre away from where it was registered."""

    library = "tracker-drift"

    def __init__(self, size):
        super().__init__()
        self.size = size

    def draw(self, fam, machine, rng):
        v = rng.normal(size=3)
        v[2] *= 0.5
        self.p = {"shift": _mag(rng, self.size) * v / np.linalg.norm(v)}

    def tracker(self, fam, machine, pose, pts, rots):
        if pose["session"] < 2:
            return pts, rots
        r = machine["tracker"][:3, :3]
        d = r.T @ self.p["shift"]
        return {k: v - d for k, v in pts.items()}, rots


# ============================================================================ out of the library
class LooseNest(Effect):
    """A reflector sits in a worn nest: the ball settles toward gravity within the nest's plane
    (fully when the nest faces sideways, not at all when it faces up) and re-seats a little
    differently after each move.  Only that target moves."""

    kind = "out"

    def __init__(self, target, sag):
        super().__init__()
        self.target = target
        self.sag = sag

    def draw(self, fam, machine, rng):
        self.p = {"target": self.target, "sag": _mag(rng, self.sag)}

    def offsets(self, fam, machine, q, pose, t_out, offs, roffs):
        _, normal, _ = fam.targets[self.target]
        n = normal if normal is not None else np.array([0.0, 0.0, 1.0])
        g_local = t_out[:3, :3].T @ np.array([0.0, 0.0, -1.0])
        proj = g_local - np.dot(g_local, n) * n
        jitter = pose["rng"].normal(0, 0.004, 3)
        jitter -= np.dot(jitter, n) * n
        offs = dict(offs)
        offs[self.target] = offs[self.target] + self.p["sag"] * proj + jitter
        return offs, roffs


class ProbeSag(Effect):
    """A 6-D probe on a loose adapter: it sags toward gravity within the adapter's plane and
    tips with it (sag over the adapter's 40 mm lever)."""

    kind = "out"

    def __init__(self, target, sag):
        super().__init__()
        self.target = target
        self.sag = sag

    def draw(self, fam, machine, rng):
        self.p = {"target": self.target, "sag": _mag(rng, self.sag)}

    def offsets(self, fam, machine, q, pose, t_out, offs, roffs):
        n = np.array([0.0, 0.0, 1.0])
        g_local = t_out[:3, :3].T @ np.array([0.0, 0.0, -1.0])
        proj = g_local - np.dot(g_local, n) * n
        offs = dict(offs)
        roffs = dict(roffs)
        offs[self.target] = offs[self.target] + self.p["sag"] * proj
        tip = np.cross(n, proj) * (self.p["sag"] / 40.0)
        roffs[self.target] = geom.rotvec_to_matrix(tip) @ roffs[self.target]
        return offs, roffs


class CrossJoint(Effect):
    """The dress pack (or a hose) twists one joint as another bends: dq_target = eps f(q_source)
    with f = 1 - cos (a cable bent over a wrist) or sin(q + phase) (a hose dragged round an axis)."""

    kind = "out"

    def __init__(self, target, source, eps, form):
        super().__init__()
        self.target = target
        self.source = source
        self.eps = eps
        self.form = form

    def draw(self, fam, machine, rng):
        self.p = {"joint": self.target, "follows": self.source, "eps": _sign(rng) * _mag(rng, self.eps),
                  "form": self.form, "phase": rng.uniform(0, 2 * np.pi)}

    def joint_error(self, fam, machine, q, pose):
        dq = np.zeros(len(q))
        s = q[_idx(fam, self.source)]
        f = 1.0 - np.cos(s) if self.form == "1-cos" else np.sin(s + self.p["phase"])
        dq[_idx(fam, self.target)] = self.p["eps"] * f
        return dq


class WarmUpArm(Effect):
    """Heat from the axis-2 and axis-3 motors flows into the link arm and the arm: both grow
    along their length with a time constant of tens of minutes, while the recorded
    temperature (the hall's air, a metrology-grade hall) stays put."""

    kind = "out"
    cover = ("thermal",)

    def __init__(self, upper, fore, tau):
        super().__init__()
        self.size = (upper, fore)
        self.tau = tau

    def draw(self, fam, machine, rng):
        self.p = {"upper": _mag(rng, self.size[0]), "fore": _mag(rng, self.size[1]), "tau_s": self.tau}

    def post(self, fam, machine, q, pose):
        f = 1.0 - np.exp(-pose["time"] / self.tau)
        return {1: geom.trans(self.p["upper"] * f, 0, 0), 3: geom.trans(0, 0, self.p["fore"] * f)}


class CablePull(Effect):
    """An external cable to the tool pulls the flange toward its anchor on the floor; the
    controller compensates the arm's gravity deflection (model based) but not this pull, which
    the joints' elasticity turns into joint errors dq = C J^T F."""

    kind = "out"

    def __init__(self, force, anchor, compliances):
        super().__init__()
        self.force = force
        self.anchor = np.asarray(anchor, dtype=float)
        self.c = np.asarray(compliances, dtype=float)

    def draw(self, fam, machine, rng):
        self.p = {"force_N": _mag(rng, self.force), "anchor": self.anchor + rng.uniform(-100, 100, 3) * [1, 1, 0],
                  "c": self.c * rng.uniform(0.7, 1.0, len(self.c))}

    def joint_error(self, fam, machine, q, pose):
        t = fam.output_pose(machine, q)
        p = t[:3, 3]
        f = self.p["force_N"] * (self.p["anchor"] - p) / np.linalg.norm(self.p["anchor"] - p)
        jac = np.zeros((3, len(q)))
        for j in range(len(q)):
            d = np.array(q, dtype=float)
            d[j] += 1e-6
            jac[:, j] = (fam.output_pose(machine, d)[:3, 3] - p) / 1e-6
        return self.p["c"] * (jac.T @ f)


class RollReadout(Effect):
    """The 6-D probe's roll (its turn about its own axis, as the tracker's camera reads it) has
    a once-per-turn readout error: the reported orientation is turned about the probe's axis by
    A sin(roll + phase).  Positions are not affected."""

    kind = "out"

    def __init__(self, amplitude):
        super().__init__()
        self.amp = amplitude

    def draw(self, fam, machine, rng):
        self.p = {"A": _mag(rng, self.amp), "phase": rng.uniform(0, 2 * np.pi)}

    def tracker(self, fam, machine, pose, pts, rots):
        out = {}
        up = machine["tracker"][:3, :3].T @ np.array([0.0, 0.0, 1.0])
        for k, r in rots.items():
            if r is None:
                out[k] = r
                continue
            z = r[:, 2]
            x = r[:, 0]
            ref = up - np.dot(up, z) * z
            ref /= np.linalg.norm(ref)
            roll = np.arctan2(np.dot(np.cross(ref, x), z), np.dot(ref, x))
            d = self.p["A"] * np.sin(roll + self.p["phase"])
            out[k] = r @ geom.rot_z(d)[:3, :3]
        return pts, out


class ZeroDrift(Effect):
    """A joint's zero drifts as its gear warms up (the output moves against the motor encoder
    as the preload changes): dq = A (1 - exp(-t / tau)), the recorded temperature steady."""

    kind = "out"

    def __init__(self, joint, amplitude, tau):
        super().__init__()
        self.joint = joint
        self.amp = amplitude
        self.tau = tau

    def draw(self, fam, machine, rng):
        self.p = {"joint": self.joint, "A": _sign(rng) * _mag(rng, self.amp), "tau_s": self.tau}

    def joint_error(self, fam, machine, q, pose):
        dq = np.zeros(len(q))
        dq[_idx(fam, self.joint)] = self.p["A"] * (1.0 - np.exp(-pose["time"] / self.tau))
        return dq


class SpindleGrowth(Effect):
    """The spindle warms up while running between poses: the tool holder moves out along the
    spindle axis by A (1 - exp(-t / tau)); the recorded temperature (the hall) steady."""

    kind = "out"

    def __init__(self, amplitude, tau):
        super().__init__()
        self.amp = amplitude
        self.tau = tau

    def draw(self, fam, machine, rng):
        self.p = {"A": _mag(rng, self.amp), "tau_s": self.tau}

    def world(self, fam, machine, q, pose, t_out, pts, rots):
        d = -self.p["A"] * (1.0 - np.exp(-pose["time"] / self.tau)) * t_out[:3, 2]
        return {k: v + d for k, v in pts.items()}, rots


class ScrewSelfHeat(Effect):
    """Each leg's ball screw warms by its own travel (friction of nut and bearings) and cools
    with a time constant: its temperature, which nobody records (the recorded one is the
    hall's), differs leg by leg; the leg grows by kappa dT_j q_j."""

    kind = "out"
    cover = ("leg-thermal",)

    def __init__(self, peak, kappa=1.15e-5, tau=1500.0):
        super().__init__()
        self.peak = peak
        self.kappa = kappa
        self.tau = tau

    def draw(self, fam, machine, rng):
        self.p = {"peak_degC": _mag(rng, self.peak), "kappa": self.kappa, "tau_s": self.tau}
        self.legs = [j for j in fam.actuated if fam.mech.elements[j].type == "P"]

    def prepare(self, fam, machine, q_all, meta):
        order = meta["order"]
        t = meta["time"]
        idx = [_idx(fam, j) for j in self.legs]
        temp = np.zeros((len(q_all), len(idx)))
        cur = np.zeros(len(idx))
        prev = None
        # heating per mm of travel, each leg with its own friction
        rng = np.random.default_rng(int(1e6 * self.p["peak_degC"]) % (2 ** 31))
        gain = rng.uniform(0.6, 1.4, len(idx))
        for i in order:
            if prev is not None:
                dt = t[i] - t[prev]
                travel = np.abs(q_all[i][idx] - q_all[prev][idx])
                cur = cur * np.exp(-dt / self.tau) + gain * travel
            temp[i] = cur
            prev = i
        temp *= self.p["peak_degC"] / max(np.max(temp), 1e-9)
        self._temp = temp
        self._idx = idx

    def joint_error(self, fam, machine, q, pose):
        dq = np.zeros(len(q))
        for k, i in enumerate(self._idx):
            dq[i] = self.kappa * self._temp[pose["index"], k] * q[i]
        return dq


class PlatformBend(Effect):
    """The platform plate bends under the payload at its centre: the probe's mount, off the
    centre, tips outward by k x payload about the plate's axis across its radius, and the
    probe (above the plate) moves with the tip."""

    kind = "out"

    def __init__(self, target, k):
        super().__init__()
        self.target = target
        self.k = k

    def draw(self, fam, machine, rng):
        self.p = {"target": self.target, "k_rad_per_kg": _mag(rng, self.k)}

    def offsets(self, fam, machine, q, pose, t_out, offs, roffs):
        off = fam.targets[self.target][0]
        radial = np.array([off[0], off[1], 0.0])
        radial /= np.linalg.norm(radial)
        axis = np.cross([0.0, 0.0, 1.0], radial)          # tipping outward: the top moves out
        r = geom.rotvec_to_matrix(-self.p["k_rad_per_kg"] * pose["payload"] * axis)
        mount = np.array([off[0], off[1], 0.0])
        offs = dict(offs)
        roffs = dict(roffs)
        offs[self.target] = mount + r @ (offs[self.target] - mount)
        if roffs.get(self.target) is not None:
            roffs[self.target] = r @ roffs[self.target]
        return offs, roffs


class BaseCreep(Effect):
    """The machine's stand creeps while the floor under one of its feet warms (floor heating,
    a door to the yard): the base tilts steadily with time about a horizontal axis, by theta_max
    over the campaign; the tracker stands elsewhere.  The recorded temperature (the hall's air,
    at the machine) stays put."""

    kind = "out"

    def __init__(self, theta_max):
        super().__init__()
        self.theta = theta_max

    def draw(self, fam, machine, rng):
        az = rng.uniform(0, 2 * np.pi)
        self.p = {"theta_max": _mag(rng, self.theta), "axis_azimuth": az}

    def prepare(self, fam, machine, q_all, meta):
        self._tmax = float(np.max(meta["time"]))

    def world(self, fam, machine, q, pose, t_out, pts, rots):
        az = self.p["axis_azimuth"]
        th = self.p["theta_max"] * pose["time"] / self._tmax
        r = geom.rotvec_to_matrix(th * np.array([np.cos(az), np.sin(az), 0.0]))
        return ({k: r @ v for k, v in pts.items()}, {k: (r @ v if v is not None else None) for k, v in rots.items()})


class SessionStep(Effect):
    """A joint was re-mastered during the break (after a small collision): in the second session
    its zero sits a little elsewhere.  The file says nothing about it."""

    kind = "out"

    def __init__(self, joint, size):
        super().__init__()
        self.joint = joint
        self.size = size

    def draw(self, fam, machine, rng):
        self.p = {"joint": self.joint, "step": _sign(rng) * _mag(rng, self.size)}

    def joint_error(self, fam, machine, q, pose):
        dq = np.zeros(len(q))
        if pose["session"] >= 2:
            dq[_idx(fam, self.joint)] = self.p["step"]
        return dq


class SlipStep(Effect):
    """The coupling between a leg's motor (and its encoder) and its screw slipped once, in the
    middle of the first session: from then on the leg is longer or shorter than the encoder says
    by a constant."""

    kind = "out"

    def __init__(self, joint, size):
        super().__init__()
        self.joint = joint
        self.size = size

    def draw(self, fam, machine, rng):
        self.p = {"joint": self.joint, "step": _sign(rng) * _mag(rng, self.size), "at_fraction": rng.uniform(0.2, 0.35)}

    def prepare(self, fam, machine, q_all, meta):
        self._t = float(np.max(meta["time"])) * self.p["at_fraction"]

    def joint_error(self, fam, machine, q, pose):
        dq = np.zeros(len(q))
        if pose["time"] > self._t:
            dq[_idx(fam, self.joint)] = self.p["step"]
        return dq


class TrackerTilt(Effect):
    """The tracker's tripod warms on one side (sun through a window, a heater): its vertical
    axis leans slowly during the campaign, theta(t) = theta_max (1 - exp(-t / tau)) about a
    horizontal axis through the tracker head; every point it measures turns with it."""

    kind = "out"

    def __init__(self, theta_max, tau):
        super().__init__()
        self.theta = theta_max
        self.tau = tau

    def draw(self, fam, machine, rng):
        self.p = {"theta_max": _mag(rng, self.theta), "axis_azimuth": rng.uniform(0, 2 * np.pi), "tau_s": self.tau}

    def tracker(self, fam, machine, pose, pts, rots):
        az = self.p["axis_azimuth"]
        th = self.p["theta_max"] * (1.0 - np.exp(-pose["time"] / self.tau))
        axis = machine["tracker"][:3, :3].T @ np.array([np.cos(az), np.sin(az), 0.0])
        r = geom.rotvec_to_matrix(th * axis)
        return ({k: r @ v for k, v in pts.items()}, {k: (r @ v if v is not None else None) for k, v in rots.items()})
