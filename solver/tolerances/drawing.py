"""Part drawings: ISO 1101 frames on real features, per part, with ISO 5459 datum systems.

Units: mm and rad; a frame's zone is a length in mm; points and directions in the base frame at home.

A tolerance of hyperstat is a statement about defect parameters (``dK21 - dK23 = 0 +- 7.88e-4 rad``);
a workshop releases part drawings.  :func:`part_drawings` writes every tolerance that has a value
(assembly conditions, accuracy-critical and compensable tolerances) as frames on the parts'
features (:mod:`hyperstat.solver.tolerances.parts`), each referred to its part's datum system
(:mod:`hyperstat.solver.tolerances.datums`), so that every statement stays within its value for
every deviation the frames admit:

1. **the statement as a physical quantity**: its terms, made independent of the gauges (a
   normalisation component or a shift along a joint's own axis builds the same mechanism as other
   parameters, :func:`hyperstat.solver.analysis.verify.gauge_equivalent`): ``s = sum a_k phi_k`` over
   the components ``phi_k`` of the features' deviations relative to their datum systems (least
   squares; a statement no component expresses is reported, never drawn);
2. **frames**: per feature and kind of component (tilt, shift, shift along a face's normal) one
   frame per component with a two-plane zone whose direction is stated (by ``A`` for a tilt toward
   ``A`` or a shift along it, by an orientation-plane indicator naming ``C`` otherwise), or one
   cylindrical zone (⌀) for both components where the part has no ``C``;
3. **a statement across parts** is split into equal shares per part (each part's frames keep its
   share), unless one of its components also carries another tolerance that the split would cut
   (a compensable value opened by calibration): it is then an **assembly requirement** naming its
   parts (the Tripteor's ``dK21 - dK23 = 0`` between two universal joints' crosses);
4. **allocation**: each frame's bound ``z`` (a tilt in rad, a half zone in mm) enters every statement
   it carries through its zone's support function (``|a|`` for a two-plane zone, ``||a||_2`` for a
   cylinder); the bounds grow together from equal shares until a statement binds, then the others
   go on (max-min, progressive filling: a closed form per step);
5. zones are rounded down (:func:`safe_round`): a tilt ``z`` over a feature of length ``L`` is a
   zone ``z L``; a half zone ``z`` a zone ``2 z``.

The frames' semantics (what a zone admits, which datums lock what) are those of
``docs/drawing-format.md``; ``tests/solver/tolerances/test_part_drawings.py`` re-derives them
without this module.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.kinematics.model import Mechanism

__all__ = ["safe_round", "SYMBOLS", "part_drawings", "add_drawing", "statement_functional", "provisional_drawings",
           "campaign_words", "PRACTICAL_ZONE_MM", "PRACTICAL_SIZE_WARNING", "practical_size_warning"]

#: ISO 1101 symbols
SYMBOLS = {"parallelism": "\u2225", "perpendicularity": "\u27c2", "angularity": "\u2220", "position": "\u2316",
           "coaxiality": "\u25ce"}
_DIAMETER = "\u2300"
_ORIENTATION = ("parallelism", "perpendicularity", "angularity")
_PRIORITY = {"tilt": 0, "normal": 1, "shift": 2}
_SEAT_ORDER = {"seat": 0, "seatface": 1, "seatflat": 2}  # the seat's bore first: the longest lever, the widest zone


#: the smallest zone (mm) a frame states without a warning: 0.3 µm, the finest standard tolerance grade of ISO 286-1
#: (IT01, nominal sizes up to 3 mm: a grade for gauges).  A workshop is never asked to hold a size that closely on the
#: smallest part, let alone an orientation or a position on a mechanism's part; a zone below it is a value no part
#: can be made to, however right the model that computed it
PRACTICAL_ZONE_MM = 3e-4
#: the start of the classification's warning that names the frames below :data:`PRACTICAL_ZONE_MM` (the report's
#: page 1 carries it whole)
PRACTICAL_SIZE_WARNING = "PRACTICAL SIZE: "


def safe_round(value: float | None, digits: int = 3) -> float | None:
    """``value`` rounded towards zero to ``digits`` significant digits: a tolerance never opens by rounding.

    >>> safe_round(1.76777e-3)
    0.00176
    >>> safe_round(0.0999999)
    0.0999
    """
    if value is None or not math.isfinite(value) or value == 0:
        return value
    exponent = math.floor(math.log10(abs(value))) - digits + 1
    step = 10.0 ** exponent
    out = math.floor(abs(value) / step * (1 + 1e-12)) * step  # the 1e-12 keeps 0.00176 from reading 0.00175999
    if out > abs(value):
        out -= step
    return float(f"{math.copysign(out, value):.{digits}g}")


def campaign_words(cl) -> str:
    """The declared calibration campaign, as a drawing's note states the condition of a value with calibration: the
    measurements, the tracker frame and the target offsets; and, where hyperstat's own calibration (identify,
    export-controller) fits what the declaration holds and that matters (the classification's warning), so.

    >>> from types import SimpleNamespace as NS
    >>> decl = NS(measurement_kind="positions", targets_mm=((0, 0, 0),), noise_mm=0.002, frame="registered",
    ...           offsets="known")
    >>> campaign_words(NS(declaration=decl, calibration={}))
    'positions, 1 target(s), noise 0.002 mm, the tracker frame registered on references of the base, the target \
offsets known'
    >>> words = campaign_words(NS(declaration=decl, calibration={"as_identify_fits": {"worse": True}}))
    >>> "; " in words, words.endswith("report's page 1")  # one note: the part pages number a note's clauses at "; "
    (False, True)
    """
    decl = cl.declaration
    text = (f"{decl.measurement_kind}, {len(decl.targets_mm)} target(s), noise {decl.noise_mm:g} mm, the tracker frame "
            + ("registered on references of the base" if decl.frame == "registered" else "identified")
            + ", the target offsets " + ("known" if decl.offsets == "known" else "identified"))
    if ((cl.calibration or {}).get("as_identify_fits") or {}).get("worse"):
        held = [w for w, on in (("the tracker frame", decl.frame == "registered"),
                                ("the target offsets", decl.offsets == "known")) if on]
        text += (f", which 'hyperstat identify' and 'export-controller' do not hold ({' and '.join(held)} identified): "
                 "see the CALIBRATION CAMPAIGN warning on the report's page 1")
    return text


def statement_functional(mechanism: Mechanism, terms: dict, gauges: dict | None = None) -> np.ndarray:
    """The statement ``sum terms`` as a function of the defects that every gauge leaves unchanged, (n_xi,).

    A gauge ``g`` (a normalisation component, a shift along a joint's own axis) builds the same
    mechanism as a vector ``V_g`` of other parameters; the physical statement reads ``g`` as ``V_g``:
    ``s_g = s . V_g``.  ``gauges``: ``g -> V_g`` (computed when omitted).
    """
    index = mechanism.parameter_index
    s = np.zeros(len(index))
    for n, c in terms.items():
        if n in index:
            s[index[n]] += float(c)
    gauges = gauges if gauges is not None else gauge_vectors(mechanism)
    for _ in range(len(gauges) + 1):  # an equivalent may itself be a gauge (dc5 ≡ dc4 ≡ dc6): until it settles
        before = s.copy()
        for g, v in gauges.items():
            s[index[g]] = float(s @ v)
        if np.allclose(before, s, rtol=0, atol=1e-15):
            break
    return s


def gauge_vectors(mechanism: Mechanism) -> dict:
    """Gauge parameter -> the first-order vector of other parameters that builds the same mechanism (per unit)."""
    from hyperstat.solver.analysis.stationarity import gauge_parameters
    from hyperstat.solver.analysis.verify import gauge_equivalent

    out = {}
    comp = {p.name: p.component for p in mechanism.parameters}
    for g in gauge_parameters(mechanism):
        h = 1e-7 if comp[g] in "IJK" else 1.0
        out[g] = gauge_equivalent(mechanism, g, h) / h
    return out


@dataclass
class _Frame:
    ds: object  # DatumSystem
    feature: object  # Feature
    group: str
    comps: list
    shape: str
    direction: np.ndarray | None
    indicator: dict | None
    letters: list
    characteristic: str
    carries: dict = field(default_factory=dict)  # (statement id, part) -> support coefficient h
    ref: float = math.inf
    bound: float = 0.0
    binding: tuple | None = None
    id: str = ""


def _carry_coefficient(frame: _Frame, a: dict) -> float:
    vals = np.array([a.get(c.key, 0.0) for c in frame.comps])
    return float(np.linalg.norm(vals)) if frame.shape == "cylinder" else float(np.sum(np.abs(vals)))


def _orientation_plane(ds, m: np.ndarray) -> dict | None:
    """The orientation-plane indicator that states a zone normal ``m`` across ``A`` (None when ``A`` states it)."""
    a = ds.a.direction
    if abs(abs(m @ a) - 1) < 1e-9 or ds.nu_c is None:
        return None
    letter = ds.letter(ds.c)
    if abs(abs(m @ ds.nu_c) - 1) < 1e-9:  # the zone's planes parallel to the plane through A and C
        return {"kind": "orientation plane", "datum": letter, "relation": "parallel"}
    if abs(abs(m @ np.cross(a, ds.nu_c)) - 1) < 1e-9:  # perpendicular to it, parallel to A
        return {"kind": "orientation plane", "datum": letter, "relation": "perpendicular"}
    return {"kind": "orientation plane", "datum": letter, "relation": "at an angle"}


def _frames_of(ds, feature, group: str, comps: list) -> list:
    """The frames of the needed components ``comps`` of one feature and group (module docstring, step 2)."""
    a = ds.a.direction
    n = feature.direction
    has_c = ds.c is not None and feature is not ds.c
    letters_base = ["A"]
    out = []
    if group == "normal":
        c = comps[0]
        letters = letters_base + (["B"] if c.along_a and ds.b is not None else []) + \
            ([ds.letter(ds.c)] if c.affected and ds.c is not None else [])
        return [_Frame(ds, feature, group, [c], "two parallel planes", c.direction, None, letters, "position")]
    directional = all(c.oriented_by == "A" for c in comps) or has_c
    if directional and not (not has_c and any(c.affected for c in comps)):
        for c in comps:
            ind = None if c.oriented_by == "A" else _orientation_plane(ds, c.direction)
            if ind is not None and ind["relation"] == "at an angle":
                directional = False
                break
        else:
            for c in comps:
                ind = None if c.oriented_by == "A" else _orientation_plane(ds, c.direction)
                if group == "tilt":
                    letters = letters_base + ([ind["datum"]] if ind else [])
                    if ind is None:
                        ch = "perpendicularity" if abs(n @ a) < 1e-9 else "angularity"
                    else:
                        on_plane = abs(n @ ds.nu_c) < 1e-9
                        ch = "parallelism" if on_plane else ("perpendicularity" if abs(abs(n @ ds.nu_c) - 1) < 1e-9
                                                             else "angularity")
                else:
                    letters = letters_base + (["B"] if c.along_a and ds.b is not None else []) + \
                        ([ds.letter(ds.c)] if (ind or c.affected) and ds.c is not None else [])
                    ch = "position"
                out.append(_Frame(ds, feature, group, [c], "two parallel planes", c.direction, ind, letters, ch))
            return out
    # one cylindrical zone for the group (both components; a rotation about A the datums leave free moves neither
    # of the needed ones)
    full = [c for c in ds.components if c.feature is feature and c.group == group]
    if group == "tilt":
        ch = "parallelism" if abs(abs(n @ a) - 1) < 1e-9 else ("perpendicularity" if abs(n @ a) < 1e-9
                                                                else "angularity")
        return [_Frame(ds, feature, group, full, "cylinder", None, None, ["A"], ch)]
    d = feature.point - ds.a.point
    coaxial = abs(abs(n @ a) - 1) < 1e-9 and np.linalg.norm(d - (d @ a) * a) < 1e-6
    letters = letters_base + (["B"] if any(c.along_a for c in full) and ds.b is not None else []) + \
        ([ds.letter(ds.c)] if has_c and any(c.affected for c in comps) else [])  # located about A by C
    return [_Frame(ds, feature, group, full, "cylinder", None, None, letters,
                   "coaxiality" if coaxial and letters == ["A"] else "position")]


def _independent(comps: list) -> list:
    """The components whose rows add rank, tilts first, then faces, then shifts (a shift that only follows a tilt
    carries nothing of its own); a tool seat's last, so that it carries only what no joint's feature sees (the rows
    kept are independent: a statement the joints' features express keeps the same expression)."""
    order = sorted(range(len(comps)), key=lambda i: (comps[i].feature.side == "output",
                                                     _SEAT_ORDER.get(comps[i].feature.role, 0), _PRIORITY[comps[i].group]))
    kept, basis = [], np.zeros((0, len(comps[0].row))) if comps else np.zeros((0, 0))
    for i in order:
        row = comps[i].row
        norm = float(np.linalg.norm(row))
        if norm < 1e-12:
            continue
        r = row / norm
        if len(basis):
            r = r - basis.T @ (basis @ r)
        if np.linalg.norm(r) > 1e-8:
            basis = np.vstack([basis, r / np.linalg.norm(r)])
            kept.append(comps[i])
    return kept


def _express(phi: np.ndarray, s: np.ndarray) -> np.ndarray | None:
    """Least-squares coefficients of ``s`` on the rows of ``phi``, coefficients below 1e-6 of the largest dropped and
    the rest fitted again (a coefficient of round-off would give a frame an absurd zone)."""
    if not len(phi) or not np.any(s):
        return None
    a = np.linalg.lstsq(phi.T, s, rcond=None)[0]
    for _ in range(3):
        big = float(np.max(np.abs(a))) if a.size else 0.0
        if big == 0.0:
            return None
        keep = np.abs(a) > 1e-6 * big
        b = np.zeros_like(a)
        b[keep] = np.linalg.lstsq(phi[keep].T, s, rcond=None)[0]
        if np.array_equal(np.abs(b) > 0, keep):
            return b
        a = b
    return a


def part_drawings(cl, mechanism: Mechanism, kin=None) -> dict:
    """The part drawings of a classification with values (see the module docstring).

    Returns
    -------
    dict
        ``drawings`` (one per part, JSON of ``docs/drawing-format.md``), ``assembly_requirements``,
        ``by_tolerance`` (tolerance id -> its frames in the former per-tolerance form), ``not_drawn``
        (tolerance id -> why no part drawing carries it).
    """
    from hyperstat.solver.kinematics.closure import Kinematics
    from hyperstat.solver.tolerances.datums import datum_system
    from hyperstat.solver.tolerances.parts import find_parts, node_displacements

    kin = kin or Kinematics(mechanism)
    parts = find_parts(mechanism, cl.declaration)
    systems = [datum_system(p, mechanism, node_displacements(p, kin)) for p in parts]
    comps = _independent([c for ds in systems for c in ds.components])
    by_key = {c.key: c for c in comps}
    sys_of = {c.key: ds for ds in systems for c in ds.components}
    phi = np.array([c.row for c in comps]) if comps else np.zeros((0, kin.n_xi))
    gauges = gauge_vectors(mechanism)
    calibrated = "measurements" in cl.declaration.declared
    carried = [t for t in cl.items if t.cls != "non-influent" and t.drawing_value]
    expr, not_drawn = {}, {}
    invisible, setups = {}, []
    for t in carried:
        s = statement_functional(mechanism, t.terms, gauges)
        a = _express(phi, s)
        if a is None:  # it places a frame of the model (the base's, the tool's) relative to the parts: a setup
            setups.append(t)
            continue
        resid = float(np.linalg.norm(phi.T @ a - s)) / max(float(np.linalg.norm(s)), 1e-300)
        if resid > 1e-6:
            # its part along motions no feature of any part sees (a turn about a passive joint's own axis): the
            # parts are then nominal, so the mechanism moves and assembles as the nominal one; left out
            invisible[t.id] = resid
        expr[t.id] = {comps[i].key: float(a[i]) for i in np.nonzero(a)[0]}
    items = {t.id: t for t in carried}
    # statements across parts: split, or an assembly requirement when a component also carries another tolerance
    users: dict = {}
    for tid, a in expr.items():
        for k in a:
            users.setdefault(k, set()).add(tid)
    requirements, shares = [], {}
    for tid, a in expr.items():
        parts_of = list(dict.fromkeys(sys_of[k].part.id for k in a))
        t = items[tid]
        if len(parts_of) > 1 and t.cls == "assembly" and any(
                items[u].cls != "assembly" for k in a for u in users[k] if u != tid):
            requirements.append((t, parts_of, a))
            continue
        for p in parts_of:
            shares[(tid, p)] = (float(t.drawing_value) / len(parts_of), {k: c for k, c in a.items()
                                                                          if sys_of[k].part.id == p})
    # frames per (feature, group) over the needed components
    needed: dict = {}
    for (tid, p), (_, a) in shares.items():
        for k in a:
            c = by_key[k]
            needed.setdefault((id(c.feature), c.group), (sys_of[k], c.feature, c.group, []))[3].append(c)
    frames = []
    for (_, _), (ds, feat, group, cs) in needed.items():
        uniq = list({c.key: c for c in cs}.values())
        uniq.sort(key=lambda c: c.key)
        frames.extend(_frames_of(ds, feat, group, uniq))
    frame_of_key: dict = {}
    for f in frames:
        for c in f.comps:
            frame_of_key.setdefault(c.key, f)
    # each share: sum_f h z_f <= value; the reference shares, then progressive filling
    constraints = []
    for (tid, p), (value, a) in shares.items():
        fs: dict = {}
        for k, coef in a.items():
            f = frame_of_key[k]
            fs.setdefault(id(f), (f, {}))[1][k] = coef
        row = [(f, _carry_coefficient(f, aa)) for f, aa in fs.values()]
        row = [(f, h) for f, h in row if h > 0]
        constraints.append(((tid, p), value, row))
        for f, h in row:
            f.carries[(tid, p)] = h
            f.ref = min(f.ref, value / (len(row) * h))
    active = {id(f): f for f in frames if math.isfinite(f.ref)}
    fixed: dict = {}
    for _ in range(len(frames) + 1):
        if not active:
            break
        best, tight = math.inf, []
        for key, value, row in constraints:
            rest = value - sum(h * fixed[id(f)] for f, h in row if id(f) in fixed)
            grow = sum(h * f.ref for f, h in row if id(f) in active)
            if grow <= 0:
                continue
            lam = max(rest, 0.0) / grow
            if lam < best * (1 - 1e-12):
                best, tight = lam, [(key, row)]
            elif lam <= best * (1 + 1e-12):
                tight.append((key, row))
        if not math.isfinite(best):
            break
        for key, row in tight:
            for f, _ in row:
                if id(f) in active:
                    fixed[id(f)] = best * f.ref
                    f.binding = key
                    del active[id(f)]
    for f in frames:
        f.bound = fixed.get(id(f), 0.0)
    _drop_idle_seats(parts, frames)
    out = _assemble(cl, mechanism, systems, frames, requirements, expr, not_drawn, items, calibrated)
    _setup_requirements(out, setups, mechanism)
    out["invisible"] = invisible
    out["expressions"] = expr
    return out


def _drop_idle_seats(parts: list, frames: list) -> None:
    """A tool seat stays on its part's drawing only where a frame carries it: where the joints' features already fix
    the output frame (a wrist's flange on its journal), the part is drawn as before, with no seat (in place)."""
    used = {id(f.feature) for f in frames if f.bound > 0}
    for part in parts:
        seat = [ft for ft in part.features if ft.side == "output"]
        if seat and not any(id(ft) in used for ft in seat):
            part.features = [ft for ft in part.features if ft.side != "output"]


def _zone(f: _Frame) -> tuple[float, float | None]:
    """(zone in mm rounded down, the feature length it is toleranced over or None)."""
    if f.group == "tilt":
        length = f.feature.length or 0.0
        return safe_round(f.bound * length * (1 + 1e-9)), length
    return safe_round(2.0 * f.bound * (1 + 1e-9)), None


def _assemble(cl, mechanism, systems, frames, requirements, expr, not_drawn, items, calibrated) -> dict:
    """JSON of the drawings (docs/drawing-format.md)."""
    by_part: dict = {}
    for f in frames:
        by_part.setdefault(f.ds.part.id, []).append(f)
    by_tolerance: dict = {}
    drawings = []
    for ds in systems:
        part = ds.part
        out_frames = []
        for i, f in enumerate(sorted(by_part.get(part.id, []), key=lambda g: (g.feature.id, g.group))):
            f.id = f"{part.id}-F{i + 1}"
            zone, length = _zone(f)
            if not zone:
                continue
            tids = list(dict.fromkeys(k[0] for k in f.carries))
            binding = items[f.binding[0]] if f.binding else None
            with_cal = bool(binding is not None and calibrated and binding.cls == "compensable" and
                            binding.value_with_calibration is not None and binding.value is not None and
                            binding.drawing_value > binding.value * (1 + 1e-9))
            sym = SYMBOLS[f.characteristic]
            cyl = f.shape == "cylinder"
            letters = f.letters
            unit_b = "rad" if f.group == "tilt" else "mm"
            limit = zone / length if f.group == "tilt" and length else zone / 2.0
            bounds = [{"quantity": {"tilt": "tilt", "shift": "shift", "normal": "axial shift"}[f.group],
                       "unit": unit_b, "limit": limit}]
            ted = _teds(ds, f)
            note = ""
            if with_cal:
                note = (f"value with calibration: holds only on a machine calibrated from the declared measurements "
                        f"({campaign_words(cl)}) and compensated by the controller file that "
                        "'hyperstat export-controller' writes from that calibration; without calibration the value is "
                        f"{safe_round(binding.value):g} {binding.unit}")
            cross = [tid for tid in tids if len({k.split(".")[0] for k in expr.get(tid, {})}) > 1]
            if cross:
                note += ("; " if note else "") + "; ".join(
                    f"a share of {tid} ({items[tid].statement} within {items[tid].drawing_value:g} "
                    f"{items[tid].unit}) split between its parts" for tid in cross)
            if zone < PRACTICAL_ZONE_MM:
                note += ("; " if note else "") + (
                    f"a zone below {PRACTICAL_ZONE_MM * 1e3:g} µm, the finest grade of ISO 286-1 (IT01): no workshop "
                    "holds it; see the PRACTICAL SIZE warning on the report's page 1")
            text = _text(ds, f, zone, length, ted)
            cells = f"|{sym}|{_DIAMETER if cyl else ''}{zone:g}|" + "|".join(letters) + "|"
            frame = {"id": f.id, "tolerances": tids, "feature": f.feature.id, "characteristic": f.characteristic,
                     "symbol": sym, "zone_mm": zone, "zone_shape": "cylinder" if cyl else "two parallel planes",
                     "zone_direction": None if cyl else [float(v) for v in f.direction], "indicator": f.indicator,
                     "datum_system": list(letters), "ted": ted,
                     "value_kind": "with calibration" if with_cal else "without calibration", "note": note,
                     "bounds": bounds, "text": text, "frame": cells, "length_mm": length}
            out_frames.append(frame)
            legacy = {"characteristic": f.characteristic, "symbol": sym, "zone": zone, "unit": "mm",
                      "diameter_zone": cyl, "feature": f"{f.feature.name} ({part.id})", "feature_length": length,
                      "datums": list(letters),
                      "datum_features": {d.letter: f"{d.feature.name} ({part.id})" for d in ds.datums
                                         if d.letter in letters},
                      "text": text + (f" [{note}]" if note else ""), "frame": cells, "part": part.id,
                      "frame_id": f.id, "value_kind": frame["value_kind"]}
            for tid in tids:
                by_tolerance.setdefault(tid, []).append(legacy)
        drawings.append({"part": part.id, "title": part.title, "elements": list(part.elements),
                         "links": list(part.links), "chain": part.chain, "units": {"length": "mm", "angle": "rad"},
                         "features": [ft.to_dict() for ft in part.features],
                         "datums": [{"letter": d.letter, "feature": d.feature.id, "precedence": d.precedence}
                                    for d in ds.datums],
                         "frames": out_frames})
    reqs = []
    for i, (t, parts_of, a) in enumerate(requirements):
        feats = list(dict.fromkeys(k.split(":")[0] for k in a))
        text = (f"assembly requirement {t.id}: {t.statement} within ± {t.drawing_value:g} {t.unit}, between "
                + ", ".join(parts_of) + " (features " + ", ".join(feats) + "): the parts' own frames leave this "
                "combination open (each carries a value with calibration), so it is met at assembly: measure the parts "
                "and pair them, or adjust (shim) until it holds")
        reqs.append({"id": f"AR{i + 1}", "kind": "assembly", "tolerances": [t.id], "parts": parts_of, "features": feats,
                     "statement": t.statement, "value": t.drawing_value, "unit": t.unit, "text": text,
                     "terms": {k: v for k, v in a.items()}})
        by_tolerance.setdefault(t.id, []).append(
            {"characteristic": "assembly requirement", "symbol": "", "zone": t.drawing_value, "unit": t.unit,
             "diameter_zone": False, "feature": ", ".join(feats), "feature_length": None, "datums": [],
             "datum_features": {}, "text": text, "frame": f"{t.id} ± {t.drawing_value:g} {t.unit} (assembly)",
             "part": None, "frame_id": f"AR{i + 1}", "value_kind": "assembly requirement"})
    return {"drawings": drawings, "assembly_requirements": reqs, "by_tolerance": by_tolerance,
            "not_drawn": not_drawn}


def _setup_requirements(out: dict, setups: list, mechanism: Mechanism) -> None:
    """Tolerances no feature of any part moves with: they place a frame of the model relative to the parts (the base
    frame the task is measured in, relative to the base's reference bore; the tool frame, relative to the last
    part): stated as setup requirements, met at installation and identified by the declared calibration."""
    first = {ch.elements[0].name for ch in mechanism.chains if ch.start == mechanism.base and ch.elements}
    where = {p.name: p.element for p in mechanism.parameters}
    n = len(out["assembly_requirements"])
    for t in setups:
        elements = {where[p] for p in t.parameters if p in where}
        if elements <= first:
            what = (f"the base frame {mechanism.base} (where the task is measured) relative to the base's reference "
                    "bore: the machine's installation")
        else:
            what = "the output (tool) frame relative to the last part: the tool's setting"
        n += 1
        text = (f"setup requirement {t.id}: {t.statement} within ± {t.drawing_value:g} {t.unit}; it is no geometry of "
                f"any part: it places {what}, set at installation and identified by the declared calibration")
        out["assembly_requirements"].append({"id": f"AR{n}", "kind": "setup", "tolerances": [t.id], "parts": [],
                                             "features": [], "statement": t.statement, "value": t.drawing_value,
                                             "unit": t.unit, "text": text, "terms": dict(t.terms)})
        out["by_tolerance"].setdefault(t.id, []).append(
            {"characteristic": "setup requirement", "symbol": "", "zone": t.drawing_value, "unit": t.unit,
             "diameter_zone": False, "feature": what, "feature_length": None, "datums": [], "datum_features": {},
             "text": text, "frame": f"{t.id} ± {t.drawing_value:g} {t.unit} (setup)", "part": None,
             "frame_id": f"AR{n}", "value_kind": "setup requirement"})


def _teds(ds, f: _Frame) -> list:
    """Theoretically exact dimensions locating a position zone: from A (across it) and from B (along it)."""
    if f.characteristic not in ("position", "coaxiality"):
        return []
    a, pa = ds.a.direction, ds.a.point
    d = f.feature.point - pa
    across = d - (d @ a) * a
    r = float(np.linalg.norm(across))
    out = [{"from": "A", "distance_mm": round(r, 6),
            "direction": [float(v) for v in (across / r if r > 1e-9 else np.zeros(3))]}]
    if "B" in f.letters and ds.b is not None:
        z = float((f.feature.point - ds.b.point) @ a)
        out.append({"from": "B", "distance_mm": round(abs(z), 6), "direction": [float(v) for v in (a if z >= 0 else -a)]})
    return out


def _text(ds, f: _Frame, zone: float, length: float | None, ted: list) -> str:
    names = {d.letter: d.feature.name for d in ds.datums}
    datums = "|".join(f.letters) + " (" + "; ".join(f"{x}: {names[x]}" for x in f.letters) + ")"
    cyl = f.shape == "cylinder"
    zone_words = (f"within a cylinder of {_DIAMETER}{zone:g} mm" if cyl else
                  f"within two parallel planes {zone:g} mm apart, normal to (" +
                  ", ".join(f"{v:.4g}" for v in f.direction) + ")")
    if f.indicator:
        zone_words += (f", orientation plane {f.indicator['relation']} to datum {f.indicator['datum']}")
    if f.group == "tilt":
        return (f"{f.characteristic} of the axis of the {f.feature.name} relative to {datums}: {zone_words}, over its "
                f"{length:g} mm (a tilt of {zone / length:.3g} rad)")
    where = "; ".join(f"{t['distance_mm']:g} mm from {t['from']}" for t in ted)
    what = "axis of the " + f.feature.name if f.feature.kind == "axis" else f.feature.name
    return (f"{f.characteristic} of the {what} relative to {datums}, at its true position ({where}): {zone_words} "
            f"(± {zone / 2:.3g} mm)")


def provisional_drawings(cl, mechanism: Mechanism, kin=None) -> list[dict]:
    """The part drawings predicted before the tolerance values: every tolerance but the non-influent ones carried at
    a unit value (``cl`` is left as it was).

    A part drawing's features (the geometry its solid is built from) depend on which tolerances its frames carry,
    not on their values, so the report builds the solids of these drawings while the values are computed.  It is a
    prediction, not an answer: a final drawing whose features differ (a tolerance left without a value, a tool seat
    no frame carries) is built again (:func:`hyperstat.cad_plugin.report_parts.prebuild`).

    Examples
    --------
    >>> import hyperstat as hs
    >>> from hyperstat.solver.tolerances.classification import classify
    >>> mech = hs.load("slider_crank")
    >>> cl = classify(mech, hs.analyze(mech))
    >>> [d["part"] for d in provisional_drawings(cl, mech)]  # the four bodies of the slider-crank
    ['base', 'crank', 'rod', 'block']
    >>> all(t.drawing_value is None for t in cl.items)  # no value yet, and none left behind
    True
    """
    saved = [t.drawing_value for t in cl.items]
    try:
        for t in cl.items:
            if t.cls != "non-influent":
                t.drawing_value = 1.0
        return part_drawings(cl, mechanism, kin)["drawings"]
    finally:
        for t, v in zip(cl.items, saved):
            t.drawing_value = v


def add_drawing(cl, mechanism: Mechanism, kin=None) -> dict:
    """Fill ``drawing`` of every tolerance with its frames and keep the part drawings on ``cl.drawings`` (in place)."""
    out = part_drawings(cl, mechanism, kin)
    for t in cl.items:
        t.drawing = out["by_tolerance"].get(t.id, [])
        if t.id in out["invisible"]:
            t.evidence["drawing"] = {
                "left_out_share": out["invisible"][t.id],
                "meaning": "the part of the statement along defects that move no feature of any part (a turn about a "
                           "passive joint's own axis): it builds the nominal parts, so the mechanism moves and "
                           "assembles as the nominal one; the frames bound the rest (its orthogonal projection on what "
                           "the features see)"}
    cl.drawings = out
    cl.warnings = [w for w in cl.warnings if not w.startswith(PRACTICAL_SIZE_WARNING)]
    warning = practical_size_warning(out["drawings"], {t.id: t for t in cl.items})
    if warning:
        cl.warnings.append(warning)
    return out


def practical_size_warning(drawings: list, items: dict) -> str | None:
    """The warning that names every frame of ``drawings`` whose zone is below :data:`PRACTICAL_ZONE_MM`, with its
    tolerances and their classes; None when there is none.

    A frame's zone is what the model asks of the features it bounds (from the accuracy spec, or from the joints'
    clearances for an assembly condition); below the finest grade no part can be made to it, so the drawing cannot be
    released as it is, however right the model.  The assembly and set-up requirements (values in rad or mm between
    parts, not zones) are not checked here.

    Examples
    --------
    >>> from types import SimpleNamespace as NS
    >>> drawings = [{"part": "base", "frames": [{"id": "base-F1", "zone_mm": 1.7e-07, "tolerances": ["T17"]},
    ...                                         {"id": "base-F2", "zone_mm": 0.004, "tolerances": ["T18"]}]}]
    >>> print(practical_size_warning(drawings, {"T17": NS(cls="accuracy-critical")}))  # doctest: +NORMALIZE_WHITESPACE
    PRACTICAL SIZE: 1 frame of 2 states a zone below 0.3 µm, the finest grade of ISO 286-1 (IT01), which no workshop
    holds: base-F1 (1.7e-07 mm; T17 accuracy-critical). The parts cannot be made to this drawing as it is. An accuracy
    tolerance's value comes from the accuracy spec: relax the spec, or change the design so that the tool is less
    sensitive to these defects.
    >>> practical_size_warning(drawings, {"T17": NS(cls="assembly")}).split("as it is. ")[1]
    "An assembly condition's value comes from the joints' clearances: give them more play, adjust at assembly, or \
remove the over-constraint."
    >>> more = [{"part": "arm", "frames": [{"id": "arm-F1", "zone_mm": 1e-4, "tolerances": ["T3", "T4", "T5", "T9"]}]}]
    >>> practical_size_warning(more, {t: NS(cls="compensable") for t in ("T3", "T4", "T5", "T9")}).split(": ")[2][:41]
    'arm-F1 (0.0001 mm; T3-T5, T9 compensable)'
    >>> practical_size_warning([{"part": "base", "frames": [drawings[0]["frames"][1]]}], {}) is None
    True
    """
    frames = [f for d in drawings for f in d.get("frames") or []]
    small = [f for f in frames if f.get("zone_mm") is not None and f["zone_mm"] < PRACTICAL_ZONE_MM]
    if not small:
        return None

    from hyperstat.solver.tolerances.classification import _id_list

    def carried(f: dict) -> str:  # the frame's tolerances by class, consecutive ids as ranges: "T52-T56 compensable"
        by_class: dict = {}
        for tid in f.get("tolerances") or []:
            by_class.setdefault(items[tid].cls if tid in items else "", []).append(tid)
        return ", ".join(f"{_id_list(ids)} {cls}".rstrip() for cls, ids in by_class.items())

    listed = "; ".join(f"{f['id']} ({f['zone_mm']:g} mm; {carried(f)})" for f in small[:12])
    if len(small) > 12:
        listed += f"; and {len(small) - 12} more (their notes on the part pages say so)"
    verb = "states" if len(small) == 1 else "state"
    classes = {items[tid].cls for f in small for tid in f.get("tolerances") or [] if tid in items}
    why = []
    if "assembly" in classes:
        why.append("An assembly condition's value comes from the joints' clearances: give them more play, adjust at "
                   "assembly, or remove the over-constraint.")
    if classes - {"assembly"} or not classes:
        why.append("An accuracy tolerance's value comes from the accuracy spec: relax the spec, or change the design "
                   "so that the tool is less sensitive to these defects.")
    return (f"{PRACTICAL_SIZE_WARNING}{len(small)} frame{'s' if len(small) > 1 else ''} of {len(frames)} {verb} a zone "
            f"below {PRACTICAL_ZONE_MM * 1e3:g} µm, the finest grade of ISO 286-1 (IT01), which no workshop holds: "
            f"{listed}. The parts cannot be made to this drawing as it is. " + " ".join(why))
