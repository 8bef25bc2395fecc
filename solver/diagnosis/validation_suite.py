"""Withheld-effect validation of the diagnosis: simulate reality with an effect, fit the rigid model, diagnose.

Units: lengths in mm, angles in rad (rates in %).

For each mechanism, seed and case (no effect; each applicable effect alone at a
realistic magnitude; pairs of effects), a virtual machine with that effect generates
107 identification and 30 validation points with campaign metadata
(:func:`hyperstat.solver.calibration.virtual.workshop_metadata`); the rigid model is fitted and
:func:`hyperstat.solver.diagnosis.diagnose.diagnose` is run without being told the effect.  Recorded: the
effect ranked first, the effects selected, validation RMS before and after against the
noise RMS, the magnitude recovered.  ``hyperstat validate-diagnosis`` runs it and writes
the confusion matrix and rates (``docs/diagnosis.md``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.diagnosis.diagnose import OUTCOMES as OUTCOMES_ORDER
from hyperstat.solver.diagnosis.diagnose import diagnose
from hyperstat.solver.diagnosis.effects import EFFECT_NAMES, applicable_effects, make_effect
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.analysis.stationarity import StationarityResult
from hyperstat.solver.calibration.virtual import VirtualMachine, workshop_metadata

__all__ = ["CaseResult", "run_suite", "suite_cases", "summarize", "with_declared_mass", "to_markdown", "VIOLATION_MAGNITUDE", "IndependentCase",
           "load_independent_generator", "run_independent", "summarize_independent", "independent_markdown"]

VIOLATION_MAGNITUDE = 1e-2  # rad or mm: a grossly violated forced defect (see docs/diagnosis.md)
PAIRS = (("thermal", "backlash"), ("screw-periodic", "tracker-drift"))
VISIBLE = 1.15  # a case whose validation RMS before is below 1.15x the noise RMS has no gap to find
LIBRARY_SINCE_28 = ("link-bending", "angle-harmonic-3")  # out of the library before issue 28, in it since
ABSORBED = ("tracker-scale",)  # absorbed by the geometric parameters at realistic magnitudes


@dataclass
class CaseResult:
    """One simulated case and what the diagnosis said."""

    mechanism: str
    seed: int
    truth: tuple
    gap_significant: bool
    ranked_first: str | None
    selected: tuple
    correct: bool
    validation_before: float
    validation_after: float | None
    noise_rms: float
    magnitude_true: float | None
    magnitude_found: float | None
    violated_defect: str | None
    elapsed: float
    truth_defect: str | None = None
    violated_ambiguous_with: tuple = ()
    outcome: str = ""

    def to_dict(self) -> dict:
        """JSON-ready dictionary (mm)."""
        return dict(self.__dict__, truth=list(self.truth), selected=list(self.selected),
                    violated_ambiguous_with=list(self.violated_ambiguous_with))


def suite_cases(mechanism: Mechanism, analysis: StationarityResult, pairs: bool = True) -> list[tuple]:
    """Cases for a mechanism: (), each applicable effect alone, and pairs of applicable effects."""
    meta = workshop_metadata(mechanism, 8, seed=0)
    from hyperstat.solver.calibration.measurements import MeasurementSet

    probe = MeasurementSet([str(i) for i in range(8)], [], np.zeros((8, len(mechanism.actuated))), np.zeros((8, 3)),
                           metadata=meta)
    missing = applicable_effects(mechanism, analysis, probe)
    cases = [()] + [(name,) for name in EFFECT_NAMES if name not in missing]
    if pairs:
        cases += [p for p in PAIRS if not any(e in missing for e in p)]
    return cases


def _violated_choice(mechanism, analysis, kin) -> str:
    """The forced defect whose violation position measurements see best.

    Most of a violation's effect on the target is absorbed by the free geometric
    parameters; this picks the forced defect with the largest part left over (its effect
    columns after projection on the rigid model's, at 60 poses of the nominal machine).
    """
    from hyperstat.solver.calibration.identify import _weights, identify
    from hyperstat.solver.diagnosis.screening import Screen, absorbed, effect_columns, folds

    vm = VirtualMachine.random(mechanism, analysis, seed=0, kinematics=kin, angle_tolerance=0.0,
                               length_tolerance=0.0)
    data = vm.measure(vm.poses(60, seed=0), noise=False)
    rigid = identify(mechanism, analysis, data, kinematics=kin)
    base_idx = [rigid.model.names.index(b) for b in rigid.base]
    full = rigid.model.predict(rigid.theta, data, jacobian=True)
    screen = Screen(_weights(data), rigid.residuals, full.jacobian[:, :, base_idx], np.ones(len(base_idx)),
                    folds(data, 4, 0))
    best, best_name = -1.0, None
    for p in analysis.parameters:
        if p.verdict != "forced":
            continue
        effect = make_effect("violated-constraint", mechanism, analysis, data, only=[p.name])
        cols, _ = effect_columns(mechanism, analysis, kin, rigid, data, effect)
        size = float(np.sqrt(np.mean(np.sum(cols[:, :, 0] ** 2, axis=1))))
        seen = size * absorbed(screen, cols)
        if seen > best:
            best, best_name = seen, p.name
    return best_name


def run_case(mechanism, analysis, kin, case: tuple, seed: int, violated: str | None, n_id: int = 107,
             n_val: int = 30) -> CaseResult:
    """Simulate one case and diagnose it."""
    rng = np.random.default_rng(1000 + seed)
    effects = []
    for name in case:
        options = {}
        if name == "tracker-drift":
            options["sessions"] = [1.0, 2.0]
        if name == "violated-constraint":
            options.update(only=[violated], magnitude_rad=VIOLATION_MAGNITUDE, magnitude_mm=VIOLATION_MAGNITUDE)
        effects.append(make_effect(name, mechanism, analysis, None, **options).draw_truth(rng))
    vm = VirtualMachine.random(mechanism, analysis, seed=seed, kinematics=kin, effects=tuple(effects))
    meta = workshop_metadata(mechanism, n_id + n_val, seed=seed)
    q = vm.poses(n_id + n_val, seed=seed + 10)
    data = vm.measure(q[:n_id], seed=seed + 20, metadata={k: v[:n_id] for k, v in meta.items()})
    val = vm.measure(q[n_id:], seed=seed + 30, prefix="V", metadata={k: v[n_id:] for k, v in meta.items()})
    t0 = time.perf_counter()
    d = diagnose(mechanism, analysis, data, val, kinematics=kin)
    # the effect the diagnosis names: the first selected, else the best candidate it did not refuse
    fits = [e["effect"] for e in d.ranking if not e.get("note") and not e.get("rejected")]
    first = d.selected[0] if d.selected else (fits[0] if fits else None)
    if not case:
        correct = not d.gap_significant
    elif len(case) == 1 and case[0] in ABSORBED:
        correct = not d.gap_significant or first == case[0]
    elif len(case) == 1:
        correct = d.gap_significant and first == case[0]
    else:
        correct = d.gap_significant and set(d.selected) == set(case)
    true_mag = found_mag = None
    if len(case) == 1 and d.effect_parameters and case[0] in d.selected:
        true_mag = float(np.linalg.norm(effects[0].truth))
        found = [p["estimate"] for p in d.effect_parameters if p["effect"] == case[0]]
        found_mag = float(np.linalg.norm(found))
        if case[0] == "violated-constraint" and d.violated_defect["defect"] != violated:
            found_mag = None  # another defect (maybe of another unit) was named: no magnitude to compare
    return CaseResult(mechanism.name, seed, tuple(case), d.gap_significant, first, tuple(d.selected), bool(correct),
                      d.validation_before["rms"], None if d.validation_after is None else d.validation_after["rms"],
                      d.rigid.noise_rms, true_mag, found_mag,
                      None if d.violated_defect is None else d.violated_defect["defect"], time.perf_counter() - t0,
                      violated if "violated-constraint" in case else None,
                      () if d.violated_defect is None else tuple(d.violated_defect["ambiguous_with"]), d.outcome)


SUITE_MOVING_MASS = 50.0  # kg: the mass the suite declares on a machine that declares none (its virtual machine's)


def with_declared_mass(mechanism: Mechanism) -> Mechanism:
    """The mechanism with a declared moving mass when it declares no mass at all.

    The diagnosis never assumes a mass; the suite's virtual machine needs one to draw its
    gravity-driven effects, so it declares :data:`SUITE_MOVING_MASS` at the output
    (``metadata.moving_mass``) and gives the same declaration to the diagnosis, as a user
    of that machine would.
    """
    import dataclasses

    from hyperstat.solver.diagnosis.effects import gravity_source

    if gravity_source(mechanism) is not None or mechanism.metadata.get("masses"):
        return mechanism
    meta = {**mechanism.metadata, "moving_mass": SUITE_MOVING_MASS,
            "moving_mass_note": "declared by the validation suite's virtual machine (kg at the output)"}
    return dataclasses.replace(mechanism, metadata=meta)


def run_suite(sources: list[tuple[Mechanism, StationarityResult]], seeds: int = 5, pairs: bool = True,
              only: tuple | None = None, progress=None) -> list[CaseResult]:
    """Run every case over ``seeds`` seeds for each (mechanism, analysis); ``only`` restricts the cases."""
    results = []
    for mechanism, analysis in sources:
        mechanism = with_declared_mass(mechanism)
        kin = Kinematics(mechanism)
        cases = suite_cases(mechanism, analysis, pairs)
        if only is not None:
            cases = [c for c in cases if ("+".join(c) or "none") in only]
        violated = _violated_choice(mechanism, analysis, kin) if any("violated-constraint" in c for c in cases) else None
        for case in cases:
            for seed in range(seeds):
                res = run_case(mechanism, analysis, kin, case, seed, violated)
                results.append(res)
                if progress is not None:
                    progress(res)
    return results


def summarize(results: list[CaseResult]) -> dict:
    """Rates and the confusion matrix (true case -> effect ranked first / 'no gap')."""
    confusion: dict = {}
    for r in results:
        key = "+".join(r.truth) or "none"
        said = ("no significant gap" if not r.gap_significant else
                ("+".join(sorted(r.selected)) if len(r.truth) > 1 else (r.ranked_first or "-")))
        confusion.setdefault(r.mechanism, {}).setdefault(key, {}).setdefault(said, 0)
        confusion[r.mechanism][key][said] += 1
    single = [r for r in results if len(r.truth) == 1 and r.truth[0] not in ABSORBED
              and r.validation_before >= VISIBLE * r.noise_rms]
    hidden = [r for r in results if len(r.truth) == 1 and r.truth[0] not in ABSORBED
              and r.validation_before < VISIBLE * r.noise_rms]
    null = [r for r in results if not r.truth]
    fixed = single  # an effect ranked first but not added counts as not fixed
    pairs = [r for r in results if len(r.truth) > 1]
    absorbed = [r for r in results if len(r.truth) == 1 and r.truth[0] in ABSORBED]
    return {
        "cases": len(results),
        "right_effect_first": float(np.mean([r.correct for r in single])) if single else None,
        "right_effect_first_n": len(single),
        "after_within_1.3x_noise": float(np.mean([r.validation_after is not None
                                                  and r.validation_after <= 1.3 * r.noise_rms for r in fixed]))
        if fixed else None,
        "after_within_1.3x_noise_n": len(fixed),
        "false_alarm": float(np.mean([r.gap_significant for r in null])) if null else None,
        "false_alarm_n": len(null),
        "pairs_both_found": float(np.mean([r.correct for r in pairs])) if pairs else None,
        "pairs_n": len(pairs),
        "absorbed_cases_without_gap_or_named": float(np.mean([r.correct for r in absorbed])) if absorbed else None,
        "below_noise_floor": [f"{r.mechanism} {r.truth[0]} seed {r.seed}" for r in hidden],
        "below_noise_floor_no_gap": float(np.mean([not r.gap_significant or r.correct for r in hidden]))
        if hidden else None,
        "violated_defect_named": sorted({r.violated_defect for r in results if r.violated_defect}),
        "violated_defect_named_right": [r.violated_defect == r.truth_defect for r in results
                                        if r.truth == ("violated-constraint",) and r.violated_defect],
        "violated_defect_named_right_or_ambiguous": [
            r.violated_defect == r.truth_defect or r.truth_defect in r.violated_ambiguous_with for r in results
            if r.truth == ("violated-constraint",) and r.violated_defect],
        "confusion": confusion,
    }


def to_markdown(results: list[CaseResult], summary: dict, command: str) -> str:
    """The confusion matrix and rates as Markdown."""
    lines = [f"Produced by `{command}` ({summary['cases']} cases).", "",
             "| rate | value | cases |", "|---|---|---|"]

    def pct(v):
        return "-" if v is None else f"{100 * v:.0f} %"

    lines += [
        f"| right effect ranked first (single effects whose validation RMS before is at least {VISIBLE}x the noise) | {pct(summary['right_effect_first'])} | "
        f"{summary['right_effect_first_n']} |",
        f"| validation RMS within 1.3x noise RMS after adding it | {pct(summary['after_within_1.3x_noise'])} | "
        f"{summary['after_within_1.3x_noise_n']} |",
        f"| false alarm on no-effect cases | {pct(summary['false_alarm'])} | {summary['false_alarm_n']} |",
        f"| violated forced defect named right (when selected) | "
        f"{pct(np.mean(summary['violated_defect_named_right']) if summary['violated_defect_named_right'] else None)} | "
        f"{len(summary['violated_defect_named_right'])} |",
        f"| violated forced defect named right, or reported ambiguous with the right one | "
        f"{pct(np.mean(summary['violated_defect_named_right_or_ambiguous']) if summary['violated_defect_named_right_or_ambiguous'] else None)} | "
        f"{len(summary['violated_defect_named_right_or_ambiguous'])} |",
        f"| both effects of a pair selected | {pct(summary['pairs_both_found'])} | {summary['pairs_n']} |",
        f"| single effects below the noise floor (validation before < {VISIBLE}x noise): no gap or named | "
        f"{pct(summary['below_noise_floor_no_gap'])} | {len(summary['below_noise_floor'])} |",
        f"| absorbed effects (tracker-scale): no gap, or named | {pct(summary['absorbed_cases_without_gap_or_named'])} "
        f"| {sum(1 for r in results if r.truth and r.truth[0] in ABSORBED and len(r.truth) == 1)} |",
        "",
    ]
    for mech, table in summary["confusion"].items():
        said = sorted({s for row in table.values() for s in row})
        lines += [f"#### {mech}: true case (rows) against the diagnosis (columns)", "",
                  "| true \\ diagnosed | " + " | ".join(said) + " |", "|---" * (len(said) + 1) + "|"]
        for true, row in table.items():
            lines.append(f"| {true} | " + " | ".join(str(row.get(s, "")) for s in said) + " |")
        lines.append("")
    lines += ["#### Every case", "",
              "| mechanism | seed | true | gap | first | selected | val. before (µm) | after (µm) | noise (µm) | "
              "magnitude true / found | time (s) |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        mag = "-" if r.magnitude_true is None else f"{r.magnitude_true:.3g} / " + (
            f"{r.magnitude_found:.3g}" if r.magnitude_found is not None else f"({r.violated_defect} named)")
        if r.truth_defect is not None and r.violated_defect is not None:
            mag += f" [{r.truth_defect} -> {r.violated_defect}" + (
                f", ambiguous with {', '.join(r.violated_ambiguous_with)}]" if r.violated_ambiguous_with else "]")
        after = "-" if r.validation_after is None else f"{1000 * r.validation_after:.1f}"
        lines.append(f"| {r.mechanism} | {r.seed} | {'+'.join(r.truth) or 'none'} | {'yes' if r.gap_significant else 'no'}"
                     f" | {r.ranked_first} | {'+'.join(r.selected) or '-'} | {1000 * r.validation_before:.1f} | {after} | "
                     f"{1000 * r.noise_rms:.1f} | {mag} | {r.elapsed:.1f} |")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------- the independent generator
@dataclass
class IndependentCase:
    """One campaign of the independent generator (``tests/solver/diagnosis/independent_generator.py``) and the answer."""

    arm: str
    case: str
    kind: str  # "in-library", "out-of-library", "noise"
    seed: int
    outcome: str
    named: str | None
    selected: tuple
    where: str | None
    where_right: bool | None
    validation_before: float
    validation_after: float | None
    noise_rms: float
    noise_factor_true: float
    noise_factor_found: float | None
    elapsed: float
    members: tuple = ()  # every member of the answer's equivalence sets (named effects included)
    ambiguous: bool = False

    @property
    def library_name(self) -> str | None:
        """The truth's name in the library of issue 28 (link bending and any periodic order joined it), or None."""
        if self.kind == "in-library" or self.case in LIBRARY_SINCE_28:
            return self.case
        return None

    @property
    def visible(self) -> bool:
        """Whether the case leaves a gap to find (validation RMS before at least ``VISIBLE`` x the noise)."""
        return self.validation_before >= VISIBLE * self.noise_rms

    def to_dict(self) -> dict:
        """JSON-ready dictionary (mm)."""
        return dict(self.__dict__, selected=list(self.selected), visible=self.visible)


def load_independent_generator(path: str | None = None):
    """The independent generator module, loaded from the source tree's ``tests/`` (it is not installed).

    Raises
    ------
    DataError
        If the file is absent (an installed wheel has no tests).
    """
    import importlib.util
    import sys
    from pathlib import Path

    from hyperstat.solver.errors import DataError

    file = Path(path) if path else (Path(__file__).resolve().parents[2] / "tests" / "solver" / "diagnosis"
                                    / "independent_generator.py")
    if not file.is_file():
        raise DataError(f"the independent generator {file} is not there: it lives in the source tree's tests/ "
                        f"(run validate-diagnosis from a checkout of hyperstat).")
    spec = importlib.util.spec_from_file_location("hyperstat_independent_generator", file)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def run_independent(generator, seeds: int = 3, arms: tuple | None = None, cases: tuple | None = None,
                    progress=None) -> list[IndependentCase]:
    """Diagnose every campaign of the independent generator (each arm, case, seed)."""
    from hyperstat.solver.analysis.stationarity import analyze
    from hyperstat.solver.calibration.measurements import parse_measurements
    from hyperstat.solver.kinematics.modelfile import load_model

    results = []
    for arm, path in generator.MODELS.items():
        if arms is not None and arm not in arms:
            continue
        mech = load_model(path)
        analysis = analyze(mech, n_configurations=24, seed=0)
        kin = Kinematics(mech)
        for case in generator.cases_for(arm):
            if cases is not None and case not in cases:
                continue
            kind = ("in-library" if case in generator.IN_LIBRARY else
                    "out-of-library" if case in generator.OUT_OF_LIBRARY else "noise")
            for seed in range(seeds):
                id_text, val_text, truth = generator.campaign(path, case, seed)
                data = parse_measurements(id_text, mech, f"{arm}-{case}-{seed}.csv")
                val = parse_measurements(val_text, mech, f"{arm}-{case}-{seed}.validation.csv")
                t0 = time.perf_counter()
                d = diagnose(mech, analysis, data, val, kinematics=kin)
                named = d.selected[0] if d.selected else None
                where = d.verdict.get("where")
                words = generator.where_words(arm, case, truth) if kind == "out-of-library" else []
                where_right = (any(w in where for w in words) if where else False) if words else None
                found = d.verdict.get("noise_consistent", {}).get("factor")
                members = tuple(dict.fromkeys(m for st in d.equivalence_sets for m in st["members"]))
                res = IndependentCase(arm, case, kind, seed, d.outcome, named, tuple(d.selected), where, where_right,
                                      d.validation_before["rms"],
                                      None if d.validation_after is None else d.validation_after["rms"],
                                      d.rigid.noise_rms, truth["noise_factor"], found, time.perf_counter() - t0,
                                      members, d.ambiguous)
                results.append(res)
                if progress is not None:
                    progress(res)
    return results


def _rate(flags: list) -> float | None:
    return float(np.mean(flags)) if flags else None


def summarize_independent(results: list[IndependentCase]) -> dict:
    """Rates of the independent generator, per kind (see ``docs/diagnosis.md``)."""
    inlib = [r for r in results if r.kind == "in-library" and r.visible]
    outlib = [r for r in results if r.kind == "out-of-library" and r.visible]
    under = [r for r in results if r.case == "understated-noise"]
    null = [r for r in results if r.case == "none"]
    hidden = [r for r in results if r.kind != "noise" and not r.visible]
    # the library of issue 28 names link bending and any periodic order: those cases are right when the answer
    # names the truth or puts it in an equivalence set; the others stay out of the library
    lib = [r for r in results if r.library_name and r.visible]
    outside = [r for r in results if r.kind == "out-of-library" and not r.library_name and r.visible]
    return {
        "library_28_named": _rate([r.library_name in r.selected for r in lib]),
        "library_28_named_or_in_set": _rate([r.library_name in r.selected or r.library_name in r.members
                                             for r in lib]),
        "library_28_explained": _rate([r.outcome == "explained" and r.library_name in r.selected for r in lib]),
        "library_28_ambiguous": _rate([r.ambiguous for r in lib]),
        "library_28_n": len(lib),
        "outside_28_honest": _rate([r.outcome in ("unexplained", "partly explained") for r in outside]),
        "outside_28_n": len(outside),
        "cases": len(results),
        "in_library_right_first": _rate([r.named == r.case for r in inlib]), "in_library_n": len(inlib),
        "in_library_explained": _rate([r.named == r.case and r.outcome == "explained" for r in inlib]),
        "out_of_library_honest": _rate([r.outcome in ("unexplained", "partly explained") for r in outlib]),
        "out_of_library_misattributed": _rate([r.outcome in ("explained", "understated noise") for r in outlib]),
        "out_of_library_no_gap": _rate([r.outcome == "no significant gap" for r in outlib]),
        "out_of_library_where_right": _rate([bool(r.where_right) for r in outlib
                                             if r.outcome in ("unexplained", "partly explained")]),
        "out_of_library_n": len(outlib),
        "understated_noise_flagged": _rate([r.outcome == "understated noise" for r in under]),
        "understated_noise_n": len(under),
        "false_alarm": _rate([r.outcome != "no significant gap" for r in null]), "false_alarm_n": len(null),
        "hidden": [f"{r.arm} {r.case} seed {r.seed}: {r.outcome}" for r in hidden],
    }


def independent_markdown(results: list[IndependentCase], summary: dict, command: str) -> str:
    """Rates, outcome matrix and every case of the independent generator, as Markdown."""
    def pct(v):
        return "-" if v is None else f"{100 * v:.0f} %"

    s = summary
    lines = [f"Produced by `{command}` ({s['cases']} campaigns of the independent generator).", "",
             "| rate (independent generator) | value | cases |", "|---|---|---|",
             f"| in-library: right effect named first (validation RMS before >= {VISIBLE}x noise) | "
             f"{pct(s['in_library_right_first'])} | {s['in_library_n']} |",
             f"| in-library: right effect and outcome 'explained' | {pct(s['in_library_explained'])} | "
             f"{s['in_library_n']} |",
             f"| out-of-library: honest ('unexplained' or 'partly explained') | {pct(s['out_of_library_honest'])} | "
             f"{s['out_of_library_n']} |",
             f"| out-of-library: confidently misattributed ('explained' or 'understated noise') | "
             f"{pct(s['out_of_library_misattributed'])} | {s['out_of_library_n']} |",
             f"| out-of-library: no significant gap found | {pct(s['out_of_library_no_gap'])} | "
             f"{s['out_of_library_n']} |",
             f"| out-of-library honest answers whose 'where' names the right joint or column | "
             f"{pct(s['out_of_library_where_right'])} | - |",
             f"| understated noise (1.6x the header) flagged 'understated noise' | "
             f"{pct(s['understated_noise_flagged'])} | {s['understated_noise_n']} |",
             f"| false alarm (noise-only campaigns not answered 'no significant gap') | {pct(s['false_alarm'])} | "
             f"{s['false_alarm_n']} |",
             f"| library of issue 28 (the in-library cases, link bending, three cycles per revolution): truth named "
             f"| {pct(s['library_28_named'])} | {s['library_28_n']} |",
             f"| library of issue 28: truth named or in the answer's equivalence set | "
             f"{pct(s['library_28_named_or_in_set'])} | {s['library_28_n']} |",
             f"| library of issue 28: answered 'explained' by the truth | {pct(s['library_28_explained'])} | "
             f"{s['library_28_n']} |",
             f"| library of issue 28: answer ambiguous (an equivalence set with several members) | "
             f"{pct(s['library_28_ambiguous'])} | {s['library_28_n']} |",
             f"| still outside the library (coupling, tool growth): honest | {pct(s['outside_28_honest'])} | "
             f"{s['outside_28_n']} |", ""]
    outcomes = list(OUTCOMES_ORDER)
    for arm in sorted({r.arm for r in results}):
        lines += [f"#### {arm}: true case (rows) against the outcome (columns)", "",
                  "| true case | " + " | ".join(outcomes) + " | named effects |", "|---" * (len(outcomes) + 2) + "|"]
        for case in dict.fromkeys(r.case for r in results if r.arm == arm):
            rows = [r for r in results if r.arm == arm and r.case == case]
            counts = [str(sum(r.outcome == o for r in rows) or "") for o in outcomes]
            named = sorted({"+".join(r.selected) + (" {" + ", ".join(r.members) + "}" if r.ambiguous else "")
                            for r in rows if r.selected})
            lines.append(f"| {case} | " + " | ".join(counts) + f" | {', '.join(named) or '-'} |")
        lines.append("")
    lines += ["#### Every campaign", "",
              "| arm | case | seed | outcome | selected | where | val. before (µm) | after (µm) | noise (µm) | "
              "time (s) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        after = "-" if r.validation_after is None else f"{1000 * r.validation_after:.1f}"
        where = (r.where or "-").split(":")[0].replace("|", "/")
        lines.append(f"| {r.arm} | {r.case} | {r.seed} | {r.outcome} | {'+'.join(r.selected) or '-'} | {where} | "
                     f"{1000 * r.validation_before:.1f} | {after} | {1000 * r.noise_rms:.1f} | {r.elapsed:.1f} |")
    return "\n".join(lines) + "\n"


