"""identify's fit quality: "inputs wrong" (sigma in the hundreds) apart from "the rigid model misses an effect".

Units: lengths in mm, angles in rad.  Campaigns of the independent generator (6R arm,
noise 5 um + 5 um/m): with geometric errors only (sigma about 1), with joint compliance
the model lacks (sigma a few), and with joint 2's column of sign flipped (a wrong joint
map: residuals of a link's size).
"""

from __future__ import annotations

import json
import warnings

import pytest

from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.calibration.identify import fit_quality, identify
from hyperstat.solver.calibration.measurements import parse_measurements
from hyperstat.solver.diagnosis.diagnose import diagnose
from hyperstat.solver.kinematics.modelfile import load_model

from tests.solver.diagnosis import independent_generator as gen


@pytest.fixture(scope="module")
def arm():
    mech = load_model(gen.ARM_6R)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return mech, analyze(mech, n_configurations=24, seed=0)


def _flip_joint_2(text: str) -> str:
    lines = text.splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("pose,"))
    col = lines[head].split(",").index("q2[rad]")
    for i in range(head + 1, len(lines)):
        cells = lines[i].split(",")
        cells[col] = repr(-float(cells[col]))
        lines[i] = ",".join(cells)
    return "\n".join(lines) + "\n"


def _identify(arm, case: str, flip: bool = False):
    mech, analysis = arm
    id_text, val_text, _ = gen.campaign(gen.ARM_6R, case, 0)
    if flip:
        id_text, val_text = _flip_joint_2(id_text), _flip_joint_2(val_text)
    data = parse_measurements(id_text, mech, "id.csv")
    val = parse_measurements(val_text, mech, "val.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return identify(mech, analysis, data, val), data, val


def test_a_rigid_model_that_fits_is_ok(arm):
    res, _, _ = _identify(arm, "none")
    assert res.fit_quality == "ok" and res.sigma < 1.5
    assert not [w for w in res.warnings if "ABSURD" in w or "MISSES" in w]
    assert res.to_dict()["fit_quality"] == "ok"


def test_a_missing_effect_is_not_called_wrong_inputs(arm):
    """Joint compliance the model lacks: sigma a few times the noise; the words send the user to diagnose."""
    res, _, _ = _identify(arm, "compliance")
    assert 3.0 < res.sigma < 100.0 and res.fit_quality == "model misses an effect"
    words = [w for w in res.warnings if w.startswith("MODEL MISSES AN EFFECT")]
    assert len(words) == 1 and "hyperstat diagnose" in words[0] and "held-out error" in words[0]
    assert not [w for w in res.warnings if w.startswith("ABSURD FIT")]


def test_a_wrong_joint_sign_is_wrong_inputs(arm):
    """Joint 2's readings with the wrong sign: residuals of a link's size, sigma in the thousands."""
    res, data, val = _identify(arm, "none", flip=True)
    assert res.sigma > 100.0 and res.fit_quality == "inputs wrong"
    assert any(w.startswith("ABSURD FIT") and "joint map" in w for w in res.warnings)
    # the diagnosis then tries no effect: the inputs, not a missing effect, make this gap
    mech, analysis = arm
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = diagnose(mech, analysis, data, val)
    assert d.outcome == "inputs wrong" and d.named_effects == [] and d.ranking == []
    assert "joint map" in d.verdict["evidence"]
    doc = d.to_dict()
    assert doc["outcome"] == "inputs wrong" and json.dumps(doc)  # JSON-ready


def test_fit_quality_thresholds():
    """The classes follow sigma and the residual size against the machine's size (closed thresholds)."""
    assert fit_quality(2.9, 0.05, 1000.0, True) == "ok"
    assert fit_quality(3.1, 0.05, 1000.0, True) == "model misses an effect"
    assert fit_quality(99.0, 5.0, 1000.0, True) == "model misses an effect"
    assert fit_quality(100.0, 5.0, 1000.0, True) == "inputs wrong"
    assert fit_quality(5.0, 10.1, 1000.0, True) == "inputs wrong"  # residuals beyond 1 % of the machine's size
    assert fit_quality(1e6, 5.0, 1000.0, False) == "ok"  # no stated noise: only the size test applies
