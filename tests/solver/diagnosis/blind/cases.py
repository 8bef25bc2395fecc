"""The blind generator's case table: what each campaign contains and how its answer is judged.

Every case has a category (``none``, ``understated-noise``, ``in-library``,
``out-of-library``), the arms it runs on, its effects with realistic sizes (each drawn per
seed as the nominal size times a factor uniform in [0.7, 1], with a random sign or phase
where the physics allows one), its pose design, reflectors, metadata columns and units.
The judging rules are in RULES.md; the fields ``truth`` (in-library: the library name that
counts as right), ``accept`` (out-of-library: a library name that *is* the physics, e.g.
``link-bending`` for a bending link) and ``family`` (the physical family an equivalence set
must contain for an "explained, ambiguous" answer to be honest) feed them.

Joint indices are 0-based in the code (joint 2 of the text = index 1).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

# Families of library names (RULES.md).  ``angle-harmonic-*`` matches any order.
GRAVITY = ["compliance", "link-bending", "backlash-gravity", "gravity-deformation"]
GRAVITY_SIZED = ["compliance", "link-bending", "backlash-gravity"]   # need masses to be sized
TRANSMISSION = ["angle-scale", "angle-harmonic-*", "backlash", "backlash-gravity"]
PERIODIC = ["angle-harmonic-*"]
THERMAL = ["thermal"]


@dataclasses.dataclass
class Case:
    name: str
    category: str                       # none | understated-noise | in-library | out-of-library
    arms: Tuple[str, ...]
    effects: Callable[[str, np.random.Generator], Tuple[list, str]]   # -> (specs, size text)
    design: str = "full"
    targets: int = 1
    extension: bool = False             # reflector on a 300 mm tool extension
    payload: bool = False
    temperature: Optional[str] = None   # None | "ramp" | "arm"
    session: bool = False
    dirs: bool = False
    time: bool = False
    units: Tuple[str, str] = ("mm", "rad")
    masses: bool = True
    noise_factor: float = 1.0
    truth: Optional[str] = None         # in-library: the library name that is right
    truth_order: Optional[float] = None # in-library harmonic: its order
    accept: Tuple[str, ...] = ()        # out-of-library: library names that are the physics
    accept_order: Optional[float] = None
    family: Tuple[str, ...] = ()        # out-of-library: what an equivalence set must contain
    rule: str = ""                      # none | noise | in-library | out-of-library | no-mass
    note: str = ""

    def __post_init__(self):
        if not self.rule:
            self.rule = {"none": "none", "understated-noise": "noise", "in-library": "in-library",
                         "out-of-library": "out-of-library"}[self.category]


def _f(rng):
    """Size factor of a campaign: uniform in [0.7, 1]."""
    return float(rng.uniform(0.7, 1.0))


def _sign(rng):
    return float(rng.choice([-1.0, 1.0]))


def _phase(rng):
    return float(rng.uniform(0, 2 * math.pi))


def nothing(arm, rng):
    return [], "-"


def compliance(arm, rng):
    f = _f(rng)
    k = {"ind6": "K2 2.0e6, K3 1.2e6 N m/rad", "cobot6": "K2 1.5e5, K3 1.0e5 N m/rad"}[arm]
    return [("joint_compliance", {"factor": f})], f"joint stiffness {k} divided by {f:.2f}"


def thermal(arm, rng):
    a = 2.3e-5 * _f(rng)
    return [("thermal", {"alpha": a})], f"alpha {a:.2e} /degC (aluminium 2.3e-5), T 17->29 degC"


def scaled(effect, key, nominal, text, signed=False, **fixed):
    """A one-parameter effect: ``key`` = nominal x factor (x a random sign if ``signed``);
    ``text`` formats the drawn value ``v``."""
    def make(arm, rng):
        v = nominal * _f(rng) * (_sign(rng) if signed else 1.0)
        return [(effect, {**fixed, key: v})], text.format(v=v)
    return make


angle_scale_j3 = scaled("angle_scale", "s", 2e-4, "joint 3 scale {v:+.2e}", signed=True, joint=2)


def harmonic_on(joint, order, amp):
    def make(arm, rng):
        a = amp * _f(rng)
        return ([("harmonic", {"joint": joint, "order": order, "amplitude": a, "phase": _phase(rng)})],
                f"joint {joint + 1}: {a:.2e} rad at {order:g} cycles/rev")
    return make


backlash_j1 = scaled("backlash", "clearance", 4e-4, "joint 1 dead band {v:.2e} rad", joint=0)
gravity_backlash_j2 = scaled("gravity_backlash", "clearance", 4e-4, "joint 2 dead band {v:.2e} rad, gravity side", joint=1)


def tracker_drift(arm, rng):
    v = rng.normal(size=3)
    v *= 1e-4 * _f(rng) / np.linalg.norm(v)   # a tripod that settled or was brushed: ~0.1 mm
    return [("tracker_moved", {"shifts": {2: v}})], f"tracker moved {np.linalg.norm(v) * 1e6:.0f} um between sessions"


def bending(which, factor=1.0, torsion=False):
    def make(arm, rng):
        f = _f(rng) * factor
        kw = {"which": which, "bending": 0.0 if torsion else f, "torsion": f if torsion else 0.0}
        what = "torsion (GJ" if torsion else "bending (EI"
        return [("beam", kw)], f"{which}-arm {what} / {f:.2f})"
    return make


def base_tilt(arm, rng):
    f = _f(rng)
    return [("base_tilt", {"factor": f})], f"pedestal EI / {f:.2f}"


coupling_3_from_2 = scaled("coupling", "kappa", 3e-4, "joint 3 follows joint 2: {v:+.1e} rad/rad", signed=True,
                           joint=2, source=1)
coupling_5_from_4 = scaled("coupling", "kappa", 4e-4, "joint 5 follows joint 4: {v:+.1e} rad/rad", signed=True,
                           joint=4, source=3)
parallelogram_j3 = scaled("parallelogram", "rod_error", 3e-4, "joint-3 parallelogram rod {v:+.1e} of the crank",
                          signed=True, joint=2)


def dress_pack_j2(arm, rng):
    t = 12.0 * _f(rng) * _sign(rng)
    return ([("dress_pack", {"joint": 1, "torque": t, "centre": -1.57 + rng.uniform(-0.3, 0.3), "width": 0.4})],
            f"hose torque {t:+.1f} N m through K2")


tool_growth = scaled("tool_growth", "alpha", 2.3e-5, "500 mm aluminium extension, alpha {v:.2e} /degC", length=0.50)
upper_arm_growth = scaled("link_growth", "alpha", 2.3e-5, "upper arm alone, alpha {v:.2e} /degC (arm 20->36 degC)",
                          origin=2)


# The pose designs (rad): full working ranges, or joint 2 (and 3) over a 1.5 rad window.
DESIGNS: Dict[str, Dict[str, List[Tuple[float, float]]]] = {
    "full": {
        "ind6": [(-2.9, 2.9), (-1.2, 1.45), (-1.15, 1.5), (-2.9, 2.9), (-1.9, 1.9), (-2.9, 2.9)],
        "cobot6": [(-3.0, 3.0), (-3.0, 0.0), (-2.6, 2.6), (-3.0, 3.0), (-3.0, 3.0), (-3.0, 3.0)],
    },
    "short2": {
        "ind6": [(-2.9, 2.9), (-0.45, 1.05), (-1.15, 1.5), (-2.9, 2.9), (-1.9, 1.9), (-2.9, 2.9)],
        "cobot6": [(-3.0, 3.0), (-2.35, -0.85), (-2.6, 2.6), (-3.0, 3.0), (-3.0, 3.0), (-3.0, 3.0)],
    },
    "short23": {
        "ind6": [(-2.9, 2.9), (-0.45, 1.05), (-0.75, 0.75), (-2.9, 2.9), (-1.9, 1.9), (-2.9, 2.9)],
        "cobot6": [(-3.0, 3.0), (-2.35, -0.85), (0.2, 1.7), (-3.0, 3.0), (-3.0, 3.0), (-3.0, 3.0)],
    },
    "parallelogram": {
        "ind6": [(-2.9, 2.9), (-1.2, 1.45), (-1.0, 1.1), (-2.9, 2.9), (-1.9, 1.9), (-2.9, 2.9)],
    },
}

BOTH = ("ind6", "cobot6")

CASES: List[Case] = [
    # ------------------------------------------------------------------ noise only
    Case("none", "none", BOTH, nothing, note="geometric errors and the stated noise"),
    Case("none-3smr-meta", "none", BOTH, nothing, targets=3, payload=True, temperature="ramp",
         session=True, dirs=True, time=True, units=("m", "deg"),
         note="3 reflectors, every metadata column, lengths in m and angles in deg, no effect"),
    Case("none-short", "none", ("ind6",), nothing, design="short23", note="joints 2 and 3 over 1.5 rad"),
    Case("none-nomass", "none", BOTH, nothing, masses=False, note="URDF without <inertial>"),
    Case("noise-1.5x", "understated-noise", BOTH, nothing, noise_factor=1.5),
    Case("noise-2x-3smr", "understated-noise", BOTH, nothing, noise_factor=2.0, targets=3),
    Case("noise-1.7x-nomass", "understated-noise", ("cobot6",), nothing, noise_factor=1.7, masses=False),
    # ------------------------------------------------------------------ in the library
    Case("compliance", "in-library", BOTH, compliance, payload=True, truth="compliance"),
    Case("compliance-3smr", "in-library", ("ind6",), compliance, payload=True, targets=3, truth="compliance"),
    Case("compliance-short", "in-library", ("ind6",), compliance, payload=True, design="short23",
         truth="compliance", note="joints 2, 3 over 1.5 rad: may alias 1/rev harmonics or bending"),
    Case("thermal", "in-library", BOTH, thermal, temperature="ramp", time=True, truth="thermal"),
    Case("angle-scale-j3", "in-library", BOTH, angle_scale_j3, truth="angle-scale"),
    Case("harmonic1-j1", "in-library", BOTH, harmonic_on(0, 1, 1.2e-4), truth="angle-harmonic", truth_order=1,
         note="encoder eccentricity: 6 um on a 50 mm code-disc radius = 1.2e-4 rad"),
    Case("harmonic2-j1", "in-library", BOTH, harmonic_on(0, 2, 1.4e-4), truth="angle-harmonic", truth_order=2,
         note="strain-wave gear: 1 arcmin (2.9e-4 rad) peak-to-peak positioning accuracy (HD CSF catalogue)"),
    Case("harmonic3-j1", "in-library", BOTH, harmonic_on(0, 3, 1.2e-4), truth="angle-harmonic", truth_order=3,
         note="three-crank RV reducer; joint 1 over 5.8 rad: 2, 3 and 4 cycles/rev resolved"),
    Case("harmonic1-j2", "in-library", ("ind6",), harmonic_on(1, 1, 2e-4), truth="angle-harmonic", truth_order=1,
         note="1/rev of the shoulder (10 um eccentricity on a 50 mm code disc): may alias gravity effects"),
    Case("backlash-j1", "in-library", BOTH, backlash_j1, dirs=True, truth="backlash",
         note="lost motion ~1 arcmin (RV / strain-wave hysteresis loss) + wear"),
    Case("backlash-gravity-j2", "in-library", ("ind6",), gravity_backlash_j2, payload=True, truth="backlash-gravity"),
    Case("tracker-drift", "in-library", BOTH, tracker_drift, session=True, time=True, truth="tracker-drift"),
    Case("thermal-nomass", "in-library", ("cobot6",), thermal, temperature="ramp", time=True, masses=False,
         truth="thermal", note="an effect that needs no mass, on a model without masses"),
    # ------------------------------------------------------------------ out of the library
    Case("harmonic3-j2-short", "out-of-library", BOTH, harmonic_on(1, 3, 1.5e-4), design="short2",
         accept=("angle-harmonic",), accept_order=3, family=tuple(PERIODIC),
         note="3 cycles/rev over 1.5 rad: aliases 1 and 2 cycles/rev"),
    Case("harmonic1.5-j2-short", "out-of-library", ("ind6",), harmonic_on(1, 1.5, 2e-4), design="short2",
         accept=("angle-harmonic",), accept_order=1.5, family=tuple(PERIODIC),
         note="1.5 cycles/rev (a 2:3 intermediate gear) over 1.5 rad"),
    Case("upperarm-bending", "out-of-library", BOTH, bending("upper"), payload=True,
         accept=("link-bending",), family=tuple(GRAVITY)),
    Case("upperarm-bending-short", "out-of-library", ("ind6",), bending("upper", factor=2.0), design="short2",
         accept=("link-bending",), family=tuple(GRAVITY),
         note="no payload change, joint 2 over 1.5 rad: the issue's 'explained by angle-harmonic-1' case"),
    Case("forearm-bending", "out-of-library", ("cobot6",), bending("fore"), payload=True,
         accept=("link-bending",), family=tuple(GRAVITY), note="link after joint 3, next joint parallel"),
    Case("upperarm-torsion", "out-of-library", ("cobot6",), bending("upper", factor=2.0, torsion=True), payload=True,
         family=tuple(GRAVITY), note="twist about the upper-arm axis from the lateral offset of the forearm "
                                     "(GJ halved: tube plus the joint housings' flanges)"),
    Case("base-tilt", "out-of-library", BOTH, base_tilt, payload=True, family=tuple(GRAVITY),
         note="foundation / pedestal tilt under the overturning moment"),
    Case("coupling-3-from-2", "out-of-library", ("ind6",), coupling_3_from_2, family=tuple(TRANSMISSION)),
    Case("coupling-5-from-4", "out-of-library", ("ind6",), coupling_5_from_4, family=tuple(TRANSMISSION)),
    Case("parallelogram-j3", "out-of-library", ("ind6",), parallelogram_j3, design="parallelogram",
         family=tuple(TRANSMISSION), note="a nonlinear (1/cos q3) joint-3 error"),
    Case("dresspack-j2", "out-of-library", ("cobot6",), dress_pack_j2, family=tuple(TRANSMISSION) + ("compliance",),
         note="a saturating cable torque through the joint stiffness"),
    Case("tool-growth", "out-of-library", BOTH, tool_growth, temperature="ramp", time=True, extension=True,
         note="reflector on a 500 mm aluminium extension bar that grows along the tool axis",
         family=tuple(THERMAL)),
    Case("upperarm-growth", "out-of-library", ("ind6",), upper_arm_growth, temperature="arm", time=True,
         family=tuple(THERMAL), note="only the upper arm warms (motor heat); the column is its temperature"),
    Case("bending-3smr", "out-of-library", ("cobot6",), bending("upper"), payload=True, targets=3,
         accept=("link-bending",), family=tuple(GRAVITY)),
    Case("compliance-nomass", "out-of-library", BOTH, compliance, masses=False, rule="no-mass",
         family=tuple(GRAVITY), note="real joint compliance, URDF without masses: cannot be sized"),
    Case("bending-nomass", "out-of-library", ("ind6",), bending("upper", factor=1.5), masses=False, rule="no-mass",
         family=tuple(GRAVITY), note="upper-arm bending, URDF without masses"),
]

CASE_BY_NAME = {c.name: c for c in CASES}


def campaigns(seeds: int, names: Optional[List[str]] = None):
    """(case, arm, seed) of every campaign, in a fixed order."""
    out = []
    for c in CASES:
        if names and c.name not in names:
            continue
        for arm in c.arms:
            for s in range(seeds):
                out.append((c, arm, s))
    return out
