"""The calibrated serial robot for its controller: URDF and corrected DH / modified-DH tables.

Units: lengths in mm and angles in rad in the code; a URDF is written in metres (its
convention), a DH table in mm and deg (stated in the file).

* **URDF**: one link per joint; each joint's ``<origin>`` is the calibrated ``D`` of
  paper 1, eq. (2) (fixed elements before it folded in), its axis is z, and a fixed joint
  carries the tool frame.  The URDF's forward kinematics is then the calibrated model's,
  exactly up to the printing of floats (``repr``: round trip exact) and the roll-pitch-yaw
  conversion (round-off).
* **Corrected DH**: the nominal table the model was imported from (``metadata.dh``),
  with every ``a, alpha, d, theta`` (mastering offsets and link lengths) and the base and
  tool frames refitted by least squares to the calibrated model's tool poses over sampled
  configurations.  DH cannot represent every calibrated geometry (a tilt of a joint axis
  out of the common-normal plane of a parallel pair, the reason for Hayati's extra
  parameter), so the file states how far the table is from the calibrated model (max
  deviation of the tool origin and of points 100 mm along its axes, mm), and the export
  warns when that exceeds :data:`DH_WARN_MM`.

Examples
--------
>>> from hyperstat.solver.kinematics.robot_import import parse_dh_table, dh_to_mechanism
>>> t = parse_dh_table({"format": "hyperstat-dh", "version": 1, "name": "r2", "convention": "dh",
...                     "units": {"length": "mm", "angle": "deg"},
...                     "joints": [{"type": "R", "a": 100, "alpha": 0, "d": 0, "theta": 0},
...                                {"type": "R", "a": 50, "alpha": 0, "d": 0, "theta": 0}]})
>>> '<robot name="r2">' in urdf_text(dh_to_mechanism(t))
True
"""

from __future__ import annotations

import math
from xml.sax.saxutils import escape

import numpy as np

from hyperstat.solver.errors import ModelError
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Joint, Mechanism

__all__ = ["urdf_text", "rpy_of", "serial_matrices", "corrected_dh", "dh_forward", "dh_text", "DH_WARN_MM",
           "joint_variables_text", "joint_map_text"]

DH_WARN_MM = 0.01  #: a corrected DH table further than this from the calibrated model is reported loudly


def serial_matrices(mechanism: Mechanism, xi: np.ndarray | None = None) -> tuple[list, np.ndarray]:
    """Joints of a serial chain as ``(name, type, D, range)`` with fixed elements folded in, and the tool ``D``.

    Raises
    ------
    ModelError
        If the mechanism is not one serial chain.
    """
    if len(mechanism.chains) != 1 or mechanism.closures:
        raise ModelError(f"'{mechanism.name}' is not a serial robot (one chain, no loop): URDF and DH export "
                         f"apply to serial robots.")
    mats = Kinematics(mechanism).element_matrices(xi)
    joints = []
    pending = np.eye(4)
    for ei, el in enumerate(mechanism.chains[0].elements):
        pending = pending @ mats[(0, ei)]
        if isinstance(el, Joint):
            joints.append((el.name, el.type, pending, el.range))
            pending = np.eye(4)
    return joints, pending


def rpy_of(r: np.ndarray) -> tuple[float, float, float]:
    """Roll, pitch, yaw (rad) with ``r = Rz(yaw) Ry(pitch) Rx(roll)`` (the URDF convention)."""
    pitch = math.atan2(-r[2, 0], math.hypot(r[0, 0], r[1, 0]))
    if math.hypot(r[0, 0], r[1, 0]) < 1e-12:  # gimbal lock: put the whole turn in roll
        return math.atan2(-r[1, 2], r[1, 1]), pitch, 0.0
    return math.atan2(r[2, 1], r[2, 2]), pitch, math.atan2(r[1, 0], r[0, 0])


def _origin(t: np.ndarray) -> str:
    xyz = " ".join(repr(float(v) / 1000.0) for v in t[:3, 3])
    rpy = " ".join(repr(float(v)) for v in rpy_of(t[:3, :3]))
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def urdf_text(mechanism: Mechanism, xi: np.ndarray | None = None, name: str | None = None,
              comment: str = "", joint_map_file: str | None = None) -> str:
    """URDF of a serial robot at defects ``xi`` (the calibrated geometry), lengths in metres.

    Links ``base_link``, ``link_<joint>`` and ``tool``; joint ``<joint>`` turns about z of its
    origin frame (the model's ``L`` frame); the fixed joint ``tool_joint`` carries the tool frame
    (the model's output frame).  Effort and velocity limits are not calibration results and
    are written as 0 (fill them in from the robot's data sheet).  A comment says which joint
    variables the URDF expects: the model's, and, when the model carries a joint map (the
    controller's convention: signs, offsets, couplings such as FANUC's J2/J3), how the
    controller's joints give them, with the side file ``joint_map_file`` that holds the map.
    """
    joints, tool = serial_matrices(mechanism, xi)
    variables = joint_variables_text(mechanism, "revolute joints in rad, prismatic in m", joint_map_file)
    lines = ['<?xml version="1.0"?>', f"<!-- {escape(comment).replace('--', '- -')} -->" if comment else None,
             f"<!-- {escape(variables).replace('--', '- -')} -->",
             f'<robot name="{escape(name or mechanism.name)}">', '  <link name="base_link"/>']
    parent = "base_link"
    for jname, jtype, d, (lo, hi) in joints:
        child = f"link_{jname}"
        kind = "revolute" if jtype == "R" else "prismatic"
        f = 1.0 if jtype == "R" else 1e-3
        lines += [f'  <link name="{escape(child)}"/>',
                  f'  <joint name="{escape(jname)}" type="{kind}">',
                  f'    <parent link="{escape(parent)}"/>', f'    <child link="{escape(child)}"/>',
                  f"    {_origin(d)}", '    <axis xyz="0 0 1"/>',
                  f'    <limit lower="{lo * f!r}" upper="{hi * f!r}" effort="0" velocity="0"/>',
                  "  </joint>"]
        parent = child
    lines += ['  <link name="tool"/>', '  <joint name="tool_joint" type="fixed">',
              f'    <parent link="{escape(parent)}"/>', '    <child link="tool"/>', f"    {_origin(tool)}",
              "  </joint>", "</robot>"]
    return "\n".join(line for line in lines if line is not None) + "\n"


def joint_variables_text(mechanism: Mechanism, units: str, joint_map_file: str | None = None) -> str:
    """Which joint variables an exported file expects, in one paragraph (the joint map spelled out).

    Examples
    --------
    >>> from types import SimpleNamespace as S
    >>> robot = S(joints=[S(name="1", type="R"), S(name="2", type="R")], actuated=[0, 1],
    ...           metadata={"joint_map": {"units": {"angle": "deg"},
    ...                                   "joints": {"1": {"J1": -1}, "2": {"J2": 1, "J1": 1, "offset": 0.5}}}})
    >>> print(joint_variables_text(robot, "rad"))
    joint variables: the model's joints 1, 2 (rad), zero at the table's zero. They are NOT the controller's: with its joints (in deg) q1 = -J1; q2 = J2 + J1 + 0.5 (joint map, q_model = sum(coefficient * J) / ratio + offset); feeding the controller's values directly is wrong wherever a sign, an offset or a coupling differs.
    """
    names = [mechanism.joints[i].name for i in mechanism.actuated]
    text = f"joint variables: the model's joints {', '.join(names)} ({units}), zero at the table's zero."
    jm = mechanism.metadata.get("joint_map") if isinstance(mechanism.metadata, dict) else None
    if not jm:
        return text + " No joint map: the controller's joint values are these."
    rows = []
    for model_joint, entry in jm["joints"].items():
        ratio = float(entry.get("ratio", 1.0))
        terms = [(c, float(v)) for c, v in entry.items() if c not in ("ratio", "offset") and float(v) != 0.0]
        expr = ""
        for k, (c, v) in enumerate(terms):
            sign = "-" if v < 0 else ("" if k == 0 else "+")
            mag = "" if abs(v) == 1.0 else f"{abs(v):g} "
            expr += f"{' ' if k else ''}{sign}{' ' if sign and k else ''}{mag}{c}"
        if ratio != 1.0:
            expr = f"({expr}) / {ratio:g}"
        offset = float(entry.get("offset", 0.0))
        if offset:
            expr += f" {'-' if offset < 0 else '+'} {abs(offset):g}"
        rows.append(f"q{model_joint} = {expr}")
    kinds = {"angle" if mechanism.joints[i].type == "R" else "length" for i in mechanism.actuated}
    units_of = ", ".join(str(jm["units"][k]) for k in ("angle", "length") if k in kinds and k in jm["units"])
    where = f", in {joint_map_file}" if joint_map_file else ""
    return (text + f" They are NOT the controller's: with its joints (in {units_of}) " + "; ".join(rows)
            + f" (joint map{where}, q_model = sum(coefficient * J) / ratio + offset); feeding the controller's "
              f"values directly is wrong wherever a sign, an offset or a coupling differs.")


def joint_map_text(mechanism: Mechanism, exported: str) -> str | None:
    """The model's joint map as a YAML side file of an export (None without a map): readable by
    ``hyperstat identify --joint-map``."""
    import yaml

    jm = mechanism.metadata.get("joint_map") if isinstance(mechanism.metadata, dict) else None
    if not jm:
        return None
    head = (f"# joint map of {exported}: the controller's joints -> the joints of {exported}\n"
            f"# q_model = sum(coefficient * J) / ratio + offset, controller values and offsets in 'units'\n")
    return head + yaml.safe_dump({"joint_map": jm}, sort_keys=False, default_flow_style=None)


# ---------------------------------------------------------------------- corrected DH
def _dh(theta, d, a, alpha):
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    k = np.shape(theta)
    out = np.zeros(k + (4, 4))
    out[..., 0, :] = np.stack([ct, -st * ca, st * sa, a * ct], -1)
    out[..., 1, :] = np.stack([st, ct * ca, -ct * sa, a * st], -1)
    out[..., 2, 1], out[..., 2, 2], out[..., 2, 3] = sa, ca, d
    out[..., 3, 3] = 1.0
    return out


def _mdh(alpha, a, theta, d):
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    k = np.shape(theta)
    out = np.zeros(k + (4, 4))
    out[..., 0, :] = np.stack([ct, -st, np.zeros(k), a], -1)
    out[..., 1, :] = np.stack([st * ca, ct * ca, -sa, -sa * d], -1)
    out[..., 2, :] = np.stack([st * sa, ct * sa, ca, ca * d], -1)
    out[..., 3, 3] = 1.0
    return out


def _pose(v: np.ndarray) -> np.ndarray:
    from hyperstat.solver.kinematics.frames import make_transform, so3_exp

    return make_transform(so3_exp(v[:3]), v[3:])


def dh_forward(convention: str, rows: np.ndarray, types: list, base: np.ndarray, tool: np.ndarray,
               q: np.ndarray) -> np.ndarray:
    """Tool poses (K, 4, 4) of a DH table ``rows`` (n, 4) = ``a, alpha, d, theta`` (mm, rad)."""
    q = np.atleast_2d(q)
    t = np.broadcast_to(base, (len(q), 4, 4)).copy()
    for i, (a, alpha, d, theta) in enumerate(rows):
        th = theta + (q[:, i] if types[i] == "R" else 0.0)
        dd = d + (q[:, i] if types[i] == "P" else 0.0)
        if convention == "dh":
            m = _dh(th, np.broadcast_to(dd, th.shape), np.full(th.shape, a), np.full(th.shape, alpha))
        else:
            m = _mdh(np.full(th.shape, alpha), np.full(th.shape, a), th, np.broadcast_to(dd, th.shape))
        t = t @ m
    return t @ tool


def corrected_dh(mechanism: Mechanism, xi: np.ndarray, n_samples: int = 100, seed: int = 0) -> dict:
    """Corrected DH table of a calibrated robot imported from a DH table (mm, rad).

    Every ``a, alpha, d, theta`` and the base and tool frames (rotation vector and origin)
    are refitted (Gauss-Newton, minimum-norm steps) so that the table's tool frame follows the
    calibrated model's over ``n_samples`` configurations (tool origin and points 100 mm
    along its x, y, z axes).

    Returns
    -------
    dict
        ``convention``, ``rows`` (name, type, a, alpha, d, theta, and ``delta_*`` against the
        nominal table), ``base``, ``tool`` (4x4), ``max_deviation_mm`` and ``rms_deviation_mm``
        over the samples.

    Raises
    ------
    ModelError
        If the model was not imported from a DH table (no ``metadata.dh``).
    """

    dh = mechanism.metadata.get("dh") if isinstance(mechanism.metadata, dict) else None
    if not dh:
        raise ModelError(f"'{mechanism.name}' was not imported from a DH table: export the URDF instead "
                         f"(hyperstat export-urdf).")
    conv = dh["convention"]
    types = [r["type"] for r in dh["joints"]]
    nominal = np.array([[r["a"], r["alpha"], r["d"], r["theta"]] for r in dh["joints"]], dtype=float)
    base0, tool0 = np.array(dh["base"], float), np.array(dh["tool"], float)
    kin = Kinematics(mechanism)
    rng = np.random.default_rng(seed)
    lo, hi = mechanism.ranges[mechanism.actuated].T
    q = lo + rng.random((n_samples, len(lo))) * (hi - lo)
    target, _ = kin.forward(q, xi)
    probe = np.array([[0, 0, 0, 1], [100, 0, 0, 1], [0, 100, 0, 1], [0, 0, 100, 1]], float).T
    want = (target @ probe)[:, :3, :]
    n = len(types)

    # Unknowns: the n rows (a, alpha, d, theta), a base correction (6) applied before the base
    # frame, and a tool correction Ry(beta) Ty(t) before the tool frame (2).  theta_1 and d_1 stay
    # nominal (the base absorbs them) and the tool correction is restricted to what the last row
    # cannot do, so that the representation is unique.
    free = np.ones(4 * n, dtype=bool)
    free[[2, 3]] = False  # d_1, theta_1

    def unpack(x):
        rows = nominal.ravel().copy()
        rows[free] = x[:int(free.sum())]
        rest = x[int(free.sum()):]
        tool_fix = _pose(np.array([0.0, rest[6], 0.0, 0.0, rest[7], 0.0]))
        return rows.reshape(n, 4), _pose(rest[:6]) @ base0, tool_fix @ tool0


    x0 = np.r_[nominal.ravel()[free], np.zeros(8)]
    scale = np.r_[np.tile([1.0, 1e-3, 1.0, 1e-3], n)[free], [1e-3] * 3, [1.0] * 3, 1e-3, 1.0]
    # A weak pull towards the nominal table (1e-3 of a mm per scaled unit) keeps the near-parallel
    # pairs from running away: DH represents an out-of-plane tilt of parallel axes only through
    # huge d offsets (Hayati); what it cannot represent stays as the stated deviation.
    reg = 1e-3

    def resid(x):
        rows, b, t = unpack(x)
        got = (dh_forward(conv, rows, types, b, t, q) @ probe)[:, :3, :]
        return np.r_[(got - want).ravel(), reg * (x - x0) / scale]

    x = x0.copy()
    r = resid(x)
    for _ in range(30):
        jac = np.empty((len(r), len(x)))
        for j in range(len(x)):
            h = 1e-7 * scale[j]
            xp = x.copy()
            xp[j] += h
            jac[:, j] = (resid(xp) - r) / h
        step = np.linalg.lstsq(jac * scale, -r, rcond=1e-12)[0] * scale
        for _half in range(12):
            x_new = x + step
            r_new = resid(x_new)
            if r_new @ r_new < r @ r:
                break
            step = step / 2.0
        else:
            break
        x, r = x_new, r_new
        if np.max(np.abs(step / scale)) < 1e-12:
            break

    rows, b, t = unpack(x)
    dev = np.linalg.norm(r[:12 * n_samples].reshape(n_samples, 3, 4), axis=1)
    names = [r["name"] for r in dh["joints"]]
    out_rows = []
    for i, (name, ty) in enumerate(zip(names, types)):
        a, alpha, d, theta = rows[i]
        na, nal, nd, nth = nominal[i]
        out_rows.append({"name": name, "type": ty, "a": float(a), "alpha": float(alpha), "d": float(d),
                         "theta": float(theta), "delta_a": float(a - na), "delta_alpha": float(alpha - nal),
                         "delta_d": float(d - nd), "delta_theta": float(theta - nth)})
    return {"convention": conv, "rows": out_rows, "base": b, "tool": t, "max_deviation_mm": float(dev.max()),
            "rms_deviation_mm": float(np.sqrt(np.mean(dev**2))), "samples": n_samples}


def dh_text(mechanism: Mechanism, table: dict, comment: str = "") -> str:
    """The corrected table as a ``hyperstat-dh`` YAML file (mm, deg), with the nominal deltas as comments."""
    def frame(t: np.ndarray) -> str:
        rpy = [math.degrees(v) for v in rpy_of(t[:3, :3])]
        return (f"{{origin: [{', '.join(repr(float(v)) for v in t[:3, 3])}], "
                f"rpy: [{', '.join(repr(float(v)) for v in rpy)}]}}")

    lines = [f"# corrected {table['convention']} table of '{mechanism.name}' (hyperstat export-dh)"]
    lines += [f"# {line}" for line in comment.splitlines()]
    lines += [f"# {joint_variables_text(mechanism, 'rad or mm, added to theta or d')}"
              .replace(" (joint map, ", " (the joint_map below, ")]
    lines += [f"# reproduces the calibrated model to {table['max_deviation_mm']:.3g} mm max, "
              f"{table['rms_deviation_mm']:.3g} mm RMS over {table['samples']} configurations "
              f"(tool origin and points 100 mm along its axes)",
              "format: hyperstat-dh", "version: 1", f"name: {mechanism.name}", f"convention: {table['convention']}",
              "units: {length: mm, angle: deg}", f"base: {frame(table['base'])}", f"tool: {frame(table['tool'])}",
              "joints:"]
    ranges = {j.name: j.range for j in mechanism.joints}
    for r in table["rows"]:
        lo, hi = ranges[r["name"]]
        f = math.degrees(1.0) if r["type"] == "R" else 1.0
        lines.append(f"  - {{name: \"{r['name']}\", type: {r['type']}, a: {r['a']!r}, "
                     f"alpha: {math.degrees(r['alpha'])!r}, d: {r['d']!r}, theta: {math.degrees(r['theta'])!r}, "
                     f"min: {lo * f!r}, max: {hi * f!r}}}"
                     f"  # delta a {r['delta_a']:+.4f} mm, alpha {math.degrees(r['delta_alpha']):+.5f} deg, "
                     f"d {r['delta_d']:+.4f} mm, theta {math.degrees(r['delta_theta']):+.5f} deg")
    jm = mechanism.metadata.get("joint_map") if isinstance(mechanism.metadata, dict) else None
    if jm:
        import yaml

        lines.append(yaml.safe_dump({"joint_map": jm}, sort_keys=False, default_flow_style=None).rstrip())
    return "\n".join(lines) + "\n"
