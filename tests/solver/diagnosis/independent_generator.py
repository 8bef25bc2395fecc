"""A second campaign generator, written independently of hyperstat's effects and virtual machine.

Units: lengths in mm, angles in rad, temperatures in degC, masses in kg, forces in N.

It imports nothing from hyperstat: it reads the model file (JSON, ``docs/model-format.md``)
with its own parser, computes the forward kinematics of the serial chain with its own
4x4 products, draws its own geometric errors (a small random rigid transform on every
placement, joint zero offsets included), simulates a laser tracker (pose, noise
``a + b d`` per axis) and writes measurement files (CSV, ``hyperstat measurements, version 1``)
that ``hyperstat diagnose`` reads like any user's file.

Effects are its own implementations, some of the library's kinds done differently and
some the library does not have:

in the library (implemented differently)
    ``angle-scale`` (gear ratio error of one joint), ``angle-harmonic-1`` / ``-2``
    (eccentricity / ellipticity of one joint, with a random phase), ``compliance`` (joint
    stiffness, gravity torques from the link masses of the model file by differentiating
    the potential energy numerically), ``backlash`` (a dead band the load follows while
    the motor approaches the pose from the recorded direction), ``backlash-gravity`` (the
    load rests on the flank the gravity torque pushes it to), ``thermal`` (every link length
    and the target offset grow with the temperature);
out of the library
    ``link-bending`` (the upper arm bends under the weight it carries: a rotation and a
    deflection at its end), ``coupling`` (a joint moves with another: the SCARA's
    ball-screw spline, the 6R's wrist), ``angle-harmonic-3`` (three cycles per revolution,
    a period the library lacks), ``tool-thermal`` (the tool grows along its axis with
    the temperature);
noise cases
    ``none`` (geometric errors and the stated noise), ``understated-noise`` (the tracker
    is 1.6 times noisier than the header says).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["Arm", "IN_LIBRARY", "OUT_OF_LIBRARY", "NOISE_CASES", "campaign", "cases_for", "ARM_6R", "SCARA", "MODELS",
           "where_words"]

HERE = Path(__file__).resolve().parent
ARM_6R = HERE / "data" / "arm_6r.skel.json"
SCARA = HERE / "data" / "scara.skel.json"  # the SCARA template at its defaults, link masses declared
MODELS = {"arm_6r": ARM_6R, "scara": SCARA}
G = np.array([0.0, 0.0, -9.81])  # m/s^2, base -z
IN_LIBRARY = ("angle-scale", "angle-harmonic-1", "angle-harmonic-2", "compliance", "backlash", "backlash-gravity",
              "thermal")
OUT_OF_LIBRARY = ("link-bending", "coupling", "angle-harmonic-3", "tool-thermal")
NOISE_CASES = ("none", "understated-noise")
STATED_NOISE = (0.005, 0.005)  # mm, mm/m: what the file header says


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues rotation matrix."""
    axis = np.asarray(axis, float)
    n = np.linalg.norm(axis)
    if n == 0 or angle == 0:
        return np.eye(3)
    k = axis / n
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def _placement(p: dict) -> np.ndarray:
    z = np.asarray(p["z_axis"], float)
    x = np.asarray(p["x_axis"], float)
    t = np.eye(4)
    t[:3, 0], t[:3, 1], t[:3, 2], t[:3, 3] = x, np.cross(z, x), z, p["origin"]
    return t


@dataclass
class Element:
    """One element of the serial chain: its placement, and its joint type (None for a fixed one)."""

    name: str
    placement: np.ndarray
    type: str | None
    range: tuple | None
    home: float = 0.0


class Arm:
    """A serial arm read from a model file, with its own true geometry.

    Parameters
    ----------
    path : path
        Model file (JSON).  Its ``metadata.masses`` declares the link masses (kg) and
        centres of mass (mm, base frame at the home configuration) per joint.
    rng : numpy Generator
        Draws the geometric errors: every placement turned by a rotation vector of
        uniform components within +-2e-4 rad and shifted within +-0.05 mm.
    """

    def __init__(self, path: Path, rng: np.random.Generator) -> None:
        doc = json.loads(Path(path).read_text())
        if len(doc["chains"]) != 1:
            raise ValueError("the independent generator handles serial chains only")
        self.name = doc["name"]
        self.doc = doc
        self.elements = []
        for el in doc["chains"][0]["elements"]:
            if el["kind"] == "frame":
                continue
            self.elements.append(Element(el["name"], _placement(el["placement"]),
                                         el.get("type") if el["kind"] == "joint" else None,
                                         tuple(el["range"]) if el["kind"] == "joint" else None,
                                         float(el.get("home", 0.0))))
        self.joints = [e for e in self.elements if e.type is not None]
        self.true = []
        for e in self.elements:
            d = np.eye(4)
            d[:3, :3] = _rot(rng.uniform(-1, 1, 3), 2e-4 * np.sqrt(3) * rng.uniform(0, 1))
            d[:3, 3] = rng.uniform(-0.05, 0.05, 3)
            self.true.append(e.placement @ d)
        masses = doc.get("metadata", {}).get("masses", {})
        self.masses = {}
        home = np.array([e.home for e in self.joints])
        frames = self.body_frames(home, nominal=True)
        for name, spec in masses.items():
            i = [e.name for e in self.elements].index(name)
            local = np.linalg.solve(frames[i], np.r_[spec["com"], 1.0])
            self.masses[i] = (float(spec["mass"]), local)

    def body_frames(self, q: np.ndarray, nominal: bool = False, scale: float = 1.0, extra: dict | None = None,
                    ) -> list[np.ndarray]:
        """Absolute frame of every element after its motion, at joint values ``q`` (one pose)."""
        t = np.eye(4)
        out = []
        j = 0
        for i, e in enumerate(self.elements):
            d = (e.placement if nominal else self.true[i]).copy()
            d[:3, 3] *= scale
            if extra and i in extra:
                d = d @ extra[i]
            t = t @ d
            if e.type == "R":
                m = np.eye(4)
                m[:3, :3] = _rot([0, 0, 1], q[j])
                t = t @ m
                j += 1
            elif e.type == "P":
                m = np.eye(4)
                m[2, 3] = q[j]
                t = t @ m
                j += 1
            out.append(t)
        return out

    def potential(self, q: np.ndarray, payload: float, target: np.ndarray) -> float:
        """Gravity potential energy (N mm) of the link masses and the payload at the target."""
        frames = self.body_frames(q, nominal=True)
        v = 0.0
        for i, (m, local) in self.masses.items():
            v -= m * G @ (frames[i] @ local)[:3]
        v -= payload * G @ (frames[-1] @ np.r_[target, 1.0])[:3]
        return v

    def gravity_torques(self, q: np.ndarray, payload: float, target: np.ndarray) -> np.ndarray:
        """Generalised gravity forces ``-dV/dq`` by central differences (N mm per rad, N per mm)."""
        tau = np.zeros(len(q))
        for j in range(len(q)):
            h = 1e-6 if self.joints[j].type == "R" else 1e-4
            qp, qm = q.copy(), q.copy()
            qp[j] += h
            qm[j] -= h
            tau[j] = -(self.potential(qp, payload, target) - self.potential(qm, payload, target)) / (2 * h)
        return tau

    def random_poses(self, n: int, rng: np.random.Generator) -> np.ndarray:
        lo = np.array([e.range[0] for e in self.joints])
        hi = np.array([e.range[1] for e in self.joints])
        span = hi - lo
        return lo + 0.05 * span + rng.random((n, len(lo))) * 0.9 * span


def cases_for(arm_name: str) -> list[str]:
    """The cases run on an arm (every kind applies to both arms)."""
    return list(NOISE_CASES) + list(IN_LIBRARY) + list(OUT_OF_LIBRARY)


def where_words(arm_name: str, case: str, truth: dict) -> list[str]:
    """Words a right 'where' contains for an out-of-library case (the joint the effect lives on)."""
    j = truth.get("joint")
    if case == "coupling":
        return [f"joint {truth['source']}", f"joint {j}"]
    if case == "angle-harmonic-3":
        return [f"joint {j}"]
    if case == "tool-thermal":
        return ["temperature", "time", "session"]
    if case == "link-bending":
        return [f"joint {k}" for k in truth.get("joints", [])] + ["payload"]
    return []


def _apply(case, arm, q, q_true, extra_frames, scale, tool_growth, temp, payload, dirs, target, rng, info):
    """Add one effect to the true joint values / frames / scale / tool growth (in place); returns ``info``.

    The joint an effect acts on is the second revolute (the shoulder of the 6R, the elbow
    of the SCARA), the most influential.
    """
    n, nj = q.shape
    names = [e.name for e in arm.joints]
    revolute = [j for j, e in enumerate(arm.joints) if e.type == "R"]
    prismatic = [j for j, e in enumerate(arm.joints) if e.type == "P"]
    main = 1 if len(revolute) > 1 else revolute[0]
    sign = rng.choice([-1.0, 1.0])
    size = rng.uniform(0.7, 1.0)
    if case == "angle-scale":
        s = sign * 1e-4 * size
        q_true[:, main] += s * q[:, main]
        info.update(joint=names[main], value=s)
    elif case in ("angle-harmonic-1", "angle-harmonic-2", "angle-harmonic-3"):
        h = int(case[-1])
        amp, phase = 1e-4 * size, rng.uniform(0, 2 * np.pi)
        q_true[:, main] += amp * np.sin(h * q[:, main] + phase)
        info.update(joint=names[main], value=amp, cycles=h)
    elif case in ("compliance", "backlash-gravity", "link-bending"):
        tau = np.array([arm.gravity_torques(q[k], payload[k], target) for k in range(n)])
        if case == "compliance":
            # stiffness per joint: 2e6 N m/rad on revolutes (5e-10 rad/(N mm)), 5 N/um on the quill
            compliance = np.array([5e-10 * size if e.type == "R" else 2e-4 * size for e in arm.joints])
            q_true += tau * compliance
            info.update(value=compliance.tolist(), joint=names[int(np.argmax(np.abs(tau * compliance).max(0)))])
        elif case == "backlash-gravity":
            beta = np.array([3e-4 * size if e.type == "R" else 0.04 * size for e in arm.joints])
            scale_tau = np.abs(tau).max(axis=0, keepdims=True) + 1e-300
            side = np.where(np.abs(tau) > 1e-6 * scale_tau, np.sign(tau), 0.0)
            q_true += 0.5 * beta * side
            info.update(value=beta.tolist(), joint=names[main])
        else:
            # the link after joint ``main`` bends under the weight it carries (cantilever, isotropic
            # section): end slope = c M_perp (M the moment of the weights beyond its root, M_perp its
            # part across the link), end deflection 2/3 L times the slope, across the link
            link = [i for i, e in enumerate(arm.elements) if e.name == names[main]][0] + 1
            c_bend = (2e-10 if prismatic == [] else 6e-10) * size  # rad / (N mm)
            for k in range(n):
                frames = arm.body_frames(q[k], nominal=True)
                root = frames[link - 1][:3, 3]
                tip_l = frames[link - 1] @ arm.elements[link].placement  # tip frame before its motion
                along = tip_l[:3, 3] - root
                length = float(np.linalg.norm(along))
                u = along / length
                moment = np.zeros(3)
                for i, (m, local) in arm.masses.items():
                    if i >= link - 1:
                        moment += np.cross((frames[i] @ local)[:3] - root, m * G)
                moment += np.cross((frames[-1] @ np.r_[target, 1.0])[:3] - root, payload[k] * G)
                theta = c_bend * (moment - (moment @ u) * u)
                r = tip_l[:3, :3]
                th_l, u_l = r.T @ theta, r.T @ u
                bend = np.eye(4)
                bend[:3, :3] = _rot(th_l, float(np.linalg.norm(th_l)))
                bend[:3, 3] = (2.0 / 3.0) * length * np.cross(th_l, u_l)
                extra_frames[k] = {link: bend}
            info.update(joint=names[main], joints=[names[main], names[min(main + 1, nj - 1)]], value=c_bend)
    elif case == "backlash":
        beta = np.array([3e-4 * size if e.type == "R" else 0.04 * size for e in arm.joints])
        for k in range(n):
            for j in range(nj):
                # dead band: the motor comes from 0.05 (rad or mm) on the recorded side; the load
                # starts anywhere in the band and is dragged once it touches a flank
                motor = q[k, j] - dirs[k, j] * 0.05
                load = motor + rng.uniform(-0.5, 0.5) * beta[j]
                for m_pos in np.linspace(motor, q[k, j], 20):
                    load = min(max(load, m_pos - beta[j] / 2), m_pos + beta[j] / 2)
                q_true[k, j] += load - q[k, j]
        info.update(value=beta.tolist(), joint=names[main])
    elif case == "thermal":
        alpha = 1.2e-5 * size  # steel
        scale *= 1.0 + alpha * (temp - 20.0)
        info.update(value=alpha)
    elif case == "coupling":
        if prismatic:  # SCARA: the ball-screw spline lifts the quill with the wrist turn
            src, dst, k_c = revolute[-1], prismatic[0], sign * 0.02 * size  # mm per rad
        else:  # 6R: the wrist's joint 5 follows joint 4
            src, dst, k_c = 3, 4, sign * 2e-4 * size  # rad per rad
        q_true[:, dst] += k_c * q[:, src]
        info.update(joint=names[dst], source=names[src], value=k_c)
    elif case == "tool-thermal":
        tool_growth += 6e-3 * size * (temp - 18.0)  # mm: 6 um/degC of the heated tool holder
        info.update(value=6e-3 * size)
    elif case == "understated-noise":
        info["noise_factor"] = 1.6
    elif case != "none":
        raise ValueError(f"unknown case {case}")
    return info


def campaign(model: Path, case: str, seed: int, n_id: int = 107, n_val: int = 30) -> tuple[str, str, dict]:
    """Identification and validation measurement files (CSV text) of one simulated campaign.

    Returns
    -------
    id_text, val_text : str
        Measurement files (``# noise: 0.005 mm + 0.005 mm/m`` stated).
    truth : dict
        The case, its parameters, the joint it acts on, the true noise factor.
    """
    rng = np.random.default_rng(7919 * seed + sum(map(ord, case)))
    arm = Arm(model, rng)
    n = n_id + n_val
    q = arm.random_poses(n, rng)
    nj = len(arm.joints)
    names = [e.name for e in arm.joints]
    t = np.arange(n) * 60.0
    temp = 18.0 + 8.0 * t / t[-1] + rng.normal(0, 0.3, n)
    payload = rng.choice([0.0, 10.0, 25.0], n)
    dirs = rng.choice([-1.0, 1.0], (n, nj))
    session = np.where(np.arange(n) < n // 2, 1.0, 2.0)
    target = np.array([12.0, -8.0, -25.0])
    truth = {"case": case, "noise_factor": 1.0}
    q_true = q.copy()
    extra_frames = [None] * n
    tool_growth = np.zeros(n)
    scale = np.ones(n)
    for part in case.split("+"):
        _apply(part, arm, q, q_true, extra_frames, scale, tool_growth, temp, payload, dirs, target, rng, truth)
    # tracker: twice the reach away, turned about a near-vertical axis
    reach = max(np.linalg.norm(arm.body_frames(qq, nominal=True)[-1][:3, 3]) for qq in q[:20])
    trk_rot = _rot([0.1, 0.2, 1.0], rng.uniform(0, 2 * np.pi))
    trk_org = 2.0 * reach * np.array([0.83, -0.5, -0.1]) + rng.uniform(-50, 50, 3)
    pos = np.zeros((n, 3))
    for k in range(n):
        frames = arm.body_frames(q_true[k], scale=scale[k], extra=extra_frames[k])
        tool = frames[-1]
        tgt = target * scale[k] + np.array([0.0, 0.0, tool_growth[k]])
        world = (tool @ np.r_[tgt, 1.0])[:3]
        local = trk_rot.T @ (world - trk_org)
        sigma = (STATED_NOISE[0] + STATED_NOISE[1] * np.linalg.norm(local) / 1000.0) * truth["noise_factor"]
        pos[k] = local + rng.normal(0, sigma, 3)

    def write(rows: range, prefix: str) -> str:
        head = ["# hyperstat measurements, version 1", f"# mechanism: {arm.name}",
                f"# noise: {STATED_NOISE[0]} mm + {STATED_NOISE[1]} mm/m"]
        cols = ["pose"] + [f"q{nm}[{'rad' if e.type == 'R' else 'mm'}]" for nm, e in zip(names, arm.joints)]
        cols += ["x[mm]", "y[mm]", "z[mm]", "temperature[degC]", "payload[kg]", "time[s]", "session"]
        cols += [f"dir{nm}" for nm in names]
        lines = head + [",".join(cols)]
        for k in rows:
            vals = [f"{prefix}{k + 1}"] + [repr(float(v)) for v in q[k]] + [repr(float(v)) for v in pos[k]]
            vals += [f"{temp[k]:.3f}", f"{payload[k]:g}", f"{t[k]:g}", f"{session[k]:g}"]
            vals += [f"{d:g}" for d in dirs[k]]
            lines.append(",".join(vals))
        return "\n".join(lines) + "\n"

    return write(range(n_id), "P"), write(range(n_id, n), "V"), truth
