"""Effects put into the virtual machines of the ninth blind generator (numpy only).

Units: mm, rad, °C, s, kg, N.  In the library: the equations of ``docs/diagnosis.md`` ("The
effects library"), written from the docs.  Out of the library: this generator's own physical
ideas (none is a library effect's equation).  Each effect is ``apply(ctx) -> Mod``:

* ``ctx``: the pose's context (``q`` actuated values in model units, ``T`` temperature, ``payload``,
  ``dir`` per joint, ``t`` operating time s, ``session``, ``k`` pose index, ``hist`` per-joint history
  state, ``grav`` a callable giving the generalized gravity forces, ``moment`` the base moment);
* ``Mod``: ``dq`` (actuated corrections), ``point`` (base-frame point map), ``meas`` (tracker-frame
  measurement map), ``rot`` (rotation applied to the measured orientation, base frame).
"""
from __future__ import annotations

import numpy as np

G = 9.81  # m/s^2


class Mod:
    def __init__(self):
        self.dq = {}
        self.point = None  # f(p_base, ctx) -> p_base'
        self.meas = None   # f(m_tracker, ctx) -> m'
        self.target_scale = None  # f(offset (3,), ctx) -> offset'
        self.out_rot = None  # f(ctx) -> angle (rad) the tool turns about the output frame's z

    def add(self, j, v):
        self.dq[j] = self.dq.get(j, 0.0) + v


# --- in the library (docs/diagnosis.md) ------------------------------------------------------

def harmonic(ctx, p):
    m = Mod()
    k = p["k"]
    for j, (a, b) in p["per"].items():
        q = ctx["q"][j]
        m.add(j, a * np.sin(k * q) + b * np.cos(k * q))
    return m


def scale(ctx, p):
    m = Mod()
    for j, s in p["per"].items():
        m.add(j, s * ctx["q"][j])
    return m


def screw_pitch(ctx, p):
    return scale(ctx, p)


def screw_periodic(ctx, p):
    m = Mod()
    period = 10.0 / p.get("order", 1)  # no lead declared: the docs' 10 mm
    for j, (a, b) in p["per"].items():
        q = ctx["q"][j]
        m.add(j, a * np.sin(2 * np.pi * q / period) + b * np.cos(2 * np.pi * q / period))
    return m


def backlash(ctx, p):
    m = Mod()
    for j, beta in p["per"].items():
        m.add(j, -beta / 2 * ctx["dir"][j])
    return m


def leg_thermal(ctx, p):
    m = Mod()
    for j, kap in p["per"].items():
        m.add(j, kap * (ctx["T"] - 20.0) * ctx["q"][j])
    return m


def thermal(ctx, p):
    m = Mod()
    kap = p["kappa"]
    m.point = lambda x, c: (1 + kap * (c["T"] - 20.0)) * x
    return m


def tracker_drift(ctx, p):
    m = Mod()
    s = np.array(p["shift"], float)
    m.meas = lambda x, c: x + (s if c["session"] >= 2 else 0.0)
    return m


def tracker_scale(ctx, p):
    m = Mod()
    s = p["s"]
    m.meas = lambda x, c: (1 + s) * x
    return m


def compliance(ctx, p):
    m = Mod()
    tau = ctx["grav"]()
    for j, c in p["per"].items():
        m.add(j, c * tau[j])
    return m


def link_bending(ctx, p):
    """link between parallel revolutes a, b: dq_a += 2/3 c tau_a, dq_b += 1/3 c tau_a."""
    m = Mod()
    tau = ctx["grav"]()
    for a, (b, c) in p["per"].items():
        m.add(a, 2.0 / 3.0 * c * tau[a])
        m.add(b, 1.0 / 3.0 * c * tau[a])
    return m


def backlash_gravity(ctx, p):
    m = Mod()
    tau = ctx["grav"]()
    for j, beta in p["per"].items():
        m.add(j, beta / 2 * np.sign(tau[j]))
    return m


def base_deformation(ctx, p):
    m = Mod()
    M = ctx["moment"]()  # N mm, base frame
    c1, c2 = p["c"]
    th = np.array([c1 * M[0], c2 * M[1], 0.0])
    m.point = lambda x, c: x + np.cross(th, x)
    return m


# --- out of the library (own ideas) ----------------------------------------------------------

def crosstalk(ctx, p):
    """A motor's magnetic field reaches another joint's (magnetic) encoder: joint ``joint`` reads
    wrong by ``a sin(q_src + phase)``, periodic in ANOTHER joint's angle."""
    m = Mod()
    m.add(p["joint"], p["a"] * np.sin(ctx["q"][p["src"]] + p["phase"]))
    return m


def screw_curvature(ctx, p):
    """A ball screw whose lead error is quadratic along its travel (a screw ground with a drift
    of its lead): ``dq = c (s^2 - 1/3)``, ``s`` the travel scaled to [-1, 1]."""
    m = Mod()
    s = (ctx["q"][p["joint"]] - p["mid"]) / p["half"]
    m.add(p["joint"], p["c"] * (s * s - 1.0 / 3.0))
    return m


def tool_growth(ctx, p):
    """The tool (an aluminium extension of length L along the output frame's z) grows with the
    air temperature: every target offset's z grows by ``kappa (T - 20) L``; the joints, the
    structure and the tracker are unchanged."""
    m = Mod()
    d = p["kappa"] * p["L"]
    m.target_scale = lambda off, c: off + np.array([0.0, 0.0, d * (c["T"] - 20.0)])
    return m


def motor_heating(ctx, p):
    """A leg's own motor heats its screw with the work it does: heat state
    ``H_k = H_{k-1} exp(-dt / tau) + |move_k|`` (mm of travel), the leg longer by ``c H_k``."""
    m = Mod()
    m.add(p["joint"], p["c"] * ctx["hist"]["heat"][p["joint"]])
    return m


def beam_bending(ctx, p):
    """The tracker's beam bends in a vertical air-temperature gradient: the measured point is
    high by ``k d_h^2`` (mm, ``d_h`` the horizontal distance to the tracker in m)."""
    m = Mod()
    k = p["k"]

    def f(x, c):
        dh = np.linalg.norm((x - c["tracker_o"])[:2]) / 1000.0
        return x + np.array([0.0, 0.0, k * dh * dh])
    m.point = f
    return m


def hose_stiffening(ctx, p):
    """A dress pack (hoses, cables) that stiffens as it is twisted: its torque grows with the cube
    of the joint's excursion from the hose's neutral angle; the joint deflects by
    ``dq = c ((q - mid) / half)^3`` (rad)."""
    m = Mod()
    s = (ctx["q"][p["joint"]] - p["mid"]) / p["half"]
    m.add(p["joint"], p["c"] * s ** 3)
    return m


def payload_twist(ctx, p):
    """A tool changer whose locking ring yields under the payload's off-centre weight: the tool
    turns about the output frame's z by ``c * payload`` (rad/kg)."""
    m = Mod()
    m.out_rot = lambda c_: c_["payload"] * p["c"]
    return m


def spline_coupling(ctx, p):
    """SCARA ball-screw spline: turning joint 4 moves the quill by a part of the spline's lead
    the controller does not compensate: ``dq3 = c q4`` (mm per rad)."""
    m = Mod()
    m.add(p["joint"], p["c"] * ctx["q"][p["src"]])
    return m


def zero_creep(ctx, p):
    """An encoder's zero creeps with the machine's operating time: ``dq = r t_op`` (t_op in h)."""
    m = Mod()
    m.add(p["joint"], p["r"] * ctx["t_op"] / 3600.0)
    return m


def joint_zero_thermal(ctx, p):
    """A joint's encoder mount moves with the temperature: ``dq = c (T - 20)`` (one joint of a
    serial arm, rad/°C)."""
    m = Mod()
    m.add(p["joint"], p["c"] * (ctx["T"] - 20.0))
    return m


EFFECTS = {
    "angle-harmonic": harmonic, "angle-scale": scale, "screw-pitch": screw_pitch,
    "screw-periodic": screw_periodic, "backlash": backlash, "leg-thermal": leg_thermal,
    "thermal": thermal, "tracker-drift": tracker_drift, "tracker-scale": tracker_scale,
    "compliance": compliance, "link-bending": link_bending, "backlash-gravity": backlash_gravity,
    "base-deformation": base_deformation,
    "crosstalk": crosstalk, "screw-curvature": screw_curvature, "tool-growth": tool_growth,
    "motor-heating": motor_heating, "beam-bending": beam_bending, "spline-coupling": spline_coupling,
    "zero-creep": zero_creep, "hose-stiffening": hose_stiffening, "payload-twist": payload_twist, "joint-zero-thermal": joint_zero_thermal,
}

GRAVITY = {"compliance", "link-bending", "backlash-gravity", "base-deformation"}
