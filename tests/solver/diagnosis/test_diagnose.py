"""Diagnosis on data whose effect was withheld from the fitted model (small version of the suite).

Units: lengths in mm.  The expected answers come from the simulation: the effect the
virtual machine contains (or none), and the noise floor of its tracker.
"""

from __future__ import annotations

import json
import warnings

import pytest

from hyperstat.cad_plugin.cli import main
from hyperstat.solver.diagnosis.validation_suite import run_case, summarize
from hyperstat.solver.kinematics.closure import Kinematics

from tests.conftest import TEMPLATES


@pytest.fixture(scope="module")
def tripteor_kin(tripteor):
    return Kinematics(tripteor)


@pytest.mark.parametrize("case", [(), ("thermal",), ("backlash",), ("tracker-drift",)])
def test_tripteor_withheld_effect(tripteor, tripteor_analysis, tripteor_kin, case):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = run_case(tripteor, tripteor_analysis, tripteor_kin, case, seed=0, violated=None)
    if not case:
        assert not r.gap_significant  # no false alarm
        return
    assert r.gap_significant and r.ranked_first == case[0] and r.selected[0] == case[0]
    assert r.validation_after <= 1.3 * r.noise_rms < r.validation_before
    assert r.magnitude_found == pytest.approx(r.magnitude_true, rel=0.3)


@pytest.mark.parametrize("seed", [3])
def test_violated_forced_defect_is_named(tripteor, tripteor_analysis, tripteor_kin, seed):
    # seed 3: dc13 (a length) explains the gap as well as dK13 by cross-validation, with a
    # violation 18x its realistic magnitude against 7x: the tie is reported and broken by size.
    # (Seed 1, the same assertions on a campaign without the tie, took 20-25 s of CPU in the
    # nonlinear fit's assembly continuation; it is one of the 3 violated-constraint seeds
    # `hyperstat validate-diagnosis` runs, see docs/diagnosis.md.)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = run_case(tripteor, tripteor_analysis, tripteor_kin, ("violated-constraint",), seed=seed, violated="dK13")
    assert r.ranked_first == "violated-constraint" and r.violated_defect == "dK13"
    assert "dK13" not in r.violated_ambiguous_with
    assert r.validation_after <= 1.3 * r.noise_rms
    assert r.magnitude_found == pytest.approx(r.magnitude_true, rel=0.2)


def test_scara_suite_rates(scara, scara_analysis):
    kin = Kinematics(scara)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # one seed per case (a second seed repeated the same statements at twice the time; the rates over
        # 3 seeds are validate-diagnosis's, docs/diagnosis.md)
        results = [run_case(scara, scara_analysis, kin, case, seed, None)
                   for case in [(), ("thermal",), ("backlash",), ("thermal", "backlash")] for seed in (0,)]
    s = summarize(results)
    assert s["false_alarm"] == 0.0
    assert s["right_effect_first"] == 1.0 and s["after_within_1.3x_noise"] == 1.0
    assert s["pairs_both_found"] == 1.0


def test_diagnose_command_json_contract(tmp_path, capsys):
    src = str(TEMPLATES / "scara.py")
    data = tmp_path / "d.csv"
    assert main(["simulate", src, "--poses", "80", "--validation", "30", "--effect", "backlash", "--out", str(data),
                 "--quiet"]) == 0
    out = tmp_path / "diag.json"
    plots = tmp_path / "plots"
    assert main(["diagnose", src, str(data), "--validation", str(tmp_path / "d.validation.csv"), "--json", str(out),
                 "--plots", str(plots)]) == 0
    doc = json.loads(out.read_text())
    assert doc["gap_significant"] is True
    assert doc["selected"][0] == "backlash"
    # the contract of issue 28 (docs/diagnosis.md, "The JSON contract")
    from hyperstat.solver.diagnosis.diagnose import OUTCOMES

    assert doc["outcome"] in OUTCOMES and doc["named_effects"] == doc["selected"][:len(doc["named_effects"])]
    assert isinstance(doc["ambiguous"], bool)
    assert doc["ambiguous"] == any(len(s["members"]) > 1 for s in doc["equivalence_sets"])
    assert [s["members"][0] for s in doc["equivalence_sets"]] == doc["named_effects"]
    assert all(set(s) == {"members", "separating_measurement"} for s in doc["equivalence_sets"])
    # the SCARA template declares no mass: the gravity-driven effects are listed, none is assumed
    assert {c["effect"] for c in doc["cannot_size"]} == {"compliance", "link-bending", "backlash-gravity",
                                                          "base-deformation"}
    assert all(set(c) == {"effect", "reason", "field"} for c in doc["cannot_size"])
    revolutes = {f"{j}" for j in ("1", "2", "4")}
    assert set(doc["spectrum_peaks"]) == revolutes
    assert all(set(p) >= {"cycles_per_rev", "share", "p_value", "resolution_cycles_per_rev"}
               for p in doc["spectrum_peaks"].values())
    assert doc["noise_factor"] is None and doc["validation_factor"] > 0 and doc["identification_factor"] > 0
    assert doc["per_target"] == [] and doc["targets_agree"] is None
    # issue 40: the joints of each named per-joint effect, and the confidence
    assert doc["effect_joints"] == {"backlash": ["1", "2", "3", "4"]} or set(doc["effect_joints"]) == {"backlash"}
    assert doc["confidence"] in ("high", "low") and isinstance(doc["selection_steps"], list)
    assert all(set(r) >= {"effect", "stage", "reason"} for r in doc["rejected"])
    assert all({"effect", "validation_rms", "criterion"} <= set(e) for e in doc["ranking"])
    for key in ("validation_before", "validation_after"):
        assert set(doc[key]) >= {"mean", "max", "rms"}
    assert doc["validation_after"]["rms"] < doc["validation_before"]["rms"]
    assert {p.name for p in plots.iterdir()} >= {"residuals_vs_joints.png", "before_after.png"}
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in plots.iterdir())
    text = capsys.readouterr().out
    assert "Which effect?" in text and "backlash" in text


def test_diagnose_needs_a_noise_model(tmp_path, capsys):
    src = str(TEMPLATES / "scara.py")
    data = tmp_path / "d.csv"
    assert main(["simulate", src, "--poses", "40", "--validation", "0", "--out", str(data), "--quiet"]) == 0
    text = "\n".join(line for line in data.read_text().splitlines() if not line.startswith("# noise"))
    data.write_text(text + "\n")
    assert main(["diagnose", src, str(data), "--json", str(tmp_path / "x.json")]) == 2
    assert "noise" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()
