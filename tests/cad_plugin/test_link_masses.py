"""Link masses and centres of mass from the template's CadQuery solids (volume x density) against closed forms.

Units: lengths in mm, densities in kg/m^3, masses in kg, torques in N mm.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hyperstat.cad_plugin import build_template
from hyperstat.solver import TemplateError

ARM = '''"""Two-link arm about horizontal axes (test template).  Units: lengths in mm."""
from dataclasses import dataclass

from hyperstat.cad_plugin.params import make_parameters, param
from hyperstat.cad_plugin.skeleton import Skeleton


@dataclass
class Parameters:
    """Dimensions (mm)."""

    upper: float = param(600.0, "mm", "shoulder to elbow", minimum=0.0, exclusive_minimum=True)
    fore: float = param(400.0, "mm", "elbow to tool flange", minimum=0.0, exclusive_minimum=True)


def build(**overrides):
    p = make_parameters(Parameters, overrides)
    sk = Skeleton("arm2", parameters=p)
    sk.revolute("1", (0, 0, 0), (0, 1, 0), role="actuated", range=(-2.0, 2.0))
    sk.revolute("2", (p.upper, 0, 0), (0, 1, 0), role="actuated", range=(-2.0, 2.0))
    sk.fixed("3", (p.upper + p.fore, 0, 0), (0, 1, 0), (1, 0, 0))
    sk.chain("arm", "R0", "T", ["1", "2", "3"])
    sk.output = "T"
    sk.material(MATERIAL)
    # the upper arm drawn as two collinear bars (fused into one cylinder), the forearm as one
    sk.link("upper_a", [(0, 0, 0), (0.25 * p.upper, 0, 0)], 30.0, body="1")
    sk.link("upper_b", [(0.25 * p.upper, 0, 0), "2"], 30.0, body="1")
    sk.link("fore", ["2", "3"], 20.0, body="2")
    sk.link("drawing_only", [(0, 0, -50), (0, 0, 0)], 10.0)  # no body: drawn, weightless
    DECLARED
    return sk
'''


def _template(tmp_path, material='"aluminium"', declared=""):
    path = tmp_path / "arm2.py"
    path.write_text(ARM.replace("MATERIAL", material).replace("DECLARED", declared))
    return path


def test_masses_are_density_times_volume_at_the_centroid(tmp_path):
    pytest.importorskip("cadquery")
    mech = build_template(_template(tmp_path)).mechanism()
    masses = mech.metadata["masses"]
    rho = 2700.0e-9  # kg/mm^3, aluminium
    # cylinders: m = rho pi r^2 L, centre of mass at the middle of the axis
    assert masses["1"]["mass"] == pytest.approx(rho * math.pi * 30.0**2 * 600.0, rel=1e-6)
    assert masses["2"]["mass"] == pytest.approx(rho * math.pi * 20.0**2 * 400.0, rel=1e-6)
    np.testing.assert_allclose(masses["1"]["com"], [300.0, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(masses["2"]["com"], [800.0, 0.0, 0.0], atol=1e-6)
    assert "aluminium" in masses["1"]["source"]
    assert set(masses) == {"1", "2"}  # the link without a body carries no mass


def test_computed_masses_reach_the_gravity_loads_of_the_solver(tmp_path):
    """Through the model file (the solver reads numbers, not CAD): shoulder torque at home = g sum m_b x_b."""
    pytest.importorskip("cadquery")
    from hyperstat.solver.diagnosis.effects import gravity_loads
    from hyperstat.solver.kinematics.closure import Kinematics
    from hyperstat.solver.kinematics.modelfile import load_model, save_model

    mech = build_template(_template(tmp_path)).mechanism()
    save_model(mech, tmp_path / "arm2.skel.json")
    again = load_model(tmp_path / "arm2.skel.json")
    m = again.metadata["masses"]
    tau = gravity_loads(again, Kinematics(again), np.zeros((1, 2)), np.zeros(1))[0]
    g = 9.81
    # axis +y, arm along +x, gravity -z: tau = y . ((x, 0, 0) x (0, 0, -m g)) = m g x
    assert tau[0] == pytest.approx(g * (m["1"]["mass"] * 300.0 + m["2"]["mass"] * 800.0), rel=1e-9)
    assert tau[1] == pytest.approx(g * m["2"]["mass"] * (800.0 - 600.0), rel=1e-9)


def test_declared_masses_override_the_computed_ones(tmp_path):
    pytest.importorskip("cadquery")
    declared = 'sk.metadata["masses"] = {"2": {"mass": 3.5, "com": [820.0, 0.0, 5.0]}}'
    masses = build_template(_template(tmp_path, declared=declared)).mechanism().metadata["masses"]
    assert masses["2"] == {"mass": 3.5, "com": [820.0, 0.0, 5.0]}
    assert masses["1"]["mass"] == pytest.approx(2700.0e-9 * math.pi * 30.0**2 * 600.0, rel=1e-6)


def test_an_unknown_material_is_refused_with_its_name(tmp_path):
    with pytest.raises(TemplateError, match="material 'unobtainium'"):
        build_template(_template(tmp_path, material='"unobtainium"'))
