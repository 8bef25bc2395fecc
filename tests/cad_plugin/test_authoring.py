"""docs/authoring.md as written: its two example templates build and analyse, its mistakes give its errors.

Units: lengths in mm, angles in rad.

The code blocks are read from the markdown (```` ```python file=NAME ```` blocks are written
to files as they are, ```` ```python mistake ```` blocks change one line of the planar
example, ```` ```text error ```` blocks are what the command prints); nothing of the guide is
repeated here.  The expected mobility and over-constraint come from the Kutzbach count and
the known mobility of each linkage, not from a run.
"""

from __future__ import annotations

import json
import re

import pytest

from hyperstat.cad_plugin.cli import main

from tests.conftest import ROOT

GUIDE = (ROOT / "docs" / "authoring.md").read_text(encoding="utf-8")
BLOCKS = re.findall(r"```([^\n]*)\n(.*?)```", GUIDE, flags=re.S)
FILES = {info.split("file=")[1].strip(): body for info, body in BLOCKS if "file=" in info}
MISTAKES = [body for info, body in BLOCKS if info.strip() == "python mistake"]
ERRORS = [body.strip() for info, body in BLOCKS if info.strip() == "text error"]
# name: (bodies incl. the base, joints (all revolute), true mobility) -> over-constraint = mobility - Kutzbach count
LINKAGES = {"planar_3rrr.py": (8, 9, 3), "spherical_4r.py": (4, 4, 1)}


@pytest.fixture()
def examples(tmp_path, monkeypatch):
    for name, body in FILES.items():
        (tmp_path / name).write_text(body, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_the_guide_has_its_two_examples_and_three_mistakes():
    assert set(FILES) == set(LINKAGES)
    assert len(MISTAKES) == 3 and len(ERRORS) == 4


@pytest.mark.parametrize("name", sorted(LINKAGES))
def test_each_example_builds_and_analyses_as_written(examples, name, capsys):
    bodies, joints, mobility = LINKAGES[name]
    out = examples / "a.json"
    assert main(["analyze", name, "--verify", "--json", str(out), "--quiet"]) == 0, capsys.readouterr().err
    doc = json.loads(out.read_text())
    kutzbach = 6 * (bodies - 1) - 5 * joints
    assert doc["mobility"] == mobility and doc["overconstraint"] == mobility - kutzbach
    assert doc["verification"] and all(c["confirmed"] for c in doc["verification"])
    assert doc["stability"]["stable"]
    words = f"mobility {mobility} and a degree of over-constraint {mobility - kutzbach}" if name.startswith("planar") \
        else f"Mobility {mobility}, degree of over-constraint {mobility - kutzbach}"
    assert words in GUIDE  # what the guide says about it
    assert main(["build", name, "--model", str(examples / "m.json"), "--step", str(examples / "m.step"),
                 "--quiet"]) == 0


def test_the_mistakes_give_the_errors_the_guide_quotes(examples, capsys):
    planar = FILES["planar_3rrr.py"]
    for body, error in zip(MISTAKES, ERRORS):
        right, wrong = body.rstrip("\n").split("\n")
        assert planar.count(right + "\n") == 1, right
        (examples / "planar_3rrr.py").write_text(planar.replace(right + "\n", wrong + "\n"), encoding="utf-8")
        assert main(["analyze", "planar_3rrr.py", "--quiet"]) == 2
        assert capsys.readouterr().err.strip() == error
    (examples / "planar_3rrr.py").write_text(planar, encoding="utf-8")
    command, error = ERRORS[3].split("\n")
    assert main(command.split()[1:]) == 2
    assert capsys.readouterr().err.strip() == error


def test_forgetting_the_reference_joint_adds_six_silent_parameters(examples, capsys):
    planar = FILES["planar_3rrr.py"]
    assert 'defects="" if i == 1 else "IJKabc"' in planar
    (examples / "no_reference.py").write_text(planar.replace('defects="" if i == 1 else "IJKabc"', 'defects="IJKabc"'))
    counts = []
    for name in ("planar_3rrr.py", "no_reference.py"):
        assert main(["analyze", name, "--json", str(examples / f"{name}.json"), "--quiet"]) == 0
        counts.append(json.loads((examples / f"{name}.json").read_text())["counts"]["total"])
    assert counts[1] - counts[0] == 6 and f"{counts[1]} defect parameters instead of {counts[0]}" in GUIDE
