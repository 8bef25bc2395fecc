"""What the diagnosis of a parallel machine costs, and what it must not recompute (issue 40: the hexapod).

Units: lengths in mm, angles in rad.  The campaigns come from the project's generators
(``independent_generator.py``, ``pkm_generator.py``: their own parsers, kinematics and effects; they import
nothing from hyperstat).  No timing is asserted: the tests check that work whose result the diagnosis never
reads is not done, and that the answer is the same without it; the times are in ``docs/diagnosis.md``
("Speed") and ``benchmarks/diagnose_hexapod.py``.
"""

from __future__ import annotations

import warnings

import numpy as np

from hyperstat.solver.analysis.stationarity import analyze
from tests.solver.diagnosis.pkm_models import pkm_model
from hyperstat.solver.calibration.identify import identify
from hyperstat.solver.calibration.measurements import parse_measurements
from hyperstat.solver.diagnosis.diagnose import diagnose
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.modelfile import load_model

from tests.solver.diagnosis import independent_generator as gen


def test_the_diagnosis_does_not_refit_the_rigid_model_to_name_outliers():
    """One identification point off by 0.4 mm (80x the noise): ``identify`` flags it and, to say which points are
    outliers, fits the whole model again without it (``without_outliers``).  The diagnosis reads neither the flags nor
    that second fit (its answer comes from the fit itself), so it must not pay for it: on the hexapod that second fit
    was half of the rigid fit's CPU time (70 of 124 s at 107 poses).  The rigid fit the diagnosis uses is the same
    fit, to the last digit."""
    mech = load_model(gen.SCARA)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        analysis = analyze(mech, n_configurations=24, seed=0)
        kin = Kinematics(mech)
        id_text, val_text, _ = gen.campaign(gen.SCARA, "none", 0)
        data = parse_measurements(id_text, mech, "id.csv")
        val = parse_measurements(val_text, mech, "val.csv")
        data.position[5, 0] += 0.4  # mm: a gross error on one point
        full = identify(mech, analysis, data, val, kinematics=kin)
        d = diagnose(mech, analysis, data, val, kinematics=kin, per_target=False)
    assert full.without_outliers is not None  # the calibration's own check names the outlier (a second fit)
    assert d.rigid.without_outliers is None  # the diagnosis skipped that second fit ...
    np.testing.assert_array_equal(d.rigid.theta, full.theta)  # ... and fitted the same model
    assert d.rigid.sigma == full.sigma and d.rigid.rank == full.rank


# ------------------------------------------------------------ a ball screw's error at another order than once per turn
_pkm_model = pkm_model  # the machine, its analysis and kinematics, once per test process


def _pkm_diagnose(arm: str, seed: int, lead: float | None, n_id: int = 60, n_val: int = 20, size: float = 1.0):
    from tests.solver.diagnosis import pkm_generator as pkm

    mech, analysis, kin = _pkm_model(arm)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        id_text, val_text, truth = pkm.campaign(pkm.MODELS[arm], "screw-periodic", seed, n_id=n_id, n_val=n_val,
                                                lead=lead, size=size)
        data = parse_measurements(id_text, mech, "id.csv")
        val = parse_measurements(val_text, mech, "val.csv")
        return diagnose(mech, analysis, data, val, kinematics=kin, per_target=False), truth


def test_a_screw_error_at_twice_per_turn_is_named_at_its_order():
    """The Tripteor's leg 42 with a ball-screw error of period 5 mm, half the 10 mm lead (two cycles per turn of the
    screw, 0.0076 mm; the PKM generator's ``lead=5``), 60 + 20 poses.  The screws' spectrum of the structure tests
    has 40 periods evenly spaced from 2 to 80 mm over the leg's 240 mm of travel: 5 mm falls between 4 and 6 mm,
    where 48 cycles over the travel leave nothing of the error, and only the lead (10 mm) was tried.  The order at the
    peak of a spectrum fine enough for the travel (a quarter of 1 / travel) is tried, named as a gear's order is (the
    simplest within a chi-square of 10): two cycles per turn, on leg 42, the order stated.  Before: "no significant
    gap"."""
    d, truth = _pkm_diagnose("tripteor_x7", 1, 5.0)
    assert d.outcome == "explained" and d.named_effects == ["screw-periodic"]
    assert d.effect_joints["screw-periodic"] == truth["joints"] == ["42"]
    declared = "screw_lead" in _pkm_model("tripteor_x7")[0].metadata  # the template declares none: 10 mm assumed
    assert d.verdict["screw_order"] == {"cycles_per_turn": 2.0, "period_mm": 5.0, "lead_mm": 10.0,
                                        "lead_declared": declared}
    assert "2 cycles per turn of the screw" in d.verdict["evidence"]
    assert ("assumed: the model declares no metadata.screw_lead" in d.verdict["evidence"]) is not declared
    amp = np.hypot(*[p["estimate"] for p in d.effect_parameters])
    assert abs(amp - truth["value"]) < 0.3 * truth["value"]  # mm


def test_a_screw_error_below_the_five_percent_bar_is_named_with_low_confidence():
    """The same campaign at 0.8 of the error (0.0061 mm at twice per turn of leg 42): the candidate on leg 42 lowers the
    BIC by about 20 but the cross-validated RMS by less than the selection's 5 %, while the structure tests' signature
    test of the screw's error is significant.  It is taken at the lower bar for an effect the structure tests locate,
    on leg 42 at 2 cycles per turn, with a low confidence and words saying it is under the 5 %.  Before: "unexplained"
    with high confidence, although ``where`` named the signature of screw-periodic (the hexapod's 2/turn error of leg
    32 at 0.0087 mm over 107 + 30 poses was the same miss: docs/diagnosis.md)."""
    d, truth = _pkm_diagnose("tripteor_x7", 1, 5.0, size=0.8)
    assert d.outcome == "explained" and d.named_effects == ["screw-periodic"]
    assert d.effect_joints["screw-periodic"] == truth["joints"]
    lead = d.verdict["screw_order"]["lead_mm"]
    assert d.verdict["screw_order"]["cycles_per_turn"] == lead / truth["lead"]
    (weak,) = d.verdict["below_guard"]
    assert weak["joint"] == truth["joints"][0] and 0.02 <= weak["cv_drop"] < 0.05 and weak["delta_bic"] < -10.0
    assert d.confidence == "low" and "under the 5 % the selection asks" in d.verdict["evidence"]


def test_a_screw_error_once_per_turn_is_still_named_at_the_lead():
    """The same campaign's error at the 10 mm lead (once per turn; seed 0, leg 41): named at 1 cycle per turn, the
    lead's parameters (no period in their names)."""
    d, truth = _pkm_diagnose("tripteor_x7", 0, None)
    assert d.outcome == "explained" and d.named_effects == ["screw-periodic"]
    assert d.effect_joints["screw-periodic"] == truth["joints"]
    assert d.verdict["screw_order"]["cycles_per_turn"] == 1.0
    assert [p["name"] for p in d.effect_parameters] == [f"periodic_{truth['joints'][0]}_sin",
                                                        f"periodic_{truth['joints'][0]}_cos"]


def test_where_states_a_screw_period_in_turns_of_the_screw():
    """An unexplained periodic error of a screw is stated in turns of the screw too (lead / period): 5 mm on a 10 mm
    lead is 2 cycles per turn (the hexapod's leg 32 at 0.0087 mm over 107 poses, below the selection's guard)."""
    from hyperstat.solver.diagnosis.where import describe_where

    test = {"family": "joint error", "joint": "32", "variable": "q32", "kind": "periodic", "period_mm": 5.0,
            "lead_mm": 10.0, "share": 0.05, "F": 14.0, "p_value": 1e-6, "direction": [0.73, -0.66, -0.18]}
    words = describe_where(test)
    assert "period of 5.0 mm along its travel (2 cycles per turn of a screw of 10 mm lead)" in words
    assert "cycles per turn" not in describe_where({**test, "lead_mm": None})
    assumed = describe_where({**test, "lead_declared": False})  # a lead the model does not declare is said assumed
    assert "(2 cycles per turn of a screw of 10 mm lead, assumed: the model declares none)" in assumed
