"""Effects tried joint by joint, combinations, and targets that disagree (issue 40), on a KUKA-like 6R.

Units: lengths in mm, angles in rad.  The campaigns come from ``kuka_like.py`` (modified DH in
degrees, spherical wrist, three reflectors per pose, its own forward kinematics, link masses,
gravity torques and effects; it imports nothing from hyperstat): the expected answers are the
generator's truth, the effect it put in, on which joint and at which order.  60 poses identify,
24 are held out.  Before issue 40 each of these campaigns was answered otherwise (noted per test:
measured on the commit before the change with the same seeds).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.calibration.measurements import parse_measurements
from hyperstat.solver.diagnosis.diagnose import diagnose
from hyperstat.solver.kinematics.robot_import import import_robot

from tests.solver.diagnosis import kuka_like as kl


@pytest.fixture(scope="module")
def kuka(tmp_path_factory):
    """The KUKA-like arm imported from its modified-DH table (degrees), its link masses declared as a user would."""
    path = tmp_path_factory.mktemp("kuka") / "kuka_like.dh.yaml"
    path.write_text(kl.MDH_YAML)
    mech = import_robot(path)
    mech.metadata["masses"] = kl.KukaLike(0).declared_masses(mech.home[mech.actuated])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return mech, analyze(mech, n_configurations=24, seed=0)


def _diagnose(kuka, case: str, seed: int, per_target: bool = False, candidates=None, **options):
    mech, analysis = kuka
    id_text, val_text, truth, _ = kl.campaign(case, seed, **options)
    data = parse_measurements(id_text, mech, "id.csv")
    val = parse_measurements(val_text, mech, "val.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return diagnose(mech, analysis, data, val, per_target=per_target, candidates=candidates), truth


def test_the_generator_agrees_with_the_imported_model(kuka):
    """Two forward models of the same modified-DH table agree at the nominal geometry (1e-9 mm)."""
    from hyperstat.solver.kinematics.closure import Kinematics

    mech, _ = kuka
    kin = Kinematics(mech)
    robot = kl.KukaLike(0)
    q = robot.poses(6)
    st = kin.evaluate(kin.solve(q).q, None)
    mine = np.array([robot.frames(qq, true=False)[-1] for qq in q])
    np.testing.assert_allclose(mine, st.output_pose, atol=1e-9)


def test_an_eccentric_on_one_joint_of_six_is_named_on_that_joint(kuka):
    """A 1/rev error of joint 1 (3.5e-5 rad): named with its two parameters on joint 1, not twelve on all six joints
    (before: "unexplained" on this seed; the ten noise-level terms of joints 2-6 cost more than joint 1's pair
    gained)."""
    d, truth = _diagnose(kuka, "harmonic", 0, joint=0, amplitude=3.5e-5)
    assert d.outcome == "explained" and d.named_effects == ["angle-harmonic-1"]
    assert d.effect_joints == {"angle-harmonic-1": [truth["joint"]]}
    params = {p["name"]: p["estimate"] for p in d.effect_parameters}
    assert set(params) == {"harmonic1_1_sin", "harmonic1_1_cos"}
    assert np.hypot(*params.values()) == pytest.approx(truth["amplitude"], rel=0.35)
    assert d.to_dict()["effect_joints"] == {"angle-harmonic-1": ["1"]}


def test_an_order_the_spectrum_refuses_is_replaced_by_the_order_at_its_peak(kuka):
    """The candidates named are 2/rev and compliance; the truth is a 1/rev error of joint 1.  The 2/rev candidate fits
    best, the spectrum of joint 1 refuses it (it peaks at 1), and the order at the peak is tried in its place and named
    (before: "unexplained", the 1/rev never tried)."""
    d, truth = _diagnose(kuka, "harmonic", 0, joint=0, amplitude=6e-5, candidates=("angle-harmonic-2", "compliance"))
    refused = [r for r in d.rejected if r["effect"] == "angle-harmonic-2" and r["stage"] == "spectrum"]
    assert refused and "does not agree" in refused[0]["reason"] and refused[0]["joint"] == "1"
    assert d.outcome == "explained" and d.named_effects == ["angle-harmonic-1"]
    assert d.effect_joints == {"angle-harmonic-1": ["1"]}
    assert d.selection_steps[0]["added"] == "angle-harmonic-1@1"


def test_a_scale_error_of_joint_3_is_named_on_joint_3(kuka):
    """A gear-ratio error of joint 3 (8e-5): one parameter on joint 3 (before: the scale error of all six joints)."""
    d, truth = _diagnose(kuka, "scale", 0, scale_joint=2, scale=8e-5)
    assert d.outcome == "explained" and d.named_effects == ["angle-scale"]
    assert d.effect_joints == {"angle-scale": ["3"]}
    (p,) = d.effect_parameters
    assert p["name"] == "angle_scale_3" and p["estimate"] == pytest.approx(truth["scale"], rel=0.3)


def test_compliance_and_an_eccentric_are_both_named(kuka):
    """Joint compliance (gravity, payloads 0/60/150 kg) with a 1/rev error of joint 1: both named, the eccentric on
    its joint, compliance with the gravity family its poses cannot separate from it (before: "partly explained by
    compliance", the eccentric refused because the 12-parameter harmonic fitted compliance's signature on joint 2
    beyond its prior)."""
    d, truth = _diagnose(kuka, "compliance+harmonic", 0, joint=0, compliance_factor=0.1)
    assert d.outcome == "explained" and set(d.named_effects) == {"compliance", "angle-harmonic-1"}
    assert d.effect_joints == {"angle-harmonic-1": ["1"]}
    sets = {s["effect"]: s for s in d.equivalence_sets}
    assert "compliance" in sets["compliance"]["members"]
    assert len(sets["compliance"]["members"]) == 1 or sets["compliance"]["separating_measurement"]
    assert d.validation_after["rms"] < 1.15 * d.rigid.noise_rms


def test_a_two_stage_gear_is_named_at_its_order(kuka):
    """An error at 1.5 cycles per revolution of joint 1 (a gear stage): named ``angle-harmonic-1.5`` (before: 1.55,
    the refined spectrum peak)."""
    d, truth = _diagnose(kuka, "harmonic", 2, joint=0, order=1.5)
    assert d.outcome == "explained" and d.named_effects == ["angle-harmonic-1.5"]
    assert d.effect_joints == {"angle-harmonic-1.5": ["1"]} and d.confidence == "high"
    assert not any(r["effect"] == "angle-harmonic-1.5" for r in d.rejected)


def test_a_gear_stage_seen_over_less_than_one_period_is_named_when_the_data_establish_it(kuka):
    """The 1.5/rev stage of joint 1 (9e-5 rad) with joint 1 within +-100 deg (2.9 rad: less than one period of 1.5/rev,
    resolution 2.2 cycles per revolution).  The spectrum peaks at 1.5, where 1 explains 13 less and 2 explains 49
    less: the order is established by the data although the Rayleigh limit would let them alias, and it beats a smooth
    trend of the joint.  Before: the order was never tried below the resolution, 1 and 2 were refused by the
    spectrum, and the answer was "unexplained"."""
    d, truth = _diagnose(kuka, "harmonic", 1, joint=0, order=1.5, amplitude=9e-5, narrow={0: (-100.0, 100.0)})
    assert d.spectrum_peaks["1"]["resolution_cycles_per_rev"] > 1.5
    assert d.outcome == "explained" and d.named_effects == ["angle-harmonic-1.5"]
    assert d.effect_joints == {"angle-harmonic-1.5": ["1"]}
    params = {p["name"]: p["estimate"] for p in d.effect_parameters}
    assert np.hypot(*params.values()) == pytest.approx(truth["amplitude"], rel=0.35)


def test_a_reflector_that_tells_another_story_lowers_the_confidence(kuka):
    """One reflector's nest slides with the wrist (the others are right): alone it is explained by a periodic error of
    joint 6, which the whole file does not find.  The answer says the targets disagree and its confidence is low
    (before: the check reported that they agree on this seed)."""
    d, truth = _diagnose(kuka, "loose-reflector", 1, per_target=True, loose=0.05)
    alone = next(t for t in d.per_target if t["target"] == truth["reflector"])
    assert alone["named_effects"] and alone["effect_joints"] == {alone["named_effects"][0]: ["6"]}
    assert d.targets_agree is False and d.confidence == "low" and d.to_dict()["confidence"] == "low"
    assert f"target {truth['reflector']}" in d.targets_evidence
    assert "the targets disagree" in d.verdict["evidence"] and "confidence low" in d.verdict["evidence"]


def test_the_check_per_target_compares_orders():
    """The issue's case: the whole file explained by a 1/rev error of joint 1 while each reflector alone refuses that
    order because its own spectrum peaks at 1.5: another story.  A reflector that cannot establish the order with its
    third of the data and names a scale error of that joint tells less, not another story."""
    from hyperstat.solver.diagnosis.targets import targets_agree

    whole = {"outcome": "explained", "named_effects": ["angle-harmonic-1"], "effect_joints": {"angle-harmonic-1": ["1"]},
             "equivalence_sets": [{"members": ["angle-harmonic-1"]}]}
    peak = ("the spectrum of joint 1's error peaks at 1.5 cycles per revolution (40 % of the residual variance), "
            "where 1 explains 25 less (chi-square): the spectrum does not agree with its order")
    refusing = [{"target": f"SMR{i}", "outcome": "unexplained", "named_effects": [], "effect_joints": {},
                 "refused": [{"effect": "angle-harmonic-1", "joint": "1", "reason": peak, "alias": None}]}
                for i in (1, 2, 3)]
    ok, words = targets_agree(whole, refusing)
    assert not ok and "SMR1's own spectrum refuses angle-harmonic-1" in words and "1.5 cycles" in words
    weaker = [{"target": "SMR1", "outcome": "explained", "named_effects": ["angle-scale"],
               "effect_joints": {"angle-scale": ["1"]},
               "refused": [{"effect": "angle-harmonic-1", "joint": "1", "reason": "not established", "alias": 2.0}]}]
    ok, words = targets_agree(whole, weaker)
    assert ok and "do not establish the order" in words
    elsewhere = [{"target": "SMR2", "outcome": "explained", "named_effects": ["angle-harmonic-1"],
                  "effect_joints": {"angle-harmonic-1": ["4"]}, "refused": []}]
    ok, words = targets_agree(whole, elsewhere)
    assert not ok and "on joint(s) 4" in words


@pytest.fixture(scope="module")
def kuka_wide_shoulder(tmp_path_factory):
    """The KUKA-like arm with joint 2 allowed over -180..15 deg (the generator then moves it over about 2.9 rad)."""
    path = tmp_path_factory.mktemp("kuka_wide") / "kuka_like.dh.yaml"
    path.write_text(kl.MDH_YAML.replace("min: -140.0, max: -5.0", "min: -180.0, max: 15.0"))
    mech = import_robot(path)
    mech.metadata["masses"] = kl.KukaLike(0).declared_masses(mech.home[mech.actuated])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return mech, analyze(mech, n_configurations=24, seed=0)


@pytest.mark.parametrize("seed", [3, 8])
def test_a_periodic_error_whose_order_the_range_cannot_establish_is_named_as_a_set(kuka_wide_shoulder, seed):
    """A weak 2/rev error of joint 2 (1.5e-5 rad) with joint 2 over about 2.9 rad: orders closer than 2 pi / 2.9 = 2.2
    cycles per revolution alias, and on these seeds a neighbouring order fits the error as well as 2 (the seventh blind
    run's miss).  The answer names a periodic error of joint 2 as a set holding the truth, with the measurement that
    separates its members (joint 2 over a longer range) and a low confidence.  Before: "unexplained" with high
    confidence, both orders refused as "not established"."""
    d, truth = _diagnose(kuka_wide_shoulder, "harmonic", seed, joint=1, order=2.0, amplitude=1.5e-5,
                         narrow={1: (-180.0, 15.0)})
    peak = d.spectrum_peaks[truth["joint"]]
    assert peak["resolution_cycles_per_rev"] == pytest.approx(2 * np.pi / peak["range_rad"]) and \
        peak["resolution_cycles_per_rev"] > 2.0  # over this range orders 1 apart alias (the Rayleigh limit)
    assert d.outcome in ("explained", "partly explained") and len(d.named_effects) == 1
    named = d.named_effects[0]
    assert named.startswith("angle-harmonic-") and d.effect_joints == {named: [truth["joint"]]}
    members = next(s["members"] for s in d.equivalence_sets if s["effect"] == named)
    assert "angle-harmonic-2" in members and len(members) >= 2  # the truth, among the orders that alias
    sep = next(s["separating_measurement"] for s in d.equivalence_sets if s["effect"] == named)
    span = float(sep.split("poses over more than ")[1].split(" rad")[0])
    assert f"of joint {truth['joint']}" in sep and span > peak["range_rad"]
    assert d.confidence == "low" and d.to_dict()["confidence"] == "low" and d.ambiguous
    assert "confidence low" in d.verdict["evidence"] and d.verdict["order_not_established"][0]["joint"] == "2"


@pytest.mark.parametrize("seed", [7, 9])
def test_a_weak_periodic_error_the_spectrum_locates_is_named_with_low_confidence(kuka_wide_shoulder, seed):
    """The same 2/rev error of joint 2 (1.5e-5 rad over about 2.8 rad) on seeds where the order is established or one
    of two: the candidate on joint 2 alone (2 parameters) lowers the BIC by 20 to 35 but the cross-validated RMS by 3 to
    4 %, under the selection's 5 % bar, and nothing else passes.  Joint 2's spectrum has a significant peak (the
    structure tests), so the candidate is taken at the lower bar for an effect they locate, named on joint 2 with the
    truth in its set, and the answer says it is below the 5 % and lowers its confidence.  Before: "unexplained" with
    high confidence, although ``where`` named joint 2's error at 2 cycles per revolution."""
    d, truth = _diagnose(kuka_wide_shoulder, "harmonic", seed, joint=1, order=2.0, amplitude=1.5e-5,
                         narrow={1: (-180.0, 15.0)})
    assert d.spectrum_peaks[truth["joint"]]["p_value"] < d.gap_test["structure"]["threshold"]  # located
    assert d.outcome in ("explained", "partly explained") and len(d.named_effects) == 1
    named = d.named_effects[0]
    members = next(s["members"] for s in d.equivalence_sets if s["effect"] == named)
    assert f"angle-harmonic-{truth['order']:g}" in members and d.effect_joints == {named: [truth["joint"]]}
    (weak,) = d.verdict["below_guard"]
    assert weak["effect"] == named and weak["joint"] == truth["joint"]
    assert 0.02 <= weak["cv_drop"] < 0.05 and weak["delta_bic"] < -10.0  # the 2 % bar, under the 5 %; the BIC's 10
    assert weak["settling_measurement"].startswith(f"poses over more than {2 * np.pi:.2g} rad of joint 2")
    assert d.confidence == "low" and "under the 5 % the selection asks" in d.verdict["evidence"]
