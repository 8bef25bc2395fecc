"""Reader of the public real data set kept under ``data/figaroh_ur10/`` (FIGAROH's UR10 calibration, Apache-2.0).

Units: lengths in mm, angles in rad in the files it writes (the source is in m and rad).

The source (``data/figaroh_ur10/README.md``): 23 poses of a Universal Robots UR10e measured
by a camera (an Intel RealSense on the arm and a checkerboard), one 6-D target per pose:
``x1, y1, z1`` (m) and ``phix1, phiy1, phiz1`` (rad, roll-pitch-yaw as pinocchio's
``matrixToRpy``: ``R = Rz(phiz) Ry(phiy) Rx(phix)``), then the six joint angles (rad).  The
robot is the URDF beside it (its links' ``<inertial>`` give the masses).  Nothing here
imports hyperstat: the reader turns the CSV into a ``hyperstat measurements`` file; the
tests then read it like a user's file.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

__all__ = ["UR10_DIR", "UR10_URDF", "UR10_CSV", "UR10_TIP", "UR10_NOISE", "ur10_measurements"]

UR10_DIR = Path(__file__).resolve().parent / "data" / "figaroh_ur10"
UR10_URDF = UR10_DIR / "robot.urdf"
UR10_CSV = UR10_DIR / "calibration.csv"
UR10_TIP = "wrist_3_link"  # FIGAROH's tool frame of this data set (examples/ur10/config/ur10_config.yaml)
#: stated noise (1-sigma per axis): the source states none; a checkerboard pose from a RealSense at about
#: 1 m is good to about a millimetre and a few mrad (README.md) -- an assumption, said so wherever used
UR10_NOISE = {"position_mm": 1.0, "orientation_rad": 5e-3}
JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint"]


def _rpy_to_rotvec(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rotation vector of ``Rz(yaw) Ry(pitch) Rx(roll)`` (rad)."""
    cr, sr, cp, sp, cy, sy = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), \
        math.sin(yaw)
    r = np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                  [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                  [-sp, cp * sr, cp * cr]])
    angle = math.acos(max(-1.0, min(1.0, (np.trace(r) - 1.0) / 2.0)))
    if angle < 1e-12:
        return np.zeros(3)
    axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if math.pi - angle < 1e-6:  # near a half turn: the axis from the symmetric part
        m = (r + np.eye(3)) / 2.0
        axis = m[:, int(np.argmax(np.diag(m)))]
        return math.pi * axis / np.linalg.norm(axis)
    return angle * axis / np.linalg.norm(axis)


def ur10_measurements(mechanism_name: str, n_identification: int = 15, noise: dict | None = None,
                      position_only: bool = False) -> tuple[str, str]:
    """The source CSV as two ``hyperstat measurements`` files (identification, validation), text.

    The first ``n_identification`` poses (in the source's order) identify, the rest are held out.
    """
    noise = dict(UR10_NOISE, **(noise or {}))
    with open(UR10_CSV, newline="") as f:
        rows = list(csv.DictReader(f))
    head = ["# hyperstat measurements, version 1", f"# mechanism: {mechanism_name}",
            "# source: FIGAROH examples/ur10/data/calibration.csv (Apache-2.0), converted by "
            "tests/solver/diagnosis/real_data.py",
            f"# noise: {noise['position_mm']} mm + 0 mm/m"]
    cols = ["pose"] + [f"q{j}[rad]" for j in JOINTS] + ["x[mm]", "y[mm]", "z[mm]"]
    if not position_only:
        head.append(f"# orientation noise: {noise['orientation_rad']} rad")
        cols += ["rx[rad]", "ry[rad]", "rz[rad]"]
    lines = []
    for k, row in enumerate(rows):
        vals = [f"P{k + 1}"] + [row[j] for j in JOINTS] + [repr(1000.0 * float(row[a])) for a in ("x1", "y1", "z1")]
        if not position_only:
            rv = _rpy_to_rotvec(float(row["phix1"]), float(row["phiy1"]), float(row["phiz1"]))
            vals += [repr(float(v)) for v in rv]
        lines.append(",".join(vals))
    ident = head + [",".join(cols)] + lines[:n_identification]
    val = head + [",".join(cols)] + lines[n_identification:]
    return "\n".join(ident) + "\n", "\n".join(val) + "\n"
