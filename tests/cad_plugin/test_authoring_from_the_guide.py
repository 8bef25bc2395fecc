"""Two templates written from docs/authoring.md alone, by an author who read no source code.

Units: lengths in mm, angles in rad.

The templates of ``docs/validation/guide_authoring/`` were written by a helper that read only the guide,
the README and the docs they link, from one line each ("a Bennett linkage", "a planar 3-RRR"); what it got
stuck on went into the guide (its record: ``docs/validation/guide_authoring/README.md``).  Here ``analyze``
is compared with the screw theory of the same declarations (``tests/templates/screw_theory.py``, which
shares no code with the solver) and with the numbers the author wrote in each docstring.
"""

from __future__ import annotations

import json
import re

import pytest

from hyperstat.cad_plugin.cli import main
from hyperstat.cad_plugin.templates import build_template

from tests.conftest import ROOT
from tests.templates.screw_theory import screw_model

GUIDE_DIR = ROOT / "docs" / "validation" / "guide_authoring"


@pytest.mark.parametrize("name", ["bennett_user.py", "rrr3_user.py"])
def test_a_template_written_from_the_guide_analyses_as_its_theory(name, tmp_path, capsys):
    path = GUIDE_DIR / name
    said = re.search(r"Theory: mobility (\d+), degree of over-constraint (\d+)", path.read_text(encoding="utf-8"))
    mobility, overconstraint = map(int, said.groups())
    got = screw_model(build_template(path)).theory(configurations=14 if mobility == 1 else 8)
    assert got["condition_gap"] > 1e4, got
    assert (got["mobility"], got["overconstraint"]) == (mobility, overconstraint)
    out = tmp_path / "a.json"
    assert main(["analyze", str(path), "--json", str(out), "--quiet"]) == 0
    doc = json.loads(out.read_text(encoding="utf-8"))
    assert (doc["mobility"], doc["overconstraint"]) == (mobility, overconstraint)
    assert doc["rank"] == got["conditions"] + got["overconstraint"]
