"""Plain-text tables for the terminal (units: mm, rad)."""

from __future__ import annotations

from ..stationarity import StationarityResult

__all__ = ["format_analysis"]


def _fmt_gap(gap: float) -> str:
    return "none (full rank)" if gap == float("inf") else f"{gap:.3g}"


def format_analysis(result: StationarityResult, checks: list | None = None, exact=None) -> str:
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
        if ch.kind == "parameter":
            by_name[ch.subject] = ch
    header = f"{'element':<10}{'parameter':<11}{'unit':<5}{'verdict':<9}{'effect on output':<18}"
    if checks:
        header += "nonlinear check"
    lines.append(header)
    lines.append("-" * len(header.rstrip()) + ("-" * 40 if checks else ""))
    previous = None
    for p in result.parameters:
        el = p.element if p.element != previous else ""
        previous = p.element
        effect = "-" if p.influential is None else ("influential" if p.influential else "non-influent")
        row = f"{el:<10}{p.name:<11}{p.unit:<5}{p.verdict:<9}{effect:<18}"
        if p.name in by_name:
            ch = by_name[p.name]
            mark = "confirmed" if ch.confirmed else "NOT CONFIRMED"
            row += f"{mark}: residual {ch.residual:.2e} mm"
            if ch.expected == "does not assemble":
                row += f" (linear {ch.predicted:.2e})"
        elif checks and p.verdict == "gauge":
            row += p.reason
        lines.append(row.rstrip())
    lines.append("")
    lines.append(
        f"counts: gauge {c['gauge']}, forced {c['forced']}, coupled {c['coupled']}, free {c['free']} "
        f"({c['free_influential']} influential, {c['free_non_influent']} non-influent)"
    )
    if result.relations:
        lines.append("relations between coupled defects (coefficients per rad or per mm):")
        for r in result.relations:
            lines.append(f"  {r.text}")
    rel_checks = [ch for ch in checks or [] if ch.kind != "parameter"]
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
        else:
            lines.append(f"exact check unavailable: {exact.reason}")
    for w in result.warnings:
        lines.append(f"warning: {w}")
    return "\n".join(lines) + "\n"
