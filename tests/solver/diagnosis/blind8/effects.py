"""Effects put into the virtual machines of the tenth blind generator (``blind8``).

Units: mm, rad, degC, kg, N / N mm (gravity loads), s.  ``q`` is the joint value the file states; the
joint really sits at ``q + dq``.  In-library effects follow the equations of ``docs/diagnosis.md``
("The effects library"), read by this generator only from the docs; out-of-library effects are this
generator's own physical ideas, none a library effect's equation.

Every effect is ``apply(name, params, ctx)`` -> ``Perturbation``; ``ctx`` holds one pose: ``qa``
(commanded actuated values), ``T`` (temperature), ``payload``, ``dir`` (approach directions),
``session``, ``tau`` (true gravity loads), ``M`` (true base moment), ``frames`` (serial: joint frames
after their motion at the commanded pose), ``qfull`` (parallel: every joint at the commanded pose),
``ranges`` (actuated ranges).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .machine import rot_about_line

LIBRARY = {"angle-harmonic", "angle-scale", "screw-pitch", "screw-periodic", "backlash",
           "backlash-gravity", "joint-clearance", "compliance", "link-bending", "leg-thermal",
           "thermal", "tracker-drift", "base-deformation", "guide-straightness"}
OUT = {"guide-twist", "bridge-yaw", "tracker-weather", "hose-wind", "ram-bending", "skew-thermal",
       "belt-load", "wrist-coupling", "absolute-harmonic", "table-tilt-thermal", "race-wobble",
       "passive-drag", "holder-sag"}
DEFAULT_LEAD = 10.0  # mm, the docs' screw lead when the model declares none


@dataclass
class Perturbation:
    dq: dict = field(default_factory=dict)          # actuated joint -> added value (rad or mm)
    post: dict = field(default_factory=dict)        # serial joint -> local 4x4 after its motion
    E: np.ndarray = field(default_factory=lambda: np.eye(4))   # base-frame map of target points
    E_rot: np.ndarray = field(default_factory=lambda: np.eye(3))  # its action on orientations
    meas_scale: float = 1.0                          # tracker frame: m -> scale m + shift
    meas_shift: np.ndarray = field(default_factory=lambda: np.zeros(3))


def _scaled(q, rng):
    lo, hi = rng
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    return (q - mid) / half, half


def _rigid(E):
    return E, E[:3, :3].copy()


def apply(name, p, ctx):
    out = Perturbation()
    qa, T = ctx["qa"], ctx["T"]
    dT = T - 20.0
    if name == "none":
        return out
    per = p.get("per", {})
    # ---- in the library -------------------------------------------------------------------------
    if name == "angle-harmonic":
        k = p["k"]
        for j, (a, b) in per.items():
            out.dq[j] = a * np.sin(k * qa[j]) + b * np.cos(k * qa[j])
    elif name == "offset":  # self-check only: a constant joint offset, which the rigid fit absorbs
        for j, c in per.items():
            out.dq[j] = c
    elif name in ("angle-scale", "screw-pitch"):
        for j, s in per.items():
            out.dq[j] = s * qa[j]
    elif name == "screw-periodic":
        period = p.get("lead", DEFAULT_LEAD) / p.get("order", 1)
        for j, (a, b) in per.items():
            w = 2 * np.pi * qa[j] / period
            out.dq[j] = a * np.sin(w) + b * np.cos(w)
    elif name == "backlash":
        for j, beta in per.items():
            out.dq[j] = -0.5 * beta * ctx["dir"][j]
    elif name in ("backlash-gravity", "joint-clearance"):
        for j, beta in per.items():
            out.dq[j] = 0.5 * beta * np.sign(ctx["tau"][j])
    elif name == "compliance":
        for j, c in per.items():
            out.dq[j] = c * ctx["tau"][j]
    elif name == "link-bending":
        for a, (b, c) in per.items():
            out.dq[a] = out.dq.get(a, 0.0) + 2.0 / 3.0 * c * ctx["tau"][a]
            out.dq[b] = out.dq.get(b, 0.0) + 1.0 / 3.0 * c * ctx["tau"][a]
    elif name == "leg-thermal":
        for j, kappa in per.items():
            out.dq[j] = kappa * dT * qa[j]
    elif name == "thermal":
        s = 1.0 + p["kappa"] * dT
        out.E = np.diag([s, s, s, 1.0])
    elif name == "tracker-drift":
        sh = p["shift"].get(str(ctx["session"]))
        if sh is not None:
            out.meas_shift = np.asarray(sh, float)
    elif name == "base-deformation":
        c1, c2 = p["c"]
        M = ctx["M"]
        theta = np.array([c1 * M[0], c2 * M[1], 0.0])  # e1 = x, e2 = y of the base (gravity -z)
        out.E, out.E_rot = _rigid(rot_about_line(np.zeros(3), theta if np.linalg.norm(theta) > 0
                                                 else np.array([1.0, 0, 0]), np.linalg.norm(theta)))
    elif name == "guide-straightness":
        for j, (cx, cy) in per.items():
            s, h = _scaled(qa[j], ctx["ranges"][j])
            fp = -2.0 * s / h
            L = np.eye(4)
            L[0, 3] = cx * (1 - s * s)
            L[1, 3] = cy * (1 - s * s)
            wy, wx = cx * fp, -cy * fp
            from .machine import rotvec_to_R
            L[:3, :3] = rotvec_to_R(np.array([wx, wy, 0.0]))
            out.post[j] = L
    # ---- out of the library (own ideas) ---------------------------------------------------------
    elif name == "guide-twist":
        # the bridge rolls about its own travel axis, linearly along the travel
        j = p["joint"]
        s, _ = _scaled(qa[j], ctx["ranges"][j])
        F = ctx["frames"][j]
        out.E, out.E_rot = _rigid(rot_about_line(F[:3, 3], F[:3, 2], p["eps"] * s))
    elif name == "bridge-yaw":
        # the saddle's weight off the bridge's middle makes the two drives of the bridge lag apart:
        # the bridge (and all it carries) turns about the vertical by c times the saddle's position
        s, _ = _scaled(qa[p["src"]], ctx["ranges"][p["src"]])
        F = ctx["frames"][p["joint"]]
        out.E, out.E_rot = _rigid(rot_about_line(F[:3, 3] + np.asarray(p["centre"], float),
                                                 [0, 0, 1.0], p["c"] * s))
    elif name == "tracker-weather":
        # the tracker's air compensation is off: its distances scale with the air temperature,
        # about the tracker's own origin
        out.meas_scale = 1.0 + p["k"] * dT
    elif name in ("hose-wind", "wrist-coupling"):
        # a dress pack wound by one axis pulls another (hose-wind), or a differential wrist's
        # uncompensated coupling ratio (wrist-coupling): dq_joint = c q_src
        out.dq[p["joint"]] = p["c"] * qa[p["src"]]
    elif name == "ram-bending":
        # the ram bends as a cantilever under the head's moment: the ram end turns about a line
        # through the saddle's guide, parallel to the A axis, by c tau_A (L0 + q_ram)
        j, a = p["ram"], p["head"]
        F3, F5 = ctx["frames"][j], ctx["frames"][a]
        L = p["L0"] + qa[j]
        pivot = F3[:3, 3] - qa[j] * F3[:3, 2]
        out.E, out.E_rot = _rigid(rot_about_line(pivot, F5[:3, 2], p["c"] * ctx["tau"][a] * L))
    elif name == "skew-thermal":
        # the bridge's squareness to its rails changes with the temperature (a steel bridge on an
        # aluminium-framed rail): the point shifts along x by c (T - 20) (q_y - mid)
        s, h = _scaled(qa[p["src"]], ctx["ranges"][p["src"]])
        E = np.eye(4)
        E[0, 3] = p["c"] * dT * s * h
        out.E = E
    elif name == "belt-load":
        # joint 3 driven through a belt from a motor behind joint 2: the belt stretches with the
        # shoulder's load, dq_3 = c tau_2
        out.dq[p["joint"]] = p["c"] * ctx["tau"][p["src"]]
    elif name == "absolute-harmonic":
        # a belt pulley turning with the forearm's absolute angle: dq_3 = a sin(q2 + q3 + phi)
        s = sum(qa[j] for j in p["sum"])
        out.dq[p["joint"]] = p["a"] * np.sin(s + p["phase"])
    elif name == "table-tilt-thermal":
        # the table (frame) under the machine bends as it warms unevenly: a tilt about the base x
        out.E, out.E_rot = _rigid(rot_about_line(np.asarray(p.get("point", [0, 0, 0]), float),
                                                 [1.0, 0, 0], p["c"] * dT))
    elif name == "race-wobble":
        # an oval bearing race: the joint's body tilts about a direction fixed in its carrier,
        # twice per turn of the joint
        j = p["joint"]
        F = ctx["frames"][j]
        v = qa[j]
        xfix = F[:3, :3] @ np.array([np.cos(-v), np.sin(-v), 0.0])
        ang = p["a"] * np.sin(2 * v + p["phase"])
        out.E, out.E_rot = _rigid(rot_about_line(F[:3, 3], xfix, ang))
    elif name == "passive-drag":
        # a leg's screw nut dragged by the turn of a passive joint at its end: dq_leg = c q_passive
        out.dq[p["joint"]] = p["c"] * ctx["qfull"][p["src"]]
    elif name == "holder-sag":
        # the reflector holder on the gripper sags straight down with the payload's weight
        E = np.eye(4)
        E[2, 3] = -p["c"] * ctx["payload"]
        out.E = E
    else:
        raise ValueError(f"unknown effect {name!r}")
    return out


__all__ = ["apply", "Perturbation", "LIBRARY", "OUT"]
