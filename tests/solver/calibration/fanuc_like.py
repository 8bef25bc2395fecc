"""An independent FANUC-like 6R campaign generator (issue 21), shared by the tests and the FIGAROH benchmark.

Units: lengths in mm, angles in rad in the code; the files it writes use deg and m where stated.

It shares no code with hyperstat (not with :mod:`hyperstat.solver.calibration.virtual` either):
its own standard-DH forward kinematics ``T_i = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``
on a *true* table (the nominal one perturbed), its own tracker frame, three targets (SMRs) on
the tool, Gaussian noise, and controller joint readings in FANUC's convention (J2 sign flipped,
``J3 = q3 - J2``'s inverse of the coupling ``q3 = J3 + J2``, J4 sign flipped, a J6 zero offset).
No pytest here: ``benchmarks/figaroh_compare.py`` imports it.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["NOMINAL", "LIMITS_DEG", "TARGETS", "J6_OFFSET_DEG", "NOISE_A", "NOISE_B", "DH_YAML",
           "Campaign", "noise_rms", "dh_matrix", "rotvec", "quaternion", "write_campaign"]

# nominal table: a, alpha (deg), d, theta (deg); FANUC R-2000iC-like proportions (mm)
NOMINAL = [(312.0, -90.0, 670.0, 0.0), (1075.0, 0.0, 0.0, -90.0), (225.0, -90.0, 0.0, 0.0),
           (0.0, 90.0, 1280.0, 0.0), (0.0, -90.0, 0.0, 0.0), (0.0, 0.0, 215.0, 0.0)]
LIMITS_DEG = [(-180, 180), (-60, 75), (-70, 70), (-180, 180), (-120, 120), (-180, 180)]
TARGETS = {"SMR1": (110.0, 0.0, 60.0), "SMR2": (-70.0, 95.0, 45.0), "SMR3": (10.0, -85.0, 130.0)}
J6_OFFSET_DEG = 0.5
NOISE_A, NOISE_B = 0.010, 0.005  # 1-sigma per axis: mm + mm per m of distance

DH_YAML = """\
format: hyperstat-dh
version: 1
name: fanuc_like
convention: dh
units: {length: mm, angle: deg}
joints:
""" + "".join(
    f"  - {{name: \"{i + 1}\", type: R, a: {a}, alpha: {al}, d: {d}, theta: {th}, min: {lo}, max: {hi}}}\n"
    for i, ((a, al, d, th), (lo, hi)) in enumerate(zip(NOMINAL, LIMITS_DEG))) + f"""\
joint_map:
  units: {{angle: deg}}
  joints:
    "1": {{J1: 1}}
    "2": {{J2: -1}}
    "3": {{J3: 1, J2: 1}}
    "4": {{J4: -1}}
    "5": {{J5: 1}}
    "6": {{J6: 1, offset: {J6_OFFSET_DEG}}}
"""


def dh_matrix(theta: float, d: float, a: float, alpha: float) -> np.ndarray:
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])


def rotvec(w: np.ndarray) -> np.ndarray:
    t = float(np.linalg.norm(w))
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / t
    return np.eye(3) + math.sin(t) * k + (1 - math.cos(t)) * k @ k


def quaternion(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method)."""
    tr = np.trace(r)
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        return np.array([0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s])
    i = int(np.argmax(np.diag(r)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * math.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
    out = np.zeros(4)
    out[0] = (r[k, j] - r[j, k]) / s
    out[1 + i] = 0.25 * s
    out[1 + j] = (r[j, i] + r[i, j]) / s
    out[1 + k] = (r[k, i] + r[i, k]) / s
    return out


class Campaign:
    """The true robot, tracker and targets, and the measurements they give."""

    def __init__(self, seed: int, errors: float = 1.0, noise: tuple = (NOISE_A, NOISE_B)) -> None:
        rng = np.random.default_rng(seed)
        self.rng = rng
        self.noise = noise
        e = errors
        self.table = [(a + e * rng.uniform(-0.5, 0.5), math.radians(al) + e * rng.uniform(-1e-3, 1e-3),
                       d + e * rng.uniform(-0.5, 0.5), math.radians(th) + e * rng.uniform(-1e-3, 1e-3))
                      for a, al, d, th in NOMINAL]
        tool = np.eye(4)
        tool[:3, :3] = rotvec(e * rng.uniform(-2e-3, 2e-3, 3) + 1e-9)
        tool[:3, 3] = e * rng.uniform(-0.3, 0.3, 3)
        self.tool = tool
        self.targets = {k: np.array(v) + rng.uniform(-0.2, 0.2, 3) for k, v in TARGETS.items()}
        self.target_rot = {k: rotvec(rng.uniform(-0.5, 0.5, 3)) for k in TARGETS}
        self.tracker_r = rotvec(np.array([0.05, -0.1, 0.6]))
        self.tracker_t = np.array([3200.0, -1400.0, -300.0])

    def flange(self, q: np.ndarray) -> np.ndarray:
        t = np.eye(4)
        for (a, al, d, th), qi in zip(self.table, q):
            t = t @ dh_matrix(th + qi, d, a, al)
        return t @ self.tool

    def poses(self, n: int) -> np.ndarray:
        lo, hi = np.radians(np.array(LIMITS_DEG, float)).T
        return lo + 0.8 * (hi - lo) * (0.5 + (self.rng.random((n, 6)) - 0.5))

    def measure(self, q: np.ndarray, target: str) -> np.ndarray:
        f = self.flange(q)
        world = f[:3, :3] @ self.targets[target] + f[:3, 3]
        p = self.tracker_r.T @ (world - self.tracker_t)
        sigma = self.noise[0] + self.noise[1] * np.linalg.norm(p) / 1000.0
        return p + self.rng.normal(0.0, sigma, 3)

    def measure_pose(self, q: np.ndarray, target: str, sigma_rad: float) -> tuple[np.ndarray, np.ndarray]:
        """Position (mm) and orientation quaternion (w, x, y, z) of a 6-D target in the tracker frame."""
        f = self.flange(q)
        r = self.tracker_r.T @ f[:3, :3] @ self.target_rot[target]
        r = rotvec(self.rng.normal(0.0, sigma_rad, 3)) @ r
        return self.measure(q, target), quaternion(r)

    @staticmethod
    def controller(q: np.ndarray) -> np.ndarray:
        """FANUC-like controller readings (deg) of model joints q (rad): the inverse of the joint map."""
        qd = np.degrees(q)
        j2 = -qd[1]
        return np.array([qd[0], j2, qd[2] - j2, -qd[3], qd[4], qd[5] - J6_OFFSET_DEG])

    def csv(self, q: np.ndarray, prefix: str, priors: bool = True, stacked: bool = False,
            metres: bool = True, only: tuple | None = None) -> str:
        targets = {k: v for k, v in TARGETS.items() if only is None or k in only}
        unit = "m" if metres else "mm"
        f = 1e-3 if metres else 1.0
        lines = ["# hyperstat measurements, version 1", "# mechanism: fanuc_like",
                 f"# noise: {self.noise[0]} mm + {self.noise[1]} mm/m"]
        if priors:
            lines += [f"# target {k}: " + " ".join(f"{v + 8 * s:.1f}" for v, s in zip(c, (1, -1, 1)))
                      for k, c in targets.items()]
        cols = ["pose"] + [f"J{i}[deg]" for i in range(1, 7)]
        if stacked:
            cols += [f"x[{unit}]", f"y[{unit}]", f"z[{unit}]"]
        else:
            cols += [f"{a}_{k}[{unit}]" for k in targets for a in "xyz"]
        lines.append(",".join(cols))
        for i, qi in enumerate(q):
            jc = self.controller(qi)
            if stacked:  # one row per SMR, as if they were one target (readings differ by encoder jitter)
                for k in targets:
                    jitter = jc + self.rng.normal(0.0, 1e-4, 6)
                    lines.append(",".join([f"{prefix}{i + 1}{k}"] + [repr(float(v)) for v in jitter]
                                          + [f"{v * f:.10f}" for v in self.measure(qi, k)]))
            else:
                vals = [v * f for k in targets for v in self.measure(qi, k)]
                lines.append(",".join([f"{prefix}{i + 1}"] + [repr(float(v)) for v in jc] + [f"{v:.10f}" for v in vals]))
        return "\n".join(lines) + "\n"


def noise_rms(data) -> float:
    """3-D noise RMS the generator used (mm), from the measured distances."""
    s = NOISE_A + NOISE_B * np.linalg.norm(data.position, axis=1) / 1000.0
    return float(np.sqrt(np.mean(3 * s**2)))


def write_campaign(out: str, seed: int = 21, poses: int = 50, validation: int = 30) -> list:
    """Write the files of the workflow in ``docs/identification.md`` into ``out``: the DH table with its
    joint map (``fanuc_like.dh.yaml``), ``meas.csv`` and ``meas.validation.csv`` (3 SMRs, m, deg)."""
    from pathlib import Path

    d = Path(out)
    d.mkdir(parents=True, exist_ok=True)
    c = Campaign(seed)
    files = {"fanuc_like.dh.yaml": DH_YAML, "meas.csv": c.csv(c.poses(poses), "P"),
             "meas.validation.csv": c.csv(c.poses(validation), "V")}
    for name, text in files.items():
        (d / name).write_text(text)
    return [str(d / name) for name in files]


if __name__ == "__main__":  # python -m tests.solver.calibration.fanuc_like OUT_DIR
    import sys

    for path in write_campaign(sys.argv[1] if len(sys.argv) > 1 else "."):
        print(f"wrote {path}")
