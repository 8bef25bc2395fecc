"""Joint maps: the controller's joint values turned into the model's joint values.

Units: model joints in rad (revolute) and mm (prismatic); controller joints in the units
the map declares (``deg`` or ``rad``, ``mm`` or ``m``), converted explicitly.

A robot controller reports joint values in its own convention: a sign, a zero offset
(mastering position), a gear ratio (motor angles), and couplings between axes.  FANUC's
J3, for instance, is the forearm angle to the horizontal, so that the model's elbow angle
is ``q3 = J3 + J2``.  The map is linear and declared in the robot file::

    joint_map:
      units: {angle: deg, length: mm}       # units of the controller values and offsets
      joints:                                # one entry per model joint (actuated order)
        "1": {J1: 1}
        "2": {J2: -1, offset: 90}            # sign and zero offset
        "3": {J3: 1, J2: 1}                  # FANUC coupling q3 = J3 + J2
        "4": {J4: 1, ratio: 1}               # ratio: controller units per model unit
        ...

so that ``q_model = A @ J + b``: ``A[i, k] = coefficient / ratio`` (after converting ``J_k``
to rad / mm) and ``b[i] = offset`` (converted).  Measurement files then carry the
controller's columns (``J1[deg]``, ...) and :func:`hyperstat.solver.calibration.measurements.parse_measurements`
applies the map.

Examples
--------
>>> m = joint_map_from_dict({"units": {"angle": "deg"}, "joints": {"2": {"J2": 1}, "3": {"J3": 1, "J2": 1}}},
...                         {"2": "R", "3": "R"})
>>> import numpy as np
>>> np.degrees(m.apply(np.radians([[10.0, 20.0]])))   # columns J2, J3
array([[10., 30.]])
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.solver.errors import DataError
from hyperstat.solver.plausibility import plausible_angle, plausible_in, plausible_length

__all__ = ["JointMap", "joint_map_from_dict", "LENGTH_UNITS", "ANGLE_UNITS", "unit_factor"]

LENGTH_UNITS = {"mm": 1.0, "m": 1000.0}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0}
_RESERVED = {"offset", "ratio"}
#: plausibility of a map's numbers: a gear ratio (controller units per model unit) within 1e-6 .. 1e6, a
#: coupling coefficient within +-1000 (FANUC's J2/J3 coupling is 1)
MAX_RATIO = 1e6
MAX_COEFFICIENT = 1e3


def unit_factor(unit: str, kind: str, where: str) -> float:
    """Factor turning a value in ``unit`` into mm (``kind="length"``) or rad (``kind="angle"``).

    Raises
    ------
    DataError
        Naming ``where`` when the unit is not one of mm, m (lengths) or rad, deg (angles).
    """
    table = LENGTH_UNITS if kind == "length" else ANGLE_UNITS
    if not isinstance(unit, str) or unit not in table:
        raise DataError(f"{where}: unit {unit!r} is not a {kind} unit; use {' or '.join(table)}.")
    return table[unit]


@dataclass
class JointMap:
    """Linear map ``q_model = matrix @ J + offset`` (J converted to rad / mm).

    Attributes
    ----------
    model : list of str
        Model joint names (rows).
    controller : list of str
        Controller joint names (columns of ``matrix``; the measurement-file columns).
    kinds : list of str
        ``"R"`` or ``"P"`` per controller joint (the type of the model joint it drives first).
    matrix : ndarray, (n_model, n_controller)
        Coefficients (model unit per controller unit after conversion).
    offset : ndarray, (n_model,)
        Zero offsets (rad / mm).
    units : dict
        Declared units ``{"angle": ..., "length": ...}`` of controller values and offsets.
    declared : dict
        The ``joints`` entries as declared (for writing the map back).
    """

    model: list
    controller: list
    kinds: list
    matrix: np.ndarray
    offset: np.ndarray
    units: dict
    declared: dict

    def apply(self, controller_values: np.ndarray) -> np.ndarray:
        """Model joint values (rad / mm) from controller values already in rad / mm, shape (K, n_controller)."""
        return np.asarray(controller_values, dtype=float) @ self.matrix.T + self.offset

    def inverse(self, model_values: np.ndarray) -> np.ndarray:
        """Controller values (rad / mm) giving the model values (square, invertible maps only)."""
        if self.matrix.shape[0] != self.matrix.shape[1]:
            raise DataError("the joint map is not square: controller values cannot be recovered from model values.")
        return np.linalg.solve(self.matrix, (np.asarray(model_values, float) - self.offset).T).T

    def controller_unit(self, k: int) -> str:
        """Declared unit of controller joint ``k``."""
        return self.units["angle"] if self.kinds[k] == "R" else self.units["length"]

    def to_dict(self) -> dict:
        """Dictionary form, as declared in the robot file (declared units)."""
        return {"units": dict(self.units), "joints": {k: dict(v) for k, v in self.declared.items()}}


def joint_map_from_dict(doc: object, model_joints: dict, source: str = "joint_map") -> JointMap:
    """Read a joint map (see the module docstring) for the model joints ``{name: "R" | "P"}``.

    Parameters
    ----------
    doc : dict
        The ``joint_map`` mapping of a robot file.
    model_joints : dict
        Actuated model joint names and types, in the model's actuated order.
    source : str
        Where the map comes from (for messages).

    Raises
    ------
    DataError
        One sentence naming the field at fault.
    """
    if not isinstance(doc, dict):
        raise DataError(f"{source}: the joint map must be a mapping with 'units' and 'joints'.")
    units = doc.get("units")
    if not isinstance(units, dict) or not units:
        raise DataError(f"{source}.units must state the controller units, e.g. {{angle: deg, length: mm}}.")
    unknown = set(units) - {"angle", "length"}
    if unknown:
        raise DataError(f"{source}.units: unknown key '{sorted(unknown)[0]}' (use angle and length).")
    units = {"angle": units.get("angle", "rad"), "length": units.get("length", "mm")}
    unit_factor(units["angle"], "angle", f"{source}.units.angle")
    unit_factor(units["length"], "length", f"{source}.units.length")
    joints = doc.get("joints")
    if not isinstance(joints, dict) or not joints:
        raise DataError(f"{source}.joints must map every model joint to controller coefficients.")
    if len({str(k) for k in joints}) < len(joints):
        twice = next(str(k) for k in joints if sum(str(j) == str(k) for j in joints) > 1)
        raise DataError(f"{source}.joints declares model joint '{twice}' twice.")
    joints = {str(k): v for k, v in joints.items()}
    missing = [n for n in model_joints if n not in joints]
    if missing:
        raise DataError(f"{source}.joints has no entry for model joint '{missing[0]}' "
                        f"(model joints: {', '.join(model_joints)}).")
    extra = [n for n in joints if n not in model_joints]
    if extra:
        raise DataError(f"{source}.joints names '{extra[0]}', which is not an actuated joint of the model "
                        f"(model joints: {', '.join(model_joints)}).")
    controller: list[str] = []
    kinds: list[str] = []
    for name in model_joints:
        entry = joints[name]
        if not isinstance(entry, dict) or not entry:
            raise DataError(f"{source}.joints.{name} must map controller joints to coefficients, e.g. {{J3: 1, J2: 1}}.")
        for key in entry:
            key = str(key)
            if key in _RESERVED:
                continue
            if key in model_joints:
                raise DataError(f"{source}.joints.{name}: '{key}' is the name of a model joint; the keys of an entry "
                                f"name the controller's joints (e.g. J{key}), which feed the model joints.")
            if not key.replace("_", "").isalnum() or not key[0].isalpha():
                raise DataError(f"{source}.joints.{name}: controller joint name '{key}' must be letters, digits and _.")
            if key not in controller:
                controller.append(key)
                kinds.append(model_joints[name])
    n, m = len(model_joints), len(controller)
    a = np.zeros((n, m))
    b = np.zeros(n)
    for i, (name, kind) in enumerate(model_joints.items()):
        entry = {str(k): v for k, v in joints[name].items()}
        where = f"{source}.joints.{name}"
        ratio = entry.get("ratio", 1.0)
        if not isinstance(ratio, (int, float)) or isinstance(ratio, bool) or not math.isfinite(ratio) or ratio == 0:
            raise DataError(f"{where}.ratio must be a finite non-zero number, got {ratio!r}.")
        plausible_in(abs(ratio), 1.0 / MAX_RATIO, MAX_RATIO, "", f"{where}.ratio", "gear ratio magnitude")
        off = entry.get("offset", 0.0)
        if not isinstance(off, (int, float)) or isinstance(off, bool) or not math.isfinite(off):
            raise DataError(f"{where}.offset must be a finite number, got {off!r}.")
        own = "angle" if kind == "R" else "length"
        unit_factor(units[own], own, f"{source}.units.{own}")
        b[i] = (plausible_angle(off, units[own], f"{where}.offset") if own == "angle"
                else plausible_length(off, units[own], f"{where}.offset"))
        for key, coef in entry.items():
            if key in _RESERVED:
                continue
            if not isinstance(coef, (int, float)) or isinstance(coef, bool) or not math.isfinite(coef):
                raise DataError(f"{where}.{key} must be a finite number, got {coef!r}.")
            plausible_in(coef, -MAX_COEFFICIENT, MAX_COEFFICIENT, "", f"{where}.{key}", "coupling coefficient")
            k = controller.index(key)
            if kinds[k] != kind and coef != 0:
                raise DataError(f"{where}.{key}: a {'revolute' if kind == 'R' else 'prismatic'} joint cannot be "
                                f"driven by controller joint '{key}' of the other type.")
            a[i, k] = coef / ratio
    if np.linalg.matrix_rank(a) < n:
        raise DataError(f"{source}: the joint map is singular (two model joints follow the same controller "
                        f"combination).")
    declared = {name: {str(k): v for k, v in joints[name].items()} for name in model_joints}
    return JointMap(list(model_joints), controller, kinds, a, b, units, declared)
