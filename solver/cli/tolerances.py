"""Commands of the tolerance stage: ``accuracy``, ``montecarlo``.

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


def _accuracy_inputs(args: argparse.Namespace, progress):
    from hyperstat.solver.tolerances.accuracy import sample_workspace
    from hyperstat.solver.tolerances.workspace import workspace_of

    progress.next("stationarity analysis")
    mech, provenance, kin, result = analysis_of(args)
    ranges = _ranges(args.range)
    actuated = {mech.joints[i].name for i in mech.actuated}
    unknown = [j for j in ranges if j not in actuated]
    if unknown:
        raise HyperstatError(f"--range: '{unknown[0]}' is not an actuated joint of '{mech.name}' "
                             f"({', '.join(sorted(actuated))}).")
    if args.configurations_workspace < 1:
        raise HyperstatError(f"--workspace-configurations must be at least 1, got {args.configurations_workspace}.")
    ws = workspace_of(mech, ranges)
    progress.next("workspace sampling")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        q = sample_workspace(mech, args.configurations_workspace, seed=args.seed, kinematics=kin, workspace=ws)
    if len(q) == 0:
        raise HyperstatError(f"no configuration of '{mech.name}' assembles in the workspace ({ws.source}).")
    args.workspace_used = ws
    over = result.overconstraint > 0
    return mech, provenance, kin, (result if over else None), q, over


def _workspace_doc(mech, ws) -> dict:
    return {"source": ws.source, "declared_ranges": {k: list(v) for k, v in ws.declared.items()},
            "actuated_box": {mech.joints[i].name: [float(ws.lower[i]), float(ws.upper[i])] for i in mech.actuated}}


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
    from hyperstat.solver.tolerances.accuracy import accuracy_maps, allocate, compensable
    from hyperstat.solver.tolerances.worst_case import refine_extremes

    names = ["stationarity analysis", "workspace sampling", "accuracy maps"] + ([] if args.no_refine else
                                                                               ["worst cases"])
    with stages(args, names) as progress:
        mech, provenance, kin, analysis, q, over = _accuracy_inputs(args, progress)
        progress.next("accuracy maps")
        maps = accuracy_maps(mech, q, analysis, kinematics=kin)
        extremes = {}
        if not args.no_refine:
            progress.next("worst cases")
            extremes = refine_extremes(mech, maps, analysis, kinematics=kin, workspace=args.workspace_used,
                                       kinds=("max", "min") if args.refine_minima else ("max",))
        # the refined maximum plus its stated tolerance: an upper bound of the coefficient, so the
        # allocated tolerances are conservative when the tolerance estimate holds
        maxima = {name: e.value + (e.tolerance if math.isfinite(e.tolerance) else 0.0)
                  for (name, kind), e in extremes.items() if kind == "max"}
        allocation = allocate(maps, args.orientation_accuracy, args.position_accuracy, _fixed(args.fixed),
                              maxima=maxima)
        comp = compensable(q[: min(len(q), 200)], mech, analysis, kinematics=kin)
    coefficients = maps.summary()
    for name, v in coefficients.items():
        v["sampled_min"], v["sampled_max"] = v["min"], v["max"]
        for kind in ("min", "max"):
            if (name, kind) in extremes:
                v[kind] = extremes[(name, kind)].value
    doc = {"mechanism": mech.name, "source": provenance, "units": {"length": "mm", "angle": "rad"},
           "workspace": _workspace_doc(mech, args.workspace_used),
           "configurations": len(q), "coefficients": coefficients, "coefficient_units": maps.units,
           "extremes": {name: {kind: extremes[(name, kind)].as_dict() for kind in ("max", "min")
                               if (name, kind) in extremes} for name in coefficients},
           "extremes_method": "sampled only (--no-refine)" if args.no_refine else (
               "sampled, then the best samples refined by bounded local optimisation (SLSQP) over the joint "
               "variables with the closures as constraints and the workspace ranges as bounds; the allocation "
               "uses the refined maxima" + ("" if args.refine_minima else "; the minima are sampled only "
                                            "(--refine-minima refines them)")),
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
                         f"({doc['geometric_errors']}); workspace: {args.workspace_used.source}:\n")
        for name, v in doc["coefficients"].items():
            sys.stdout.write(f"  {name:<11} min {v['min']:.9g}  mean {v['mean']:.6g}  max {v['max']:.9g}  "
                             f"[{maps.units[name]}]\n")
            for kind in ("max", "min"):
                e = extremes.get((name, kind))
                if e is not None and e.location != "constant":
                    sys.stdout.write(f"      {kind} {e.value:.9g} (sampled {e.sampled:.6g}, tolerance {e.tolerance:.2g}): "
                                     f"{e.where()}\n")
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
    from hyperstat.solver.tolerances.accuracy import geometric_parameters
    from hyperstat.solver.tolerances.montecarlo import monte_carlo

    if args.samples < 1:
        raise HyperstatError(f"--samples must be at least 1, got {args.samples}.")
    with stages(args, ["stationarity analysis", "workspace sampling", "Monte Carlo"]) as progress:
        mech, provenance, kin, analysis, q, over = _accuracy_inputs(args, progress)
        names, _ = geometric_parameters(mech, analysis)
        units = {p.name: p.unit for p in mech.parameters}
        tol = {n: args.angle_tolerance if units[n] == "rad" else args.length_tolerance for n in names}
        for i in mech.actuated:
            j = mech.joints[i]
            tol[j.name] = args.actuation_tolerance_angle if j.type == "R" else args.actuation_tolerance_length
        progress.next("Monte Carlo")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = monte_carlo(mech, q, tol, args.samples, args.distribution, args.seed, analysis, kin)
    summary = res.summary(args.orientation_accuracy, args.position_accuracy)
    doc = {"mechanism": mech.name, "source": provenance, "units": {"length": "mm", "angle": "rad"},
           "workspace": _workspace_doc(mech, args.workspace_used),
           "geometric_errors": "admissible influential defects only (the forced ones are assembly conditions)"
           if over else "every defect parameter of the model", **summary,
           "worst_samples": _worst_samples(mech, kin, q, res)}
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
        for kind, w in doc["worst_samples"].items():
            at = ", ".join(f"{k}={v:.6g}" for k, v in w["actuated"].items())
            sys.stdout.write(f"  largest {kind} error {w['value']:.4g} {w['unit']} (sample {w['sample']}) at {at} "
                             f"(O_p = {', '.join(f'{v:.4g}' for v in w['position_mm'])} mm)\n")
        if summary["not_assembled"]:
            sys.stdout.write(f"  {summary['not_assembled']} samples did not assemble with their defects (near the "
                             "workspace's singular boundary a defect can leave a leg too short): left out\n")
        if args.json:
            sys.stdout.write(f"wrote {args.json}\n")
    return 0


def _worst_samples(mech, kin, q, res) -> dict:
    """Where the largest orientation and position errors of the Monte Carlo samples occur (sample i uses q[i mod K])."""
    import numpy as np

    out = {}
    ok = np.nonzero(res.converged)[0]
    if not len(ok):
        return out
    for kind, values, unit in (("orientation", res.orientation, "rad"), ("position", res.position, "mm")):
        i = int(ok[np.argmax(values[ok])])
        qi = q[i % len(q)]
        pose = kin.evaluate(qi[None], None, jacobians=False).output_pose[0]
        out[kind] = {"value": float(values[i]), "unit": unit, "sample": i, "configuration_index": i % len(q),
                     "actuated": {mech.joints[j].name: float(qi[j]) for j in mech.actuated},
                     "position_mm": [float(v) for v in pose[:3, 3]],
                     "over_linear_bound": float(values[i] / max((res.orientation_bound if kind == "orientation"
                                                                 else res.position_bound)[i], 1e-300))}
    return out


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Add this stage's sub-commands to the ``hyperstat`` parser."""
    for name, helptext in (("accuracy", "accuracy coefficients (paper 2) over the workspace, tolerance allocation"),
                           ("montecarlo", "Monte Carlo tolerance analysis through the nonlinear model")):
        p = sub.add_parser(name, help=helptext)
        p.add_argument("source", help="template, model file or STEP file")
        p.add_argument("--range", action="append", metavar="JOINT=LO:HI", help="actuated range for the workspace")
        p.add_argument("--workspace-configurations", dest="configurations_workspace", type=int, default=2000,
                       help="configurations sampled over the workspace (default 2000)")
        p.add_argument("--orientation-accuracy", type=float, metavar="RAD", help="required |dphi|max (rad)")
        if name == "accuracy":
            p.add_argument("--no-refine", action="store_true",
                           help="report the sampled extremes only (no local optimisation of the worst cases)")
            p.add_argument("--refine-minima", action="store_true",
                           help="also refine the minima (slower: a largest singular value is not smooth at its "
                                "minima; the allocation uses only the maxima)")
        p.add_argument("--position-accuracy", type=float, metavar="MM", help="required ||dO_p||max (mm)")
        common_options(p)
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
