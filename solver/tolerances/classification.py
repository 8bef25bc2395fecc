"""One verdict per tolerance: the single place that classifies tolerances.

Units: defects in mm (positions) and rad (orientations); task errors in mm and rad.

A tolerance is a statement about a linear combination of defect parameters, not a label
on one parameter (DESIGN.md, "Tolerances").  From the stationarity analysis (paper 1,
eq. 3) this module builds

* **assembly conditions** (class ``assembly``): each forced defect (``dI21 = 0``) and each
  relation between coupled defects (``dK21 - dK23 = 0``), written with every physical
  parameter: a redundant along-axis shift (a *gauge* of the analysis) is put back with
  its equivalent, so the slider-crank's forced ``dc3`` reads ``dc2 + dc3 = 0``;
* one **admissible-direction tolerance** per free or coupled parameter (the parameter
  moving, the coupled ones following their relations), classed

  - ``non-influent``: it moves nothing the task uses (the template's task components,
    :mod:`hyperstat.solver.tolerances.declaration`);
  - ``compensable``: influential, and a calibration from the declared measurements
    plus the controller cancels it on the task components at every configuration: the
    calibration estimate (least squares over the admissible coordinates and the
    measurement nuisances: tracker frame, target offsets) leaves no part the task sees,
    and the actuators cancel what was estimated (its task twist lies in the range of
    the actuated joints' task twists, paper 2 eq. 13);
  - ``accuracy-critical``: influential and not compensable.

A coupled parameter has both: its relation (an assembly condition) and its
admissible direction; ``parameters[name]["class"]`` is then ``assembly``.
*Normalisation* components (along the nominal axis, no geometric meaning) are not
tolerances: they go to :attr:`Classification.appendix`.  A redundant along-axis
shift is merged with its equivalent (``dc2 ≡ dc3``) and shares its tolerance.

Every output (``analyze``, ``report``, ``accuracy``, ``montecarlo``, the FreeCAD panel, the
controller file) uses :func:`classify`, so their vocabularies and counts are equal.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from fractions import Fraction
import warnings

import numpy as np

from hyperstat.solver.analysis.stationarity import StationarityResult, gauge_parameters
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Joint, Mechanism
from hyperstat.solver.tolerances.accuracy import output_twist_maps
from hyperstat.solver.tolerances.declaration import Declaration, declaration_of, n_rotation_rows, task_rows
from hyperstat.solver.threads import limited_blas

__all__ = ["CLASSES", "CLASS_MEANING", "Tolerance", "Classification", "classify", "format_terms", "redundant_text",
           "workspace_checkpoints", "WORKSPACE_CHECKPOINTS"]

CLASSES = ("assembly", "accuracy-critical", "compensable", "non-influent")
CLASS_MEANING = {
    "assembly": "assembly condition: must hold for the machine to assemble and move without deforming "
                "(value from the joint clearances)",
    "accuracy-critical": "moves what the task uses; calibration and the controller cannot cancel it "
                         "(value from allocation against the spec)",
    "compensable": "moves what the task uses; calibration from the declared measurements and the controller "
                   "cancel it (value: what keeps the spec without calibration; it can open)",
    "non-influent": "moves nothing the task uses",
}
_COMPONENT_WORDS = {"I": "axis tilt, x component", "J": "axis tilt, y component", "K": "axis tilt, z component",
                    "a": "origin shift along x", "b": "origin shift along y", "c": "origin shift along z",
                    "G": "rotation about its own axis"}
_REL = 1e-6  # relative threshold on task residuals (dimensionless, round-off is ~1e-12)
#: workspace configurations (seed 0) checked besides the analysis' (classification, assemblability), whatever the command
WORKSPACE_CHECKPOINTS = 64
_CHECKPOINTS: dict = {}  # the last checkpoints computed (one mechanism per process, as the commands run)


def workspace_checkpoints(mechanism: Mechanism, kin: Kinematics, workspace=None,
                          n: int = WORKSPACE_CHECKPOINTS) -> tuple[np.ndarray, np.ndarray]:
    """Fixed configurations of the declared workspace: a sample (seed 0) and the corners of the actuated box.

    The same for every command (``analyze``, ``accuracy``, ``report``), so that the
    assemblability values agree.  A revolute actuator turning a full circle has no bound:
    it stays at its home value in the corners.  The corners are assembled from the nearest sample on its
    branch and kept when they converge inside the workspace (the reachable set may cut a
    corner off); at most 2^8 corners.

    Returns
    -------
    sample, corners : ndarray, (K, n_q) each
    """
    from hyperstat.solver.tolerances.accuracy import sample_workspace
    from hyperstat.solver.kinematics.continuation import continue_nearest
    from hyperstat.solver.tolerances.workspace import workspace_of

    key = (id(mechanism), id(kin), n)
    if workspace is None and _CHECKPOINTS.get("key") == key and _CHECKPOINTS.get("kin") is kin:
        return _CHECKPOINTS["value"]
    ws = workspace or workspace_of(mechanism)
    with warnings.catch_warnings():
        # draws of the actuated box outside the reachable set are expected here (the Triflex-II's box is a third
        # unreachable): they are left out without a warning, and the configurations kept are counted in 'checked'
        warnings.simplefilter("ignore")
        sample = sample_workspace(mechanism, n, seed=0, kinematics=kin, workspace=ws)
    lo, hi = ws.actuated_box(mechanism)
    n_a = len(lo)
    if not len(sample) or n_a > 8 or not np.all(np.isfinite(np.r_[lo, hi])):
        out = (sample, np.zeros((0, kin.n_q)))
    else:
        # a revolute actuator turning a full circle has no boundary: it stays at home in the corners
        turn = np.array([mechanism.joints[i].type == "R" and hi[a] - lo[a] >= 2 * np.pi - 1e-9
                         for a, i in enumerate(mechanism.actuated)])
        varied = np.nonzero(~turn)[0]
        if not len(varied):
            out = (sample, np.zeros((0, kin.n_q)))
        else:
            bits = (np.arange(2 ** len(varied))[:, None] >> np.arange(len(varied))[None, :]) & 1
            qa = np.tile(mechanism.home[mechanism.actuated].astype(float), (len(bits), 1))
            qa[:, varied] = np.where(bits == 1, hi[varied], lo[varied])
            # certified continuation from the nearest sample (the sample is the pool), on home's branch
            q, cert = continue_nearest(kin, qa, None, mechanism.home, pool=sample if len(sample) else None,
                                       inside=ws.inside)
            out = (sample, q[cert.certified])
    if workspace is None:
        _CHECKPOINTS.update(key=key, kin=kin, value=out)
    return out




@dataclass
class Tolerance:
    """One tolerance: a statement, its class, value and why.

    Attributes
    ----------
    id : str
        ``T1``, ``T2``... (assembly conditions first, then directions in parameter order).
    cls : str
        One of :data:`CLASSES`.
    kind : str
        ``forced``, ``relation`` or ``direction``.
    statement : str
        ``dc2 + dc3 = 0`` (assembly) or the parameter with its merged equivalents (``dc3 ≡ dc2``).
    terms : dict
        Parameter -> coefficient of the statement (per mm or per rad).
    parameters : list of str
        Every physical parameter the statement involves.
    unit : str
        ``mm`` or ``rad``: the unit of the statement's value.
    feature : str
        The joint or transform it belongs to (``joint 2 (revolute)``).
    words : str
        What it is in words.
    why : str
        Why this class, with the evidence.
    value : float or None
        Tolerance (± value in ``unit``), when computed.
    value_source : str
        How the value was obtained.
    evidence : dict
        Numbers behind the verdict.
    assembly_ids : list of str
        For a coupled parameter's direction: the relations it is bound by.
    direction : ndarray
        Defect vector (rad / mm) of one unit of the statement (violation for assembly).
    """

    id: str
    cls: str
    kind: str
    statement: str
    terms: dict
    parameters: list
    unit: str
    feature: str
    words: str
    why: str
    value: float | None = None
    value_source: str = ""
    evidence: dict = field(default_factory=dict)
    assembly_ids: list = field(default_factory=list)
    direction: np.ndarray | None = None
    contribution: float | None = None
    summary: str = ""
    value_with_calibration: float | None = None
    value_with_calibration_limit: str | None = None
    drawing_value: float | None = None
    bounds: dict | None = None
    drawing: list = field(default_factory=list)

    def to_dict(self) -> dict:
        """JSON-ready form (``class`` for ``cls``; the direction is left out; keys of docs/tolerances.md)."""
        return {"id": self.id, "class": self.cls, "kind": self.kind, "statement": self.statement,
                "terms": dict(self.terms), "parameters": list(self.parameters), "value": self.value,
                "unit": self.unit, "feature": self.feature, "words": self.words, "why": self.why,
                "value_source": self.value_source, "assembly_ids": list(self.assembly_ids),
                "contribution_percent": self.contribution, "summary": self.summary or self.why,
                "evidence": dict(self.evidence), "value_with_calibration": self.value_with_calibration,
                "value_with_calibration_limit": self.value_with_calibration_limit,
                "drawing_value": self.drawing_value, "bounds": None if self.bounds is None else dict(self.bounds),
                "drawing": [dict(c) for c in self.drawing]}


@dataclass
class Classification:
    """Tolerances of a mechanism, one vocabulary for every output.

    Attributes
    ----------
    items : list of Tolerance
    parameters : dict
        Parameter name -> {"class", "tolerance_id", ...}; normalisation components have
        class ``normalisation`` and no tolerance id.
    appendix : list of dict
        Normalisation components (not tolerances) and why.
    redundant : dict
        Redundant parameter -> {"equivalent": name, "coefficients": {...}}.
    declaration : Declaration
    n_configurations : int
    warnings : list of str
    """

    mechanism: str
    items: list
    parameters: dict
    appendix: list
    redundant: dict
    declaration: Declaration
    n_configurations: int
    warnings: list = field(default_factory=list)
    calibration: dict = field(default_factory=dict)
    allocation: dict = field(default_factory=dict)
    checked: dict = field(default_factory=dict)
    configurations: np.ndarray | None = field(default=None, repr=False)
    analysis: object = field(default=None, repr=False)
    drawings: dict = field(default_factory=dict, repr=False)

    def counts(self) -> dict:
        """Number of tolerances per class (every class present, in :data:`CLASSES` order)."""
        return {c: sum(1 for t in self.items if t.cls == c) for c in CLASSES}

    def by_class(self, cls: str) -> list:
        """Tolerances of one class."""
        return [t for t in self.items if t.cls == cls]

    def item(self, tid: str) -> Tolerance:
        """Tolerance by id."""
        for t in self.items:
            if t.id == tid:
                return t
        raise KeyError(tid)

    def of_parameter(self, name: str) -> Tolerance | None:
        """The tolerance a parameter's class comes from (None for a normalisation component)."""
        tid = self.parameters[name]["tolerance_id"]
        return None if tid is None else self.item(tid)

    def to_dict(self) -> dict:
        """The ``tolerances`` object of the analysis and report JSON (stable keys, units mm / rad)."""
        d = self.declaration
        return {"units": {"length": "mm", "angle": "rad"}, "classes": dict(CLASS_MEANING), "counts": self.counts(),
                "items": [t.to_dict() for t in self.items], "parameters": {k: dict(v) for k, v in self.parameters.items()},
                "appendix": {"normalisation": list(self.appendix)},
                "redundant": {k: dict(v) for k, v in self.redundant.items()},
                "task": list(d.task), "declaration": d.to_dict(), "configurations": self.n_configurations,
                "calibration": dict(self.calibration), "allocation": dict(self.allocation),
                "checked": dict(self.checked), "warnings": list(self.warnings)}


def _clean(c: float) -> float:
    if abs(c) < 1e-10:
        return 0.0
    frac = Fraction(c).limit_denominator(1000)
    if abs(float(frac) - c) < 1e-9 * max(1.0, abs(c)):
        return float(frac)
    return float(f"{c:.10g}")


def format_terms(terms: dict, rhs: str | None = "0", digits: int = 6) -> str:
    """``{"dc2": 1, "dc3": 1}`` -> ``dc2 + dc3 = 0`` (coefficients per mm or per rad, ``digits`` significant digits)."""
    from hyperstat.solver.analysis.stationarity import _printed

    parts = []
    for i, (n, c) in enumerate(terms.items()):
        mag = abs(c)
        coef = "" if mag == 1.0 else f"{_printed(c, digits)[0]}*"
        if i == 0:
            parts.append(f"-{coef}{n}" if c < 0 else f"{coef}{n}")
        else:
            parts.append(f" {'-' if c < 0 else '+'} {coef}{n}")
    text = "".join(parts)
    return text if rhs is None else f"{text} = {rhs}"


def _elements(mechanism: Mechanism) -> dict:
    """Parameter -> (element, kind words)."""
    out = {}
    for ch in mechanism.chains:
        for el in ch.elements:
            if isinstance(el, Joint):
                kind = f"joint {el.name} ({el.type}, {el.role})"
            else:
                kind = f"fixed {el.name}"
            for d in getattr(el, "defects", ()):
                out[d.name] = (el.name, kind, d.component)
    return out


def _redundant(mechanism: Mechanism, names: list) -> tuple[dict, dict]:
    """Normalisation components and redundant along-axis shifts with their linear equivalents."""
    from hyperstat.solver.analysis.verify import gauge_equivalent

    gauges = gauge_parameters(mechanism)
    normal, redundant = {}, {}
    comp = {p.name: p.component for p in mechanism.parameters}
    for g, why in gauges.items():
        if comp[g] in "IJK":
            normal[g] = why
            continue
        vec = gauge_equivalent(mechanism, g, 1.0)  # exact and linear in the size for a shift
        coeffs = {names[j]: _clean(float(vec[j])) for j in np.nonzero(np.abs(vec) > 1e-12)[0]}
        coeffs = {k: v for k, v in coeffs.items() if v != 0.0}
        # the equivalent is the next element's shift (the largest coefficient outside g's own element)
        own = {p.name for p in mechanism.parameters if p.element == next(
            q.element for q in mechanism.parameters if q.name == g)}
        outside = {k: v for k, v in coeffs.items() if k not in own} or coeffs
        eq = max(outside, key=lambda k: abs(outside[k]))
        redundant[g] = {"equivalent": eq, "coefficients": coeffs, "why": why, "vector": vec}
    # an equivalent may itself be redundant (dc5 ≡ dc4 ≡ dc6 along parallel axes): resolve to analysis parameters
    for _ in range(len(redundant)):
        changed = False
        for g, r in redundant.items():
            inner = [k for k in r["coefficients"] if k in redundant and k != g]
            for k in inner:
                c = r["coefficients"].pop(k)
                for kk, vv in redundant[k]["coefficients"].items():
                    r["coefficients"][kk] = _clean(r["coefficients"].get(kk, 0.0) + c * vv)
                changed = True
            r["coefficients"] = {k: v for k, v in r["coefficients"].items() if v != 0.0 and k not in normal}
            if r["equivalent"] in redundant:
                r["equivalent"] = redundant[r["equivalent"]]["equivalent"]
                changed = True
        if not changed:
            break
    return normal, redundant


def _merged_words(gauge: str, name: str, coefficients: dict) -> str:
    """How a merged shift is printed: ``" ≡ dc3"`` only when it is the identical shift (one coefficient of +-1 on
    ``name``); along skew axes, the relation with its coefficients (``db4`` builds the same mechanism as a
    combination of shifts of other elements).

    >>> _merged_words("dc3", "dc2", {"dc2": 1.0})
    ' ≡ dc3'
    >>> _merged_words("da52", "dc62", {"dc62": -1.0})
    ' ≡ -da52'
    >>> _merged_words("db4", "dc5", {"dc5": 1.3624, "dc4": -0.5131})
    ' (db4 acts as 1.3624*dc5 - 0.5131*dc4: a shift along a skew axis)'
    """
    if set(coefficients) == {name} and abs(abs(coefficients[name]) - 1.0) < 1e-12:
        return f" ≡ {'-' if coefficients[name] < 0 else ''}{gauge}"
    return f" ({gauge} acts as {format_terms(coefficients, rhs=None)}: a shift along a skew axis)"


def redundant_text(gauge: str, entry: dict) -> str:
    """A merged shift in words: ``"dc2 ≡ dc3"`` for the identical shift, else the combination it acts as.

    >>> redundant_text("dc2", {"equivalent": "dc3", "coefficients": {"dc3": 1.0}})
    'dc2 ≡ dc3'
    """
    coeffs = entry.get("coefficients") or {entry["equivalent"]: 1.0}
    if len(coeffs) == 1 and abs(abs(next(iter(coeffs.values()))) - 1.0) < 1e-12:
        name, c = next(iter(coeffs.items()))
        return f"{gauge} ≡ {'-' if c < 0 else ''}{name}"
    return f"{gauge} acts as {format_terms(coeffs, rhs=None)}"


def _physical_terms(terms: dict, redundant: dict, order: list) -> dict:
    """Terms over the analysis' parameters -> terms with every redundant parameter put back."""
    out = dict(terms)
    for g, r in redundant.items():
        c = sum(terms.get(k, 0.0) * v for k, v in r["coefficients"].items())
        c = _clean(c)
        if c != 0.0:
            out[g] = out.get(g, 0.0) + c
    lead = next((out[n] for n in order if out.get(n)), 1.0)
    out = {n: _clean(out[n] / lead) for n in order if out.get(n)}
    return {n: c for n, c in out.items() if c != 0.0}


@limited_blas
def classify(mechanism: Mechanism, analysis: StationarityResult, kinematics: Kinematics | None = None,
             declaration: Declaration | None = None, configurations: np.ndarray | None = None) -> Classification:
    """Classify the tolerances of ``mechanism`` (see the module docstring).

    Parameters
    ----------
    mechanism : Mechanism
    analysis : StationarityResult
        Its stationarity analysis (paper 1, eq. 3).
    kinematics : Kinematics, optional
    declaration : Declaration, optional
        Task, measurements, spec, clearances; default: what the mechanism carries.
    configurations : ndarray, (K, n_q), optional
        Assembled configurations for the task and calibration tests; default: the
        analysis' configurations and the fixed checkpoints of the declared workspace
        (:func:`workspace_checkpoints`: a sample and the corners of the actuated box), the
        same for every command.

    Returns
    -------
    Classification

    Examples
    --------
    >>> from hyperstat.solver.kinematics.modelfile import load_model  # doctest: +SKIP
    >>> c = classify(mech, analyze(mech))  # doctest: +SKIP
    >>> c.counts()  # doctest: +SKIP
    {'assembly': 6, 'accuracy-critical': 0, 'compensable': 3, 'non-influent': 1}
    """
    return _classify(mechanism, analysis, kinematics, declaration, configurations)


def _classify(mechanism: Mechanism, analysis: StationarityResult, kinematics: Kinematics | None,
              declaration: Declaration | None, configurations: np.ndarray | None) -> Classification:
    """Body of :func:`classify` (BLAS single-threaded by the caller)."""
    kin = kinematics or Kinematics(mechanism)
    decl = declaration or declaration_of(mechanism)
    m = mechanism
    names = [p.name for p in m.parameters]
    index = {n: i for i, n in enumerate(names)}
    where = _elements(m)
    unit = {p.name: p.unit for p in m.parameters}
    normal, redundant = _redundant(m, names)
    merged_into: dict = {}
    for g, r in redundant.items():
        merged_into.setdefault(r["equivalent"], []).append(g)
    warns: list = []
    verdict = {p.name: p for p in analysis.parameters}

    # ---------------------------------------------------------------- assembly conditions
    items: list[Tolerance] = []
    forced = [p.name for p in analysis.parameters if p.verdict == "forced"]
    if len(forced) + len(analysis.relations) != analysis.rank:
        warns.append(f"{len(forced)} forced defects and {len(analysis.relations)} relations for a constraint rank of "
                     f"{analysis.rank}: the assembly conditions may not describe the constraint exactly.")
    relation_of: dict = {}

    def feature_of(params: list) -> str:
        feats = []
        for n in params:
            f = where[n][1]
            if f not in feats:
                feats.append(f)
        if len(feats) > 1:
            return "elements " + ", ".join(dict.fromkeys(where[n][0] for n in params))
        return feats[0]

    for f in forced:
        terms = _physical_terms({f: 1.0}, redundant, names)
        direction = np.zeros(len(names))
        direction[index[f]] = 1.0 / terms[f]
        el, kind, comp = where[f]
        extra = [g for g in terms if g != f]
        words = _COMPONENT_WORDS[comp]
        if extra:
            words += " (with the same shift " + ", ".join(extra) + ")"
        items.append(Tolerance("", "assembly", "forced", format_terms(terms), terms, list(terms), unit[f],
                               feature_of(list(terms)), words,
                               "forced by the over-constraint: the passive joints cannot absorb it at every "
                               "configuration (its admissible part is "
                               f"{verdict[f].admissible:.1e})", direction=direction))
    for r in analysis.relations:
        terms = _physical_terms(dict(r.terms), redundant, names)
        pivot = next(iter(r.terms))
        direction = np.zeros(len(names))
        direction[index[pivot]] = 1.0 / r.terms[pivot]
        units = {unit[n] for n in terms}
        items.append(Tolerance("", "assembly", "relation", format_terms(terms, digits=r.digits), terms, list(terms),
                               unit[pivot] if len(units) == 1 else unit[pivot], feature_of(list(terms)),
                               "relation between the defects of " + ", ".join(dict.fromkeys(where[n][0] for n in terms)),
                               "coupled defects: admissible only in this combination; breaking it loads the structure",
                               direction=direction))
        for n in r.terms:
            relation_of.setdefault(n, []).append(len(items) - 1)

    # ---------------------------------------------------------------- admissible directions
    origin = {}
    if configurations is None:
        sample, corners = workspace_checkpoints(m, kin)
        q = np.vstack([analysis.configurations] + [p for p in (sample, corners) if len(p)])
        origin = {"analysis": int(len(analysis.configurations)), "workspace_sample": int(len(sample)),
                  "actuated_box_corners": int(len(corners))}
    else:
        q = np.atleast_2d(configurations)
        origin = {"given": int(len(q))}
    st = kin.evaluate(q, None, jacobians=True)
    try:  # undamped (round-off only) at the analysis' generic configurations; damped if one is singular
        k_xi, k_a = output_twist_maps(kin, st, damping=1e-16)
    except np.linalg.LinAlgError:
        k_xi, k_a = output_twist_maps(kin, st)
    ls = kin.length_scale
    sel = task_rows(decl.task, st.output_pose)  # (K, r, 6)
    n_rot = n_rotation_rows(decl.task)
    row_scale = np.r_[np.ones(n_rot), np.full(sel.shape[1] - n_rot, 1.0 / ls)]  # dimensionless rows
    pscale = kin.parameter_scale
    task_xi = (sel @ k_xi) * row_scale[None, :, None] * pscale[None, None, :]  # per dimensionless defect
    act = m.actuated
    jscale = kin.joint_scale[act]
    task_a = (sel @ k_a) * row_scale[None, :, None] * jscale[None, None, :]
    basis = analysis.admissible_basis if analysis.admissible_basis is not None else np.zeros((len(names), 0))
    meas_xi, nuisance, nuisance_labels = _measurement_maps(decl, st, k_xi, ls, pscale)
    rows_m = meas_xi.shape[0] * meas_xi.shape[1]
    j_m = np.concatenate([(meas_xi @ basis).reshape(rows_m, basis.shape[1]),
                          nuisance.reshape(rows_m, nuisance.shape[2])], axis=1)
    j_pinv = np.linalg.pinv(j_m, rcond=1e-10) if j_m.size else np.zeros((j_m.shape[1], j_m.shape[0]))
    if j_m.size:
        _, sv, vt_m = np.linalg.svd(j_m, full_matrices=True)
        blind = vt_m[int(np.sum(sv > 1e-10 * sv[0])):].T if sv.size and sv[0] > 0 else np.eye(j_m.shape[1])
    else:
        sv, blind = np.zeros(0), np.zeros((j_m.shape[1], 0))  # blind: what the measurements cannot see
    ka_pinv = np.linalg.pinv(task_a, rcond=1e-8)  # (K, n_a, r)
    # task-singular configurations (a dead centre: the actuators lose a task direction there, so nothing is
    # cancellable to first order) are left out of the residual test: their rank is below the generic one
    if task_a.size:
        sa = np.linalg.svd(task_a, compute_uv=False)
        rank_a = np.sum(sa > 1e-6 * max(float(sa.max()), 1e-300), axis=1)
        regular = rank_a == rank_a.max()
    else:
        regular = np.ones(len(q), dtype=bool)
    n_s = basis.shape[1]

    def task_of(d: np.ndarray) -> np.ndarray:
        return task_xi @ d  # (K, r)

    def residual_shares(d: np.ndarray, meas: np.ndarray, pinv: np.ndarray) -> tuple[float, float, float]:
        # the task residual of a calibration (measurement rows ``meas``, its pseudo-inverse ``pinv``) and the
        # compensation per unit of the direction ``d``, as shares of its task effect: unseen, uncancelled, total
        u_d = basis.T @ d
        y = np.einsum("kij,j->ki", meas, d).reshape(-1)
        est = pinv @ y
        u_hat = est[:n_s]
        predicted = task_of(basis @ u_hat)  # what the calibrated model predicts on the task
        unseen = task_of(basis @ (u_d - u_hat))
        delta_a = np.einsum("kar,kr->ka", ka_pinv, predicted)
        uncancelled = predicted - np.einsum("kra,ka->kr", task_a, delta_a)
        total = unseen + uncancelled
        ref = float(np.max(np.linalg.norm(task_of(d), axis=1)))
        return (float(np.max(np.linalg.norm(unseen[regular], axis=1))) / ref,
                float(np.max(np.linalg.norm(uncancelled[regular], axis=1))) / ref,
                float(np.max(np.linalg.norm(total[regular], axis=1))) / ref)

    directions = []
    compensable_directions = []  # (item index, dimensionless direction) of the compensable ones
    for p in analysis.parameters:
        if p.verdict not in ("free", "coupled"):
            continue
        j = index[p.name]
        proj = basis @ basis[j]  # dimensionless projection of e_j on the admissible subspace
        if abs(proj[j]) < 1e-12:
            continue
        d = proj / proj[j]
        directions.append((p, d))
    influence = [float(np.max(np.linalg.norm(task_of(d), axis=1))) for _, d in directions]
    top = max(influence, default=0.0)
    for (p, d), infl in zip(directions, influence):
        el, kind, comp = where[p.name]
        eqs = merged_into.get(p.name, [])
        statement = p.name + "".join(_merged_words(g, p.name, redundant[g]["coefficients"]) for g in eqs)
        params = [p.name] + eqs
        words = _COMPONENT_WORDS[comp]
        if eqs:
            words += " (" + ", ".join(f"{g}: the same shift on the previous joint" for g in eqs) + ")"
        ev = {"task_influence": infl}
        if p.verdict == "coupled":
            words += ", coupled ones following"
        if infl <= 1e-9 * max(top, 1e-300) or infl < 1e-12:
            cls = "non-influent"
            why = (f"its admissible motion moves no task component ({', '.join(decl.task)}): largest task "
                   f"motion {infl:.1e} per unit defect over {len(q)} configurations")
        else:
            u_d = basis.T @ d
            r_unseen, r_unc, r_total = residual_shares(d, meas_xi, j_pinv)
            ref = float(np.max(np.linalg.norm(task_of(d), axis=1)))
            ev.update({"not_identified_share": r_unseen, "not_cancelled_share": r_unc, "residual_share": r_total})
            # confounded: the part of (u_d, no nuisance) the measurements cannot see moves the task; the pseudo-inverse
            # would split it between the defect and what it is confounded with by the smallest norm (an artefact),
            # so the direction is called not identifiable, and what it cannot be told from is named
            hidden = blind @ (blind.T @ np.r_[u_d, np.zeros(j_m.shape[1] - n_s)])
            hidden_task = float(np.max(np.linalg.norm(task_of(basis @ hidden[:n_s])[regular], axis=1))) / ref \
                if hidden.size else 0.0
            confounded = []
            if hidden_task >= _REL:
                weights = np.abs(hidden[n_s:])
                confounded = list(dict.fromkeys(nuisance_labels[i] for i in np.argsort(-weights)
                                                if weights[i] > 1e-3 * max(float(weights.max()), 1e-300)))
                moved = basis @ hidden[:n_s]
                others = [names[i] for i in np.argsort(-np.abs(moved)) if abs(moved[i]) > 1e-3 * np.abs(moved).max()
                          and names[i] != p.name][:3]
                confounded += others
            ev.update({"identifiable": hidden_task < _REL, "confounded_with": confounded})
            if r_total < _REL:
                compensable_directions.append((len(items), d))
                cls = "compensable"
                why = (f"a calibration from {decl.measurement_kind} identifies it (or the combination that absorbs "
                       f"it) and the actuators cancel it on {', '.join(decl.task)}: task residual "
                       f"{r_total:.1e} of its effect at the worst of {len(q)} configurations")
            else:
                cls = "accuracy-critical"
                reasons = []
                if not ev["identifiable"]:
                    reasons.append(f"not identifiable: a calibration from {decl.measurement_kind} cannot tell it from "
                                   + (", ".join(ev["confounded_with"]) or "other defects"))
                elif r_unseen >= _REL:
                    reasons.append(f"{100 * r_unseen:.0f} % of its task effect is invisible to a calibration from "
                                   f"{decl.measurement_kind}")
                if r_unc >= _REL:
                    reasons.append(f"{100 * r_unc:.0f} % of its task effect is outside what the actuators can "
                                   "cancel")
                why = "; ".join(reasons) + f" (worst of {len(q)} configurations)"
            if _REL / 100 <= r_total < 100 * _REL:  # within two decades of the threshold: say it is weak
                why += (f"; weak evidence: the residual {r_total:.1e} is within a factor 100 of the threshold "
                        f"{_REL:.0e}")
                warns.append(f"{p.name}: its class ({cls}) rests on a task residual of {r_total:.1e}, close to the "
                             f"threshold {_REL:.0e}.")
        if cls == "non-influent" and infl > 1e-11 * max(top, 1e-300):
            why += f"; weak evidence: {infl / top:.1e} of the largest task motion, close to the threshold 1e-9"
            warns.append(f"{p.name}: non-influent by a task motion of {infl / top:.1e} of the largest, close to the "
                         "threshold 1e-9.")
        direction = d * pscale / pscale[index[p.name]]  # per unit of the parameter
        if p.verdict == "coupled":
            # the admissible motion of a coupled parameter moves others with it: the statement says so, so that the
            # direction is never read as the parameter alone (whose class is its relation's, assembly)
            # largest first; terms of the same size (to 10 digits: a relation's +-200 and -200) in parameter order,
            # not in the order round-off would give them
            size = np.round(np.abs(d) / max(float(np.max(np.abs(d))), 1e-300), 10)
            followers = [(names[k], _clean(float(direction[k]))) for k in np.lexsort((np.arange(len(d)), -size))
                         if names[k] not in params and abs(direction[k]) > 1e-9]
            # every follower, written out (a statement a workshop reads is never cut short)
            shown = [f"{n} = {'' if c == 1 else '-' if c == -1 else f'{c:.4g}*'}{p.name}" for n, c in followers
                     if c != 0.0]
            if shown:
                statement += " with " + ", ".join(shown)
        t = Tolerance("", cls, "direction", statement, {p.name: 1.0}, params, unit[p.name], feature_of(params), words,
                      why, evidence=ev, direction=direction)
        if p.verdict == "coupled":
            t.assembly_ids = [i for i in relation_of.get(p.name, [])]
        items.append(t)

    # ids, cross references, short reasons, parameter map
    for i, t in enumerate(items):
        t.id = f"T{i + 1}"
        ev = t.evidence
        if t.kind == "forced":
            t.summary = "forced by the over-constraint"
        elif t.kind == "relation":
            t.summary = "coupled: only this combination is admissible"
        elif t.cls == "non-influent":
            t.summary = "moves no task component"
        elif t.cls == "compensable":
            t.summary = f"calibrated and cancelled (residual {ev['residual_share']:.0e})"
        else:
            parts = []
            if not ev.get("identifiable", True):
                parts.append("not identifiable (confounded with " + (", ".join(ev["confounded_with"][:2]) or
                                                                       "other defects") + ")")
            elif ev["not_identified_share"] >= _REL:
                parts.append(f"{100 * ev['not_identified_share']:.0f} % unseen by calibration")
            if ev["not_cancelled_share"] >= _REL:
                parts.append(f"{100 * ev['not_cancelled_share']:.0f} % not cancellable")
            t.summary = "; ".join(parts)
    for t in items:
        if t.assembly_ids:
            ids = [items[i].id for i in t.assembly_ids]
            t.assembly_ids = ids
            t.why += "; also bound by the assembly condition " + ", ".join(ids)
            t.summary += "; relation " + ", ".join(ids)
    params: dict = {}
    for t in items:
        if t.kind == "direction":
            for n in t.parameters:
                params[n] = {"class": t.cls, "tolerance_id": t.id, "tolerance_ids": [t.id]}
    for t in items:
        if t.kind != "direction":
            for n in t.parameters:
                entry = params.get(n)
                if entry is None or entry["class"] != "assembly":
                    params[n] = {"class": "assembly", "tolerance_id": t.id,
                                 "tolerance_ids": [t.id] + ([] if entry is None else entry["tolerance_ids"])}
                elif t.id not in entry["tolerance_ids"]:
                    entry["tolerance_ids"].append(t.id)
    for n in names:
        if n in normal:
            params[n] = {"class": "normalisation", "tolerance_id": None, "tolerance_ids": []}
        elif n in redundant:  # merged with its equivalent: the same tolerance, one class of its own
            eq = redundant[n]["equivalent"]
            src = params.get(n) or params.get(eq) or {"tolerance_id": None, "tolerance_ids": []}
            params[n] = {"class": "redundant", "tolerance_id": src["tolerance_id"],
                         "tolerance_ids": list(src["tolerance_ids"])}
        if n in redundant:
            params[n]["equivalent"] = redundant[n]["equivalent"]
    params = {n: params[n] for n in names}
    appendix = [{"name": n, "element": where[n][0], "why": why} for n, why in normal.items()]
    red = {g: {"equivalent": r["equivalent"], "coefficients": r["coefficients"], "why": r["why"]}
           for g, r in redundant.items()}
    cal = _calibration_residual(decl, j_m, task_xi @ basis, n_s, n_rot, ls, len(q), decl.poses)
    cal.update({"smallest_singular_value": float(sv[-1]) if sv.size else None, "measurements": decl.measurement_kind,
                "unknowns": int(j_m.shape[1]),
                "non_identifiable_share_max": max((t.evidence["residual_share"] for t in items
                                                   if t.cls == "compensable"), default=0.0)})
    # the campaign hyperstat's own calibration runs: identify and export-controller fit the tracker frame and every
    # target offset; a declaration that holds them (a registered frame, known offsets) promises a calibration those
    # commands do not make
    if decl.frame == "registered" or (decl.offsets == "known" and decl.targets_mm):
        fitted = replace(decl, frame="unknown", offsets="unknown")
        meas_f, nuis_f, _ = _measurement_maps(fitted, st, k_xi, ls, pscale)
        j_f = np.concatenate([(meas_f @ basis).reshape(rows_m, n_s), nuis_f.reshape(rows_m, nuis_f.shape[2])], axis=1)
        pinv_f = np.linalg.pinv(j_f, rcond=1e-10)
        lost = [items[i].id for i, d in compensable_directions if residual_shares(d, meas_f, pinv_f)[2] >= _REL]
        as_fitted = _calibration_residual(fitted, j_f, task_xi @ basis, n_s, n_rot, ls, len(q), decl.poses)
        held = [w for w, on in (("the tracker frame registered on references of the base", decl.frame == "registered"),
                                ("the target offsets known", decl.offsets == "known")) if on]
        cal["as_identify_fits"] = {
            "fits": "the tracker frame and every target offset (hyperstat identify and export-controller)",
            "declared_holds": held, "position_mm": as_fitted["position_mm"],
            "orientation_rad": as_fitted["orientation_rad"], "unknowns": int(j_f.shape[1]),
            "compensable_not_identified": lost}
        over = [f"{as_fitted[k]:.3g} {u} against the spec's {s:g} {u}" for k, u, s in
                (("position_mm", "mm", decl.position_mm), ("orientation_rad", "rad", decl.orientation_rad))
                if s is not None and as_fitted[k] >= s]
        worse = lost or over or any(as_fitted[k] > 1.25 * max(cal[k], 1e-300) and as_fitted[k] > 1e-9
                                    for k in ("position_mm", "orientation_rad"))
        cal["as_identify_fits"]["worse"] = bool(worse)
        if worse:
            n_comp = len(compensable_directions)
            opens = " and the compensable ones open with it" if n_comp else ""
            warns.append(
                "CALIBRATION CAMPAIGN: the values assume a calibration with " + " and ".join(held) + ", as declared "
                f"(the accuracy-critical ones are allocated against the spec less its 3-sigma task error{opens}); "
                "hyperstat identify and export-controller fit the tracker frame and every target offset: then "
                + (f"{len(lost)} of {n_comp} compensable tolerances are not identified"
                   + (f" ({_id_list(lost)})" if lost else "") + " and " if n_comp else "")
                + f"the calibration's 3-sigma task error is {as_fitted['position_mm']:.3g} mm, "
                f"{as_fitted['orientation_rad']:.3g} rad (declared: {cal['position_mm']:.3g} mm, "
                f"{cal['orientation_rad']:.3g} rad)" + (f", {' and '.join(over)}" if over else "")
                + ". A machine calibrated by them is not assured these values.")
    shares = {c: [t.evidence.get("residual_share") for t in items if t.cls == c and t.kind == "direction"]
              for c in ("compensable", "accuracy-critical")}
    infl = [t.evidence["task_influence"] / top for t in items if t.cls == "non-influent" and top > 0]
    checked = {"configurations": int(len(q)), "of": origin, "task_singular_left_out": int(np.sum(~regular)),
               "thresholds": {"residual_share": _REL,
                                                                          "task_motion_ratio": 1e-9},
               "compensable_largest_residual": max(shares["compensable"], default=None),
               "accuracy_critical_smallest_residual": min(shares["accuracy-critical"], default=None),
               "non_influent_largest_motion_ratio": max(infl, default=None)}
    margins = []
    if checked["compensable_largest_residual"] is not None:
        margins.append(_REL / max(checked["compensable_largest_residual"], 1e-300))
    if checked["accuracy_critical_smallest_residual"] is not None:
        margins.append(checked["accuracy_critical_smallest_residual"] / _REL)
    if checked["non_influent_largest_motion_ratio"] is not None:
        margins.append(1e-9 / max(checked["non_influent_largest_motion_ratio"], 1e-300))
    checked["margin"] = min(margins, default=None)
    checked["margin_meaning"] = ("smallest factor between a verdict's evidence and its threshold over the checked "
                                 "configurations (compensable: threshold / largest task residual; accuracy-critical: "
                                 "smallest residual / threshold; non-influent: threshold / largest task motion)")
    return Classification(m.name, items, params, appendix, red, decl, int(len(q)), warns, cal, checked=checked,
                          configurations=q, analysis=analysis)


def _measurement_maps(decl: Declaration, st, k_xi: np.ndarray, ls: float, pscale: np.ndarray):
    """Measured rows per dimensionless defect and the nuisance columns (tracker frame, target offsets).

    Positions of every target ``t`` (output frame) move by ``v + omega x R t``; a tracker
    frame error ``(omega0, v0)`` (when the declaration says the frame is ``unknown``) moves
    a measured point ``p`` by ``omega0 x p + v0``; a target offset error ``dt`` (offsets
    ``unknown``) by ``R dt``.  Rows are dimensionless (mm / length scale,
    rad).
    """
    pose = st.output_pose
    k = pose.shape[0]
    rows, nuis = [], []
    n_t = len(decl.targets_mm)
    for ti, t in enumerate(decl.targets_mm):
        arm = pose[:, :3, :3] @ np.asarray(t, float)  # (K, 3)
        p = pose[:, :3, 3] + arm
        moved = k_xi[:, 3:] - _skew(arm) @ k_xi[:, :3]  # v + omega x arm
        rows.append(moved / ls * pscale[None, None, :])
        cols = np.zeros((k, 3, 6 + 3 * n_t))
        cols[:, :, :3] = -_skew(p / ls)
        cols[:, :, 3:6] = np.eye(3)
        cols[:, :, 6 + 3 * ti: 9 + 3 * ti] = pose[:, :3, :3]
        nuis.append(cols)
    if decl.measurement_kind == "poses":
        rows.append(k_xi[:, :3] * pscale[None, None, :])
        cols = np.zeros((k, 3, 6 + 3 * n_t))
        cols[:, :, :3] = np.eye(3)
        nuis.append(cols)
    nuis = np.concatenate(nuis, axis=1)
    keep = np.ones(nuis.shape[2], dtype=bool)
    if decl.frame == "registered":  # the tracker frame is known
        keep[:6] = False
    if decl.offsets == "known":  # the targets sit at known offsets
        keep[6:] = False
    labels = ["the tracker frame"] * 6 + [f"the offset of target {i + 1}" for i in range(n_t) for _ in range(3)]
    nuis = nuis[:, :, keep]
    return np.concatenate(rows, axis=1), nuis, [lab for lab, k in zip(labels, keep) if k]


def _calibration_residual(decl: Declaration, j_m: np.ndarray, task_u: np.ndarray, n_s: int, n_rot: int, ls: float,
                          n_cfg: int, poses: int = 60) -> dict:
    """Task error left by calibration noise: 3 sigma, worst configuration (mm, rad).

    The identified admissible coordinates have covariance ``(J^T W J)^+`` (``W``: inverse
    noise variances of the declared measurements, the design repeated to ``poses``
    poses); the task error's covariance follows through the task rows.
    """
    if not j_m.size or not n_s:
        return {"position_mm": 0.0, "orientation_rad": 0.0, "poses": poses, "noise_mm": decl.noise_mm}
    per_pose = j_m.shape[0] // n_cfg
    n_pos = 3 * len(decl.targets_mm)
    sigma = np.r_[np.full(n_pos, decl.noise_mm / ls), np.full(per_pose - n_pos, decl.noise_rad)]
    w = np.tile(1.0 / sigma**2, n_cfg) * (poses / n_cfg)
    cov = np.linalg.pinv(j_m.T @ (j_m * w[:, None]), rcond=1e-10)[:n_s, :n_s]
    tc = task_u @ cov @ np.swapaxes(task_u, 1, 2)  # (K, r, r)
    out = {"poses": poses, "noise_mm": decl.noise_mm, "noise_rad": decl.noise_rad}
    r = tc.shape[1]
    pos = tc[:, n_rot:, n_rot:] * ls**2
    rot = tc[:, :n_rot, :n_rot]
    out["position_mm"] = float(3 * np.sqrt(max(float(np.max(np.linalg.eigvalsh(pos))), 0.0))) if r > n_rot else 0.0
    out["orientation_rad"] = float(3 * np.sqrt(max(float(np.max(np.linalg.eigvalsh(rot))), 0.0))) if n_rot else 0.0
    return out


def _id_list(ids: list) -> str:
    """Tolerance ids, consecutive ones as ranges: ``"T3-T5, T9"``.

    >>> _id_list(["T3", "T4", "T5", "T9"])
    'T3-T5, T9'
    """
    nums = sorted(int(i[1:]) for i in ids)
    runs: list = []
    for n in nums:
        if runs and n == runs[-1][1] + 1:
            runs[-1][1] = n
        else:
            runs.append([n, n])
    return ", ".join(f"T{a}" if a == b else f"T{a}-T{b}" for a, b in runs)


def _skew(p: np.ndarray) -> np.ndarray:
    out = np.zeros(p.shape[:-1] + (3, 3))
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -z, y, -x
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = z, -y, x
    return out
