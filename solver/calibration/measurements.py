"""Measurement files: actuated joint values and tracker-measured target positions (CSV).

Units: lengths in mm, angles in rad; every column header states its unit in brackets.

Format (version 1)::

    # hyperstat measurements, version 1
    # mechanism: tripteor_x7
    # noise: 0.005 mm + 0.005 mm/m          (optional: 1-sigma per axis, a + b * distance to the tracker)
    # tracker: 2000 -1500 -500 0 0 0.3       (optional: nominal tracker pose in the base frame, mm and rad)
    # target: 0 0 -10                        (optional: nominal target offset in the output frame, mm)
    pose,q41[mm],q42[mm],q43[mm],q6[rad],q7[rad],x[mm],y[mm],z[mm],temperature[degC],payload[kg],dir41,time[s],session
    1,841.2,...

* ``pose``: an identifier per row (text);
* ``q<joint>[mm|rad]``: one column per actuated joint of the model, its value;
* ``x[mm], y[mm], z[mm]``: measured target position in the tracker frame;
* ``rx[rad], ry[rad], rz[rad]`` (optional): measured orientation as a rotation vector;
* optional metadata used by the diagnosis: ``temperature[degC]``, ``payload[kg]``,
  ``dir<joint>`` (approach direction of an actuator, -1 or +1), ``time[s]``, ``session``.

Reading validates everything and names the row and the column at fault.
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
from hyperstat.solver.kinematics.model import Mechanism

__all__ = ["MeasurementSet", "NoiseModel", "read_measurements", "write_measurements", "parse_measurements",
           "parse_noise",
           "METADATA_COLUMNS"]

_HEADER = "# hyperstat measurements, version 1"
METADATA_COLUMNS = {"temperature": "degC", "payload": "kg", "time": "s", "session": ""}
_COL = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[([^\]]*)\])?$")


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

    def __len__(self) -> int:
        return len(self.pose)

    def subset(self, rows: np.ndarray) -> "MeasurementSet":
        """The rows ``rows`` (indices or boolean mask)."""
        rows = np.asarray(rows)
        idx = np.nonzero(rows)[0] if rows.dtype == bool else rows
        return MeasurementSet(
            [self.pose[i] for i in idx], list(self.joints), self.q[idx], self.position[idx],
            None if self.rotation is None else self.rotation[idx],
            {k: v[idx] for k, v in self.metadata.items()}, self.noise,
            self.tracker, self.target, self.mechanism, self.source,
        )


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


def parse_measurements(text: str, mechanism: Mechanism, source: str = "measurements") -> MeasurementSet:
    """Parse and validate measurement-file text against a mechanism.

    Raises
    ------
    DataError
        Naming the file, row and column at fault.
    """
    lines = text.splitlines()
    if not lines or lines[0].strip() != _HEADER:
        raise DataError(f"{source}: the first line must be '{_HEADER}'.")
    header: dict[str, str] = {}
    body_start = 0
    for i, line in enumerate(lines):
        if line.startswith("#"):
            if ":" in line and i > 0:
                key, value = line[1:].split(":", 1)
                header[key.strip().lower()] = value.strip()
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
    required = [(f"q{j.name}", "rad" if j.type == "R" else "mm", f"actuated joint {j.name}") for j in joints]
    required += [("x", "mm", "measured position"), ("y", "mm", "measured position"), ("z", "mm", "measured position")]
    if "pose" not in parsed:
        raise DataError(f"{source}: column 'pose' is missing.")
    for name, unit, what in required:
        if name not in parsed:
            raise DataError(f"{source}: column '{name}[{unit}]' ({what}) is missing.")
        if parsed[name][1] != unit:
            raise DataError(f"{source}: column '{parsed[name][0]}' must be in {unit} (write '{name}[{unit}]').")
    has_rot = any(k in parsed for k in ("rx", "ry", "rz"))
    if has_rot:
        for k in ("rx", "ry", "rz"):
            if k not in parsed:
                raise DataError(f"{source}: column '{k}[rad]' is missing (orientation needs rx, ry and rz).")
            if parsed[k][1] != "rad":
                raise DataError(f"{source}: column '{parsed[k][0]}' must be in rad.")
    known = {"pose", "x", "y", "z", "rx", "ry", "rz"} | {r[0] for r in required} | set(METADATA_COLUMNS)
    known |= {f"dir{j.name}" for j in joints}
    for name, (full, unit) in parsed.items():
        if name not in known:
            raise DataError(f"{source}: column '{full}' is not part of the format (actuated joints: "
                            f"{', '.join('q' + j.name for j in joints)}).")
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
    q = np.zeros((k, len(joints)))
    pos = np.zeros((k, 3))
    rot = np.zeros((k, 3)) if has_rot else None
    meta = {name: np.zeros(k) for name in parsed if name in METADATA_COLUMNS or name.startswith("dir")}
    poses = []
    ranges = mechanism.ranges[mechanism.actuated]
    for i, (r, row) in enumerate(rows):
        poses.append(row[index["pose"]])
        for jj, j in enumerate(joints):
            col = f"q{j.name}"
            v = _number(row[index[col]], f"{source}, row {r}, column '{parsed[col][0]}'")
            lo, hi = ranges[jj]
            if not (lo - 1e-9 <= v <= hi + 1e-9):
                raise DataError(f"{source}, row {r}, column '{parsed[col][0]}': {v:g} is outside the joint range "
                                f"[{lo:g}, {hi:g}].")
            q[i, jj] = v
        for a, name in enumerate("xyz"):
            pos[i, a] = _number(row[index[name]], f"{source}, row {r}, column '{parsed[name][0]}'")
        if rot is not None:
            for a, name in enumerate(("rx", "ry", "rz")):
                rot[i, a] = _number(row[index[name]], f"{source}, row {r}, column '{parsed[name][0]}'")
        for name in meta:
            v = _number(row[index[name]], f"{source}, row {r}, column '{parsed[name][0]}'")
            if name.startswith("dir") and v not in (-1.0, 1.0):
                raise DataError(f"{source}, row {r}, column '{name}': an approach direction is -1 or +1, got {v:g}.")
            meta[name][i] = v
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
                        f"and metadata).")
    noise = parse_noise(header["noise"], f"{source}: header 'noise'") if "noise" in header else None

    def vector(key: str, n: int) -> np.ndarray | None:
        if key not in header:
            return None
        parts = header[key].split()
        if len(parts) != n:
            raise DataError(f"{source}: header '{key}' needs {n} numbers, got '{header[key]}'.")
        return np.array([_number(p, f"{source}: header '{key}'") for p in parts])

    name = header.get("mechanism", "")
    if name and name != mechanism.name:
        raise DataError(f"{source}: the file is for mechanism '{name}', not '{mechanism.name}'.")
    return MeasurementSet(poses, [j.name for j in joints], q, pos, rot, meta, noise, vector("tracker", 6),
                          vector("target", 3), name or mechanism.name, source)


def read_measurements(path: str | Path, mechanism: Mechanism) -> MeasurementSet:
    """Read and validate a measurement file (see module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such measurement file.")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise DataError(f"{path}: not UTF-8 text.") from None
    return parse_measurements(text, mechanism, str(path))


def write_measurements(path: str | Path, data: MeasurementSet, mechanism: Mechanism, comment: str = "") -> Path:
    """Write a measurement file atomically (values with 12 significant digits)."""
    joints = [mechanism.joints[i] for i in mechanism.actuated]
    out = io.StringIO()
    out.write(_HEADER + "\n")
    out.write(f"# mechanism: {mechanism.name}\n")
    out.write("# units: lengths mm, angles rad (also in every column header)\n")
    if data.noise is not None:
        out.write(f"# noise: {data.noise.text()}\n")
    if data.tracker is not None:
        out.write("# tracker: " + " ".join(f"{v:.12g}" for v in data.tracker) + "\n")
    if data.target is not None:
        out.write("# target: " + " ".join(f"{v:.12g}" for v in data.target) + "\n")
    for line in comment.splitlines():
        out.write(f"# {line}\n")
    cols = ["pose"] + [f"q{j.name}[{'rad' if j.type == 'R' else 'mm'}]" for j in joints] + ["x[mm]", "y[mm]", "z[mm]"]
    if data.rotation is not None:
        cols += ["rx[rad]", "ry[rad]", "rz[rad]"]
    meta_names = sorted(data.metadata)
    cols += [f"{n}[{METADATA_COLUMNS[n]}]" if METADATA_COLUMNS.get(n) else n for n in meta_names]
    w = csv.writer(out, lineterminator="\n")
    w.writerow(cols)
    for i in range(len(data)):
        row = [data.pose[i]] + [f"{v:.12g}" for v in data.q[i]] + [f"{v:.12g}" for v in data.position[i]]
        if data.rotation is not None:
            row += [f"{v:.12g}" for v in data.rotation[i]]
        row += [f"{data.metadata[n][i]:.12g}" for n in meta_names]
        w.writerow(row)
    return write_text(path, out.getvalue())
