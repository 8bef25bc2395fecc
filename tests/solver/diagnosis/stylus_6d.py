"""A 6-D probe on a serial arm whose stylus sags under gravity (issue 40): campaigns of position and orientation rows.

Units: lengths in mm, angles in rad in the code; the files it writes state deg (joints) and mm.

It shares no code with hyperstat: the arm, its true geometry, the tracker and the controller's joint
readings are those of the FANUC-like generator of the calibration tests (``fanuc_like.py``, its own
standard-DH kinematics; numpy only).  One 6-D probe sits on the flange (``SMR1``'s place, its own
orientation); the tracker reads the probe body's orientation (a quaternion, with the noise
``# orientation noise`` states) and the position of the stylus tip (with the noise ``# noise``
states).  The effect, out of the library:

``stylus-sag``
    the stylus (along the probe's z axis) is a cantilever: its tip deflects under its weight, towards
    gravity and across the stylus, by ``c (g - (g . a) a)`` (``g`` the unit vector of gravity, ``a`` the
    stylus axis, both in the base frame; ``c`` the tip deflection of a horizontal stylus, mm).  The tip
    moves, the probe body does not turn: the orientation rows do not see it;
``none`` / ``understated-noise``
    geometric errors only; the tracker's positions (``understated-noise``: and orientations) 1.6 times
    noisier than the header says.

Gravity is ``-z`` of the arm's base frame (the DH table's first axis is vertical).
"""

from __future__ import annotations

import numpy as np

from tests.solver.calibration.fanuc_like import DH_YAML, Campaign, quaternion, rotvec

__all__ = ["DH_YAML", "ProbeCampaign", "campaign", "SIGMA_RAD", "SAG_MM"]

SIGMA_RAD = 5e-5  # rad, the orientation noise the header states (1 sigma per axis)
SAG_MM = 0.1  # mm, the tip deflection of a horizontal stylus (a long, thin extension on a 6-D probe)
DOWN = np.array([0.0, 0.0, -1.0])  # gravity's direction in the base frame


class ProbeCampaign(Campaign):
    """The FANUC-like arm carrying a 6-D probe whose stylus tip sags by ``sag`` mm when horizontal."""

    def __init__(self, seed: int, sag: float = 0.0, noise_factor: float = 1.0) -> None:
        super().__init__(seed)
        self.sag, self.noise_factor = sag, noise_factor
        self.noise_true = (self.noise[0] * noise_factor, self.noise[1] * noise_factor)

    def measure_probe(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Position of the stylus tip (mm, tracker frame) and the probe body's quaternion (w, x, y, z)."""
        f = self.flange(q)
        r_probe = f[:3, :3] @ self.target_rot["SMR1"]
        tip = f[:3, :3] @ self.targets["SMR1"] + f[:3, 3]
        axis = r_probe[:, 2]
        tip = tip + self.sag * (DOWN - (DOWN @ axis) * axis)  # the cantilever's tip, towards gravity across the stylus
        p = self.tracker_r.T @ (tip - self.tracker_t)
        sigma = self.noise_true[0] + self.noise_true[1] * np.linalg.norm(p) / 1000.0
        r = self.tracker_r.T @ r_probe
        if self.noise_factor > 0:  # 0: a noise-free copy (how visible the effect is)
            r = rotvec(self.rng.normal(0.0, SIGMA_RAD * self.noise_factor, 3)) @ r
        return p + self.rng.normal(0.0, 1.0, 3) * sigma, quaternion(r)


def campaign(case: str, seed: int, n_id: int = 30, n_val: int = 15, sag: float = SAG_MM,
             noise_free: bool = False) -> tuple[str, str, dict]:
    """Identification and validation files (CSV text, one 6-D probe, deg and mm) of one campaign, and its truth.

    ``noise_free``: the same poses and true machine without noise (the header still states the noise).
    """
    if case not in ("none", "understated-noise", "stylus-sag"):
        raise ValueError(f"unknown case {case}")
    factor = 0.0 if noise_free else 1.6 if case == "understated-noise" else 1.0
    c = ProbeCampaign(7000 + seed, sag=sag if case == "stylus-sag" else 0.0, noise_factor=factor)
    q = c.poses(n_id + n_val)

    def write(rows, prefix: str) -> str:
        lines = ["# hyperstat measurements, version 1", "# mechanism: fanuc_like",
                 f"# noise: {c.noise[0]} mm + {c.noise[1]} mm/m", f"# orientation noise: {SIGMA_RAD} rad",
                 "pose," + ",".join(f"J{i}[deg]" for i in range(1, 7))
                 + ",x[mm],y[mm],z[mm],quat_w,quat_x,quat_y,quat_z"]
        for i in rows:
            p, quat = c.measure_probe(q[i])
            lines.append(",".join([f"{prefix}{i + 1}"] + [repr(float(v)) for v in c.controller(q[i])]
                                  + [repr(float(v)) for v in p] + [repr(float(v)) for v in quat]))
        return "\n".join(lines) + "\n"

    truth = {"case": case, "noise_factor": factor, "sag": c.sag}
    return write(range(n_id), "P"), write(range(n_id, n_id + n_val), "V"), truth
