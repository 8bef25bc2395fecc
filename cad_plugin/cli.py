"""The ``hyperstat`` console script: the solver's commands plus CAD sources and commands.

Units: lengths in mm, angles in rad.
"""

from __future__ import annotations

import sys
import time
from functools import partial
from pathlib import Path

from hyperstat.solver import cli as solver_cli
from hyperstat.solver.cli.cached import cache_option
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.threads import limited_blas

__all__ = ["main"]


def _load_template(path: Path, overrides: list[str]) -> tuple[Mechanism, dict]:
    from hyperstat.cad_plugin.templates import build_template

    skeleton = build_template(path, overrides)
    mech = skeleton.mechanism()
    return mech, {"source": str(path), "kind": "template", "parameters": mech.metadata.get("parameters", {})}


def _load_step(path: Path, overrides: list[str]) -> tuple[Mechanism, dict]:
    from hyperstat.solver.errors import HyperstatError

    from hyperstat.cad_plugin.extract import extract_from_step

    if overrides:
        raise HyperstatError(f"{path}: parameter overrides (-p) apply to templates, not to STEP files.")
    mech = extract_from_step(path)
    return mech, {"source": str(path), "kind": "step", "parameters": mech.metadata.get("parameters", {})}


def _plot_diagnosis(diag, data, directory):
    from hyperstat.cad_plugin.plots import write_diagnosis_plots

    return write_diagnosis_plots(diag, data, directory)


def _plot_accuracy(*args, **kwargs):
    from hyperstat.cad_plugin.plots import accuracy_map_png

    return accuracy_map_png(*args, **kwargs)


def _bundled(name: str) -> Path:
    """A bundled template's path from its name (``tripteor_x7``, ``bennett``); one sentence if there is none."""
    from hyperstat.cad_plugin.templates import template_path

    return template_path(name)


def _template_arg(text: str, command: str) -> Path:
    """The template of ``build``, ``parameters``, ``sweep``: a ``.py`` file or a bundled template's name."""
    from hyperstat.solver.errors import HyperstatError

    path = Path(text)
    if not path.suffix and not path.exists():
        path = _bundled(text)
    if path.suffix.lower() != ".py":
        raise HyperstatError(f"{text}: '{command}' takes a template (.py) or a bundled template's name.")
    return path


solver_cli.register_name_resolver(_bundled)
solver_cli.register_plotter("diagnosis", _plot_diagnosis)
solver_cli.register_plotter("accuracy", _plot_accuracy)
solver_cli.register_source(".py", _load_template)
solver_cli.register_source(".step", _load_step)
solver_cli.register_source(".stp", _load_step)


def _cmd_build(args) -> int:
    from hyperstat.solver.errors import HyperstatError
    from hyperstat.solver.kinematics.modelfile import save_model

    from hyperstat.cad_plugin.assembly import export_step
    from hyperstat.cad_plugin.templates import build_template

    args.template = str(_template_arg(args.template, "build"))
    skeleton = build_template(args.template, args.param)
    mech = skeleton.mechanism()
    wrote = []
    if args.model:
        wrote.append(save_model(mech, args.model))
    if args.step:
        wrote += list(export_step(skeleton, args.step))
    if not args.quiet:
        counts = mech.count()
        print(f"{mech.name}: {counts['R']} R + {counts['P']} P joints ({counts['actuated']} actuated), "
              f"{counts['parameters']} defect parameters, {counts['closures']} loop closure(s)")
        for w in wrote:
            print(f"wrote {w}")
    return 0


def _cmd_view(args) -> int:
    from hyperstat.cad_plugin.view import render_png

    with solver_cli.stages(args, ["model", "rendering"]) as progress:
        progress.next("model")
        mech, provenance = solver_cli.load_source(args.source, args.param)
        analysis = _analysis_file(args.analysis, mech)
        progress.next("rendering")
        out = render_png(mech, args.png, analysis=analysis, words=args.words)
    if not args.quiet:
        print(f"wrote {out}")
    return 0


def _analysis_file(path: str | None, mech: Mechanism) -> dict | None:
    """The JSON of ``hyperstat analyze --json`` at ``path``, checked against ``mech``."""
    import json

    from hyperstat.solver.errors import HyperstatError

    analysis = None
    if path:
        try:
            analysis = json.loads(Path(path).read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise HyperstatError(f"{path}: cannot be read as an analysis JSON ({exc.__class__.__name__}).") from None
        if not isinstance(analysis, dict) or not isinstance(analysis.get("parameters"), list):
            raise HyperstatError(f"{path}: field 'parameters' is missing: not a 'hyperstat analyze --json' output.")
        known = {p.name for p in mech.parameters}
        unknown = [p.get("name") for p in analysis["parameters"] if p.get("name") not in known]
        if unknown:
            raise HyperstatError(f"{path}: parameter '{unknown[0]}' is not a defect of '{mech.name}'.")
    return analysis


def _cmd_report(args) -> int:
    import warnings
    from types import SimpleNamespace

    from hyperstat.solver.calibration.measurements import read_measurements
    from hyperstat.solver.export.report_content import report_document
    from hyperstat.solver.analysis.verify import verify
    from hyperstat.solver.tolerances.accuracy import report_section, sample_workspace
    from hyperstat.solver.tolerances.classification import classify
    from hyperstat.solver.tolerances.values import ASSEMBLY_SAMPLE, assign_values, monte_carlo_at_values
    from hyperstat.solver.tolerances.workspace import workspace_of
    from hyperstat.solver.cli.cached import cached_sample, cached_values, command_cache, store_selection

    from hyperstat.cad_plugin.background import PAGES_NICE, PICTURES_NICE, Background
    from hyperstat.cad_plugin.palette import element_classes
    from hyperstat.cad_plugin.report import (cached_diagnosis, cached_views, decode_entry, diagnosis_entry,
                                             part_pages_worker, preload_pictures, skeleton_views_drawn,
                                             store_diagnosis, store_views, write_report)

    date = _report_date(args.date)  # a bad date is refused before any work
    if args.workspace_loss is not None:  # and a bad budget
        from hyperstat.solver.tolerances.declaration import check_workspace_loss

        check_workspace_loss(args.workspace_loss, "--workspace-loss")
    if args.pdf:  # a missing printer is said before any work
        from hyperstat.cad_plugin.report_pdf import chromium
        from hyperstat.solver.errors import HyperstatError

        if args.json_only:
            raise HyperstatError("--pdf prints the HTML report, which --json-only does not write; give one of them.")
        chromium()
    stages = ["stationarity analysis", "verification", "calibration and diagnosis", "tolerances and accuracy",
              "layout and pictures"]
    with solver_cli.stages(args, stages) as progress:
        progress.next("stationarity analysis")
        mech, provenance, kin, result = solver_cli.analysis_of(args)
        from hyperstat.solver.forked import idle_core, when_idle

        # the pictures' children yield the cores to this process' values when nothing else runs now (PICTURES_NICE)
        quiet = idle_core()
        # the accuracy coefficients depend on the analysis only: by a child on the core the start leaves idle (the
        # same numbers; computed here at once when no core is idle), not alone at the end
        accuracy_job = when_idle(_quietly, report_section, mech, result, kin)
        # the tolerance classes colour the skeleton views: classified now, the views are drawn by a forked
        # child (pyvista import and rendering) while this process verifies, diagnoses and allocates; the child
        # also lays out the skeleton drawing without frames (a report with part drawings has its frames on the
        # parts' pages), which write_report would otherwise draw at the end, alone on the critical path
        tolerances = classify(mech, result, kin)
        from hyperstat.solver.cli.tolerances import with_workspace_loss

        with_workspace_loss(tolerances, args.workspace_loss)
        early = solver_cli.jsonable({**result.to_dict(), "tolerances": tolerances.to_dict()})
        preloaded = False

        def before_a_fork() -> None:  # matplotlib imported once, before the first child that draws, not in each
            nonlocal preloaded
            if not (args.json_only or preloaded):
                preload_pictures()
                preloaded = True

        # this model's views as an earlier report drew them (the same bytes), else drawn now by the child
        drawn_before = None if args.json_only else cached_views(args, mech, early)
        views = None
        if not (args.json_only or drawn_before is not None):
            before_a_fork()
            views = Background(skeleton_views_drawn, mech, early, nice=PICTURES_NICE if quiet else 0)
        pages = None

        def start_pages() -> None:  # values to compute: a child imports OCCT meanwhile, then draws the part pages
            nonlocal pages
            if not (args.json_only or args.step_drawings or all(t.cls == "non-influent" for t in tolerances.items)):
                before_a_fork()
                pages = part_pages_worker(command_cache(args), provisional, nice=PAGES_NICE if quiet else 0)

        kinds = {el.name: getattr(el, "type", "F") for ch in mech.chains for el in ch.elements}
        types = {p.element: kinds.get(p.element, "F") for p in result.parameters}  # as report.json's "joints"

        def provisional() -> tuple:  # in the pages' child: the drawings predicted before the values, to build ahead
            from hyperstat.solver.tolerances.drawing import provisional_drawings

            return solver_cli.jsonable(provisional_drawings(tolerances, mech, kin)), types
        data = read_measurements(args.data, mech) if args.data else None
        validation = read_measurements(args.validation, mech) if args.validation else None
        hypotheses = None
        if args.hypotheses:
            from hyperstat.solver.analysis.hypotheses import check_hypotheses, load_hypotheses

            axes, points, hyps = load_hypotheses(args.hypotheses, mech)
            hypotheses = check_hypotheses(mech, result, axes, points, hyps, kinematics=kin)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            progress.next("verification")
            checks = verify(mech, result, kinematics=kin)
            progress.next("calibration and diagnosis")
            diagnosis = identification = diagnosing = None
            images = {}
            data_files = [args.data, args.validation]
            if data is not None:
                stored = None if data.noise is None else cached_diagnosis(args, mech, result, data_files,
                                                                          not args.json_only)
                if stored is not None:  # this model's diagnosis of these data files, as a report wrote it
                    identification, diagnosis = stored["identification"], stored["diagnosis"]
                    if not args.json_only:
                        images.update(stored["figures"])
                    store_selection(args, mech, result, data_files, SimpleNamespace(
                        selected=stored["selected"], violated_defect=stored["violated_defect"]))
                elif data.noise is not None:  # diagnosed and plotted by a forked child while this computes the values
                    before_a_fork()
                    diagnosing = Background(diagnosis_entry, mech, result, data, validation, kin, not args.json_only,
                                            nice=PICTURES_NICE if quiet else 0)
                else:
                    from hyperstat.solver.calibration.identify import identify

                    identification = identify(mech, result, data, validation, kinematics=kin)
            progress.next("tolerances and accuracy")
            workspace = cached_sample(args, mech, 200, 0, workspace_of(mech),
                                      lambda: sample_workspace(mech, 200, seed=0, kinematics=kin))
            if len(workspace) == 0:
                workspace = result.configurations
            # the values with calibration on the second core, beside the searches (the same values)
            cached_values(args, tolerances, mech, kin, workspace, partial(assign_values, background=True),
                          on_miss=start_pages,
                          position_accuracy=args.position_accuracy, orientation_accuracy=args.orientation_accuracy,
                          assembly_configurations=result.configurations[:ASSEMBLY_SAMPLE])
            sent = None
            if pages is not None:  # the part drawings are final with the values: the child draws them meanwhile
                sent = solver_cli.jsonable({"drawings": (getattr(tolerances, "drawings", None) or {}).get("drawings")
                                            or [], "joints": [{"element": e, "type": t} for e, t in types.items()]})
                pages.send(sent)
            accuracy = accuracy_job.result()
            # the Monte Carlo before the diagnosis' result: it needs the values only, and the diagnosis' child may
            # still be drawing its plots
            montecarlo = monte_carlo_at_values(tolerances, mech, kin, workspace, samples=1000, seed=0,
                                               position_accuracy=args.position_accuracy,
                                               orientation_accuracy=args.orientation_accuracy) or None
            if diagnosing is not None:
                stored = decode_entry(diagnosing.result(timeout=600.0))
                identification, diagnosis = stored["identification"], stored["diagnosis"]
                images.update(stored["figures"] or {})
                store_selection(args, mech, result, data_files, SimpleNamespace(  # export-controller's
                    selected=stored["selected"], violated_defect=stored["violated_defect"]))
                store_diagnosis(args, mech, result, data_files, stored)
        doc = report_document(mech, provenance, result, checks, hypotheses, identification, diagnosis, tolerances,
                              accuracy, montecarlo)
        _title_block(doc, args.revision, date)
        progress.next("layout and pictures")
        if pages is not None:
            final = solver_cli.jsonable({"drawings": doc.get("drawings") or [], "joints": doc["joints"]})
            if doc.get("drawings") and final["drawings"] == sent["drawings"] and \
                    {str(j["element"]): j.get("type") for j in final["joints"]} == \
                    {str(j["element"]): j.get("type") for j in sent["joints"]}:
                images["parts"] = pages
            else:  # nothing to draw, or not what the child was sent (then write_report draws them here)
                pages.result()
        analysis_json = solver_cli.jsonable({**result.to_dict(), "tolerances": doc["tolerances"]})
        if args.json_only:  # the values without the pictures (the FreeCAD workbench's Analyse)
            from hyperstat.solver.atomic import dumps_json, write_text

            written = [write_text(Path(args.out) / "report.json", dumps_json(solver_cli.jsonable(doc)))]
        else:
            drawn = drawn_before
            if drawn is None:
                drawn = views.result()
                store_views(args, mech, early, drawn)
            if element_classes(analysis_json) == element_classes(early):  # else write_report renders them again
                images["rendered"], images["skeleton"] = drawn["rendered"], drawn["drawing"]
            written = write_report(solver_cli.jsonable(doc), args.out, mech, analysis_json, images,
                                   step_drawings=args.step_drawings, pdf=args.pdf, cache=command_cache(args))
    if not args.quiet:  # a drawing no workshop can make is said here too (its page 1 says it first)
        from hyperstat.solver.tolerances.drawing import PRACTICAL_SIZE_WARNING

        for w in (doc.get("tolerances") or {}).get("warnings") or []:
            if w.startswith(PRACTICAL_SIZE_WARNING):
                sys.stderr.write(f"hyperstat: warning: {Path(args.out) / 'report.json'}: {w}\n")
        c = doc["summary"]["tolerance_classes"]
        print(f"{mech.name}: " + ", ".join(f"{n} {k}" for k, n in c.items()))
        for w in written:
            print(f"wrote {w}")
        if not args.json_only:
            print(f"open {Path(args.out) / 'report.html'} in a browser (self-contained, prints on A4)")
    return 0


def _quietly(fn, *args):
    """``fn(*args)`` with its warnings silenced, as the report computes its stages (a child's would reach the terminal)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args)


def _report_date(text: str | None) -> str:
    """``--date`` (YYYY-MM-DD) or today (UTC; ``SOURCE_DATE_EPOCH`` when set, for reproducible reports)."""
    import datetime as dt
    import os

    from hyperstat.solver.errors import HyperstatError

    if text is not None:
        try:
            return dt.date.fromisoformat(text).isoformat()
        except ValueError:
            raise HyperstatError(f"--date '{text}' is not a date of the form YYYY-MM-DD.") from None
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    now = dt.datetime.fromtimestamp(int(epoch), dt.timezone.utc) if epoch and epoch.isdigit() else \
        dt.datetime.now(dt.timezone.utc)
    return now.date().isoformat()


def _title_block(doc: dict, revision: str, date: str) -> None:
    """The report's title block: version, date, revision, and the source path as printed (never absolute)."""
    from hyperstat.cad_plugin.report_words import display_path

    shown = display_path(doc["title"].get("template"))
    doc["title"].update({"template": shown, "hyperstat_version": solver_cli._installed_version(),
                         "date": date, "revision": revision})
    doc["source"] = {**doc["source"], "source": shown}


def _cmd_parameters(args) -> int:
    from hyperstat.solver.atomic import write_json
    from hyperstat.solver.errors import HyperstatError

    from hyperstat.cad_plugin.params import describe
    from hyperstat.cad_plugin.templates import load_template, template_parameters

    args.template = str(_template_arg(args.template, "parameters"))
    module = load_template(args.template)
    doc = (module.__doc__ or "").strip().splitlines()
    out = {"template": str(args.template), "title": doc[0] if doc else Path(args.template).stem,
           "units": {"length": "mm", "angle": "rad"}, "parameters": describe(template_parameters(module))}
    if args.json:
        write_json(args.json, solver_cli.jsonable(out))
    if not args.quiet:
        for d in out["parameters"]:
            print(f"{d['name']:<24} {d['default']:>12g} {d['unit']:<4} {d['doc']}")
        if args.json:
            print(f"wrote {args.json}")
    return 0

def _cmd_sweep(args) -> int:

    from hyperstat.solver.errors import HyperstatError

    from hyperstat.cad_plugin.sweep import sweep_template, write_table

    args.template = str(_template_arg(args.template, "sweep"))
    if Path(args.out).suffix.lower() != ".csv":
        raise HyperstatError(f"--out '{args.out}': the sweep table is written as CSV; give a file name ending in .csv.")
    if args.configurations < 1:
        raise HyperstatError(f"--configurations must be at least 1, got {args.configurations}.")
    montecarlo = None
    if args.montecarlo:
        if args.samples < 1:
            raise HyperstatError(f"--samples must be at least 1, got {args.samples}.")
        montecarlo = {"samples": args.samples, "angle_tolerance": args.angle_tolerance,
                      "length_tolerance": args.length_tolerance}
    t0 = time.perf_counter()
    rows, units = sweep_template(args.template, args.grid, args.param, configurations=args.configurations,
                                 seed=args.seed, montecarlo=montecarlo, scheduler=args.scheduler,
                                 progress=not args.quiet)
    out = write_table(args.out, rows, units)
    failed = sum(bool(r["error"]) for r in rows)
    if not args.quiet:
        where = f"on {args.scheduler}" if args.scheduler else "serially"
        print(f"{len(rows)} variant(s) analysed {where} in {time.perf_counter() - t0:.1f} s, {failed} failed "
              f"(see the 'error' column)")
        print(f"wrote {out}")
    return 1 if rows and failed == len(rows) else 0


def build_parser():
    """The solver's parser plus the CAD commands."""
    parser = solver_cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    p = sub.add_parser("build", help="build a template: model file and/or STEP file with its sidecar")
    p.add_argument("template", help="template file (.py)")
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="template parameter override")
    p.add_argument("--step", metavar="OUT.step", help="write the CAD skeleton as STEP (+ OUT.step.json sidecar)")
    p.add_argument("--model", metavar="OUT.json", help="write the model file")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_cmd_build)
    p = sub.add_parser("view", help="render the skeleton with its markers (PNG, off-screen)")
    p.add_argument("source", help="template (.py), model file (.json) or STEP file")
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="template parameter override")
    p.add_argument("--analysis", metavar="RESULT.json",
                   help="colour the joints by the tolerance classes of this analysis")
    p.add_argument("--png", required=True, metavar="OUT.png", help="output picture")
    p.add_argument("--words", metavar="OUT.json", help="also write the words the picture shows (legend, views, "
                   "callouts) as JSON")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_cmd_view)
    p = sub.add_parser("report", help="tolerance report: report.html (self-contained), report.md, report.json")
    p.add_argument("source", help="template (.py), model file (.json) or STEP file")
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="template parameter override")
    p.add_argument("--data", metavar="ID.csv", help="identification measurements (identification and diagnosis)")
    p.add_argument("--validation", metavar="VAL.csv", help="validation measurements")
    p.add_argument("--hypotheses", metavar="H.yaml", help="design hypotheses to check")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--position-accuracy", type=float, metavar="MM", help="spec: required position accuracy (mm), "
                   "overrides the template's")
    p.add_argument("--orientation-accuracy", type=float, metavar="RAD", help="spec: required orientation accuracy "
                   "(rad), overrides the template's")
    from hyperstat.solver.cli.tolerances import workspace_loss_option

    workspace_loss_option(p)
    p.add_argument("--configurations", type=int, default=24, help="configurations sampled (default 24)")
    p.add_argument("--seed", type=int, default=0, help="seed of the configuration sample")
    p.add_argument("--revision", default="-", metavar="TEXT", help="revision printed in the title block (default '-')")
    p.add_argument("--step-drawings", action="store_true", help="also write each part drawing as DIR/parts/PART.step: "
                   "STEP AP242 with its datums and geometric tolerances as semantic PMI")
    p.add_argument("--date", metavar="YYYY-MM-DD", help="date printed in the title block (default: today, or "
                   "SOURCE_DATE_EPOCH when set)")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.add_argument("--pdf", action="store_true", help="also print the report on A4 as DIR/report.pdf (headless Chromium)")
    p.add_argument("--json-only", action="store_true", help="write report.json only: the same content, without the "
                   "pictures, the HTML and the Markdown (what the FreeCAD workbench's Analyse reads)")
    cache_option(p)
    p.set_defaults(func=_cmd_report, known_outputs=("report.json", "report.md", "report.html", "skeleton_views.png",
                                               "skeleton_views.png.json", "report.pdf"))
    p = sub.add_parser("parameters", help="list a template's parameters: name, default, unit, meaning, bounds")
    p.add_argument("template", help="template file (.py)")
    p.add_argument("--json", metavar="OUT.json", help="write them as JSON")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_cmd_parameters)

    p = sub.add_parser("sweep", help="stationarity analysis over a grid of template parameters (CSV table)")
    p.add_argument("template", help="template file (.py)")
    p.add_argument("--grid", action="append", required=True, metavar="NAME=LOW:HIGH:COUNT",
                   help="sweep a parameter over COUNT evenly spaced values (units as for -p); repeat for a product")
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="fixed template parameter override")
    p.add_argument("--configurations", type=int, default=24, help="configurations sampled per analysis (default 24)")
    p.add_argument("--seed", type=int, default=0, help="seed of the configuration sample (the same for every variant)")
    p.add_argument("--montecarlo", action="store_true", help="add Monte Carlo pose-error columns per variant")
    p.add_argument("--samples", type=int, default=10000, help="Monte Carlo samples per variant (default 10000)")
    p.add_argument("--angle-tolerance", type=float, default=2e-4, help="Monte Carlo angular tolerance (rad)")
    p.add_argument("--length-tolerance", type=float, default=0.05, help="Monte Carlo length tolerance (mm)")
    p.add_argument("--out", required=True, metavar="TABLE.csv", help="output table, one row per variant")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run the variants on this Dask scheduler")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no summary")
    p.set_defaults(func=_cmd_sweep)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``hyperstat`` command.

    BLAS runs single-threaded (``HYPERSTAT_BLAS_THREADS`` to change it, see
    :mod:`hyperstat.solver.threads`): the commands do many small dense solves, where
    OpenBLAS's threads only add synchronisation.
    """
    return limited_blas(solver_cli.main)(argv, build_parser())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
