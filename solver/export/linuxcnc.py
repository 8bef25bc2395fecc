"""LinuxCNC ``genhexkins`` parameters for a 6-UPS hexapod (HAL ``setp`` lines and the INI ``[KINS]`` section).

Units: lengths in mm (``genhexkins`` is unit-agnostic: the machine's INI decides).

``genhexkins`` models a Gough-Stewart platform by six base joint centres ``base.N`` (base
frame) and six platform joint centres ``platform.N`` (platform frame); a strut length is
``|p + R a_N - b_N|``.  The centres are taken from the (identified) model at its home
configuration: the universal joint's origin of each leg and its spherical joint's origin
expressed in the output frame.  Defects that make a universal joint's axes miss each
other, or a leg's prismatic axis miss the joint centres, have no place in this model:
:func:`genhexkins_parameters` reports the largest strut-length difference between the
two models over a set of poses, so that the integrator knows what the export loses, and
:func:`refuse_unrepresentable` stops the export when that difference is above a
threshold (by default the calibration's noise floor): a controller that is off by more
than the measurements could see is not what the calibration found.  The generated
kinematics module (:mod:`hyperstat.solver.export.linuxcnc_kins`) carries every defect.
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.model import Joint

__all__ = ["genhexkins_parameters", "hal_lines", "ini_section", "strut_lengths", "refuse_unrepresentable",
           "noise_floor"]


def _legs(mechanism) -> list[tuple[int, int, int, str]]:
    """(chain, universal joint element, spherical joint element, leg joint name) per leg (6-UPS check)."""
    legs = []
    for ci, chain in enumerate(mechanism.chains):
        kinds = [(ei, el.type if isinstance(el, Joint) else "F", el) for ei, el in enumerate(chain.elements)]
        types = "".join(k[1] for k in kinds).rstrip("F")
        if types != "RRPRRR":
            raise DataError(f"genhexkins needs a 6-UPS hexapod: chain '{chain.name}' is {types or 'empty'}, "
                            f"not R R P R R R.")
        legs.append((ci, kinds[0][0], kinds[3][0], kinds[2][2].name))
    if len(legs) != 6:
        raise DataError(f"genhexkins needs six legs, '{mechanism.name}' has {len(legs)}.")
    return legs


def genhexkins_parameters(mechanism, xi: np.ndarray | None = None) -> dict:
    """Base and platform joint centres (6 x 3 each, mm) of the model with defects ``xi``.

    Returns
    -------
    dict
        ``base``, ``platform`` (lists of [x, y, z]), ``max_strut_difference_mm`` over 200
        random poses of the model's workspace (0 for the nominal model) and
        ``max_strut_difference_after_offset_mm``, what remains after the best constant offset
        per strut (the part a joint offset cannot take).
    """
    legs = _legs(mechanism)
    kin = Kinematics(mechanism)
    st = kin.evaluate(mechanism.home[None, :], xi, jacobians=False)
    out = st.output_pose[0]
    inv = np.linalg.inv(out)
    base, plat = [], []
    for ci, eu, es, _ in legs:
        base.append(st.element_frames[(ci, eu)][0][:3, 3])
        plat.append((inv @ np.r_[st.element_frames[(ci, es)][0][:3, 3], 1.0])[:3])
    base, plat = np.array(base), np.array(plat)
    rng = np.random.default_rng(0)
    act = mechanism.actuated
    lo, hi = mechanism.ranges[act].T
    qa = lo + (hi - lo) * (0.25 + 0.5 * rng.random((200, len(act))))
    res = kin.solve(qa, xi)
    ok = res.converged
    poses = kin.evaluate(res.q[ok], xi, jacobians=False).output_pose
    model_lengths = strut_lengths(base, plat, poses)
    order = [list(act).index(mechanism.joint_index[name]) for _, _, _, name in legs]
    signed = model_lengths - qa[ok][:, order]
    diff = np.abs(signed)
    after = np.abs(signed - signed.mean(axis=0))
    return {"base": base.tolist(), "platform": plat.tolist(), "max_strut_difference_mm": float(diff.max()),
            "max_strut_difference_after_offset_mm": float(after.max()), "poses_checked": int(ok.sum())}


def noise_floor(doc: dict) -> float | None:
    """Noise floor of a controller file's calibration (mm): the noise RMS, else the identification RMS."""
    stats = doc.get("statistics", {})
    if stats.get("noise_rms"):
        return float(stats["noise_rms"])
    ident = stats.get("identification") or {}
    return float(ident["rms"]) if ident.get("rms") else None


def refuse_unrepresentable(params: dict, threshold_mm: float, mechanism_name: str, origin: str) -> None:
    """Raise when genhexkins' strut lengths differ from the model by more than ``threshold_mm``.

    Parameters
    ----------
    params : dict
        :func:`genhexkins_parameters`.
    threshold_mm : float
        Largest acceptable strut-length difference (mm).
    mechanism_name, origin : str
        For the message (``origin`` says where the threshold comes from).

    Raises
    ------
    DataError
        One sentence: the difference, the threshold, and what to do.

    Examples
    --------
    >>> refuse_unrepresentable({"max_strut_difference_mm": 1e-13}, 0.01, "hexapod", "given")
    """
    diff = params["max_strut_difference_mm"]
    if diff > threshold_mm:
        after = params.get("max_strut_difference_after_offset_mm")
        extra = f" ({after:.3g} mm after a constant offset per strut)" if after is not None else ""
        raise DataError(f"genhexkins cannot represent the identified geometry of '{mechanism_name}': its strut "
                        f"lengths differ from the model by up to {diff:.3g} mm{extra}, above the threshold "
                        f"{threshold_mm:.3g} mm ({origin}); use the generated kinematics module "
                        f"(export-linuxcnc-kins) or raise --max-error.")


def strut_lengths(base: np.ndarray, platform: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Strut lengths ``|p + R a_N - b_N|`` (genhexkins' inverse kinematics) at output poses (K, 4, 4)."""
    pts = np.einsum("kij,nj->kni", poses[:, :3, :3], platform) + poses[:, None, :3, 3]
    return np.linalg.norm(pts - base[None], axis=2)


def hal_lines(params: dict) -> str:
    """HAL ``setp`` lines for ``genhexkins`` (mm)."""
    lines = ["# genhexkins geometry exported by hyperstat (lengths in mm)", "loadrt genhexkins"]
    for kind in ("base", "platform"):
        for n, p in enumerate(params[kind]):
            for axis, v in zip("xyz", p):
                lines.append(f"setp genhexkins.{kind}.{n}.{axis} {v:.12g}")
    return "\n".join(lines) + "\n"


def ini_section() -> str:
    """The INI ``[KINS]`` section naming the module."""
    return "[KINS]\nKINEMATICS = genhexkins\nJOINTS = 6\n"
