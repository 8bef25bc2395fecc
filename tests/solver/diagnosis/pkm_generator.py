"""A campaign generator for parallel machines (issue 40), written independently of hyperstat's effects and kinematics.

Units: lengths in mm, angles in rad, temperatures in degC, masses in kg, forces in N.

It imports nothing from hyperstat (numpy only).  It reads a model file (JSON,
``docs/model-format.md``) with its own parser, and assembles the machine with its own loop
solver: every chain's frames by its own 4x4 products (placement then the joint's motion), the
passive joints found by a Newton iteration on the closures (each chain that reaches a frame
another chain defined must reach it at the same pose), finite-difference Jacobians, batched
over the poses, continued from the home configuration.  Its true machine carries errors that
every assembly accommodates (leg length offsets, the serial wrist's placements, the base
joints of spherical legs; on a machine that is not over-constrained every placement), its own
laser tracker (twice the reach away, noise ``a + b d`` per axis as the header states), two
targets on the tool, campaign metadata (temperature drift, payloads, approach directions, two
sessions) and its own effects, the physics of ``docs/diagnosis.md`` written again:

in the library
    ``leg-thermal`` (each leg's length grows by ``alpha (T - 20) q``), ``screw-periodic`` (a
    ball screw's error once per turn of the screw), ``guide-straightness`` (a leg's carriage
    follows a bowed guide: an extra displacement and turn after its prismatic joint),
    ``joint-clearance`` (the platform joint sits on the side of its clearance the leg's force
    pushes it to, along the leg), ``base-deformation`` (the machine turns about the base origin
    under the moment of the moving mass's weight), ``compliance`` (legs yield under their
    force), ``backlash`` (a dead band crossed from the recorded direction);
out of the library
    ``tool-thermal`` (the tool grows along its axis with the temperature), ``wrist-coupling``
    (on a machine with a wrist: its second axis follows the first), ``stand-creep`` (the machine's
    stand tilts slowly with time about a horizontal axis through the base origin: a rigid motion of
    the machine relative to the tracker, as a drifting tracker gives), ``loose-nest`` (the reflector
    ``T2`` sits loosely in its nest: it settles by ``sag`` towards gravity across the nest's axis,
    with a seating scatter of a third of that from pose to pose; the other target is right), ``seat-sink`` (the seat
    of one leg, its base joint's mounting, sinks along the leg as the machine warms: that leg alone is longer by
    ``r (T - 18 degC)``, ``r`` in mm/degC, an offset that follows the temperature and not the leg's length);
noise cases
    ``none``, ``understated-noise`` (the tracker 1.6 times noisier than the header says).

The actuator forces under gravity come from the potential energy of the moving mass (the
declared ``metadata.moving_mass`` at ``metadata.com`` of the output frame, and the payload),
``f_a = -dV/dq_a`` by central differences through the loop solver.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["Machine", "IN_LIBRARY", "OUT_OF_LIBRARY", "NOISE_CASES", "MODELS", "campaign", "cases_for", "where_words"]

HERE = Path(__file__).resolve().parent
#: the templates' model files with a declared moving mass (kg, centre in the output frame, mm)
MODELS = {"tripteor_x7": HERE / "data" / "tripteor_x7.skel.json", "hexapod": HERE / "data" / "hexapod.skel.json"}

IN_LIBRARY = ("leg-thermal", "screw-periodic", "guide-straightness", "joint-clearance", "base-deformation",
              "compliance", "backlash", "tracker-drift")
OUT_OF_LIBRARY = ("tool-thermal", "wrist-coupling", "stand-creep", "loose-nest", "seat-sink")
NOISE_CASES = ("none", "understated-noise")
STATED_NOISE = (0.005, 0.005)  # mm, mm/m
G = np.array([0.0, 0.0, -9.81])
SIGMA_RAD = 5e-5  # rad, the orientation noise a 6-D campaign's header states (1 sigma per axis)
TARGETS = (np.array([10.0, -6.0, -20.0]), np.array([-8.0, 12.0, 80.0]))  # on the tool, output frame (mm)


def _rot(axis, angle: float) -> np.ndarray:
    axis = np.asarray(axis, float)
    n = np.linalg.norm(axis)
    if n == 0 or angle == 0:
        return np.eye(3)
    k = axis / n
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def _quaternion(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method, w >= 0)."""
    tr = np.trace(r)
    i = int(np.argmax([tr, r[0, 0], r[1, 1], r[2, 2]]))
    if i == 0:
        w = 0.5 * np.sqrt(1.0 + tr)
        q = np.array([w, (r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w), (r[1, 0] - r[0, 1]) / (4 * w)])
    else:
        a, b, c = i - 1, i % 3, (i + 1) % 3
        v = np.zeros(3)
        v[a] = 0.5 * np.sqrt(1.0 + r[a, a] - r[b, b] - r[c, c])
        v[b] = (r[b, a] + r[a, b]) / (4 * v[a])
        v[c] = (r[c, a] + r[a, c]) / (4 * v[a])
        q = np.r_[(r[c, b] - r[b, c]) / (4 * v[a]), v]
    return q if q[0] >= 0 else -q


def _placement(p: dict) -> np.ndarray:
    z, x = np.asarray(p["z_axis"], float), np.asarray(p["x_axis"], float)
    t = np.eye(4)
    t[:3, 0], t[:3, 1], t[:3, 2], t[:3, 3] = x, np.cross(z, x), z, p["origin"]
    return t


@dataclass
class Elem:
    name: str
    kind: str  # joint, fixed, frame
    type: str | None
    role: str | None
    placement: np.ndarray
    defects: tuple
    range: tuple | None
    home: float


class Machine:
    """A mechanism read from a model file, with a true geometry and a batched loop solver.

    Parameters
    ----------
    path : path
        Model file (JSON).
    rng : numpy Generator
        Draws the true machine's errors (0.05 mm, 2e-4 rad scale).
    """

    def __init__(self, path: Path, rng: np.random.Generator, errors: float = 1.0) -> None:
        doc = json.loads(Path(path).read_text())
        self.name, self.base, self.output = doc["name"], doc["base"], doc["output"]
        self.meta = doc.get("metadata", {})
        self.chains = []
        for ch in doc["chains"]:
            elems = []
            for el in ch["elements"]:
                defects = tuple(d if isinstance(d, str) else d["component"] for d in el.get("defects", []))
                elems.append(Elem(el["name"], el["kind"], el.get("type"), el.get("role"), _placement(el["placement"]),
                                  defects, tuple(el["range"]) if "range" in el else None, float(el.get("home", 0.0))))
            self.chains.append((ch["name"], ch["start"], ch["end"], elems))
        self.joints = [e for _, _, _, els in self.chains for e in els if e.kind == "joint"]
        self.index = {e.name: i for i, e in enumerate(self.joints)}
        self.actuated = [i for i, e in enumerate(self.joints) if e.role == "actuated"]
        self.passive = [i for i, e in enumerate(self.joints) if e.role == "passive"]
        # the chain that first reaches each frame defines it; the others close loops on it
        self.defining, self.closing = {}, []
        for c, (_, start, end, _) in enumerate(self.chains):
            if end in self.defining or end == self.base:
                self.closing.append(c)
            else:
                self.defining[end] = c
        self.true = {e.name: e.placement.copy() for _, _, _, els in self.chains for e in els}
        self._perturb(rng, errors)
        self.extra = {}  # element name -> (K, 4, 4) extra transform after its motion (effects)

    # ------------------------------------------------------------------ the true machine
    def _perturb(self, rng: np.random.Generator, errors: float) -> None:
        """Errors every assembly accommodates: on a machine whose loops are not over-constrained every placement
        with defects; otherwise the serial tail, each leg's length and a spherical leg's base joint."""
        over = 6 * len(self.closing) > len(self.passive)
        tail = self._tail()
        for _, _, _, els in self.chains:
            for i, e in enumerate(els):
                if not e.defects:
                    continue
                t = self.true[e.name]
                if not over or e.name in tail:
                    d = np.eye(4)
                    if set("IJK") & set(e.defects):
                        d[:3, :3] = _rot(rng.uniform(-1, 1, 3) * [1, 1, 0], 2e-4 * errors * rng.uniform(0.3, 1.0))
                    if set("abc") & set(e.defects):
                        d[:3, 3] = rng.uniform(-0.05, 0.05, 3) * errors
                    self.true[e.name] = t @ d
                elif i > 0 and els[i - 1].type == "P" and "c" in e.defects:
                    t[2, 3] += rng.uniform(-0.05, 0.05) * errors  # the leg's length offset (along the leg)
                elif i == 0 and [x.type for x in els[:3]] == ["R", "R", "R"] and "a" in e.defects:
                    t[:3, 3] += rng.uniform(-0.05, 0.05, 3) * errors  # a spherical base joint's centre

    def _tail(self) -> set:
        """Names of the elements of chains that start at a frame other than the base and close nothing (the wrist)."""
        out = set()
        for c, (_, start, end, els) in enumerate(self.chains):
            if start != self.base and c not in self.closing:
                out |= {e.name for e in els}
        return out

    # ------------------------------------------------------------------ kinematics
    def frames(self, q: np.ndarray, true: bool = True) -> dict:
        """Pose (K, 4, 4) of every named frame and of every element (after its motion), base = identity."""
        k = len(q)
        poses = {self.base: np.broadcast_to(np.eye(4), (k, 4, 4)).copy()}
        elems = {}
        done = set()
        while len(done) < len(self.chains):
            progressed = False
            for c, (_, start, end, els) in enumerate(self.chains):
                if c in done or start not in poses:
                    continue
                t = poses[start].copy()
                for e in els:
                    t = t @ (self.true[e.name] if true else e.placement)
                    if e.kind == "joint":
                        v = q[:, self.index[e.name]]
                        m = np.broadcast_to(np.eye(4), (k, 4, 4)).copy()
                        if e.type == "R":
                            c_, s_ = np.cos(v), np.sin(v)
                            m[:, 0, 0], m[:, 0, 1], m[:, 1, 0], m[:, 1, 1] = c_, -s_, s_, c_
                        else:
                            m[:, 2, 3] = v
                        t = t @ m
                    if e.name in self.extra:
                        t = t @ self.extra[e.name]
                    elems[e.name] = t
                key = end if c not in self.closing else f"{end}@{c}"
                poses[key] = t
                done.add(c)
                progressed = True
            if not progressed:
                raise ValueError("the chains do not all start from the base or a defined frame")
        return {**poses, "_elements": elems}

    def _closure(self, q: np.ndarray, true: bool) -> np.ndarray:
        f = self.frames(q, true)
        res = []
        for c in self.closing:
            end = self.chains[c][2]
            a, b = f[end], f[f"{end}@{c}"]
            r = np.einsum("kji,kjl->kil", a[:, :3, :3], b[:, :3, :3])
            w = 0.5 * np.stack([r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]], axis=1)
            res += [b[:, :3, 3] - a[:, :3, 3], 1000.0 * w]
        return np.concatenate(res, axis=1) if res else np.zeros((len(q), 0))

    def assemble(self, q: np.ndarray, true: bool = True, iterations: int = 30) -> np.ndarray:
        """The passive joints of configurations ``q`` (warm start in ``q``) closing every loop (Newton, batched)."""
        q = q.copy()
        if not self.closing:
            return q
        p = self.passive
        for _ in range(iterations):
            r = self._closure(q, true)
            if np.abs(r).max() < 1e-10:
                break
            jac = np.zeros((len(q), r.shape[1], len(p)))
            for n, i in enumerate(p):
                dq = q.copy()
                dq[:, i] += 1e-7
                jac[:, :, n] = (self._closure(dq, true) - r) / 1e-7
            step = np.linalg.solve(np.einsum("kri,krj->kij", jac, jac) + 1e-12 * np.eye(len(p)),
                                   np.einsum("kri,kr->ki", jac, r)[:, :, None])[:, :, 0]
            q[:, p] -= step
        return q

    def solve(self, qa: np.ndarray, true: bool = True, steps: int = 3) -> np.ndarray:
        """Full configurations at actuated values ``qa`` (K, n_act), continued from home in ``steps`` steps."""
        home = np.array([e.home for e in self.joints])
        q = np.tile(home, (len(qa), 1))
        start = home[self.actuated]
        for s in range(1, steps + 1):
            q[:, self.actuated] = start + (qa - start) * s / steps
            q = self.assemble(q, true)
        return q

    def tool(self, q: np.ndarray, true: bool = True) -> np.ndarray:
        return self.frames(q, true)[self.output]

    def forces(self, q: np.ndarray, payload: np.ndarray) -> np.ndarray:
        """Actuator forces under gravity ``-dV/dq_a`` (N or N mm), (K, n_act), nominal geometry."""
        mass = float(self.meta.get("moving_mass", 0.0)) + payload
        com = np.r_[np.asarray(self.meta.get("com", (0.0, 0.0, 0.0)), float), 1.0]
        out = np.zeros((len(q), len(self.actuated)))
        for n, i in enumerate(self.actuated):
            h = 1e-3 if self.joints[i].type == "P" else 1e-6
            v = []
            for sign in (1.0, -1.0):
                qq = q.copy()
                qq[:, i] += sign * h
                qq = self.assemble(qq, true=False)
                p = np.einsum("kij,j->ki", self.tool(qq, true=False), com)[:, :3]
                v.append(-mass * (p @ G))
            out[:, n] = -(v[0] - v[1]) / (2 * h)
        return out


def cases_for(arm: str) -> list:
    """The cases run on a machine of :data:`MODELS` (the wrist coupling needs two actuated revolutes)."""
    doc = json.loads(Path(MODELS[arm]).read_text())
    revolutes = [e for ch in doc["chains"] for e in ch["elements"]
                 if e["kind"] == "joint" and e.get("role") == "actuated" and e["type"] == "R"]
    out = list(NOISE_CASES) + list(IN_LIBRARY) + ["tool-thermal"]
    if len(revolutes) >= 2:
        out.append("wrist-coupling")
    return out


def where_words(arm: str, case: str, truth: dict) -> list:
    """Words a right 'where' contains for an out-of-library case (the joint or column the effect follows)."""
    if case == "wrist-coupling":
        return [f"joint {truth['source']}", f"joint {truth['joints'][0]}"]
    if case == "tool-thermal":
        return ["temperature", "time", "session"]
    return []


def _bow(machine: Machine, joint: str, q: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Extra transform after prismatic ``joint``'s motion on a guide bowed by ``c = (c_x, c_y)`` mm at mid-stroke."""
    e = machine.joints[machine.index[joint]]
    lo, hi = e.range
    s = (q - 0.5 * (lo + hi)) / (0.5 * (hi - lo))
    k = len(q)
    out = np.broadcast_to(np.eye(4), (k, 4, 4)).copy()
    for n in range(k):
        dx, dy = c * (1.0 - s[n] ** 2)
        sx, sy = c * (-2.0 * s[n] / (0.5 * (hi - lo)))
        out[n, :3, :3] = _rot([-sy, sx, 0.0], float(np.hypot(sx, sy)))  # the carriage follows the guide's tangent
        out[n, :3, 3] = (dx, dy, 0.0)
    return out


def campaign(model: Path, case: str, seed: int, n_id: int = 107, n_val: int = 30, size: float = 1.0,
             lead: float | None = None, wrist_compliance: float = 0.0, pivot: float = 0.0,
             temperature: str = "ramp", six_d: bool = False, noise_factor: float = 1.6) -> tuple[str, str, dict]:
    """Identification and validation files (CSV text, two targets) of one campaign, and its truth.

    ``six_d``: one 6-D target ``T`` instead (the first target's place, with an orientation of its own: the tracker
    reads its position and its orientation, a quaternion, with the noise ``# orientation noise`` states,
    ``SIGMA_RAD``); ``noise_factor``: how much noisier than stated the tracker is in an ``understated-noise`` case
    (positions and orientations).

    ``size`` scales the effect (1: the magnitudes below, drawn in [0.7, 1] with a random sign where the
    physics allows one); ``lead``: the screw lead of a ``screw-periodic`` case (mm; default the model's
    ``metadata.screw_lead``, else 10 mm); ``wrist_compliance``: in a ``compliance`` case, the compliance of
    the actuated revolutes too (rad/(N mm); 0: the legs only); ``pivot``: in a ``base-deformation`` case, how far
    below the base origin the frame tilts (mm: a table standing on feet below the base joints; 0: about the origin);
    ``temperature``: ``"ramp"`` (18 to 26 degC, rising with the time) or ``"cycle"`` (18 to 26 and back to 18 degC: the
    temperature does not follow the time).  Magnitudes: leg expansion 1.2e-5 /degC, periodic screw error 0.01 mm, a
    seat sinking 4 um/degC, leg stiffness 10 N/um, clearance 0.05 mm, backlash 0.03 mm, guide bow 0.02 mm, frame tilt
    stiffness 1.25e6 N m/rad (the structural effects near the upper end of their plausible range, so that
    the campaigns show them).
    """
    rng = np.random.default_rng(104729 * seed + sum(map(ord, case)))
    mach = Machine(model, rng)
    n = n_id + n_val
    act = mach.actuated
    lo = np.array([mach.joints[i].range[0] for i in act])
    hi = np.array([mach.joints[i].range[1] for i in act])
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    qa = mid + 0.8 * half * (2 * rng.random((n, len(act))) - 1)
    names = [mach.joints[i].name for i in act]
    t = np.arange(n) * 60.0
    if temperature == "cycle":  # the workshop warms up and cools down again: the temperature does not follow the time
        temp = 18.0 + 8.0 * np.sin(np.pi * t / t[-1]) + rng.normal(0, 0.3, n)
    else:  # "ramp": a steady warm-up over the campaign
        temp = 18.0 + 8.0 * t / t[-1] + rng.normal(0, 0.3, n)
    payload = rng.choice([0.0, 10.0, 25.0], n)
    dirs = rng.choice([-1.0, 1.0], (n, len(act)))
    session = np.where(np.arange(n) < n // 2, 1.0, 2.0)
    truth = {"case": case, "noise_factor": 1.0}
    amount = size * rng.uniform(0.7, 1.0)
    prismatic = [a for a, i in enumerate(act) if mach.joints[i].type == "P"]
    q_true = qa.copy()
    tool_growth = np.zeros(n)
    tilt = None
    legs = rng.permutation(prismatic)
    if case == "leg-thermal":
        alpha = 1.2e-5 * amount * rng.uniform(0.85, 1.15, len(prismatic))
        for a, al in zip(prismatic, alpha):
            q_true[:, a] = qa[:, a] * (1.0 + al * (temp - 20.0))
        truth.update(value=alpha.tolist(), joints=[names[a] for a in prismatic])
    elif case == "screw-periodic":
        lead = float(lead or mach.meta.get("screw_lead", 10.0))
        a = int(legs[0])
        amp = 0.01 * amount
        q_true[:, a] += amp * np.sin(2 * np.pi * qa[:, a] / lead + rng.uniform(0, 2 * np.pi))
        truth.update(value=amp, joints=[names[a]], lead=lead)
    elif case == "compliance":
        f = mach.forces(mach.solve(qa, true=False), payload)
        c = 1e-4 * amount  # mm/N: a 10 N/um leg
        q_true[:, prismatic] += c * f[:, prismatic]
        revolute = [a for a in range(len(act)) if a not in prismatic]
        if wrist_compliance and revolute:  # the wrist's axes yield under their gravity torques (N mm)
            q_true[:, revolute] += wrist_compliance * amount * f[:, revolute]
        truth.update(value=c, wrist=wrist_compliance * amount)
    elif case == "joint-clearance":
        f = mach.forces(mach.solve(qa, true=False), payload)
        beta = 0.05 * amount
        truth.update(value=beta, joints=[names[a] for a in prismatic])
    elif case == "backlash":
        beta = 0.03 * amount
        for a in prismatic:  # the load lags the drive by half the band, crossed from the recorded side
            q_true[:, a] -= 0.5 * beta * dirs[:, a]
        truth.update(value=beta)
    elif case == "wrist-coupling":
        rev = [a for a, i in enumerate(act) if mach.joints[i].type == "R"]
        k_c = 3e-4 * amount * rng.choice([-1.0, 1.0])
        q_true[:, rev[1]] += k_c * qa[:, rev[0]]
        truth.update(value=k_c, joints=[names[rev[1]]], source=names[rev[0]])
    elif case == "tool-thermal":
        tool_growth = 6e-3 * amount * (temp - 18.0)
        truth.update(value=6e-3 * amount)
    elif case == "understated-noise":
        truth["noise_factor"] = noise_factor
    elif case == "tracker-drift":
        shift = 0.05 * amount * rng.choice([-1.0, 1.0], 3) * rng.uniform(0.5, 1.0, 3)  # mm, the tracker's move
        truth.update(value=shift.tolist())
    elif case == "stand-creep":
        creep = 7e-5 * amount  # rad at the end of the campaign
        azimuth = rng.uniform(0, 2 * np.pi)
        truth.update(value=creep, axis=[float(np.cos(azimuth)), float(np.sin(azimuth)), 0.0])
    elif case == "seat-sink":  # one leg's seat moves along the leg with the temperature (not with the leg's length)
        a = int(legs[0])
        rate = 4e-3 * amount * rng.choice([-1.0, 1.0])  # mm/degC: 32 um over the campaign's 8 degC
        q_true[:, a] = qa[:, a] + rate * (temp - 18.0)
        truth.update(value=rate, joints=[names[a]])
    elif case == "loose-nest":
        sag = 0.06 * amount  # mm
        truth.update(value=sag, target="T2")
    elif case not in ("none", "guide-straightness", "base-deformation"):
        raise ValueError(f"unknown case {case}")
    q = mach.solve(q_true)
    if case == "joint-clearance":  # the platform joint shifts along the leg: after the leg's motion
        for a in prismatic:
            joint = names[a]
            shift = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
            shift[:, 2, 3] = 0.5 * beta * np.sign(f[:, a])
            mach.extra[joint] = shift
        q = mach.assemble(q)
    if case == "guide-straightness":
        # a bow the loops cannot close without straining the machine (an over-constrained one) is left out: this
        # generator does not model elastic deformation, so it bows a guide only where the machine still assembles
        # each leg bowed in the direction (x or y of its joint frame) that moves the tool most among those the
        # loops close with
        kept = []
        base = mach.tool(q)[:, :3, 3]
        for a in legs:
            moves = []
            for d in (0, 1):
                unit = np.zeros(2)
                unit[d] = 0.02
                mach.extra = {names[a]: _bow(mach, names[a], q[:, act[a]], unit)}
                qq = mach.assemble(q)
                closed = np.abs(mach._closure(qq, True)).max() <= 1e-6
                moves.append(np.abs(mach.tool(qq)[:, :3, 3] - base).max() if closed else -1.0)
            mach.extra = {}
            d = int(np.argmax(moves))
            if moves[d] > 1e-4:
                c = np.zeros(2)
                c[d] = 0.02 * amount * rng.choice([-1.0, 1.0])
                kept.append((a, c))
        for a, c in kept:
            mach.extra[names[a]] = _bow(mach, names[a], q[:, act[a]], c)
        truth.update(value=0.02 * amount, joints=[names[a] for a, _ in kept])
        q = mach.assemble(q)
    if case == "base-deformation":
        mass = float(mach.meta.get("moving_mass", 0.0)) + payload
        com = np.r_[np.asarray(mach.meta.get("com", (0.0, 0.0, 0.0)), float), 1.0]
        p = np.einsum("kij,j->ki", mach.tool(q), com)[:, :3]
        moment = np.cross(p, mass[:, None] * G[None, :])
        c = 8e-10 * amount  # rad/(N mm): a light frame of 1.25e6 N m/rad
        tilt = c * moment * np.array([1.0, 1.0, 0.0])
        truth.update(value=c, pivot=pivot)
    # tracker: twice the reach away, turned about a near-vertical axis
    tool = mach.tool(q)
    reach = float(np.max(np.linalg.norm(tool[:, :3, 3], axis=1)))
    trk_rot = _rot([0.1, 0.2, 1.0], rng.uniform(0, 2 * np.pi))
    trk_org = 2.0 * reach * np.array([0.83, -0.5, -0.1]) + rng.uniform(-50, 50, 3)
    pos, quat = {}, None
    if six_d:  # one 6-D target: its orientation is the tool's turned by a fixed mounting rotation
        mount = _rot([1.0, -2.0, 0.5], 0.4)
        r_local = np.einsum("ji,kjl->kil", trk_rot, tool[:, :3, :3] @ mount)  # trk_rot^T R_tool mount
        if tilt is not None:
            r_local = np.stack([trk_rot.T @ _rot(tk, np.linalg.norm(tk)) @ tool[k, :3, :3] @ mount
                                for k, tk in enumerate(tilt)])
        if case == "stand-creep":
            r_local = np.stack([trk_rot.T @ _rot(truth["axis"], truth["value"] * tk / t[-1]) @ tool[k, :3, :3] @ mount
                                for k, tk in enumerate(t)])
        noise = rng.normal(0, SIGMA_RAD * truth["noise_factor"], (n, 3))
        quat = np.stack([_quaternion(_rot(w, np.linalg.norm(w)) @ r) for w, r in zip(noise, r_local)])
    for ti, target in enumerate(TARGETS[:1] if six_d else TARGETS):
        tgt = np.tile(target, (n, 1))
        tgt[:, 2] += tool_growth
        world = tool[:, :3, 3] + np.einsum("kij,kj->ki", tool[:, :3, :3], tgt)
        if case == "loose-nest" and ti == 1:  # the ball settles towards gravity across the nest's axis
            axis = tool[:, :3, 2]
            down = G / np.linalg.norm(G)
            across = down[None, :] - (axis @ down)[:, None] * axis
            world = world + truth["value"] * (across + rng.normal(0, 1.0 / 3.0, (n, 3)))
        if tilt is not None:  # the frame turns about a point ``pivot`` mm below the base origin
            world = world + np.cross(tilt, world + np.array([0.0, 0.0, pivot]))
        if case == "stand-creep":  # the stand turns about the base origin by an angle growing with time
            world = np.stack([_rot(truth["axis"], truth["value"] * tk / t[-1]) @ wk for tk, wk in zip(t, world)])
        local = (world - trk_org) @ trk_rot
        if case == "tracker-drift":
            local = local - (session == 2.0)[:, None] * np.asarray(truth["value"])[None, :]
        sigma = (STATED_NOISE[0] + STATED_NOISE[1] * np.linalg.norm(local, axis=1) / 1000.0) * truth["noise_factor"]
        pos["T" if six_d else f"T{ti + 1}"] = local + rng.normal(0, 1, (n, 3)) * sigma[:, None]

    def write(rows: range, prefix: str) -> str:
        head = ["# hyperstat measurements, version 1", f"# mechanism: {mach.name}",
                f"# noise: {STATED_NOISE[0]} mm + {STATED_NOISE[1]} mm/m"]
        head += [f"# orientation noise: {SIGMA_RAD} rad"] if six_d else []
        cols = ["pose"] + [f"q{nm}[{'rad' if mach.joints[i].type == 'R' else 'mm'}]" for nm, i in zip(names, act)]
        cols += [f"{a}_{tname}[mm]" for tname in pos for a in "xyz"]
        cols += [f"{a}_T" for a in ("quat_w", "quat_x", "quat_y", "quat_z")] if six_d else []
        cols += ["temperature[degC]", "payload[kg]", "time[s]", "session"] + [f"dir{nm}" for nm in names]
        lines = head + [",".join(cols)]
        for k in rows:
            vals = [f"{prefix}{k + 1}"] + [repr(float(v)) for v in qa[k]]
            vals += [repr(float(v)) for tname in pos for v in pos[tname][k]]
            vals += [repr(float(v)) for v in quat[k]] if six_d else []
            vals += [f"{temp[k]:.3f}", f"{payload[k]:g}", f"{t[k]:g}", f"{session[k]:g}"]
            vals += [f"{d:g}" for d in dirs[k]]
            lines.append(",".join(vals))
        return "\n".join(lines) + "\n"

    return write(range(n_id), "P"), write(range(n_id, n), "V"), truth
