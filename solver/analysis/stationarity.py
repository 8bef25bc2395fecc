"""Automated stationarity analysis of an over-constrained mechanism (paper 1, sections 3-4).

Units: defects in rad (orientation, roll) and mm (position); relations are printed
with coefficients per those units.

The paper writes the stationarity of the closure ``f(xi, q) = 0`` (eq. 3),

    S(f) = sum_i df/dxi_i dxi_i + sum_j df/dq_pj dq_pj = 0,

and reads by hand which defects must vanish for the passive joints to absorb the
defects at every configuration.  Here, at each sampled configuration, ``A_s = df/dxi``
and ``B_s = df/dq_p`` are computed from screws; a defect ``d`` is admissible iff
``A_s d`` lies in ``range(B_s)``, i.e. ``U0^T A_s d = 0`` with ``U0`` a basis of the
left null space of ``B_s``.  Stacking ``U0^T A_s`` over configurations gives the
constraint matrix ``G``; its singular value decomposition gives

* the rank (number of independent constraints) and the singular-value gap,
* the admissible subspace ``null(G)``,
* *forced* parameters: ``e_j`` in ``row(G)`` (zero in every admissible defect),
* *coupled* parameters: constrained only in combination (relations printed),
* *free* parameters: ``e_j`` in ``null(G)``, split into *influential* and
  *non-influent* by their effect on the output frame with the passive joints
  following (``K = O_xi - O_p B_s^+ A_s``).

*Gauge* parameters carry no geometry and are fixed first: the axis component along
the nominal axis (normalisation ``n . dn = 0``) and, for a revolute followed by an
element with a full position defect, the shift of its origin along its own axis
(equal to the next element's ``dc``).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from fractions import Fraction

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.errors import AnalysisError
from hyperstat.solver.kinematics.model import Joint, Mechanism
from hyperstat.solver.kinematics.sampling import sample_configurations

__all__ = ["ParameterVerdict", "Relation", "StationarityResult", "analyze", "compare_samples", "gauge_parameters",
           "format_relation", "relations_span"]

_ZERO = 1e-7  # threshold on dimensionless projections (they are 0 or O(1))


@dataclass
class ParameterVerdict:
    """Verdict on one defect parameter.

    Attributes
    ----------
    name : str
        Paper name (``dI21``).
    element : str
        Joint or transform it belongs to.
    component : str
        ``I J K a b c G``.
    unit : str
        ``rad`` or ``mm``.
    verdict : str
        ``gauge``, ``forced``, ``coupled`` or ``free``.
    influential : bool or None
        Whether an admissible defect along this parameter moves the output frame
        (``None`` for gauge and forced parameters).
    admissible : float
        Norm of the projection of the unit defect on the admissible subspace
        (0 for forced, 1 for free, between for coupled); dimensionless.
    influence : float
        Largest dimensionless output motion per unit admissible defect.
    reason : str
        One line on why.
    """

    name: str
    element: str
    component: str
    unit: str
    verdict: str
    influential: bool | None
    admissible: float
    influence: float
    reason: str = ""


@dataclass
class Relation:
    """A linear relation ``sum terms[name] * name = 0`` that admissible defects satisfy.

    ``digits``: the significant digits ``text`` prints, as few as keep the printed relations on the
    analysis' subspace to 1e-6 (:func:`relations_span`).
    """

    terms: dict
    text: str
    digits: int = 6


@dataclass
class StationarityResult:
    """Outcome of :func:`analyze`; ``to_dict`` gives the JSON of ``hyperstat analyze --json``."""

    mechanism: str
    parameters: list
    relations: list
    rank: int
    n_constraint_rows: int
    singular_values: list
    gap: float
    threshold: float
    mobility: int
    overconstraint: int
    n_closure_equations: int
    n_configurations: int
    influential_rank: int
    influential_gap: float
    length_scale: float
    elapsed: float
    warnings: list = field(default_factory=list)
    configurations: np.ndarray | None = None
    admissible_basis: np.ndarray | None = None
    stability: dict | None = None

    @property
    def stable(self) -> bool | None:
        """Whether every repeated sample agreed (``None`` when only one sample was analysed)."""
        return None if self.stability is None else bool(self.stability["stable"])

    def by_verdict(self, verdict: str) -> list[str]:
        """Names of the parameters with a verdict."""
        return [p.name for p in self.parameters if p.verdict == verdict]

    def verdict_of(self, name: str) -> ParameterVerdict:
        """Verdict of one parameter by name."""
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    def counts(self) -> dict:
        """Number of parameters per verdict, and free influential / non-influent."""
        out = {v: len(self.by_verdict(v)) for v in ("gauge", "forced", "coupled", "free")}
        out["free_influential"] = sum(p.verdict == "free" and bool(p.influential) for p in self.parameters)
        out["free_non_influent"] = sum(p.verdict == "free" and p.influential is False for p in self.parameters)
        out["total"] = len(self.parameters)
        return out

    def parameterization(self, mechanism: Mechanism, influential_only: bool = True) -> tuple[list[str], np.ndarray]:
        """Independent coordinates of the admissible defects and the map to the full defect vector.

        Free parameters are their own coordinates; for each relation between coupled
        parameters the pivot (first) parameter is dependent and follows the others.

        Parameters
        ----------
        mechanism : Mechanism
            The analysed model.
        influential_only : bool
            Keep only coordinates that move the output (identification unknowns).

        Returns
        -------
        names : list of str
            Independent parameter names.
        matrix : ndarray, (n_xi, len(names))
            ``xi = matrix @ u`` in physical units (rad, mm).
        """
        index = mechanism.parameter_index
        dependent = {}
        for rel in self.relations:
            pivot = next(iter(rel.terms))
            dependent[pivot] = {n: -c / rel.terms[pivot] for n, c in rel.terms.items() if n != pivot}
        names = []
        for p in self.parameters:
            if p.verdict not in ("free", "coupled") or p.name in dependent:
                continue
            if influential_only and not p.influential:
                continue
            names.append(p.name)
        matrix = np.zeros((len(mechanism.parameters), len(names)))
        for k, n in enumerate(names):
            matrix[index[n], k] = 1.0
            for pivot, terms in dependent.items():
                if n in terms:
                    matrix[index[pivot], k] = terms[n]
        return names, matrix

    def to_dict(self) -> dict:
        """JSON-ready dictionary (units: rad, mm)."""
        return {
            "mechanism": self.mechanism,
            "units": {"length": "mm", "angle": "rad"},
            "counts": _public_counts(self.counts(), self.parameters),
            "parameters": [_public_verdict(asdict(p)) for p in self.parameters],
            "relations": [{"terms": r.terms, "text": r.text} for r in self.relations],
            "rank": self.rank,
            "n_constraint_rows": self.n_constraint_rows,
            "singular_values": self.singular_values,
            "singular_value_gap": self.gap,
            "rank_threshold": self.threshold,
            "mobility": self.mobility,
            "overconstraint": self.overconstraint,
            "closure_equations": self.n_closure_equations,
            "configurations": self.n_configurations,
            "influential_rank": self.influential_rank,
            "influential_gap": self.influential_gap,
            "length_scale_mm": self.length_scale,
            "warnings": list(self.warnings),
            "stability": self.stability,
        }


def _public_verdict(entry: dict) -> dict:
    """One parameter of the JSON: a gauge is named for what it is, ``normalisation`` (an axis component along the
    nominal axis) or ``redundant`` (a shift along a revolute's own axis, equal to the next element's)."""
    if entry["verdict"] == "gauge":
        entry["verdict"] = "normalisation" if entry["component"] in "IJK" else "redundant"
    return entry


def _public_counts(counts: dict, parameters: list) -> dict:
    """The counts of the JSON, the gauges split into normalisation components and redundant shifts."""
    out = {k: v for k, v in counts.items() if k != "gauge"}
    out["normalisation"] = sum(p.verdict == "gauge" and p.component in "IJK" for p in parameters)
    out["redundant"] = sum(p.verdict == "gauge" and p.component not in "IJK" for p in parameters)
    return out


def gauge_parameters(mechanism: Mechanism) -> dict[str, str]:
    """Gauge parameters and why: they carry no geometry and are fixed to zero.

    * Normalisation (paper 1, after eq. 7: ``I dI + J dJ + K dK = 0``): of the axis
      components an element carries, the one along which the nominal axis has its
      largest component is fixed; the others still tilt the axis in every direction.
    * Along-axis shift of a revolute origin: a shift along the joint's own axis
      commutes with the rotation and equals the next element's shift along the same
      axis; it is a gauge when the next element of the chain carries ``a, b, c``.
    """
    out: dict[str, str] = {}

    def largest(comps: list[str], letters: str, n0: np.ndarray) -> str:
        # ties (equal components within 1e-9) go to the first letter, so that round-off
        # in a model read back from CAD cannot change the choice
        top = max(abs(n0[letters.index(c)]) for c in comps)
        return next(c for c in comps if abs(n0[letters.index(c)]) >= top - 1e-9)

    for chain in mechanism.chains:
        for ei, el in enumerate(chain.elements):
            defects = {d.component: d.name for d in getattr(el, "defects", ())}
            n0 = np.asarray(el.placement.z_axis, dtype=float)
            orient = [c for c in "IJK" if c in defects]
            if orient:
                comp = largest(orient, "IJK", n0)
                if abs(n0["IJK".index(comp)]) > 1e-9:
                    out[defects[comp]] = "normalisation of the axis (n . dn = 0)"
            pos = [c for c in "abc" if c in defects]
            if isinstance(el, Joint) and el.type == "R" and pos and ei + 1 < len(chain.elements):
                nxt = chain.elements[ei + 1]
                nxt_pos = {d.component for d in getattr(nxt, "defects", ())} & set("abc")
                if nxt_pos == set("abc"):
                    comp = largest(pos, "abc", n0)
                    if abs(n0["abc".index(comp)]) > 1e-9:
                        out[defects[comp]] = (
                            f"shift along the joint's own axis, equal to the shift d{'c'} of the next element '{nxt.name}'"
                        )
    return out


def _rank_gap(s: np.ndarray, rel: float = 1e-8) -> tuple[int, float, float]:
    """Numerical rank, gap ``s[r-1]/s[r]`` and threshold for singular values ``s``."""
    if s.size == 0 or s[0] == 0:
        return 0, float("inf"), 0.0
    thr = rel * s[0]
    r = int(np.sum(s > thr))
    if r == s.size:
        gap = float("inf")
    elif r == 0:
        gap = 0.0
    else:
        gap = float(s[r - 1] / max(s[r], np.finfo(float).tiny))
    return r, gap, float(thr)


def _clean_coefficient(c: float) -> float:
    if abs(c) < 1e-10:
        return 0.0
    frac = Fraction(c).limit_denominator(1000)
    if abs(float(frac) - c) < 1e-9 * max(1.0, abs(c)):
        return float(frac)
    return float(f"{c:.10g}")


#: a column becomes a relation's pivot only if its entry is at least this share of the largest entry left
PIVOT_SHARE = 0.1


def _relations(basis: np.ndarray, names: list[str], scale: np.ndarray) -> list[Relation]:
    """Readable relations from a basis of the constraint row space (dimensionless columns).

    Pivoted elimination (reduced row-echelon form) that prefers the parameters in their order
    (the paper's way of writing them: ``dK21 - dK23 = 0``) but takes a column as a pivot only where
    its entry is at least :data:`PIVOT_SHARE` of the largest entry left: a tiny pivot (a column the
    rows reach only by round-off) would divide round-off into coefficients of 1e12 and print the same
    relation several times.  The rows left without such a pivot in order take the largest entry left
    (complete pivoting).  The rows are turned into physical units (coefficients per rad or per mm)
    and cleaned of round-off; :func:`relations_span` checks that they span the basis at their
    printed digits.
    """
    if basis.size == 0:
        return []
    mat = basis.copy()
    rows, cols = mat.shape
    pivots: list[int] = []

    def eliminate(r: int, col: int) -> None:
        mat[r] /= mat[r, col]
        for other in range(rows):
            if other != r:
                mat[other] -= mat[other, col] * mat[r]

    pivot_row = 0
    for col in range(cols):
        if pivot_row >= rows:
            break
        rest = np.abs(mat[pivot_row:])
        top = float(rest.max()) if rest.size else 0.0
        p = pivot_row + int(np.argmax(rest[:, col]))
        if abs(mat[p, col]) < max(PIVOT_SHARE * top, 1e-9):
            continue
        mat[[pivot_row, p]] = mat[[p, pivot_row]]
        eliminate(pivot_row, col)
        pivots.append(col)
        pivot_row += 1
    while pivot_row < rows:  # what parameter order left: complete pivoting on the rest
        rest = np.abs(mat[pivot_row:])
        rest[:, pivots] = 0.0
        if rest.max() < 1e-9:
            break
        r, col = np.unravel_index(int(np.argmax(rest)), rest.shape)
        mat[[pivot_row, pivot_row + r]] = mat[[pivot_row + r, pivot_row]]
        eliminate(pivot_row, int(col))
        pivots.append(int(col))
        pivot_row += 1
    out = []
    for row in mat[:pivot_row]:
        # entries at the round-off of the analysis (below 1e-7 of the row's largest) are not terms: led by one, a
        # relation would carry the inverse of round-off as its other coefficients
        kept = np.nonzero(np.abs(row) > 1e-7 * float(np.max(np.abs(row))))[0]
        phys = row / scale  # coefficient per physical unit
        phys = phys / phys[kept[0]]
        terms = {}
        for j in kept:
            c = _clean_coefficient(float(phys[j]))
            if c != 0.0:
                terms[names[j]] = c
        out.append(Relation(terms, format_relation(terms)))
    return out


def _printed(c: float, digits: int) -> tuple[str, float]:
    """A coefficient as printed (a fraction of denominator up to 1000 when it is one, else ``digits`` significant
    digits) and the value that text stands for."""
    frac = Fraction(c).limit_denominator(1000)
    if frac.denominator > 1 and abs(float(frac) - c) <= 1e-12 * max(1.0, abs(c)):
        return f"{abs(frac.numerator)}/{frac.denominator}", float(frac)
    text = f"{abs(c):.{digits}g}"
    return text, float(text) if c >= 0 else -float(text)


def format_relation(terms: dict, digits: int = 6) -> str:
    """``{"dK21": 1, "dK23": -1}`` -> ``dK21 - dK23 = 0`` (coefficients with ``digits`` significant digits, or as
    fractions when they are)."""
    parts = []
    for i, (n, c) in enumerate(terms.items()):
        sign = "-" if c < 0 else "+"
        mag = abs(c)
        coef = "" if mag == 1.0 else f"{_printed(c, digits)[0]}*"
        parts.append((f"-{coef}{n}" if sign == "-" else f"{coef}{n}") if i == 0 else f" {sign} {coef}{n}")
    return "".join(parts) + " = 0"


def relations_span(relations: list, basis: np.ndarray, names: list[str], scale: np.ndarray, digits: int = 6) -> dict:
    """How well the relations *as printed* (``digits`` significant digits) span the analysis' relation subspace.

    Returns the sine of the largest principal angle between the two row spaces (dimensionless
    coefficients), the rank of the printed rows against their number (distinct relations), and the
    largest coefficient.
    """
    if not relations or basis.size == 0:
        return {"angle": 0.0, "rank": 0, "relations": 0, "largest_coefficient": 0.0}
    index = {n: i for i, n in enumerate(names)}
    printed = np.zeros((len(relations), len(names)))
    for k, rel in enumerate(relations):
        for n, c in rel.terms.items():
            printed[k, index[n]] = _printed(c, digits)[1] * scale[index[n]]  # per dimensionless defect
    q_b = np.linalg.svd(basis, full_matrices=False)[2]
    u, s, vt = np.linalg.svd(printed, full_matrices=False)
    rank = int(np.sum(s > 1e-9 * s[0])) if s.size and s[0] > 0 else 0
    q_p = vt[:rank]
    outside = q_b - (q_b @ q_p.T) @ q_p  # the analysis' relations the printed ones miss
    angle = float(np.linalg.norm(outside, 2)) if outside.size else 0.0
    back = q_p - (q_p @ q_b.T) @ q_b  # printed relations outside the analysis' subspace
    angle = max(angle, float(np.linalg.norm(back, 2)) if back.size else 0.0)
    return {"angle": min(angle, 1.0), "rank": rank, "relations": len(relations), "digits": digits,
            "largest_coefficient": float(max(abs(c) for rel in relations for c in rel.terms.values()))}


def analyze(
    mechanism: Mechanism,
    n_configurations: int = 24,
    seed: int = 0,
    configurations: np.ndarray | None = None,
    kinematics: Kinematics | None = None,
    samples: int = 1,
) -> StationarityResult:
    """Classify every defect parameter of ``mechanism`` (paper 1, eq. 3, automated).

    With ``samples >= 2`` the analysis is repeated on further independent samples
    (seeds ``seed + 1``, ``seed + 2``, ...; each assembled on the home branch by certified
    continuation, from the nearest configuration already assembled) and compared with the
    first: rank, admissible dimension, mobility, every verdict and the admissible subspace
    (largest principal angle).  The result is the first sample's, with ``stability``
    saying whether all samples agreed and naming every disagreement
    (:func:`compare_samples`).

    Parameters
    ----------
    mechanism : Mechanism
        Nominal model.
    n_configurations : int
        Configurations sampled over the actuated ranges (ignored if ``configurations``).
    seed : int
        Seed for the sample.
    configurations : ndarray, (K, n_q), optional
        Assembled configurations to use instead of a random sample.
    kinematics : Kinematics, optional
        Reuse an existing forward model.
    samples : int
        Independent samples to analyse and compare (1: no stability check; ignored
        when ``configurations`` is given).

    Returns
    -------
    StationarityResult

    Raises
    ------
    AnalysisError
        If the nominal mechanism cannot move or no configuration assembles.
    """
    t0 = time.perf_counter()
    kin = kinematics or Kinematics(mechanism)
    first = _analyze_once(mechanism, n_configurations, seed, configurations, kin)
    if configurations is not None or samples < 2:
        return first
    others = []
    pool = first.configurations
    for i in range(1, samples):
        sample = sample_configurations(kin, n_configurations, seed=seed + i, pool=pool)
        res = _analyze_once(mechanism, n_configurations, seed + i, sample.q, kin)
        res.warnings = list(sample.warnings) + res.warnings
        others.append(res)
        pool = np.concatenate([pool, sample.q])
    first.stability = compare_samples([first] + others, [seed + i for i in range(samples)])
    for res in others:
        for w in res.warnings:
            if w not in first.warnings:
                first.warnings.append(f"(sample with seed {seed + others.index(res) + 1}) {w}")
    first.elapsed = time.perf_counter() - t0
    return first


def compare_samples(results: list, seeds: list) -> dict:
    """Compare analyses of independent samples: rank, admissible dimension, mobility, verdicts, subspace.

    Parameters
    ----------
    results : list of StationarityResult
        The first is the reference.
    seeds : list of int
        Their seeds (for the messages).

    Returns
    -------
    dict
        ``samples``, ``seeds``, ``configurations``, ``ranks``, ``admissible_dimensions``,
        ``singular_value_gaps``, ``max_subspace_angle`` (rad, largest principal angle
        between the admissible subspaces), ``stable`` and ``disagreements`` (sentences),
        ``summary`` (one sentence for the user).
    """
    ref = results[0]
    n_active = lambda r: sum(p.verdict != "gauge" for p in r.parameters)  # noqa: E731
    dims = [n_active(r) - r.rank for r in results]
    problems: list[str] = []
    angle = 0.0
    for r, sd in zip(results[1:], seeds[1:]):
        tag = f"seed {seeds[0]} and seed {sd}"
        if r.rank != ref.rank:
            problems.append(f"the constraint rank differs between {tag}: {ref.rank} and {r.rank}")
        if n_active(r) - r.rank != dims[0]:
            problems.append(f"the admissible dimension differs between {tag}: {dims[0]} and {n_active(r) - r.rank}")
        if r.mobility != ref.mobility:
            problems.append(f"the mobility differs between {tag}: {ref.mobility} and {r.mobility}")
        changed = []
        for a, b in zip(ref.parameters, r.parameters):
            if a.verdict != b.verdict or (a.influential is not None and b.influential is not None
                                          and a.influential != b.influential):
                va = a.verdict + ("" if a.influential is None else (" influential" if a.influential else " non-influent"))
                vb = b.verdict + ("" if b.influential is None else (" influential" if b.influential else " non-influent"))
                changed.append(f"{a.name} ({va} / {vb})")
        if changed:
            problems.append(f"{len(changed)} verdict(s) differ between {tag}: " + ", ".join(changed))
        ba, bb = ref.admissible_basis, r.admissible_basis
        if ba is not None and bb is not None and ba.shape[1] and bb.shape[1]:
            if ba.shape[1] == bb.shape[1]:
                # sine of the largest principal angle: the part of one basis outside the other
                outside = bb - ba @ (ba.T @ bb)
                pair = float(np.arcsin(np.clip(np.linalg.norm(outside, 2), 0.0, 1.0)))
                angle = max(angle, pair)
                if pair > 1e-6:
                    problems.append(f"the admissible subspaces of {tag} differ by a principal angle of {pair:.3g} rad")
    stable = not problems
    n = len(results)
    if stable:
        summary = (f"stable across {n} independent samples (seeds {', '.join(str(s) for s in seeds)}; same rank "
                   f"{ref.rank}, admissible dimension {dims[0]} and verdicts; admissible subspaces within "
                   f"{angle:.1e} rad)")
    else:
        summary = f"NOT stable across {n} independent samples: " + "; ".join(problems)
    return {"samples": n, "seeds": list(seeds), "configurations": [r.n_configurations for r in results],
            "ranks": [r.rank for r in results], "admissible_dimensions": dims,
            "singular_value_gaps": [r.gap for r in results], "max_subspace_angle": angle,
            "stable": stable, "disagreements": problems, "summary": summary}


def _analyze_once(
    mechanism: Mechanism,
    n_configurations: int,
    seed: int,
    configurations: np.ndarray | None,
    kinematics: Kinematics,
) -> StationarityResult:
    """One analysis on one sample (the body of :func:`analyze`)."""
    t0 = time.perf_counter()
    kin = kinematics or Kinematics(mechanism)
    m = mechanism
    warns: list[str] = []
    if configurations is None:
        sample = sample_configurations(kin, n_configurations, seed=seed)
        q = sample.q
        warns += sample.warnings
    else:
        q = np.atleast_2d(np.asarray(configurations, dtype=float))
    st = kin.evaluate(q)
    n_xi = kin.n_xi
    names = [p.name for p in m.parameters]
    pscale = kin.parameter_scale
    a = kin.dimensionless(st.closure_xi, pscale)  # (K, m, n_xi)
    bq = kin.dimensionless(st.closure_q, kin.joint_scale)  # (K, m, n_q)
    bp = bq[:, :, m.passive]
    n_rows = a.shape[1]

    # Mobility and over-constraint of the nominal mechanism (generic rank of [B_p, B_a]).
    if n_rows:
        sv_full = np.linalg.svd(bq, compute_uv=False)
        full_rank = int(np.max(np.sum(sv_full > 1e-8 * sv_full[:, :1], axis=1)))
    else:
        full_rank = 0
    mobility = kin.n_q - full_rank
    overconstraint = n_rows - full_rank
    if mobility == 0:
        raise AnalysisError(
            f"the nominal mechanism '{m.name}' cannot move: its closure equations have rank {full_rank} for "
            f"{kin.n_q} joints (mobility 0)."
        )
    if mobility < len(m.actuated):
        warns.append(
            f"'{m.name}' has mobility {mobility} but {len(m.actuated)} actuated joints: the actuators are redundant."
        )

    # Left null space of B_s per configuration -> constraint rows U0^T A_s.
    blocks = []
    pinv_bp = []
    for kk in range(q.shape[0]):
        if n_rows == 0:
            break
        if bp.shape[2]:
            u, s, vt = np.linalg.svd(bp[kk], full_matrices=True)
            r = int(np.sum(s > 1e-8 * s[0])) if s.size and s[0] > 0 else 0
            pinv_bp.append(np.linalg.pinv(bp[kk], rcond=1e-8))
        else:
            u = np.eye(n_rows)
            r = 0
            pinv_bp.append(np.zeros((0, n_rows)))
        blocks.append(u[:, r:].T @ a[kk])
    g_full = np.concatenate(blocks, axis=0) if blocks else np.zeros((0, n_xi))

    gauges = gauge_parameters(m)
    active = [j for j, n in enumerate(names) if n not in gauges]
    g = g_full[:, active]
    if g.shape[0]:
        _, s, vt = np.linalg.svd(g, full_matrices=True)
    else:
        s, vt = np.zeros(0), np.eye(len(active))
    rank, gap, thr = _rank_gap(s)
    null = vt[rank:].T  # (n_active, dim S)
    row = vt[:rank]  # (rank, n_active)
    admissible = np.linalg.norm(null, axis=1) if null.size else np.zeros(len(active))
    forced_local = [i for i in range(len(active)) if admissible[i] < _ZERO]
    nonforced_local = [i for i in range(len(active)) if admissible[i] >= _ZERO]
    # Relations among non-forced parameters: projection of row(G) on their coordinates.
    rel_basis = np.zeros((0, len(nonforced_local)))
    if rank and nonforced_local:
        proj = row[:, nonforced_local]
        u2, s2, vt2 = np.linalg.svd(proj, full_matrices=False)
        # The row basis is orthonormal: a genuine relation keeps an O(1) projection.
        r2 = int(np.sum(s2 > 1e-6)) if s2.size else 0
        rel_basis = vt2[:r2]
    rel_weight = np.linalg.norm(rel_basis, axis=0) if rel_basis.size else np.zeros(len(nonforced_local))
    rel_names = [names[active[i]] for i in nonforced_local]
    rel_scale = pscale[[active[i] for i in nonforced_local]]
    relations = _relations(rel_basis, rel_names, rel_scale)
    for digits in (6, 8, 10):  # as few digits as keep the printed relations on the analysis' subspace to 1e-6
        span = relations_span(relations, rel_basis, rel_names, rel_scale, digits)
        if span["angle"] <= 1e-6:
            for rel in relations:
                rel.text, rel.digits = format_relation(rel.terms, digits), digits
            break
    if relations and (span["angle"] > 1e-6 or span["rank"] < span["relations"]):
        warns.append(f"the {len(relations)} printed relations span the analysis' relations only to "
                     f"{span['angle']:.1e} rad at their printed digits (rank {span['rank']} of "
                     f"{span['relations']}): read the coefficients of the JSON ('terms'), not the text.")

    # Influence on the output frame with the passive joints following (K = O_xi - O_p B^+ A).
    o_xi = kin.dimensionless(st.output_xi, pscale)
    o_q = kin.dimensionless(st.output_q, kin.joint_scale)
    o_p = o_q[:, :, m.passive]
    infl = []
    for kk in range(q.shape[0]):
        kx = o_xi[kk]
        if n_rows and bp.shape[2]:
            kx = kx - o_p[kk] @ (pinv_bp[kk] @ a[kk])
        infl.append(kx[:, active])
    infl = np.concatenate(infl, axis=0)  # (6K, n_active)
    proj_s = null @ null.T if null.size else np.zeros((len(active), len(active)))
    influence = np.linalg.norm(infl @ proj_s, axis=0) / np.sqrt(q.shape[0])
    col_infl = np.linalg.norm(infl, axis=0) / np.sqrt(q.shape[0])
    if null.size:
        s_inf = np.linalg.svd(infl @ null, compute_uv=False)
        infl_rank, infl_gap, _ = _rank_gap(s_inf)
    else:
        infl_rank, infl_gap = 0, float("inf")

    verdicts = []
    local_of = {j: i for i, j in enumerate(active)}
    nf_pos = {i: k for k, i in enumerate(nonforced_local)}
    for j, p in enumerate(m.parameters):
        if p.name in gauges:
            verdicts.append(ParameterVerdict(p.name, p.element, p.component, p.unit, "gauge", None, 0.0, 0.0,
                                             gauges[p.name]))
            continue
        i = local_of[j]
        if i in forced_local:
            verdicts.append(ParameterVerdict(
                p.name, p.element, p.component, p.unit, "forced", None, float(admissible[i]), 0.0,
                "the passive joints cannot absorb it at every configuration"))
            continue
        w = rel_weight[nf_pos[i]] if rel_weight.size else 0.0
        inf_val = float(influence[i])
        influential = bool(inf_val > 1e-7 * max(1.0, float(np.max(col_infl)) if col_infl.size else 1.0))
        if w > _ZERO:
            verdicts.append(ParameterVerdict(
                p.name, p.element, p.component, p.unit, "coupled", influential, float(admissible[i]), inf_val,
                "admissible only in combination with other defects (see relations)"))
        else:
            verdicts.append(ParameterVerdict(
                p.name, p.element, p.component, p.unit, "free", influential, float(admissible[i]), inf_val,
                "moves the output frame" if influential else "absorbed by the passive joints; no effect on the output"))
    if gap < 1e4 and rank < len(active):
        warns.append(
            f"the singular-value gap of the constraint matrix is only {gap:.3g}: the rank decision may not be trustworthy."
        )
    return StationarityResult(
        mechanism=m.name,
        parameters=verdicts,
        relations=relations,
        rank=rank,
        n_constraint_rows=int(g.shape[0]),
        singular_values=[float(v) for v in s],
        gap=gap,
        threshold=thr,
        mobility=mobility,
        overconstraint=overconstraint,
        n_closure_equations=n_rows,
        n_configurations=int(q.shape[0]),
        influential_rank=infl_rank,
        influential_gap=infl_gap,
        length_scale=kin.length_scale,
        elapsed=time.perf_counter() - t0,
        warnings=warns,
        configurations=q,
        admissible_basis=_embed(null, active, n_xi),
    )


def _embed(null: np.ndarray, active: list[int], n_xi: int) -> np.ndarray:
    """Admissible basis in the full (dimensionless) parameter space, gauge rows zero."""
    out = np.zeros((n_xi, null.shape[1] if null.ndim == 2 else 0))
    if out.shape[1]:
        out[active] = null
    return out
