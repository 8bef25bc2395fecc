"""``hyperstat parameters TEMPLATE``: what the FreeCAD workbench reads to make its properties (mm, rad)."""

import json

import pytest

from hyperstat.cad_plugin import describe, load_template
from hyperstat.cad_plugin.cli import main

from tests.conftest import TEMPLATES


@pytest.mark.parametrize("name", ["slider_crank", "tripteor_x7"])
def test_parameters_json_is_the_templates_declaration(tmp_path, capsys, name):
    out = tmp_path / "p.json"
    assert main(["parameters", str(TEMPLATES / f"{name}.py"), "--json", str(out), "--quiet"]) == 0
    assert capsys.readouterr().out == ""
    doc = json.loads(out.read_text())
    assert doc["parameters"] == describe(load_template(TEMPLATES / f"{name}.py").Parameters)
    assert doc["units"] == {"length": "mm", "angle": "rad"}


def test_parameters_prints_a_table(capsys):
    assert main(["parameters", str(TEMPLATES / "slider_crank.py")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split()[0] for ln in lines] == ["L1", "L2", "L3", "L4", "home_angle", "section"]


@pytest.mark.parametrize("source, message", [("missing.py", "no such template file"),
                                             ("model.json", "takes a template (.py)")])
def test_parameters_bad_input_is_one_sentence(tmp_path, capsys, source, message):
    out = tmp_path / "p.json"
    assert main(["parameters", str(tmp_path / source), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()
