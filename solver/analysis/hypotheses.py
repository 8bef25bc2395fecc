"""Designer's geometric hypotheses checked against the stationarity analysis (paper 1, Table 4).

Units: lengths in mm, angles in rad.

A hypothesis file (YAML) names axes and points of the skeleton and states relations
between them: ``parallel``, ``perpendicular``, ``collinear``, ``coplanar`` (two axes),
``point_on_axis``.  Each relation, linearised at the nominal geometry, is a set of
linear conditions ``H xi = 0`` on the defects.  Against the admissible subspace ``S``
of the stationarity analysis (the defects the mechanism tolerates):

* **required**: ``H`` vanishes on ``S``: every admissible defect already satisfies the
  hypothesis; it is implied by the forced constraints (and relations);
* **not required**: no part of ``H`` is implied: the hypothesis forbids defects the
  mechanism tolerates (over-restrictive, a tolerance paid for in manufacturing);
* **partly required**: some conditions of ``H`` are implied, others are not.

The geometry of every axis and point is followed along the chains from the base
with the joints held at the home configuration, which is how a designer states such
relations (between the frames of one body or across a joint whose motion does not
change them).

File format::

    format: hyperstat-hypotheses
    version: 1
    axes:                      # name: joint / fixed transform whose z axis (through its origin) it is
      u1: {element: "11"}
      leg1: {element: "41"}
      l12: {through: [A1, B1]} # or the line through two named points
    points:
      A3: {element: "13"}      # origin of the element's frame L_i (or of a frame: {frame: MPS})
    hypotheses:
      - {id: u1_par_u3, parallel: [u1, u3]}
      - {id: A1A3_on_u1, point_on_axis: [A3, u1]}
"""

from __future__ import annotations

import re
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.analysis.stationarity import StationarityResult, gauge_parameters
from hyperstat.solver.analysis.verify import reassembly_residual

__all__ = ["Hypothesis", "HypothesisVerdict", "load_hypotheses", "parse_hypotheses", "check_hypotheses",
           "RELATIONS"]

RELATIONS = {
    "parallel": ("axis", "axis"),
    "perpendicular": ("axis", "axis"),
    "collinear": ("axis", "axis"),
    "coplanar": ("axis", "axis"),
    "point_on_axis": ("point", "axis"),
}
_ID = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


@dataclass
class Hypothesis:
    """One stated relation between two named entities."""

    id: str
    relation: str
    first: str
    second: str
    note: str = ""


@dataclass
class HypothesisVerdict:
    """Verdict on one hypothesis.

    Attributes
    ----------
    id : str
        Hypothesis id.
    verdict : str
        ``required``, ``not-required`` or ``partly-required``.
    reason : str
        One or two sentences: what implies it, or which tolerated defects it forbids.
    conditions : int
        Number of independent linear conditions the hypothesis states.
    implied : int
        How many of them the forced constraints imply.
    forbids : list of str
        Admissible defect parameters the hypothesis restricts (when not implied).
    implied_by : list of str
        Forced parameters and relation texts that imply it.
    evidence : str
        Nonlinear re-assembly with a defect that violates the hypothesis: for a
        hypothesis that is not (fully) required, an admissible defect that breaks it
        still assembles (round-off residual); for a required one, breaking it leaves a
        first-order residual.
    violation : float
        How much that defect breaks the hypothesis (rad, or mm for point/line conditions).
    residual : float
        Largest closure residual after re-assembly with that defect (mm).
    """

    id: str
    verdict: str
    reason: str
    conditions: int
    implied: int
    forbids: list = field(default_factory=list)
    implied_by: list = field(default_factory=list)
    evidence: str = ""
    violation: float = 0.0
    residual: float = 0.0

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        return asdict(self)


def _require(cond: bool, where: str, message: str) -> None:
    if not cond:
        raise DataError(f"{where}: {message}")


def parse_hypotheses(doc: Any, mechanism: Mechanism, source: str = "hypotheses") -> tuple[dict, dict, list]:
    """Validate a hypothesis document against a mechanism; returns (axes, points, hypotheses).

    Raises
    ------
    DataError
        Naming the file and the field at fault.
    """
    _require(isinstance(doc, dict), source, "the file must hold a mapping at the top level.")
    _require(doc.get("format") == "hyperstat-hypotheses", source,
             f"field 'format' must be 'hyperstat-hypotheses', got {doc.get('format')!r}.")
    _require(doc.get("version") == 1, source, f"field 'version' is {doc.get('version')!r}, this hyperstat reads 1.")
    elements = {el.name for ch in mechanism.chains for el in ch.elements if el.kind != "frame"}
    frames = set(mechanism.frames)
    axes: dict[str, dict] = {}
    points: dict[str, dict] = {}
    for kind, table, target in (("axes", doc.get("axes", {}), axes), ("points", doc.get("points", {}), points)):
        _require(isinstance(table, dict), source, f"field '{kind}' must be a mapping of names.")
        for name, spec in table.items():
            where = f"{source}: field '{kind}.{name}'"
            _require(isinstance(name, str) and _ID.match(name) is not None, source,
                     f"name {name!r} in '{kind}' must be an identifier.")
            _require(isinstance(spec, dict) and len(spec) == 1, where.split(": ", 1)[0],
                     f"field '{kind}.{name}' must have exactly one of 'element', 'frame'" +
                     (", 'through'." if kind == "axes" else "."))
            key, value = next(iter(spec.items()))
            if key == "element":
                _require(str(value) in elements, source,
                         f"field '{kind}.{name}.element' names '{value}', which is not a joint or fixed transform of "
                         f"'{mechanism.name}'.")
                target[name] = {"element": str(value)}
            elif key == "frame":
                _require(str(value) in frames, source,
                         f"field '{kind}.{name}.frame' names '{value}', which is not a frame of '{mechanism.name}'.")
                target[name] = {"frame": str(value)}
            elif key == "through" and kind == "axes":
                _require(isinstance(value, list) and len(value) == 2, source,
                         f"field 'axes.{name}.through' must list two point names.")
                _require(str(value[0]) != str(value[1]), source,
                         f"field 'axes.{name}.through' names point '{value[0]}' twice; an axis needs two points.")
                target[name] = {"through": [str(v) for v in value]}
            else:
                raise DataError(f"{source}: field '{kind}.{name}' has unknown key '{key}'.")
    for name, spec in axes.items():
        if "through" in spec:
            for pt in spec["through"]:
                _require(pt in points, source, f"field 'axes.{name}.through' names point '{pt}', which is not declared.")
    items = doc.get("hypotheses")
    _require(isinstance(items, list) and items, source, "field 'hypotheses' must be a non-empty list.")
    hyps: list[Hypothesis] = []
    seen: set[str] = set()
    for i, item in enumerate(items):
        where = f"hypotheses[{i}]"
        _require(isinstance(item, dict), source, f"field '{where}' must be a mapping.")
        hid = item.get("id")
        _require(isinstance(hid, str) and _ID.match(hid) is not None, source,
                 f"field '{where}.id' must be an identifier, got {hid!r}.")
        _require(hid not in seen, source, f"field '{where}.id' '{hid}' is used twice.")
        seen.add(hid)
        rels = [k for k in item if k in RELATIONS]
        unknown = [k for k in item if k not in RELATIONS and k not in ("id", "note")]
        _require(not unknown, source, f"field '{where}.{unknown[0] if unknown else ''}' is not a relation; use one of "
                 f"{', '.join(RELATIONS)}.")
        _require(len(rels) == 1, source, f"field '{where}' must state exactly one relation ({', '.join(RELATIONS)}).")
        rel = rels[0]
        args = item[rel]
        _require(isinstance(args, list) and len(args) == 2, source, f"field '{where}.{rel}' must list two names.")
        kinds = RELATIONS[rel]
        for k, (arg, kind) in enumerate(zip(args, kinds)):
            table = axes if kind == "axis" else points
            _require(str(arg) in table, source,
                     f"field '{where}.{rel}[{k}]' names '{arg}', which is not a declared {kind}.")
        hyps.append(Hypothesis(hid, rel, str(args[0]), str(args[1]), str(item.get("note", ""))))
    return axes, points, hyps


def load_hypotheses(path: str | Path, mechanism: Mechanism) -> tuple[dict, dict, list]:
    """Read a YAML hypothesis file (``yaml.safe_load``: no code is ever evaluated)."""
    from hyperstat.solver.strict_load import load_yaml

    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such hypothesis file.")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise DataError(f"{path}: not valid YAML (not UTF-8 text).") from None
    axes, points, hyps = parse_hypotheses(load_yaml(text, str(path)), mechanism, str(path))
    _refuse_coincident_points(mechanism, axes, points, str(path))
    return axes, points, hyps


def _refuse_coincident_points(mechanism: Mechanism, axes: dict, points: dict, source: str) -> None:
    """An axis through two points needs two distinct points at the home configuration."""
    through = {name: spec["through"] for name, spec in axes.items() if "through" in spec}
    if not through:
        return
    el_pose, frame_pose, _ = _geometry(Kinematics(mechanism))

    def where(p: str) -> np.ndarray:
        spec = points[p]
        return (el_pose[spec["element"]] if "element" in spec else frame_pose[spec["frame"]])[:3, 3]

    for name, (a, b) in through.items():
        pa, pb = where(a), where(b)
        if np.linalg.norm(pb - pa) < 1e-9 * max(1.0, float(np.linalg.norm(pa))):
            raise DataError(f"{source}: field 'axes.{name}.through' names points '{a}' and '{b}', which coincide at "
                            f"the home configuration: they give no direction.")


def _geometry(kin: Kinematics) -> tuple[dict, dict, dict]:
    """World frames at home and the spatial twists of the defects acting on each of them.

    Returns (element frames by name, frame poses by name, twists by element name or
    ``"frame:" + name``: arrays (n_xi, 6)); a defect acts on a frame when its element
    lies on the frame's path from the base (chains followed, joints at home).
    """
    m = kin.mechanism
    st = kin.evaluate(m.home[None, :])
    el_pose = {m.chains[ci].elements[ei].name: t[0] for (ci, ei), t in st.element_frames.items()}
    frame_pose = {k: v[0] for k, v in st.frames.items()}
    tw = st.defect_twists[0]
    where = [(p.chain, p.index) for p in m.parameters]

    def masked(path: set) -> np.ndarray:
        return tw * np.array([w in path for w in where], dtype=float)[:, None]

    twists: dict[str, np.ndarray] = {}
    for ci, ch in enumerate(m.chains):
        start_path = set(m.path_to(ch.start))
        for ei, el in enumerate(ch.elements):
            twists[el.name] = masked(start_path | {(ci, k) for k in range(ei + 1)})
    for f in m.frames:
        twists["frame:" + f] = masked(set(m.path_to(f)))
    return el_pose, frame_pose, twists


def _rows(h: Hypothesis, axes: dict, points: dict, el_pose: dict, frame_pose: dict, twists: dict) -> np.ndarray:
    """Linear conditions of one hypothesis on the defects, shape (k, n_xi) (physical units)."""

    def point(name: str) -> tuple[np.ndarray, np.ndarray]:
        spec = points[name]
        key = spec.get("element")
        t = el_pose[key] if key else frame_pose[spec["frame"]]
        tw = twists[key] if key else twists["frame:" + spec["frame"]]
        p = t[:3, 3]
        return p, tw[:, 3:] + np.cross(tw[:, :3], p)  # (n_xi, 3) velocity of the point

    def axis(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        spec = axes[name]
        if "through" in spec:
            (pa, va), (pb, vb) = point(spec["through"][0]), point(spec["through"][1])
            d = pb - pa
            if np.linalg.norm(d) < 1e-9 * max(1.0, float(np.linalg.norm(pa))):
                raise DataError(f"axis '{name}' goes through points '{spec['through'][0]}' and "
                                f"'{spec['through'][1]}', which coincide at the home configuration: no direction.")
            n = d / np.linalg.norm(d)
            dn = ((vb - va) - np.outer((vb - va) @ n, n)) / np.linalg.norm(d)
            return pa, n, va, dn
        key = spec.get("element")
        t = el_pose[key] if key else frame_pose[spec["frame"]]
        tw = twists[key] if key else twists["frame:" + spec["frame"]]
        p, n = t[:3, 3], t[:3, 2]
        return p, n, tw[:, 3:] + np.cross(tw[:, :3], p), np.cross(tw[:, :3], n)

    def perp_basis(n: np.ndarray) -> np.ndarray:
        a = np.eye(3)[int(np.argmin(np.abs(n)))]
        e1 = np.cross(n, a)
        e1 /= np.linalg.norm(e1)
        return np.stack([e1, np.cross(n, e1)])

    def on_axis(pp: np.ndarray, vp: np.ndarray, pa: np.ndarray, n: np.ndarray, va: np.ndarray, dn: np.ndarray):
        t = float(n @ (pp - pa))
        return perp_basis(n) @ (vp - va - dn * t).T  # (2, n_xi)

    if h.relation == "point_on_axis":
        pp, vp = point(h.first)
        pa, n, va, dn = axis(h.second)
        return on_axis(pp, vp, pa, n, va, dn)
    pa, na, va, dna = axis(h.first)
    pb, nb, vb, dnb = axis(h.second)
    if h.relation == "perpendicular":
        return (dna @ nb + dnb @ na)[None, :]
    if h.relation == "coplanar":
        cross = np.cross(na, nb)
        return ((vb - va) @ cross + (pb - pa) @ (np.cross(dna, nb).T + np.cross(na, dnb).T))[None, :]
    s = 1.0 if na @ nb >= 0 else -1.0
    par = perp_basis(na) @ (dna - s * dnb).T
    if h.relation == "parallel":
        return par
    return np.vstack([par, on_axis(pb, vb, pa, na, va, dna)])  # collinear


def _nominal_holds(h: Hypothesis, axes: dict, points: dict, el_pose: dict, frame_pose: dict) -> float:
    """Residual of the relation at the nominal geometry (0 when the hypothesis holds nominally)."""
    def p_of(name):
        spec = points[name]
        return (el_pose[spec["element"]] if "element" in spec else frame_pose[spec["frame"]])[:3, 3]

    def a_of(name):
        spec = axes[name]
        if "through" in spec:
            a, b = p_of(spec["through"][0]), p_of(spec["through"][1])
            return a, (b - a) / np.linalg.norm(b - a)
        t = el_pose[spec["element"]] if "element" in spec else frame_pose[spec["frame"]]
        return t[:3, 3], t[:3, 2]

    if h.relation == "point_on_axis":
        p = p_of(h.first)
        a, n = a_of(h.second)
        r = p - a
        return float(np.linalg.norm(r - (r @ n) * n))
    (a, na), (b, nb) = a_of(h.first), a_of(h.second)
    if h.relation == "perpendicular":
        return abs(float(na @ nb))
    if h.relation == "parallel":
        return float(np.linalg.norm(np.cross(na, nb)))
    if h.relation == "coplanar":
        return abs(float((b - a) @ np.cross(na, nb)))
    r = b - a
    return float(np.linalg.norm(np.cross(na, nb)) + np.linalg.norm(r - (r @ na) * na))


def check_hypotheses(
    mechanism: Mechanism,
    result: StationarityResult,
    axes: dict,
    points: dict,
    hypotheses: list[Hypothesis],
    kinematics: Kinematics | None = None,
    evidence: bool = True,
    delta: float = 1e-4,
) -> list[HypothesisVerdict]:
    """Verdict on each hypothesis against the admissible defects of ``result``.

    With ``evidence`` each verdict is backed by a nonlinear re-assembly at four of the
    analysed configurations with a defect of dimensionless size ``delta`` that breaks
    the hypothesis (see :class:`HypothesisVerdict`).

    Raises
    ------
    DataError
        If a hypothesis does not even hold at the nominal geometry.
    """
    kin = kinematics or Kinematics(mechanism)
    el_pose, frame_pose, twists = _geometry(kin)
    scale = kin.parameter_scale
    lc = kin.length_scale
    names = [p.name for p in mechanism.parameters]
    gauges = gauge_parameters(mechanism)
    keep = np.array([n not in gauges for n in names])
    basis = result.admissible_basis  # dimensionless
    forced = set(result.by_verdict("forced"))
    out = []
    for h in hypotheses:
        nominal = _nominal_holds(h, axes, points, el_pose, frame_pose)
        if nominal > 1e-6 * lc:
            raise DataError(f"hypothesis '{h.id}' ({h.relation} {h.first}, {h.second}) does not hold at the nominal "
                            f"geometry of '{mechanism.name}' (off by {nominal:.3g}).")
        rows = _rows(h, axes, points, el_pose, frame_pose, twists)
        # dimensionless: length conditions divided by the length scale, columns per unit dimensionless defect
        unit = np.array([lc if h.relation == "point_on_axis" or (h.relation == "collinear" and i >= 2) else
                         (lc if h.relation == "coplanar" else 1.0) for i in range(rows.shape[0])])
        hd = rows * scale[None, :] / unit[:, None]
        hd[:, ~keep] = 0.0
        sv = np.linalg.svd(hd, compute_uv=False)
        rank_h = int(np.sum(sv > 1e-8 * max(1.0, sv[0] if sv.size else 1.0)))
        hs = hd @ basis if basis is not None and basis.size else np.zeros((hd.shape[0], 0))
        sv_s = np.linalg.svd(hs, compute_uv=False) if hs.size else np.zeros(0)
        rank_s = int(np.sum(sv_s > 1e-7))
        implied = rank_h - rank_s
        restricted = hs @ basis.T if hs.size else np.zeros_like(hd)
        forbids = [names[j] for j in np.nonzero(np.max(np.abs(restricted), axis=0) > 1e-7)[0]] if hs.size else []
        involved = [names[j] for j in np.nonzero(np.max(np.abs(hd), axis=0) > 1e-9)[0]]
        implied_by = [n for n in involved if n in forced]
        for rel in result.relations:
            if set(rel.terms) & set(involved):
                implied_by.append(rel.text)
        direct = [n for n in involved if n in forbids]
        through = [n for n in forbids if n not in direct]
        if rank_h == 0:
            verdict, reason = "required", "no defect of the model can change it (it holds by construction)"
        elif rank_s == 0:
            verdict = "required"
            reason = "implied by the over-constraint: " + (", ".join(implied_by) or "the forced constraints")
        elif implied == 0:
            verdict = "not-required"
            reason = ("over-restrictive: the mechanism assembles and moves with " + ", ".join(direct) + " != 0"
                      + (f" (together with {', '.join(through)}, through the relations)" if through else "")
                      + ", which it forbids")
        else:
            verdict = "partly-required"
            reason = (f"{implied} of its {rank_h} conditions follow from the over-constraint ("
                      + (", ".join(implied_by) or "forced constraints") + "); the rest forbids tolerated defects ("
                      + ", ".join(forbids) + ")")
        item = HypothesisVerdict(h.id, verdict, reason, rank_h, implied, forbids, implied_by)
        if evidence and rank_h:
            _evidence(item, kin, result, hd, hs, basis, scale, unit, delta)
        out.append(item)
    return out


def _evidence(item: HypothesisVerdict, kin: Kinematics, result: StationarityResult, hd: np.ndarray,
              hs: np.ndarray, basis: np.ndarray, scale: np.ndarray, unit: np.ndarray, delta: float) -> None:
    """Re-assemble with a defect that breaks the hypothesis (nonlinear evidence)."""
    q0 = result.configurations[:4]
    if item.verdict == "required":
        direction = hd[int(np.argmax(np.linalg.norm(hd, axis=1)))]
        direction = direction / np.linalg.norm(direction)
    else:
        _, _, vt = np.linalg.svd(hs)
        direction = basis @ vt[0]
        direction /= np.linalg.norm(direction)
    violation = float(np.max(np.abs(hd @ direction * unit))) * delta
    residual, _ = reassembly_residual(kin, q0, direction * delta * scale)
    item.violation = violation
    item.residual = residual
    per_unit = residual / (delta * kin.length_scale)
    if item.verdict == "required":
        item.evidence = (f"breaking it by {violation:.2e} leaves a closure residual of {residual:.2e} mm after "
                         f"re-assembly: the mechanism no longer assembles")
    else:
        item.evidence = (f"an admissible defect that breaks it by {violation:.2e} re-assembles with a residual of "
                         f"{residual:.2e} mm ({'round-off' if per_unit < 1e-6 else 'second order'})")
