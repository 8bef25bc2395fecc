"""Effects put into the virtual machines of the twelfth blind generator (directory ``blind10``).

Units: mm, rad, degC, s, kg, N (prismatic loads), N mm (revolute loads).  Source-blind: the library
effects are written from the equations of ``docs/diagnosis.md`` ("The effects library"); the
out-of-library effects are this generator's own physical ideas.  Nothing here imports hyperstat.

An effect acts at one of three places (``KIND``):

* ``joint``: the joint really sits at ``q + dq`` (``joint_dq`` returns ``dq`` per joint);
* ``frame``: a local transform after a joint's motion (``frame_post``: a bowed or tilting guide);
* ``point``: on the measured point (base frame, ``point_base``) or in the tracker frame
  (``point_tracker``).

``ctx`` (one pose): ``q`` file values, ``dir`` last-move signs, ``tau`` true gravity loads, ``M`` base
moment (N mm), ``T`` temperature, ``ts`` seconds since the session's start, ``session``, ``payload``,
``lo``/``hi`` joint ranges, ``jz`` {joint: z axis of the joint frame (base)}, ``jx`` {joint: x axis}.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import erf

LIBRARY = {
    "angle-harmonic", "angle-scale", "screw-pitch", "screw-periodic", "backlash", "backlash-gravity",
    "compliance", "link-bending", "leg-thermal", "joint-clearance", "thermal", "tracker-drift",
    "tracker-scale", "base-deformation", "guide-straightness",
}
OUT = {"adm-warmup-scale", "tracker-azimuth-warmup", "platform-bow-thermal", "telescope-overlap-tilt",
       "anchor-yaw-step"}
DROPPED = {"screw-hotspot", "abbe-scale-offset"}  # invisible at physical sizes (first visibility pass)

KIND = {
    "angle-harmonic": "joint", "angle-scale": "joint", "screw-pitch": "joint", "screw-periodic": "joint",
    "backlash": "joint", "backlash-gravity": "joint", "compliance": "joint", "link-bending": "joint",
    "leg-thermal": "joint", "joint-clearance": "joint", "screw-hotspot": "joint",
    "abbe-scale-offset": "joint", "offset": "joint",
    "guide-straightness": "frame", "telescope-overlap-tilt": "frame",
    "thermal": "point_base", "base-deformation": "point_base", "anchor-yaw-step": "point_base",
    "tracker-drift": "point_tracker", "tracker-scale": "point_tracker", "adm-warmup-scale": "point_tracker",
    "tracker-azimuth-warmup": "point_tracker", "platform-bow-thermal": "target",
}


def _rot(axis, angle):
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def joint_dq(name, p, ctx):
    """dq per joint (rad or mm) of a joint-level effect with parameters ``p``."""
    q, out = ctx["q"], {}
    per = p.get("per", {})
    if name == "offset":
        return dict(per)
    if name == "angle-harmonic":  # docs: dq = a sin(k q) + b cos(k q)
        k = p["k"]
        for j, (a, b) in per.items():
            out[j] = a * math.sin(k * q[j]) + b * math.cos(k * q[j])
    elif name in ("angle-scale", "screw-pitch"):  # dq = s q
        for j, s in per.items():
            out[j] = s * q[j]
    elif name == "screw-periodic":  # dq = a sin(2 pi q order / lead) + b cos(...)
        lead, order = p.get("lead", 10.0), p.get("order", 1)
        for j, (a, b) in per.items():
            ph = 2 * math.pi * q[j] * order / lead
            out[j] = a * math.sin(ph) + b * math.cos(ph)
    elif name == "backlash":  # dq = -beta/2 dir
        for j, beta in per.items():
            out[j] = -beta / 2 * ctx["dir"][j]
    elif name in ("backlash-gravity", "joint-clearance"):  # dq = beta/2 sign(tau)
        for j, beta in per.items():
            out[j] = beta / 2 * float(np.sign(ctx["tau"][j]))
    elif name == "compliance":  # dq = c tau
        for j, c in per.items():
            out[j] = c * ctx["tau"][j]
    elif name == "link-bending":  # the link between parallel revolutes a, b: 2/3 c tau_a, 1/3 c tau_a
        for a, (b, c) in per.items():
            out[a] = out.get(a, 0.0) + 2.0 / 3.0 * c * ctx["tau"][a]
            out[b] = out.get(b, 0.0) + 1.0 / 3.0 * c * ctx["tau"][a]
    elif name == "leg-thermal":  # dq = kappa (T - 20) q
        for j, k in per.items():
            out[j] = k * (ctx["T"] - 20.0) * q[j]
    elif name == "screw-hotspot":
        # own: a hot spot on the screw where the nut dwells most (centre x0, width w mm), heating
        # with the running time of the session: dT(x) = D (1 - exp(-ts/tau)) exp(-((x - x0)/w)^2);
        # the nut's position error is the screw's growth between its fixed end and the nut:
        # dq = kappa * integral_lo^q dT(x) dx (steel kappa 1.15e-5).
        j, D, x0, w, tau = p["joint"], p["D"], p["x0"], p["w"], p.get("tau", 1800.0)
        lo = ctx["lo"][j]
        heat = D * (1 - math.exp(-ctx["ts"] / tau))
        integ = w * math.sqrt(math.pi) / 2 * (erf((q[j] - x0) / w) - erf((lo - x0) / w))
        out[j] = 1.15e-5 * heat * integ
    elif name == "abbe-scale-offset":
        # own: a linear scale mounted e mm off a leg's screw axis, along the leg frame's x; the
        # carriage pitches under the gravity component across the leg, theta = c (g_hat . x_leg),
        # so the scale reads e theta too little: dq = k (-e_z . x_leg), k = e c (mm).
        for j, k in per.items():
            out[j] = k * float(-ctx["jx"][j][2])
    else:
        raise KeyError(name)
    return out


def frame_post(name, p, ctx):
    """{joint: 4x4 local transform after the joint's motion} of a frame-level effect."""
    j = p["joint"]
    lo, hi = ctx["lo"][j], ctx["hi"][j]
    mid, h = (lo + hi) / 2, (hi - lo) / 2
    s = (ctx["q"][j] - mid) / h
    T = np.eye(4)
    if name == "guide-straightness":
        # docs: displaced by c (1 - s^2) along x (resp. y), turned by c f' about y (resp. -c f' about x),
        # f' = -2 s / h
        cx, cy = p["c"]
        fp = -2 * s / h
        T[:3, 3] = [cx * (1 - s * s), cy * (1 - s * s), 0.0]
        T[:3, :3] = _rot([0, 1, 0], cx * fp) @ _rot([1, 0, 0], -cy * fp)
        return {j: T}
    if name == "telescope-overlap-tilt":
        # own: a telescopic boom guided by two bushings whose overlap shortens as it extends; the
        # radial play g lets the boom tilt by g / overlap, overlap = L0 - q (mm), about the rear
        # bushing (b mm behind the boom's zero); it tilts to the side gravity pulls it to:
        # about the joint frame's axis perpendicular to gravity and to the boom.
        g, L0 = p["g"], p["L0"]
        theta = g / (L0 - ctx["q"][j])
        R_j = ctx["jR"][j]
        gl = R_j.T @ np.array([0.0, 0.0, -1.0])  # gravity in the joint frame
        perp = gl - gl[2] * np.array([0, 0, 1.0])
        n = np.linalg.norm(perp)
        if n < 1e-9:
            return {j: T}
        axis = np.cross([0, 0, 1.0], perp / n)  # turning z towards gravity
        R = _rot(axis, theta * n)
        c = np.array([0.0, 0.0, -(ctx["q"][j] + p["b"])])  # the rear bushing, b mm behind the zero
        T[:3, :3] = R
        T[:3, 3] = c - R @ c
        return {j: T}
    raise KeyError(name)


def point_base(name, p, ctx, P):
    """The measured point P (base frame, mm) moved by a base-frame effect; also returns the rotation
    applied to the orientation (3x3)."""
    I3 = np.eye(3)
    if name == "thermal":  # docs: (1 + kappa (T - 20)) p about the base origin
        return (1 + p["kappa"] * (ctx["T"] - 20.0)) * P, I3
    if name == "base-deformation":  # docs: theta = c1 M_x e_x + c2 M_y e_y, p -> p + theta x p
        M = ctx["M"]
        th = np.array([p["c"][0] * M[0], p["c"][1] * M[1], 0.0])
        R = _rot(th, np.linalg.norm(th)) if np.linalg.norm(th) > 0 else I3
        return R @ P, R
    if name == "anchor-yaw-step":
        # own: the base's anchors slip when the arm is hit at the end of session s0: from then on the
        # whole machine is turned by a small yaw psi about the vertical through a point (cx, cy)
        # of the base plate (not the base origin) and lifted on one side (pitch psi2).
        if ctx["session"] < p["from_session"]:
            return P, I3
        R = _rot([0, 0, 1], p["psi"]) @ _rot([1, 0, 0], p.get("psi2", 0.0))
        c = np.array([p["cx"], p["cy"], 0.0])
        return R @ (P - c) + c, R
    raise KeyError(name)


def target_shift(name, p, ctx, off):
    """Change (output frame, mm) of a target's offset ``off`` by a target-level effect."""
    if name == "platform-bow-thermal":
        # own: the moving platform (or tool plate) bows as its upper face warms with the hall: a
        # reflector at radius r from the plate's centre rises along the output z by
        # beta (T - 20) (1 - (r / R)^2) (a spherical cap; the rim stays, the middle rises).
        r2 = (off[0] ** 2 + off[1] ** 2) / p["R"] ** 2
        return np.array([0.0, 0.0, p["beta"] * (ctx["T"] - 20.0) * (1 - r2)])
    raise KeyError(name)


def point_tracker(name, p, ctx, m):
    """The measured point m (tracker frame, mm) changed by a measurement effect."""
    if name == "tracker-drift":  # docs: a translation per session after the first
        sh = p["shift"].get(str(ctx["session"]))
        return m + np.asarray(sh, float) if sh is not None else m
    if name == "tracker-scale":  # docs: (1 + s) p
        return (1 + p["s"]) * m
    if name == "adm-warmup-scale":
        # own: the tracker is switched on at each session's start; its absolute distance meter's
        # wavelength settles as the laser warms: the range (along the beam) is scaled by
        # s0 exp(-ts / tau); directions (angles) unaffected.
        s = p["s0"] * math.exp(-ctx["ts"] / p["tau"])
        return (1 + s) * m
    if name == "tracker-azimuth-warmup":
        # own: the tracker head's azimuth encoder drifts as the head warms after each session's
        # power-on: every measured point turned about the tracker's vertical axis (its own z) by
        # psi0 exp(-ts / tau); the range is unaffected.
        return _rot([0, 0, 1], p["psi0"] * math.exp(-ctx["ts"] / p["tau"])) @ m
    raise KeyError(name)


__all__ = ["LIBRARY", "OUT", "DROPPED", "KIND", "joint_dq", "frame_post", "point_base", "point_tracker",
           "target_shift"]
