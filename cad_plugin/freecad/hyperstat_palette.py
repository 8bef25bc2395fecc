"""The tolerance classes' colours and legend words, and what a joint marker shows.

Units: none (colours, words).

One definition for the whole project: ``classes.json`` beside this file, read here.  FreeCAD
imports this module as ``hyperstat_palette`` (the workbench's folder is on its path); the
project as ``hyperstat.cad_plugin.freecad.hyperstat_palette``, re-exported by
:mod:`hyperstat.cad_plugin.palette` for the report and the pictures.  Pure Python with no import
outside the standard library, so that FreeCAD's own Python and the project's can both use it.

>>> CLASS_COLORS["assembly"], CLASS_RGB["compensable"]
('#c2007a', (0.0, 0.5137254901960784, 0.5607843137254902))
>>> element_classes({"parameters": [{"name": "dc2", "element": "2"}, {"name": "dK2", "element": "2"}],
...                  "tolerances": {"parameters": {"dc2": {"class": "assembly", "tolerance_ids": ["T5"]},
...                                                "dK2": {"class": "normalisation", "tolerance_ids": []}}}})
({'2': 'assembly'}, {'2': ['T5']})
"""

from __future__ import annotations

import json
import os

__all__ = ["DEFINITION", "CLASS_ORDER", "CLASS_COLORS", "CLASS_RGB", "CLASS_LABELS", "RETIRED_WORDS", "TOLERANCE_CLASSES",
           "hex_to_rgb", "element_classes", "callout_text", "tolerance_counts"]

#: the file that defines the classes' colours and words
DEFINITION = os.path.join(os.path.dirname(os.path.abspath(__file__)), "classes.json")
with open(DEFINITION, encoding="utf-8") as _fh:
    _DEFINITION = json.load(_fh)

#: most severe first: a joint marker takes the most severe class of its parameters
CLASS_ORDER: tuple = tuple(_DEFINITION["order"])
#: class -> colour ("#rrggbb"), the same in the report, the pictures and FreeCAD
CLASS_COLORS: dict = dict(_DEFINITION["colors"])
#: class -> legend words
CLASS_LABELS: dict = dict(_DEFINITION["labels"])
#: words of the retired vocabulary (stationarity verdicts): never in a legend, a label or a picture
RETIRED_WORDS: tuple = tuple(_DEFINITION["retired"])
#: the classes that are tolerances (the others, redundant and normalisation, are not)
TOLERANCE_CLASSES: tuple = ("assembly", "accuracy-critical", "compensable", "non-influent")


def hex_to_rgb(color: str) -> tuple:
    """``"#rrggbb"`` -> (r, g, b) in 0..1.

    >>> hex_to_rgb("#ff8000")
    (1.0, 0.5019607843137255, 0.0)
    """
    return tuple(int(color[i:i + 2], 16) / 255.0 for i in (1, 3, 5))


#: class -> (r, g, b) in 0..1
CLASS_RGB: dict = {k: hex_to_rgb(v) for k, v in CLASS_COLORS.items()}


def element_classes(analysis: dict | None) -> tuple:
    """Most severe tolerance class per element, and the tolerance ids of each element.

    Reads an analysis JSON (``hyperstat analyze --json``, or the report's): the elements of
    its ``parameters`` list and ``tolerances.parameters[name]`` (``class``, ``tolerance_ids``).
    Elements whose parameters have no tolerance entry are left out.
    """
    classes: dict = {}
    ids: dict = {}
    entries = ((analysis or {}).get("tolerances") or {}).get("parameters") or {}
    for p in (analysis or {}).get("parameters", []):
        entry = entries.get(p.get("name"))
        if not entry:
            continue
        cls = entry.get("class")
        if cls not in CLASS_ORDER:
            continue
        element = str(p["element"])
        if element not in classes or CLASS_ORDER.index(cls) < CLASS_ORDER.index(classes[element]):
            classes[element] = cls
        for t in entry.get("tolerance_ids") or ([entry["tolerance_id"]] if entry.get("tolerance_id") else []):
            if t not in ids.setdefault(element, []):
                ids[element].append(t)
    return classes, ids


def callout_text(name: str, ids: list) -> str:
    """``"21: T13, T15-T19"``: a joint and its tolerance ids, consecutive ids as ranges.

    >>> callout_text("21", ["T17", "T13", "T15", "T16", "T18", "T19"])
    '21: T13, T15-T19'
    >>> callout_text("6", [])
    '6'
    """
    nums = sorted(int(t[1:]) for t in ids if t[1:].isdigit())
    if not nums:
        return name
    runs, start = [], nums[0]
    for a, b in zip(nums, nums[1:] + [None]):
        if b != a + 1:
            runs.append(f"T{start}" if start == a else f"T{start}-T{a}")
            start = b
    return f"{name}: " + ", ".join(runs)


def tolerance_counts(tolerances: dict) -> dict:
    """Number of tolerances per class, in the report's order (the ``counts`` of the JSON, or counted from its items).

    >>> tolerance_counts({"items": [{"class": "assembly"}, {"class": "compensable"}, {"class": "assembly"}]})
    {'assembly': 2, 'accuracy-critical': 0, 'compensable': 1, 'non-influent': 0}
    """
    if isinstance(tolerances.get("counts"), dict):
        return {c: int(tolerances["counts"].get(c, 0)) for c in TOLERANCE_CLASSES}
    counts = dict.fromkeys(TOLERANCE_CLASSES, 0)
    for item in tolerances.get("items", []):
        counts[item["class"]] = counts.get(item["class"], 0) + 1
    return counts
