"""docs/authoring.md as written: its example templates build and analyse, its mistakes give its errors.

Units: lengths in mm, angles in rad.

The code blocks are read from the markdown (```` ```python file=NAME ```` blocks are written
to files as they are, ```` ```python mistake file=NAME ```` blocks change one line of that
example, ```` ```text error ```` blocks are what the command prints); nothing of the guide is
repeated here.  The expected mobility and over-constraint come from the Kutzbach count and
the known mobility of each linkage, the assembly conditions from the theory line of the
shipped corpus template the example is (:mod:`tests.templates.test_corpus` checks those lines
against an independent screw computation), not from a run.
"""

from __future__ import annotations

import json
import re

import pytest

from hyperstat.cad_plugin.cli import main
from hyperstat.cad_plugin.templates import CORPUS_DIR
from hyperstat.solver.tolerances.declaration import parse_declaration

from tests.conftest import ROOT
from tests.templates.corpus_runner import theory_of

GUIDE = (ROOT / "docs" / "authoring.md").read_text(encoding="utf-8")
WORDS = " ".join(GUIDE.split())  # the prose as read, line breaks aside
BLOCKS = re.findall(r"```([^\n]*)\n(.*?)```", GUIDE, flags=re.S)
FILES = {info.split("file=")[1].strip(): body for info, body in BLOCKS if info.startswith("python file=")}
MISTAKES = [(info.split("file=")[1].strip(), body) for info, body in BLOCKS if info.startswith("python mistake")]
ERRORS = [body.strip() for info, body in BLOCKS if info.strip() == "text error"]
SNIPPETS = [body for info, body in BLOCKS if info.strip() == "python"]
# name: (bodies incl. the base, joints (all revolute), true mobility, assembly conditions); the planar 3-RRR's 21 are
# the screw computation's (tests/templates/screw_theory.py: 15 conditions on its lines + its over-constraint 6)
LINKAGES = {"planar_3rrr.py": (8, 9, 3, 21), "spherical_4r.py": (4, 4) + theory_of("spherical_4r")[::2],
            "bennett.py": (4, 4) + theory_of("bennett")[::2]}
SAID = {"planar_3rrr.py": "mobility {m} and a degree of over-constraint {d}",
        "spherical_4r.py": "Mobility {m}, degree of over-constraint {d}",
        "bennett.py": "Mobility {m}, degree of over-constraint {d}, and {c} assembly conditions"}


@pytest.fixture()
def examples(tmp_path, monkeypatch):
    for name, body in FILES.items():
        (tmp_path / name).write_text(body, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_the_guide_has_its_three_examples_and_its_mistakes():
    assert set(FILES) == set(LINKAGES)
    assert len(MISTAKES) == 4 and len(ERRORS) == 6


@pytest.mark.parametrize("name", ["spherical_4r.py", "bennett.py"])
def test_the_spatial_examples_are_the_shipped_corpus_templates(name):
    """What the guide shows is what ships: letter for letter."""
    assert FILES[name] == (CORPUS_DIR / name).read_text(encoding="utf-8")


def test_the_position_only_task_is_a_shipped_declaration():
    """The guide's position-only TOLERANCING is a corpus template's, and it parses."""
    (snippet,) = SNIPPETS
    assert snippet in (CORPUS_DIR / "goldberg_5r.py").read_text(encoding="utf-8")
    scope: dict = {}
    exec(snippet, scope)  # noqa: S102 - the guide's own block, as a template would hold it
    decl = parse_declaration(scope["TOLERANCING"], "authoring.md")
    assert list(decl.task) == ["position"] and decl.orientation_rad is None


@pytest.mark.parametrize("name", sorted(LINKAGES))
def test_each_example_builds_and_analyses_as_written(examples, name, capsys):
    bodies, joints, mobility, conditions = LINKAGES[name]
    out = examples / "a.json"
    assert main(["analyze", name, "--verify", "--json", str(out), "--quiet"]) == 0, capsys.readouterr().err
    doc = json.loads(out.read_text())
    kutzbach = 6 * (bodies - 1) - 5 * joints
    assert doc["mobility"] == mobility and doc["overconstraint"] == mobility - kutzbach
    assert doc["tolerances"]["counts"]["assembly"] == conditions
    assert doc["verification"] and all(c["confirmed"] for c in doc["verification"])
    assert doc["stability"]["stable"]
    assert SAID[name].format(m=mobility, d=mobility - kutzbach, c=conditions) in WORDS  # what the guide says
    assert f"{conditions} assembly conditions" in WORDS
    assert main(["build", name, "--model", str(examples / "m.json"), "--step", str(examples / "m.step"),
                 "--quiet"]) == 0


def test_the_mistakes_give_the_errors_the_guide_quotes(examples, capsys):
    for (name, body), error in zip(MISTAKES, ERRORS):
        good = FILES[name]
        right, wrong = body.rstrip("\n").split("\n")
        assert good.count(right + "\n") == 1, right
        (examples / name).write_text(good.replace(right + "\n", wrong + "\n"), encoding="utf-8")
        assert main(["analyze", name, "--quiet"]) == 2
        assert capsys.readouterr().err.strip() == error
        (examples / name).write_text(good, encoding="utf-8")
    for block in ERRORS[len(MISTAKES):]:
        command, error = block.split("\n")
        assert command.startswith(".venv/bin/hyperstat ")
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
    assert counts[1] - counts[0] == 6 and f"{counts[1]} defect parameters instead of {counts[0]}" in WORDS


def test_the_guide_commands_name_the_venv():
    """Every command line the guide shows runs the checkout's .venv/bin/hyperstat."""
    commands = [line for info, body in BLOCKS if not info.strip() or info.strip() == "text error"
                for line in body.splitlines() if "hyperstat " in line and not line.startswith("hyperstat: ")]
    assert commands and all(line.startswith(".venv/bin/hyperstat ") for line in commands), commands
