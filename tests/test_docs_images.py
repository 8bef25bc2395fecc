"""The README's and the docs' pictures cannot go stale: each was drawn by a real command, with today's words.

Units: none.

``make images`` draws every picture of ``docs/img`` again (``docs/make_images.py`` and the FreeCAD
clicking test) and writes beside each ``NAME.png`` its record ``NAME.png.json``: the command, the
PNG's SHA-256 and the words the picture shows.  A picture fails here when it has no record, when
it was redrawn by hand (its hash differs), or when its words are not today's: a class the
classification no longer has, a legend whose words changed (``cad_plugin/freecad/classes.json``),
or a retired word of the stationarity vocabulary (forced, coupled, free, gauge, none).
"""

from __future__ import annotations

import hashlib
import json
import re

import pytest

from hyperstat.cad_plugin.palette import CLASS_LABELS, CLASS_ORDER, RETIRED_WORDS

from tests.conftest import ROOT

IMG = ROOT / "docs" / "img"
PICTURES = sorted(IMG.glob("*.png"))


def _strings(value) -> list[str]:
    if isinstance(value, str):
        return [value]
    if isinstance(value, dict):
        return [s for v in value.values() for s in _strings(v)]
    if isinstance(value, list):
        return [s for v in value for s in _strings(v)]
    return []


def test_every_picture_the_docs_show_is_there():
    shown = set()
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for ref in re.findall(r"!\[[^\]]*\]\(([^)]+\.png)\)", page.read_text(encoding="utf-8")):
            path = (page.parent / ref).resolve()
            assert path.is_file(), f"{page.name} shows {ref}, which does not exist"
            shown.add(path)
    assert shown and shown <= {p.resolve() for p in PICTURES}


@pytest.mark.parametrize("png", PICTURES, ids=[p.name for p in PICTURES])
def test_each_picture_was_drawn_by_a_command_with_todays_words(png):
    record_path = png.with_name(png.name + ".json")
    assert record_path.is_file(), f"{png.name} has no record: draw it with 'make images'"
    record = json.loads(record_path.read_text(encoding="utf-8"))
    assert record["png_sha256"] == hashlib.sha256(png.read_bytes()).hexdigest(), \
        f"{png.name} changed after its record was written: draw it with 'make images'"
    assert record["command"]
    words = " ".join(_strings({k: v for k, v in record.items() if k not in ("command", "png_sha256")}))
    for word in RETIRED_WORDS:
        assert not re.search(rf"(?<![\w-]){re.escape(word)}(?![\w-])", words, flags=re.I), \
            f"{png.name} shows the retired word '{word}': draw it again with 'make images'"
    classes = record.get("classes") or []
    assert set(classes) <= set(CLASS_ORDER), f"{png.name} was drawn with classes {classes}"
    for cls in classes:  # a legend written with today's words for each class it draws
        assert any(CLASS_LABELS[cls] in text or cls in text for text in _strings(record.get("legend"))), (png.name, cls)
