"""Plain-text tables for the terminal (units: mm, rad)."""

from __future__ import annotations

from hyperstat.solver.analysis.stationarity import StationarityResult

__all__ = ["format_analysis", "format_tolerances", "format_identification", "format_diagnosis", "natural_ids"]


def _fmt_gap(gap: float) -> str:
    return "none (full rank)" if gap == float("inf") else f"{gap:.3g}"


def _value(t: dict, key: str = "value") -> str:
    """``+-value unit``, rounded towards the safe side (down) to three significant digits."""
    from hyperstat.solver.tolerances.drawing import safe_round

    v = t.get(key)
    if v is None:
        return "-"
    return f"+-{safe_round(v):.3g} {t['unit']}"


def natural_ids(ids) -> list[str]:
    """Tolerance ids in natural order (``T2`` before ``T10``).

    >>> natural_ids(["T2", "T21", "T3", "T10", "T1"])
    ['T1', 'T2', 'T3', 'T10', 'T21']
    """
    import re

    return sorted(ids, key=lambda i: [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", str(i))])


def _wrap(statement: str, width: int) -> list[str]:
    """A statement cut into lines of at most ``width`` characters between terms: before a ``+`` or ``-`` term,
    before its final ``= 0``, or after a comma (a longer term stays whole).

    >>> _wrap("dI2 - 0.5*db2 + 0.25*dJ5 = 0", 14)
    ['dI2 - 0.5*db2', '+ 0.25*dJ5 = 0']
    >>> _wrap("dI2 with db2 = 92.56*dI2, dc4 = -42.09*dI2, ...", 26)
    ['dI2 with db2 = 92.56*dI2,', 'dc4 = -42.09*dI2, ...']
    """
    import re

    atoms = [a for a in re.split(r" (?=[+-] )| (?== 0$)|(?<=,) ", statement) if a]
    lines, current = [], ""
    for atom in atoms:
        if current and len(current) + 1 + len(atom) > width:
            lines.append(current)
            current = atom
        else:
            current = f"{current} {atom}" if current else atom
    lines.append(current)
    return lines


def format_tolerances(tolerances: dict, limit: int | None = None) -> str:
    """The tolerance table of a :meth:`~hyperstat.solver.tolerances.classification.Classification.to_dict`.

    One line per tolerance (id, class, statement, value, why), the counts per class, the
    redundant shifts merged with their equivalents and the normalisation components
    (not tolerances).

    >>> doc = {"counts": {"assembly": 1, "accuracy-critical": 0, "compensable": 0, "non-influent": 0},
    ...        "items": [{"id": "T1", "class": "assembly", "statement": "dc2 + dc3 = 0", "value": 0.02, "unit": "mm",
    ...                   "why": "forced"}], "task": ["x"], "declaration": {"measurements": {"kind": "positions"}},
    ...        "redundant": {"dc2": {"equivalent": "dc3"}}, "appendix": {"normalisation": [{"name": "dK2"}]}}
    >>> print(format_tolerances(doc).splitlines()[1])
    counts: assembly 1, accuracy-critical 0, compensable 0, non-influent 0
    """
    decl = tolerances.get("declaration", {})
    spec = decl.get("spec", {})
    head = (f"Tolerances (task: {', '.join(tolerances.get('task', []))}; measurements: "
            f"{decl.get('measurements', {}).get('kind', '-')}")
    if spec.get("position_mm") is not None or spec.get("orientation_rad") is not None:
        head += "; spec " + ", ".join(f"{v:g} {u}" for v, u in ((spec.get("position_mm"), "mm"),
                                                                  (spec.get("orientation_rad"), "rad")) if v is not None)
    lines = [head + "):", "counts: " + ", ".join(f"{k} {n}" for k, n in tolerances["counts"].items())]
    items = tolerances["items"]
    width = max([len(t["statement"]) for t in items] + [9])
    width = min(width, 60)
    calibrated = any(t.get("value_with_calibration") is not None for t in items)
    id_width = max([len(t["id"]) for t in items] + [2]) + 2
    lines.append(f"{'id':<{id_width}}{'class':<19}{'statement':<{width + 2}}{'value':<17}"
                 + (f"{'with calibration':<18}" if calibrated else "") + "why")
    for t in items[:limit] if limit else items:
        parts = _wrap(t["statement"], width)  # a long relation continues below, in its column
        lines.append(f"{t['id']:<{id_width}}{t['class']:<19}{parts[0]:<{width}}  {_value(t):<15}  "
                     + (f"{_value(t, 'value_with_calibration'):<16}  " if calibrated else "") + t["why"])
        lines += [f"{'':<{id_width + 19}}{part}" for part in parts[1:]]
    if limit and len(items) > limit:
        lines.append(f"... {len(items) - limit} more (see the JSON or the report)")
    if calibrated:
        lines.append("values rounded towards the safe side (down); 'with calibration': the largest defect a calibration "
                     "from the declared measurements plus the controller's compensation still keeps within the spec "
                     "(its limit in the JSON, value_with_calibration_limit)")
    shown = [t for t in (items[:limit] if limit else items) if t.get("drawing")]
    if shown:
        lines.append("drawing (ISO 1101 feature control frames, zones rounded down):")
        for t in shown:
            for c in t["drawing"]:
                lines.append(f"  {t['id']:<5}{c['frame']:<16}{c['text']}")
    bounds = {}
    for t in items:
        if t.get("bounds"):
            bounds.setdefault(t["class"], t["bounds"])
    for cls, b in bounds.items():
        lines.append(f"linear worst case of the {cls} tolerances at their values: attainable "
                     f"{b['attainable_linear_worst_case']:.4g} {b['unit']} (the worst sign pattern at the worst "
                     f"configuration found), triangle bound {b['triangle_bound']:.4g} {b['unit']} (every effect "
                     "adding up: no machine need reach it)")
    red = tolerances.get("redundant", {})
    if red:
        from hyperstat.solver.tolerances.classification import redundant_text

        lines.append("redundant shifts, merged with their equivalent (the same physical shift, or the combination it "
                     "acts as along a skew axis): " + ", ".join(redundant_text(g, r) for g, r in red.items()))
    normal = tolerances.get("appendix", {}).get("normalisation", [])
    if normal:
        lines.append("not tolerances (normalisation components along the nominal axis, no geometric meaning): "
                     + ", ".join(a["name"] for a in normal))
    if items and all(t.get("value") is None for t in items):
        lines.append("values: 'hyperstat accuracy' and 'hyperstat report' compute them (allocation against the spec, "
                     "joint clearances); see docs/tolerances.md")
    for w in tolerances.get("warnings", []):
        lines.append(f"warning: {w}")
    return "\n".join(lines) + "\n"


def format_analysis(result: StationarityResult, checks: list | None = None, exact=None,
                    tolerances: dict | None = None) -> str:
    """Readable table of a stationarity analysis, grouped by joint, with the checks if given."""
    c = result.counts()
    lines = [
        f"Stationarity analysis of '{result.mechanism}': {c['total']} defect parameters, "
        f"{result.n_configurations} configurations, {result.elapsed:.2f} s",
        f"mobility {result.mobility}, closure equations {result.n_closure_equations}, "
        f"degree of over-constraint {result.overconstraint}",
        f"constraint rank {result.rank} ({result.n_constraint_rows} stacked rows), singular-value gap "
        f"{_fmt_gap(result.gap)} at threshold {result.threshold:.3g}; independent influential directions "
        f"{result.influential_rank} (gap {_fmt_gap(result.influential_gap)})",
        "",
    ]
    by_name = {}
    for ch in checks or []:
        if ch.kind in ("parameter", "gauge"):
            by_name[ch.subject] = ch
    params = (tolerances or {}).get("parameters", {})

    def ids_of(e: dict) -> str:
        tol = ", ".join(natural_ids(e.get("tolerance_ids") or [])) or "-"
        return tol + (f" (≡ {e['equivalent']})" if e.get("equivalent") else "")

    el_width = max([len(str(p.element)) for p in result.parameters] + [7]) + 2
    name_width = max([len(p.name) for p in result.parameters] + [9]) + 2
    tol_width = max([len(ids_of(e)) for e in params.values()] + [9]) + 2
    header = f"{'element':<{el_width}}{'parameter':<{name_width}}{'unit':<5}"
    header += f"{'class':<19}{'tolerance':<{tol_width}}" if params else f"{'verdict':<15}{'effect on output':<18}"
    if checks:
        header += "nonlinear check"
    lines.append(header)
    lines.append("-" * len(header.rstrip()) + ("-" * 40 if checks else ""))
    previous = None
    for p in result.parameters:
        el = p.element if p.element != previous else ""
        previous = p.element
        row = f"{el:<{el_width}}{p.name:<{name_width}}{p.unit:<5}"
        if params:  # one class per parameter, the tolerances' (one vocabulary)
            e = params.get(p.name, {})
            row += f"{e.get('class', '-'):<19}{ids_of(e):<{tol_width}}"
        else:  # the stationarity analysis alone (no tolerance classes): its verdict, a gauge named for what it is
            verdict = p.verdict if p.verdict != "gauge" else ("normalisation" if p.component in "IJK" else "redundant")
            effect = "-" if p.influential is None else ("influential" if p.influential else "non-influent")
            row += f"{verdict:<15}{effect:<18}"
        if p.name in by_name and by_name[p.name].kind == "gauge":
            ch = by_name[p.name]
            mark = "confirmed" if ch.confirmed else "NOT CONFIRMED"
            row += f"{mark}: same as its equivalent to {ch.residual:.1e} mm; {p.reason}"
        elif p.name in by_name:
            ch = by_name[p.name]
            mark = "confirmed" if ch.confirmed else "NOT CONFIRMED"
            row += f"{mark}: residual {ch.residual:.2e} mm"
            if ch.expected == "does not assemble":
                row += f" (linear {ch.predicted:.2e})"
        elif checks and p.verdict == "gauge":
            row += p.reason
        lines.append(row.rstrip())
    lines.append("")
    n_normal = sum(p.verdict == "gauge" and p.component in "IJK" for p in result.parameters)
    lines.append(
        f"stationarity verdicts: forced {c['forced']}, coupled {c['coupled']}, free {c['free']} "
        f"({c['free_influential']} influential, {c['free_non_influent']} non-influent), normalisation {n_normal}, "
        f"redundant shifts {c['gauge'] - n_normal}"
    )
    if result.relations:
        lines.append("relations between coupled defects (coefficients per rad or per mm):")
        for r in result.relations:
            lines.append(f"  {r.text}")
    rel_checks = [ch for ch in checks or [] if ch.kind.startswith("relation")]
    for ch in rel_checks:
        mark = "confirmed" if ch.confirmed else "NOT CONFIRMED"
        lines.append(f"  {ch.kind}: {ch.subject}: {mark}, residual {ch.residual:.2e} mm")
    if checks is not None:
        bad = [ch for ch in checks if not ch.confirmed]
        lines.append(f"nonlinear checks: {len(checks) - len(bad)} of {len(checks)} confirmed")
    if exact is not None:
        if exact.available:
            agree = exact.rank == result.rank and sorted(exact.forced) == sorted(result.by_verdict("forced"))
            lines.append(
                f"exact check (sympy, rationals): {exact.reason}; forced {', '.join(exact.forced) or 'none'}; "
                + ("agrees with the numerical analysis" if agree else "DIFFERS from the numerical analysis")
            )
            for rel in getattr(exact, "relations", []) if agree else []:
                lines.append(f"  exact relation: {rel['text']}")
        else:
            lines.append(f"exact check unavailable: {exact.reason}")
    for w in result.warnings:
        lines.append(f"warning: {w}")
    if tolerances is not None:
        lines += ["", format_tolerances(tolerances).rstrip("\n")]
    return "\n".join(lines) + "\n"


def format_identification(result) -> str:
    """Readable summary of an :class:`~hyperstat.solver.calibration.identify.IdentificationResult` (units: mm, rad; residuals in µm)."""
    lines = [
        f"Identification: {result.rank} identifiable of {result.n_unknowns} unknowns "
        f"(singular-value gap {_fmt_gap(result.singular_value_gap)}), condition number "
        f"{result.condition_number:.3g} (scaled columns; raw {result.condition_number_raw:.3g}), "
        f"{result.iterations} evaluations, {result.elapsed:.2f} s",
        "observability  " + "  ".join(f"{k} {v:.3g}" for k, v in result.observability.items()),
        "",
        f"{'parameter':<12} {'unit':<4} {'estimate':>12} {'std':>10}",
    ]
    for p in result.parameters:
        if p["identifiable"]:
            lines.append(f"{p['name']:<12} {p['unit']:<4} {p['estimate']:>12.6g} {p['std']:>10.3g}")
    if result.unidentifiable:
        lines += ["", "not identifiable alone (held at their prior value):"]
        for u in result.unidentifiable:
            comb = " ".join(f"{c:+.4g}*{n}" for n, c in u["combination"].items()) or "-"
            lines.append(f"  {u['name']:<12} {u['reason']}; seen as {u['name']} = {comb}")
    if result.correlations:
        lines += ["", f"strong correlations (|rho| > 0.9): {len(result.correlations)}"]
        for c in sorted(result.correlations, key=lambda c: -abs(c["rho"]))[:8]:
            lines.append(f"  {c['a']:<12} {c['b']:<12} {c['rho']:+.4f}")

    def row(label: str, s: dict | None) -> str:
        if s is None:
            return f"{label:<15} -"
        return (f"{label:<15} mean {1000 * s['mean']:8.2f} µm  max {1000 * s['max']:8.2f} µm  "
                f"RMS {1000 * s['rms']:8.2f} µm  ({s['n']} points)")

    lines += ["", row("identification", result.identification), row("validation", result.validation)]
    nominal = getattr(result, "nominal", None)
    if nominal:
        lines += ["nominal model (tracker frame and targets fitted, geometry nominal):",
                  row("  identification", nominal["identification"]), row("  validation", nominal["validation"])]
    if result.noise_rms is not None:
        lines.append(f"{'noise floor':<15} RMS {1000 * result.noise_rms:8.2f} µm (the data's noise model)")
    ori = getattr(result, "orientation", None)
    if ori:
        def arow(label: str, a: dict | None) -> str:
            if a is None:
                return f"{label:<15} -"
            return (f"{label:<15} mean {1e6 * a['mean']:8.1f} µrad max {1e6 * a['max']:8.1f} µrad "
                    f"RMS {1e6 * a['rms']:8.1f} µrad ({a['n']} orientations)")

        lines += [arow("orientation id.", ori["identification"]), arow("orientation val.", ori["validation"]),
                  f"{'orient. noise':<15} RMS {1e6 * ori['noise_rms']:8.1f} µrad (the file's orientation noise)"]
    weighted = result.noise_rms is not None
    lines.append(f"sigma {result.sigma:.3g} " + ("(weighted residuals: 1 when the noise model holds)" if weighted
                                                 else "mm (no noise model in the file: residual std per axis)"))
    lines.append(f"fit quality: {getattr(result, 'fit_quality', 'ok')}")
    ratios = getattr(result, "noise_ratios", None) or {}
    for part in ("identification", "validation"):
        per = ratios.get(part)
        if per and (part == "validation" or ratios.get("reference") == "stated noise"):
            ref = "the stated noise" if ratios.get("reference") == "stated noise" else "the fit's residual scale"
            lines.append(f"  {part} RMS / {ref}, per target: " + ", ".join(
                f"{name} {v:.3g}" for name, v in per.items() if v is not None))
    counts = getattr(result, "equations", None)
    if counts:
        lines.append(f"equations: {counts['equations']} for {counts['parameters']} parameters "
                     f"({counts['per_parameter']:.3g} per parameter, a pose counting at most 6 for the machine; "
                     f"{counts['poses']} distinct poses)")
    rounds = getattr(result, "base_rounds", [])
    if len(rounds) > 1:
        lines.append(f"identifiable set decided at the solution: rank by round {rounds}")
    held = getattr(result, "held_back", None)
    if held:
        n_und = held.get("undetermined_directions", 0)
        why = ("standard errors beyond 1 % of the machine's size: not determined by the data"
               if n_und == held["extra_directions"] else
               f"{n_und} with standard errors beyond 1 % of the machine's size, the others not significant"
               if n_und else "not significant")
        lines.append(f"  {held['extra_directions']} more direction(s) independent at the solution (rank "
                     f"{held['rank_at_solution']}) explain chi2 {held['chi2_decrease']:.3g} less: {why}, "
                     f"held at their prior")
    sel = getattr(result, "model_selection", None)
    if sel:
        values = (" -> CV RMS (µm) " + " ".join(f"{1000 * v:.1f}" for v in sel["cv_rms"])) if sel.get("cv_rms") \
            else (" -> criterion " + " ".join(f"{v:.1f}" for v in sel["criterion"]))
        lines.append(f"model size by {sel['method']}: geometry sizes {sel['sizes']}{values}; kept {sel['chosen']}")
    table = getattr(result, "residual_table", [])
    flagged = [r for r in table if r["outlier"]]
    if table:
        lines.append(f"outliers (normalised residual with the observation left out, p < 0.001 over the campaign): "
                     f"{len(flagged)} of {len(table)}" + (f"; excluded on request: {len(result.excluded)}"
                                                          if getattr(result, "excluded", None) else ""))
    lines += [f"warning: {w}" for w in result.warnings]
    return "\n".join(lines) + "\n"


def format_diagnosis(diag) -> str:
    """Readable summary of a :class:`~hyperstat.solver.diagnosis.diagnose.Diagnosis` (residuals in µm)."""
    um = 1000.0
    t = diag.gap_test
    lines = ["Is there a gap?"]
    for key in ("identification", "validation"):
        if key in t:
            chi = t[key].get("chi2_whitened", t[key]["chi2"])  # held-out rows: whitened by the prediction covariance
            lines.append(f"  {key:<15} chi2 {chi:.1f} for {t[key]['dof']} dof, p = {t[key]['p_value']:.2g}"
                         + (f" (the fitted model's own uncertainty at these poses: {t[key]['variance_inflation']:.2f}x "
                            f"the noise's variance on average)" if "chi2_whitened" in t[key] else ""))
    lines.append("  -> " + ("significant gap (p below %.1g)" % t["threshold"] if diag.gap_significant
                            else "no significant gap: the residuals are at the noise level of the data"))
    w = diag.where
    lines += ["", "Where?",
              "  by direction (base frame, RMS µm): " + "  ".join(f"{k} {um * v:.1f}" for k, v in w["direction_rms"].items()),
              "  by workspace region (RMS µm): " + "  ".join(f"#{r['region']} {um * r['rms']:.1f} ({r['points']} pts)"
                                                           for r in w["regions"]),
              "  share of the residual explained by: " + ", ".join(f"{e['variable']} {100 * e['share']:.0f} %"
                                                                  for e in w["explained_by"][:5])]
    for s in w["spectra"]:
        lines.append(f"  spectrum along q{s['joint']}: peak at a period of {s['peak_period_mm']:.2f} mm "
                     f"({100 * s['peak_share']:.0f} % of the power)")
    lines += ["", "Which effect? (blocked cross-validation; BIC relative to the rigid model)"]
    for e in diag.ranking:
        note = f"  [{e['note']}]" if e.get("note") else ""
        lines.append(f"  {e['effect']:<20} CV RMS {um * e['cv_rms']:7.1f} µm   dBIC {e['criterion']:8.1f}{note}")
    for name, why in diag.not_applicable.items():
        lines.append(f"  {name:<20} not tried: {why}")
    lines.append("  selected: " + (", ".join(diag.selected) or "none"))
    for a in diag.selection_ties:
        lines.append(f"  tie between {a['effects'][0]} and {a['effects'][1]}: {a['note']}")
    if diag.violated_defect:
        v = diag.violated_defect
        est = f" = {v['estimate']:.4g} +- {v['std']:.2g} {v['unit']}" if "std" in v else ""
        lines.append(f"  violated forced defect: {v['defect']}{est}")
        if v.get("ambiguous_with"):
            lines.append("    ambiguous with " + ", ".join(v["ambiguous_with"]) + ": the data explain the gap "
                         f"almost as well with it; {v['defect']} is named: it needs the smallest violation "
                         f"({v['times_realistic']:.0f}x its realistic magnitude)")
        if v.get("alternatives"):
            lines.append("    next candidates: " + ", ".join(
                f"{a['defect']} = {a['estimate']:.3g} {a['unit']} ({a['times_realistic']:.0f}x, "
                f"CV RMS {um * a['cv_rms']:.1f} µm)" for a in v["alternatives"]))
    for p in diag.effect_parameters:
        std = "-" if p["std"] is None else f"{p['std']:.2g}"
        lines.append(f"    {p['name']:<22} {p['estimate']:.4g} +- {std} {p['unit']}")
    lines += ["", "How far does it shrink?"]
    b, a = diag.validation_before, diag.validation_after
    if b:
        lines.append(f"  validation before: mean {um * b['mean']:.1f}  max {um * b['max']:.1f}  RMS {um * b['rms']:.1f} µm")
    if a:
        lines.append(f"  validation after:  mean {um * a['mean']:.1f}  max {um * a['max']:.1f}  RMS {um * a['rms']:.1f} µm")
    if diag.rigid.noise_rms is not None:
        lines.append(f"  noise floor RMS {um * diag.rigid.noise_rms:.1f} µm")
    if diag.share_explained is not None:
        lines.append(f"  share of the gap explained: {100 * diag.share_explained:.0f} %")
    c = diag.ceiling
    if "black_box_share_blocked" in c and "selected_share_blocked" in c:
        lines.append(f"  ceiling: under the same blocked folds, a black-box regression on joints and metadata removes "
                     f"{100 * c['black_box_share_blocked']:.0f} % of the rigid residuals' variance (the selected "
                     f"effects: {100 * c['selected_share_blocked']:.0f} %)")
    return "\n".join(lines) + "\n"
