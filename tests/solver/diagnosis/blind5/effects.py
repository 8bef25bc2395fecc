"""The effects this generator puts into its virtual machines (numpy only, own implementations).

Units: mm, rad, degC, s.  In-library effects follow the equations of docs/diagnosis.md ("The
effects library"), written from that table only; out-of-library effects are this generator's
own physical ideas, none of them in that table.

Every effect acts through some of these hooks, called per pose with a context ``ctx`` (dict:
``qa`` commanded actuated values, ``T`` temperature degC, ``t`` time s, ``session``, ``dir``
dict joint -> +-1, ``model``):

* ``dq(ctx)`` -> dict joint -> added value (the joint's true value is the file's plus this);
* ``extra(ctx)`` -> dict joint -> 4x4 transform after the joint's motion (a bowed guide);
* ``base_point(ctx, p, k, fr)`` -> point of target k in the base frame, moved;
* ``tracker_point(ctx, m)`` -> point in the tracker frame, moved (the instrument's own errors).
"""
from __future__ import annotations

import numpy as np

from .kin import hom, rot_vec


class Effect:
    name = "none"
    library = False

    def __init__(self, **p):
        self.p = p

    def dq(self, ctx):
        return {}

    def extra(self, ctx):
        return {}

    def base_point(self, ctx, p, k, fr):
        return p

    def tracker_point(self, ctx, m):
        return m


# ----------------------------------------------------------------------------- in the library
class LegThermal(Effect):
    """leg-thermal: dq_j = kappa_j (T - 20) q_j on the legs (parallel machines)."""
    name, library = "leg-thermal", True

    def dq(self, ctx):
        return {j: k * (ctx["T"] - 20.0) * ctx["qa"][j] for j, k in self.p["kappa"].items()}


class ScrewPitch(Effect):
    """screw-pitch: dq_j = s_j q_j."""
    name, library = "screw-pitch", True

    def dq(self, ctx):
        return {j: s * ctx["qa"][j] for j, s in self.p["s"].items()}


class ScrewPeriodic(Effect):
    """screw-periodic: dq_j = a sin(2 pi q / lead) + b cos(2 pi q / lead), lead 10 mm (none declared)."""
    name, library = "screw-periodic", True

    def dq(self, ctx):
        lead = self.p.get("lead", 10.0)
        out = {}
        for j, (a, b) in self.p["ab"].items():
            ph = 2 * np.pi * ctx["qa"][j] / lead
            out[j] = a * np.sin(ph) + b * np.cos(ph)
        return out


class AngleScale(Effect):
    """angle-scale: dq_j = s_j q_j on revolutes."""
    name, library = "angle-scale", True

    def dq(self, ctx):
        return {j: s * ctx["qa"][j] for j, s in self.p["s"].items()}


class AngleHarmonic(Effect):
    """angle-harmonic-<k>: dq_j = a sin(k q_j) + b cos(k q_j)."""
    library = True

    def __init__(self, **p):
        super().__init__(**p)
        k = p["k"]
        self.name = "angle-harmonic-%s" % (int(k) if float(k).is_integer() else k)

    def dq(self, ctx):
        k = self.p["k"]
        return {j: a * np.sin(k * ctx["qa"][j]) + b * np.cos(k * ctx["qa"][j])
                for j, (a, b) in self.p["ab"].items()}


class Backlash(Effect):
    """backlash: dq_j = -beta_j / 2 * dir_j (the load lags the drive)."""
    name, library = "backlash", True

    def dq(self, ctx):
        return {j: -b / 2.0 * ctx["dir"][j] for j, b in self.p["beta"].items()}


class Thermal(Effect):
    """thermal: the whole structure grows about the base origin, p -> p + kappa (T - 20) p."""
    name, library = "thermal", True

    def base_point(self, ctx, p, k, fr):
        return p + self.p["kappa"] * (ctx["T"] - 20.0) * p


class TrackerScale(Effect):
    """tracker-scale: the measurement scaled, m -> (1 + s) m (tracker frame)."""
    name, library = "tracker-scale", True

    def tracker_point(self, ctx, m):
        return (1.0 + self.p["s"]) * m


class TrackerDrift(Effect):
    """tracker-drift: a translation of the measurements in every session after the first."""
    name, library = "tracker-drift", True

    def tracker_point(self, ctx, m):
        return m + np.asarray(self.p["shift"]) * (ctx["session"] - 1)


class GuideStraightness(Effect):
    """guide-straightness: the prismatic joint's moving frame on a bowed guide.

    Displaced by c (1 - s^2) along the joint frame's x (resp. y), turned by the slope
    (c_x f' about y, -c_y f' about x, f' = -2 s / h), s = (q - q_mid) / h over the declared range.
    """
    name, library = "guide-straightness", True

    def extra(self, ctx):
        out = {}
        model = ctx["model"]
        for j, (cx, cy) in self.p["c"].items():
            lo, hi = model.ranges[j]
            qm, h = (lo + hi) / 2.0, (hi - lo) / 2.0
            s = (ctx["qa"][j] - qm) / h
            fp = -2.0 * s / h
            w = np.array([-cy * fp, cx * fp, 0.0])
            out[j] = hom(rot_vec(w), [cx * (1 - s * s), cy * (1 - s * s), 0.0])
        return out


# ----------------------------------------------------------------------------- out of the library
class CableDrag(Effect):
    """A leg's length error driven by another joint (a cable chain pulling on the leg's nut as the
    wrist turns): dq_leg = a sin(q_drive).  Not a joint's own error, not in the library."""
    name = "cable-drag"

    def dq(self, ctx):
        return {self.p["leg"]: self.p["a"] * np.sin(ctx["qa"][self.p["drive"]])}


class ToolSag(Effect):
    """The tool droops along gravity (-z of the base) by d sin^2(q_tilt) (1 + cos q_turn) / 2: a
    cantilever sag that depends on the wrist's attitude.  Moves the points only."""
    name = "tool-sag"

    def base_point(self, ctx, p, k, fr):
        qa = ctx["qa"]
        f = np.sin(qa[self.p["tilt"]]) ** 2 * (1 + np.cos(qa[self.p["turn"]])) / 2.0
        return p + np.array([0.0, 0.0, -self.p["d"] * f])


class SlidingNest(Effect):
    """One reflector's nest slides in the tool frame with the wrist angle: offset
    + u * a sin(q_drive) along the tool frame direction u, for target index k only."""
    name = "sliding-nest"

    def base_point(self, ctx, p, k, fr):
        if k != self.p["target"]:
            return p
        r = fr[ctx["model"].output][:3, :3]
        return p + r @ (np.asarray(self.p["u"]) * self.p["a"] * np.sin(ctx["qa"][self.p["drive"]]))


class TrackerAzimuthHarmonic(Effect):
    """The tracker's azimuth encoder is eccentric: the horizontal angle of each measurement is off
    by e sin(az + phi) (rad), which moves the point sideways by its horizontal distance times it."""
    name = "tracker-azimuth-eccentric"

    def tracker_point(self, ctx, m):
        az = np.arctan2(m[1], m[0])
        da = self.p["e"] * np.sin(az + self.p.get("phi", 0.0))
        c, s = np.cos(da), np.sin(da)
        return np.array([c * m[0] - s * m[1], s * m[0] + c * m[1], m[2]])


class RefractionGradient(Effect):
    """An air-temperature gradient along the beam: a range error growing with the square of the
    distance, m -> m (1 + c d) with d the distance in m (c per m)."""
    name = "refraction-gradient"

    def tracker_point(self, ctx, m):
        d = np.linalg.norm(m) / 1000.0
        return m * (1.0 + self.p["c"] * d)


class QuadraticLead(Effect):
    """A screw whose lead error grows along the travel: dq_j = k (q_j - q_mid)^2 (a screw ground
    with a taper), not a constant pitch error and not periodic."""
    name = "quadratic-lead"

    def dq(self, ctx):
        j = self.p["joint"]
        lo, hi = ctx["model"].ranges[j]
        return {j: self.p["k"] * (ctx["qa"][j] - (lo + hi) / 2.0) ** 2}


class JointCoupling(Effect):
    """A joint's angle depends on another's (a cable or belt crossing the joint): dq_a = k q_b."""
    name = "cross-coupling"

    def dq(self, ctx):
        return {self.p["joint"]: self.p["k"] * ctx["qa"][self.p["from"]]}


class WarmUpDrift(Effect):
    """A joint's zero drifts as its motor warms up: dq_j = a (1 - exp(-t / tau)), with time, not
    with the measured air temperature."""
    name = "warm-up-drift"

    def dq(self, ctx):
        return {self.p["joint"]: self.p["a"] * (1 - np.exp(-ctx["t"] / self.p["tau"]))}


class GearDent(Effect):
    """A damaged tooth: a localised bump in a joint's error, dq = a exp(-((q - q0) / w)^2)."""
    name = "gear-dent"

    def dq(self, ctx):
        j = self.p["joint"]
        return {j: self.p["a"] * np.exp(-((ctx["qa"][j] - self.p["q0"]) / self.p["w"]) ** 2)}


EFFECTS = {c.name: c for c in [LegThermal, ScrewPitch, ScrewPeriodic, AngleScale, Backlash, Thermal,
                               TrackerScale, TrackerDrift, GuideStraightness, CableDrag, ToolSag,
                               SlidingNest, TrackerAzimuthHarmonic, RefractionGradient, QuadraticLead,
                               JointCoupling, WarmUpDrift, GearDent]}


def make(spec):
    """An effect from its spec dict ``{"effect": name, ...params}``; None for no effect."""
    if spec is None:
        return None
    spec = dict(spec)
    name = spec.pop("effect")
    if name == "angle-harmonic":
        return AngleHarmonic(**spec)
    return EFFECTS[name](**spec)
