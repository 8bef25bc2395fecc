"""Serial robots from Denavit-Hartenberg tables (YAML, CSV) and URDF, as a :class:`Mechanism`.

Units: lengths in mm, angles in rad inside the code.  A table states its own units
(``mm`` or ``m``, ``deg`` or ``rad``) and every value is converted explicitly; a table
without units is refused.

Conventions
-----------
* **Standard DH** (``convention: dh``): ``T_i = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``;
  joint ``i`` turns about ``z_{i-1}``.  A prismatic joint adds ``q_i`` to ``d_i``.
* **Modified DH** (Craig, ``convention: modified-dh``): ``T_i = Rx(alpha_{i-1}) Tx(a_{i-1})
  Rz(theta_i + q_i) Tz(d_i)``; row ``i`` of the table holds ``alpha_{i-1}, a_{i-1}, theta_i, d_i``.

Both become the joint-invariant chain of paper 1, eq. (2): the joint frame ``L_i`` sits on
the joint axis (its origin at the foot of the common normal, ``theta_i`` turns it), the
motion ``M_i(q_i)`` is the controller-free model joint value (``q_i = 0`` at the table's
zero), and the constant part after the motion moves into the next element's ``D``.
The first joint carries no defect (its placement is absorbed by the measurement frame),
every other revolute ``IJKabc`` and prismatic ``IJK``, and the tool a full rigid defect
``IJKabcG``, so that the identifiable count is eq. (1), ``4R + 2P + 6``.

A URDF is read with ``yourdfpy`` (a maintained URDF parser): the chain from the root link
to the tip link, fixed joints merged into the next element, revolute / continuous /
prismatic joints about their declared axis.

Examples
--------
>>> t = parse_dh_table({"format": "hyperstat-dh", "version": 1, "name": "r2", "convention": "dh",
...                     "units": {"length": "mm", "angle": "deg"},
...                     "joints": [{"type": "R", "a": 100, "alpha": 0, "d": 0, "theta": 0},
...                                {"type": "R", "a": 50, "alpha": 0, "d": 0, "theta": 0}]})
>>> m = dh_to_mechanism(t)
>>> [j.name for j in m.joints]
['1', '2']
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hyperstat.solver.errors import DataError, ModelError
from hyperstat.solver.kinematics.frames import axis_frame, make_transform
from hyperstat.solver.kinematics.joint_map import JointMap, joint_map_from_dict, unit_factor
from hyperstat.solver.kinematics.model import Chain, Defect, FixedTransform, Joint, Mechanism, Placement

__all__ = ["DHJoint", "DHTable", "read_dh_table", "parse_dh_table", "dh_to_mechanism", "dh_link_matrices",
           "dh_table_to_dict", "read_urdf", "import_robot", "rpy_matrix", "CONVENTIONS"]

CONVENTIONS = ("dh", "modified-dh")
_FORMAT = "hyperstat-dh"


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _tx(v: float) -> np.ndarray:
    t = np.eye(4)
    t[0, 3] = v
    return t


def _tz(v: float) -> np.ndarray:
    t = np.eye(4)
    t[2, 3] = v
    return t


def rpy_matrix(rpy) -> np.ndarray:
    """Rotation of roll-pitch-yaw angles (rad) as URDF defines it: ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


@dataclass
class DHJoint:
    """One row of a DH table (mm, rad).

    For ``convention="dh"`` the row is ``theta_i, d_i, a_i, alpha_i`` of
    ``Rz(theta + q) Tz(d) Tx(a) Rx(alpha)``; for ``"modified-dh"`` it is
    ``alpha_{i-1}, a_{i-1}, theta_i, d_i`` of ``Rx(alpha) Tx(a) Rz(theta + q) Tz(d)``.
    """

    name: str
    type: str
    a: float
    alpha: float
    d: float
    theta: float
    range: tuple[float, float]


@dataclass
class DHTable:
    """A serial robot as a DH table (mm, rad).

    Attributes
    ----------
    name : str
        Robot name.
    convention : {"dh", "modified-dh"}
        Table convention.
    joints : list of DHJoint
        Rows, base to tip.
    base : ndarray, (4, 4)
        World (robot base) to frame 0 of the table.
    tool : ndarray, (4, 4)
        Last table frame to the tool (flange) frame.
    joint_map : JointMap or None
        Controller convention, if declared.
    source : str
        File name, for messages.
    """

    name: str
    convention: str
    joints: list
    base: np.ndarray = field(default_factory=lambda: np.eye(4))
    tool: np.ndarray = field(default_factory=lambda: np.eye(4))
    joint_map: JointMap | None = None
    source: str = "DH table"


def dh_link_matrices(table: DHTable) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Constant parts before and after the joint motion of every row.

    Returns ``(pre, post)`` with ``T_i = pre_i M(q_i) post_i`` (the motion about / along z):
    standard DH ``pre = Rz(theta) Tz(d)``, ``post = Tx(a) Rx(alpha)``; modified DH
    ``pre = Rx(alpha) Tx(a) Rz(theta) Tz(d)``, ``post = I``.
    """
    pre, post = [], []
    for j in table.joints:
        if table.convention == "dh":
            pre.append(_rz(j.theta) @ _tz(j.d))
            post.append(_tx(j.a) @ _rx(j.alpha))
        else:
            pre.append(_rx(j.alpha) @ _tx(j.a) @ _rz(j.theta) @ _tz(j.d))
            post.append(np.eye(4))
    return pre, post


def _home(lo: float, hi: float) -> float:
    return 0.0 if lo <= 0.0 <= hi else 0.5 * (lo + hi)


def _chain_mechanism(name: str, elements: list, tool: np.ndarray, description: str, metadata: dict) -> Mechanism:
    """Mechanism of one serial chain: ``elements`` = (joint name, type, D, range); ``tool`` the last D."""
    out = []
    for i, (jname, jtype, d, rng) in enumerate(elements):
        if i == 0:
            comps = ""
        else:
            comps = "IJKabc" if jtype == "R" else "IJK"
        out.append(Joint(jname, jtype, "actuated", Placement.from_matrix(_orthonormal(d)),
                         tuple(Defect(c, f"d{c}{jname}") for c in comps), (float(rng[0]), float(rng[1])),
                         _home(*rng)))
    names = [e[0] for e in elements]
    tool_name = str(len(elements) + 1) if all(n.isdigit() for n in names) else "tool"
    while tool_name in names:
        tool_name += "_"
    out.append(FixedTransform(tool_name, Placement.from_matrix(_orthonormal(tool)),
                              tuple(Defect(c, f"d{c}{tool_name}") for c in "IJKabcG")))
    try:
        return Mechanism(name, "R0", "T", (Chain("arm", "R0", "T", tuple(out)),), description, metadata)
    except ModelError as exc:
        raise ModelError(f"{name}: {exc}") from None


def _orthonormal(t: np.ndarray) -> np.ndarray:
    """Re-orthonormalise a rotation built from products of exact rotations (round-off only)."""
    u, _, vt = np.linalg.svd(t[:3, :3])
    out = t.copy()
    out[:3, :3] = u @ vt
    return out


def dh_to_mechanism(table: DHTable) -> Mechanism:
    """The joint-invariant model of a DH table (paper 1, eq. 2): ``D_1 = base pre_1``,
    ``D_i = post_{i-1} pre_i``, tool ``D = post_n tool``; model joint ``q_i`` is the table's joint
    variable (``q_i = 0`` at the table's zero).

    Returns
    -------
    Mechanism
        One chain ``arm`` from ``R0`` to the tool frame ``T``; the joint map (if any) and the
        table are kept in ``metadata``.
    """
    if not table.joints:
        raise ModelError(f"{table.source}: the table has no joints.")
    pre, post = dh_link_matrices(table)
    elements = []
    prev = table.base
    for j, p, q in zip(table.joints, pre, post):
        elements.append((j.name, j.type, prev @ p, j.range))
        prev = q
    metadata = {"imported_from": {"kind": table.convention, "source": str(table.source)},
                "dh": dh_table_to_dict(table)}
    if table.joint_map is not None:
        metadata["joint_map"] = table.joint_map.to_dict()
    return _chain_mechanism(table.name, elements, prev @ table.tool,
                            f"serial robot imported from a {table.convention} table", metadata)


def dh_table_to_dict(table: DHTable) -> dict:
    """The table as a dictionary in mm and rad (kept in the model's metadata)."""
    return {"convention": table.convention, "units": {"length": "mm", "angle": "rad"},
            "joints": [{"name": j.name, "type": j.type, "a": j.a, "alpha": j.alpha, "d": j.d, "theta": j.theta,
                        "min": j.range[0], "max": j.range[1]} for j in table.joints],
            "base": table.base.tolist(), "tool": table.tool.tolist()}


def _num(v: object, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        try:
            v = float(str(v).strip())
        except ValueError:
            raise DataError(f"{where} must be a number, got {v!r}.") from None
    v = float(v)
    if not math.isfinite(v):
        raise DataError(f"{where} must be finite, got {v!r}.")
    return v


def _frame(doc: object, lf: float, af: float, where: str) -> np.ndarray:
    if doc is None:
        return np.eye(4)
    if not isinstance(doc, dict) or set(doc) - {"origin", "rpy"}:
        raise DataError(f"{where} must be a mapping with 'origin' [x, y, z] and 'rpy' [roll, pitch, yaw].")
    o = doc.get("origin", [0, 0, 0])
    r = doc.get("rpy", [0, 0, 0])
    if not isinstance(o, list) or len(o) != 3 or not isinstance(r, list) or len(r) != 3:
        raise DataError(f"{where}: 'origin' and 'rpy' must be lists of three numbers.")
    origin = np.array([_num(v, f"{where}.origin[{i}]") for i, v in enumerate(o)]) * lf
    rpy = np.array([_num(v, f"{where}.rpy[{i}]") for i, v in enumerate(r)]) * af
    return make_transform(rpy_matrix(rpy), origin)


def parse_dh_table(doc: object, source: str = "DH table") -> DHTable:
    """A DH table from its YAML mapping (see ``docs/identification.md``).

    Raises
    ------
    DataError
        One sentence naming the file and the field at fault (missing units, unknown
        convention, a non-numeric value, an empty range...).
    """
    if not isinstance(doc, dict):
        raise DataError(f"{source}: a DH table must be a YAML mapping.")
    if doc.get("format") != _FORMAT:
        raise DataError(f"{source}: field 'format' must be '{_FORMAT}', got {doc.get('format')!r}.")
    if doc.get("version") != 1:
        raise DataError(f"{source}: field 'version' is {doc.get('version')!r}, but this hyperstat reads version 1.")
    conv = doc.get("convention")
    if conv not in CONVENTIONS:
        raise DataError(f"{source}: field 'convention' must be 'dh' or 'modified-dh', got {conv!r}.")
    units = doc.get("units")
    if not isinstance(units, dict) or "length" not in units or "angle" not in units:
        raise DataError(f"{source}: field 'units' must state both, e.g. {{length: mm, angle: deg}}.")
    lf = unit_factor(str(units["length"]), "length", f"{source}: units.length")
    af = unit_factor(str(units["angle"]), "angle", f"{source}: units.angle")
    rows = doc.get("joints")
    if not isinstance(rows, list) or not rows:
        raise DataError(f"{source}: field 'joints' must be a non-empty list of rows.")
    joints = []
    for i, row in enumerate(rows):
        where = f"{source}: joints[{i}]"
        if not isinstance(row, dict):
            raise DataError(f"{where} must be a mapping (type, a, alpha, d, theta).")
        unknown = set(row) - {"name", "type", "a", "alpha", "d", "theta", "min", "max"}
        if unknown:
            raise DataError(f"{where}: unknown field '{sorted(unknown)[0]}'.")
        joints.append(_row(row, i, lf, af, where))
    names = [j.name for j in joints]
    for n in names:
        if names.count(n) > 1:
            raise DataError(f"{source}: joint name '{n}' appears twice.")
    name = str(doc.get("name") or Path(str(source)).stem.split(".")[0])
    table = DHTable(name, conv, joints, _frame(doc.get("base"), lf, af, f"{source}: base"),
                    _frame(doc.get("tool"), lf, af, f"{source}: tool"), None, source)
    if doc.get("joint_map") is not None:
        table.joint_map = joint_map_from_dict(doc["joint_map"], {j.name: j.type for j in joints},
                                              f"{source}: joint_map")
    return table


def _row(row: dict, i: int, lf: float, af: float, where: str) -> DHJoint:
    jtype = str(row.get("type", "R")).upper()
    if jtype not in ("R", "P"):
        raise DataError(f"{where}.type must be R or P, got {row.get('type')!r}.")
    vals = {}
    for key in ("a", "alpha", "d", "theta"):
        if key not in row or row[key] is None or (isinstance(row[key], str) and not row[key].strip()):
            raise DataError(f"{where}.{key} is missing.")
        vals[key] = _num(row[key], f"{where}.{key}") * (lf if key in ("a", "d") else af)
    rf = af if jtype == "R" else lf
    lo = _num(row["min"], f"{where}.min") * rf if row.get("min") not in (None, "") else (-math.pi if jtype == "R" else -100.0)
    hi = _num(row["max"], f"{where}.max") * rf if row.get("max") not in (None, "") else (math.pi if jtype == "R" else 100.0)
    if not lo < hi:
        raise DataError(f"{where}: the range [min, max] must have min < max.")
    name = str(row.get("name", i + 1)).strip()
    if not name or not name.replace("_", "").isalnum():
        raise DataError(f"{where}.name must be letters, digits and _, got {row.get('name')!r}.")
    return DHJoint(name, jtype, vals["a"], vals["alpha"], vals["d"], vals["theta"], (lo, hi))


def _parse_csv(text: str, source: str) -> dict:
    """A CSV DH table as the YAML mapping: ``# key: value`` header lines, then named columns with units."""
    header: dict = {}
    lines = text.splitlines()
    body = 0
    for body, line in enumerate(lines):
        if line.startswith("#"):
            if ":" in line:
                k, v = line[1:].split(":", 1)
                header[k.strip().lower()] = v.strip()
            continue
        break
    reader = csv.reader(io.StringIO("\n".join(lines[body:])))
    try:
        cols = [c.strip() for c in next(reader)]
    except StopIteration:
        raise DataError(f"{source}: no column header line.") from None
    units: dict = {}
    names = []
    for c in cols:
        base, _, unit = c.partition("[")
        unit = unit.rstrip("]").strip()
        base = base.strip()
        names.append(base)
        if base in ("a", "d"):
            units.setdefault("length", unit)
            if unit != units["length"]:
                raise DataError(f"{source}: column '{c}' must use the same length unit as the others.")
        if base in ("alpha", "theta"):
            units.setdefault("angle", unit)
            if unit != units["angle"]:
                raise DataError(f"{source}: column '{c}' must use the same angle unit as the others.")
        if base in ("a", "d", "alpha", "theta") and not unit:
            raise DataError(f"{source}: column '{c}' must state its unit, e.g. '{base}[mm]' or '{base}[deg]'.")
        if base in ("min", "max") and unit and unit not in (units.get("angle", unit),):
            raise DataError(f"{source}: column '{c}' must use the angle unit of alpha and theta.")
    for need in ("a", "alpha", "d", "theta"):
        if need not in names:
            raise DataError(f"{source}: column '{need}' is missing (columns: joint, type, a[unit], alpha[unit], "
                            f"d[unit], theta[unit], min[unit], max[unit]).")
    rows = []
    for r, row in enumerate(reader, start=body + 2):
        if not row or all(not v.strip() for v in row):
            continue
        if len(row) != len(cols):
            raise DataError(f"{source}, row {r}: {len(row)} values for {len(cols)} columns.")
        d = {("name" if n == "joint" else n): v.strip() for n, v in zip(names, row)}
        rows.append(d)
    doc = {"format": _FORMAT, "version": 1, "name": header.get("name"), "convention": header.get("convention"),
           "units": units, "joints": rows}
    return doc


def read_dh_table(path: str | Path) -> DHTable:
    """Read a DH / modified-DH table from YAML (``.yaml``, ``.yml``) or CSV (``.csv``)."""
    import yaml

    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such file.")
    text = path.read_text(encoding="utf-8")
    if path.suffix.lower() == ".csv":
        doc = _parse_csv(text, str(path))
    else:
        try:
            doc = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise DataError(f"{path}: not valid YAML ({str(exc).splitlines()[0]}).") from None
    return parse_dh_table(doc, str(path))


def read_urdf(path: str | Path, tip: str | None = None, name: str | None = None) -> Mechanism:
    """The serial chain of a URDF, read with ``yourdfpy``, as a :class:`Mechanism` (mm, rad).

    The chain runs from the root link to ``tip`` (default: the only leaf reached through
    moving joints); fixed joints are merged into the next element's ``D``; a revolute,
    continuous or prismatic joint about the unit axis ``a`` becomes ``L = D R_a`` with
    ``R_a`` the frame whose z axis is ``a`` and the motion about z, followed by ``R_a^T``
    in the next ``D``, which is the URDF's rotation about ``a`` exactly.

    Raises
    ------
    ModelError
        If the file cannot be read, the tree is not a chain to ``tip``, or a joint type
        is not supported (floating, planar).
    """
    import yourdfpy

    path = Path(path)
    if not path.is_file():
        raise ModelError(f"{path}: no such URDF file.")
    try:
        robot = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False,
                                   build_collision_scene_graph=False, load_collision_meshes=False)
    except Exception as exc:  # yourdfpy raises several types on malformed XML
        raise ModelError(f"{path}: cannot read the URDF ({exc}).") from None
    joints = {j.child: j for j in robot.robot.joints}
    children: dict = {}
    for j in robot.robot.joints:
        children.setdefault(j.parent, []).append(j)
    links = [lk.name for lk in robot.robot.links]
    roots = [lk for lk in links if lk not in joints]
    if len(roots) != 1:
        raise ModelError(f"{path}: the URDF must have one root link, found {len(roots)}.")
    if tip is None:
        leaves = [lk for lk in links if lk not in children]

        def moving(link: str) -> int:
            count = 0
            while link in joints:
                count += joints[link].type != "fixed"
                link = joints[link].parent
            return count

        best = max(moving(lk) for lk in leaves)
        cands = [lk for lk in leaves if moving(lk) == best]
        if len(cands) != 1:
            raise ModelError(f"{path}: several tip links ({', '.join(cands)}); name one with --tip.")
        tip = cands[0]
    if tip not in links:
        raise ModelError(f"{path}: tip link '{tip}' is not in the URDF.")
    path_joints = []
    link = tip
    while link in joints:
        path_joints.append(joints[link])
        link = joints[link].parent
    path_joints.reverse()
    elements = []
    pending = np.eye(4)
    for j in path_joints:
        origin = np.array(j.origin if j.origin is not None else np.eye(4), dtype=float)
        origin[:3, 3] *= 1000.0  # URDF lengths are metres
        if j.type == "fixed":
            pending = pending @ origin
            continue
        if j.type not in ("revolute", "continuous", "prismatic"):
            raise ModelError(f"{path}: joint '{j.name}' is of type '{j.type}'; only revolute, continuous, "
                             f"prismatic and fixed joints form a serial chain here.")
        if j.mimic is not None:
            raise ModelError(f"{path}: joint '{j.name}' mimics another joint; mimic joints are not supported.")
        axis = np.array(j.axis if j.axis is not None else [1.0, 0.0, 0.0], dtype=float)
        ra = make_transform(axis_frame(axis / np.linalg.norm(axis)), np.zeros(3))
        jtype = "P" if j.type == "prismatic" else "R"
        if j.type == "continuous" or j.limit is None or j.limit.lower is None or j.limit.upper is None:
            rng = (-math.pi, math.pi) if jtype == "R" else (-100.0, 100.0)
        else:
            f = 1.0 if jtype == "R" else 1000.0
            rng = (float(j.limit.lower) * f, float(j.limit.upper) * f)
        elements.append((j.name, jtype, pending @ origin @ ra, rng))
        pending = ra.T.copy()
    if not elements:
        raise ModelError(f"{path}: no moving joint between the root link and '{tip}'.")
    metadata = {"imported_from": {"kind": "urdf", "source": str(path), "root": roots[0], "tip": tip}}
    mech = _chain_mechanism(name or robot.robot.name or path.stem, elements, pending,
                            f"serial robot imported from URDF {path.name}", metadata)
    masses = _urdf_masses(robot.robot, roots[0], [j.name for j in path_joints if j.type != "fixed"],
                          {j.name: j.home for j in mech.joints if hasattr(j, "home")}, path)
    if masses:
        metadata["masses"] = masses
    return mech


def _urdf_masses(robot, root: str, chain_joints: list, home: dict, path: Path) -> dict:
    """The link masses of a URDF as ``metadata.masses``: per moving joint of the chain, the body it moves.

    Every link with an ``<inertial>`` belongs to the body of the last chain joint on its path
    from the root (links before the first moving joint do not move and are left out; links
    hanging from joints off the chain, a gripper's fingers, are taken at those joints' zero).
    The body's mass is the sum of its links' masses and its centre of mass their
    mass-weighted centres, in the base (root link) frame at the home configuration, in mm.

    Raises
    ------
    DataError
        If an inertial states a negative or non-finite mass.
    """
    by_child = {j.child: j for j in robot.joints}
    frames: dict = {root: np.eye(4)}

    def frame(link: str) -> np.ndarray:
        if link not in frames:
            j = by_child[link]
            t = np.array(j.origin if j.origin is not None else np.eye(4), dtype=float)
            q = home.get(j.name, 0.0) if j.name in chain_joints else 0.0
            axis = np.array(j.axis if j.axis is not None else [1.0, 0.0, 0.0], dtype=float)
            axis = axis / np.linalg.norm(axis)
            motion = np.eye(4)
            if j.type in ("revolute", "continuous"):
                k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
                motion[:3, :3] = np.eye(3) + math.sin(q) * k + (1 - math.cos(q)) * k @ k
            elif j.type == "prismatic":
                motion[:3, 3] = axis * q / 1000.0  # model joint values in mm, URDF in m
            frames[link] = frame(j.parent) @ t @ motion
        return frames[link]

    def body_of(link: str) -> str | None:
        while link in by_child:
            j = by_child[link]
            if j.name in chain_joints:
                return j.name
            link = j.parent
        return None

    sums: dict = {}
    for lk in robot.links:
        inertial = getattr(lk, "inertial", None)
        if inertial is None or inertial.mass is None:
            continue
        m = float(inertial.mass)
        if not (math.isfinite(m) and m >= 0.0):
            raise DataError(f"{path}: link '{lk.name}' has an <inertial> mass of {inertial.mass!r}; a mass is a "
                            f"finite number >= 0 (kg).")
        body = body_of(lk.name)
        if body is None or m == 0.0:
            continue
        origin = np.array(inertial.origin if inertial.origin is not None else np.eye(4), dtype=float)
        com = (frame(lk.name) @ origin)[:3, 3] * 1000.0  # m -> mm, base frame at home
        entry = sums.setdefault(body, {"mass": 0.0, "moment": np.zeros(3), "links": []})
        entry["mass"] += m
        entry["moment"] += m * com
        entry["links"].append(lk.name)
    return {b: {"mass": e["mass"], "com": (e["moment"] / e["mass"]).tolist(),
                "source": f"URDF <inertial> of link{'s' if len(e['links']) > 1 else ''} {', '.join(e['links'])}"}
            for b, e in sums.items() if e["mass"] > 0.0}


def import_robot(path: str | Path, tip: str | None = None) -> Mechanism:
    """A serial robot from a DH table (``.yaml``, ``.yml``, ``.csv``) or a URDF (``.urdf``)."""
    path = Path(path)
    if path.suffix.lower() == ".urdf":
        return read_urdf(path, tip)
    if path.suffix.lower() in (".yaml", ".yml", ".csv"):
        return dh_to_mechanism(read_dh_table(path))
    raise DataError(f"{path}: unknown robot file kind '{path.suffix}'; use .yaml/.yml/.csv (DH table) or .urdf.")
