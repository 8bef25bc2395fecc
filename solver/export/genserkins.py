"""LinuxCNC ``genserkins`` parameters (modified Denavit-Hartenberg, Craig) of a 6R serial robot.

Units: lengths in mm, angles in rad (``genserkins``' ``ALPHA-i`` pins are in rad; LinuxCNC's
joints and A B C in degrees).

``genserkins`` chains six links ``RotX(alpha_{i-1}) TransX(a_{i-1}) RotZ(theta_i)
TransZ(d_i)`` from the world frame to the last link's frame (pins ``A-k`` = ``a_k``,
``ALPHA-k`` = ``alpha_k``, ``D-k`` = ``d_{k+1}``, ``k`` = 0..5) with ``theta_i`` the LinuxCNC
joint value: no base transform, no tool transform, no joint offset.  A model fits when, at
its zero configuration, every joint axis is perpendicular to the world x axis, consecutive
axes are joined by lines along x, and the output frame is the last link's frame.  The
parameters are read off the (identified) model's joint axes at ``q = 0`` under that
structure; :func:`genserkins_parameters` then compares the DH chain with the model over
random configurations and reports the largest pose difference, and
:func:`refuse_unrepresentable` refuses the export above a threshold, as for ``genhexkins``.
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.frames import so3_log
from hyperstat.solver.kinematics.model import Joint

__all__ = ["genserkins_parameters", "dh_forward", "hal_lines", "refuse_unrepresentable"]


def _joints(mechanism) -> list[tuple[int, int]]:
    if mechanism.closures:
        raise DataError(f"genserkins needs a serial robot: '{mechanism.name}' has {len(mechanism.closures)} loop(s).")
    path = [e for e in mechanism.path_to(mechanism.output)
            if isinstance(mechanism.chains[e[0]].elements[e[1]], Joint)]
    types = "".join(mechanism.chains[c].elements[e].type for c, e in path)
    if types != "RRRRRR" or len(mechanism.joints) != 6 or len(mechanism.actuated) != 6:
        raise DataError(f"genserkins needs six actuated revolute joints in series: '{mechanism.name}' has "
                        f"{types or 'no joint'} on its output path.")
    return path


def dh_forward(a: np.ndarray, alpha: np.ndarray, d: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Poses (K, 4, 4) of the modified-DH chain ``prod RotX(alpha) TransX(a) RotZ(theta) TransZ(d)``.

    Examples
    --------
    >>> import numpy as np
    >>> t = dh_forward(np.array([0, 10, 0, 0, 0, 0.]), np.zeros(6), np.zeros(6), np.zeros((1, 6)))
    >>> t[0, :3, 3].tolist()
    [10.0, 0.0, 0.0]
    """
    theta = np.atleast_2d(theta)
    out = np.tile(np.eye(4), (len(theta), 1, 1))
    for i in range(6):
        ca, sa = np.cos(alpha[i]), np.sin(alpha[i])
        ct, st = np.cos(theta[:, i]), np.sin(theta[:, i])
        t = np.zeros((len(theta), 4, 4))
        t[:, 0, 0], t[:, 0, 1], t[:, 0, 3] = ct, -st, a[i]
        t[:, 1, 0], t[:, 1, 1], t[:, 1, 2], t[:, 1, 3] = st * ca, ct * ca, -sa, -sa * d[i]
        t[:, 2, 0], t[:, 2, 1], t[:, 2, 2], t[:, 2, 3] = st * sa, ct * sa, ca, ca * d[i]
        t[:, 3, 3] = 1.0
        out = out @ t
    return out


def genserkins_parameters(mechanism, xi: np.ndarray | None = None, samples: int = 200, seed: int = 0) -> dict:
    """Modified-DH parameters of a 6R robot for ``genserkins``, and what they miss of the model.

    Returns
    -------
    dict
        ``a``, ``alpha``, ``d`` (6 each; mm, rad, mm), ``max_position_difference_mm`` and
        ``max_rotation_difference_rad`` between the DH chain and the model over ``samples``
        random configurations in the joint ranges.
    """
    path = _joints(mechanism)
    kin = Kinematics(mechanism)
    q0 = np.zeros((1, len(mechanism.joints)))
    st = kin.evaluate(q0, xi, jacobians=False)
    frames = st.element_frames
    p = [frames[key][0, :3, 3] for key in path]
    z = [frames[key][0, :3, 2] for key in path]
    ex = np.array([1.0, 0.0, 0.0])
    a, alpha, d = np.zeros(6), np.zeros(6), np.zeros(6)
    z_prev, origin = np.array([0.0, 0.0, 1.0]), np.zeros(3)
    meet = None  # where the x line of the previous frame meets the current axis
    for i in range(6):
        # alpha_{i}: from z_{i} (previous) to the next axis about x
        alpha[i] = np.arctan2(np.dot(np.cross(z_prev, z[i]), ex), np.dot(z_prev, z[i]))
        # the previous frame's x line, origin + t ex, meets axis i at p_i + u z_i
        sol = np.linalg.lstsq(np.column_stack([ex, -z[i]]), p[i] - origin, rcond=None)[0]
        a[i] = sol[0]
        meet = p[i] + sol[1] * z[i]
        if i < 5:
            # this frame's origin on axis i, where an x line reaches axis i+1
            sol = np.linalg.lstsq(np.column_stack([z[i], ex, -z[i + 1]]), p[i + 1] - meet, rcond=None)[0]
            new_origin = meet + sol[0] * z[i]
        else:
            new_origin = meet + np.dot(st.output_pose[0, :3, 3] - meet, z[i]) * z[i]
        d[i] = np.dot(new_origin - meet, z[i])
        z_prev, origin = z[i], new_origin
    rng = np.random.default_rng(seed)
    act = mechanism.actuated
    lo, hi = mechanism.ranges[act].T
    q = np.zeros((samples, len(mechanism.joints)))
    q[:, act] = lo + (hi - lo) * rng.random((samples, len(act)))
    model = kin.evaluate(q, xi, jacobians=False).output_pose
    order = [mechanism.joint_index[mechanism.chains[c].elements[e].name] for c, e in path]
    dh = dh_forward(a, alpha, d, q[:, order])
    dpos = np.linalg.norm(dh[:, :3, 3] - model[:, :3, 3], axis=1)
    drot = np.linalg.norm(so3_log(dh[:, :3, :3] @ np.transpose(model[:, :3, :3], (0, 2, 1))), axis=1)
    return {"a": a.tolist(), "alpha": alpha.tolist(), "d": d.tolist(), "joint_order": order,
            "max_position_difference_mm": float(dpos.max()), "max_rotation_difference_rad": float(drot.max()),
            "configurations_checked": samples}


def refuse_unrepresentable(params: dict, threshold_mm: float, mechanism_name: str, origin: str) -> None:
    """Raise when the DH chain's poses differ from the model by more than ``threshold_mm`` (or mrad-equivalent).

    Examples
    --------
    >>> refuse_unrepresentable({"max_position_difference_mm": 1e-12, "max_rotation_difference_rad": 1e-15},
    ...                        0.01, "robot", "given")
    """
    dpos, drot = params["max_position_difference_mm"], params["max_rotation_difference_rad"]
    if dpos > threshold_mm or drot * 1000.0 > threshold_mm:
        raise DataError(f"genserkins cannot represent the geometry of '{mechanism_name}': its modified-DH chain "
                        f"misses the model by up to {dpos:.3g} mm and {drot:.3g} rad, above the threshold "
                        f"{threshold_mm:.3g} mm ({origin}; rotations count as mm at 1 m); use the generated "
                        f"kinematics module (export-linuxcnc-kins) or raise --max-error.")


def hal_lines(params: dict) -> str:
    """HAL ``setp`` lines for ``genserkins`` (mm, rad)."""
    lines = ["# genserkins modified-DH geometry exported by hyperstat (lengths in mm, angles in rad)"]
    for k in range(6):
        lines += [f"setp genserkins.A-{k} {params['a'][k]:.12g}",
                  f"setp genserkins.ALPHA-{k} {params['alpha'][k]:.12g}",
                  f"setp genserkins.D-{k} {params['d'][k]:.12g}"]
    return "\n".join(lines) + "\n"


def ini_section() -> str:
    """The INI ``[KINS]`` section naming the module."""
    return "[KINS]\nKINEMATICS = genserkins\nJOINTS = 6\n"


def write_sim(directory, mechanism, params: dict, home: np.ndarray | None = None):
    """A simulated machine (INI, HAL) running LinuxCNC's ``genserkins`` with ``params``; returns the INI path.

    The machine of :func:`hyperstat.solver.export.linuxcnc_sim.write_sim` with ``X Y Z A B C``
    world coordinates, the HAL ``setp`` lines appended.
    """
    from hyperstat.solver.export import linuxcnc_sim

    return linuxcnc_sim.write_sim(directory, mechanism, "genserkins", {"coordinates": "XYZABC"}, home=home,
                                  extra_hal=hal_lines(params))
