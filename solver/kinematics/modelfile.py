"""The model file: a versioned JSON description of a mechanism (``*.skel.json``).

Units: lengths in mm, angles in rad (stated in the file's ``units`` field).

The model file is the contract between the CAD side and the solver; anything that
writes it can use the solver.  Its schema is ``solver/kinematics/schema/model.schema.json``
and is documented in ``docs/model-format.md``.  Reading a malformed file raises
:class:`~hyperstat.solver.errors.ModelError` with one sentence naming the file and the field.
Writing is atomic; a file written and read back gives an equal mechanism.
"""

from __future__ import annotations

import json
import os
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

from hyperstat.solver.atomic import dumps_json, write_text
from hyperstat.solver.errors import ModelError
from hyperstat.solver.strict_load import load_json
from hyperstat.solver.kinematics.model import (
    Chain,
    ConfigurationFrame,
    Defect,
    FixedTransform,
    Joint,
    Mechanism,
    Placement,
)

__all__ = [
    "FORMAT",
    "VERSION",
    "model_schema",
    "mechanism_to_dict",
    "mechanism_from_dict",
    "dumps_model",
    "save_model",
    "load_model",
]

FORMAT = "hyperstat-model"
VERSION = 1


@lru_cache(maxsize=1)
def model_schema() -> dict:
    """The JSON Schema of the model file."""
    text = resources.files("hyperstat.solver.kinematics").joinpath("schema/model.schema.json").read_text(encoding="utf-8")
    return json.loads(text)


def _placement(p: Placement) -> dict:
    return {"origin": list(p.origin), "z_axis": list(p.z_axis), "x_axis": list(p.x_axis)}


def _defects(element_name: str, defects: tuple[Defect, ...]) -> list:
    return [d.component if d.name == f"d{d.component}{element_name}" else {"component": d.component, "name": d.name}
            for d in defects]


def mechanism_to_dict(m: Mechanism) -> dict:
    """Dictionary of the model file (format ``hyperstat-model``, version 1)."""
    chains = []
    for ch in m.chains:
        els = []
        for el in ch.elements:
            if isinstance(el, Joint):
                els.append({
                    "kind": "joint", "name": el.name, "type": el.type, "role": el.role,
                    "placement": _placement(el.placement), "defects": _defects(el.name, el.defects),
                    "range": [el.range[0], el.range[1]], "home": el.home,
                })
            elif isinstance(el, FixedTransform):
                els.append({"kind": "fixed", "name": el.name, "placement": _placement(el.placement),
                            "defects": _defects(el.name, el.defects)})
            else:
                els.append({"kind": "frame", "name": el.name, "placement": _placement(el.placement)})
        chains.append({"name": ch.name, "start": ch.start, "end": ch.end, "elements": els})
    return {
        "format": FORMAT,
        "version": VERSION,
        "units": {"length": "mm", "angle": "rad"},
        "name": m.name,
        "description": m.description,
        "base": m.base,
        "output": m.output,
        "chains": chains,
        "metadata": {k: v for k, v in m.metadata.items() if k != "tolerancing"},
        **({"tolerancing": m.metadata["tolerancing"]} if m.metadata.get("tolerancing") else {}),
    }


def _path(parts) -> str:
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "(top level)"


def _schema_message(err) -> str:
    path = _path(err.absolute_path)
    v = err.validator
    inst = err.instance
    if v == "required":
        missing = [k for k in err.validator_value if k not in inst]
        field = f"{path}.{missing[0]}" if path != "(top level)" else missing[0]
        return f"field '{field}' is missing"
    if v == "additionalProperties":
        extra = sorted(set(inst) - set(err.schema.get("properties", {})))
        field = f"{path}.{extra[0]}" if path != "(top level)" else extra[0]
        return f"field '{field}' is not part of the format"
    if v == "const":
        return f"field '{path}' must be {json.dumps(err.validator_value)}, got {json.dumps(inst)}"
    if v == "enum":
        return f"field '{path}' must be one of {', '.join(json.dumps(x) for x in err.validator_value)}, got {json.dumps(inst)}"
    if v == "type":
        return f"field '{path}' must be of type {err.validator_value}, got {json.dumps(inst)}"
    if v in ("minItems", "maxItems"):
        return f"field '{path}' has {len(inst)} item(s), which is the wrong number"
    if v == "minLength":
        return f"field '{path}' must not be empty"
    if v == "oneOf" and "defects" in path:
        return f"field '{path}' must be a component letter (I J K a b c G) or {{\"component\": ..., \"name\": ...}}"
    return f"field '{path}' is invalid ({err.message})"


def mechanism_from_dict(doc: Any, source: str = "model") -> Mechanism:
    """Mechanism from a model-file dictionary; errors name ``source`` and the field.

    Raises
    ------
    ModelError
        On any malformed content.
    """
    import jsonschema

    if not isinstance(doc, dict):
        raise ModelError(f"{source}: the model file must hold a JSON object at the top level.")
    if doc.get("format") != FORMAT:
        raise ModelError(f"{source}: field 'format' must be \"{FORMAT}\", got {json.dumps(doc.get('format'))}.")
    if doc.get("version") != VERSION:
        raise ModelError(
            f"{source}: field 'version' is {json.dumps(doc.get('version'))}, but this hyperstat reads version {VERSION}."
        )
    validator = jsonschema.Draft202012Validator(model_schema())
    errors = sorted(validator.iter_errors(doc), key=lambda e: (list(e.absolute_path), e.validator != "required"))
    if errors:
        best = jsonschema.exceptions.best_match(errors)
        raise ModelError(f"{source}: {_schema_message(best)}.")

    def placement(d: dict) -> Placement:
        return Placement(tuple(float(v) for v in d["origin"]), tuple(float(v) for v in d["z_axis"]),
                         tuple(float(v) for v in d["x_axis"]))

    def defects(name: str, items: list) -> tuple[Defect, ...]:
        return tuple(Defect(i, f"d{i}{name}") if isinstance(i, str) else Defect(i["component"], i["name"])
                     for i in items)

    chains = []
    for ch in doc["chains"]:
        els = []
        for e in ch["elements"]:
            if e["kind"] == "joint":
                els.append(Joint(e["name"], e["type"], e["role"], placement(e["placement"]),
                                 defects(e["name"], e["defects"]), (float(e["range"][0]), float(e["range"][1])),
                                 float(e["home"])))
            elif e["kind"] == "fixed":
                els.append(FixedTransform(e["name"], placement(e["placement"]), defects(e["name"], e["defects"])))
            else:
                els.append(ConfigurationFrame(e["name"], placement(e["placement"])))
        chains.append(Chain(ch["name"], ch["start"], ch["end"], tuple(els)))
    metadata = dict(doc.get("metadata", {}))
    if "tolerancing" in doc:  # optional, checked by the schema: task, measurements, spec, clearances
        metadata["tolerancing"] = doc["tolerancing"]
    try:
        mech = Mechanism(doc["name"], doc["base"], doc["output"], tuple(chains), doc.get("description", ""),
                         metadata)
    except ModelError as exc:
        raise ModelError(f"{source}: {exc}") from None
    from hyperstat.solver.kinematics.masses import check_declared_masses

    check_declared_masses(mech, source, ModelError)  # finite, plausible for each body's size, none left out
    return mech


def dumps_model(m: Mechanism) -> str:
    """Model-file text (deterministic; field order as in the format description)."""
    return dumps_json(mechanism_to_dict(m), sort_keys=False)


def save_model(m: Mechanism, path: str | os.PathLike) -> Path:
    """Write the model file atomically."""
    return write_text(path, dumps_model(m))


def load_model(path: str | os.PathLike) -> Mechanism:
    """Read and validate a model file.

    Raises
    ------
    ModelError
        If the file cannot be read, is not JSON, or does not follow the format.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ModelError(f"{path}: no such model file.") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"{path}: cannot be read as UTF-8 text ({exc.__class__.__name__}).") from None
    doc = load_json(text, str(path), error=ModelError)  # a key declared twice is refused, not overwritten
    return mechanism_from_dict(doc, source=str(path))
