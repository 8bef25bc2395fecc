"""Typed, documented template parameters and their parsing from the command line.

Units: lengths in mm, angles in rad.  A template declares its parameters as a
dataclass whose fields are made with :func:`param`; the command line passes
``NAME=VALUE`` strings that are parsed as numbers with an optional unit, never
evaluated as code.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

from hyperstat.solver.cli.suggest import did_you_mean
from hyperstat.solver.errors import TemplateError
from hyperstat.solver.plausibility import plausible_angle, plausible_length

__all__ = ["param", "describe", "parse_value", "parse_overrides", "make_parameters"]

_LENGTH = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}
_ANGLE = {"rad": 1.0, "deg": math.pi / 180.0}
_NUMBER = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z]*)\s*$")


def param(default: float, unit: str, doc: str, minimum: float | None = None,
          maximum: float | None = None, exclusive_minimum: bool = False) -> Any:
    """A template parameter: default value, unit (``"mm"``, ``"rad"``, ``"1"``), meaning and bounds."""
    return dataclasses.field(
        default=default,
        metadata={"unit": unit, "doc": doc, "minimum": minimum, "maximum": maximum,
                  "exclusive_minimum": exclusive_minimum},
    )


def describe(parameters_cls: type) -> list[dict]:
    """Name, default, unit, meaning and bounds of every parameter of a template."""
    out = []
    for f in dataclasses.fields(parameters_cls):
        md = f.metadata
        out.append({"name": f.name, "default": f.default, "unit": md.get("unit", "1"), "doc": md.get("doc", ""),
                    "minimum": md.get("minimum"), "maximum": md.get("maximum")})
    return out


def parse_value(text: str, unit: str, name: str) -> float:
    """Parse ``"40"``, ``"40mm"``, ``"4 cm"``, ``"30deg"`` into the parameter's unit.

    Raises
    ------
    TemplateError
        If the text is not a number, or its unit does not fit the parameter.
    """
    m = _NUMBER.match(text)
    if not m:
        raise TemplateError(f"parameter '{name}': '{text}' is not a number (with an optional unit).")
    value = float(m.group(1))
    given = m.group(2)
    if not given:
        return value
    table = _LENGTH if unit == "mm" else _ANGLE if unit == "rad" else {}
    if given not in table:
        allowed = ", ".join(table) if table else "none (a plain number)"
        raise TemplateError(f"parameter '{name}' is in {unit}: unit '{given}' is not accepted (use {allowed}).")
    return value * table[given]


def parse_overrides(items: list[str] | None, parameters_cls: type) -> dict[str, float]:
    """``["NAME=VALUE", ...]`` to a dict of floats in the parameters' units."""
    fields = {f.name: f for f in dataclasses.fields(parameters_cls)}
    out: dict[str, float] = {}
    for item in items or []:
        if "=" not in item:
            raise TemplateError(f"parameter override '{item}' must read NAME=VALUE.")
        name, text = (s.strip() for s in item.split("=", 1))
        if name in out:
            raise TemplateError(f"parameter '{name}' is given twice (-p {name}=...); give it once.")
        if name not in fields:
            valid = ", ".join(f"{n} [{f.metadata.get('unit', '1')}]" for n, f in fields.items())
            raise TemplateError(f"unknown parameter '{name}'{did_you_mean(name, fields)}; valid parameters: {valid}.")
        out[name] = parse_value(text, fields[name].metadata.get("unit", "1"), name)
    return out


def _degrees_hint(value: float, md: dict) -> str:
    """``"; did you mean 30deg (0.5236 rad)?"`` when an angle out of its bounds would fit them in degrees.

    An angle without a unit is in rad (the project's unit); a value out of bounds that fits them once read in
    degrees is refused with this hint, never reinterpreted: a silently converted value would build another
    mechanism that looks right.

    >>> _degrees_hint(30.0, {"unit": "rad", "minimum": -3.14, "maximum": 3.14})
    '; did you mean 30deg (0.5236 rad)? an angle without a unit is in rad'
    >>> _degrees_hint(30.0, {"unit": "mm", "maximum": 10.0})
    ''
    """
    if md.get("unit") != "rad":
        return ""
    rad = math.radians(value)
    lo, hi = md.get("minimum"), md.get("maximum")
    if (lo is not None and (rad < lo or (md.get("exclusive_minimum") and rad == lo))) or (hi is not None and rad > hi):
        return ""
    return f"; did you mean {value:g}deg ({rad:.4g} rad)? an angle without a unit is in rad"


def make_parameters(parameters_cls: type, values: dict[str, Any]) -> Any:
    """Instantiate and bound-check a template's parameter dataclass."""
    fields = {f.name: f for f in dataclasses.fields(parameters_cls)}
    unknown = [k for k in values if k not in fields]
    if unknown:
        valid = ", ".join(fields)
        raise TemplateError(f"unknown parameter '{unknown[0]}'{did_you_mean(unknown[0], fields)}; "
                            f"valid parameters: {valid}.")
    for name, value in values.items():
        md = fields[name].metadata
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise TemplateError(f"parameter '{name}' must be a number, got {value!r}.") from None
        if not math.isfinite(value):
            raise TemplateError(f"parameter '{name}' must be finite, got {value}.")
        lo, hi = md.get("minimum"), md.get("maximum")
        if lo is not None and (value < lo or (md.get("exclusive_minimum") and value == lo)):
            cmp = ">" if md.get("exclusive_minimum") else ">="
            raise TemplateError(f"parameter '{name}' must be {cmp} {lo:g} {md.get('unit', '')}, got {value:g}"
                                f"{_degrees_hint(value, md)}.")
        if hi is not None and value > hi:
            raise TemplateError(f"parameter '{name}' must be <= {hi:g} {md.get('unit', '')}, got {value:g}"
                                f"{_degrees_hint(value, md)}.")
        if md.get("unit") == "mm":
            plausible_length(value, "mm", f"parameter '{name}'", error=TemplateError)
        elif md.get("unit") == "rad":
            plausible_angle(value, "rad", f"parameter '{name}'", error=TemplateError)
        values[name] = value
    return parameters_cls(**values)
