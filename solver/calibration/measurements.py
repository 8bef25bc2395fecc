"""Measurement files: joint values and tracker-measured target positions / poses (CSV).

Units: lengths in mm, angles in rad inside the code.  Every column header states its unit
in brackets; lengths may be given in ``mm`` or ``m`` and angles in ``rad`` or ``deg``, and
are converted explicitly (never guessed).

Format (version 1)::

    # hyperstat measurements, version 1
    # mechanism: tripteor_x7
    # noise: 0.005 mm + 0.005 mm/m          (optional: 1-sigma per axis, a + b * distance to the tracker)
    # tracker: 2000 -1500 -500 0 0 0.3       (optional: nominal tracker pose in the base frame, mm and rad)
    # target: 0 0 -10                        (optional: nominal target offset in the output frame, mm)
    pose,q41[mm],q42[mm],q43[mm],q6[rad],q7[rad],x[mm],y[mm],z[mm],temperature[degC],payload[kg],dir41,time[s],session
    1,841.2,...

* ``pose``: an identifier per row (text);
* ``q<joint>[mm|m|rad|deg]``: one column per actuated joint of the model, its value; when the
  model carries a joint map (an imported robot, :mod:`hyperstat.solver.kinematics.joint_map`),
  the columns are the *controller's* joints instead (``J1[deg]``, ...) and the map turns
  them into model joints (sign, zero offset, gear ratio, couplings such as ``q3 = J3 + J2``);
* ``x[mm], y[mm], z[mm]``: measured target position in the tracker frame; with several
  targets on one tool (one geometry, one offset per target), one group per target:
  ``x_SMR1[mm], y_SMR1[mm], z_SMR1[mm], x_SMR2[mm], ...``, a group left empty where the
  tracker did not see that target; priors ``# target SMR1: 12 -8 -25``;
* orientation (optional, 6-D measurements): a rotation vector ``rx, ry, rz [rad|deg]`` or a
  unit quaternion ``quat_w, quat_x, quat_y, quat_z`` (suffixed ``_<target>`` with several
  targets) of the target frame in the tracker frame, with the header line
  ``# orientation noise: 0.1 mrad`` (1-sigma per axis);
* optional metadata used by the diagnosis: ``temperature[degC]``, ``payload[kg]``,
  ``dir<joint>`` (approach direction of an actuator, -1 or +1), ``time[s]``, ``session``.

A file with several targets is read as one row per (pose, target) observation
(:attr:`MeasurementSet.target_index`).  Reading validates everything and names the row and
the column at fault.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hyperstat.solver.atomic import write_text
from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.joint_map import ANGLE_UNITS, LENGTH_UNITS, JointMap, joint_map_from_dict
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.plausibility import plausible_angle, plausible_in, plausible_length

__all__ = ["MeasurementSet", "joined", "NoiseModel", "read_measurements", "write_measurements", "parse_measurements",
           "parse_noise",
           "METADATA_COLUMNS"]

_HEADER = "# hyperstat measurements, version 1"
METADATA_COLUMNS = {"temperature": "degC", "payload": "kg", "time": "s", "session": ""}
#: plausible values of the metadata columns (low, high, unit, what)
METADATA_RANGES = {"temperature": (-100.0, 200.0, "degC", "workshop temperature"),
                   "payload": (0.0, 1e4, "kg", "payload")}
#: largest plausible tracker noise terms (1 sigma per axis: mm, and mm per m of distance)
MAX_NOISE_MM = 100.0
#: largest plausible orientation noise of a 6-D tracker (1 sigma per axis, rad)
MAX_ORIENTATION_NOISE_RAD = 0.1
_COL = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[([^\]]*)\])?$")
_TARGET_COL = re.compile(r"^([xyz])_([A-Za-z0-9]+)$")


@dataclass
class NoiseModel:
    """Tracker noise: 1-sigma per axis ``a + b * d`` (mm), ``d`` the distance to the tracker in m."""

    a: float = 0.005
    b: float = 0.005

    def sigma(self, distance_mm: np.ndarray) -> np.ndarray:
        """Per-axis standard deviation (mm) at distances in mm."""
        return self.a + self.b * np.asarray(distance_mm) / 1000.0

    def text(self) -> str:
        """Header form, e.g. ``0.005 mm + 0.005 mm/m``."""
        return f"{self.a:g} mm + {self.b:g} mm/m"


@dataclass
class MeasurementSet:
    """Poses and measurements.

    Attributes
    ----------
    pose : list of str
        Row identifiers.
    joints : list of str
        Actuated joint names, in the model's actuated order.
    q : ndarray, (K, n_actuated)
        Actuated joint values (rad / mm).
    position : ndarray, (K, 3)
        Measured target positions in the tracker frame (mm).
    rotation : ndarray or None, (K, 3)
        Measured orientations (rotation vectors, rad), if given.
    metadata : dict
        Column name -> (K,) array: ``temperature``, ``payload``, ``time``, ``session``,
        ``dir<joint>``.
    noise : NoiseModel or None
        Noise model stated in the header.
    tracker : ndarray or None, (6,)
        Nominal tracker pose ``(x, y, z, rx, ry, rz)`` in the base frame (mm, rad).
    target : ndarray or None, (3,)
        Nominal target offset in the output frame (mm).
    mechanism : str
        Mechanism name stated in the header.
    source : str
        File name (for messages).
    target_index : ndarray of int, (K,)
        Target seen in each row (index into ``target_names``).  A file with several
        targets per pose gives one row per (pose, target) observation.
    target_names : list of str
        Target names (``[""]`` for a single target).
    target_priors : dict
        Target name -> nominal offset in the output frame (mm), from ``# target <name>:``.
    pose_id : list of str
        Pose identifier of each row (the file's ``pose`` column).
    rotation_noise : float or None
        1-sigma per axis of the orientation measurements (rad).
    """

    pose: list
    joints: list
    q: np.ndarray
    position: np.ndarray
    rotation: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)
    noise: NoiseModel | None = None
    tracker: np.ndarray | None = None
    target: np.ndarray | None = None
    mechanism: str = ""
    source: str = "measurements"
    target_index: np.ndarray | None = None
    target_names: list = field(default_factory=lambda: [""])
    target_priors: dict = field(default_factory=dict)
    pose_id: list | None = None
    rotation_noise: float | None = None

    def __post_init__(self) -> None:
        if self.target_index is None:
            self.target_index = np.zeros(len(self.pose), dtype=int)
        if self.pose_id is None:
            self.pose_id = list(self.pose)

    def __len__(self) -> int:
        return len(self.pose)

    @property
    def n_targets(self) -> int:
        """Number of targets (one geometry, one offset each)."""
        return len(self.target_names)

    @property
    def n_poses(self) -> int:
        """Number of distinct poses (rows of the file)."""
        return len(dict.fromkeys(self.pose_id))

    def subset(self, rows: np.ndarray) -> "MeasurementSet":
        """The rows ``rows`` (indices or boolean mask)."""
        rows = np.asarray(rows)
        idx = np.nonzero(rows)[0] if rows.dtype == bool else rows
        return MeasurementSet(
            [self.pose[i] for i in idx], list(self.joints), self.q[idx], self.position[idx],
            None if self.rotation is None else self.rotation[idx],
            {k: v[idx] for k, v in self.metadata.items()}, self.noise,
            self.tracker, self.target, self.mechanism, self.source,
            np.asarray(self.target_index)[idx], list(self.target_names), dict(self.target_priors),
            [self.pose_id[i] for i in idx], self.rotation_noise,
        )


def joined(first: MeasurementSet, second: MeasurementSet, prefix: str = "held-out ") -> MeasurementSet | None:
    """The rows of ``first`` then those of ``second`` as one set (the second's poses renamed ``prefix + pose`` so
    that no pose name is shared), with the first's noise model, tracker and targets; None when the two sets do not
    have the same joints, targets, metadata columns and row kinds (3-D or 6-D).

    >>> a = MeasurementSet(["P1"], ["1"], np.zeros((1, 1)), np.zeros((1, 3)))
    >>> both = joined(a, MeasurementSet(["P1"], ["1"], np.ones((1, 1)), np.ones((1, 3))))
    >>> both.pose, both.q.ravel().tolist()
    (['P1', 'held-out P1'], [0.0, 1.0])
    """
    if list(second.joints) != list(first.joints) or list(second.target_names) != list(first.target_names) \
            or set(second.metadata) != set(first.metadata) or (second.rotation is None) != (first.rotation is None):
        return None
    return MeasurementSet(
        list(first.pose) + [prefix + str(p) for p in second.pose], list(first.joints),
        np.concatenate([first.q, second.q]), np.concatenate([first.position, second.position]),
        None if first.rotation is None else np.concatenate([first.rotation, second.rotation]),
        {k: np.concatenate([np.asarray(v), np.asarray(second.metadata[k])]) for k, v in first.metadata.items()},
        first.noise, first.tracker, first.target, first.mechanism, first.source,
        np.concatenate([np.asarray(first.target_index), np.asarray(second.target_index)]),
        list(first.target_names), dict(first.target_priors),
        list(first.pose_id) + [prefix + str(p) for p in second.pose_id], first.rotation_noise,
    )


def _declaration(key: str) -> bool:
    """Whether a header key declares something (once only), rather than being a free comment."""
    return key in ("mechanism", "noise", "tracker", "target", "orientation noise") or key.startswith("target ")


def _number(text: str, where: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise DataError(f"{where}: '{text}' is not a number.") from None
    if math.isnan(v):
        raise DataError(f"{where}: the value is NaN.")
    if math.isinf(v):
        raise DataError(f"{where}: the value is infinite.")
    return v


def parse_noise(text: str, where: str = "noise") -> NoiseModel:
    """Noise model from its text form ``'A mm + B mm/m'`` (1-sigma per axis).

    Raises
    ------
    DataError
        Naming ``where`` if the text does not have that form or a value is negative.
    """
    m = re.match(r"^\s*([0-9.eE+-]+)\s*mm\s*\+\s*([0-9.eE+-]+)\s*mm/m\s*$", text)
    if not m:
        raise DataError(f"{where} must read 'A mm + B mm/m' (e.g. '0.005 mm + 0.005 mm/m'), got '{text}'.")
    try:
        a, b = float(m.group(1)), float(m.group(2))
    except ValueError:
        raise DataError(f"{where}: '{text}' does not hold two numbers.") from None
    if not (math.isfinite(a) and math.isfinite(b)) or a < 0 or b < 0 or a + b == 0:
        raise DataError(f"{where}: the noise terms must be finite, non-negative and not both zero, got '{text}'.")
    return NoiseModel(a, b)


def _joint_columns(mechanism: Mechanism, joint_map: JointMap | None) -> list[tuple[str, str, str]]:
    """Required joint columns ``(name, kind, description)``: controller joints with a map, model joints without."""
    if joint_map is not None:
        return [(c, "angle" if k == "R" else "length", f"controller joint {c}")
                for c, k in zip(joint_map.controller, joint_map.kinds)]
    joints = [mechanism.joints[i] for i in mechanism.actuated]
    return [(f"q{j.name}", "angle" if j.type == "R" else "length", f"actuated joint {j.name}") for j in joints]


def mechanism_joint_map(mechanism: Mechanism) -> JointMap | None:
    """The joint map a model file carries in ``metadata.joint_map`` (imported robots), or None."""
    doc = mechanism.metadata.get("joint_map") if isinstance(mechanism.metadata, dict) else None
    if doc is None:
        return None
    joints = [mechanism.joints[i] for i in mechanism.actuated]
    return joint_map_from_dict(doc, {j.name: j.type for j in joints}, f"model '{mechanism.name}': metadata.joint_map")


def parse_measurements(text: str, mechanism: Mechanism, source: str = "measurements",
                       joint_map: JointMap | None = None) -> MeasurementSet:
    """Parse and validate measurement-file text against a mechanism.

    Parameters
    ----------
    text : str
        File content (see the module docstring).
    mechanism : Mechanism
        The model; its ``metadata.joint_map`` (imported robots) applies unless ``joint_map``
        is given.
    source : str
        File name for messages.
    joint_map : JointMap, optional
        Controller convention: the file then holds controller joint columns (``J1[deg]``...)
        and the model joint values are ``joint_map.apply`` of them.

    Raises
    ------
    DataError
        Naming the file, row and column at fault.
    """
    if joint_map is None:
        joint_map = mechanism_joint_map(mechanism)
    lines = text.splitlines()
    if not lines or lines[0].strip() != _HEADER:
        raise DataError(f"{source}: the first line must be '{_HEADER}'.")
    header: dict[str, str] = {}
    header_line: dict[str, int] = {}
    body_start = 0
    for i, line in enumerate(lines):
        if line.startswith("#"):
            if ":" in line and i > 0:
                key, value = line[1:].split(":", 1)
                key = " ".join(key.split()).lower()
                if key in header_line and _declaration(key):
                    raise DataError(f"{source}, line {i + 1}: header '{key}' is already declared in line "
                                    f"{header_line[key]}; give it once.")
                header_line.setdefault(key, i + 1)
                header.setdefault(key, value.strip())
            continue
        body_start = i
        break
    else:
        raise DataError(f"{source}: no column header line after the comments.")
    reader = csv.reader(io.StringIO("\n".join(lines[body_start:])))
    try:
        columns = [c.strip() for c in next(reader)]
    except StopIteration:
        raise DataError(f"{source}: no column header line.") from None
    parsed = {}
    for c in columns:
        m = _COL.match(c)
        if not m:
            raise DataError(f"{source}: column header '{c}' must read NAME or NAME[unit].")
        if m.group(1) in parsed:
            raise DataError(f"{source}: column '{m.group(1)}' appears twice.")
        parsed[m.group(1)] = (c, m.group(2) or "")
    joints = [mechanism.joints[i] for i in mechanism.actuated]
    jcols = _joint_columns(mechanism, joint_map)
    if "pose" not in parsed:
        raise DataError(f"{source}: column 'pose' is missing.")
    # targets: x[mm] (one target) or x_<T>[mm] per target T
    targets: list[str] = []
    for name in parsed:
        m = _TARGET_COL.match(name)
        if m and m.group(2) not in targets:
            targets.append(m.group(2))
    if "x" in parsed or "y" in parsed or "z" in parsed or not targets:
        if targets:
            raise DataError(f"{source}: columns x, y, z (one target) and x_<target> (several targets) cannot be mixed.")
        targets = [""]
    by_case: dict[str, str] = {}
    for t in targets:
        if t.lower() in by_case:
            raise DataError(f"{source}: targets '{by_case[t.lower()]}' and '{t}' differ only by case; their priors "
                            f"('# target <name>:') could not be told apart.")
        by_case[t.lower()] = t
    for key, line in header_line.items():
        if key.startswith("target ") and key[len("target "):] not in by_case:
            raise DataError(f"{source}, line {line}: header '# {key}:' gives a prior for a target that has no "
                            f"columns (targets: {', '.join(t for t in targets if t) or 'one, columns x, y, z'}); "
                            f"several targets go in columns x_<target>, y_<target>, z_<target>, not stacked in x, y, z.")

    def col(base: str, t: str) -> str:
        return base if t == "" else f"{base}_{t}"

    factors: dict[str, float] = {}

    def need(name: str, kind: str, what: str, default: str | None = None) -> None:
        default = default or ("rad" if kind == "angle" else "mm")
        if name not in parsed:
            raise DataError(f"{source}: column '{name}[{default}]' ({what}) is missing.")
        unit = parsed[name][1]
        table = ANGLE_UNITS if kind == "angle" else LENGTH_UNITS
        if unit not in table:
            raise DataError(f"{source}: column '{parsed[name][0]}' must be in {' or '.join(table)} "
                            f"(write '{name}[{default}]').")
        factors[name] = table[unit]

    for name, kind, what in jcols:
        need(name, kind, what, None if joint_map is None else joint_map.units[kind])
    for t in targets:
        for a in "xyz":
            need(col(a, t), "length", "measured position" + (f" of target {t}" if t else ""))
    rot_cols: dict[str, list[str]] = {}
    quat_cols: dict[str, list[str]] = {}
    for t in targets:
        rv = [col(a, t) for a in ("rx", "ry", "rz")]
        qv = [col(a, t) for a in ("quat_w", "quat_x", "quat_y", "quat_z")]
        if any(c in parsed for c in rv):
            for c in rv:
                need(c, "angle", "orientation (rotation vector needs rx, ry and rz)")
            rot_cols[t] = rv
        if any(c in parsed for c in qv):
            if t in rot_cols:
                raise DataError(f"{source}: target '{t or 'the target'}' has both a rotation vector and a quaternion.")
            for c in qv:
                if c not in parsed:
                    raise DataError(f"{source}: column '{c}' is missing (a quaternion needs quat_w, quat_x, quat_y, "
                                    f"quat_z).")
            quat_cols[t] = qv
    oriented = set(rot_cols) | set(quat_cols)
    if oriented and oriented != set(targets):
        raise DataError(f"{source}: orientation columns are given for some targets only; give them for every target "
                        f"or none.")
    known = {"pose"} | {c for c, _, _ in jcols} | set(METADATA_COLUMNS)
    known |= {col(a, t) for t in targets for a in "xyz"} | {c for v in rot_cols.values() for c in v}
    known |= {c for v in quat_cols.values() for c in v}
    known |= {f"dir{j.name}" for j in joints}
    for name, (full, unit) in parsed.items():
        if name not in known:
            raise DataError(f"{source}: column '{full}' is not part of the format (joint columns: "
                            f"{', '.join(c for c, _, _ in jcols)}).")
        if name in METADATA_COLUMNS and METADATA_COLUMNS[name] and unit != METADATA_COLUMNS[name]:
            raise DataError(f"{source}: column '{full}' must be in {METADATA_COLUMNS[name]}.")
    index = {name: columns.index(full) for name, (full, _) in parsed.items()}
    rows = []
    for r, row in enumerate(reader, start=body_start + 2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != len(columns):
            raise DataError(f"{source}, row {r}: {len(row)} values for {len(columns)} columns.")
        rows.append((r, [c.strip() for c in row]))
    if not rows:
        raise DataError(f"{source}: no data rows.")
    k = len(rows)
    n_t = len(targets)
    raw = np.zeros((k, len(jcols)))
    pos = np.full((k, n_t, 3), np.nan)
    rot = np.full((k, n_t, 3), np.nan) if oriented else None
    meta = {name: np.zeros(k) for name in parsed if name in METADATA_COLUMNS or name.startswith("dir")}
    poses = []
    for i, (r, row) in enumerate(rows):
        poses.append(row[index["pose"]])
        for jj, (c, _, _) in enumerate(jcols):
            raw[i, jj] = _number(row[index[c]], f"{source}, row {r}, column '{parsed[c][0]}'") * factors[c]
        for ti, t in enumerate(targets):
            cells = [row[index[col(a, t)]] for a in "xyz"]
            if n_t > 1 and all(not c for c in cells):
                continue  # target not seen at this pose
            for a, name in enumerate(col(a, t) for a in "xyz"):
                where = f"{source}, row {r}, column '{parsed[name][0]}'"
                pos[i, ti, a] = plausible_length(_number(row[index[name]], where), parsed[name][1], where)
            if t in rot_cols:
                rot[i, ti] = [plausible_angle(_number(row[index[c]], f"{source}, row {r}, column '{parsed[c][0]}'"),
                                              parsed[c][1], f"{source}, row {r}, column '{parsed[c][0]}'")
                              for c in rot_cols[t]]
            elif t in quat_cols:
                qv = np.array([_number(row[index[c]], f"{source}, row {r}, column '{c}'") for c in quat_cols[t]])
                norm = float(np.linalg.norm(qv))
                if abs(norm - 1.0) > 1e-3:
                    raise DataError(f"{source}, row {r}, columns '{quat_cols[t][0]}'...: the quaternion's norm is "
                                    f"{norm:.6g}, not 1.")
                rot[i, ti] = _quaternion_to_rotvec(qv / norm)
        for name in meta:
            where = f"{source}, row {r}, column '{parsed[name][0]}'"
            v = _number(row[index[name]], where)
            if name.startswith("dir") and v not in (-1.0, 1.0):
                raise DataError(f"{where}: an approach direction is -1 or +1, got {v:g}.")
            if name in METADATA_RANGES:
                low, high, unit, what = METADATA_RANGES[name]
                plausible_in(v, low, high, unit, where, what)
            meta[name][i] = v
    q = joint_map.apply(raw) if joint_map is not None else raw
    ranges = mechanism.ranges[mechanism.actuated]
    for i, (r, _row) in enumerate(rows):
        for jj, j in enumerate(joints):
            lo, hi = ranges[jj]
            if not (lo - 1e-9 <= q[i, jj] <= hi + 1e-9):
                what = f"column '{parsed[jcols[jj][0]][0]}'" if joint_map is None else \
                    f"model joint {j.name} (from the controller columns through the joint map)"
                hint = ""
                if joint_map is None and j.type == "R" and parsed[jcols[jj][0]][1] == "rad" and \
                        lo <= np.radians(q[i, jj]) <= hi and abs(q[i, jj]) > 2 * np.pi:
                    hint = f": it looks like degrees (write '{jcols[jj][0]}[deg]')"
                raise DataError(f"{source}, row {r}, {what}: {q[i, jj]:g} is outside the joint range "
                                f"[{lo:g}, {hi:g}] ({'rad' if j.type == 'R' else 'mm'}){hint}.")
    seen: dict[str, int] = {}
    for i, p in enumerate(poses):
        if p in seen:
            raise DataError(f"{source}, row {rows[i][0]}, column 'pose': pose '{p}' already appears in row "
                            f"{rows[seen[p]][0]}.")
        seen[p] = i
    keys = np.round(np.hstack([q, np.stack([meta[n] for n in sorted(meta)], axis=1) if meta else np.zeros((k, 0))]), 9)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    if len(first) < k:
        dup = int(np.nonzero(np.bincount(inverse.ravel()) > 1)[0][0])
        rows_dup = [rows[i][0] for i in np.nonzero(inverse.ravel() == dup)[0]]
        raise DataError(f"{source}: rows {rows_dup[0]} and {rows_dup[1]} repeat the same pose (same actuated values "
                        f"and metadata); several targets measured at one pose go in one row, columns x_<target>.")
    noise = parse_noise(header["noise"], f"{source}: header 'noise'") if "noise" in header else None
    if noise is not None:
        plausible_in(noise.a, 0.0, MAX_NOISE_MM, "mm", f"{source}: header 'noise', constant term", "tracker noise")
        plausible_in(noise.b, 0.0, MAX_NOISE_MM, "mm/m", f"{source}: header 'noise', distance term", "tracker noise")
    rot_noise = None
    if "orientation noise" in header:
        rot_noise = _parse_angle(header["orientation noise"], f"{source}: header 'orientation noise'")
        plausible_in(rot_noise, 0.0, MAX_ORIENTATION_NOISE_RAD, "rad", f"{source}: header 'orientation noise'",
                     "orientation noise")
    elif oriented:
        raise DataError(f"{source}: orientation columns need a header line '# orientation noise: A rad' "
                        f"(or deg, mrad): their 1-sigma per axis.")

    def vector(key: str, n: int) -> np.ndarray | None:
        if key not in header:
            return None
        parts = header[key].split()
        unit = "mm"
        if n == 3 and len(parts) == 4 and parts[3] in LENGTH_UNITS:
            unit = parts.pop()
        if len(parts) != n:
            raise DataError(f"{source}: header '{key}' needs {n} numbers, got '{header[key]}'.")
        where = f"{source}: header '{key}'"
        values = [_number(p, where) for p in parts]
        return np.array([plausible_length(v, unit, where) if k < 3 else plausible_angle(v, "rad", where)
                         for k, v in enumerate(values)])

    name = header.get("mechanism", "")
    if name and name != mechanism.name:
        raise DataError(f"{source}: the file is for mechanism '{name}', not '{mechanism.name}'.")
    priors = {}
    for t in targets:
        v = vector("target" if t == "" else f"target {t.lower()}", 3)
        if v is not None:
            priors[t] = v
    if n_t > 1 and "target" in header:
        raise DataError(f"{source}: with several targets, give each prior as '# target <name>: x y z'.")
    # one row per (pose, target) observation
    seen_mask = ~np.isnan(pos[:, :, 0])
    pi, ti = np.nonzero(seen_mask)
    if n_t == 1:
        labels = poses
    else:
        labels = [f"{poses[a]}/{targets[b]}" for a, b in zip(pi, ti)]
    return MeasurementSet(
        labels, [j.name for j in joints], q[pi], pos[pi, ti], None if rot is None else rot[pi, ti],
        {key: v[pi] for key, v in meta.items()}, noise, vector("tracker", 6),
        priors.get("") if n_t == 1 else None, name or mechanism.name, source,
        target_index=ti.astype(int), target_names=list(targets), target_priors=priors,
        pose_id=[poses[a] for a in pi], rotation_noise=rot_noise)


def _parse_angle(text: str, where: str) -> float:
    m = re.match(r"^\s*([0-9.eE+-]+)\s*(rad|mrad|deg|urad)\s*$", text)
    if not m:
        raise DataError(f"{where} must read 'A rad' (or mrad, urad, deg), got '{text}'.")
    v = _number(m.group(1), where) * {"rad": 1.0, "mrad": 1e-3, "urad": 1e-6, "deg": math.pi / 180}[m.group(2)]
    if v <= 0:
        raise DataError(f"{where} must be positive, got '{text}'.")
    return v


def _quaternion_to_rotvec(qv: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of a unit quaternion ``(w, x, y, z)``."""
    w, v = qv[0], qv[1:]
    if w < 0:
        w, v = -w, -v
    s = float(np.linalg.norm(v))
    if s < 1e-12:
        return 2.0 * v
    return 2.0 * math.atan2(s, w) * v / s


def read_measurements(path: str | Path, mechanism: Mechanism, joint_map: JointMap | None = None) -> MeasurementSet:
    """Read and validate a measurement file (see module docstring); ``joint_map`` overrides the model's."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such measurement file.")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise DataError(f"{path}: not UTF-8 text.") from None
    return parse_measurements(text, mechanism, str(path), joint_map=joint_map)


def write_measurements(path: str | Path, data: MeasurementSet, mechanism: Mechanism, comment: str = "") -> Path:
    """Write a measurement file atomically (values with 12 significant digits; one target)."""
    if data.n_targets != 1:
        raise DataError("write_measurements writes one-target files; this set has several targets.")
    joints = [mechanism.joints[i] for i in mechanism.actuated]
    joint_map = mechanism_joint_map(mechanism)
    out = io.StringIO()
    out.write(_HEADER + "\n")
    out.write(f"# mechanism: {mechanism.name}\n")
    if joint_map is None:
        out.write("# units: lengths mm, angles rad (also in every column header)\n")
    else:
        out.write("# units: lengths mm; controller joints in the units of their column headers (joint map)\n")
    if data.noise is not None:
        out.write(f"# noise: {data.noise.text()}\n")
    if data.tracker is not None:
        out.write("# tracker: " + " ".join(f"{v:.12g}" for v in data.tracker) + "\n")
    if data.target is not None:
        out.write("# target: " + " ".join(f"{v:.12g}" for v in data.target) + "\n")
    for line in comment.splitlines():
        out.write(f"# {line}\n")
    if joint_map is None:
        jcols = [f"q{j.name}[{'rad' if j.type == 'R' else 'mm'}]" for j in joints]
        jvals = data.q
    else:  # the controller's columns, in the map's units (a model that carries a joint map reads those)
        units = [joint_map.controller_unit(k) for k in range(len(joint_map.controller))]
        jcols = [f"{c}[{u}]" for c, u in zip(joint_map.controller, units)]
        factors = np.array([ANGLE_UNITS.get(u, LENGTH_UNITS.get(u, 1.0)) for u in units])
        jvals = joint_map.inverse(data.q) / factors
    cols = ["pose"] + jcols + ["x[mm]", "y[mm]", "z[mm]"]
    if data.rotation is not None:
        cols += ["rx[rad]", "ry[rad]", "rz[rad]"]
    meta_names = sorted(data.metadata)
    cols += [f"{n}[{METADATA_COLUMNS[n]}]" if METADATA_COLUMNS.get(n) else n for n in meta_names]
    w = csv.writer(out, lineterminator="\n")
    w.writerow(cols)
    for i in range(len(data)):
        row = [data.pose[i]] + [f"{v:.12g}" for v in jvals[i]] + [f"{v:.12g}" for v in data.position[i]]
        if data.rotation is not None:
            row += [f"{v:.12g}" for v in data.rotation[i]]
        row += [f"{data.metadata[n][i]:.12g}" for n in meta_names]
        w.writerow(row)
    return write_text(path, out.getvalue())
