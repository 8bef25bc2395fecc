"""A KUKA-like 6R campaign generator (issue 40): modified DH in degrees, spherical wrist, 3 reflectors per pose.

Units: lengths in mm, angles in rad in the code; the files it writes state deg and mm.

It shares no code with hyperstat (it imports numpy only): its own modified-DH (Craig) forward
kinematics ``T_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i + q_i) Tz(d_i)`` on a *true* robot whose
every link transform is turned and shifted by a small random rigid transform, its own link
masses and gravity torques (``-dV/dq`` by central differences of the potential energy), its own
laser tracker and three reflectors on the flange, and its own effects:

``harmonic``
    ``q_j + A sin(k q_j + phase)`` on one joint (``k = 1`` an eccentric output bearing, ``k = 2``
    a strain-wave ellipticity, ``k = 1.5`` a two-stage gear whose intermediate wheel turns 1.5
    times per revolution of the joint);
``scale``
    ``(1 + s) q_j`` on one joint (a gear-ratio error);
``compliance``
    ``q + C tau`` (joint stiffness of each joint, gravity torques of the link masses and the payload);
``loose-reflector``
    the nest of one reflector (``SMR3``) is loose on the flange: it slides along the flange's x axis by
    ``0.04 mm sin(q_6 + 0.3)`` as the wrist turns (a cable pulling it); the other reflectors are right;
``none`` / ``understated-noise``
    geometric errors only, the tracker as stated or 1.6 times noisier than the header says.

Cases combine with ``+`` (``compliance+harmonic``).  The model the diagnosis is given comes
from :data:`MDH_YAML` through ``hyperstat import-robot`` and carries the link masses of
:meth:`KukaLike.declared_masses` (base frame at the model's home), as a user would declare them.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["MDH", "LIMITS_DEG", "MDH_YAML", "REFLECTORS", "NOISE", "KukaLike", "campaign"]

# alpha_{i-1} (deg), a_{i-1} (mm), theta_i (deg), d_i (mm): a KR 210-like arm (shoulder offset 350 mm,
# upper arm 1150 mm, forearm 1200 mm with a 41 mm elbow offset, spherical wrist)
MDH = [(0.0, 0.0, 0.0, 675.0), (-90.0, 350.0, 0.0, 0.0), (0.0, 1150.0, -90.0, 0.0), (-90.0, -41.0, 0.0, 1200.0),
       (90.0, 0.0, 0.0, 0.0), (-90.0, 0.0, 0.0, 0.0)]
FLANGE = 215.0  # mm along z6
LIMITS_DEG = [(-170.0, 170.0), (-140.0, -5.0), (-120.0, 155.0), (-180.0, 180.0), (-120.0, 120.0), (-180.0, 180.0)]
REFLECTORS = {"SMR1": (120.0, 0.0, 60.0), "SMR2": (-70.0, 100.0, 40.0), "SMR3": (0.0, -90.0, 130.0)}
NOISE = (0.010, 0.005)  # mm + mm per m of distance, 1-sigma per axis (what the header states)
# link masses (kg) and centres of mass in each link's own (modified-DH) frame (mm): a 1 t class arm
MASSES = {1: (320.0, (-60.0, 30.0, -200.0)), 2: (180.0, (575.0, 0.0, 120.0)), 3: (140.0, (60.0, -300.0, 30.0)),
          4: (40.0, (0.0, 0.0, -200.0)), 5: (20.0, (0.0, 30.0, 0.0)), 6: (5.0, (0.0, 0.0, 40.0))}
STIFFNESS = (8e6, 3e6, 3e6, 6e5, 6e5, 4e5)  # N m / rad per joint (Dumas et al. 2011 class of a heavy arm)
G = np.array([0.0, 0.0, -9.81])

MDH_YAML = """\
format: hyperstat-dh
version: 1
name: kuka_like
convention: modified-dh
units: {length: mm, angle: deg}
joints:
""" + "".join(
    f"  - {{name: \"{i + 1}\", type: R, alpha: {al}, a: {a}, theta: {th}, d: {d}, min: {lo}, max: {hi}}}\n"
    for i, ((al, a, th, d), (lo, hi)) in enumerate(zip(MDH, LIMITS_DEG))) + f"tool: {{origin: [0, 0, {FLANGE}], rpy: [0, 0, 0]}}\n"


def _rx(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _rz(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _trans(x: float, y: float, z: float) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = (x, y, z)
    return t


def _rotvec(w) -> np.ndarray:
    w = np.asarray(w, float)
    t = float(np.linalg.norm(w))
    if t == 0.0:
        return np.eye(3)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / t
    return np.eye(3) + math.sin(t) * k + (1 - math.cos(t)) * k @ k


class KukaLike:
    """The true robot, its tracker and reflectors (geometric errors drawn from ``seed``)."""

    def __init__(self, seed: int, noise_factor: float = 1.0) -> None:
        self.rng = rng = np.random.default_rng(seed)
        self.noise_factor = noise_factor
        self.delta = []
        for _ in range(len(MDH) + 1):  # every link transform and the flange: 0.3 mrad, 0.1 mm
            d = np.eye(4)
            d[:3, :3] = _rotvec(rng.uniform(-3e-4, 3e-4, 3))
            d[:3, 3] = rng.uniform(-0.1, 0.1, 3)
            self.delta.append(d)
        self.reflectors = {k: np.array(v) + rng.uniform(-0.3, 0.3, 3) for k, v in REFLECTORS.items()}
        self.tracker_r = _rotvec([0.02, -0.05, 0.8 + rng.uniform(-0.2, 0.2)])
        self.loose: dict = {}  # reflector -> amplitude (mm) of its loose nest
        self.tracker_t = np.array([3500.0, -1800.0, -200.0]) + rng.uniform(-100, 100, 3)

    # ------------------------------------------------------------------ kinematics
    def frames(self, q, true: bool = True) -> list:
        """Frame of every link after its motion (base frame), the flange last."""
        t = np.eye(4)
        out = []
        for i, ((al, a, th, d), qi) in enumerate(zip(MDH, q)):
            link = _rx(math.radians(al)) @ _trans(a, 0, 0) @ _rz(math.radians(th) + qi) @ _trans(0, 0, d)
            t = t @ (self.delta[i] @ link if true else link)
            out.append(t)
        flange = _trans(0, 0, FLANGE)
        out.append(t @ (self.delta[-1] @ flange if true else flange))
        return out

    def potential(self, q, payload: float) -> float:
        """Gravity potential energy (N mm) of the link masses and the payload at the flange (nominal geometry)."""
        f = self.frames(q, true=False)
        v = 0.0
        for j, (m, c) in MASSES.items():
            v -= m * G @ (f[j - 1] @ np.r_[c, 1.0])[:3]
        v -= payload * G @ f[-1][:3, 3]
        return float(v)

    def gravity_torques(self, q, payload: float) -> np.ndarray:
        """``-dV/dq`` by central differences (N mm per rad)."""
        tau = np.zeros(6)
        for j in range(6):
            qp, qm = np.array(q, float), np.array(q, float)
            qp[j] += 1e-6
            qm[j] -= 1e-6
            tau[j] = -(self.potential(qp, payload) - self.potential(qm, payload)) / 2e-6
        return tau

    def declared_masses(self, home) -> dict:
        """``metadata.masses`` for the model file: per joint, its body's mass and centre (base frame at ``home``)."""
        f = self.frames(np.asarray(home, float), true=False)
        return {str(j): {"mass": m, "com": (f[j - 1] @ np.r_[c, 1.0])[:3].tolist()} for j, (m, c) in MASSES.items()}

    def poses(self, n: int, narrow: dict | None = None) -> np.ndarray:
        """Random joint values (rad) within 85 % of the limits (``narrow``: joint index -> (lo, hi) deg instead)."""
        narrow = {int(k): v for k, v in (narrow or {}).items()}
        lims = np.radians(np.array([narrow.get(j, lim) for j, lim in enumerate(LIMITS_DEG)], float))
        lo, hi = lims.T
        mid, half = (lo + hi) / 2, (hi - lo) / 2
        return mid + 0.85 * half * (2 * self.rng.random((n, 6)) - 1)

    def measure(self, q_true, reflector: str) -> np.ndarray:
        f = self.frames(q_true)[-1]
        point = self.reflectors[reflector].copy()
        if reflector in self.loose:
            point[0] += self.loose[reflector] * math.sin(q_true[5] + 0.3)
        world = f[:3, :3] @ point + f[:3, 3]
        p = self.tracker_r.T @ (world - self.tracker_t)
        sigma = (NOISE[0] + NOISE[1] * np.linalg.norm(p) / 1000.0) * self.noise_factor
        return p + self.rng.normal(0.0, sigma, 3)


def _effects(robot: KukaLike, case: str, q: np.ndarray, payload: np.ndarray, truth: dict, options: dict) -> np.ndarray:
    """True joint values for the recorded ``q`` under the case's effects (the generator's own implementations)."""
    q_true = q.copy()
    rng = robot.rng
    for part in case.split("+"):
        if part == "harmonic":
            j, k = options.get("joint", 0), options.get("order", 1.0)
            amp = options.get("amplitude", 6e-5) * rng.uniform(0.8, 1.0)
            phase = rng.uniform(0, 2 * np.pi)
            q_true[:, j] += amp * np.sin(k * q[:, j] + phase)
            truth.update(joint=str(j + 1), order=k, amplitude=amp)
        elif part == "scale":
            j = options.get("scale_joint", 2)
            s = options.get("scale", 1.5e-4) * rng.choice([-1.0, 1.0]) * rng.uniform(0.8, 1.0)
            q_true[:, j] += s * q[:, j]
            truth.update(scale_joint=str(j + 1), scale=s)
        elif part == "compliance":
            c = 1.0 / (np.array(STIFFNESS) * 1000.0) * options.get("compliance_factor", 1.0)  # rad / (N mm)
            tau = np.array([robot.gravity_torques(qq, p) for qq, p in zip(q, payload)])
            q_true += tau * c
            truth.update(compliance=c.tolist())
        elif part == "loose-reflector":
            robot.loose["SMR3"] = options.get("loose", 0.04)
            truth.update(reflector="SMR3", loose=robot.loose["SMR3"])
        elif part == "understated-noise":
            robot.noise_factor = 1.6
            truth.update(noise_factor=1.6)
        elif part != "none":
            raise ValueError(f"unknown case {part}")
    return q_true


def campaign(case: str, seed: int, n_id: int = 60, n_val: int = 24, narrow: dict | None = None,
             **options) -> tuple[str, str, dict, "KukaLike"]:
    """Identification and validation files (CSV text, 3 reflectors, deg and mm) of one campaign, its truth, the robot.

    ``options``: ``joint`` (index) and ``order``, ``amplitude`` (rad) of a harmonic; ``scale_joint`` and ``scale``;
    ``compliance_factor`` (times the nominal compliance of :data:`STIFFNESS`).
    """
    robot = KukaLike(1000 + seed)
    n = n_id + n_val
    q = robot.poses(n, narrow)
    payload = robot.rng.choice([0.0, 60.0, 150.0], n)
    temp = 20.0 + robot.rng.normal(0.0, 0.3, n)
    truth = {"case": case, "noise_factor": 1.0}
    q_true = _effects(robot, case, q, payload, truth, options)
    meas = {k: np.array([robot.measure(qq, k) for qq in q_true]) for k in REFLECTORS}

    def write(rows, prefix: str) -> str:
        lines = ["# hyperstat measurements, version 1", "# mechanism: kuka_like",
                 f"# noise: {NOISE[0]} mm + {NOISE[1]} mm/m",
                 "pose," + ",".join(f"q{j}[deg]" for j in range(1, 7))
                 + "," + ",".join(f"{a}_{k}[mm]" for k in REFLECTORS for a in "xyz")
                 + ",payload[kg],temperature[degC]"]
        for i in rows:
            vals = [f"{prefix}{i + 1}"] + [repr(float(v)) for v in np.degrees(q[i])]
            vals += [f"{v:.6f}" for k in REFLECTORS for v in meas[k][i]]
            vals += [f"{payload[i]:g}", f"{temp[i]:.2f}"]
            lines.append(",".join(vals))
        return "\n".join(lines) + "\n"

    return write(range(n_id), "P"), write(range(n_id, n), "V"), truth, robot
