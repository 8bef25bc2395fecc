"""The 6R serial arm of the peer benchmarks, its pinocchio twin and a naive numpy loop.

Units: lengths in mm, angles in rad.

One arm, three implementations of its forward kinematics and Jacobian:

* hyperstat, batched over configurations (:meth:`hyperstat.solver.kinematics.closure.Kinematics.forward`,
  :mod:`hyperstat.solver.kinematics.fastfk`);
* pinocchio (PyPI ``pin``), called once per configuration from Python, with a model
  built joint by joint from the *same* ``D`` matrices (``Kinematics.element_matrices``);
* a naive loop over configurations that multiplies 4x4 numpy matrices
  ``D_1 M_1(q_1) ... D_6 M_6(q_6) D_tool`` (paper 1, eq. 2) and builds the Jacobian
  column by column from the joint screws.

The arm is an industrial-like anthropomorphic 6R (shoulder offset, upper arm, forearm,
spherical-like wrist) drawn at home with :class:`hyperstat.solver.kinematics.build.MechanismBuilder`; the
benchmark evaluates it at a random small defect vector so that every ``D`` is a general
rigid transform (tilted axes, shifted origins), not an axis-aligned one.
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver import Kinematics, Mechanism, MechanismBuilder
from hyperstat.solver.kinematics.frames import motion_matrix
from hyperstat.solver.kinematics.model import Joint

__all__ = ["arm_6r", "arm_geometry", "pinocchio_arm", "naive_fk", "naive_fk_jacobian"]


def arm_6r() -> Mechanism:
    """An anthropomorphic 6R arm (mm): shoulder offset 150, upper arm 700, forearm 800, flange 100."""
    b = MechanismBuilder("arm_6r", base="R0", description="industrial-like 6R serial arm (benchmark)")
    b.revolute("1", (0, 0, 0), (0, 0, 1), role="actuated", defects="", range=(-np.pi, np.pi))
    b.revolute("2", (150, 0, 450), (0, 1, 0), role="actuated", range=(-2.0, 2.0))
    b.revolute("3", (150, 0, 1150), (0, 1, 0), role="actuated", range=(-2.5, 2.5))
    b.revolute("4", (300, 0, 1265), (1, 0, 0), role="actuated", range=(-np.pi, np.pi))
    b.revolute("5", (950, 0, 1265), (0, 1, 0), role="actuated", range=(-2.0, 2.0))
    b.revolute("6", (1040, 0, 1265), (1, 0, 0), role="actuated", range=(-np.pi, np.pi))
    b.fixed("7", (1140, 0, 1265), (1, 0, 0), (0, 0, -1), defects="IJKabcG")
    b.chain("arm", "R0", "T", ["1", "2", "3", "4", "5", "6", "7"])
    b.output = "T"
    return b.build()


def arm_geometry(kin: Kinematics, xi: np.ndarray | None) -> list[tuple[np.ndarray, str | None]]:
    """``(D, joint type or None)`` along the arm's single chain at defects ``xi``."""
    mech = kin.mechanism
    if len(mech.chains) != 1:
        raise ValueError("a serial mechanism (one chain) is expected")
    mats = kin.element_matrices(xi)
    return [(mats[(0, ei)], el.type if isinstance(el, Joint) else None) for ei, el in enumerate(mech.chains[0].elements)]


def pinocchio_arm(geometry: list[tuple[np.ndarray, str | None]]):
    """pinocchio model of a serial chain from its ``D`` matrices: joint placements = ``D``.

    Fixed elements between joints are folded into the next joint's placement; those after
    the last joint become the placement of an operational frame ``"output"``.

    Returns
    -------
    model, data, frame_id
    """
    import pinocchio as pin

    model = pin.Model()
    parent = 0
    pending = np.eye(4)
    for i, (d, typ) in enumerate(geometry):
        pending = pending @ d
        if typ is None:
            continue
        joint = pin.JointModelRZ() if typ == "R" else pin.JointModelPZ()
        parent = model.addJoint(parent, joint, pin.SE3(pending[:3, :3].copy(), pending[:3, 3].copy()), f"joint{i}")
        pending = np.eye(4)
    frame = pin.Frame("output", parent, pin.SE3(pending[:3, :3].copy(), pending[:3, 3].copy()), pin.FrameType.OP_FRAME)
    fid = model.addFrame(frame)
    return model, model.createData(), fid


def naive_fk(geometry: list[tuple[np.ndarray, str | None]], q: np.ndarray) -> np.ndarray:
    """Output pose per configuration by a Python loop of 4x4 products (K, 4, 4)."""
    out = np.empty((len(q), 4, 4))
    for k, qk in enumerate(q):
        t = np.eye(4)
        j = 0
        for d, typ in geometry:
            t = t @ d
            if typ is not None:
                t = t @ motion_matrix(typ, qk[j])
                j += 1
        out[k] = t
    return out


def naive_fk_jacobian(geometry: list[tuple[np.ndarray, str | None]], q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Output pose (K, 4, 4) and Jacobian (K, 6, n) rows ``(omega, v)`` at the output origin, per configuration."""
    n = sum(typ is not None for _, typ in geometry)
    poses = np.empty((len(q), 4, 4))
    jac = np.empty((len(q), 6, n))
    for k, qk in enumerate(q):
        t = np.eye(4)
        axes = []
        j = 0
        for d, typ in geometry:
            t = t @ d
            if typ is not None:
                axes.append((typ, t[:3, 2].copy(), t[:3, 3].copy()))
                t = t @ motion_matrix(typ, qk[j])
                j += 1
        p = t[:3, 3]
        for j, (typ, z, o) in enumerate(axes):
            if typ == "R":
                jac[k, :3, j] = z
                jac[k, 3:, j] = np.cross(z, p - o)
            else:
                jac[k, :3, j] = 0.0
                jac[k, 3:, j] = z
        poses[k] = t
    return poses, jac
