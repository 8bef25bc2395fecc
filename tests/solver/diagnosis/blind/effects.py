"""The blind generator's own effects: what the real machine does that a rigid model does not.

Each effect is a function ``effect(ctx, **params) -> Change``: it reads the commanded joint
values and the campaign's metadata in ``ctx`` and returns how the true machine differs from
the rigid one (joint errors, link deformations, base motion, growth of lengths, tracker
motion).  Loads come from our own mass model (``kinematics.gravity_torques``: minus the
derivative of the potential energy; beam and pedestal formulas of Euler-Bernoulli theory,
evaluated at the undeformed configuration: first order).  SI units throughout.

Written without reading hyperstat's effects library: these are textbook models, named after
the physics, not after the library's effect names (the case table says which library name,
if any, a case counts as).
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Dict, Optional

import numpy as np

from .kinematics import GVEC, Arm, Geometry, com_positions, exp_so3, frames, gravity_torques, mass_vector


@dataclasses.dataclass
class Context:
    arm: Arm
    geom: Geometry
    q: np.ndarray              # (K, 6) commanded joint values (what the file holds), rad
    payload: np.ndarray        # (K,) kg at the tool0 origin
    temperature: np.ndarray    # (K,) degC
    dirs: np.ndarray           # (K, 6) approach direction of the last motion, +-1
    session: np.ndarray        # (K,) 1, 2, ...
    n_targets: int


@dataclasses.dataclass
class Change:
    dq: np.ndarray                                   # (K, 6) rad, added to the commanded values
    deform: Dict[int, np.ndarray]                    # link index -> (K, 4, 4), see kinematics.frames
    scale: Optional[np.ndarray] = None               # (K, 7) factor on origin translations
    target_scale: Optional[np.ndarray] = None        # (K,) factor on the target offsets
    target_shift: Optional[np.ndarray] = None        # (K, 3) m, added to every target offset (tool frame)
    world_shift: Optional[np.ndarray] = None         # (K, 3) m, added to measured world positions (tracker moved)

    @staticmethod
    def empty(k: int, n: int = 6) -> "Change":
        return Change(np.zeros((k, n)), {})


def combine(a: Change, b: Change) -> Change:
    out = Change(a.dq + b.dq, dict(a.deform))
    for i, d in b.deform.items():
        out.deform[i] = out.deform[i] @ d if i in out.deform else d
    for name in ("scale", "target_scale"):
        x, y = getattr(a, name), getattr(b, name)
        setattr(out, name, x if y is None else (y if x is None else x * y))
    for name in ("target_shift", "world_shift"):
        x, y = getattr(a, name), getattr(b, name)
        setattr(out, name, x if y is None else (y if x is None else x + y))
    return out


# --------------------------------------------------------------------------- joint (transmission) errors

def angle_scale(ctx: Context, joint: int, s: float) -> Change:
    """Gear-ratio / encoder scale error: the joint turns (1 + s) times the commanded angle."""
    c = Change.empty(len(ctx.q))
    c.dq[:, joint] = s * ctx.q[:, joint]
    return c


def harmonic(ctx: Context, joint: int, order: float, amplitude: float, phase: float) -> Change:
    """Periodic angle error ``A sin(k q + phase)`` at ``k`` cycles per revolution of the joint
    (encoder eccentricity k = 1, strain-wave ellipticity k = 2, three-crank RV reducer k = 3,
    an intermediate gear turning 1.5 times per output turn k = 1.5)."""
    c = Change.empty(len(ctx.q))
    c.dq[:, joint] = amplitude * np.sin(order * ctx.q[:, joint] + phase)
    return c


def coupling(ctx: Context, joint: int, source: int, kappa: float) -> Change:
    """Cross-coupling: joint ``joint`` turns by ``kappa`` rad per rad of joint ``source`` (a
    decoupling factor of the controller that is off: a forearm drive mounted on the turret,
    a hollow wrist whose bevel gears carry joint 4's motion into joint 5)."""
    c = Change.empty(len(ctx.q))
    mid = ctx.q[:, source].mean()
    c.dq[:, joint] = kappa * (ctx.q[:, source] - mid)
    return c


def parallelogram(ctx: Context, joint: int, rod_error: float) -> Change:
    """Joint driven through a parallelogram whose coupler is ``rod_error`` (relative to the
    crank radius) too long: the follower angle is off by ``-rod_error / sin(phi)``, with the
    parallelogram angle ``phi = pi/2 + q`` (first order in the length error)."""
    c = Change.empty(len(ctx.q))
    c.dq[:, joint] = -rod_error / np.cos(ctx.q[:, joint])
    return c


def dress_pack(ctx: Context, joint: int, torque: float, centre: float, width: float) -> Change:
    """A cable/hose package that winds around the joint pulls with a torque that saturates
    either side of its neutral angle, ``tau0 tanh((q - c) / w)``; the joint's own stiffness
    turns it into an angle error ``tau / K``."""
    c = Change.empty(len(ctx.q))
    c.dq[:, joint] = torque / ctx.arm.stiffness[joint] * np.tanh((ctx.q[:, joint] - centre) / width)
    return c


def backlash(ctx: Context, joint: int, clearance: float) -> Change:
    """Dead band of width ``clearance``: the motor drags the load, which therefore lags the
    command by half the band on the side it came from (``dir`` = +1: it came from below)."""
    c = Change.empty(len(ctx.q))
    c.dq[:, joint] = -0.5 * clearance * ctx.dirs[:, joint]
    return c


# --------------------------------------------------------------------------- gravity-driven

def _true_q(ctx: Context, prior: Optional[Change]) -> np.ndarray:
    return ctx.q + (prior.dq if prior is not None else 0.0)


def joint_compliance(ctx: Context, factor: float, prior: Optional[Change] = None, joints=None) -> Change:
    """Each joint gives way to the gravity torque: ``dq_j = tau_j / K_j`` (``K`` of the arm
    times ``1/factor``), ``tau = -dV/dq`` of our own masses and the payload."""
    q = _true_q(ctx, prior)
    tau = gravity_torques(ctx.arm, ctx.geom, q, ctx.payload)
    c = Change.empty(len(q))
    sel = range(ctx.arm.n) if joints is None else joints
    for j in sel:
        c.dq[:, j] = factor * tau[:, j] / ctx.arm.stiffness[j]
    return c


def gravity_backlash(ctx: Context, joint: int, clearance: float, prior: Optional[Change] = None) -> Change:
    """The load rests on the flank gravity pushes it to: ``dq = clearance/2 * sign(tau)``."""
    q = _true_q(ctx, prior)
    tau = gravity_torques(ctx.arm, ctx.geom, q, ctx.payload)
    c = Change.empty(len(q))
    c.dq[:, joint] = 0.5 * clearance * np.sign(tau[:, joint])
    return c


def _small_transform(centre: np.ndarray, shift: np.ndarray, rotvec: np.ndarray) -> np.ndarray:
    """(K,4,4): rotation ``rotvec`` about ``centre`` (link frame), then a shift."""
    k = len(shift)
    r = exp_so3(rotvec)
    out = np.repeat(np.eye(4)[None], k, axis=0)
    out[:, :3, :3] = r
    out[:, :3, 3] = centre + shift - np.einsum("kij,j->ki", r, centre)
    return out


def beam(ctx: Context, which: str, bending: float = 1.0, torsion: float = 0.0,
         prior: Optional[Change] = None) -> Change:
    """Euler-Bernoulli deformation of one link under the weights it carries.

    The link is a cantilever clamped at its root (the joint before it).  Loads: its own
    weight spread uniformly (w), and the resultant of everything downstream (links and
    payload) reduced to the beam end: a force F and a moment M.  With e the beam direction,
    the transverse parts P = F - (F.e)e, w_p, M_b = M - (M.e)e and the torsion T = M.e give
    (Roark / any strength-of-materials table, small deflections):

        end deflection  d = P L^3/(3EI) + w_p L^4/(8EI) + M_b x e L^2/(2EI)
        end rotation    w = e x P L^2/(2EI) + e x w_p L^3/(6EI) + M_b L/EI + T e L/GJ

    ``bending`` and ``torsion`` scale the two parts (0 switches one off; 1/bending is the
    factor on EI).  Applied as a small transform about the beam end, in the link frame.
    """
    arm = ctx.arm
    bm = arm.beams[which]
    q = _true_q(ctx, prior)
    fr = frames(arm, ctx.geom, q)
    com = com_positions(arm, fr)                        # (K, 7, 3)
    m = mass_vector(arm, ctx.payload)                   # (K, 7)
    f_link = fr[bm.link]
    rl = f_link[:, :3, :3]
    e = np.einsum("kij,j->ki", rl, bm.direction)
    root = np.einsum("kij,j->ki", rl, bm.start) + f_link[:, :3, 3]
    end = root + bm.length * e
    down = slice(bm.link, arm.n + 1)                    # bodies of joints link+1..6 and the payload
    force = np.sum(m[:, down], axis=1)[:, None] * GVEC[None, :]
    moment = np.sum(np.cross(com[:, down] - end[:, None, :], m[:, down, None] * GVEC[None, None, :]), axis=1)
    w = (m[:, bm.link - 1] / bm.length)[:, None] * GVEC[None, :]

    def perp(v):
        return v - np.sum(v * e, axis=1)[:, None] * e

    p, wp, mb = perp(force), perp(w), perp(moment)
    t = np.sum(moment * e, axis=1)
    L, EI, GJ = bm.length, bm.EI, bm.GJ
    d = bending * (p * L ** 3 / (3 * EI) + wp * L ** 4 / (8 * EI) + np.cross(mb, e) * L ** 2 / (2 * EI))
    rot = bending * (np.cross(e, p) * L ** 2 / (2 * EI) + np.cross(e, wp) * L ** 3 / (6 * EI) + mb * L / EI)
    rot = rot + torsion * (t * L / GJ)[:, None] * e
    d_l = np.einsum("kji,kj->ki", rl, d)                # into the link frame
    r_l = np.einsum("kji,kj->ki", rl, rot)
    centre = bm.start + bm.length * bm.direction
    c = Change.empty(len(q))
    c.deform[bm.link] = _small_transform(centre, d_l, r_l)
    return c


def base_tilt(ctx: Context, factor: float, prior: Optional[Change] = None) -> Change:
    """The pedestal under the robot is a cantilever of height H loaded at its top by the
    overturning moment of the arm's weights and the payload, ``M = sum r x m g`` about the
    base origin: the top turns by ``M H / EI`` and shifts by ``M x z H^2 / (2 EI)``."""
    arm = ctx.arm
    q = _true_q(ctx, prior)
    fr = frames(arm, ctx.geom, q)
    com = com_positions(arm, fr)
    m = mass_vector(arm, ctx.payload)
    moment = np.sum(np.cross(com, m[:, :, None] * GVEC[None, None, :]), axis=1)
    h, ei = arm.pedestal_height, arm.pedestal_EI / factor
    rot = moment * h / ei
    shift = np.cross(moment, np.array([0.0, 0.0, 1.0])) * h ** 2 / (2 * ei)
    c = Change.empty(len(q))
    c.deform[0] = _small_transform(np.zeros(3), shift, rot)
    return c


# --------------------------------------------------------------------------- thermal and measurement

def thermal(ctx: Context, alpha: float) -> Change:
    """Uniform expansion of the arm: every link length and the target offsets grow by
    ``alpha (T - 20 degC)``."""
    k = len(ctx.q)
    s = 1.0 + alpha * (ctx.temperature - 20.0)
    c = Change.empty(k)
    c.scale = np.repeat(s[:, None], ctx.arm.n + 1, axis=1)
    c.target_scale = s
    return c


def link_growth(ctx: Context, origin: int, alpha: float) -> Change:
    """One link warms (its motor), the others do not: only the translation of origin
    ``origin`` (the next joint's placement) grows by ``alpha (T - 20)``; T is the recorded
    temperature (a sensor on that link)."""
    k = len(ctx.q)
    s = np.ones((k, ctx.arm.n + 1))
    s[:, origin] = 1.0 + alpha * (ctx.temperature - 20.0)
    c = Change.empty(k)
    c.scale = s
    return c


def tool_growth(ctx: Context, length: float, alpha: float) -> Change:
    """The tool that carries the reflectors (an aluminium extension of ``length`` m along the
    tool's z axis) grows by ``alpha length (T - 20)`` along that axis."""
    k = len(ctx.q)
    c = Change.empty(k)
    c.target_shift = np.zeros((k, 3))
    c.target_shift[:, 2] = alpha * length * (ctx.temperature - 20.0)
    return c


def tracker_moved(ctx: Context, shifts: Dict[int, np.ndarray]) -> Change:
    """The tracker was bumped between sessions: from session s on, every measured position
    is off by ``shifts[s]`` (world frame, m)."""
    k = len(ctx.q)
    c = Change.empty(k)
    c.world_shift = np.zeros((k, 3))
    for s, v in shifts.items():
        c.world_shift[ctx.session == s] = v
    return c


TRANSMISSION: Dict[str, Callable[..., Change]] = {
    "angle_scale": angle_scale, "harmonic": harmonic, "coupling": coupling,
    "parallelogram": parallelogram, "dress_pack": dress_pack, "backlash": backlash,
}
GRAVITY: Dict[str, Callable[..., Change]] = {
    "joint_compliance": joint_compliance, "gravity_backlash": gravity_backlash, "beam": beam,
    "base_tilt": base_tilt,
}
OTHER: Dict[str, Callable[..., Change]] = {
    "thermal": thermal, "link_growth": link_growth, "tool_growth": tool_growth,
    "tracker_moved": tracker_moved,
}


def apply(ctx: Context, specs) -> Change:
    """All effects of a case: joint (transmission) errors first, then the gravity-driven
    ones evaluated at the configuration those errors give, then the others."""
    k = len(ctx.q)
    total = Change.empty(k)
    for name, kw in specs:
        if name in TRANSMISSION:
            total = combine(total, TRANSMISSION[name](ctx, **kw))
    trans = Change(total.dq.copy(), {})
    for name, kw in specs:
        if name in GRAVITY:
            total = combine(total, GRAVITY[name](ctx, prior=trans, **kw))
    for name, kw in specs:
        if name in OTHER:
            total = combine(total, OTHER[name](ctx, **kw))
    unknown = [n for n, _ in specs if n not in TRANSMISSION and n not in GRAVITY and n not in OTHER]
    if unknown:
        raise ValueError(f"unknown effect(s) {unknown}")
    return total
