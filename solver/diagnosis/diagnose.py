"""Diagnosis of the sim-to-real gap: is there one, where it lies, which effect causes it, how far it shrinks.

Units: lengths in mm (residuals reported in mm; the text output prints µm), angles in rad.

The method's steps are modules of this package (``docs/diagnosis.md``):

1. **Is there a gap?** (:mod:`.gap`) The chi-square gap test on the identification and
   the validation points; "inputs wrong" when sigma is in the hundreds or the residuals
   are a fraction of a link (nothing else is tried); over-fitting when the rigid fit
   predicts held-out poses far worse than the poses it was fitted to.
2. **Where?** (:mod:`.where`) Residual RMS per workspace region and direction, the share
   each variable explains, and the structure tests (F-tests of joint errors, trends,
   harmonics with each revolute's spectrum and its resolution, candidate signatures).
3. **Which effect?** (:mod:`.screening`, :mod:`.periodic`) Every candidate linearised at
   the rigid solution, scored by blocked cross-validation and BIC, fitted within its
   domain and checked against its sourced magnitude prior; periodic effects of the
   orders the spectrum shows join; a periodic effect is chosen only when the spectrum
   agrees with its order and the order is established.
4. **How far does it shrink, and what else fits as well?** The selected effects are
   identified with the geometry by the full nonlinear fit (an effect leaving its domain
   or worsening the validation error is removed); the equivalence sets
   (:mod:`.equivalence`) list every effect these poses cannot separate from each named
   one, and the measurement that would.
5. **The answer** (:mod:`.answer`), one of :data:`OUTCOMES`, with its evidence; for a
   file with several targets, each target is diagnosed alone too (:mod:`.targets`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.analysis.stationarity import StationarityResult
from hyperstat.solver.calibration.identify import IdentificationResult, MeasurementModel, identify
from hyperstat.solver.calibration.measurements import MeasurementSet, joined
from hyperstat.solver.diagnosis.answer import OUTCOMES, format_outcome, verdict
from hyperstat.solver.diagnosis.effects import (GRAVITY_EFFECTS, LinkBending, MASS_FIELD, MASS_FIELD_SHORT, applicable_effects,
                                                available_effects, gravity_source, harmonic_name, harmonic_order,
                                                is_jointwise, is_known_effect, is_library_effect, make_effect,
                                                screw_lead)
from hyperstat.solver.diagnosis.equivalence import (STAND_MOTION, STAND_MOTION_WORDS, bending_alternatives,
                                                    equivalence_sets, gravity_family, stand_motion_family)
from hyperstat.solver.diagnosis.confirmation import CONFIRM_P, validation_confirms
from hyperstat.solver.diagnosis.gap import FEW_EQUATIONS, gap_test, inputs_wrong, overfitting, weighted_validation
from hyperstat.solver.diagnosis.held_out import held_out_choice, held_out_words, nested_f_test
from hyperstat.solver.diagnosis.leg_pattern import (LEG_OFFSET, LEG_OFFSET_WORDS, leg_offset_family,
                                                    leg_thermal_pattern, prismatic_legs)
from hyperstat.solver.diagnosis.periodic import (aliased_orders, smooth_orders, periodic_gate, refined_order, screw_order,
                                                 screw_period, spectral_candidates)
from hyperstat.solver.diagnosis.screening import (PRIOR_ANGLE, PRIOR_LENGTH, Screen, UnitActuators, atom_key,
                                                  black_box_ceiling, cv_rms, folds, plugin_guard, region_blocks,
                                                  score_entry, screen_candidates, split_key)
from hyperstat.solver.diagnosis.located import below_guard_words, seen_words, settling_measurement
from hyperstat.solver.diagnosis.selection import BIC_DROP, CV_DROP, LOCATED_CV_DROP, forward_selection
from hyperstat.solver.diagnosis.observations import oriented, residual_rows, row_view, stack_rows
from hyperstat.solver.diagnosis.targets import per_target_check, targets_to_check, targets_agree
from hyperstat.solver.diagnosis.where import (ResidualField, describe_where, spectrum_peaks, structure_tests,
                                             targets_words, where_summary)
from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.threads import limited_blas

__all__ = ["Diagnosis", "diagnose", "region_blocks", "structure_tests", "describe_where", "format_outcome", "OUTCOMES"]


@dataclass
class Diagnosis:
    """Outcome of :func:`diagnose`; ``to_dict`` gives the JSON of ``hyperstat diagnose``
    (``docs/diagnosis.md``, "The JSON contract").

    ``outcome`` is one of :data:`OUTCOMES`; ``verdict`` holds its evidence (the gap tests
    after the effects, the remaining gap and where it lies, or the noise level that
    would make the data consistent); ``rejected`` lists the candidates refused for
    physical implausibility, for a spectrum that disagrees with their order, or for
    making the validation error worse, with the reason; ``equivalence_sets`` one set per
    named effect; ``cannot_size`` the gravity-driven effects no declared mass sizes.
    """

    gap_significant: bool
    gap_test: dict
    where: dict
    ranking: list
    selected: list
    selection_ties: list
    not_applicable: dict
    validation_before: dict | None
    validation_after: dict | None
    share_explained: float | None
    ceiling: dict
    effect_parameters: list
    violated_defect: dict | None
    rigid: IdentificationResult = field(repr=False)
    final: IdentificationResult | None = field(default=None, repr=False)
    elapsed: float = 0.0
    outcome: str = "no significant gap"
    verdict: dict = field(default_factory=dict)
    rejected: list = field(default_factory=list)
    equivalence_sets: list = field(default_factory=list)
    cannot_size: list = field(default_factory=list)
    spectrum_peaks: dict = field(default_factory=dict)
    per_target: list = field(default_factory=list)
    targets_agree: bool | None = None
    targets_evidence: str = ""
    effect_joints: dict = field(default_factory=dict)
    selection_steps: list = field(default_factory=list)
    pruned: list = field(default_factory=list)

    @property
    def named_effects(self) -> list:
        """The effects the answer names (empty unless ``explained`` or ``partly explained``)."""
        return list(self.selected) if self.outcome in ("explained", "partly explained") else []

    @property
    def ambiguous(self) -> bool:
        """Whether some equivalence set has more than one member."""
        return any(len(s["members"]) > 1 for s in self.equivalence_sets)

    @property
    def confidence(self) -> str:
        """``"low"`` when the targets tell different stories, the named effects could not be compared with the
        gravity-driven effects (no masses), or a named effect cannot be told from the stand (the machine's base)
        moving during the campaign (``stand-motion`` in its set: no measurement of the file separates them), or a
        named effect's parameters lie outside its physical prior in their pattern (``verdict.outside_prior``: a
        ``leg-thermal`` with the change on some legs only, :mod:`.leg_pattern`), or a named periodic error's order
        is one of two or more that the joint's range cannot tell apart (``verdict.order_not_established``), or a named
        effect was taken below the selection's 5 % bar because the structure tests locate it (``verdict.below_guard``,
        :mod:`.located`), or an ``unexplained`` answer's structure tests locate a library effect on a joint that was
        not taken (``verdict.library_effect_seen``), or an ``understated noise`` answer's strongest structure test
        falls short of its threshold by less than 10x (``verdict.near_structure``, :func:`.answer.near_structure`),
        or an ``over-fitting`` answer's held-out excess is beyond what the fitted model's own uncertainty accounts
        for (``verdict.effect_not_excluded``: a missing effect is not excluded), or the named effect was chosen on the
        held-out poses because the identification poses were too few (``verdict.held_out_choice``,
        :mod:`.held_out`), or an ``understated noise`` answer's isotropy test passes by less than 10x
        (``verdict.near_anisotropy``, :func:`.answer.near_anisotropy`), or a ``no significant gap`` answer's gap or
        structure test passes by less than 10x (``verdict.near_gap``, :func:`.answer.near_gap`), or the pooled
        choice found an effect it could not fit or answer (``verdict.held_out_found``), or a located effect was taken on
        the held-out poses' confirmation against the blocked cross-validation (``verdict.cv_overruled``); ``"high"``
        otherwise."""
        if self.targets_agree is False or self.verdict.get("unchecked_against") or self.verdict.get("stand_motion") \
                or self.verdict.get("targets_differ") or self.verdict.get("outside_prior") \
                or self.verdict.get("order_not_established") or self.verdict.get("below_guard") \
                or self.verdict.get("library_effect_seen") or self.verdict.get("near_structure") \
                or self.verdict.get("effect_not_excluded") or self.verdict.get("held_out_choice") \
                or self.verdict.get("near_anisotropy") or self.verdict.get("near_gap") \
                or self.verdict.get("held_out_found") or self.verdict.get("cv_overruled"):
            return "low"
        return "high"

    @property
    def noise_factor(self) -> float | None:
        """For ``understated noise``: the factor on the header's noise that makes the data consistent."""
        if self.outcome != "understated noise":
            return None
        return self.verdict["noise_consistent"]["factor"]

    @property
    def identification_factor(self) -> float | None:
        """``sqrt(chi2 / dof)`` of the rigid fit on its identification points."""
        return self.gap_test.get("identification", {}).get("noise_factor")

    @property
    def validation_factor(self) -> float | None:
        """``sqrt(chi2 / dof)`` of the rigid fit on the held-out points (variance inflated for its own error)."""
        return self.gap_test.get("validation", {}).get("noise_factor")

    def to_dict(self) -> dict:
        """JSON-ready dictionary (units: mm, rad)."""
        return {
            "units": {"length": "mm", "angle": "rad"},
            "outcome": self.outcome,
            "named_effects": self.named_effects,
            "effect_joints": {n: j for n, j in self.effect_joints.items() if n in self.named_effects},
            "confidence": self.confidence,
            "equivalence_sets": [{"members": s["members"], "separating_measurement": s["separating_measurement"]}
                                 for s in self.equivalence_sets],
            "ambiguous": self.ambiguous,
            "cannot_size": self.cannot_size,
            "spectrum_peaks": self.spectrum_peaks,
            "noise_factor": self.noise_factor,
            "validation_factor": self.validation_factor,
            "identification_factor": self.identification_factor,
            "per_target": self.per_target,
            "targets_agree": self.targets_agree,
            "targets_evidence": self.targets_evidence,
            "verdict": self.verdict,
            "equivalence_evidence": self.equivalence_sets,
            "gap_significant": self.gap_significant,
            "gap_test": self.gap_test,
            "where": self.where,
            "ranking": self.ranking,
            "selected": self.selected,
            "rejected": self.rejected,
            "selection_ties": self.selection_ties,
            "selection_steps": self.selection_steps,
            "pruned_joints": self.pruned,
            "not_applicable": self.not_applicable,
            "validation_before": self.validation_before,
            "validation_after": self.validation_after,
            "share_explained": self.share_explained,
            "ceiling": self.ceiling,
            "effect_parameters": self.effect_parameters,
            "violated_defect": self.violated_defect,
            "rigid_identification": {"rank": self.rigid.rank, "condition_number": self.rigid.condition_number,
                                     "identification": self.rigid.identification, "sigma": self.rigid.sigma,
                                     "fit_quality": self.rigid.fit_quality},
        }


@limited_blas
def diagnose(
    mechanism: Mechanism,
    analysis: StationarityResult,
    data: MeasurementSet,
    validation: MeasurementSet | None = None,
    candidates: tuple | None = None,
    kinematics: Kinematics | None = None,
    n_blocks: int = 4,
    seed: int = 0,
    max_effects: int = 3,
    progress=None,
    per_target: bool = True,
) -> Diagnosis:
    """Diagnose the gap left by the rigid model (see the module docstring for the method).

    Parameters
    ----------
    mechanism, analysis : Mechanism, StationarityResult
        Nominal model and its stationarity analysis.
    data : MeasurementSet
        Identification measurements (one or several targets, 3-D or 6-D rows); its noise
        model is needed for the gap test.
    validation : MeasurementSet, optional
        Held-out points for the before / after numbers and the gap test after the
        effects (never used to choose among candidates, only to refuse one that makes
        them worse).
    candidates : tuple of str, optional
        Effect names to consider (default: the library, the periodic orders of the
        residual spectrum, and the plug-ins of the ``hyperstat.effects`` entry-point group).
    n_blocks : int
        Workspace regions of the blocked cross-validation.
    max_effects : int
        Most effects added.
    progress : callable, optional
        Called with a short stage name as the diagnosis advances (a progress bar).
    per_target : bool
        With several targets, also diagnose each target alone (``per_target``, ``targets_agree``).

    Returns
    -------
    Diagnosis

    Raises
    ------
    DataError
        If the data state no noise model (the gap test needs one), name an unknown effect,
        or a plug-in effect fails (one sentence naming it).
    """
    return _diagnose(mechanism, analysis, data, validation, candidates, kinematics, n_blocks, seed, max_effects,
                     progress, per_target)


def _cannot_size(mechanism: Mechanism, names) -> list:
    """Gravity-driven effects that no declared mass can size (never an assumed mass)."""
    if gravity_source(mechanism) is not None:
        return []
    parallel = len(mechanism.chains) > 1 and bool(mechanism.closures)
    legs = any(mechanism.joints[i].type == "P" for i in mechanism.actuated)
    names = [n for n in names if n != "joint-clearance" or (parallel and legs)]  # only a parallel machine's legs
    return [{"effect": n, "field": MASS_FIELD,
             "reason": (f"the gravity loads need the link masses and centres of mass, and '{mechanism.name}' declares "
                        f"none; declare them in {MASS_FIELD_SHORT}")} for n in GRAVITY_EFFECTS if n in names]


def _rigid_rows(mechanism, analysis, kin, rigid: IdentificationResult, data: MeasurementSet):
    """Rows at the rigid fit: residuals, weights, base columns, ``d row / d q_a``, ``d row / d target offset``."""
    six_d = oriented(rigid.model, data)
    base_idx = [rigid.model.names.index(b) for b in rigid.base]
    resid, w, jac, full = residual_rows(rigid.model, rigid.theta, data, jacobian=True, q_start=rigid.configurations)
    n_act = data.q.shape[1]
    unit_model = MeasurementModel(mechanism, analysis, kin, effects=(UnitActuators(n_act),),
                                  targets=list(data.target_names), orientation=six_d)
    theta_u = unit_model.initial()
    theta_u[: rigid.model.n] = rigid.theta
    pred = unit_model.predict(theta_u, data, jacobian=True, q_start=full.q)
    n = rigid.model.n
    act_jac = stack_rows(pred.jacobian[:, :, n:], pred.rotation_jacobian[:, :, n:] if six_d else None)
    k = len(data)
    tj = full.jacobian[:, :, rigid.model.sl_target].reshape(k, 3, -1, 3)
    target_jac = tj[np.arange(k), :, np.asarray(data.target_index, dtype=int), :]
    target_jac = stack_rows(target_jac, np.zeros_like(target_jac) if six_d else None)  # an offset turns nothing
    return resid, w, jac[:, :, base_idx], full, act_jac, target_jac, base_idx


def _at_rigid(kin, rigid: IdentificationResult, full) -> dict:
    """The rigid solution's configurations, state, target points (base frame) and tracker rotation."""
    state = kin.evaluate(full.q, rigid.model.defects(rigid.theta), jacobians=False)
    r_trk, _ = rigid.model.tracker_pose(rigid.theta)
    return {"q": full.q, "state": state, "world": full.world, "r_trk": r_trk}


class _Run:
    """What the steps of one diagnosis share (filled step by step)."""

    def __init__(self, mechanism, analysis, data, validation, kin, n_blocks: int, seed: int) -> None:
        self.mechanism, self.analysis, self.data, self.validation, self.kin = mechanism, analysis, data, validation, kin
        self.n_blocks, self.seed = n_blocks, seed


def _candidate_names(data, candidates) -> list:
    """The candidate effect names (the library and plug-ins by default), checked; the data must state a noise."""
    if data.noise is None:
        raise DataError(f"{data.source}: the diagnosis needs the header line '# noise: A mm + B mm/m' (the tracker's "
                        f"noise model) to tell a gap from noise.")
    known = available_effects()
    names = list(known if candidates is None else candidates)
    for c in names:
        if not is_known_effect(c):
            raise DataError(f"unknown effect '{c}'; effects are {', '.join(known)} and angle-harmonic-<k> for any "
                            f"positive k.")
    return names


def _diagnose(mechanism, analysis, data, validation, candidates, kinematics, n_blocks, seed, max_effects,
              progress, per_target=True, pooled_choice=True) -> Diagnosis:
    """Body of :func:`diagnose` (BLAS single-threaded by the caller): the steps in order.  ``pooled_choice`` false
    (each target alone, for the per-target check): an over-fitting answer is not followed by the pooled choice of an
    effect (:func:`_held_out_answer`), which is the whole file's decision and costs a fit per candidate."""
    t0 = time.perf_counter()
    step = progress or (lambda _name: None)
    names = _candidate_names(data, candidates)
    run = _Run(mechanism, analysis, data, validation, kinematics or Kinematics(mechanism), n_blocks, seed)
    step("rigid fit")
    run.rigid = identify(mechanism, analysis, data, validation, kinematics=run.kin, outlier_probe=False)
    run.test = gap_test(run.rigid, data, validation)
    run.significant = run.test.pop("significant")
    run.cannot_size = _cannot_size(mechanism, names)
    wrong = inputs_wrong(run.rigid, run.kin.length_scale)
    if wrong is not None:  # a wrong joint map or unit is no missing effect: say so, try nothing
        outcome, words = verdict(data, validation, True, run.test, None, [], {}, None, {}, run.rigid.noise_rms, None,
                                 [], [], run.cannot_size, None, wrong)
        where = {"regions": [], "direction_rms": {}, "explained_by": [], "spectra": [], "revolute_spectra": []}
        return Diagnosis(True, run.test, where, [], [], [], {}, run.rigid.validation, None, None, {}, [], None,
                         run.rigid, None, time.perf_counter() - t0, outcome, words, [], [], run.cannot_size, {})
    step("where")
    _rows_and_screen(run)
    run.weak = bool(pooled_choice and validation is not None and run.rigid.rank * FEW_EQUATIONS > 3 * len(run.screen.w))
    options = {}
    if candidates is None:  # the periodic orders the spectrum shows join the candidates
        for name, spec in spectral_candidates(run.plain, run.rows, run.act_jac).items():
            names.append(name)
            options[name] = {"joints": spec["joints"]}
    if "screw-periodic" in names and run.plain["spectra"]:  # a screw's period from its spectrum, not the lead
        period = screw_period(run.plain, run.rows, run.act_jac, screw_lead(mechanism)[0])
        if period is not None:
            options["screw-periodic"] = {"lead": period}
    step("candidates")
    _screen_candidates(run, names, options)
    step("selection")
    _select(run, max_effects)
    step("nonlinear fit")
    overruled = _cv_overruled(run)
    _shrink(run, confirm=True if overruled else None)
    step("verdict")
    diag = _answer(run)
    if overruled and diag.named_effects == [overruled["effect"]]:
        diag.verdict["cv_overruled"] = overruled
        diag.verdict["evidence"] += (
            f"; confidence low: {overruled['effect']} (joint {overruled['joint']}) was taken although the blocked "
            f"cross-validation of the identification poses refused it (CV RMS {1000 * overruled['cv_rms_with']:.1f} "
            f"µm with it against {1000 * overruled['cv_rms_rigid']:.1f} µm rigid: with these poses its folds "
            f"extrapolate): the structure tests locate it (it is what 'where' names, BIC {overruled['delta_bic']:+.0f}) "
            f"and the held-out poses confirm its prediction")
    # too few identification poses: the gap tests are weak (the held-out poses' predictions are uncertain, the
    # identification residuals bent around a missing effect), and the identification poses cannot choose; all the
    # poses pooled choose (:mod:`.held_out`), after an over-fitting answer whose held-out excess is beyond the fitted
    # model's uncertainty, and after a passing gap test or an excess without structure on so few poses (the F-test
    # is the same whatever the noise's scale)
    if pooled_choice and validation is not None and getattr(run, "pool", None) and (
            (diag.outcome == "over-fitting" and diag.verdict.get("effect_not_excluded"))
            or (diag.outcome in ("no significant gap", "understated noise") and run.weak)):
        step("held-out choice")
        diag = _held_out_answer(run) or _pooled_nothing(diag, run)
    checks = targets_to_check(data, validation) if per_target else []
    if checks:
        step("per target")
        diag.per_target = per_target_check(
            lambda d, v: _diagnose(mechanism, analysis, d, v, candidates, run.kin, n_blocks, seed, max_effects, None,
                                   per_target=False, pooled_choice=False), checks)
        whole = {"outcome": diag.outcome, "named_effects": diag.named_effects,
                 "equivalence_sets": diag.equivalence_sets, "effect_joints": diag.effect_joints}
        diag.targets_agree, diag.targets_evidence = targets_agree(whole, diag.per_target)
        if diag.verdict.get("targets_differ"):  # the whole file's residuals already say one target differs
            diag.targets_agree = False
            diag.targets_evidence = "the targets disagree: " + diag.verdict["targets_differ"]
        if not diag.targets_agree and "evidence" in diag.verdict and not diag.verdict.get("targets_differ"):
            diag.verdict["targets_disagree"] = diag.targets_evidence
            diag.verdict["evidence"] += (f"; {diag.targets_evidence} (confidence low: check the targets' offsets and "
                                         f"measure again before acting on this answer)")
    diag.elapsed = time.perf_counter() - t0
    return diag


def _rows_and_screen(run: _Run) -> None:
    """Step 2: the rows, their Jacobians at the rigid fit, the screening set-up and the plain structure tests."""
    rigid, data = run.rigid, run.data
    six_d = oriented(rigid.model, data)
    run.rows = row_view(data, six_d)  # one row per position, and per orientation for 6-D data
    run.k = k = len(data)
    schemes = folds(run.rows, run.n_blocks, run.seed)
    resid, w, base_jac, full, run.act_jac, run.target_jac, base_idx = _rigid_rows(run.mechanism, run.analysis,
                                                                                   run.kin, rigid, data)
    run.at_rigid = _at_rigid(run.kin, rigid, full)
    units, kinds = rigid.model.units, rigid.model.kinds
    prior = np.array([(PRIOR_ANGLE if units[j] == "rad" else PRIOR_LENGTH) if kinds[j] == "geometry" else 1e3
                      for j in base_idx])
    cv_scale = None
    if six_d:  # orientation rows count in the cross-validated RMS at the lever where both noises are alike
        cv_scale = stack_rows(np.ones(k), np.full(k, float(np.median(1.0 / w[:k])) / data.rotation_noise))
    run.screen = Screen(w, resid, base_jac, prior, schemes, full.q, cv_scale=cv_scale)
    run.r_trk, _ = rigid.model.tracker_pose(rigid.theta)
    run.base_cv, run.base_bic, _, _ = cv_rms(run.screen, None, None)
    run.plain = structure_tests(run.mechanism, run.rows, resid, w, run.screen.prepared()["qb"], run.r_trk,
                                run.act_jac, run.target_jac, positions=k)


def _screen_candidates(run: _Run, names: list, options: dict) -> None:
    """Step 3: every candidate scored and checked; the structure tests with their signatures; where."""
    data, screen = run.data, run.screen
    run.not_applicable = {k: v for k, v in applicable_effects(run.mechanism, run.analysis, data).items()
                          if k in names}
    scr = screen_candidates(run.mechanism, run.analysis, run.kin, run.rigid, data, screen, run.act_jac, run.base_cv,
                            run.base_bic, names, run.not_applicable, options, with_atoms=False,
                            at_rigid=run.at_rigid)
    run.ranking, run.columns, run.effects = scr["ranking"], scr["columns"], scr["effects"]
    run.rejected, run.violated, run.atoms = scr["rejected"], scr["violated"], scr["atoms"]
    run.options = options
    signatures = {e["effect"]: run.columns[e["effect"]][0] for e in run.ranking if not e.get("note")}
    stand = stand_motion_family(data, run.at_rigid["world"], run.r_trk, len(screen.w))
    if stand is not None:  # the stand or the tracker moving with time: structure, never noise
        signatures[STAND_MOTION] = stand
    run.structure = structure_tests(run.mechanism, run.rows, screen.resid, screen.w, screen.prepared()["qb"],
                                    run.r_trk, run.act_jac, run.target_jac, signatures, positions=run.k)
    run.where = where_summary(run.rigid, data, screen.schemes[0][1][:run.k], run.structure)
    # the structure tests are a second, scale-free gap test: under a right model they hold at
    # 1e-3 whatever the noise, so a structured residual is a gap even below the chi-square's power
    st = run.structure
    run.test["structure"] = {"p_value": st["best"]["p_value"] if st["best"] else 1.0, "threshold": st["threshold"],
                             "tests": st["n_tests"]}
    if st["structured"] and not run.significant:
        run.significant = True
        run.test["significant_by"] = "structure"
    if not st["targets_homogeneous"]:  # one reflector's residuals larger than the others': a gap the noise is not
        run.test["targets"] = {k: st["targets"][k] for k in ("p_value", "factors", "worst")}
        if not run.significant:
            run.significant = True
            run.test["significant_by"] = "targets"


def _select(run: _Run, max_effects: int) -> None:
    """Step 3: forward selection, joint by joint then grouped (:mod:`.selection`); periodic effects and scale errors
    pass the spectrum's gate when they are added, and a periodic one the spectrum refuses is replaced by the order at
    the spectrum's peak on that joint."""
    pool = {}
    for e in run.ranking:
        eff = run.effects[e["effect"]]
        pool[e["effect"]] = {"entry": e, "columns": run.columns[e["effect"]], "effect": eff,
                             "joints": list(eff.param_joints) if is_jointwise(e["effect"]) and
                             hasattr(eff, "param_joints") else None}
    if run.significant or run.weak:  # the per-joint candidates (a gap needs them, and a pooled choice may)
        from hyperstat.solver.diagnosis.screening import make_atom

        for e in run.ranking:
            eff, name = run.effects[e["effect"]], e["effect"]
            if not (is_library_effect(name) and is_jointwise(name) and hasattr(eff, "param_joints")):
                continue
            joints = list(dict.fromkeys(eff.param_joints))
            kw = dict(run.options.get(name, {}))
            for joint in joints if len(joints) > 1 else []:
                run.atoms[atom_key(name, joint)] = make_atom(run.screen, run.mechanism, run.analysis, run.data, name,
                                                             eff, run.columns[name], joint, kw, run.rigid.rank,
                                                             run.base_bic)
    for key, atom in run.atoms.items():
        pool[key] = {"entry": atom["entry"], "columns": atom["columns"], "effect": atom["effect"], "joints": None}
    run.pool = pool

    def gated(name: str) -> bool:
        return harmonic_order(name) is not None or name == "angle-scale"

    def field_after(chosen: list):
        """The rigid residual projected off the geometry and the candidates ``chosen`` (None: nothing chosen)."""
        if not chosen:
            return None
        ew = run.screen.weighted(np.concatenate([pool[k]["columns"][0] for k in chosen], axis=2))
        both = np.concatenate([run.screen.prepared()["jw"], ew], axis=1)
        basis, _ = np.linalg.qr(both / np.linalg.norm(both, axis=0).clip(min=1e-300))
        return ResidualField(run.screen.resid, run.screen.w, basis)

    run.aliased = {}

    def refuse(key: str, chosen: list = ()) -> dict | None:
        name, _ = split_key(key)
        if not gated(name):
            return None
        field = field_after([k for k in chosen if k != key])
        why = periodic_gate(name, pool[key]["effect"], pool[key]["entry"], run.plain, run.rows, run.act_jac, field)
        run.aliased.pop(key, None)
        if why is not None and why.get("alias") and why.get("joint"):
            # the joint's error is periodic and its order one of two the range cannot tell apart: the candidate is
            # taken, and the answer names both orders as a set, with low confidence and the separating range
            a = run.data.joints.index(why["joint"])
            orders = aliased_orders(why, field or run.plain["field"], run.act_jac[:, :, a], run.rows.q[:, a])
            if orders is not None:
                run.aliased[key] = {**why, "orders": orders}
                return None
        if why is not None and why.get("alias") is not None and why.get("joint"):
            # a smooth trend of the joint fits as well: a curved error of that joint over the range it moved, which
            # the low periodic orders all read; taken with those orders as its set, low confidence, and the answer
            # says a smooth error outside the library fits as well
            a = run.data.joints.index(why["joint"])
            orders = smooth_orders(why, field or run.plain["field"], run.act_jac[:, :, a], run.rows.q[:, a])
            if orders is not None:
                run.aliased[key] = {**why, "orders": orders, "trend": True}
                return None
        if why is not None:
            why = {**why, "effect": name, "candidate": key}
        return why

    def replace(key: str, why: dict, chosen: list = ()) -> str | None:
        """The order at the spectrum's peak on the refused candidate's joint, screened as a new candidate."""
        if why.get("alias") is not None or why.get("peak_cycles_per_revolution") is None or not why.get("joint"):
            return None
        joint = why["joint"]
        a = run.data.joints.index(joint)
        order, _ = refined_order(field_after(list(chosen)) or run.plain["field"], run.act_jac[:, :, a],
                                 run.rows.q[:, a], why["peak_cycles_per_revolution"])
        spec = next((sp for sp in run.plain["revolute_spectra"] if sp["joint"] == joint), None)
        if spec is None or order <= 0 or (order not in (1.0, 2.0)
                                          and order < min(spec["resolution_cycles_per_revolution"], 1.0)):
            return None  # 1 and 2 always (the library's orders); below 1 and the resolution, a trend (the gate
            # asks the data to establish an order of 1 or more seen over less than one period)
        name = harmonic_name(order)
        new = atom_key(name, joint)
        if new == key or new in pool:
            return new if new != key else None
        return _add_atom(run, name, joint)

    run.pool_add = lambda name, joint: _add_atom(run, name, joint)
    if run.significant:
        peaks = tuple(sp["joint"] for sp in run.plain["revolute_spectra"] if sp["peak_p_value"] < run.plain["threshold"])
        # located: at the threshold of the structure tests with the candidates' signatures (the stricter), so that a
        # located candidate is always a structured residual: never a campaign answered "no significant gap" or
        # "understated noise" (both need no structure)
        strict = run.structure["threshold"]
        spiked = tuple(sp["joint"] for sp in run.plain["revolute_spectra"] if sp["peak_p_value"] < strict)
        screws = tuple(sp["joint"] for sp in run.plain["spectra"] if sp["peak_p_value"] < strict)
        signed = _significant_signatures(run)
        best = run.structure["best"] or {}

        def headline(name: str, joint: str) -> bool:
            """Whether the most significant structure test (what ``where`` names) is this joint's periodic error or
            this effect's signature: a weak periodic error is not named beside a larger structure it does not
            explain (an out-of-library coupling of joint 4 with joint 5 shows a 2/rev peak on joint 4 too)."""
            if best.get("family") == "candidate signature":
                return best.get("variable") == name
            return best.get("family") == "joint error" and best.get("kind") == "periodic" and best.get("joint") == joint

        def located(key: str) -> bool:
            """A periodic error of a joint whose residual spectrum has a significant peak, or of an effect whose
            signature test is significant (the structure tests'), that peak or test being what ``where`` names."""
            name, joint = split_key(key)
            periodic = harmonic_order(name) is not None or name == "screw-periodic"
            return joint is not None and periodic and headline(name, joint) and (
                name in signed or (joint in spiked if name != "screw-periodic" else joint in screws))

        sel = forward_selection(run.screen, pool, run.base_cv, run.base_bic, max_effects, refuse, replace, peaks,
                                located)
        run.located, run.refuse = located, refuse
    else:
        sel = {"selected": [], "joints": {}, "columns": {}, "keys": [], "steps": [], "refused": [], "ties": [],
               "pruned": []}
    # a grouped periodic effect: every joint of its group passes the gate on its own, given the other effects
    for name in list(sel["selected"]):
        joints = sel["joints"].get(name)
        if not gated(name) or not joints or len(joints) < 2:
            continue
        others = [k for k in sel["keys"] if split_key(k)[0] != name]
        for joint in list(joints):
            key = atom_key(name, joint)
            if key not in pool:
                key = _add_atom(run, name, joint)
            why = refuse(key, others) if key else None
            if why is not None:
                sel["refused"].append(why)
                joints.remove(joint)
        if not joints:
            sel["selected"].remove(name)
        else:
            idx = [j for j in joints]
            per = [pool[atom_key(name, j)]["columns"] for j in idx]
            sel["columns"][name] = (np.concatenate([c for c, _ in per], axis=2), np.concatenate([p for _, p in per]))
    run.selected, run.ties = sel["selected"], sel["ties"]
    run.rejected += sel["refused"]
    run.order_sets = {split_key(k)[0]: run.aliased[k] for k in sel["keys"] if k in run.aliased
                      and split_key(k)[0] in run.selected}
    run.selection_steps, run.pruned = sel["steps"], sel["pruned"]
    run.below_guard = [st for st in sel["steps"] if st.get("below_guard")]
    run.effect_joints = {n: list(j) for n, j in sel["joints"].items() if j and n in run.selected}
    run.selected_columns = {n: sel["columns"][n] for n in run.selected}
    for name in run.selected:  # the named effect on the joints of its group
        joints = run.effect_joints.get(name)
        whole = run.effects.get(name)
        if joints and (whole is None or list(dict.fromkeys(getattr(whole, "param_joints", []))) != joints):
            run.effects[name] = _effect_on(run, name, joints)
        elif whole is None:
            run.effects[name] = pool[atom_key(name, joints[0])]["effect"] if joints else None
    for entry in run.ranking:  # the per-joint candidates, beside their whole effect
        parts = [a["entry"] for k, a in pool.items() if split_key(k)[0] == entry["effect"] and split_key(k)[1]]
        if parts:
            entry["per_joint"] = [{"joint": split_key(p["effect"])[1], "criterion": p["criterion"],
                                   **({"rejected": p["rejected"]} if p.get("rejected") else {})} for p in parts]


def _cv_overruled(run: _Run) -> dict | None:
    """Nothing selected, a gap with structure, and a library periodic effect on one joint that the structure tests
    locate (what ``where`` names: the joint's spectral peak at its order) lowers the BIC by :data:`BIC_DROP` but not
    the blocked cross-validated RMS: with some pose designs (poses in clusters at the workspace's corners) a fold
    left out is an extrapolation, and the blocked cross-validation refuses what the data establish.  The candidate
    with the lowest BIC is then put to the held-out poses, which must confirm its prediction
    (:func:`.validation_confirms`, in the nonlinear fit); the answer says so, with low confidence.  Returns the
    record of the candidate tried (``run.selected`` set to it), or None."""
    if run.selected or not run.significant or run.validation is None or not len(run.validation) \
            or not run.structure.get("structured") or getattr(run, "located", None) is None:
        return None
    trials = []
    for key, cand in run.pool.items():
        name, joint = split_key(key)
        entry = cand["entry"]
        if joint is None or cand["effect"] is None or entry.get("rejected") or "bounded_estimates" in entry \
                or entry.get("note") or entry.get("criterion") is None or entry["criterion"] > -BIC_DROP:
            continue
        if not run.located(key) or run.refuse(key, []) is not None:
            continue
        trials.append((entry["criterion"], key))
    if not trials:
        return None
    _, key = min(trials)
    name, joint = split_key(key)
    cand = run.pool[key]
    cv, _, _, _ = cv_rms(run.screen, cand["columns"][0], cand["columns"][1])
    if cv <= CV_DROP * run.base_cv:  # the cross-validation did not refuse it: not this rule's case
        return None
    run.selected, run.effects[name] = [name], cand["effect"]
    run.selected_columns = {name: cand["columns"]}
    run.effect_joints = {name: [joint]}
    if key in run.aliased:  # its order is one of several the joint's range cannot tell apart: named as their set
        run.order_sets = {name: run.aliased[key]}
    return {"effect": name, "joint": joint, "delta_bic": float(cand["entry"]["criterion"]), "cv_rms_with": float(cv),
            "cv_rms_rigid": float(run.base_cv)}


def _effect_on(run: _Run, name: str, joints: list):
    """Effect ``name`` built on ``joints`` only (the options its candidate was screened with)."""
    kw = {k: v for k, v in run.options.get(name, {}).items() if k != "joints"}
    if name in ("guide-straightness",):
        kw["kin"] = run.kin
    return make_effect(name, run.mechanism, run.analysis, run.data, joints=list(joints), **kw)


def _add_atom(run: _Run, name: str, joint: str) -> str | None:
    """Screen ``name`` on ``joint`` alone as a new candidate of the pool (a periodic order from the spectrum)."""
    from hyperstat.solver.diagnosis.screening import effect_columns

    key = atom_key(name, joint)
    if key in run.pool:
        return key
    try:
        effect = _effect_on(run, name, [joint])
    except DataError:
        return None
    cols, prior = effect_columns(run.mechanism, run.analysis, run.kin, run.rigid, run.data, effect, run.screen.q,
                                 run.act_jac, run.at_rigid)
    if not np.any(cols):
        return None
    entry = score_entry(run.screen, key, effect, cols, prior, run.rigid.rank, run.base_bic, cross_validate=False)
    if entry.get("rejected"):
        run.rejected.append({"effect": name, "stage": "screening", "reason": entry["rejected"], "candidate": key})
    run.pool[key] = {"entry": entry, "columns": (cols, prior), "effect": effect, "joints": None}
    return key


def _pooled_fit(run: _Run, pooled: MeasurementSet, effects: tuple) -> dict | None:
    """A fit of the geometry (and ``effects``) on the pooled rows: its chi-square, degrees of freedom and rank (None:
    no converged fit within the effects' physical domains, or more unknowns than equations).

    The nominal model's error (``identify(nominal=...)``, a second fit of the tracker frame on the nominal geometry)
    is not computed: nothing here reads it, and without held-out poses no finding depends on it (a fifth of the
    pooled choice's time on the hexapod)."""
    try:
        with plugin_guard(effects[0].name if effects else "rigid", "fit"):
            fit = identify(run.mechanism, run.analysis, pooled, None, effects=effects, kinematics=run.kin,
                           outlier_probe=False, nominal=False)
    except DataError:
        return None
    if not fit.converged or _implausible(fit) is not None:
        return None
    test = gap_test(fit, pooled, None)["identification"]
    return {"chi2": test["chi2"], "dof": test["dof"], "rank": fit.rank}


def _pooled_nothing(diag: Diagnosis, run: _Run) -> Diagnosis:
    """The answer after a pooled choice that named nothing: a candidate it found but could not fit or answer is
    reported (``verdict.held_out_found``, any outcome); else a ``no significant gap`` on too few poses says its tests
    are weak (``verdict.few_equations``)."""
    found = getattr(run, "held_out_found", None)
    if found is not None:  # the pooled F-test found a candidate that could not be fitted or answered after all
        diag.verdict["held_out_found"] = found
        diag.verdict["evidence"] += (
            f"; confidence low: on all the poses pooled (identification and held-out) {found['chosen']} passes an "
            f"F-test against the geometry alone (F = {found['f']:.3g}, p = {found['p_value']:.2g}, family-wise 1 %), "
            f"but {found['why']}: a missing effect is not excluded; measure more poses spread over the workspace "
            f"and diagnose again")
    elif diag.outcome == "no significant gap":
        diag.verdict["few_equations"] = {"rank": run.rigid.rank, "equations": 3 * len(run.screen.w)}
        diag.verdict["evidence"] += (
            f"; with {run.rigid.rank} parameters for {3 * len(run.screen.w)} equations these tests are weak, and no "
            f"candidate fitted with the geometry on all the poses pooled (identification and held-out) passes an "
            f"F-test against the geometry alone at the family-wise 1 %")
    return diag


def _held_out_answer(run: _Run) -> Diagnosis | None:
    """An ``over-fitting`` answer whose held-out excess a missing effect may explain: the identification and the
    held-out poses are pooled, every candidate of the pool not refused at screening is fitted with the geometry on
    them, and an F-test of each against the rigid fit chooses at the family-wise 1 % (:mod:`.held_out`); the chosen
    one is named with the others that fit alike, confidence low (:func:`.held_out.held_out_words`).  None when no
    candidate passes, or the two files cannot be pooled."""
    pooled = joined(run.data, run.validation)
    rigid = _pooled_fit(run, pooled, ()) if pooled is not None else None
    if rigid is None:
        return None
    keys = [k for k, c in run.pool.items() if c["effect"] is not None and not c["entry"].get("note")
            and not c["entry"].get("rejected")]
    trials = []
    for key in keys:
        fit = _pooled_fit(run, pooled, (run.pool[key]["effect"],))
        trials.append(None if fit is None else nested_f_test(key, rigid, fit))
    choice = held_out_choice(trials)
    if choice is None:
        return None
    name, joint = split_key(choice["chosen"])
    cand = run.pool[choice["chosen"]]
    run.selected, run.effects[name] = [name], cand["effect"]
    run.selected_columns = {name: cand["columns"]}
    run.effect_joints = {name: [joint]} if joint else {}
    run.order_sets, run.below_guard = {}, []
    run.held_out_found = {"chosen": choice["chosen"], "f": choice["best"]["f"], "p_value": choice["best"]["p_value"]}
    try:
        _shrink(run, confirm=False)
    except DataError:  # more unknowns than the identification poses' equations once the effect is added
        run.held_out_found["why"] = "the identification poses alone are too few to fit it with the geometry"
        return None
    if not run.selected:  # the nonlinear fit refused it after all (its domain, or a worse validation RMS)
        run.held_out_found["why"] = "the fit on the identification poses refused it (its physical domain, or a " \
                                    "worse held-out error)"
        return None
    passed, run.significant = run.significant, True  # the pooled F-test found the gap the weak gap tests missed
    diag = _answer(run)
    run.significant = passed
    if diag.outcome not in ("explained", "partly explained") or "evidence" not in diag.verdict:
        run.held_out_found["why"] = f"the answer with it fitted is '{diag.outcome}'"
        return None
    if not passed:
        diag.verdict["evidence"] += (f"; the gap tests on the identification and the held-out poses apart passed "
                                     f"(identification p = {run.test['identification']['p_value']:.2g}, validation p "
                                     f"= {run.test['validation']['p_value']:.2g}), weak with so few poses: the F-test "
                                     f"on all the poses pooled found it")
    alike = list(dict.fromkeys(split_key(k)[0] for k in choice["alike"] if split_key(k)[0] != name))
    if alike:
        s = next((st for st in diag.equivalence_sets if st["effect"] == name), None)
        if s is None:
            s = {"effect": name, "members": [name], "separating_measurement": "", "evidence": []}
            diag.equivalence_sets.append(s)
        s["members"] += [a for a in alike if a not in s["members"]]
        way = "more poses spread over the workspace (all the poses fit them alike)"
        s["separating_measurement"] = "; ".join(w for w in (s["separating_measurement"], way) if w)
        diag.verdict["evidence"] += f"; all the poses fit {', '.join(alike)} alike"
    diag.verdict["held_out_choice"] = {k: choice[k] for k in ("chosen", "alike", "threshold", "tried", "confirmed")}
    diag.verdict["held_out_choice"].update(f=choice["best"]["f"], p_value=choice["best"]["p_value"],
                                           poses_pooled=pooled.n_poses)
    diag.verdict["evidence"] += held_out_words(choice, run.rigid.rank, 3 * len(run.screen.w), pooled.n_poses)
    return diag


def _shrink(run: _Run, confirm: bool | None = None) -> None:
    """Step 4: the nonlinear fit with the selected effects, their estimates, how far the gap shrinks (``confirm``:
    whether the held-out poses must confirm them; default: when the rigid residuals show no structure)."""
    rigid, screen, columns = run.rigid, run.screen, run.columns
    confirm = not run.structure["structured"] if confirm is None else confirm
    run.final, run.selected = _nonlinear_fit(run.mechanism, run.analysis, run.kin, run.data, run.validation,
                                             run.selected, run.effects, rigid.validation, run.rejected, run.ranking,
                                             rigid, confirm=confirm)
    current_cv = run.base_cv
    if run.selected:
        chosen = run.selected_columns
        extra = np.concatenate([chosen[n][0] for n in run.selected], axis=2)
        current_cv, _, _, _ = cv_rms(screen, extra, np.concatenate([chosen[n][1] for n in run.selected]))
    run.effect_parameters, run.validation_after = [], None
    if "violated-constraint" not in run.selected:
        run.violated = None
    if run.final is not None:
        run.validation_after = run.final.validation
        for p in run.final.parameters:
            if p["kind"].startswith("effect:"):
                run.effect_parameters.append({"effect": p["kind"][7:], **{k: p[k] for k in (
                    "name", "unit", "estimate", "std", "identifiable")}})
        if run.violated is not None:
            est = next(p for p in run.final.parameters if p["name"] == f"violated_{run.violated['defect']}")
            run.violated.update({"estimate": est["estimate"], "std": est["std"], "unit": est["unit"],
                                 "times_realistic": abs(est["estimate"]) / run.violated["realistic_magnitude"]})
    noise, before = rigid.noise_rms, rigid.validation
    run.share = None
    reference = before["rms"] if before else run.base_cv
    if run.validation_after is not None and noise is not None and reference**2 > noise**2:
        run.share = float((reference**2 - run.validation_after["rms"] ** 2) / (reference**2 - noise**2))
    run.ceiling = _ceiling(screen.resid[:run.k], run.data, folds(run.data, run.n_blocks, run.seed), run.base_cv,
                           current_cv, run.seed)
    for entry in run.ranking:
        entry["validation_rms"] = entry["cv_rms"]  # blocked cross-validation on the identification data


def _answer(run: _Run) -> Diagnosis:
    """Steps 4 and 5: the structure left after the effects, the equivalence sets, the outcome in words."""
    screen, final, selected = run.screen, run.final, run.selected
    columns = dict(run.columns)
    columns.update({n: c for n, c in run.selected_columns.items() if n in selected})
    after_structure, sets = None, []
    if final is not None:
        ew = screen.weighted(np.concatenate([columns[n][0] for n in selected], axis=2))
        both = np.concatenate([screen.prepared()["jw"], ew], axis=1)
        basis, _ = np.linalg.qr(both / np.linalg.norm(both, axis=0).clip(min=1e-300))
        r_f, _ = final.model.tracker_pose(final.theta)
        others = {e["effect"]: columns[e["effect"]][0] for e in run.ranking
                  if not e.get("note") and e["effect"] not in selected}
        resid_f, _, _, _ = residual_rows(final.model, final.theta, run.data, q_start=final.configurations)
        after_structure = structure_tests(run.mechanism, run.rows, resid_f, screen.w, basis, r_f, run.act_jac,
                                          run.target_jac, others, positions=run.k)
        masses = gravity_source(run.mechanism) == "link masses"
        family = gravity_family(run.mechanism, run.kin, run.data, run.act_jac, masses)
        refused = {r["effect"] for r in run.rejected if r["stage"] in ("screening", "nonlinear fit", "validation")}
        members = [e["effect"] for e in run.ranking if not e.get("note") and e["effect"] not in refused]
        pairs = LinkBending(run.mechanism, run.kin).pairs if masses and "compliance" in selected else {}
        bending = bending_alternatives(run.mechanism, run.kin, run.data, run.act_jac, pairs) if "compliance" in selected else []
        stand = stand_motion_family(run.data, run.at_rigid["world"], run.r_trk, len(screen.w))
        declared = gravity_source(run.mechanism) is not None  # link masses or a parallel machine's moving mass
        legs = leg_offset_family(run.mechanism, run.data, run.act_jac)
        sets = equivalence_sets(screen, selected, columns, members, family, run.data, spectrum_peaks(run.plain),
                                run.effects, declared, bending, stand, legs)
        _order_sets(run, selected, sets)
    overfit = overfitting(run.test, run.rigid, 3 * len(screen.w),
                          run.structure["structured"] or not run.structure["targets_homogeneous"])
    outcome, words = verdict(run.data, run.validation, run.significant, run.test, final, selected, run.structure,
                             after_structure, run.ceiling, run.rigid.noise_rms, run.share, sets, run.rejected,
                             run.cannot_size, overfit, None)
    left = after_structure if outcome in ("explained", "partly explained") and after_structure else run.structure
    if not left["targets_homogeneous"] and "evidence" in words:  # one reflector tells another story
        words["targets_differ"] = targets_words(left["targets"])
        if outcome in ("explained", "partly explained"):
            words["evidence"] += f"; confidence low: what remains is in {words['targets_differ']}"
    screw = run.effects.get("screw-periodic") if "screw-periodic" in selected else None
    if screw is not None and outcome in ("explained", "partly explained") and "evidence" in words:
        lead, declared = screw_lead(run.mechanism)  # the order in turns of the screw, stated
        order = screw_order(screw.lead, lead)
        words["screw_order"] = {"cycles_per_turn": order, "period_mm": screw.lead, "lead_mm": lead,
                                "lead_declared": declared}
        words["evidence"] += (f"; screw-periodic at {order:g} cycle{'' if order == 1 else 's'} per turn of the screw "
                              f"(period {screw.lead:g} mm, lead {lead:g} mm"
                              + ("" if declared else ", assumed: the model declares no metadata.screw_lead") + ")")
    if "leg-thermal" in selected and outcome in ("explained", "partly explained") and "leg-thermal" in run.columns:
        _leg_thermal_words(run, words, sets, [columns[n][0] for n in selected if n != "leg-thermal"])
    unsettled = [run.order_sets[n] for n in selected if n in getattr(run, "order_sets", {})]
    if unsettled and outcome in ("explained", "partly explained") and "evidence" in words:
        words["order_not_established"] = [{k: u[k] for k in ("effect", "joint", "orders", "range_rad")}
                                          for u in unsettled]
        for u in unsettled:
            words["order_not_established"][unsettled.index(u)]["smooth_trend_fits"] = bool(u.get("trend"))
        words["evidence"] += "".join(
            f"; confidence low: a periodic error of joint {u['joint']} fits, but over the {u['range_rad']:.2g} rad it "
            f"moved {_cycles_words(u['orders'])} per revolution fit alike"
            + (f", and so does a smooth (quadratic) error of joint {u['joint']} that no library effect describes: "
               f"what is established is a curved error of joint {u['joint']} over that range, and its compensation "
               f"holds within that range only" if u.get("trend") else "")
            + f"; moving joint {u['joint']} over more than {_separating_range(u['orders']):.2g} rad would tell them "
              f"apart" + (f" (more than a revolution: if joint {u['joint']}'s travel is shorter, no pose design can, "
                          f"and a bench measurement of its transmission error would)"
                          if _separating_range(u["orders"]) > 2.0 * np.pi else "")
            for u in unsettled)
    if run.significant and outcome in ("explained", "partly explained") and "evidence" in words \
            and getattr(run, "below_guard", None):
        info, text = below_guard_words(run.below_guard, selected,
                                       {st["added"]: _located_peak(run, *split_key(st["added"])) for st in run.below_guard})
        if info:
            words["below_guard"] = info
            words["evidence"] += text
    if outcome == "unexplained" and run.significant and "evidence" in words:
        seen = _library_effect_seen(run)
        if seen is not None:
            words["library_effect_seen"] = seen
            words["evidence"] += seen_words(seen)
    moved = [s["effect"] for s in sets if STAND_MOTION in s["members"]]
    if moved and outcome in ("explained", "partly explained"):
        words["stand_motion"] = moved
        words["evidence"] += (f"; confidence low: {' and '.join(moved)} cannot be told from the machine's stand moving "
                              f"relative to the floor during the campaign (the same relative motion of the base and "
                              f"the tracker); {STAND_MOTION_WORDS} would separate them")
    return Diagnosis(run.significant, run.test, run.where, run.ranking, selected, run.ties, run.not_applicable,
                     run.rigid.validation, run.validation_after, run.share, run.ceiling, run.effect_parameters,
                     run.violated, run.rigid, final, 0.0, outcome, words, run.rejected, sets, run.cannot_size,
                     spectrum_peaks(run.plain), effect_joints={n: j for n, j in run.effect_joints.items()
                                                               if n in selected},
                     selection_steps=run.selection_steps, pruned=run.pruned)


def _significant_signatures(run: _Run) -> dict:
    """Library effect -> its significant signature test among the structure tests of the rigid residual (the effect's
    columns fitted in sample, F-test below the structure tests' threshold)."""
    st = run.structure
    return {t["variable"]: t for t in st["tests"] if t["family"] == "candidate signature"
            and t["p_value"] < st["threshold"] and is_library_effect(t["variable"])}


def _located_peak(run: _Run, name: str, joint: str | None) -> dict:
    """The significant peak of the rigid residual's spectrum that locates a periodic candidate on ``joint``, else its
    effect's significant signature test ({} when none)."""
    thr = run.structure["threshold"]
    for sp in run.plain["revolute_spectra"]:
        if sp["joint"] == joint and sp["peak_p_value"] < thr:
            return {"joint": joint, "p_value": sp["peak_p_value"], "share": sp["peak_share"], "revolute": True,
                    "order": sp["peak_cycles_per_revolution"], "range_rad": sp["range_rad"]}
    for sp in run.plain["spectra"]:
        if sp["joint"] == joint and sp["peak_p_value"] < thr:
            return {"joint": joint, "p_value": sp["peak_p_value"], "share": sp["peak_share"], "revolute": False,
                    "period_mm": sp["peak_period_mm"], "range_rad": None}
    test = _significant_signatures(run).get(name)
    if test is not None:
        a = run.data.joints.index(joint) if joint in run.data.joints else None
        revolute = a is not None and run.mechanism.joints[run.mechanism.actuated[a]].type == "R"
        return {"joint": joint, "p_value": test["p_value"], "share": test["share"], "revolute": revolute,
                "signature": name, "range_rad": float(np.ptp(run.rows.q[:, a])) if revolute else None}
    return {}


def _library_effect_seen(run: _Run) -> dict | None:
    """For an ``unexplained`` answer: the library's periodic effect on the joint whose residual spectrum has the most
    significant peak (``angle-harmonic-<k>`` at the peak's order, or ``screw-periodic`` at the screw's period), its
    cross-validated RMS and BIC with it, why it was not taken and what would settle it; None when no spectrum of the
    rigid residual has a significant peak, or when the data speak against that effect (:func:`_refuted`)."""
    plain, strict = run.plain, run.structure["threshold"]
    peaks = [(sp["peak_p_value"], sp["joint"], True) for sp in plain["revolute_spectra"] if sp["peak_p_value"] < strict]
    peaks += [(sp["peak_p_value"], sp["joint"], False) for sp in plain["spectra"] if sp["peak_p_value"] < strict]
    if not peaks:
        return _signature_seen(run)
    _, joint, revolute = min(peaks)
    a = run.data.joints.index(joint)
    if revolute:
        spec = next(sp for sp in plain["revolute_spectra"] if sp["joint"] == joint)
        order, _ = refined_order(plain["field"], run.act_jac[:, :, a], run.rows.q[:, a],
                                 spec["peak_cycles_per_revolution"])
        if order <= 0:
            return None
        name = harmonic_name(order)
    else:
        name = "screw-periodic"
    key = atom_key(name, joint)
    if key not in run.pool:
        key = _add_atom(run, name, joint)
    if key is None:
        return None
    cand = run.pool[key]
    cv, bic, _, _ = cv_rms(run.screen, *cand["columns"])
    gate = None
    if revolute and cand["entry"].get("rejected") is None:
        gate = periodic_gate(name, cand["effect"], cand["entry"], plain, run.rows, run.act_jac)
    return _seen(run, name, joint, cand, cv, bic, gate["reason"] if gate is not None else None, revolute)


def _signature_seen(run: _Run) -> dict | None:
    """For an ``unexplained`` answer without a significant spectral peak: the library periodic effect whose signature
    test is the most significant (a screw's error whose period the screw spectra miss), on the joint where it lowers
    the cross-validated RMS most, with the numbers of :func:`_library_effect_seen`."""
    signed = [(t["p_value"], n) for n, t in _significant_signatures(run).items()
              if harmonic_order(n) is not None or n == "screw-periodic"]
    if not signed:
        return None
    _, name = min(signed)
    keys = [k for k in run.pool if split_key(k)[0] == name and split_key(k)[1] is not None] or \
        ([name] if name in run.pool else [])
    if not keys:
        return None
    scored = sorted((cv_rms(run.screen, *run.pool[k]["columns"])[:2], k) for k in keys)
    (cv, bic), key = scored[0]
    return _seen(run, name, split_key(key)[1], run.pool[key], cv, bic, None, None)


def _seen(run: _Run, name: str, joint: str | None, cand: dict, cv: float, bic: float, gate_reason: str | None,
          revolute: bool | None) -> dict | None:
    """The record of a located library effect that was not taken (``verdict.library_effect_seen``): its peak, its
    cross-validated RMS and BIC, why it was not taken (the screening's refusal, else the spectrum's gate, else the
    guard in numbers) and what would settle it; None when the data speak against it (:func:`_refuted`).
    ``revolute`` None: read from the located peak."""
    peak = _located_peak(run, name, joint)
    drop = 1.0 - cv / run.base_cv
    if _refuted(run, name, cand, drop, bic):
        return None
    why = cand["entry"].get("rejected") or gate_reason or _guard_words(drop, bic - run.base_bic)
    revolute = peak.get("revolute", False) if revolute is None else revolute
    return {"effect": name, "joint": joint, **{k: v for k, v in peak.items() if k != "joint"},
            "cv_rms_rigid": float(run.base_cv), "cv_rms_with": float(cv), "cv_drop": round(drop, 4),
            "delta_bic": float(bic - run.base_bic), "why_not": why,
            "settling_measurement": settling_measurement(joint or "", peak.get("range_rad"), revolute)}


def _refuted(run: _Run, name: str, cand: dict, drop: float, bic: float) -> bool:
    """Whether the data speak against a located effect, so that the ``unexplained`` answer keeps its confidence: it
    does not lower the cross-validated RMS and the BIC by :data:`BIC_DROP`, its estimate leaves its physical prior
    (``bounded_estimates``: the screening's refusal), or it made the held-out validation worse (the nonlinear fit).
    What is left unsettled is only the 5 % bar or the order (the spectrum's gate)."""
    if not (drop > 0.0 and bic < run.base_bic - BIC_DROP) or "bounded_estimates" in cand["entry"]:
        return True
    return any(r["effect"] == name and r.get("stage") in ("nonlinear fit", "validation") for r in run.rejected)


def _guard_words(drop: float, delta_bic: float) -> str:
    """Why a candidate did not pass the selection's guard, in numbers."""
    if drop >= 1.0 - LOCATED_CV_DROP and delta_bic <= -BIC_DROP:
        return (f"it lowers the cross-validated RMS by {100 * drop:.1f} %, under the 5 % the selection asks of an "
                f"effect, and an effect under that bar is taken only when it is the largest structure the tests find "
                f"(here another: see where)")
    return (f"it lowers the cross-validated RMS by {100 * drop:.1f} % (the selection asks 5 % of an effect, "
            f"{100 * (1 - LOCATED_CV_DROP):.0f} % of one the structure tests locate)"
            + (f" and the BIC by {delta_bic:+.0f} (it asks -{BIC_DROP:.0f})" if delta_bic > -BIC_DROP else ""))


def _cycles_words(orders: list) -> str:
    """``1 and 2 cycles``, ``1, 2 and 3 cycles``."""
    words = [f"{o:g}" for o in orders]
    return (", ".join(words[:-1]) + " and " + words[-1] if len(words) > 1 else words[0]) + " cycles"


def _separating_range(orders: list) -> float:
    """The range of a joint (rad) over which the closest two of ``orders`` (cycles per revolution) differ by one
    cycle."""
    gaps = np.diff(sorted(orders))
    if not len(gaps):  # one order against a smooth trend: one whole period of it
        return float(2.0 * np.pi / orders[0]) if len(orders) else float("inf")
    return float(2.0 * np.pi / max(float(np.min(gaps)), 1e-12))


def _order_sets(run: _Run, selected: list, sets: list) -> None:
    """A named periodic error whose order the joint's range does not establish (:func:`.periodic.aliased_orders`):
    the other order joins its equivalence set, with the range of the joint that would separate them."""
    for name in selected:
        info = getattr(run, "order_sets", {}).get(name)
        if info is None:
            continue
        s = next((st for st in sets if st["effect"] == name), None)
        if s is None:
            s = {"effect": name, "members": [name], "separating_measurement": "", "evidence": []}
            sets.append(s)
        k = harmonic_order(name)
        others = [harmonic_name(o) for o in info["orders"] if o != k and harmonic_name(o) not in s["members"]]
        if not others:  # the equivalence check already has it, with its separating measurement
            continue
        s["members"] += others
        span = _separating_range(info["orders"])
        way = (f"poses over more than {span:.2g} rad of joint {info['joint']} ({' and '.join([name] + others)} "
               f"alias over the {info['range_rad']:.2g} rad it moved)")
        s["separating_measurement"] = "; ".join(w for w in (s["separating_measurement"], way) if w)


def _leg_thermal_words(run: _Run, words: dict, sets: list, others: list) -> None:
    """A named ``leg-thermal`` outside its physical prior (:mod:`.leg_pattern`): on some legs only, or with
    coefficients that legs growing alike cannot have.  The answer says it is a change of those legs' lengths with the
    temperature, what else reproduces it and what would separate them, and its confidence is low
    (``verdict.outside_prior``)."""
    legs = [name for _, name in prismatic_legs(run.mechanism)]
    effect = run.effects.get("leg-thermal")  # its bounds are leg-thermal's physical domain (the default without it)
    domain = {} if effect is None else {"domain": (float(effect.lower[0]), float(effect.upper[0]))}
    pattern = leg_thermal_pattern(run.screen, run.columns["leg-thermal"][0], others, legs, **domain)
    words["leg_thermal_pattern"] = pattern
    named = run.effect_joints.get("leg-thermal") or legs
    unchanged = [leg for leg in legs if leg not in named]
    if pattern["consistent"] and not unchanged:
        return
    s = "s" if len(named) > 1 else ""
    if unchanged:
        reason = (f"the whole change is on leg{s} {', '.join(named)} (leg{'s' if len(unchanged) > 1 else ''} "
                  f"{', '.join(unchanged)} unchanged), where leg-thermal predicts every leg growing with the "
                  f"temperature in proportion to its length; " + pattern["words"]
                  + ("" if not pattern["consistent"] else
                     f"; these data do not refuse legs growing alike either (p = {pattern['p_value']:.2g})"))
    else:
        reason = pattern["words"]
    alike = next((st["members"][1:] for st in sets if st["effect"] == "leg-thermal"), [])
    words["outside_prior"] = [{"effect": "leg-thermal", "reason": reason}]
    words["evidence"] += (f"; confidence low: what these data show is a change of the length of leg{s} "
                          f"{', '.join(named)} with the temperature, which leg-thermal reproduces, but outside its "
                          f"physical prior ({reason}); a seat, a joint or a mounting that moves with the temperature "
                          f"changes a leg's length the same way"
                          + (f" (the family {LEG_OFFSET} in its set)" if LEG_OFFSET in alike else
                             f"; {LEG_OFFSET_WORDS} would tell them apart"))


def _implausible(fit: IdentificationResult) -> tuple | None:
    """The first effect of a fit whose estimates leave its physical domain or prior: ``(name, why)``, or None."""
    for eff, sl in zip(fit.model.effects, fit.model._effect_slices):
        std = np.array([p["std"] if p["std"] is not None else np.inf for p in fit.parameters[sl]])
        why = eff.plausibility(fit.theta[sl], std)
        if why is not None:
            return eff.name, why
    return None


def _nonlinear_fit(mechanism, analysis, kin, data, validation, selected: list, effects: dict, before: dict | None,
                   rejected: list, ranking: list, rigid: IdentificationResult, confirm: bool = False) -> tuple:
    """Identify the selected effects with the geometry (full nonlinear fit); an effect whose estimate leaves its
    domain or prior there, or whose addition makes the validation RMS worse, is removed again (with the reason).

    With ``confirm`` (the rigid residuals showed no significant structure: the selection's cross-validation is the
    only evidence), the held-out poses must also confirm the effects' prediction (:func:`.validation_confirms`);
    the last effect added is removed until they do."""
    selected = list(selected)
    final = None
    while selected:
        chosen = tuple(effects[n] for n in selected)
        with plugin_guard(next((n for n in selected if not is_library_effect(n)), selected[0]), "fit"):
            final = identify(mechanism, analysis, data, validation, effects=chosen, kinematics=kin, outlier_probe=False)
            if not final.converged:  # again from the rigid solution (the effects at zero)
                model = MeasurementModel(mechanism, analysis, kin, chosen, targets=list(data.target_names),
                                         orientation=rigid.model.orientation)
                theta0 = model.initial(data.tracker, data.target_priors if data.n_targets > 1 else data.target)
                theta0[: rigid.model.n] = rigid.theta
                warm = identify(mechanism, analysis, data, validation, effects=chosen, kinematics=kin, theta0=theta0,
                                model=model, outlier_probe=False)
                if warm.converged:
                    final = warm
        dropped = _implausible(final)
        if dropped is not None:
            dropped = (dropped[0], "nonlinear fit", dropped[1])
        if dropped is None and before is not None and final.validation is not None \
                and final.validation["rms"] > before["rms"]:
            dropped = (selected[-1], "validation",
                       f"adding it made the validation error worse (RMS {1000 * before['rms']:.1f} -> "
                       f"{1000 * final.validation['rms']:.1f} µm)")
        if dropped is None and confirm and final.validation_residuals is not None \
                and rigid.validation_residuals is not None:
            check = validation_confirms(weighted_validation(rigid, validation), weighted_validation(final, validation))
            if not check["confirmed"]:
                dropped = (selected[-1], "validation",
                           f"the held-out poses do not confirm it: the rigid residuals showed no significant "
                           f"structure, and the validation residuals move along its prediction by only "
                           f"z = {check['z']:.2g} (one-sided p = {check['p_value']:.2g}, {CONFIRM_P:g} needed; a real "
                           f"effect of this size would give about {check['prediction']:.2g}); validation RMS "
                           f"{1000 * before['rms']:.1f} -> {1000 * final.validation['rms']:.1f} µm")
        if dropped is None:
            break
        rejected.append({"effect": dropped[0], "stage": dropped[1], "reason": dropped[2]})
        selected.remove(dropped[0])
        for entry in ranking:
            if entry["effect"] == dropped[0]:
                entry["rejected"] = dropped[2]
        final = None
    return final, selected


def _ceiling(resid: np.ndarray, data, schemes: list, base_cv: float, current_cv: float, seed: int) -> dict:
    """What a black-box regression of the position residuals reaches under the same folds, beside the effects."""
    bb = black_box_ceiling(resid, data, schemes)
    rms_resid = float(np.sqrt(np.mean(np.sum(resid**2, axis=1))))
    random_folds = [("random", np.random.default_rng(seed).permutation(len(data)) % 5)]
    bb_random = black_box_ceiling(resid, data, random_folds)
    ceiling = {"cv_rms_rigid": base_cv, "cv_rms_black_box": bb, "cv_rms_selected": current_cv,
               "method": "ridge quadratic regression of the residuals on joint values and metadata, same folds",
               "black_box_share_of_residual": float(1.0 - bb_random**2 / rms_resid**2) if rms_resid > 0 else 0.0,
               "black_box_share_method": "the same regression under 5 random folds (interpolation), share of the "
                                         "rigid residual variance"}
    # Each share against its own baseline under the same blocked folds: the black box regresses the rigid fit's
    # residuals (its zero prediction leaves their RMS), the effects refit the geometry (their baseline is the rigid
    # model's blocked CV RMS).  The black box's RMS against the rigid model's refit CV RMS would mix an in-sample
    # residual with a held-out one and "explain" most of a pure-noise gap.
    if rms_resid > 0:
        ceiling["black_box_share_blocked"] = float(max(1.0 - bb**2 / rms_resid**2, 0.0))
    if base_cv > 0:
        ceiling["selected_share_blocked"] = float(max(1.0 - current_cv**2 / base_cv**2, 0.0))
    return ceiling
