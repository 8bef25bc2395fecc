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
from hyperstat.solver.strict_load import load_yaml
from hyperstat.solver.plausibility import JOINT_ANGLE_LIMIT, TURN, finite, plausible_angle, plausible_length

__all__ = ["DHJoint", "DHTable", "read_dh_table", "parse_dh_table", "dh_to_mechanism", "dh_link_matrices",
           "dh_table_to_dict", "read_urdf", "check_urdf", "import_robot", "rpy_matrix", "CONVENTIONS"]

CONVENTIONS = ("dh", "modified-dh")
_CSV_ROW = object()  # key of a CSV row's line number in the table mapping
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


def _frame(doc: object, units: dict, where: str) -> np.ndarray:
    if doc is None:
        return np.eye(4)
    if not isinstance(doc, dict) or set(doc) - {"origin", "rpy"}:
        raise DataError(f"{where} must be a mapping with 'origin' [x, y, z] and 'rpy' [roll, pitch, yaw].")
    o = doc.get("origin", [0, 0, 0])
    r = doc.get("rpy", [0, 0, 0])
    if not isinstance(o, list) or len(o) != 3 or not isinstance(r, list) or len(r) != 3:
        raise DataError(f"{where}: 'origin' and 'rpy' must be lists of three numbers.")
    origin = np.array([_value(v, "length", units, f"{where}.origin[{i}]") for i, v in enumerate(o)])
    rpy = np.array([_value(v, "angle", units, f"{where}.rpy[{i}]") for i, v in enumerate(r)])
    return make_transform(rpy_matrix(rpy), origin)


def _value(v: object, kind: str, units: dict, where: str, limit: float | None = None) -> float:
    """A table value in mm or rad, refused beyond its plausibility range (a length of 100 m, a turn)."""
    raw = _num(v, where)
    if kind == "length":
        return plausible_length(raw, units["length"], where)
    return plausible_angle(raw, units["angle"], where, TURN if limit is None else limit)


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
    units = {"length": str(units["length"]), "angle": str(units["angle"])}
    unit_factor(units["length"], "length", f"{source}: units.length")
    unit_factor(units["angle"], "angle", f"{source}: units.angle")
    rows = doc.get("joints")
    if not isinstance(rows, list) or not rows:
        raise DataError(f"{source}: field 'joints' must be a non-empty list of rows.")
    joints = []
    for i, row in enumerate(rows):
        where = f"{source}: joints[{i}]"
        if not isinstance(row, dict):
            raise DataError(f"{where} must be a mapping (type, a, alpha, d, theta).")
        line = None
        if _CSV_ROW in row:  # a CSV table: name its line
            row = dict(row)
            line = row.pop(_CSV_ROW)
            where = f"{source}, row {line}"
        unknown = set(row) - {"name", "type", "a", "alpha", "d", "theta", "min", "max"}
        if unknown:
            raise DataError(f"{where}: unknown field '{sorted(unknown)[0]}'.")
        joints.append(_row(row, i, units, where, line))
    names = [j.name for j in joints]
    for n in names:
        if names.count(n) > 1:
            raise DataError(f"{source}: joint name '{n}' appears twice.")
    name = str(doc.get("name") or Path(str(source)).stem.split(".")[0])
    table = DHTable(name, conv, joints, _frame(doc.get("base"), units, f"{source}: base"),
                    _frame(doc.get("tool"), units, f"{source}: tool"), None, source)
    if doc.get("joint_map") is not None:
        table.joint_map = joint_map_from_dict(doc["joint_map"], {j.name: j.type for j in joints},
                                              f"{source}: joint_map")
    return table


def _row(row: dict, i: int, units: dict, where: str, csv_line: int | None = None) -> DHJoint:
    def field(key: str) -> str:  # 'joints[2].alpha' in YAML, "row 4, column 'alpha'" in CSV
        return f"{where}, column '{key}'" if csv_line is not None else f"{where}.{key}"

    jtype = str(row.get("type", "R")).upper()
    if jtype not in ("R", "P"):
        raise DataError(f"{field('type')} must be R or P, got {row.get('type')!r}.")
    vals = {}
    for key in ("a", "alpha", "d", "theta"):
        if key not in row or row[key] is None or (isinstance(row[key], str) and not row[key].strip()):
            raise DataError(f"{field(key)} is missing.")
        vals[key] = _value(row[key], "length" if key in ("a", "d") else "angle", units, field(key))
    kind = "angle" if jtype == "R" else "length"
    bounds = []
    for key, default in (("min", -math.pi if jtype == "R" else -100.0), ("max", math.pi if jtype == "R" else 100.0)):
        given = row.get(key) not in (None, "")
        bounds.append(_value(row[key], kind, units, field(key), JOINT_ANGLE_LIMIT) if given else default)
    lo, hi = bounds
    if not lo < hi:
        raise DataError(f"{where}: the range [min, max] must have min < max.")
    name = str(row.get("name", i + 1)).strip()
    if not name or not name.replace("_", "").isalnum():
        raise DataError(f"{field('name')} must be letters, digits and _, got {row.get('name')!r}.")
    return DHJoint(name, jtype, vals["a"], vals["alpha"], vals["d"], vals["theta"], (lo, hi))


_CSV_HEADERS = ("name", "convention")  #: the ``# key: value`` lines a CSV DH table reads


def _parse_csv(text: str, source: str) -> dict:
    """A CSV DH table as the YAML mapping: ``# key: value`` header lines, then named columns with units."""
    header: dict = {}
    lines = text.splitlines()
    body = 0
    for body, line in enumerate(lines):
        if line.startswith("#"):
            if ":" in line:
                k, v = line[1:].split(":", 1)
                key = k.strip().lower()
                if key and " " not in key and key not in _CSV_HEADERS:
                    # a one-word header the CSV form does not read (a tool or a base frame): never silently dropped
                    raise DataError(f"{source}, line {body + 1}: header '{k.strip()}' is not read from a CSV DH table "
                                    f"(it reads {', '.join(repr(h) for h in _CSV_HEADERS)}); write the table in the "
                                    f"YAML form for a tool frame (tool: {{origin: [x, y, z], rpy: [r, p, y]}}), or "
                                    f"put a space in the comment's first words.")
                if key in header:
                    raise DataError(f"{source}, line {body + 1}: header '{k.strip()}' is declared twice.")
                header[key] = v.strip()
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
        if base in names:
            raise DataError(f"{source}: column '{base}' appears twice.")
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
        d[_CSV_ROW] = r
        rows.append(d)
    doc = {"format": _FORMAT, "version": 1, "name": header.get("name"), "convention": header.get("convention"),
           "units": units, "joints": rows}
    return doc


def read_dh_table(path: str | Path) -> DHTable:
    """Read a DH / modified-DH table from YAML (``.yaml``, ``.yml``) or CSV (``.csv``)."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such file.")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise DataError(f"{path}: not UTF-8 text.") from None
    if path.suffix.lower() == ".csv":
        doc = _parse_csv(text, str(path))
    else:
        doc = load_yaml(text, str(path))
    return parse_dh_table(doc, str(path))


_URDF_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")


def _urdf_numbers(text: str | None, count: int, where: str) -> list[float]:
    """``count`` numbers of a URDF attribute (``xyz``, ``rpy``), refused when missing or not finite."""
    parts = (text or "").split()
    if len(parts) != count:
        raise ModelError(f"{where} must hold {count} numbers, got {text!r}.")
    try:
        values = [float(v) for v in parts]
    except ValueError:
        raise ModelError(f"{where} must hold {count} numbers, got {text!r}.") from None
    for v in values:
        finite(v, where, error=ModelError)
    return values


#: largest plausible mass of one URDF link before its size is known (kg): beyond, a typing error whatever the link
URDF_MASS_LIMIT_KG = 1e6


def _check_inertial(link, where: str) -> None:
    """A link's ``<inertial>``: at most one, with at most one ``<mass>``, ``<origin>`` and ``<inertia>`` each,
    every value finite, the mass >= 0 (and below :data:`URDF_MASS_LIMIT_KG`), the origin within 100 m.

    A URDF reader keeps one of two ``<inertial>`` elements (or of two masses) silently; the other one's mass
    would be lost without a word.
    """
    inertials = link.findall("inertial")
    if len(inertials) > 1:
        raise ModelError(f"{where} declares <inertial> {len(inertials)} times; a link has one (a URDF reader keeps "
                         f"one silently): merge them into one with the link's whole mass.")
    if not inertials:
        return
    inertial = inertials[0]
    for tag in ("mass", "origin", "inertia"):
        if len(inertial.findall(tag)) > 1:
            raise ModelError(f"{where}: its <inertial> declares <{tag}> {len(inertial.findall(tag))} times.")
    mass = inertial.find("mass")
    if mass is not None:
        m = _urdf_numbers(mass.get("value"), 1, f"{where}: <inertial> mass value")[0]
        if not 0.0 <= m <= URDF_MASS_LIMIT_KG:
            raise ModelError(f"{where}: <inertial> mass value {m:g} kg is not a plausible link mass (a mass is >= 0 "
                             f"and no robot link weighs {URDF_MASS_LIMIT_KG:g} kg).")
    origin = inertial.find("origin")
    if origin is not None:
        for v, axis in zip(_urdf_numbers(origin.get("xyz", "0 0 0"), 3, f"{where}: <inertial> origin xyz"), "xyz"):
            if abs(v) > 100.0:  # URDF lengths are metres; a centre of mass 100 m out is no link's
                raise ModelError(f"{where}: <inertial> origin {axis} = {v:g} m puts the centre of mass beyond 100 m "
                                 f"from the link's frame: not a plausible link.")
        for v, axis in zip(_urdf_numbers(origin.get("rpy", "0 0 0"), 3, f"{where}: <inertial> origin rpy"),
                           ("roll", "pitch", "yaw")):
            plausible_angle(v, "rad", f"{where}: <inertial> origin {axis}", error=ModelError)
    inertia = inertial.find("inertia")
    if inertia is not None:
        for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
            _urdf_numbers(inertia.get(key, "0"), 1, f"{where}: <inertial> inertia {key}")


def check_urdf(path: str | Path) -> None:
    """Refuse a malformed URDF before it is read: one sentence naming the joint or link at fault.

    Checked on the XML itself (``xml.etree``, no entity expansion beyond expat's limits), for
    every joint, not only those of the imported chain, so that nothing is silently dropped:
    unique link and joint names; every joint's parent and child links declared; a tree (one
    root link, no link the child of two joints, no closed loop); a known joint type; origins
    finite and within 100 m, roll-pitch-yaw within a turn (more "looks like degrees"); a
    moving joint's axis a finite, non-zero direction; limits finite and plausible (a revolute
    joint within two turns, a prismatic one within 100 m), lower < upper; a mimic joint names
    an existing joint; a link's ``<inertial>`` declared once, its values finite, its mass >= 0
    and its origin within 100 m (:func:`_check_inertial`).  Mimic joints on the imported chain are
    refused by :func:`read_urdf`; masses against the links' sizes are checked by :func:`_urdf_masses`.

    Raises
    ------
    ModelError
    """
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ModelError(f"{path}: cannot read the URDF (not well-formed XML: {exc}).") from None
    if root.tag != "robot":
        raise ModelError(f"{path}: the top element is <{root.tag}>, not <robot>: not a URDF.")
    links = [lk.get("name") for lk in root.findall("link")]
    for i, lk in enumerate(links):
        if not lk:
            raise ModelError(f"{path}: link {i + 1} has no name.")
        if links.count(lk) > 1:
            raise ModelError(f"{path}: link '{lk}' is declared twice.")
    for lk in root.findall("link"):
        _check_inertial(lk, f"{path}: link '{lk.get('name')}'")
    joints = root.findall("joint")
    names = [j.get("name") for j in joints]
    parent_of: dict[str, str] = {}
    for i, j in enumerate(joints):
        jn = names[i]
        if not jn:
            raise ModelError(f"{path}: joint {i + 1} has no name.")
        if names.count(jn) > 1:
            raise ModelError(f"{path}: joint '{jn}' is declared twice.")
        where = f"{path}: joint '{jn}'"
        jtype = j.get("type")
        if jtype not in _URDF_JOINT_TYPES:
            raise ModelError(f"{where} has type {jtype!r}; URDF joint types are {', '.join(_URDF_JOINT_TYPES)}.")
        ends = {}
        for end in ("parent", "child"):
            el = j.find(end)
            ends[end] = None if el is None else el.get("link")
            if not ends[end]:
                raise ModelError(f"{where} has no <{end} link=...>.")
            if ends[end] not in links:
                raise ModelError(f"{where} names {end} link '{ends[end]}', which the URDF does not declare "
                                 f"(links: {', '.join(links)}).")
        if ends["parent"] == ends["child"]:
            raise ModelError(f"{where} joins link '{ends['child']}' to itself: a closed loop, which a URDF tree "
                             f"cannot hold.")
        if ends["child"] in parent_of:
            raise ModelError(f"{path}: link '{ends['child']}' is the child of two joints ('{parent_of[ends['child']]}' "
                             f"and '{jn}'): a closed loop, which a URDF tree cannot hold (hyperstat imports serial "
                             f"chains from URDF; describe a parallel mechanism as a model file).")
        parent_of[ends["child"]] = jn
        origin = j.find("origin")
        if origin is not None:
            for v, axis in zip(_urdf_numbers(origin.get("xyz", "0 0 0"), 3, f"{where}: origin xyz"), "xyz"):
                plausible_length(v, "m", f"{where}: origin {axis}", error=ModelError)
            for v, axis in zip(_urdf_numbers(origin.get("rpy", "0 0 0"), 3, f"{where}: origin rpy"),
                               ("roll", "pitch", "yaw")):
                plausible_angle(v, "rad", f"{where}: origin {axis}", error=ModelError)
        if jtype in ("revolute", "continuous", "prismatic"):
            axis_el = j.find("axis")
            axis = _urdf_numbers(axis_el.get("xyz") if axis_el is not None else "1 0 0", 3, f"{where}: axis xyz")
            if math.hypot(*axis) < 1e-9:
                raise ModelError(f"{where}: axis xyz=\"{axis_el.get('xyz')}\" is not a direction (zero length).")
        limit = j.find("limit")
        if jtype in ("revolute", "prismatic") and limit is not None:
            bound = []
            for key in ("lower", "upper"):
                v = _urdf_numbers(limit.get(key, "0"), 1, f"{where}: limit {key}")[0]
                if jtype == "revolute":
                    plausible_angle(v, "rad", f"{where}: limit {key}", JOINT_ANGLE_LIMIT, error=ModelError)
                else:
                    plausible_length(v, "m", f"{where}: limit {key}", error=ModelError)
                bound.append(v)
            if not bound[0] < bound[1]:
                raise ModelError(f"{where}: limit lower {bound[0]:g} must be below upper {bound[1]:g} (a joint that "
                                 f"cannot move is a fixed joint).")
        mimic = j.find("mimic")
        if mimic is not None and mimic.get("joint") not in names:
            raise ModelError(f"{where} mimics joint {mimic.get('joint')!r}, which the URDF does not declare.")
    roots = [lk for lk in links if lk not in parent_of]
    if not roots:
        raise ModelError(f"{path}: every link is the child of a joint, so the joints form a closed loop; a URDF is "
                         f"a tree from one root link.")
    if len(roots) > 1:
        raise ModelError(f"{path}: the URDF must have one root link, found {len(roots)} ({', '.join(roots)}): "
                         f"links not connected by joints.")
    child_of = {}
    for j, jn in zip(joints, names):
        child_of.setdefault(j.find("parent").get("link"), []).append(j.find("child").get("link"))
    reached, todo = {roots[0]}, [roots[0]]
    while todo:
        for c in child_of.get(todo.pop(), []):
            if c not in reached:
                reached.add(c)
                todo.append(c)
    lost = [lk for lk in links if lk not in reached]
    if lost:  # one root, one parent each, yet unreachable: a loop away from the root
        raise ModelError(f"{path}: links {', '.join(lost)} are not reached from the root link '{roots[0]}': their "
                         f"joints form a closed loop.")


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
    check_urdf(path)
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
        axis = axis / np.max(np.abs(axis))  # a direction of any size (check_urdf refused a zero one)
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
    masses, unknown = _urdf_masses(robot.robot, roots[0], [j.name for j in path_joints if j.type != "fixed"],
                                   {j.name: j.home for j in mech.joints if hasattr(j, "home")}, path)
    if masses:
        metadata["masses"] = masses
        # the bodies as the model file will carry them (joint frames only, no geometry) must pass the check every
        # command that reads that file makes: a link's mass can pass against its own geometry and its body fail
        from hyperstat.solver.kinematics.masses import check_declared_masses

        check_declared_masses(mech, f"{path} (the <inertial> masses, summed per moving body as the model file "
                                    f"carries them)", DataError)
    if unknown:  # a moving body without a mass: unknown, so no masses at all (never massless)
        metadata["masses_unknown"] = unknown
    return mech


def _urdf_masses(robot, root: str, chain_joints: list, home: dict, path: Path) -> tuple[dict, list]:
    """The link masses of a URDF as ``metadata.masses``: per moving joint of the chain, the body it moves.

    Every link with an ``<inertial>`` belongs to the body of the last chain joint on its path
    from the root (links before the first moving joint do not move and are left out; links
    hanging from joints off the chain, a gripper's fingers, are taken at those joints' zero).
    The body's mass is the sum of its links' masses and its centre of mass their
    mass-weighted centres, in the base (root link) frame at the home configuration, in mm.

    Each link's mass and centre of mass are checked against its extent
    (:func:`hyperstat.solver.kinematics.masses.check_body_mass`: its frame origin, the origins of
    the joints it carries and its visual and collision geometry, widened by a fifth of the chain's
    reach).  A moving body is *unknown* when none of its links has an ``<inertial>`` or one of them
    has geometry (it is a real part) but no ``<inertial>``: then no masses are returned at all (a
    partial set would make that body massless), and the unknown bodies are listed.

    Returns
    -------
    masses : dict
        Joint -> ``{"mass", "com", "source"}`` (empty when a body is unknown).
    unknown : list of dict
        ``joint`` and ``links`` (those without ``<inertial>``) of every unknown body.

    Raises
    ------
    DataError
        If a link's mass or centre of mass is implausible for its extent.
    """
    from hyperstat.solver.kinematics.masses import check_body_mass, chain_reach

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

    children: dict = {}
    for j in robot.joints:
        children.setdefault(j.parent, []).append(j)

    def extent(lk) -> list:
        """Points (mm, base frame at home) link ``lk`` spans: its origin, its child joints, its geometry."""
        f = frame(lk.name)
        pts = [f[:3, 3]]
        for j in children.get(lk.name, []):
            t = np.array(j.origin if j.origin is not None else np.eye(4), dtype=float)
            pts.append((f @ t)[:3, 3])
        for shape in list(getattr(lk, "visuals", None) or []) + list(getattr(lk, "collisions", None) or []):
            g = getattr(shape, "geometry", None)
            if g is None:
                continue
            o = np.array(shape.origin if getattr(shape, "origin", None) is not None else np.eye(4), dtype=float)
            centre = (f @ o)[:3, 3]
            r = 0.0
            if getattr(g, "box", None) is not None:
                r = 0.5 * float(np.linalg.norm(np.asarray(g.box.size, dtype=float)))
            elif getattr(g, "cylinder", None) is not None:
                r = math.hypot(float(g.cylinder.radius), 0.5 * float(g.cylinder.length))
            elif getattr(g, "sphere", None) is not None:
                r = float(g.sphere.radius)
            if not (math.isfinite(r) and r <= 100.0):
                continue  # a geometry size beyond 100 m says nothing about the link
            pts += [centre + r * d for d in np.vstack([np.eye(3), -np.eye(3)])]
        return [p * 1000.0 for p in pts]

    # the chain's reach: its link frames from the root to the last moving joint's child and the fixed tail after it
    tail = by_child_link(robot, chain_joints[-1])
    while len(children.get(tail, [])) == 1 and children[tail][0].type == "fixed":
        tail = children[tail][0].child
    path_links = []
    while tail in by_child:
        path_links.append(tail)
        tail = by_child[tail].parent
    reach = chain_reach([frame(root)[:3, 3] * 1000.0] + [frame(lk)[:3, 3] * 1000.0 for lk in reversed(path_links)])
    sums: dict = {}
    unknown: dict = {}
    for lk in robot.links:
        body = body_of(lk.name)
        inertial = getattr(lk, "inertial", None)
        has_mass = inertial is not None and inertial.mass is not None
        if body is None:
            continue
        if not has_mass:
            real = bool(getattr(lk, "visuals", None) or getattr(lk, "collisions", None))
            unknown.setdefault(body, {"links": [], "real": False})
            unknown[body]["links"].append(lk.name)
            unknown[body]["real"] |= real
            continue
        m = float(inertial.mass)
        if not (math.isfinite(m) and m >= 0.0):
            raise DataError(f"{path}: link '{lk.name}' has an <inertial> mass of {inertial.mass!r}; a mass is a "
                            f"finite number >= 0 (kg).")
        origin = np.array(inertial.origin if inertial.origin is not None else np.eye(4), dtype=float)
        com = (frame(lk.name) @ origin)[:3, 3] * 1000.0  # m -> mm, base frame at home
        check_body_mass(m, com, extent(lk), reach, f"{path}: link '{lk.name}' (<inertial>)")
        entry = sums.setdefault(body, {"mass": 0.0, "moment": np.zeros(3), "links": []})
        entry["mass"] += m
        entry["moment"] += m * com
        entry["links"].append(lk.name)
    missing = [{"joint": b, "links": sorted(u["links"])} for b, u in unknown.items() if u["real"] or b not in sums]
    missing += [{"joint": b, "links": []} for b in chain_joints if b not in sums and b not in unknown]
    masses = {b: {"mass": e["mass"], "com": (e["moment"] / e["mass"]).tolist(),
                  "source": f"URDF <inertial> of link{'s' if len(e['links']) > 1 else ''} {', '.join(e['links'])}"}
              for b, e in sums.items() if e["mass"] > 0.0}
    if not sums:
        return {}, []  # no <inertial> at all: nothing declared, nothing to report
    if missing:
        return {}, sorted(missing, key=lambda u: chain_joints.index(u["joint"]))
    zero = [b for b in chain_joints if b in sums and sums[b]["mass"] == 0.0]
    masses.update({b: {"mass": 0.0, "com": (frame(by_child_link(robot, b))[:3, 3] * 1000.0).tolist(),
                       "source": f"URDF <inertial> of links {', '.join(sums[b]['links'])} (mass 0)"} for b in zero})
    return masses, []


def by_child_link(robot, joint_name: str) -> str:
    """The child link of the URDF joint ``joint_name``."""
    return next(j.child for j in robot.joints if j.name == joint_name)


def import_robot(path: str | Path, tip: str | None = None) -> Mechanism:
    """A serial robot from a DH table (``.yaml``, ``.yml``, ``.csv``) or a URDF (``.urdf``)."""
    path = Path(path)
    if path.suffix.lower() == ".urdf":
        return read_urdf(path, tip)
    if path.suffix.lower() in (".yaml", ".yml", ".csv"):
        return dh_to_mechanism(read_dh_table(path))
    raise DataError(f"{path}: unknown robot file kind '{path.suffix}'; use .yaml/.yml/.csv (DH table) or .urdf.")
