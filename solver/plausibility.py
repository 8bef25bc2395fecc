"""Plausibility ranges of the numbers hyperstat reads: beyond them a value is a mistake, not a machine.

Units: mm and rad inside; every message states the value in the unit the input used.

A reader converts each value to mm or rad and checks it here, so that a table in degrees
labelled as radians, a length of 1e308 or a position in millimetres labelled as metres is
refused in one sentence naming the field, before any computation fails on it.  The ranges:

=================================  ==================================================
field                              plausible range
=================================  ==================================================
lengths and positions              ``|v| <= 100 m`` (:data:`LENGTH_LIMIT_MM`): no robot,
                                   machine or tracker set-up is larger
constant angles (DH ``alpha``,     ``|v| <= 2 pi`` (:data:`TURN`): more than a turn in a
``theta``, roll-pitch-yaw,         file that says ``rad`` is degrees ("looks like degrees")
rotation vectors, offsets)
joint ranges (revolute)            ``|v| <= 4 pi`` (:data:`JOINT_ANGLE_LIMIT`): two turns
                                   each way covers multi-turn wrists (e.g. +-400 deg)
=================================  ==================================================

Examples
--------
>>> plausible_angle(-90.0, "rad", "t.yaml: joints[0].alpha")
Traceback (most recent call last):
...
hyperstat.solver.errors.DataError: t.yaml: joints[0].alpha = -90 rad is beyond 2 pi rad (a turn): it looks like degrees (state the unit as deg).
>>> plausible_length(1e308, "mm", "t.yaml: joints[0].a")
Traceback (most recent call last):
...
hyperstat.solver.errors.DataError: t.yaml: joints[0].a = 1e+308 mm is not a plausible length (at most 100 m).
>>> round(plausible_angle(90.0, "deg", "alpha"), 6)
1.570796
"""

from __future__ import annotations

import math

from hyperstat.solver.errors import DataError

__all__ = ["LENGTH_LIMIT_MM", "TURN", "JOINT_ANGLE_LIMIT", "LENGTH_FACTORS", "ANGLE_FACTORS", "finite",
           "plausible_length", "plausible_angle", "plausible_in"]

#: largest plausible length or position (mm): 100 m
LENGTH_LIMIT_MM = 1.0e5
#: one turn (rad): the largest plausible constant angle
TURN = 2.0 * math.pi
#: largest plausible joint-range bound of a revolute joint (rad): two turns
JOINT_ANGLE_LIMIT = 4.0 * math.pi

LENGTH_FACTORS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}
ANGLE_FACTORS = {"rad": 1.0, "deg": math.pi / 180.0, "mrad": 1e-3, "urad": 1e-6}


def finite(value: float, where: str, unit: str = "", error: type = DataError) -> float:
    """``value`` as a float, refused (naming ``where``) when NaN or infinite (or an integer no float holds)."""
    try:
        v = float(value)
    except OverflowError:
        v = math.inf
    if not math.isfinite(v):
        raise error(f"{where} must be a finite number, got {value!r}{' ' + unit if unit else ''}.")
    return v


def plausible_length(value: float, unit: str, where: str, limit_mm: float = LENGTH_LIMIT_MM,
                     error: type = DataError) -> float:
    """A length given in ``unit`` (mm, cm, m, in), in mm; refused beyond ``limit_mm``.

    A value in metres that would be plausible in millimetres is named as such.
    """
    v = finite(value, where, unit, error)
    mm = v * LENGTH_FACTORS[unit]
    if abs(mm) > limit_mm:
        hint = ""
        if unit == "m" and abs(v) <= limit_mm:
            hint = ": it looks like millimetres (state the unit as mm)"
        raise error(f"{where} = {v:g} {unit} is not a plausible length (at most {_length_text(limit_mm)}){hint}.")
    return mm


def plausible_angle(value: float, unit: str, where: str, limit_rad: float = TURN, error: type = DataError) -> float:
    """An angle given in ``unit`` (rad, deg, mrad, urad), in rad; refused beyond ``limit_rad``.

    An angle in radians beyond the limit whose value would fit in degrees "looks like degrees".
    """
    v = finite(value, where, unit, error)
    rad = v * ANGLE_FACTORS[unit]
    if abs(rad) > limit_rad:
        bound = _angle_text(limit_rad)
        if unit == "rad" and abs(math.radians(v)) <= max(limit_rad, TURN):
            raise error(f"{where} = {v:g} rad is beyond {bound}: it looks like degrees (state the unit as deg).")
        raise error(f"{where} = {v:g} {unit} is not a plausible angle (at most {bound}).")
    return rad


def plausible_in(value: float, low: float, high: float, unit: str, where: str, what: str,
                 error: type = DataError) -> float:
    """A value refused outside ``[low, high]`` (``unit``), naming what the range is for."""
    v = finite(value, where, unit, error)
    if not low <= v <= high:
        u = f" {unit}" if unit else ""
        raise error(f"{where} = {v:g}{u} is not a plausible {what} (between {low:g} and {high:g}{u}).")
    return v


def _length_text(mm: float) -> str:
    return f"{mm / 1000.0:g} m" if mm >= 1000.0 else f"{mm:g} mm"


def _angle_text(rad: float) -> str:
    turns = rad / TURN
    if abs(turns - round(turns)) < 1e-12 and round(turns) in (1, 2):
        return "2 pi rad (a turn)" if round(turns) == 1 else "4 pi rad (two turns)"
    return f"{rad:g} rad"
