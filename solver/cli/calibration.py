"""Commands of the calibration stage: ``simulate``, ``identify``, ``import-robot``, ``export-urdf``, ``export-dh``.

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
from hyperstat.solver.errors import HyperstatError


def _cmd_simulate(args: argparse.Namespace) -> int:
    from hyperstat.solver.calibration.identify import MeasurementModel
    from hyperstat.solver.calibration.measurements import parse_noise, write_measurements
    from hyperstat.solver.calibration.poses import select_poses
    from hyperstat.solver.calibration.virtual import VirtualMachine

    if args.poses < 1 or args.validation < 0:
        raise HyperstatError(f"--poses must be at least 1 and --validation at least 0 (got {args.poses}, "
                             f"{args.validation}).")
    noise = parse_noise(args.noise, "--noise")
    mech, provenance, kin, result = analysis_of(args)
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
        from hyperstat.solver.calibration.virtual import workshop_metadata

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

    from hyperstat.solver.diagnosis.effects import EFFECT_NAMES, make_effect

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
            from hyperstat.solver.diagnosis.validation_suite import VIOLATION_MAGNITUDE

            if not defect:
                raise HyperstatError("--effect violated-constraint needs the forced defect, e.g. "
                                     "'violated-constraint:dK13'.")
            options.update(only=[defect], magnitude_rad=VIOLATION_MAGNITUDE, magnitude_mm=VIOLATION_MAGNITUDE)
        effects.append(make_effect(name, mech, result, None, **options).draw_truth(rng))
    return tuple(effects)


def _read_data(args: argparse.Namespace, mech):
    """Identification and validation sets of ``args``, through ``--joint-map`` when given."""
    from hyperstat.solver.calibration.measurements import read_measurements

    joint_map = None
    if getattr(args, "joint_map", None):
        joint_map = _load_joint_map(args.joint_map, mech)
    data = read_measurements(args.data, mech, joint_map=joint_map)
    validation = read_measurements(args.validation, mech, joint_map=joint_map) if args.validation else None
    return data, validation


def _load_joint_map(path: str, mech):
    from hyperstat.solver.errors import DataError
    from hyperstat.solver.kinematics.joint_map import joint_map_from_dict
    from hyperstat.solver.strict_load import load_yaml

    p = Path(path)
    if not p.is_file():
        raise DataError(f"{p}: no such joint-map file.")
    try:
        doc = load_yaml(p.read_text(encoding="utf-8"), str(p))
    except UnicodeDecodeError:
        raise DataError(f"{p}: not UTF-8 text.") from None
    if isinstance(doc, dict) and "joint_map" in doc:
        doc = doc["joint_map"]
    joints = [mech.joints[i] for i in mech.actuated]
    return joint_map_from_dict(doc, {j.name: j.type for j in joints}, str(p))


def _run_identification(args: argparse.Namespace, extra_stages: list[str] | None = None):
    from hyperstat.solver.calibration.identify import identify

    with stages(args, ["stationarity analysis", "identification"] + list(extra_stages or [])) as progress:
        progress.next("stationarity analysis")
        mech, provenance, kin, result = analysis_of(args)
        data, validation = _read_data(args, mech)
        progress.next("identification")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = identify(mech, result, data, validation, kinematics=kin,
                           select_size=getattr(args, "select_size", "none"),
                           exclude_outliers=bool(getattr(args, "exclude_outliers", False)))
        for name in extra_stages or []:
            progress.next(name)
    return mech, provenance, res


def _cmd_identify(args: argparse.Namespace) -> int:
    from hyperstat.solver.atomic import write_text
    from hyperstat.solver.export.text import format_identification

    mech, provenance, res = _run_identification(args)
    wrote = []
    if args.json:
        doc = {"mechanism": mech.name, "source": provenance, "data": str(args.data),
               "validation_data": None if args.validation is None else str(args.validation), **res.to_dict()}
        wrote.append(write_json(args.json, jsonable(doc)))
    if args.residuals:
        wrote.append(write_text(args.residuals, res.residuals_csv()))
    if not args.quiet:
        sys.stdout.write(format_identification(res))
        for w in wrote:
            sys.stdout.write(f"wrote {w}\n")
    return 0


def _cmd_import_robot(args: argparse.Namespace) -> int:
    from hyperstat.solver.kinematics.modelfile import save_model
    from hyperstat.solver.kinematics.robot_import import import_robot

    mech = import_robot(args.robot, tip=args.tip)
    path = save_model(mech, args.out)
    unknown = mech.metadata.get("masses_unknown")
    if unknown and not args.quiet:
        bodies = "; ".join(f"joint {u['joint']}" + (f" (link{'s' if len(u['links']) > 1 else ''} "
                                                     f"{', '.join(u['links'])} without <inertial>)" if u["links"] else
                                                     " (no link with <inertial>)") for u in unknown)
        sys.stderr.write(f"hyperstat: warning: {args.robot}: the body moved by {bodies} has no declared mass, so its "
                         f"mass is unknown: no link masses are recorded (gravity effects cannot be sized; never "
                         f"computed as if a body were massless); add the <inertial> to use them.\n")
    if not args.quiet:
        c = mech.count()
        jm = "with" if "joint_map" in mech.metadata else "without"
        sys.stdout.write(f"{mech.name}: {c['R']} revolute, {c['P']} prismatic joints, {c['parameters']} defect "
                         f"parameters, {jm} a joint map\nwrote {path}\n")
    return 0


def _calibrated(args: argparse.Namespace):
    mech, provenance, res = _run_identification(args, ["export"])
    args.forced_reasons = gate_calibration(res, args)
    return mech, res, res.model.defects(res.theta)


def _comment(args: argparse.Namespace, res) -> str:
    v = res.validation
    val = f", validation RMS {v['rms']:.4g} mm over {v['n']} points" if v else ""
    forced = getattr(args, "forced_reasons", [])
    why = (f"; WRITTEN WITH --force ALTHOUGH " + "; and ".join(forced)) if forced else ""
    excluded = "; outliers excluded on request: " + ", ".join(
        f"{e['pose']}{'/' + e['target'] if e['target'] else ''}" for e in res.excluded) if res.excluded else ""
    return (f"calibrated by hyperstat from {args.data}: identification RMS {res.identification['rms']:.4g} mm, "
            f"sigma {res.sigma:.3g}, fit quality {res.fit_quality}{val}{excluded}{why}; units: metres and radians "
            f"(URDF)")


def _cmd_export_urdf(args: argparse.Namespace) -> int:
    from hyperstat.solver.atomic import write_text
    from hyperstat.solver.export.robot_export import joint_map_text, urdf_text

    mech, res, xi = _calibrated(args)
    out = Path(args.out)
    side = out.with_name(out.name.removesuffix(out.suffix) + ".joint_map.yaml")
    map_text = joint_map_text(mech, out.name)
    wrote = [write_text(out, urdf_text(mech, xi, comment=_comment(args, res),
                                       joint_map_file=side.name if map_text else None))]
    if map_text:  # the controller's convention beside the URDF: both written, or neither
        wrote.append(write_text(side, map_text))
    if not args.quiet:
        for w in res.warnings:
            sys.stdout.write(f"warning: {w}\n")
        for w in wrote:
            sys.stdout.write(f"wrote {w}\n")
    return 0


def _cmd_export_dh(args: argparse.Namespace) -> int:
    from hyperstat.solver.atomic import write_text
    from hyperstat.solver.export.robot_export import DH_WARN_MM, corrected_dh, dh_text

    mech, res, xi = _calibrated(args)
    table = corrected_dh(mech, xi)
    text = dh_text(mech, table, comment=_comment(args, res).replace("metres and radians (URDF)", "mm and deg"))
    path = write_text(args.out, text)
    if not args.quiet:
        for w in res.warnings:
            sys.stdout.write(f"warning: {w}\n")
        dev = table["max_deviation_mm"]
        if dev > DH_WARN_MM:
            sys.stdout.write(f"warning: the corrected DH table differs from the calibrated model by up to {dev:.3g} mm "
                             f"(DH cannot hold every calibrated axis tilt, e.g. out of the plane of a parallel pair); "
                             f"the URDF export holds it exactly.\n")
        sys.stdout.write(f"DH table reproduces the calibrated model to {dev:.3g} mm (max over "
                         f"{table['samples']} configurations)\nwrote {path}\n")
    return 0


def _identify_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--validation", metavar="VAL.csv", help="validation measurements, never fitted")
    p.add_argument("--joint-map", metavar="MAP.yaml",
                   help="controller joint convention (overrides the model's own): sign, offset, ratio, couplings")
    p.add_argument("--select-size", choices=["none", "cv", "bic", "auto"], default="auto",
                   help="choose the number of geometry parameters: by cross-validation (cv), by the information "
                        "criterion (bic), either when data are few (auto, default: fewer than 5 equations per base "
                        "parameter; bic with a noise model), or never (none)")


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Add this stage's sub-commands to the ``hyperstat`` parser."""
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
    common_options(p)
    p.set_defaults(func=_cmd_simulate)
    p = sub.add_parser("identify", help="identify the free defects, tracker frame and target from measurements")
    p.add_argument("source", help="template, model file or STEP file")
    p.add_argument("data", help="identification measurements (CSV, see docs/identification.md)")
    _identify_options(p)
    p.add_argument("--residuals", metavar="RES.csv", help="write per-observation residuals with outlier flags (CSV)")
    p.add_argument("--exclude-outliers", action="store_true",
                   help="refit without the observations the outlier test flags (named by pose and target), one at a "
                        "time; they are never removed otherwise")
    common_options(p)
    p.set_defaults(func=_cmd_identify)
    p = sub.add_parser("import-robot", help="turn a DH / modified-DH table (YAML, CSV) or a URDF into a model file")
    p.add_argument("robot", help="DH table (.yaml, .yml, .csv) or URDF (.urdf)")
    p.add_argument("--out", required=True, metavar="MODEL.skel.json", help="model file to write")
    p.add_argument("--tip", help="URDF: the tip link of the chain (default: the only deepest leaf)")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_cmd_import_robot)
    for name, func, what, suffix in (("export-urdf", _cmd_export_urdf, "URDF (metres)", "ROBOT.urdf"),
                                     ("export-dh", _cmd_export_dh, "corrected DH table (mm, deg)", "ROBOT.dh.yaml")):
        p = sub.add_parser(name, help=f"identify, then write the calibrated serial robot as a {what}")
        p.add_argument("source", help="model file of a serial robot (hyperstat import-robot)")
        p.add_argument("data", help="identification measurements (CSV)")
        p.add_argument("--out", required=True, metavar=suffix, help="file to write")
        force_option(p)
        _identify_options(p)
        common_options(p)
        p.set_defaults(func=func)
