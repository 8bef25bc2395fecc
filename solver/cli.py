"""The ``hyperstat`` command line (solver side: model files only).

Units: lengths in mm, angles in rad.

``solver`` knows model files (``*.json``).  The CAD side (:mod:`cad_plugin.cli`)
registers more source kinds (templates ``*.py``, STEP files) and commands
(``build``, ``view``) and is what the ``hyperstat`` console script runs, so that the
solver never imports CAD code.  Every user error is one sentence on stderr and exit
code 2; outputs are written atomically.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path
from typing import Any, Callable

from .atomic import write_json
from .errors import HyperstatError
from .model import Mechanism
from .modelfile import load_model

__all__ = ["main", "build_parser", "register_source", "register_plotter", "load_source", "jsonable", "COMMANDS"]

# suffix -> loader(path, overrides) -> (Mechanism, provenance dict)
_SOURCES: dict[str, Callable[[Path, list[str]], tuple[Mechanism, dict]]] = {}
COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {}
PLOTTERS: dict[str, Callable] = {}  # kind -> plotting function, registered by the presentation side


def register_plotter(kind: str, function: Callable) -> None:
    """Let commands write plots of ``kind`` (e.g. ``"diagnosis"``) through ``function``."""
    PLOTTERS[kind] = function


def register_source(suffix: str, loader: Callable[[Path, list[str]], tuple[Mechanism, dict]]) -> None:
    """Let ``hyperstat`` read sources with ``suffix`` (e.g. ``".py"``) through ``loader``."""
    _SOURCES[suffix.lower()] = loader


def _load_json_model(path: Path, overrides: list[str]) -> tuple[Mechanism, dict]:
    if overrides:
        raise HyperstatError(f"{path}: parameter overrides (-p) apply to templates, not to model files.")
    return load_model(path), {"source": str(path), "kind": "model"}


register_source(".json", _load_json_model)


def load_source(path: str | Path, overrides: list[str] | None = None) -> tuple[Mechanism, dict]:
    """Mechanism from a model file, or a template / STEP file when the CAD side is loaded."""
    path = Path(path)
    loader = _SOURCES.get(path.suffix.lower())
    if loader is None:
        known = ", ".join(sorted(_SOURCES))
        raise HyperstatError(f"{path}: unknown source kind '{path.suffix}'; hyperstat reads {known}.")
    if not path.exists():
        raise HyperstatError(f"{path}: no such file.")
    return loader(path, list(overrides or []))


def jsonable(obj: Any) -> Any:
    """Plain JSON types: numpy scalars to Python, infinities and NaN to ``None``."""
    import numpy as np

    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


# ---------------------------------------------------------------------------- analyze
def _cmd_analyze(args: argparse.Namespace) -> int:
    from .closure import Kinematics
    from .export.text import format_analysis
    from .stationarity import analyze
    from .symbolic import exact_check
    from .verify import verify

    mech, provenance = load_source(args.source, args.param)
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, n_configurations=args.configurations, seed=args.seed, kinematics=kin)
    checks = verify(mech, result, kinematics=kin) if args.verify else None
    exact = exact_check(mech, kin=kin) if args.exact else None
    doc = result.to_dict()
    doc["source"] = provenance
    if checks is not None:
        doc["verification"] = [c.to_dict() for c in checks]
    if exact is not None:
        doc["exact"] = exact.to_dict()
    if args.json:
        write_json(args.json, jsonable(doc))
    if not args.quiet:
        sys.stdout.write(format_analysis(result, checks, exact))
        if args.json:
            sys.stdout.write(f"wrote {args.json}\n")
    if checks is not None and not all(c.confirmed for c in checks):
        return 1
    return 0


def _analysis(args: argparse.Namespace):
    from .closure import Kinematics
    from .stationarity import analyze

    mech, provenance = load_source(args.source, args.param)
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, n_configurations=args.configurations, seed=args.seed, kinematics=kin)
    return mech, provenance, kin, result


def _cmd_check_hypotheses(args: argparse.Namespace) -> int:
    from .hypotheses import check_hypotheses, load_hypotheses

    mech, provenance, kin, result = _analysis(args)
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
    from .atomic import write_text
    from .compare import compare, load_reference
    from .verify import verify

    mech, provenance, kin, result = _analysis(args)
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


# ---------------------------------------------------------------------------- simulate / identify
def _cmd_simulate(args: argparse.Namespace) -> int:
    from .identify import MeasurementModel
    from .measurements import parse_noise, write_measurements
    from .poses import select_poses
    from .virtual import VirtualMachine

    if args.poses < 1 or args.validation < 0:
        raise HyperstatError(f"--poses must be at least 1 and --validation at least 0 (got {args.poses}, "
                             f"{args.validation}).")
    noise = parse_noise(args.noise, "--noise")
    mech, provenance, kin, result = _analysis(args)
    effects = _simulated_effects(args, mech, result)
    vm = VirtualMachine.random(mech, result, seed=args.seed, angle_tolerance=args.angle_tolerance,
                               length_tolerance=args.length_tolerance, noise=noise, kinematics=kin, effects=effects)
    with_metadata = args.metadata or bool(effects)
    selection = None
    if args.select == "d-optimal":
        candidates = vm.poses(max(args.candidates, args.poses), seed=args.seed + 1)
        selection = select_poses(MeasurementModel(mech, result, kin), candidates, args.poses, seed=args.seed,
                                 noise=noise)
        q_id = candidates[selection.index]
    else:
        q_id = vm.poses(args.poses, seed=args.seed + 1, mode=args.select)
    comment = f"simulated by hyperstat: seed {args.seed}, defects within +-{args.angle_tolerance:g} rad / " \
              f"+-{args.length_tolerance:g} mm, poses {args.select}"
    q_val = vm.poses(args.validation, seed=args.seed + 3) if args.validation else None
    meta_id = meta_val = None
    if with_metadata:
        from .virtual import workshop_metadata

        meta = workshop_metadata(mech, len(q_id) + args.validation, seed=args.seed)
        meta_id = {k: v[: len(q_id)] for k, v in meta.items()}
        meta_val = {k: v[len(q_id):] for k, v in meta.items()}
    outputs = [(args.out, vm.measure(q_id, seed=args.seed + 2, metadata=meta_id), comment)]
    if args.validation:
        val_path = args.validation_out or str(Path(args.out).with_suffix("")) + ".validation.csv"
        outputs.append((val_path, vm.measure(q_val, seed=args.seed + 4, prefix="V", metadata=meta_val),
                        comment + " (validation)"))
    wrote = [write_measurements(path, data, mech, text) for path, data, text in outputs]
    if args.truth:
        doc = {"mechanism": mech.name, "source": provenance, "units": {"length": "mm", "angle": "rad"},
               "truth": vm.truth(), "drawn": vm.metadata}
        if selection is not None:
            doc["pose_selection"] = selection.to_dict()
        wrote.append(write_json(args.truth, jsonable(doc)))
    if not args.quiet:
        if selection is not None:
            sys.stdout.write(f"D-optimal poses: condition number {selection.condition_number:.3g} "
                             f"(random poses: {selection.random_condition_number:.3g})\n")
        for w in wrote:
            sys.stdout.write(f"wrote {w}\n")
    return 0


def _simulated_effects(args: argparse.Namespace, mech, result) -> tuple:
    """Effects of ``simulate --effect NAME[:DEFECT]`` with realistic true parameters (seeded)."""
    import numpy as np

    from .effects import EFFECT_NAMES, make_effect

    effects = []
    rng = np.random.default_rng(10_000 + args.seed)
    for spec in args.effect or []:
        name, _, defect = spec.partition(":")
        if name not in EFFECT_NAMES:
            raise HyperstatError(f"--effect: unknown effect '{name}'; effects are {', '.join(EFFECT_NAMES)}.")
        options: dict = {}
        if name == "tracker-drift":
            options["sessions"] = [1.0, 2.0]
        if name == "violated-constraint":
            from .diagnosis_suite import VIOLATION_MAGNITUDE

            if not defect:
                raise HyperstatError("--effect violated-constraint needs the forced defect, e.g. "
                                     "'violated-constraint:dK13'.")
            options.update(only=[defect], magnitude_rad=VIOLATION_MAGNITUDE, magnitude_mm=VIOLATION_MAGNITUDE)
        effects.append(make_effect(name, mech, result, None, **options).draw_truth(rng))
    return tuple(effects)


def _cmd_identify(args: argparse.Namespace) -> int:
    from .export.text import format_identification
    from .identify import identify
    from .measurements import read_measurements

    mech, provenance, kin, result = _analysis(args)
    data = read_measurements(args.data, mech)
    validation = read_measurements(args.validation, mech) if args.validation else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify(mech, result, data, validation, kinematics=kin)
    if args.json:
        doc = {"mechanism": mech.name, "source": provenance, "data": str(args.data),
               "validation_data": None if args.validation is None else str(args.validation), **res.to_dict()}
        write_json(args.json, jsonable(doc))
    if not args.quiet:
        sys.stdout.write(format_identification(res))
        if args.json:
            sys.stdout.write(f"wrote {args.json}\n")
    return 0


def _cmd_diagnose(args: argparse.Namespace) -> int:
    from .diagnose import diagnose
    from .effects import EFFECT_NAMES
    from .export.text import format_diagnosis
    from .measurements import read_measurements

    candidates = tuple(args.effects.split(",")) if args.effects else EFFECT_NAMES
    unknown = [c for c in candidates if c not in EFFECT_NAMES]
    if unknown:
        raise HyperstatError(f"--effects: unknown effect '{unknown[0]}'; effects are {', '.join(EFFECT_NAMES)}.")
    mech, provenance, kin, result = _analysis(args)
    data = read_measurements(args.data, mech)
    validation = read_measurements(args.validation, mech) if args.validation else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        diag = diagnose(mech, result, data, validation, candidates=candidates, kinematics=kin)
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
        for w in written + ([args.json] if args.json else []):
            sys.stdout.write(f"wrote {w}\n")
    return 0


def _cmd_validate_diagnosis(args: argparse.Namespace) -> int:
    from .atomic import write_text
    from .diagnosis_suite import run_suite, summarize, to_markdown
    from .stationarity import analyze

    sources = []
    for src in args.sources:
        mech, _ = load_source(src, [])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sources.append((mech, analyze(mech, n_configurations=args.configurations, seed=0)))

    def progress(r) -> None:
        if not args.quiet:
            sys.stderr.write(f"{r.mechanism:<14} seed {r.seed}  {'+'.join(r.truth) or 'none':<28} -> "
                             f"{'gap' if r.gap_significant else 'no gap':<6} first {r.ranked_first or '-':<20} "
                             f"selected {'+'.join(r.selected) or '-':<28} {'ok' if r.correct else 'WRONG'}\n")

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = run_suite(sources, seeds=args.seeds, pairs=not args.no_pairs,
                            only=tuple(args.cases.split(",")) if args.cases else None, progress=progress)
    summary = summarize(results)
    command = "hyperstat validate-diagnosis " + " ".join(args.sources) + f" --seeds {args.seeds}"
    if args.json:
        write_json(args.json, jsonable({"summary": summary, "cases": [r.to_dict() for r in results],
                                        "command": command}))
    if args.markdown:
        write_text(args.markdown, to_markdown(results, summary, command))
    if not args.quiet:
        sys.stdout.write(to_markdown(results, summary, command).split("### ")[0])
    return 0


def _cmd_export_controller(args: argparse.Namespace) -> int:
    from .controller import MACHINE_EFFECTS, controller_document, write_controller
    from .effects import make_effect
    from .identify import identify
    from .measurements import read_measurements

    mech, provenance, kin, result = _analysis(args)
    data = read_measurements(args.data, mech)
    validation = read_measurements(args.validation, mech) if args.validation else None
    names = list(args.effect or [])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if args.diagnose:
            from .diagnose import diagnose

            diag = diagnose(mech, result, data, validation, kinematics=kin)
            names += [n for n in diag.selected if n not in names]
            violated = diag.violated_defect["defect"] if diag.violated_defect else None
        else:
            violated = None
        effects = []
        for spec in names:
            name, _, defect = spec.partition(":")
            if name not in MACHINE_EFFECTS:
                if name in ("tracker-scale", "tracker-drift"):
                    continue  # measurement effects: fitted by the diagnosis, not part of the machine
                raise HyperstatError(f"--effect: '{name}' is not a machine effect ({', '.join(MACHINE_EFFECTS)}).")
            options = {"only": [defect or violated]} if name == "violated-constraint" else {}
            effects.append(make_effect(name, mech, result, data, **options))
        res = identify(mech, result, data, validation, effects=tuple(effects), kinematics=kin)
    files = [args.data] + ([args.validation] if args.validation else [])
    doc = controller_document(mech, res, tuple(effects), provenance, tuple(files))
    path = write_controller(args.out, doc)
    if not args.quiet:
        v = res.validation or res.identification
        sys.stdout.write(f"{mech.name}: {len(doc['identified'])} identified parameters, effects: "
                         f"{', '.join(e['effect'] for e in doc['effects']) or 'none'}; "
                         f"{'validation' if res.validation else 'identification'} RMS {1000 * v['rms']:.1f} um\n"
                         f"wrote {path} (sha256 {doc['sha256'][:16]}...)\n")
    return 0


def _cmd_export_linuxcnc(args: argparse.Namespace) -> int:
    import numpy as np

    from .atomic import write_text
    from .controller import ControllerModel, read_controller
    from .linuxcnc import genhexkins_parameters, hal_lines, ini_section

    if not args.controller and not args.source:
        raise HyperstatError("export-linuxcnc needs a hexapod SOURCE or --controller MACHINE.json.")
    if args.controller:
        doc = read_controller(args.controller)
        model = ControllerModel(doc)
        mech, xi = model.mechanism, model.xi
    else:
        mech, _ = load_source(args.source, args.param)
        xi = np.zeros(len(mech.parameters))
    params = genhexkins_parameters(mech, xi)
    hal = write_text(args.hal, hal_lines(params))
    ini = write_text(args.ini, ini_section()) if args.ini else None
    if not args.quiet:
        sys.stdout.write(f"genhexkins geometry of '{mech.name}': largest strut-length difference to the model "
                         f"{params['max_strut_difference_mm']:.3g} mm over {params['poses_checked']} poses\n"
                         f"wrote {hal}\n" + (f"wrote {ini}\n" if ini else ""))
    return 0


def _ranges(specs: list | None) -> dict:
    """``--range JOINT=LO:HI`` options -> {joint: (lo, hi)}."""
    out = {}
    for spec in specs or []:
        name, _, rest = spec.partition("=")
        try:
            lo, hi = (float(v) for v in rest.split(":"))
        except ValueError:
            raise HyperstatError(f"--range '{spec}' must read JOINT=LO:HI (mm or rad).") from None
        if not lo < hi:
            raise HyperstatError(f"--range '{spec}': LO must be below HI.")
        out[name] = (lo, hi)
    return out


def _accuracy_inputs(args: argparse.Namespace):
    from .accuracy import sample_workspace

    mech, provenance, kin, result = _analysis(args)
    ranges = _ranges(args.range)
    actuated = {mech.joints[i].name for i in mech.actuated}
    unknown = [j for j in ranges if j not in actuated]
    if unknown:
        raise HyperstatError(f"--range: '{unknown[0]}' is not an actuated joint of '{mech.name}' "
                             f"({', '.join(sorted(actuated))}).")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        q = sample_workspace(mech, args.configurations_workspace, seed=args.seed, ranges=ranges, kinematics=kin)
    if len(q) == 0:
        raise HyperstatError(f"no configuration of '{mech.name}' assembles in the actuated ranges.")
    over = result.overconstraint > 0
    return mech, provenance, kin, (result if over else None), q, over


def _fixed(specs: list | None) -> dict:
    out = {}
    for spec in specs or []:
        name, _, value = spec.partition("=")
        if name not in ("fP", "fR", "gP", "gR"):
            raise HyperstatError(f"--fixed '{spec}': the class must be fP, fR, gP or gR.")
        try:
            out[name] = float(value)
        except ValueError:
            raise HyperstatError(f"--fixed '{spec}': '{value}' is not a number.") from None
    return out


def _cmd_accuracy(args: argparse.Namespace) -> int:
    from .accuracy import accuracy_maps, allocate, compensable

    mech, provenance, kin, analysis, q, over = _accuracy_inputs(args)
    maps = accuracy_maps(mech, q, analysis, kinematics=kin)
    allocation = allocate(maps, args.orientation_accuracy, args.position_accuracy, _fixed(args.fixed))
    comp = compensable(q[: min(len(q), 200)], mech, analysis, kinematics=kin)
    doc = {"mechanism": mech.name, "source": provenance, "units": {"length": "mm", "angle": "rad"},
           "configurations": len(q), "coefficients": maps.summary(), "coefficient_units": maps.units,
           "groups": maps.groups, "allocation": allocation,
           "per_parameter": {n: {k: {"max": float(v.max()), "mean": float(v.mean())} for k, v in d.items()}
                             for n, d in maps.per_parameter.items()},
           "compensable_by_calibration": {n: r < 1e-6 for n, r in comp.items()},
           "geometric_errors": "admissible influential defects only (the forced ones are assembly conditions)"
           if over else "every defect parameter of the model"}
    if args.map:
        if "accuracy" not in PLOTTERS:
            raise HyperstatError("--map needs the plotting side (run the 'hyperstat' console script).")
        axes = tuple(args.map.split(","))
        actuated = [mech.joints[i].name for i in mech.actuated]
        if len(axes) != 2 or not all(a in actuated for a in axes):
            raise HyperstatError(f"--map '{args.map}' must name two actuated joints of '{mech.name}' "
                                 f"({', '.join(actuated)}).")
        slices = [{k: float(v) for k, v in (item.split("=") for item in spec.split(","))} for spec in args.slice or []]
        PLOTTERS["accuracy"](mech, analysis, axes, slices, args.map_png, ranges=_ranges(args.range), kinematics=kin)
    if args.json:
        write_json(args.json, jsonable(doc))
    if not args.quiet:
        sys.stdout.write(f"Accuracy coefficients of '{mech.name}' over {len(q)} configurations "
                         f"({doc['geometric_errors']}):\n")
        for name, v in doc["coefficients"].items():
            sys.stdout.write(f"  {name:<11} min {v['min']:.6g}  mean {v['mean']:.6g}  max {v['max']:.6g}  "
                             f"[{maps.units[name]}]\n")
        for cls, c in allocation["classes"].items():
            if c["tolerance"] is not None:
                sys.stdout.write(f"  class {cls}: tolerance {c['tolerance']:.6g} {c['unit']} per parameter"
                                 f"{' (given)' if c['given'] else ''}\n")
        for key in ("orientation_bound", "position_bound"):
            if allocation.get(key) is not None:
                sys.stdout.write(f"  {key.replace('_', ' ')}: {allocation[key]:.6g}\n")
        held = [n for n, ok in doc["compensable_by_calibration"].items() if not ok]
        sys.stdout.write(f"  held by manufacturing (not compensable by calibration): {', '.join(held) or 'none'}\n")
        if args.json:
            sys.stdout.write(f"wrote {args.json}\n")
    return 0


def _cmd_montecarlo(args: argparse.Namespace) -> int:
    from .accuracy import geometric_parameters
    from .montecarlo import monte_carlo

    if args.samples < 1:
        raise HyperstatError(f"--samples must be at least 1, got {args.samples}.")
    mech, provenance, kin, analysis, q, over = _accuracy_inputs(args)
    names, _ = geometric_parameters(mech, analysis)
    units = {p.name: p.unit for p in mech.parameters}
    tol = {n: args.angle_tolerance if units[n] == "rad" else args.length_tolerance for n in names}
    for i in mech.actuated:
        j = mech.joints[i]
        tol[j.name] = args.actuation_tolerance_angle if j.type == "R" else args.actuation_tolerance_length
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = monte_carlo(mech, q, tol, args.samples, args.distribution, args.seed, analysis, kin)
    summary = res.summary(args.orientation_accuracy, args.position_accuracy)
    doc = {"mechanism": mech.name, "source": provenance, "units": {"length": "mm", "angle": "rad"},
           "geometric_errors": "admissible influential defects only (the forced ones are assembly conditions)"
           if over else "every defect parameter of the model", **summary}
    if args.json:
        write_json(args.json, jsonable(doc))
    if not args.quiet:
        o, p = summary["orientation_rad"], summary["position_mm"]
        sys.stdout.write(f"Monte Carlo, {summary['samples']} samples ({args.distribution}):\n"
                         f"  orientation error: mean {o['mean']:.4g}  p99 {o['p99']:.4g}  max {o['max']:.4g} rad\n"
                         f"  position error:    mean {p['mean']:.4g}  p99 {p['p99']:.4g}  max {p['max']:.4g} mm\n"
                         f"  worst case / linear bound: orientation {summary['worst_over_bound']['orientation']:.3f}, "
                         f"position {summary['worst_over_bound']['position']:.3f}\n"
                         "  main contributors: " + ", ".join(f"{c['parameter']} ({100 * c['position_share']:.0f} %)"
                                                           for c in summary["contributors"][:5]) + "\n")
        if args.json:
            sys.stdout.write(f"wrote {args.json}\n")
    return 0


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="template parameter override")
    p.add_argument("--configurations", type=int, default=24, help="configurations sampled (default 24)")
    p.add_argument("--seed", type=int, default=0, help="seed of the configuration sample")
    p.add_argument("--json", metavar="OUT", help="write the result as JSON")
    p.add_argument("--quiet", action="store_true", help="print nothing")


def build_parser() -> argparse.ArgumentParser:
    """Argument parser with the solver's commands."""
    parser = argparse.ArgumentParser(
        prog="hyperstat",
        description="Geometric defects of over-constrained mechanisms: stationarity analysis, accuracy, "
        "identification, diagnosis (lengths in mm, angles in rad).",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("analyze", help="stationarity analysis: forced / coupled / free defects")
    p.add_argument("source", help="template (.py), model file (.json) or STEP file (.step with its sidecar)")
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="template parameter override")
    p.add_argument("--verify", action="store_true", help="confirm every verdict by nonlinear re-assembly")
    p.add_argument("--exact", action="store_true", help="certify the rank with exact rational arithmetic (sympy)")
    p.add_argument("--json", metavar="OUT", help="write the result as JSON")
    p.add_argument("--configurations", type=int, default=24, help="configurations sampled (default 24)")
    p.add_argument("--seed", type=int, default=0, help="seed of the configuration sample")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_cmd_analyze)
    p = sub.add_parser("check-hypotheses", help="check a designer's geometric hypotheses against the analysis")
    p.add_argument("source", help="template, model file or STEP file")
    p.add_argument("hypotheses", help="hypothesis file (YAML)")
    _common(p)
    p.set_defaults(func=_cmd_check_hypotheses)
    p = sub.add_parser("compare", help="compare the analysis with a paper's tables (reference YAML)")
    p.add_argument("source", help="template, model file or STEP file")
    p.add_argument("reference", help="reference file (YAML)")
    p.add_argument("--verify", action="store_true", help="attach the nonlinear evidence to every difference")
    p.add_argument("--markdown", metavar="OUT.md", help="write the comparison as Markdown")
    _common(p)
    p.set_defaults(func=_cmd_compare)
    p = sub.add_parser("simulate", help="simulate tracker measurements of a virtual machine with random defects")
    p.add_argument("source", help="template, model file or STEP file")
    p.add_argument("--poses", type=int, default=107, help="identification poses (default 107)")
    p.add_argument("--validation", type=int, default=30, help="validation poses (default 30, 0 for none)")
    p.add_argument("--noise", default="0.005 mm + 0.005 mm/m", help="1-sigma tracker noise per axis, 'A mm + B mm/m'")
    p.add_argument("--angle-tolerance", type=float, default=2e-4, help="angular defects drawn within +- (rad)")
    p.add_argument("--length-tolerance", type=float, default=0.05, help="length defects drawn within +- (mm)")
    p.add_argument("--select", choices=["random", "grid", "d-optimal"], default="random",
                   help="how identification poses are chosen")
    p.add_argument("--candidates", type=int, default=1000, help="candidate poses for --select d-optimal")
    p.add_argument("--out", required=True, metavar="DATA.csv", help="identification measurements")
    p.add_argument("--validation-out", metavar="VAL.csv", help="validation measurements (default DATA.validation.csv)")
    p.add_argument("--truth", metavar="TRUTH.json", help="write the true parameters")
    p.add_argument("--effect", action="append", metavar="NAME[:DEFECT]",
                   help="add an unmodelled effect to the simulated machine (repeatable), e.g. thermal, "
                        "violated-constraint:dK13")
    p.add_argument("--metadata", action="store_true",
                   help="record campaign metadata (time, temperature, payload, directions, sessions); implied by --effect")
    _common(p)
    p.set_defaults(func=_cmd_simulate)
    p = sub.add_parser("identify", help="identify the free defects, tracker frame and target from measurements")
    p.add_argument("source", help="template, model file or STEP file")
    p.add_argument("data", help="identification measurements (CSV, see docs/identification.md)")
    p.add_argument("--validation", metavar="VAL.csv", help="validation measurements, never fitted")
    _common(p)
    p.set_defaults(func=_cmd_identify)
    p = sub.add_parser("diagnose", help="diagnose the gap left by the rigid model: where, which effect, how far")
    p.add_argument("source", help="template, model file or STEP file")
    p.add_argument("data", help="identification measurements (CSV with a noise model)")
    p.add_argument("--validation", metavar="VAL.csv", help="validation measurements, never fitted")
    p.add_argument("--effects", help="comma-separated candidate effects (default: all)")
    p.add_argument("--plots", metavar="DIR", help="write the residual plots (PNG) to DIR")
    _common(p)
    p.set_defaults(func=_cmd_diagnose)
    p = sub.add_parser("export-controller", help="identify and write the controller parameter file")
    p.add_argument("source", help="template, model file or STEP file")
    p.add_argument("data", help="identification measurements (CSV)")
    p.add_argument("--validation", metavar="VAL.csv", help="validation measurements, never fitted")
    p.add_argument("--effect", action="append", metavar="NAME[:DEFECT]", help="machine effect to identify and export")
    p.add_argument("--diagnose", action="store_true", help="add the effects the diagnosis selects")
    p.add_argument("--out", required=True, metavar="MACHINE.json", help="controller file")
    _common(p)
    p.set_defaults(func=_cmd_export_controller)
    p = sub.add_parser("export-linuxcnc", help="LinuxCNC genhexkins parameters of a hexapod (HAL setp, INI [KINS])")
    p.add_argument("source", nargs="?", help="hexapod template or model file (nominal geometry)")
    p.add_argument("--controller", metavar="MACHINE.json", help="take the identified geometry from a controller file")
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="template parameter override")
    p.add_argument("--hal", required=True, metavar="OUT.hal", help="HAL file with the setp lines")
    p.add_argument("--ini", metavar="OUT.ini", help="INI fragment with the [KINS] section")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_cmd_export_linuxcnc)
    for name, helptext in (("accuracy", "accuracy coefficients (paper 2) over the workspace, tolerance allocation"),
                           ("montecarlo", "Monte Carlo tolerance analysis through the nonlinear model")):
        p = sub.add_parser(name, help=helptext)
        p.add_argument("source", help="template, model file or STEP file")
        p.add_argument("--range", action="append", metavar="JOINT=LO:HI", help="actuated range for the workspace")
        p.add_argument("--workspace-configurations", dest="configurations_workspace", type=int, default=2000,
                       help="configurations sampled over the workspace (default 2000)")
        p.add_argument("--orientation-accuracy", type=float, metavar="RAD", help="required |dphi|max (rad)")
        p.add_argument("--position-accuracy", type=float, metavar="MM", help="required ||dO_p||max (mm)")
        _common(p)
        if name == "accuracy":
            p.add_argument("--map", metavar="J1,J2", help="map the coefficients over a grid of two actuated joints")
            p.add_argument("--slice", action="append", metavar="J=V[,J=V]", help="one map row per slice")
            p.add_argument("--map-png", default="accuracy_map.png", metavar="OUT.png", help="where the map goes")
            p.add_argument("--fixed", action="append", metavar="CLASS=TOL",
                           help="given tolerance per parameter of a class (fP, fR, gP, gR), e.g. fP=1e-4")
            p.set_defaults(func=_cmd_accuracy)
        else:
            p.add_argument("--samples", type=int, default=10000, help="Monte Carlo samples (default 10000)")
            p.add_argument("--distribution", choices=["uniform", "normal"], default="uniform")
            p.add_argument("--angle-tolerance", type=float, default=1e-3, help="angular defects within +- (rad)")
            p.add_argument("--length-tolerance", type=float, default=0.01, help="length defects within +- (mm)")
            p.add_argument("--actuation-tolerance-length", type=float, default=0.0, help="prismatic actuators (mm)")
            p.add_argument("--actuation-tolerance-angle", type=float, default=0.0, help="revolute actuators (rad)")
            p.set_defaults(func=_cmd_montecarlo)
    p = sub.add_parser("validate-diagnosis", help="withheld-effect validation suite of the diagnosis")
    p.add_argument("sources", nargs="+", help="templates or model files")
    p.add_argument("--seeds", type=int, default=5, help="seeds per case (default 5)")
    p.add_argument("--cases", help="comma-separated cases, e.g. none,thermal,thermal+backlash (default: all)")
    p.add_argument("--no-pairs", action="store_true", help="leave out the pairs of effects")
    p.add_argument("--markdown", metavar="OUT.md", help="write the confusion matrix and rates as Markdown")
    p.add_argument("--configurations", type=int, default=24, help="configurations of the stationarity sample")
    p.add_argument("--json", metavar="OUT", help="write every case as JSON")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_cmd_validate_diagnosis)
    return parser


class Terminated(BaseException):
    """Raised by the SIGTERM handler so that pending atomic writes clean up their temporary files."""


def _on_sigterm(signum, frame):  # noqa: ARG001 - signal handler signature
    raise Terminated()


def main(argv: list[str] | None = None, parser: argparse.ArgumentParser | None = None) -> int:
    """Run the command line; returns the exit code (2 for a user error, 143 when terminated)."""
    import signal
    import threading

    parser = parser or build_parser()
    args = parser.parse_args(argv)
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        return int(args.func(args) or 0)
    except Terminated:
        sys.stderr.write("hyperstat: terminated; no output was left half-written\n")
        return 143
    except HyperstatError as exc:
        sys.stderr.write(f"hyperstat: error: {exc}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write("hyperstat: interrupted\n")
        return 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
