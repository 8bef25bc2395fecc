"""Export commands: ``export-controller``, ``check-controller``, ``export-linuxcnc``, ``export-linuxcnc-kins``.

Units: lengths in mm, angles in rad.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path

from hyperstat.solver.atomic import write_json
from hyperstat.solver.cli.common import (PLOTTERS, analysis_of, common_options, force_option, gate_calibration, jsonable,
                                         load_source, stages)
from hyperstat.solver.cli.cached import cache_option, cached_selection
from hyperstat.solver.errors import HyperstatError


def _cmd_export_controller(args: argparse.Namespace) -> int:
    from hyperstat.solver.export.controller import (MACHINE_EFFECTS, check_admissible, controller_document,
                                                    write_controller)
    from hyperstat.solver.diagnosis.effects import make_effect
    from hyperstat.solver.calibration.identify import identify
    from hyperstat.solver.calibration.measurements import read_measurements

    with stages(args, ["stationarity analysis", "identification"]) as progress:
        progress.next("stationarity analysis")
        mech, provenance, kin, result = analysis_of(args)
        data = read_measurements(args.data, mech)
        validation = read_measurements(args.validation, mech) if args.validation else None
        names = list(args.effect or [])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            progress.next("identification")
            if args.diagnose:
                from hyperstat.solver.diagnosis.diagnose import diagnose

                # what the diagnosis selects, read from the cache when a report diagnosed the same data
                selected, violated_defect = cached_selection(
                    args, mech, result, [args.data, args.validation],
                    lambda: diagnose(mech, result, data, validation, kinematics=kin))
                names += [n for n in selected if n not in names]
                violated = violated_defect["defect"] if violated_defect else None
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
            res = identify(mech, result, data, validation, effects=tuple(effects), kinematics=kin,
                           exclude_outliers=args.exclude_outliers)
    defects = _closing_defects(mech, kin, result, res, args, data)
    if defects is not None:
        held_out = validation is not None and len(validation) > 0
        _check_closing_geometry(res, mech, defects, validation if held_out else data,
                                "held-out" if held_out else "identification")
    forced = gate_calibration(res, args)
    files = [args.data] + ([args.validation] if args.validation else [])
    from hyperstat.solver.tolerances.classification import classify

    tolerances = classify(mech, result, kin).to_dict()
    doc = controller_document(mech, res, tuple(effects), provenance, tuple(files), tolerances, forced=bool(forced),
                              defects=defects)
    _check_assembles(doc, mech, args.out)
    check_admissible(doc, str(args.out))  # what the version admits: never a file a reader would refuse
    path = write_controller(args.out, doc)
    if not args.quiet:
        v = res.validation or res.identification
        sys.stdout.write(f"{mech.name}: {len(doc['identified'])} identified parameters, effects: "
                         f"{', '.join(e['effect'] for e in doc['effects']) or 'none'}; "
                         f"{'validation' if res.validation else 'identification'} RMS {1000 * v['rms']:.1f} µm"
                         f"{_noise_words(res)}; fit quality {res.fit_quality}"
                         f"{' (written with --force)' if forced else ''}\n"
                         f"wrote {path} (sha256 {doc['sha256'][:16]}...)\n")
    return 0


def _noise_words(res) -> str:
    """`` (N x the stated noise)`` for the worst held-out (else fitted) target of a calibration, or nothing."""
    ratios = res.noise_ratios or {}
    part = ratios.get("validation") or (ratios.get("identification") if ratios.get("reference") == "stated noise"
                                        else None)
    values = [v for v in (part or {}).values() if v is not None]
    if not values:
        return ""
    what = "the stated noise" if ratios.get("reference") == "stated noise" else "the fit's residual scale"
    return f" ({max(values):.2f} x {what}{' at worst' if len(values) > 1 else ''})"


def _region_words(region: dict, ranges) -> str:
    """The region the calibration poses covered, joint by joint, against the joint ranges."""
    parts = []
    for name, unit, lo, hi, (rlo, rhi) in zip(region["joints"], region["units"], region["low"], region["high"], ranges):
        share = (hi - lo) / (rhi - rlo) if rhi > rlo else 1.0
        parts.append(f"joint {name} [{lo:.4g}, {hi:.4g}] {unit} ({100 * share:.0f} % of its range)")
    return ", ".join(parts)


def _closing_defects(mech, kin, result, res, args, data):
    """The identified defects, moved onto a geometry whose loops close when they do not (else None).

    The identification is linear in the admissible defects (paper 1, section 3): where the conditions
    that keep an over-constrained mechanism mobile are not linear (a Bennett linkage's ratio, a
    spherical four-bar's common point), the identified geometry misses its loops at second order and
    a controller could not assemble it.  The machine that was measured moved, so its geometry is on the
    nonlinear set: the defects are moved there by the change that moves the predicted targets of the
    fitted poses ``data`` the least (:func:`hyperstat.solver.calibration.virtual.onto_closure` in the metric
    of :func:`~hyperstat.solver.calibration.virtual.prediction_metric`), of the order of their square, and
    the change is said on stderr.
    """
    import numpy as np

    from hyperstat.solver.calibration.virtual import onto_closure, prediction_metric
    from hyperstat.solver.errors import AnalysisError

    xi = res.model.defects(res.theta)
    try:
        moved = onto_closure(kin, xi, result.configurations, metric=lambda: prediction_metric(
            res.model, res.theta, data, q_start=res.configurations if res.configurations is not None and
            len(res.configurations) == len(data) else None))
    except AnalysisError:
        return None  # the export's own check says that the geometry does not assemble
    if moved is xi or not np.any(moved != xi):
        return None
    scale = kin.length_scale
    change = np.abs(moved - xi) / np.array([1.0 if p.unit == "mm" else 1.0 / scale for p in mech.parameters])
    k = int(np.argmax(change))
    if not args.quiet:
        p = mech.parameters[k]
        sys.stderr.write(f"hyperstat: note: {args.out}: the identified defects do not close the loops of '{mech.name}' "
                         f"beyond first order; moved onto a geometry that does, by the change that moves its predictions "
                         f"the least (largest {p.name} by {abs(moved[k] - xi[k]):.3g} {p.unit}).\n")
    return moved


#: the written (closing) geometry may predict the held-out poses at most this many times worse than the identified
#: model, whose statistics the file records (the held-out note of ``identify`` uses the same ratio)
CLOSING_WORSE = 1.5


def _registered_rms(held, world) -> float:
    """RMS (mm) of the residuals of the base-frame predictions ``world`` (K, 3) of ``held``'s poses, the tracker frame
    registered on them (Kabsch): what no placement of the tracker explains."""
    import numpy as np

    from hyperstat.solver.calibration.identify import kabsch

    rot, shift = kabsch(held.position, world)
    registered = held.position @ rot.T + shift - world
    return float(np.sqrt(np.mean(np.sum(registered ** 2, axis=1))))


def _check_closing_geometry(res, mech, defects, held, poses: str) -> None:
    """Add a finding to ``res`` when the geometry the file will carry predicts worse than the identified one.

    :func:`_closing_defects` moves the identified defects onto a geometry whose loops close; the file records the
    identified model's held-out statistics, but a controller runs the moved geometry.  Its predictions at the
    held-out poses (the identification poses without a validation set), with the fitted targets and effects and
    the tracker frame registered on them, must be within :data:`CLOSING_WORSE` of the identified model's, or the
    export is refused (the corpus' Bricard line: 0.013 mm identified, 0.13 mm moved).  A move that only displaces
    the whole workspace rigidly (the revolute Delta's least-norm move: 0.034 mm with the fitted tracker, 0.0156 mm
    registered, as the identified model; its move weighed by the measurements displaces nothing) is a note: the
    tool frame moves against the identified base frame by that much, which a workpiece referenced with the machine
    itself does not see.
    """
    import copy

    import numpy as np

    from hyperstat.solver.calibration.identify import error_stats

    model = res.model
    shift = np.asarray(defects, dtype=float) - model.defects(res.theta)
    moved = copy.copy(model)  # the same model, its defects shifted onto the closing geometry
    moved.defects = lambda theta: model.defects(theta) + shift
    ours = model.predict(res.theta, held)
    theirs = moved.predict(res.theta, held)
    fitted_id = error_stats(ours.position - held.position)["rms"]
    fitted_moved = error_stats(theirs.position - held.position)["rms"]
    rigid_id, rigid_moved = _registered_rms(held, ours.world), _registered_rms(held, theirs.world)
    if not theirs.converged.all() or not rigid_moved <= CLOSING_WORSE * rigid_id:
        what = (f"the identified defects do not close the loops of '{mech.name}', and the nearest geometry that does "
                f"(the one the file would carry) predicts the {poses} poses to {rigid_moved:.4g} mm RMS against "
                f"{rigid_id:.4g} mm with the identified model (the tracker frame registered on each)")
        res.findings.append({"code": "closing-geometry-worse", "refuses": True, "message": what[0].upper() + what[1:]
                             + ": a controller running it would be that far off.", "reason": what})
    elif not fitted_moved <= CLOSING_WORSE * fitted_id:
        offset = float(np.max(np.linalg.norm(theirs.world - ours.world, axis=1)))
        res.findings.append({"code": "closing-geometry-moved", "refuses": False, "reason": None, "message": (
            f"the geometry the file carries (the identified defects moved onto loops that close) predicts the {poses} "
            f"poses as well as the identified model once the tracker frame is placed again ({rigid_moved:.4g} "
            f"against {rigid_id:.4g} mm RMS), but it moves the tool frame against the identified base frame by up to "
            f"{offset:.3g} mm ({fitted_moved:.4g} mm RMS with the fitted tracker frame): reference the workpiece "
            f"with the machine itself, not with the tracker")})


def _check_assembles(doc: dict, mech, out: str) -> None:
    """Refuse a controller file whose identified geometry does not assemble at enough test configurations.

    The test vectors are the identified model assembled across the workspace; where its loops do not
    close, there is no vector, and a file with too few could not be checked by its reader.  Said here
    in the mechanism's terms (the file's own check would only count the vectors).
    """
    from hyperstat.solver.export.controller import ADMISSIBLE, VERSION

    rules = ADMISSIBLE[VERSION]["test_vectors"]
    got = len(doc["test_vectors"]["vectors"])
    if got >= rules["at_least"]:
        return
    scale = {p.name: (1.0 if p.unit == "mm" else 1000.0) for p in mech.parameters}  # rad as mm over 1 m
    name = max(doc["defects"], key=lambda n: abs(doc["defects"][n]) * scale[n], default=None)
    largest = "" if name is None else (f" (the largest, {name} = {doc['defects'][name]:.3g} "
                                       f"{'mm' if scale[name] == 1.0 else 'rad'})")
    raise HyperstatError(f"{out}: not written: the identified geometry of '{mech.name}' assembles at only {got} of the "
                         f"{rules['count']} test configurations (version {VERSION} needs {rules['at_least']}): its loops "
                         f"do not close with the identified defects{largest}; check the estimates and their standard "
                         "deviations (hyperstat identify).")


def _geometry(args: argparse.Namespace, what: str):
    """(mechanism, defects, controller document or None) from SOURCE or --controller."""
    import numpy as np

    from hyperstat.solver.export.controller import ControllerModel, check_reachable_ranges, read_controller

    if bool(args.controller) == bool(args.source):
        raise HyperstatError(f"{what} needs a SOURCE (nominal geometry) or --controller MACHINE.json, not both.")
    if args.controller:
        doc = read_controller(args.controller)
        model = ControllerModel(doc, str(args.controller))
        try:  # the ranges become the controller's joint limits
            check_reachable_ranges(model)
        except HyperstatError as exc:
            raise HyperstatError(f"{args.controller}: {str(exc).removeprefix('controller file: ')}") from None
        return model.mechanism, model.xi, doc
    mech, _ = load_source(args.source, args.param)
    return mech, np.zeros(len(mech.parameters)), None


def _cmd_export_linuxcnc(args: argparse.Namespace) -> int:
    from hyperstat.solver.atomic import write_text
    from hyperstat.solver.export import genserkins, linuxcnc
    from hyperstat.solver.export.linuxcnc import noise_floor

    if not args.controller and not args.source:
        raise HyperstatError("export-linuxcnc needs a hexapod or 6R robot SOURCE, or --controller MACHINE.json.")
    mech, xi, doc = _geometry(args, "export-linuxcnc")
    if args.max_error is not None:
        if not (args.max_error > 0 and math.isfinite(args.max_error)):
            raise HyperstatError(f"--max-error must be a positive length in mm, got {args.max_error}.")
        threshold, origin = args.max_error, "--max-error"
    elif doc is not None and noise_floor(doc):
        threshold, origin = noise_floor(doc), "the calibration's noise floor"
    else:
        threshold, origin = 1e-6, "the default for a nominal geometry"
    if mech.closures:  # a parallel mechanism: genhexkins (6-UPS only)
        params = linuxcnc.genhexkins_parameters(mech, xi)
        linuxcnc.refuse_unrepresentable(params, threshold, mech.name, origin)
        hal_text, ini_text = linuxcnc.hal_lines(params), linuxcnc.ini_section()
        summary = (f"genhexkins geometry of '{mech.name}': largest strut-length difference to the model "
                   f"{params['max_strut_difference_mm']:.3g} mm over {params['poses_checked']} poses")
    else:  # a serial robot: genserkins (6R only)
        params = genserkins.genserkins_parameters(mech, xi)
        genserkins.refuse_unrepresentable(params, threshold, mech.name, origin)
        hal_text, ini_text = "loadrt genserkins\n" + genserkins.hal_lines(params), genserkins.ini_section()
        summary = (f"genserkins (modified DH) geometry of '{mech.name}': largest pose difference to the model "
                   f"{params['max_position_difference_mm']:.3g} mm, {params['max_rotation_difference_rad']:.3g} rad "
                   f"over {params['configurations_checked']} configurations")
    hal = write_text(args.hal, hal_text)
    ini = write_text(args.ini, ini_text) if args.ini else None
    if not args.quiet:
        sys.stdout.write(f"{summary} (threshold {threshold:.3g} mm, {origin})\n"
                         f"wrote {hal}\n" + (f"wrote {ini}\n" if ini else ""))
    return 0


def _cmd_check_controller(args: argparse.Namespace) -> int:
    from hyperstat.solver.export.controller import check_controller

    reference = load_source(args.source, args.param)[0] if args.source else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = check_controller(args.file, reference)
    if args.json:
        write_json(args.json, res)
    if res["forced"] and not args.quiet:
        sys.stderr.write(f"hyperstat: warning: {args.file} was written with --force although "
                         f"{'; and '.join(res['reasons'])}.\n")
    if not args.quiet:
        sys.stdout.write(f"{args.file}: format, version, schema and SHA-256 valid, consistent with itself "
                         f"('{res['mechanism']}', sha256 {res['sha256'][:16]}..., fit quality {res['fit_quality']}"
                         f"{', written with --force' if res['forced'] else ''}); {res['count']} test vectors "
                         f"re-evaluated with the reference model ({res['corners']} at corners of the ranges): forward "
                         f"{res['forward_mm']:.2g} mm / {res['forward_rad']:.2g} rad, inverse {res['inverse_mm']:.2g} mm"
                         f" / {res['inverse_rad']:.2g} rad"
                         + (f" ({res['inverse_other_branch']} on another inverse solution with the same pose)"
                            if res["inverse_other_branch"] else "")
                         + (f"; {res['effect_vectors']} effect vectors (tool point with the machine effects): "
                            f"{res['effects_mm']:.2g} mm" if res.get("effect_vectors") else "")
                         + (f"; model and joint ranges equal to {args.source}'s" if args.source else
                            "; model not compared with a reference (--source)") + "\n")
        outside = (f"; {res['outside_region']} of the {res['count']} test vectors lie beyond it, where the identified "
                   f"model is extrapolated" if res["outside_region"] else "")
        sys.stdout.write(f"{args.file}: the calibration poses cover {_region_words(res['region'], res['ranges'])}"
                         f"{outside}\n")
        for note in res["notes"]:  # what the export passed on without refusing: the integrator reads it here
            sys.stdout.write(f"{args.file}: note of the calibration ({note['code']}): {note['message']}\n")
    return 0


def _cmd_export_linuxcnc_kins(args: argparse.Namespace) -> int:
    from hyperstat.solver.atomic import all_or_nothing, write_text
    from hyperstat.solver.export.linuxcnc_kins import (component_name, inverse_conditioning, kins_component,
                                                       sample_world, world_layout)
    from hyperstat.solver.export.linuxcnc_sim import write_sim

    mech, xi, doc = _geometry(args, "export-linuxcnc-kins")
    layout = world_layout(mech)
    home = mech.home.copy()
    if args.home:
        from hyperstat.solver.kinematics.closure import Kinematics

        for spec in args.home:
            joint, sep, value = spec.partition("=")
            j = mech.joint_index.get(joint.strip())
            if not sep or j is None or j not in mech.actuated:
                raise HyperstatError(f"--home: '{spec}' is not ACTUATED_JOINT=VALUE (actuated joints: "
                                     f"{', '.join(mech.joints[i].name for i in mech.actuated)}).")
            try:
                home[j] = float(value)
            except ValueError:
                raise HyperstatError(f"--home: '{value}' in '{spec}' is not a number (rad or mm).") from None
        res = Kinematics(mech).solve(home[mech.actuated][None, :], xi)
        if not res.converged[0]:
            raise HyperstatError(f"--home: the mechanism does not assemble at {', '.join(args.home)}.")
        home = res.q[0]
    cond = inverse_conditioning(mech, xi, home)
    if cond < 1e-8:
        raise HyperstatError(f"the home configuration of '{mech.name}' is singular for the world coordinates "
                             f"{' '.join(layout['coordinates'])} (conditioning {cond:.1g}): the kinematics could not "
                             f"leave it; choose another with --home ACTUATED_JOINT=VALUE (rad or mm).")
    name = args.name or component_name(mech.name, doc["sha256"] if doc else "")
    if not name.isidentifier():
        raise HyperstatError(f"--name: '{name}' is not a valid component name (letters, digits, underscores).")
    out = Path(args.out)
    with all_or_nothing():  # the component and the machine files, together or none
        comp = write_text(out / f"{name}.comp", kins_component(mech, xi, name=name, home=home))
        ini = write_sim(out, mech, name, layout, sample_world(mech, xi, layout), home=home)
    if not args.quiet:
        sys.stdout.write(f"LinuxCNC kinematics of '{mech.name}' ({'identified' if doc else 'nominal'} geometry), "
                         f"world coordinates {' '.join(layout['coordinates'])}, {len(mech.actuated)} joints\n"
                         f"wrote {comp}\nwrote {ini} and {ini.with_suffix('.hal')}\n"
                         f"build: halcompile --install {comp}   run: linuxcnc {ini}\n")
        if doc:  # the joint limits are the ranges; the calibration was measured over less
            covered = _region_words(doc["calibration"]["region"], mech.ranges[mech.actuated].tolist())
            sys.stdout.write(f"the calibration's poses cover {covered}; "
                             f"beyond, the identified model is extrapolated (check-move --controller says where a "
                             f"move leaves that region)\n")
    return 0


def _world_point(text: str, option: str, letters: str) -> list:
    """World coordinates from ``"X100 Y20 Z-1100 B10 C45"`` or ``"100 20 -1100 10 45"`` (mm, degrees)."""
    words = text.replace(",", " ").split()
    values = []
    for k, word in enumerate(words):
        if word[:1].upper() in letters and word[:1].isalpha():
            if k >= len(letters) or word[0].upper() != letters[k]:
                raise HyperstatError(f"{option}: '{text}' must give {' '.join(letters)} in this order (mm, degrees).")
            word = word[1:]
        try:
            values.append(float(word))
        except ValueError:
            raise HyperstatError(f"{option}: '{word}' in '{text}' is not a number (mm or degrees).") from None
    if len(values) != len(letters) or not all(math.isfinite(v) for v in values):
        raise HyperstatError(f"{option}: '{text}' must hold {len(letters)} finite numbers, {' '.join(letters)} "
                             f"(mm, degrees).")
    return values


def _cmd_check_move(args: argparse.Namespace) -> int:
    from hyperstat.solver.export.linuxcnc_kins import world_layout
    from hyperstat.solver.export.straight_moves import STEP_DEG, STEP_MM, check_straight_move

    mech, xi, doc = _geometry(args, "check-move")
    layout = world_layout(mech)
    letters = layout["coordinates"]
    start = _world_point(args.start, "--from", letters)
    end = _world_point(args.end, "--to", letters)
    region = doc["calibration"]["region"] if doc else None
    r = check_straight_move(mech, xi, start, end, layout=layout, region=region)
    units = {mech.joints[i].name: ("rad" if mech.joints[i].type == "R" else "mm") for i in mech.actuated}
    if args.json:
        write_json(args.json, jsonable({"mechanism": mech.name, "coordinates": letters, "from": start, "to": end,
                                        "units": {"world": "mm, degrees", "joints": units}, **r}))
    if args.quiet:
        return 0 if r["inside"] else 1
    cal = r.get("calibrated")
    if cal is not None:
        if cal["inside"]:
            sys.stdout.write(f"the straight move stays inside the region the calibration's poses covered "
                             f"({_region_words(region, mech.ranges[mech.actuated].tolist())})\n")
        else:
            where = " ".join(f"{a}{v:.6g}" for a, v in zip(letters, cal["world"]))
            unit = units[cal["joint"]]
            sys.stdout.write(f"the straight move leaves the region the calibration's poses covered at "
                             f"{100 * cal['fraction']:.3g} % of its length (near {where}): joint '{cal['joint']}' "
                             f"reaches {cal['value']:.6g} {unit}, the poses covered [{cal['low']:.6g}, "
                             f"{cal['high']:.6g}] {unit}; beyond, the identified model is extrapolated (its accuracy "
                             f"there was not measured)\n")
    if r["inside"]:
        sys.stdout.write(f"the straight move stays inside every joint range of '{mech.name}' ({r['samples']} points "
                         f"checked, every {STEP_MM:g} mm and {STEP_DEG:g} degree)\n")
        return 0
    where = " ".join(f"{a}{v:.6g}" for a, v in zip(letters, r["world"]))
    worst = ", ".join(f"joint {n} {v:.4g} {units[n]}" for n, v in r["excess"].items() if v > 0)
    sys.stdout.write(f"the straight move leaves the range of joint '{r['joint']}' at {100 * r['fraction']:.3g} % of its "
                     f"length (near {where}): the joint would reach {r['value']:.6g} {units[r['joint']]}, its range "
                     f"ends at {r['limit']:.6g} {units[r['joint']]}; beyond the ranges along the line: {worst}.  LinuxCNC starts such a "
                     f"move and stops it there (the generated component refuses poses outside the joint ranges): "
                     f"split it through a point inside the workspace.\n")
    return 1


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Add this stage's sub-commands to the ``hyperstat`` parser."""
    p = sub.add_parser("export-controller", help="identify and write the controller parameter file")
    p.add_argument("source", help="template, model file or STEP file")
    p.add_argument("data", help="identification measurements (CSV)")
    p.add_argument("--validation", metavar="VAL.csv", help="validation measurements, never fitted")
    p.add_argument("--effect", action="append", metavar="NAME[:DEFECT]", help="machine effect to identify and export")
    p.add_argument("--diagnose", action="store_true", help="add the effects the diagnosis selects")
    p.add_argument("--out", required=True, metavar="MACHINE.json", help="controller file")
    force_option(p)
    common_options(p)
    cache_option(p)
    p.set_defaults(func=_cmd_export_controller)
    p = sub.add_parser("export-linuxcnc",
                       help="LinuxCNC genhexkins (hexapod) or genserkins (6R robot) parameters (HAL setp, INI [KINS])")
    p.add_argument("source", nargs="?", help="hexapod or 6R robot template or model file (nominal geometry)")
    p.add_argument("--controller", metavar="MACHINE.json", help="take the identified geometry from a controller file")
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="template parameter override")
    p.add_argument("--hal", required=True, metavar="OUT.hal", help="HAL file with the setp lines")
    p.add_argument("--ini", metavar="OUT.ini", help="INI fragment with the [KINS] section")
    p.add_argument("--max-error", type=float, metavar="MM",
                   help="refuse when genhexkins' strut lengths (genserkins' poses) differ from the model by more "
                        "(mm; default: the calibration's noise floor for --controller)")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_cmd_export_linuxcnc)
    p = sub.add_parser("check-controller", help="check a controller file: format, version, schema, hash, test vectors")
    p.add_argument("file", help="controller file (MACHINE.json)")
    p.add_argument("--source", metavar="SOURCE",
                   help="trusted template or model file: the file's model and joint ranges must equal its")
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="template parameter override")
    p.add_argument("--json", metavar="OUT.json", help="write the check's result (largest errors, mm / rad)")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_cmd_check_controller)
    p = sub.add_parser("export-linuxcnc-kins",
                       help="LinuxCNC kinematics component (C, halcompile) and simulation configuration (INI, HAL)")
    p.add_argument("source", nargs="?", help="template or model file (nominal geometry)")
    p.add_argument("--controller", metavar="MACHINE.json", help="take the identified geometry from a controller file")
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="template parameter override")
    p.add_argument("--out", required=True, metavar="DIR", help="directory for NAME.comp, machine.ini, machine.hal")
    p.add_argument("--name", help="component name (default: hs_<mechanism>[_<hash>]_kins)")
    p.add_argument("--home", action="append", metavar="JOINT=VALUE",
                   help="home of an actuated joint (rad or mm; default the model's home), e.g. away from a singularity")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_cmd_export_linuxcnc_kins, known_outputs=("machine.ini", "machine.hal"))
    p = sub.add_parser("check-move",
                       help="check that a straight G1 move in LinuxCNC's world coordinates keeps every joint in range "
                            "(exit 1 when it does not), and with --controller say where it leaves the region the "
                            "calibration's poses covered")
    p.add_argument("source", nargs="?", help="template or model file (nominal geometry)")
    p.add_argument("--controller", metavar="MACHINE.json", help="take the identified geometry from a controller file")
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="template parameter override")
    p.add_argument("--from", dest="start", required=True, metavar="WORLD",
                   help="start of the move in world coordinates, e.g. 'X596.8 Y18.3 Z-1143 B-22.6 C161.5' (mm, deg)")
    p.add_argument("--to", dest="end", required=True, metavar="WORLD", help="end of the move (mm, degrees)")
    p.add_argument("--json", metavar="OUT.json", help="write the result (where a joint leaves its range, by how much)")
    p.add_argument("--quiet", action="store_true", help="print nothing (the exit code says it: 0 inside, 1 not)")
    p.set_defaults(func=_cmd_check_move)
