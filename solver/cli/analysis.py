"""Commands of the analysis stage: ``analyze``, ``check-hypotheses``, ``compare``.

Units: lengths in mm, angles in rad.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path

from hyperstat.solver.atomic import write_json
from hyperstat.solver.cli.common import PLOTTERS, analysis_of, common_options, jsonable, load_source
from hyperstat.solver.errors import HyperstatError


def _cmd_analyze(args: argparse.Namespace) -> int:
    from hyperstat.solver.kinematics.closure import Kinematics
    from hyperstat.solver.export.text import format_analysis
    from hyperstat.solver.analysis.stationarity import analyze
    from hyperstat.solver.analysis.symbolic import exact_check
    from hyperstat.solver.analysis.verify import verify

    mech, provenance = load_source(args.source, args.param)
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, n_configurations=args.configurations, seed=args.seed, kinematics=kin,
                         samples=args.samples)
    checks = verify(mech, result, kinematics=kin) if args.verify else None
    exact = exact_check(mech, kin=kin) if args.exact else None
    from hyperstat.solver.tolerances.classification import classify

    tolerances = classify(mech, result, kin).to_dict()
    doc = result.to_dict()
    doc["source"] = provenance
    doc["tolerances"] = tolerances
    if checks is not None:
        doc["verification"] = [c.to_dict() for c in checks]
    if exact is not None:
        doc["exact"] = exact.to_dict()
    if args.json:
        write_json(args.json, jsonable(doc))
    if not args.quiet:
        sys.stdout.write(format_analysis(result, checks, exact, tolerances))
        combined = [c for c in checks or [] if c.kind.startswith("combination")]
        if combined:
            sys.stdout.write(f"\nChecks in combination, at all {result.n_configurations} configurations (mm):\n")
            for c in combined:
                mark = "confirmed" if c.confirmed else "NOT CONFIRMED"
                if c.correction is not None:  # closed exactly by the smallest correction
                    sys.stdout.write(f"  {c.kind}: {c.subject}: {mark}, {c.note}\n")
                    continue
                sys.stdout.write(f"  {c.kind}: {c.subject}: {mark}, residual {c.residual:.2e} mm "
                                 f"({c.residual_small:.2e} mm at a tenth of the defect; "
                                 f"{c.predicted:.2e} mm predicted)\n")
        if result.stability is not None:
            sys.stdout.write(f"\nVerdicts: {result.stability['summary']}.\n")
        if args.json:
            sys.stdout.write(f"wrote {args.json}\n")
    if result.stability is not None and not result.stability["stable"]:
        sys.stderr.write(f"hyperstat: the analysis of '{mech.name}' depends on the sample: "
                         f"{'; '.join(result.stability['disagreements'])}.\n")
        return 3
    if checks is not None and not all(c.confirmed for c in checks):
        return 1
    return 0


def _cmd_check_hypotheses(args: argparse.Namespace) -> int:
    from hyperstat.solver.analysis.hypotheses import check_hypotheses, load_hypotheses

    mech, provenance, kin, result = analysis_of(args)
    axes, points, hyps = load_hypotheses(args.hypotheses, mech)
    verdicts = check_hypotheses(mech, result, axes, points, hyps, kinematics=kin)
    doc = {"mechanism": mech.name, "source": provenance, "hypothesis_file": str(args.hypotheses),
           "units": {"length": "mm", "angle": "rad"},
           "hypotheses": [v.to_dict() for v in verdicts]}
    if args.json:
        write_json(args.json, jsonable(doc))
    if not args.quiet:
        width = max(len(v.id) for v in verdicts)
        for v in verdicts:
            sys.stdout.write(f"{v.id:<{width}}  {v.verdict:<16} {v.reason}\n{'':<{width}}  {'':<16} {v.evidence}\n")
        if args.json:
            sys.stdout.write(f"wrote {args.json}\n")
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from hyperstat.solver.atomic import write_text
    from hyperstat.solver.analysis.compare import compare, load_reference
    from hyperstat.solver.analysis.verify import verify

    mech, provenance, kin, result = analysis_of(args)
    reference = load_reference(args.reference)
    checks = verify(mech, result, kinematics=kin) if args.verify else None
    comp = compare(mech, result, reference, checks)
    text = comp.to_markdown()
    if args.markdown:
        write_text(args.markdown, text)
    if args.json:
        write_json(args.json, jsonable({"mechanism": mech.name, "source": provenance, **comp.to_dict()}))
    if not args.quiet:
        sys.stdout.write(text)
    return 0


def _samples(text: str) -> int:
    """``--samples``: an integer of at least 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--samples must be an integer, got '{text}'") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"--samples must be at least 1, got {value}")
    return value


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Add this stage's sub-commands to the ``hyperstat`` parser."""
    p = sub.add_parser("analyze", help="stationarity analysis: forced / coupled / free defects")
    p.add_argument("source", help="template (.py), model file (.json) or STEP file (.step with its sidecar)")
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="template parameter override")
    p.add_argument("--verify", action="store_true", help="confirm every verdict by nonlinear re-assembly")
    p.add_argument("--exact", action="store_true", help="certify the rank with exact rational arithmetic (sympy)")
    p.add_argument("--json", metavar="OUT", help="write the result as JSON")
    p.add_argument("--configurations", type=int, default=24, help="configurations sampled (default 24)")
    p.add_argument("--seed", type=int, default=0, help="seed of the configuration sample")
    p.add_argument("--samples", type=_samples, default=2, metavar="N",
                   help="independent samples analysed and compared (default 2; exit 3 if they disagree)")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_cmd_analyze)
    p = sub.add_parser("check-hypotheses", help="check a designer's geometric hypotheses against the analysis")
    p.add_argument("source", help="template, model file or STEP file")
    p.add_argument("hypotheses", help="hypothesis file (YAML)")
    common_options(p)
    p.set_defaults(func=_cmd_check_hypotheses)
    p = sub.add_parser("compare", help="compare the analysis with a paper's tables (reference YAML)")
    p.add_argument("source", help="template, model file or STEP file")
    p.add_argument("reference", help="reference file (YAML)")
    p.add_argument("--verify", action="store_true", help="attach the nonlinear evidence to every difference")
    p.add_argument("--markdown", metavar="OUT.md", help="write the comparison as Markdown")
    common_options(p)
    p.set_defaults(func=_cmd_compare)
