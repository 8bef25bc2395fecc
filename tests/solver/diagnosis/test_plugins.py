"""A broken ``hyperstat.effects`` plug-in: one sentence naming it and the stage, exit code 2, never a traceback.

Units: lengths in mm, angles in rad.  Each plug-in is a real package installed in a
temporary directory (a module and its ``*.dist-info/entry_points.txt``), found through
``importlib.metadata`` as a user's would be; each breaks at one stage: loading, building
the effect, its columns, the nonlinear fit.
"""

from __future__ import annotations

import pytest

from tests.solver.diagnosis import independent_generator as gen

PLUGIN = '''
import numpy as np
from hyperstat.solver.diagnosis.effects import Effect

{top}


class Periodic(Effect):
    """Angle error of every revolute at three cycles per revolution (rad) (broken at one stage in test_plugins)."""

    def __init__(self, mechanism, analysis=None, data=None):
        {init}
        self.axes = [a for a, i in enumerate(mechanism.actuated) if mechanism.joints[i].type == "R"]
        names = [f"p3_{{a}}_{{t}}" for a in self.axes for t in ("sin", "cos")]
        super().__init__(names, ["rad"] * len(names), [1e-4] * len(names), plausible=5e-4)

    def actuator_correction(self, model, theta, data):
        {columns}
        k, na = data.q.shape
        dt = np.zeros((k, na, len(theta)))
        for e, a in enumerate(self.axes):
            dt[:, a, 2 * e] = np.sin(3 * data.q[:, a])
            dt[:, a, 2 * e + 1] = np.cos(3 * data.q[:, a])
        return np.einsum("kae,e->ka", dt, theta), dt
'''

STAGES = {
    "load": dict(top="raise ImportError('numpy too old for this plug-in')", init="pass", columns="pass"),
    "build": dict(top="", init="raise KeyError('gear_ratio')", columns="pass"),
    "columns": dict(top="", init="pass", columns="raise ZeroDivisionError('no lead')"),
    "fit": dict(top="", init="pass", columns="if np.any(theta): raise RuntimeError('diverged')"),
}


def install_plugin(tmp_path, monkeypatch, module: str, name: str, text: str) -> str:
    """Install module ``text`` as a package declaring the effect ``name`` (class ``Periodic``) in ``hyperstat.effects``."""
    (tmp_path / f"{module}.py").write_text(text)
    info = tmp_path / f"{module}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {module}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[hyperstat.effects]\n{name} = {module}:Periodic\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    return name


@pytest.mark.parametrize("stage", list(STAGES))
def test_a_broken_plugin_is_named_with_its_stage(tmp_path, monkeypatch, capsys, stage):
    from hyperstat.cad_plugin.cli import main

    name = install_plugin(tmp_path, monkeypatch, f"broken_{stage}", f"broken-{stage}",
                          PLUGIN.format(**STAGES[stage]))
    id_text, val_text, _ = gen.campaign(gen.ARM_6R, "angle-harmonic-3", 0)
    (tmp_path / "d.csv").write_text(id_text)
    (tmp_path / "v.csv").write_text(val_text)
    out = tmp_path / "diag.json"
    effects = [] if stage == "load" else ["--effects", f"{name},compliance"]
    code = main(["diagnose", str(gen.ARM_6R), str(tmp_path / "d.csv"), "--validation", str(tmp_path / "v.csv"),
                 "--json", str(out), "--quiet", *effects])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert f"'{name}'" in err
    words = {"load": "cannot be loaded", "build": "failed when built", "columns": "at the columns stage",
             "fit": "at the fit stage"}[stage]
    assert words in err, err
