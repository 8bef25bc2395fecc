"""The effects put into the virtual machines (own implementations, numpy only).

Units: mm, rad, °C, s, kg.  `c` is a Campaign (generate.py): per pose in measuring order
`q` (file values, dict), `temp`, `time`, `session`, `payload`, `dirs` (dict joint -> +-1),
`move` (dict joint -> the last move, file units).  An actuator effect returns `dq`: the joint
really sits at `q + dq` (docs/diagnosis.md, "The effects library": the load lags the drive, the
screw is longer, ...).  `base_motion` returns a rigid transform of the whole machine in the base
frame (4x4), `point` moves a measured point in the base frame, `meas` a measurement in the
tracker frame, `target` a target offset in the output frame.
"""
from __future__ import annotations

import numpy as np

from .kin import expm

__all__ = ["Effect", "IN_LIBRARY", "OUT_OF_LIBRARY"]


class Effect:
    kind = "in"
    name = ""

    def __init__(self, **p):
        self.p = p

    def joints(self):
        return sorted(self.p.get("per", {}).keys())

    def dq(self, c, k):
        return {}

    def base_motion(self, c, k):
        return None

    def point(self, c, k, p, T_out):
        return p

    def meas(self, c, k, m):
        return m

    def target(self, c, k, i, off):
        return off


# ----------------------------------------------------------------- in the library
class LegThermal(Effect):
    name = "leg-thermal"

    def dq(self, c, k):
        return {j: kap * (c.temp[k] - 20.0) * c.q[k][j] for j, kap in self.p["per"].items()}


class ScrewPitch(Effect):
    name = "screw-pitch"

    def dq(self, c, k):
        return {j: s * c.q[k][j] for j, s in self.p["per"].items()}


class ScrewPeriodic(Effect):
    name = "screw-periodic"

    def dq(self, c, k):
        period = self.p.get("lead", 10.0) / self.p.get("order", 1)
        out = {}
        for j, (a, b) in self.p["per"].items():
            x = 2 * np.pi * c.q[k][j] / period
            out[j] = a * np.sin(x) + b * np.cos(x)
        return out


class AngleScale(Effect):
    name = "angle-scale"

    def dq(self, c, k):
        return {j: s * c.q[k][j] for j, s in self.p["per"].items()}


class AngleHarmonic(Effect):
    @property
    def name(self):
        kk = self.p["k"]
        return "angle-harmonic-%g" % kk

    def dq(self, c, k):
        kk = self.p["k"]
        return {j: a * np.sin(kk * c.q[k][j]) + b * np.cos(kk * c.q[k][j]) for j, (a, b) in self.p["per"].items()}


class Backlash(Effect):
    name = "backlash"

    def dq(self, c, k):
        return {j: -beta / 2.0 * c.dirs[k][j] for j, beta in self.p["per"].items()}


class Thermal(Effect):
    name = "thermal"

    def point(self, c, k, p, T_out):
        return p * (1.0 + self.p["kappa"] * (c.temp[k] - 20.0))


class TrackerDrift(Effect):
    name = "tracker-drift"

    def meas(self, c, k, m):
        return m + np.asarray(self.p["shift"]) if c.session[k] >= 2 else m


IN_LIBRARY = {
    "leg-thermal": LegThermal, "screw-pitch": ScrewPitch, "screw-periodic": ScrewPeriodic,
    "angle-scale": AngleScale, "angle-harmonic": AngleHarmonic, "backlash": Backlash,
    "thermal": Thermal, "tracker-drift": TrackerDrift,
}


# ----------------------------------------------------------------- out of the library (own ideas)
class StepOffset(Effect):
    """A coupling slips once: joint `joint` is off by `size` from pose index `frac` x N on (not at a session change)."""
    kind, name = "out", "step-offset"

    def dq(self, c, k):
        return {self.p["joint"]: self.p["size"] if k >= int(self.p["frac"] * c.n) else 0.0}


class ToolFlex(Effect):
    """The tool bends under the payload: points drop along -z (base) by c x payload x the tool axis' horizontal share."""
    kind, name = "out", "tool-flex"

    def point(self, c, k, p, T_out):
        e = T_out[:3, int(self.p.get("axis", 2))]
        lever = np.sqrt(max(0.0, 1.0 - e[2] ** 2))
        return p - np.array([0, 0, self.p["c"] * c.payload[k] * lever])


class CablePull(Effect):
    """A cable going taut: joint `joint` pulled by a tanh of joint `src`'s travel from its middle."""
    kind, name = "out", "cable-pull"

    def dq(self, c, k):
        x = (c.q[k][self.p["src"]] - self.p["mid"]) / self.p["w"]
        return {self.p["joint"]: self.p["a"] * np.tanh(x)}


class StandTiltLag(Effect):
    """The machine's stand tilts with its own (lagging) temperature: about the base x axis, c (T_stand - 20),
    T_stand the air temperature through a first-order lag of time constant tau (s)."""
    kind, name = "out", "stand-tilt-lag"

    def base_motion(self, c, k):
        tau = self.p["tau"]
        Ts = c.temp[0]
        for i in range(1, k + 1):
            dt = c.time[i] - c.time[i - 1]
            a = 1 - np.exp(-dt / tau)
            Ts = Ts + a * (c.temp[i] - Ts)
        B = np.eye(4)
        B[:3, :3] = expm(np.asarray(self.p["axis"], float) * self.p["c"] * (Ts - 20.0))
        return B


class EncoderGlitch(Effect):
    """A dirty encoder track: joint `joint` reads `size` wrong inside [lo, hi] (smooth edges of width w)."""
    kind, name = "out", "encoder-glitch"

    def dq(self, c, k):
        x = c.q[k][self.p["joint"]]
        w = self.p["w"]
        s = 0.5 * (np.tanh((x - self.p["lo"]) / w) - np.tanh((x - self.p["hi"]) / w))
        return {self.p["joint"]: self.p["size"] * s}


class TravelHysteresis(Effect):
    """Friction hysteresis (Dahl-like): the lag grows with the length of the last move, -dir beta/2 (1 - exp(-|move|/lam))."""
    kind, name = "out", "travel-hysteresis"

    def dq(self, c, k):
        j = self.p["joint"]
        return {j: -self.p["beta"] / 2 * c.dirs[k][j] * (1 - np.exp(-abs(c.move[k][j]) / self.p["lam"]))}


class NestKnock(Effect):
    """Reflector nest `target` knocked at pose frac x N: its offset moves by `shift` (output frame) from then on."""
    kind, name = "out", "nest-knock"

    def target(self, c, k, i, off):
        if i == self.p["target"] and k >= int(self.p["frac"] * c.n):
            return off + np.asarray(self.p["shift"])
        return off


class BaseSettling(Effect):
    """Anchor bolts settling: the whole machine turns about the base z axis by c (1 - exp(-t/tau)) (t from the start)."""
    kind, name = "out", "base-settling"

    def base_motion(self, c, k):
        B = np.eye(4)
        ang = self.p["c"] * (1 - np.exp(-c.time[k] / self.p["tau"]))
        B[:3, :3] = expm(np.asarray(self.p.get("axis", [0, 0, 1.0])) * ang)
        B[:3, 3] = -B[:3, :3] @ np.asarray(self.p.get("pivot", [0, 0, 0.0])) + np.asarray(self.p.get("pivot", [0, 0, 0.0]))
        return B


OUT_OF_LIBRARY = {
    "step-offset": StepOffset, "tool-flex": ToolFlex, "cable-pull": CablePull,
    "stand-tilt-lag": StandTiltLag, "encoder-glitch": EncoderGlitch,
    "travel-hysteresis": TravelHysteresis, "nest-knock": NestKnock, "base-settling": BaseSettling,
}


def make(kind, **p):
    cls = IN_LIBRARY.get(kind) or OUT_OF_LIBRARY[kind]
    return cls(**p)
