"""Commands of the diagnosis stage: ``diagnose``, ``validate-diagnosis``.

Units: lengths in mm, angles in rad.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path

from hyperstat.solver.atomic import write_json
from hyperstat.solver.cli.common import PLOTTERS, analysis_of, common_options, jsonable, load_source, stages
from hyperstat.solver.errors import HyperstatError


def _cmd_diagnose(args: argparse.Namespace) -> int:
    from hyperstat.solver.diagnosis.diagnose import diagnose, format_outcome
    from hyperstat.solver.diagnosis.effects import available_effects, is_known_effect
    from hyperstat.solver.export.text import format_diagnosis
    from hyperstat.solver.calibration.measurements import read_measurements

    known = available_effects()
    candidates = tuple(args.effects.split(",")) if args.effects else None  # None: the library, spectrum, plug-ins
    unknown = [c for c in candidates or () if not is_known_effect(c)]
    if unknown:
        raise HyperstatError(f"--effects: unknown effect '{unknown[0]}'; effects are {', '.join(known)} and "
                             f"angle-harmonic-<k> for any positive k.")
    steps = ["rigid fit", "where", "candidates", "selection", "nonlinear fit", "verdict", "per target"]
    with stages(args, ["stationarity analysis"] + steps + ["plots"]) as progress:
        progress.next("stationarity analysis")
        mech, provenance, kin, result = analysis_of(args)
        data = read_measurements(args.data, mech)
        validation = read_measurements(args.validation, mech) if args.validation else None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            diag = diagnose(mech, result, data, validation, candidates=candidates, kinematics=kin,
                            progress=progress.next)
        progress.next("plots")
        written = []
        if args.plots:
            if "diagnosis" not in PLOTTERS:
                raise HyperstatError("--plots needs the plotting side (run the 'hyperstat' console script).")
            written = PLOTTERS["diagnosis"](diag, data, args.plots)
    if args.json:
        doc = {"mechanism": mech.name, "source": provenance, "data": str(args.data),
               "validation_data": None if args.validation is None else str(args.validation), **diag.to_dict()}
        write_json(args.json, jsonable(doc))
    if not args.quiet:
        sys.stdout.write(format_diagnosis(diag))
        sys.stdout.write(format_outcome(diag))
        for w in written + ([args.json] if args.json else []):
            sys.stdout.write(f"wrote {w}\n")
    return 0


def _cmd_validate_diagnosis(args: argparse.Namespace) -> int:
    from hyperstat.solver.atomic import write_text
    from hyperstat.solver.diagnosis.validation_suite import (independent_markdown, load_independent_generator,
                                                             run_independent, run_suite, summarize,
                                                             summarize_independent, to_markdown)
    from hyperstat.solver.analysis.stationarity import analyze

    if not args.sources and not args.independent:
        raise HyperstatError("validate-diagnosis: give templates or model files for the virtual-machine suite, "
                             "--independent N for the independent generator, or both.")
    generator = load_independent_generator(args.generator) if args.independent else None
    sources = []
    for src in args.sources:
        mech, _ = load_source(src, [])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sources.append((mech, analyze(mech, n_configurations=args.configurations, seed=0)))
    bar = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(desc="validate-diagnosis", unit="case", file=sys.stderr, leave=False)

    def progress(r) -> None:
        if bar is not None:
            bar.update(1)
            bar.set_postfix_str(f"{getattr(r, 'mechanism', getattr(r, 'arm', ''))} "
                                f"{'+'.join(getattr(r, 'truth', ())) or getattr(r, 'case', 'none')}: "
                                f"{r.outcome}", refresh=False)

    words = ["hyperstat validate-diagnosis", *args.sources] + (["--seeds", str(args.seeds)] if args.sources else [])
    words += ["--independent", str(args.independent)] if args.independent else []
    words += ["--cases", args.cases] if args.cases else []
    command = " ".join(words)
    doc = {"command": command}
    text = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if sources:
            results = run_suite(sources, seeds=args.seeds, pairs=not args.no_pairs,
                                only=tuple(args.cases.split(",")) if args.cases else None, progress=progress)
            summary = summarize(results)
            doc.update(summary=summary, cases=[r.to_dict() for r in results])
            text.append("### The project's virtual machine (withheld effects)\n\n" + to_markdown(results, summary, command))
        if generator is not None:
            ind = run_independent(generator, seeds=args.independent, progress=progress,
                                  cases=tuple(args.cases.split(",")) if args.cases else None)
            ind_summary = summarize_independent(ind)
            doc.update(independent_summary=ind_summary, independent_cases=[r.to_dict() for r in ind])
            text.append("### The independent generator\n\n" + independent_markdown(ind, ind_summary, command))
    if bar is not None:
        bar.close()
    if args.json:
        write_json(args.json, jsonable(doc))
    if args.markdown:
        write_text(args.markdown, "\n".join(text))
    if not args.quiet:
        for t in text:
            sys.stdout.write(t.split("####")[0])
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Add this stage's sub-commands to the ``hyperstat`` parser."""
    p = sub.add_parser("diagnose", help="diagnose the gap left by the rigid model: where, which effect, how far")
    p.add_argument("source", help="template, model file or STEP file")
    p.add_argument("data", help="identification measurements (CSV with a noise model)")
    p.add_argument("--validation", metavar="VAL.csv", help="validation measurements, never fitted")
    p.add_argument("--effects", help="comma-separated candidate effects, e.g. compliance,angle-harmonic-3 (default: the "
                   "library, the periodic orders of the residual spectrum and the plug-ins)")
    p.add_argument("--plots", metavar="DIR", help="write the residual plots (PNG) to DIR")
    common_options(p)
    p.set_defaults(func=_cmd_diagnose)
    p = sub.add_parser("validate-diagnosis", help="withheld-effect validation suite of the diagnosis")
    p.add_argument("sources", nargs="*", help="templates or model files (the virtual-machine suite)")
    p.add_argument("--seeds", type=int, default=5, help="seeds per case of the virtual-machine suite (default 5)")
    p.add_argument("--independent", type=int, default=0, metavar="N",
                   help="also run the independent generator (6R arm and SCARA model files), N seeds per case")
    p.add_argument("--generator", metavar="FILE", help="the independent generator's file (default: "
                   "tests/solver/diagnosis/independent_generator.py of this source tree)")
    p.add_argument("--cases", help="comma-separated cases, e.g. none,thermal,thermal+backlash (default: all)")
    p.add_argument("--no-pairs", action="store_true", help="leave out the pairs of effects")
    p.add_argument("--markdown", metavar="OUT.md", help="write the confusion matrix and rates as Markdown")
    p.add_argument("--configurations", type=int, default=24, help="configurations of the stationarity sample")
    p.add_argument("--json", metavar="OUT", help="write every case as JSON")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_cmd_validate_diagnosis)
