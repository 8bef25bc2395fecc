"""Commands of the tolerance stage: ``accuracy``, ``montecarlo``.

Units: lengths in mm, angles in rad.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from functools import partial
from pathlib import Path

from hyperstat.solver.atomic import write_json
from hyperstat.solver.cli.cached import (cache_option, cached_document, cached_sample, cached_sample_started,
                                         cached_values)
from hyperstat.solver.cli.common import (PLOTTERS, analysis_of, common_options, jsonable, load_source, loaded_source,
                                         stages)
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


def _accuracy_inputs(args: argparse.Namespace, progress, spill: bool = False):
    """The model, its analysis and the workspace sample; ``spill``: the sample in a temporary file, read a block at
    a time (:class:`~hyperstat.solver.tolerances.spilled.SpilledArray`: ``accuracy``'s memory does not grow with
    the count, issue 39), drawn in a forked child: returned is then what waits for it (the caller computes meanwhile)."""
    from hyperstat.solver.tolerances.workspace import workspace_of

    progress.next("stationarity analysis")
    mech, provenance, kin, result = analysis_of(args)
    ranges = _ranges(args.range)
    actuated = {mech.joints[i].name for i in mech.actuated}
    unknown = [j for j in ranges if j not in actuated]
    if unknown:
        raise HyperstatError(f"--range: '{unknown[0]}' is not an actuated joint of '{mech.name}' "
                             f"({', '.join(sorted(actuated))}).")
    if getattr(args, "workspace_loss", None) is not None:  # refused before any work
        from hyperstat.solver.tolerances.declaration import check_workspace_loss

        check_workspace_loss(args.workspace_loss, "--workspace-loss")
    if args.configurations_workspace < 1:
        raise HyperstatError(f"--workspace-configurations must be at least 1, got {args.configurations_workspace}.")
    ws = workspace_of(mech, ranges)
    progress.next("workspace sampling")
    n, seed = args.configurations_workspace, args.seed
    if spill:  # sampled in a forked child, written to the sample's temporary file, while the caller goes on
        started = cached_sample_started(args, mech, n, seed, ws, lambda: _sampling_started(mech, n, seed, kin, ws))
    else:
        q = cached_sample(args, mech, n, seed, ws, lambda: _sampled(mech, n, seed, kin, ws))
        started = lambda: q  # noqa: E731

    def sampled():
        out = started()
        if len(out) == 0:
            raise HyperstatError(f"no configuration of '{mech.name}' assembles in the workspace ({ws.source}).")
        return out
    args.workspace_used = ws
    over = result.overconstraint > 0
    args._stationarity = result  # the tolerance classes need it whatever the over-constraint
    return mech, provenance, kin, (result if over else None), (sampled if spill else sampled()), over


def _sampled(mech, n: int, seed: int, kin, ws, spill=False):
    """The workspace sample (``n`` draws, ``seed``), warnings of the corrector silenced; ``spill``: written into that
    :class:`~hyperstat.solver.tolerances.spilled.SpilledArray`."""
    from hyperstat.solver.tolerances.accuracy import sample_workspace

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sample_workspace(mech, n, seed=seed, kinematics=kin, workspace=ws, spill=spill)


def _sample_into(mech, n: int, seed: int, kin, ws, out) -> int:
    """The workspace sample written into ``out`` (a :class:`~hyperstat.solver.tolerances.spilled.SpilledArray`);
    its number of rows (what a forked child hands back: the rows are in the file)."""
    return len(_sampled(mech, n, seed, kin, ws, spill=out))


def _sampling_started(mech, n: int, seed: int, kin, ws):
    """The sampling started in a forked child (the tolerance classes are computed meanwhile: issue 39); returns what
    waits for the sample.  Without a child (``HYPERSTAT_NO_FORK``, a failed child) it is computed in-process."""
    from hyperstat.solver.forked import Forked
    from hyperstat.solver.tolerances.spilled import SpilledArray

    out = SpilledArray.empty((kin.n_q,))
    job = Forked(_sample_into, mech, n, seed, kin, ws, out)

    def wait():
        out.resize(job.result())
        return out
    return wait


def _classes(args: argparse.Namespace, mech, kin):
    """The tolerance classes, and the directions of those with a value from accuracy, (n_xi, n) or None."""
    import numpy as np

    from hyperstat.solver.tolerances.classification import classify

    cl = classify(mech, args._stationarity, kin)
    with_workspace_loss(cl, getattr(args, "workspace_loss", None))
    influential = [t for t in cl.items if t.cls in ("accuracy-critical", "compensable")]  # as assign_values
    return cl, (np.stack([t.direction for t in influential], axis=1) if influential else None)


def with_workspace_loss(cl, value: float | None) -> None:
    """``--workspace-loss`` over the declaration's ``workspace_loss`` (a fraction, 0.001 = 0.1 %), in place."""
    import dataclasses

    from hyperstat.solver.tolerances.declaration import check_workspace_loss

    if value is None:
        return
    loss = check_workspace_loss(value, "--workspace-loss")
    declared = tuple(dict.fromkeys(cl.declaration.declared + ("workspace_loss",)))
    cl.declaration = dataclasses.replace(cl.declaration, workspace_loss=loss, declared=declared)


def workspace_loss_option(p: argparse.ArgumentParser) -> None:
    """The ``--workspace-loss`` option of report, accuracy and montecarlo."""
    p.add_argument("--workspace-loss", type=float, metavar="FRACTION",
                   help="share of each actuator's range (or of the task's extent at a dead centre) the compensation of "
                        "every compensable defect together may cost, e.g. 0.001 = 0.1 %% (default: the template's "
                        "TOLERANCING workspace_loss, else 0.001)")


def _tolerances(args: argparse.Namespace, mech, kin, q, assembly: bool = True, cl=None, task_maps_at=None):
    """The tolerances of the classification module with their values (spec from the options or the template).

    ``cl`` and ``task_maps_at``: the classes and their task rows at ``q`` when already computed (by
    :func:`_classes` and the accuracy maps, from the same Jacobians).
    """
    from hyperstat.solver.tolerances.values import ASSEMBLY_SAMPLE, assign_values

    result = args._stationarity
    cl = _classes(args, mech, kin)[0] if cl is None else cl
    # the values with calibration in a forked child beside the assembly conditions' and the bounds' searches (the
    # same values, on the second core: issue 39, as ``report`` does); not part of the cache's key
    cached_values(args, cl, mech, kin, q, partial(assign_values, background=True),
                  position_accuracy=args.position_accuracy,
                  orientation_accuracy=args.orientation_accuracy, assembly=assembly,
                  assembly_configurations=result.configurations[:ASSEMBLY_SAMPLE],
                  workspace=args.workspace_used if args.range else None, calibrate=True,
                  task_maps_at=task_maps_at)
    return cl


def _tolerance_lines(tol: dict) -> str:
    from hyperstat.solver.export.text import format_tolerances

    return format_tolerances(tol)


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


def _options_key(args: argparse.Namespace, skip: tuple = ("json", "quiet", "no_cache", "func", "command")) -> dict:
    """The options of a command that its answer depends on (for the cache's key), in a fixed order."""
    return {k: v for k, v in sorted(vars(args).items()) if k not in skip and not k.startswith("_")}


def _cmd_accuracy(args: argparse.Namespace) -> int:
    if args.map:  # the map needs the analysis in this process: computed, not read
        doc = _accuracy_document(args)
    else:
        mech, _ = loaded_source(args)
        doc = cached_document(args, "accuracy", mech, _options_key(args), lambda: _accuracy_document(args))
    if args.json:
        write_json(args.json, jsonable(doc))
    if not args.quiet:
        _print_accuracy(doc)
        if args.json:
            sys.stdout.write(f"wrote {args.json}\n")
    return 0


def _print_accuracy(doc: dict) -> None:
    """The text summary of ``hyperstat accuracy`` (from its JSON document)."""
    sys.stdout.write(f"Accuracy coefficients of '{doc['mechanism']}' over {doc['configurations']} configurations "
                     f"({doc['geometric_errors']}); workspace: {doc['workspace']['source']}:\n")
    for name, v in doc["coefficients"].items():
        sys.stdout.write(f"  {name:<11} min {v['min']:.9g}  mean {v['mean']:.6g}  max {v['max']:.9g}  "
                         f"[{doc['coefficient_units'][name]}]\n")
        for kind in ("max", "min"):
            e = doc["extremes"].get(name, {}).get(kind)
            if e is not None and e["location"] != "constant":
                sys.stdout.write(f"      {kind} {e['value']:.9g} (sampled {e['sampled']:.6g}, tolerance "
                                 f"{e['tolerance']:.2g}): {e['where']}\n")
    allocation = doc["allocation"]
    for cls, c in allocation["classes"].items():
        if c["tolerance"] is not None:
            sys.stdout.write(f"  class {cls}: tolerance {c['tolerance']:.6g} {c['unit']} per parameter"
                             f"{' (given)' if c['given'] else ''}\n")
    for key in ("orientation_bound", "position_bound"):
        if allocation.get(key) is not None:
            sys.stdout.write(f"  {key.replace('_', ' ')}: {allocation[key]:.6g}\n")
    sys.stdout.write("\n" + _tolerance_lines(doc["tolerances"]))


def _refined(mech, maps, analysis, kin, workspace, kinds: tuple) -> list:
    """:func:`~hyperstat.solver.tolerances.worst_case.refine_extremes` as ``[name, kind, fields]`` (what a forked
    child hands back: every field of each :class:`~hyperstat.solver.tolerances.worst_case.Extreme`)."""
    import dataclasses

    from hyperstat.solver.tolerances.worst_case import refine_extremes

    found = refine_extremes(mech, maps, analysis, kinematics=kin, workspace=workspace, kinds=kinds)
    return [[name, kind, {f.name: getattr(e, f.name) for f in dataclasses.fields(e)}]
            for (name, kind), e in found.items()]


def _accuracy_document(args: argparse.Namespace) -> dict:
    """The JSON document of ``hyperstat accuracy`` (and the map, with ``--map``)."""
    from hyperstat.solver.tolerances.accuracy import accuracy_maps, allocate
    from hyperstat.solver.tolerances.task_summary import value_columns
    import numpy as np

    from hyperstat.solver.tolerances.worst_case import Extreme, prepare_searches

    names = ["stationarity analysis", "workspace sampling", "accuracy maps"] + ([] if args.no_refine else
                                                                               ["worst cases"]) + ["tolerances"]
    with stages(args, names) as progress:
        mech, provenance, kin, analysis, sampled, over = _accuracy_inputs(args, progress, spill=True)
        # the tolerance classes while the sample is drawn (a forked child)
        classes, directions = _classes(args, mech, kin)
        q = sampled()
        progress.next("accuracy maps")
        # one set of Jacobians per configuration: the coefficients and the task rows of the tolerance values
        # reduced block by block (issue 39): what is kept per configuration is the coefficients, not the
        # parameters' column norms nor the task rows
        columns = None if directions is None else value_columns(
            [t for t in classes.items if t.cls in ("accuracy-critical", "compensable")])
        maps = accuracy_maps(mech, q, analysis, kinematics=kin, task=None if directions is None else
                             classes.declaration.task, task_directions=directions, per_configuration=False,
                             task_columns=columns)
        extremes, refining = {}, None
        if not args.no_refine:
            from hyperstat.solver.forked import Forked

            progress.next("worst cases")
            # the structured candidates (corners, edges, faces, dead centres) of the searches here and in the values
            # stage, their nominal twist maps and the sample's conditioning median, computed once before the child is
            # forked (it inherits them; every search of these functions varies all the actuators): not once in each
            # process
            prepare_searches(kin, args.workspace_used, q)
            # searched in a forked child beside the tolerance values (which do not read them): the same extremes, on
            # the second core (issue 39)
            refining = Forked(_refined, mech, maps, analysis, kin, args.workspace_used,
                              ("max", "min") if args.refine_minima else ("max",))
        coefficients = maps.summary()
        progress.next("tolerances")
        try:
            tolerances = _tolerances(args, mech, kin, q, cl=classes, task_maps_at=maps.task_rows).to_dict()
        except BaseException:
            if refining is not None:
                refining.cancel()
            raise
        if refining is not None:
            extremes = {(name, kind): Extreme(**dict(fields, q=np.asarray(fields["q"], dtype=float)))
                        for name, kind, fields in refining.result()}
        # the refined maximum plus its stated tolerance: an upper bound of the coefficient, so the
        # allocated tolerances are conservative when the tolerance estimate holds
        maxima = {name: e.value + (e.tolerance if math.isfinite(e.tolerance) else 0.0)
                  for (name, kind), e in extremes.items() if kind == "max"}
        allocation = allocate(maps, args.orientation_accuracy, args.position_accuracy, _fixed(args.fixed),
                              maxima=maxima)
        maps.coefficients = {}  # the per-configuration coefficients are not read past here
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
           "per_parameter": maps.per_parameter_summary(),
           "tolerances": tolerances,
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
    return doc


def _cmd_montecarlo(args: argparse.Namespace) -> int:
    if args.samples < 1:
        raise HyperstatError(f"--samples must be at least 1, got {args.samples}.")
    mech, _ = loaded_source(args)
    doc = cached_document(args, "montecarlo", mech, _options_key(args), lambda: _montecarlo_document(args))
    if args.json:
        write_json(args.json, jsonable(doc))
    if not args.quiet:
        sys.stdout.write(format_montecarlo(doc))
        for kind, w in doc.get("worst_samples", {}).items():
            at = ", ".join(f"{k}={v:.6g}" for k, v in w["actuated"].items())
            sys.stdout.write(f"  largest {kind} error {w['value']:.4g} {w['unit']} (sample {w['sample']}) at {at} "
                             f"(O_p = {', '.join(f'{v:.4g}' for v in w['position_mm'])} mm)\n")
        if doc.get("not_assembled"):
            sys.stdout.write(f"  {doc['not_assembled']} samples did not assemble with their defects (near the "
                             "workspace's singular boundary a defect can leave a leg too short): left out\n")
        if args.json:
            sys.stdout.write(f"wrote {args.json}\n")
    return 0


def _montecarlo_document(args: argparse.Namespace) -> dict:
    """The JSON document of ``hyperstat montecarlo``."""
    from hyperstat.solver.tolerances.accuracy import geometric_parameters
    from hyperstat.solver.tolerances.montecarlo import monte_carlo
    from hyperstat.solver.tolerances.values import monte_carlo_at_values

    uniform = args.angle_tolerance is not None or args.length_tolerance is not None
    with stages(args, ["stationarity analysis", "workspace sampling", "tolerances", "Monte Carlo"]) as progress:
        mech, provenance, kin, analysis, q, over = _accuracy_inputs(args, progress)
        progress.next("tolerances")
        cl = _tolerances(args, mech, kin, q, assembly=False)
        progress.next("Monte Carlo")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if uniform:  # the same tolerance on every geometric parameter (the options), as before
                names, _ = geometric_parameters(mech, analysis)
                units = {p.name: p.unit for p in mech.parameters}
                tol = {n: (args.angle_tolerance or 0.0) if units[n] == "rad" else (args.length_tolerance or 0.0)
                       for n in names}
                for i in mech.actuated:
                    j = mech.joints[i]
                    tol[j.name] = args.actuation_tolerance_angle if j.type == "R" else args.actuation_tolerance_length
                res = monte_carlo(mech, q, tol, args.samples, args.distribution, args.seed, analysis, kin,
                                  task=cl.declaration.task)
                spec_o = args.orientation_accuracy if args.orientation_accuracy is not None else \
                    cl.declaration.orientation_rad
                spec_p = args.position_accuracy if args.position_accuracy is not None else cl.declaration.position_mm
                summary = res.summary(spec_o, spec_p)
                summary["spec"] = {"position_mm": spec_p, "orientation_rad": spec_o}
                summary["task"] = list(cl.declaration.task)
                drawn = "every geometric parameter at the given tolerance"
            else:
                summary = monte_carlo_at_values(cl, mech, kin, q, args.samples, args.seed, args.distribution,
                                                args.position_accuracy, args.orientation_accuracy)
                if not summary:  # nothing to draw: say why, and what draws something
                    raise HyperstatError(_nothing_to_draw(mech, cl))
                drawn = summary.pop("drawn", "every accuracy tolerance at its drawing value")
    doc = {"mechanism": mech.name, "source": provenance, "units": {"length": "mm", "angle": "rad"},
           "workspace": _workspace_doc(mech, args.workspace_used),
           "drawn": drawn, "tolerance_counts": cl.counts(), **summary}
    campaign = [w for w in cl.warnings if w.startswith("CALIBRATION CAMPAIGN: ")]
    if campaign and doc.get("calibrated"):  # its calibrated machines are calibrated as declared
        doc["warnings"] = campaign
    if uniform:
        doc["worst_samples"] = _worst_samples(mech, kin, q, res)
    return doc


def _nothing_to_draw(mech, cl) -> str:
    """Why ``montecarlo`` has no tolerance to draw at its value, in one sentence (a user error, exit 2)."""
    counts = cl.counts()
    zero = sum(1 for t in cl.items if t.cls in ("accuracy-critical", "compensable") and not t.value)
    why = f"{counts.get('accuracy-critical', 0)} accuracy-critical and {counts.get('compensable', 0)} compensable"
    if zero:
        why += f", {zero} of them at a value of 0"
        if any("uses up the spec" in w for w in cl.warnings):
            why += " because the calibration noise alone uses up the spec"
    return (f"no Monte Carlo for '{mech.name}': no tolerance has a value to draw ({why}; assembly conditions are "
            "not drawn); give --angle-tolerance and --length-tolerance to draw every geometric parameter instead.")


def format_montecarlo(doc: dict) -> str:
    """Text summary of a Monte Carlo run: errors, out of spec, worst case against the bound, both rankings.

    >>> doc = {"samples": 10, "distribution": "uniform", "drawn": "x", "task": ["x"],
    ...        "spec": {"position_mm": 0.02, "orientation_rad": None},
    ...        "position_mm": {"mean": 0.01, "p99": 0.02, "max": 0.03}, "orientation_rad": {"mean": 0, "p99": 0, "max": 0},
    ...        "out_of_spec_position_percent": 10.0, "worst_over_bound": {"position": 0.5, "orientation": 0.0},
    ...        "contributors": [{"parameter": "T1", "label": "T1 da2", "position_share": 0.9, "orientation_share": 0.0},
    ...                         {"parameter": "T2", "label": "T2 dK4", "position_share": 0.1, "orientation_share": 1.0}]}
    >>> print(format_montecarlo(doc).splitlines()[3])
      out of spec (position > 0.02 mm): 10.00 % of the samples
    """
    spec = doc.get("spec", {})
    o, p = doc["orientation_rad"], doc["position_mm"]
    lines = [f"Monte Carlo, {doc['samples']} samples ({doc['distribution']}), {doc['drawn']}; task "
             f"{', '.join(doc.get('task', []))}:",
             f"  position error:    mean {p['mean']:.4g}  p99 {p['p99']:.4g}  max {p['max']:.4g} mm",
             f"  orientation error: mean {o['mean']:.4g}  p99 {o['p99']:.4g}  max {o['max']:.4g} rad"]
    for key, spec_key, unit, label in (("out_of_spec_position_percent", "position_mm", "mm", "position"),
                                       ("out_of_spec_orientation_percent", "orientation_rad", "rad", "orientation")):
        if doc.get(key) is not None:
            lines.append(f"  out of spec ({label} > {spec[spec_key]:g} {unit}): {doc[key]:.2f} % of the samples")
        elif spec.get(spec_key) is None:
            lines.append(f"  out of spec ({label}): no {label} spec")
    cal = doc.get("calibrated")
    if cal:
        parts = [f"{k.split('_')[3]} {v:.2f} %" for k, v in cal.items() if k.startswith("out_of_spec") and v is not None]
        if parts:
            lines.append("  after calibration (compensable tolerances cancelled, calibration noise added): out of spec "
                         + ", ".join(parts))
    lines += [f"  warning: {w}" for w in doc.get("warnings", [])]
    w = doc["worst_over_bound"]
    lines.append(f"  worst sample / its linear bound (paper 2, eq. 18): position {w['position']:.3f}, orientation "
                 f"{w['orientation']:.3f}")
    for key, words in (("attainable_linear_worst_case", "attainable linear worst case (the worst sign pattern of the "
                                                         "tolerances at their values)"),
                       ("linear_worst_case", "triangle bound (every tolerance at its extreme, every effect adding "
                                             "up: no machine need reach it)")):
        lw = doc.get(key)
        if lw:
            lines.append(f"  {words}: " + ", ".join(f"{k.split('_')[0]} {v:.4g} {k.split('_')[1]}"
                                                   for k, v in lw.items() if k != "meaning" and v is not None))
    contributors = doc.get("contributors", [])
    for share, label in (("position_share", "position"), ("orientation_share", "orientation")):
        ranked = sorted(contributors, key=lambda c: -c[share])[:5]
        ranked = [c for c in ranked if c[share] > 0]
        lines.append(f"  main contributors to the {label} variance: " + (", ".join(
            f"{c.get('label', c['parameter'])} ({100 * c[share]:.0f} %)" for c in ranked) or "none"))
    return "\n".join(lines) + "\n"


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
        p.add_argument("--orientation-accuracy", type=float, metavar="RAD",
                       help="spec: required |dphi|max (rad), overrides the template's")
        p.add_argument("--position-accuracy", type=float, metavar="MM",
                       help="spec: required ||dO_p||max (mm), overrides the template's")
        workspace_loss_option(p)
        if name == "accuracy":
            p.add_argument("--no-refine", action="store_true",
                           help="report the sampled extremes only (no local optimisation of the worst cases)")
            p.add_argument("--refine-minima", action="store_true",
                           help="also refine the minima (slower: a largest singular value is not smooth at its "
                                "minima; the allocation uses only the maxima)")
        common_options(p)
        cache_option(p)
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
            p.add_argument("--angle-tolerance", type=float, help="draw every angular defect within +- this (rad) "
                           "instead of the tolerances' values")
            p.add_argument("--length-tolerance", type=float, help="draw every length defect within +- this (mm) "
                           "instead of the tolerances' values")
            p.add_argument("--actuation-tolerance-length", type=float, default=0.0, help="prismatic actuators (mm)")
            p.add_argument("--actuation-tolerance-angle", type=float, default=0.0, help="revolute actuators (rad)")
            p.set_defaults(func=_cmd_montecarlo)
