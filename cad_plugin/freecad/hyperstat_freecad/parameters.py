"""Template parameters as FreeCAD properties, and a spreadsheet whose aliases drive them.

Units: a template parameter in mm becomes an ``App::PropertyDistance`` (mm, signed), one
in rad an ``App::PropertyAngle`` (FreeCAD shows degrees; hyperstat receives rad), any
other a plain ``App::PropertyFloat``.  Values leave FreeCAD in the template's own units,
printed with ``repr`` so that no digit is lost.
"""

from __future__ import annotations

import json
import math

from .runner import HyperstatWorkbenchError

__all__ = ["PROPERTY_GROUP", "parameter_specs", "add_parameter_properties", "set_parameter", "current_parameters",
           "cli_overrides", "bind_spreadsheet", "expression_of"]

PROPERTY_GROUP = "Template parameters"
_PROPERTY_TYPE = {"mm": "App::PropertyDistance", "rad": "App::PropertyAngle"}


def _tooltip(spec: dict) -> str:
    unit = spec.get("unit", "1")
    bounds = []
    if spec.get("minimum") is not None:
        bounds.append(f"minimum {spec['minimum']:g} {unit}")
    if spec.get("maximum") is not None:
        bounds.append(f"maximum {spec['maximum']:g} {unit}")
    extra = f" ({', '.join(bounds)})" if bounds else ""
    return f"{spec.get('doc', '')} [{unit}]{extra}; default {spec.get('default'):g} {unit}"


def add_parameter_properties(obj, specs: list[dict]) -> None:
    """One property per template parameter, set to its default.

    Raises
    ------
    HyperstatWorkbenchError
        If a parameter name is already a property of the object (``Label``, ``Status``...).
    """
    for spec in specs:
        name = spec["name"]
        if name in obj.PropertiesList:
            raise HyperstatWorkbenchError(
                f"template parameter '{name}' has the name of a property of the skeleton object: rename it in the template."
            )
        obj.addProperty(_PROPERTY_TYPE.get(spec.get("unit"), "App::PropertyFloat"), name, PROPERTY_GROUP, _tooltip(spec))
        set_parameter(obj, spec, float(spec["default"]))


def set_parameter(obj, spec: dict, value: float) -> None:
    """Set one parameter from a value in the template's unit (mm, rad or none)."""
    value = float(value)
    if spec.get("unit") == "rad":
        value = math.degrees(value)  # App::PropertyAngle holds degrees
    setattr(obj, spec["name"], value)


def _read(obj, spec: dict) -> float:
    prop = obj.getPropertyByName(spec["name"])
    unit = spec.get("unit")
    if unit == "rad":
        return float(prop.getValueAs("rad"))
    if unit == "mm":
        return float(prop.getValueAs("mm"))
    return float(prop)


def parameter_specs(obj) -> list[dict]:
    """Template parameters of the skeleton (name, default, unit, doc, minimum, maximum)."""
    text = getattr(obj, "ParameterSpecs", "") or "[]"
    return json.loads(text)


def current_parameters(obj) -> dict[str, float]:
    """Parameter values of the object in the template's units (mm, rad), keyed by name."""
    return {spec["name"]: _read(obj, spec) for spec in parameter_specs(obj)}


def cli_overrides(values: dict[str, float]) -> list[str]:
    """``-p NAME=VALUE`` arguments for ``hyperstat build`` (values in template units)."""
    out: list[str] = []
    for name, value in sorted(values.items()):
        if not math.isfinite(value):
            raise HyperstatWorkbenchError(f"template parameter '{name}' is {value}: give a finite number.")
        out += ["-p", f"{name}={value!r}"]
    return out


def expression_of(obj, name: str) -> str:
    """The expression driving property ``name`` (empty if it is set by hand)."""
    for prop, expr in obj.ExpressionEngine:
        if prop == name:
            return expr
    return ""


def _alias(sheet, cell: str, name: str) -> str:
    for candidate in (name, f"{name}_", f"p_{name}"):
        try:
            sheet.setAlias(cell, candidate)
            return candidate
        except (ValueError, RuntimeError):
            continue
    raise HyperstatWorkbenchError(f"template parameter '{name}' cannot name a spreadsheet cell alias.")


def bind_spreadsheet(obj, specs: list[dict]):
    """A spreadsheet listing the parameters, each value cell aliased and bound by ``setExpression``.

    Column A the name, B the value (alias = the name, or ``name_`` when the name reads as
    a cell address such as ``L1``), C the unit, D the meaning.  Editing B and recomputing
    changes the object's properties; the next Rebuild or Analyse uses them.
    """
    doc = obj.Document
    sheet = doc.addObject("Spreadsheet::Sheet", f"{obj.Name}Parameters")
    sheet.Label = f"{obj.Label} parameters"
    for col, title in zip("ABCD", ("parameter", "value", "unit", "meaning")):
        sheet.set(f"{col}1", f"'{title}")
    for row, spec in enumerate(specs, start=2):
        name, unit = spec["name"], spec.get("unit", "1")
        value = _read(obj, spec)
        sheet.set(f"A{row}", f"'{name}")
        if unit in ("mm", "rad"):
            sheet.set(f"B{row}", f"={value!r} {unit}")
        else:
            sheet.set(f"B{row}", repr(value))
        sheet.set(f"C{row}", f"'{unit}")
        sheet.set(f"D{row}", "'" + _tooltip(spec))
        alias = _alias(sheet, f"B{row}", name)
        obj.setExpression(name, f"{sheet.Name}.{alias}")
    sheet.setColumnWidth("D", 520)
    obj.Spreadsheet = sheet
    return sheet
