"""Templates: every one builds with documented parameters; overrides change geometry and model."""

import dataclasses
import json

import numpy as np
import pytest

from hyperstat.cad_plugin import build_template, describe, list_templates, load_template
from hyperstat.cad_plugin.cli import main
from hyperstat.solver import TemplateError

from tests.conftest import TEMPLATES

NAMES = ["slider_crank", "tripteor_x7", "triflex_ii", "scara", "hexapod", "five_bar", "planar_3rrr"]


def test_the_seven_templates_are_shipped():
    assert sorted(p.stem for p in list_templates()) == sorted(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_template_parameters_are_typed_and_documented(name):
    module = load_template(TEMPLATES / f"{name}.py")
    for f in dataclasses.fields(module.Parameters):
        assert f.type in ("float", float), f.name
        assert f.metadata["unit"] in ("mm", "rad", "1"), f.name
        assert len(f.metadata["doc"]) > 10, f.name
    assert module.__doc__ and "Units" in module.__doc__
    assert all(d["default"] is not None for d in describe(module.Parameters))


@pytest.mark.parametrize("name", NAMES)
def test_template_builds_and_closes_at_home(name):
    from hyperstat.solver import Kinematics

    mech = build_template(TEMPLATES / f"{name}.py").mechanism()
    Kinematics(mech).check_home()
    assert mech.metadata["template"] == f"{name}.py"


def test_override_changes_the_geometry_and_the_model(tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    assert main(["build", str(TEMPLATES / "tripteor_x7.py"), "--model", str(a)]) == 0
    assert main(["build", str(TEMPLATES / "tripteor_x7.py"), "-p", "depth=0.9m", "--model", str(b)]) == 0
    da, db = json.loads(a.read_text()), json.loads(b.read_text())
    assert da["metadata"]["parameters"]["depth"] == 800.0 and db["metadata"]["parameters"]["depth"] == 900.0
    # leg 1's platform revolute sits at the end of the slide: the home stroke grows with the depth
    leg1 = lambda d: {e["name"]: e for e in d["chains"][0]["elements"]}  # noqa: E731
    l_a, l_b = leg1(da)["41"]["home"], leg1(db)["41"]["home"]
    assert l_a == pytest.approx(np.hypot(250.0, 800.0)) and l_b == pytest.approx(np.hypot(250.0, 900.0))


def test_template_errors_name_the_file(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("def build(:\n")
    with pytest.raises(TemplateError, match=r"bad.py: syntax error at line 1"):
        build_template(bad)
    boom = tmp_path / "boom.py"
    boom.write_text(
        "from dataclasses import dataclass\nfrom hyperstat.cad_plugin.params import param\n"
        "@dataclass\nclass Parameters:\n    L: float = param(1.0, 'mm', 'a length in mm')\n"
        "def build(**kw):\n    raise ValueError('no luck')\n"
    )
    with pytest.raises(TemplateError, match=r"boom.py: build\(\) failed \(line 7\): ValueError: no luck"):
        build_template(boom)
    with pytest.raises(TemplateError, match=r"unknown parameter 'Q'; valid parameters: L \[mm\]"):
        build_template(boom, ["Q=1"])
