"""The effects put into the virtual machines of the eleventh blind generator (directory ``blind9``).

Units: mm, rad, degC, s, kg, N (prismatic loads), N mm (revolute loads).  Source-blind: the library
effects are written from the equations of ``docs/diagnosis.md`` ("The effects library"); the
out-of-library effects are this generator's own physical ideas (``RULES.md`` lists them).

Every effect is a dict ``{"name": ..., **parameters}`` read by :func:`apply`, which returns the
parts of a pose it changes:

* ``dq``: {actuated joint: change of the true joint value against the file's value} (mm or rad);
* ``post``: {joint: 4x4 local transform after the joint's motion} (serial chains only: a bowed guide,
  a dent in a rail, an axial run-out);
* ``out``: a 4x4 transform in the output frame (the tool grows, the platform turns);
* ``base``: a function (p, R, ctx) -> (p, R) on a target's base-frame position and orientation;
* ``meas``: a function (m, ctx) -> m on a position measured in the tracker frame.

``ctx`` (one pose): ``q`` (file values, model units), ``dir``, ``T`` (degC), ``payload`` (kg),
``session`` (1..4), ``ts`` (s since the session's start), ``tau`` (true gravity loads), ``M`` (base
moment of the true masses, N mm), ``s`` (travel of each prismatic joint scaled to [-1, 1]),
``legdir`` (parallel machines: each leg's unit direction, base frame), ``tracker`` (o, R), ``Rout``.
"""
from __future__ import annotations

import numpy as np

from tests.solver.diagnosis.blind7.kin import rotvec_to_R

LIBRARY = {"compliance", "link-bending", "thermal", "screw-pitch", "screw-periodic", "angle-scale",
           "angle-harmonic", "backlash", "backlash-gravity", "tracker-drift", "leg-thermal",
           "guide-straightness", "joint-clearance", "base-deformation"}
OUT_OF_LIBRARY = {"balancer-spring", "rail-dent-pitch", "worn-screw-play", "spindle-growth", "axial-runout",
                  "smr-incidence", "platform-twist-thermal", "payload-tilt", "carriage-rock"}


def _T(R=None, p=None):
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if p is not None:
        T[:3, 3] = p
    return T


def apply(eff, ctx):
    """The parts of one pose that ``eff`` changes (see the module docstring)."""
    if eff is None:
        return {}
    n = eff["name"]
    per = eff.get("per", {})
    q, T, dT = ctx["q"], ctx["T"], ctx["T"] - 20.0
    out = {}
    if n == "angle-harmonic":
        k = eff["k"]
        out["dq"] = {j: a * np.sin(k * q[j]) + b * np.cos(k * q[j]) for j, (a, b) in per.items()}
    elif n in ("angle-scale", "screw-pitch"):
        out["dq"] = {j: s * q[j] for j, s in per.items()}
    elif n == "screw-periodic":
        lead = eff.get("lead", 10.0)
        w = 2 * np.pi * eff["order"] / lead
        out["dq"] = {j: a * np.sin(w * q[j]) + b * np.cos(w * q[j]) for j, (a, b) in per.items()}
    elif n == "backlash":
        out["dq"] = {j: -b / 2 * ctx["dir"][j] for j, b in per.items()}
    elif n in ("backlash-gravity", "joint-clearance"):
        out["dq"] = {j: b / 2 * np.sign(ctx["tau"][j]) for j, b in per.items()}
    elif n == "compliance":
        out["dq"] = {j: c * ctx["tau"][j] for j, c in per.items()}
    elif n == "link-bending":
        dq = {}
        for a, (b, c) in per.items():
            dq[a] = dq.get(a, 0.0) + 2.0 / 3.0 * c * ctx["tau"][a]
            dq[b] = dq.get(b, 0.0) + 1.0 / 3.0 * c * ctx["tau"][a]
        out["dq"] = dq
    elif n == "leg-thermal":
        out["dq"] = {j: k * dT * q[j] for j, k in per.items()}
    elif n == "thermal":
        kap = eff["kappa"]
        out["base"] = lambda p, R, c: ((1 + kap * (c["T"] - 20.0)) * p, R)
    elif n == "tracker-drift":
        sh = {int(s): np.asarray(v, float) for s, v in eff["shift"].items()}
        out["meas"] = lambda m, c: m + sh.get(c["session"], 0.0)
    elif n == "base-deformation":
        c1, c2 = eff["c"]

        def base(p, R, c):
            th = np.array([c1 * c["M"][0], c2 * c["M"][1], 0.0])
            return p + np.cross(th, p), rotvec_to_R(th) @ R
        out["base"] = base
    elif n == "guide-straightness":
        post = {}
        for j, (cx, cy) in per.items():
            s, h = ctx["s"][j], ctx["half"][j]
            f, fp = 1 - s * s, -2 * s / h
            R = rotvec_to_R([0.0, cx * fp, 0.0]) @ rotvec_to_R([-cy * fp, 0.0, 0.0])
            post[j] = _T(R, [cx * f, cy * f, 0.0])
        out["post"] = post
    # ---- out of the library (own ideas) ----
    elif n == "balancer-spring":
        # a gas-spring balancer between the link and a pivot behind the joint: the spring force
        # follows its length, the unbalanced part bends the gear: dq = c (L(q) - L0)
        j, c, r1, r2, phi = eff["joint"], eff["c"], eff["r1"], eff["r2"], eff["phi"]
        L = np.sqrt(r1 ** 2 + r2 ** 2 - 2 * r1 * r2 * np.cos(q[j] + phi))
        out["dq"] = {j: c * (L - eff["L0"])}
    elif n == "rail-dent-pitch":
        # a dent in the rail: the carriage pitches about its own x as its rollers cross it
        j = eff["joint"]
        th = eff["a"] * np.exp(-(((q[j] - eff["q0"]) / eff["w"]) ** 2))
        out["post"] = {j: _T(rotvec_to_R([th, 0.0, 0.0]))}
    elif n == "worn-screw-play":
        # the screw is worn on one part of its stroke only: the play appears there
        j = eff["joint"]
        g = 1.0 / (1.0 + np.exp(-(ctx["s"][j] - eff["s0"]) / eff["w"]))
        out["dq"] = {j: -eff["beta"] / 2 * ctx["dir"][j] * g}
    elif n == "payload-tilt":
        # the platform's (flange's) joints yield under the payload's off-centre weight: the output
        # frame tilts about its own x axis by c * payload
        out["out"] = _T(rotvec_to_R([eff["c"] * ctx["payload"], 0.0, 0.0]))
    elif n == "carriage-rock":
        # a guide carriage rocks in its clearance to the side the last motion left it: turned
        # about its own x axis by c * dir_j
        j = eff["joint"]
        out["post"] = {j: _T(rotvec_to_R([eff["c"] * ctx["dir"][j], 0.0, 0.0]))}
    elif n == "strut-sag":
        # each leg sags under its own weight across its axis: its ends come closer by c sin^2(angle
        # of the leg to the vertical)
        out["dq"] = {j: -eff["c"] * (1 - ctx["legdir"][j][2] ** 2) for j in eff["legs"]}
    elif n == "spindle-growth":
        # the tool (spindle, flange extension) grows along the output z with the temperature
        d = eff["kappa"] * eff["L"] * dT
        out["out"] = _T(None, [0.0, 0.0, d])
    elif n == "platform-twist-thermal":
        th = eff["c"] * dT
        out["out"] = _T(rotvec_to_R([0.0, 0.0, th]))
    elif n == "axial-runout":
        # a bearing's axial run-out: the joint's body lifts along its axis once per turn
        j = eff["joint"]
        out["post"] = {j: _T(None, [0.0, 0.0, eff["a"] * np.sin(q[j] + eff["phase"])])}
    elif n == "arm-droop":
        # the radial arm droops under its own weight as it extends: the tip drops by c L^2 along
        # gravity and tilts by 2 c L (L the arm's overhang, mm)
        j = eff["joint"]
        L = eff["L0"] + q[j]
        Rj = ctx["jframes"][j][:3, :3]
        g = Rj.T @ np.array([0.0, 0.0, -1.0])
        z = np.array([0.0, 0.0, 1.0])
        g = g - (g @ z) * z
        g = g / np.linalg.norm(g)
        R = rotvec_to_R(np.cross(z, g) * 2 * eff["c"] * L)
        out["post"] = {j: _T(R, g * eff["c"] * L * L)}
    elif n == "smr-incidence":
        # a glass-prism reflector's range error grows with the beam's incidence on its axis (the
        # nest's normal, the output frame's z): along the beam by c (1 - cos theta)
        c0 = eff["c"]

        def base(p, R, c):
            o_t = c["tracker"][0]
            b = p - o_t
            b = b / np.linalg.norm(b)
            nrm = c["Rout"][:, 2]
            cos = abs(float(b @ nrm))
            return p + c0 * (1 - cos) * b, R
        out["base"] = base
    elif n == "offset":  # self-checks only: a constant joint offset, absorbed by the rigid fit
        out["dq"] = {eff["joint"]: eff["value"]}
    else:
        raise ValueError(f"unknown effect {n}")
    return out


def effect_joints(eff):
    """The joints the truth names (for the 'right joint' column), or []."""
    if eff is None:
        return []
    if "per" in eff:
        return sorted(eff["per"].keys())
    return []


def library_name(eff):
    """The name of the library effect as the docs write it (angle-harmonic-<k>)."""
    if eff["name"] == "angle-harmonic":
        k = eff["k"]
        return f"angle-harmonic-{k:g}"
    return eff["name"]


def scaled(eff, f):
    """A copy of ``eff`` with its amplitude parameters multiplied by ``f`` (visibility tuning)."""
    import copy
    e = copy.deepcopy(eff)
    if "per" in e:
        for j, v in e["per"].items():
            if isinstance(v, list):
                e["per"][j] = [v[0], v[1] * f] if isinstance(v[0], str) else [x * f for x in v]
            else:
                e["per"][j] = v * f
    for key in ("kappa", "c", "a", "beta"):
        if key in e:
            e[key] = [x * f for x in e[key]] if isinstance(e[key], list) else e[key] * f
    if "shift" in e:
        e["shift"] = {s: [x * f for x in v] for s, v in e["shift"].items()}
    return e


__all__ = ["apply", "effect_joints", "library_name", "scaled", "LIBRARY", "OUT_OF_LIBRARY"]
