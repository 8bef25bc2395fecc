"""Compare a stationarity analysis with a paper's tables (references, never oracles).

Units: defects in rad and mm; residuals in mm.

A reference file (YAML, ``format: hyperstat-reference``) transcribes a paper's tables:
which geometric-parameter matrix is which element, the parameters the paper sets to
zero (e.g. paper 1, Table 3), the ones it identifies (Table 5), and the counts it
claims.  :func:`compare` puts our verdict next to the paper's for every parameter,
classifies each difference (normalisation, naming, non-influent defects counted as
zero, a relation where the paper forces each term, a paper inconsistency, or a
genuine disagreement), attaches the nonlinear evidence, and checks the paper's
counts against its own tables.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.analysis.stationarity import StationarityResult

__all__ = ["ParameterComparison", "Comparison", "load_reference", "compare"]


@dataclass
class ParameterComparison:
    """One parameter: the paper's status, ours, and why they differ."""

    name: str
    matrix: str
    group: str
    paper: str  # zero | identified | both | neither
    ours: str  # gauge | forced | coupled | free-influential | free-non-influent (+ coupled influence)
    category: str  # agree | naming | in substance | partly | paper inconsistency | disagree
    reason: str
    evidence: str = ""


@dataclass
class Comparison:
    """Result of :func:`compare`."""

    parameters: list
    matrices: list
    paper_checks: list = field(default_factory=list)

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        return {
            "parameters": [vars(p) for p in self.parameters],
            "matrices": self.matrices,
            "paper_checks": self.paper_checks,
            "categories": dict(Counter(p.category for p in self.parameters)),
        }

    def to_markdown(self) -> str:
        """The per-matrix table, the differences with evidence, and the paper's own counts."""
        out = ["| group | matrix | paper: zero (o/p) | ours: gauge | forced | coupled | non-influent | "
               "influential | paper: identified | agree / differ |",
               "|---|---|---|---|---|---|---|---|---|---|"]
        for m in self.matrices:
            out.append(
                f"| {m['group']} | {m['matrix']} | {m['paper_zero'][0]}/{m['paper_zero'][1]} | "
                f"{m['gauge'][0]}/{m['gauge'][1]} | {m['forced'][0]}/{m['forced'][1]} | "
                f"{m['coupled'][0]}/{m['coupled'][1]} | {m['non_influent'][0]}/{m['non_influent'][1]} | "
                f"{m['influential'][0]}/{m['influential'][1]} | {m['paper_identified'][0]}/{m['paper_identified'][1]} | "
                f"{m['agree']} / {m['differ']} |"
            )
        out.append("")
        out.append("(o/p: orientation / position parameters.  'influential' counts free and coupled parameters "
                   "that move the tool.)")
        out.append("")
        out.append("| parameter | matrix | paper | ours | category | reason | nonlinear evidence |")
        out.append("|---|---|---|---|---|---|---|")
        for p in self.parameters:
            if p.category == "agree":
                continue
            out.append(f"| {p.name} | {p.matrix} | {p.paper} | {p.ours} | {p.category} | {p.reason} | {p.evidence} |")
        out.append("")
        cats = Counter(p.category for p in self.parameters)
        out.append("Categories: " + ", ".join(f"{k} {v}" for k, v in sorted(cats.items())))
        if self.paper_checks:
            out.append("")
            out.append("The paper's counts against its own tables:")
            out.append("")
            for c in self.paper_checks:
                out.append(f"* {c}")
        return "\n".join(out) + "\n"


def load_reference(path: str | Path) -> dict:
    """Read a reference file (YAML, safe loader)."""
    import yaml

    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such reference file.")
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError:
        raise DataError(f"{path}: not valid YAML.") from None
    if not isinstance(doc, dict) or doc.get("format") != "hyperstat-reference":
        raise DataError(f"{path}: field 'format' must be 'hyperstat-reference'.")
    for key in ("matrices", "zero", "identified"):
        if not isinstance(doc.get(key), list):
            raise DataError(f"{path}: field '{key}' must be a list.")
    return doc


def _ours(p) -> str:
    if p.verdict == "free":
        return "free-influential" if p.influential else "free-non-influent"
    if p.verdict == "coupled":
        return "coupled-influential" if p.influential else "coupled-non-influent"
    return p.verdict


def compare(mechanism: Mechanism, result: StationarityResult, reference: dict,
            checks: list | None = None) -> Comparison:
    """Parameter-by-parameter and matrix-by-matrix comparison with a paper's tables.

    Raises
    ------
    DataError
        If the reference names a parameter or element the mechanism does not have.
    """
    names = {p.name for p in mechanism.parameters}
    elements = {el.name for ch in mechanism.chains for el in ch.elements}
    for key in ("zero", "identified"):
        for n in reference[key]:
            if n not in names:
                raise DataError(f"reference field '{key}' names '{n}', which is not a defect of '{mechanism.name}'.")
    matrix_of, group_of = {}, {}
    for m in reference["matrices"]:
        if m["element"] not in elements:
            raise DataError(f"reference field 'matrices' names element '{m['element']}', unknown to '{mechanism.name}'.")
        matrix_of[m["element"]] = m["matrix"]
        group_of[m["element"]] = m.get("group", "")
    zero, ident = set(reference["zero"]), set(reference["identified"])
    by_check = {c.subject: c for c in checks or [] if c.kind in ("parameter", "gauge")}
    relation_of = {}
    for rel in result.relations:
        for n in rel.terms:
            relation_of.setdefault(n, rel.text)
    rows = []
    for p in result.parameters:
        if p.element not in matrix_of:
            continue
        paper = "both" if p.name in zero and p.name in ident else "zero" if p.name in zero else \
            "identified" if p.name in ident else "neither"
        ours = _ours(p)
        ev = ""
        c = by_check.get(p.name)
        if c is not None:
            if c.kind == "gauge":
                ev = f"same mechanism as its equivalent to {c.residual:.1e} mm"
            elif c.expected == "does not assemble":
                ev = f"residual {c.residual:.2e} mm (linear {c.predicted:.2e})"
            else:
                ev = f"residual {c.residual:.1e} mm; tool moves {c.output_change:.2e} mm"
        normalisation = p.verdict == "gauge" and p.reason.startswith("normalisation")
        if paper == "both":
            cat, why = "paper inconsistency", "listed both as zero (Table 3) and to identify (Table 5)"
        elif paper == "zero":
            if p.verdict == "forced":
                cat, why = "agree", "forced"
            elif normalisation:
                cat, why = "agree", "normalisation"
            elif p.verdict == "gauge":
                cat, why = "agree", "gauge (along-axis shift)"
            elif ours == "free-non-influent":
                cat, why = "in substance", ("non-influent: the passive joints absorb it and the tool does not move; "
                                           "Table 3 also holds such defects (the paper's CAD test, behaviour 3)")
            elif p.verdict == "coupled":
                cat, why = "partly", f"only a relation is forced, not the parameter: {relation_of.get(p.name, '')}"
            else:
                cat, why = "disagree", "free and influential: the mechanism assembles and moves with it"
        elif paper == "identified":
            if ours in ("free-influential", "coupled-influential"):
                cat, why = "agree", "influential"
                if p.verdict == "coupled":
                    cat, why = "agree", f"influential, subject to {relation_of.get(p.name, '')}"
            elif p.verdict == "forced":
                cat, why = "disagree", "forced by the over-constraint: with it the mechanism does not assemble"
            elif p.verdict == "gauge":
                cat, why = "naming", f"a gauge in these frames ({p.reason})"
            else:
                cat, why = "disagree", "non-influent: it cannot be identified (zero column of the identification Jacobian)"
        else:
            if ours in ("free-influential", "coupled-influential"):
                cat, why = "disagree", "influential but in neither table"
            elif p.verdict == "forced":
                cat, why = "disagree", "forced, but not in Table 3"
            else:
                cat, why = "agree", "neither zero nor identified: " + ours
        rows.append(ParameterComparison(p.name, matrix_of[p.element], group_of[p.element], paper, ours, cat, why, ev))

    matrices = []
    comp_of = {p.name: p.component for p in mechanism.parameters}

    def op(items):
        return [sum(comp_of[i] in "IJKG" for i in items), sum(comp_of[i] in "abc" for i in items)]

    for m in reference["matrices"]:
        mine = [r for r in rows if r.matrix == m["matrix"]]
        by = lambda pred: [r.name for r in mine if pred(r)]  # noqa: E731
        matrices.append({
            "group": m.get("group", ""),
            "matrix": m["matrix"],
            "element": m["element"],
            "paper_zero": op(by(lambda r: r.paper in ("zero", "both"))),
            "paper_identified": op(by(lambda r: r.paper in ("identified", "both"))),
            "gauge": op(by(lambda r: r.ours == "gauge")),
            "forced": op(by(lambda r: r.ours == "forced")),
            "coupled": op(by(lambda r: r.ours.startswith("coupled"))),
            "non_influent": op(by(lambda r: r.ours == "free-non-influent")),
            "influential": op(by(lambda r: r.ours in ("free-influential", "coupled-influential"))),
            "agree": sum(r.category == "agree" for r in mine),
            "differ": sum(r.category != "agree" for r in mine),
        })
    claims = reference.get("claims", {})
    checks_text = []
    if "parameter_count" in claims:
        parallel = [r for r in rows if r.group.startswith("leg")]
        checks_text.append(f"parameters of the parallel architecture: paper {claims['parameter_count']}, "
                           f"its Table 2 (ours) {len(parallel)}")
    if "normalisation_constraints" in claims:
        norm = [p for p in result.parameters if p.verdict == "gauge" and p.reason.startswith("normalisation")
                and group_of.get(p.element, "").startswith("leg")]
        checks_text.append(f"normalisation constraints in the parallel architecture: paper "
                           f"{claims['normalisation_constraints']}, ours {len(norm)}")
    checks_text.append(f"Table 3 lists {len(zero)} zeros and Table 5 {len(ident)} parameters to identify")
    if "table5_row_totals" in claims:
        counted = Counter(group_of[p.element] for p in mechanism.parameters if p.name in ident)
        for g, total in claims["table5_row_totals"].items():
            checks_text.append(f"Table 5 '{g}': printed total {total}, entries {counted.get(g, 0)}")
    for key, groups in (("identified_parallel", ("leg 1", "leg 2", "leg 3")), ("identified_wrist", ("wrist",))):
        if key in claims:
            n = sum(1 for p in mechanism.parameters if p.name in ident and group_of.get(p.element) in groups)
            checks_text.append(f"{key.replace('_', ' ')}: text says {claims[key]}, Table 5 has {n} entries")
    if "identified_total" in claims:
        checks_text.append(f"identified in total: text says {claims['identified_total']} (and a Jacobian of rank "
                           f"{claims['identified_total']}), Table 5 has {len(ident)} entries")
    both = [r.name for r in rows if r.paper == "both"]
    if both:
        checks_text.append("in both Table 3 and Table 5: " + ", ".join(both))
    return Comparison(rows, matrices, checks_text)
