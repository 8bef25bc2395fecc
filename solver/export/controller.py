"""The controller parameter file: what a numerical-controller integrator loads, and a reference model.

Units: lengths in mm, angles in rad (stated in the file's ``units`` field).

The file (format ``hyperstat-controller``, version 3, JSON Schema
``solver/export/schema/controller.schema.json``, documented in ``docs/controller-format.md``)
holds the nominal model (the model file, embedded), the complete defect vector of the
identified machine, the tool-point offset, the identified parameters with their
standard deviations, the machine effects selected by the diagnosis (measurement
effects such as tracker scale or drift describe the tracker, not the machine, and are
left out), identification and validation statistics, the calibration's record (the gate's verdict
and the numbers it was made from, the joint-space region the poses covered, the reasons of
a ``--force``), provenance (the template and its parameters, and the SHA-256 of every data
file), test vectors (configurations across the workspace and at the corners of the actuated
ranges with their poses, read both ways, and the controller's joint values where the model
has a joint map, so that a port of the model can be checked without hyperstat) and a SHA-256
over the content: the canonical JSON (sorted keys, no spaces) of every field but ``sha256``.

:func:`read_controller` refuses a file whose format, version, schema or hash does not
match, or whose content contradicts itself (:mod:`hyperstat.solver.export.controller_checks`).  :class:`ControllerModel` is the reference forward and inverse geometric model
built from the file alone; :func:`check_controller` reads a file and re-evaluates its test
vectors with it.
"""

from __future__ import annotations

import hashlib
import json
import os
from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from hyperstat.solver.atomic import dumps_json, write_text
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.frames import so3_log
from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.kinematics.modelfile import _schema_message, mechanism_from_dict, mechanism_to_dict
from hyperstat.solver.strict_load import load_json

__all__ = ["FORMAT", "VERSION", "controller_document", "write_controller", "read_controller", "content_hash",
           "file_sha256", "ControllerModel", "MACHINE_EFFECTS", "build_test_vectors", "build_effect_vectors",
           "check_test_vectors", "check_controller", "TEST_VECTOR_TOLERANCE", "target_offsets", "target_points",
           "ADMISSIBLE", "check_admissible", "test_vector_draws", "check_reachable_ranges", "compare_model"]

FORMAT = "hyperstat-controller"
#: version 2 added the test vectors (version 1 had none); version 3 the calibration record (fit quality per target
#: against the stated noise, equations, findings, region covered, reasons of a --force), the number of unknowns, the
#: corners of the actuated ranges among the test vectors and the controller's joint values in them
VERSION = 3
#: why an older version is not read (a file of that version cannot be checked for what this one checks)
OLDER = {1: "version 1 has no test vectors",
         2: "version 2 carries no calibration record, no corners and no controller joint values, so its statistics, "
            "its joint map and its test vectors cannot be checked against one another"}
MACHINE_EFFECTS = ("compliance", "violated-constraint", "thermal", "screw-pitch", "screw-periodic", "backlash",
                   "backlash-gravity", "angle-scale", "angle-harmonic-1", "angle-harmonic-2")
#: metadata columns the effect vectors carry, per pose (temperature degC, payload kg, approach direction +-1)
EFFECT_VECTOR_COUNT = 12


@lru_cache(maxsize=1)
def controller_schema() -> dict:
    """The JSON Schema of the controller file."""
    return json.loads(resources.files("hyperstat.solver.export").joinpath("schema/controller.schema.json").read_text(encoding="utf-8"))


def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 (hex) of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def content_hash(doc: dict) -> str:
    """SHA-256 of the canonical JSON of ``doc`` without its ``sha256`` field."""
    body = {k: v for k, v in doc.items() if k != "sha256"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


#: What a file of each version may hold, fixed by the version and never read from the file: a file cannot
#: vouch for itself.  ``test_vector_tolerance``: the agreement a port must reach on the test vectors (mm for
#: lengths, rad for angles); the file repeats it for its reader and is refused if it says otherwise.
#: ``test_vectors``: how many configurations are drawn (``count``) and how many must have assembled
#: (``at_least``).  ``defect_rad`` / ``defect_mm``: the largest identified defect (a calibration corrects
#: small errors of a known geometry; beyond, the model is another machine or the fit went astray).  The
#: values are wide: poorly determined combinations of defects reach several mm in a sound calibration
#: (10.4 mm on the identified hexapod of the tests, whose validation RMS is 32 um).
#: ``offset_mm``: the largest tool point or target offset from the output frame.
#: ``corners``: the corners of the actuated ranges are test vectors too (every actuated joint at either end; for
#: more than :data:`CORNER_JOINTS` actuated joints, each joint at either end with the others mid-range).
ADMISSIBLE = {3: {"test_vector_tolerance": {"length_mm": 1e-9, "angle_rad": 1e-9},
                  "test_vectors": {"count": 24, "at_least": 12, "corners": True},
                  "defect_rad": 0.1, "defect_mm": 100.0, "offset_mm": 2000.0}}
CORNER_JOINTS = 6
TEST_VECTOR_COUNT = ADMISSIBLE[VERSION]["test_vectors"]["count"]
TEST_VECTOR_TOLERANCE = dict(ADMISSIBLE[VERSION]["test_vector_tolerance"])


def build_test_vectors(mechanism, xi: np.ndarray, target: np.ndarray, count: int = TEST_VECTOR_COUNT,
                 seed: int = 0, targets: dict | None = None) -> dict:
    """Configurations across the workspace and at the corners of the ranges with their poses, for checking a port.

    The actuated values are drawn uniformly in the middle 80 % of every actuated joint's
    range (seeded, so the same file comes out of the same inputs), followed by the corners of
    the actuated ranges (:func:`test_vector_configurations`), all assembled together on the
    identified geometry ``xi`` (rigid: the machine effects need per-pose data and are left
    out); every one that assembles is kept, in that order.  Each vector reads both ways:
    forward, ``actuated`` gives ``position`` / ``rotation`` (output frame in the base frame)
    and ``tool_point``; inverse, the pose gives ``actuated`` (the draws; a corner may be
    singular).  With a joint map in the model (an imported robot), ``controller`` holds the
    controller's joint values that the map turns into ``actuated`` (the map's units).

    Returns
    -------
    dict
        ``tolerance`` (``length_mm``, ``angle_rad``), ``seed`` and ``vectors``: per vector
        ``actuated`` (rad / mm, model order), ``joints`` (every joint, the assembled
        configuration), ``position`` (mm), ``rotation`` (3 x 3, rows) and ``tool_point`` (mm);
        with ``targets`` (name -> offset in the output frame, mm), also ``targets``: name ->
        the target's position in the base frame (mm); with a joint map, ``controller``.
    """
    kin = Kinematics(mechanism)
    act = mechanism.actuated
    qa, _ = test_vector_configurations(mechanism, seed, count)
    res = kin.solve(qa, xi)
    ok = res.converged
    q = res.q[ok]
    pose = kin.evaluate(q, xi, jacobians=False).output_pose
    tool = pose[:, :3, 3] + pose[:, :3, :3] @ np.asarray(target, dtype=float)
    vectors = [{"actuated": q[k, act].tolist(), "joints": q[k].tolist(), "position": pose[k, :3, 3].tolist(),
                "rotation": pose[k, :3, :3].tolist(), "tool_point": tool[k].tolist()} for k in range(len(q))]
    if targets:
        points = target_points(pose, targets)
        for k, v in enumerate(vectors):
            v["targets"] = {name: p[k].tolist() for name, p in points.items()}
    controller = controller_values(mechanism, q[:, act])
    if controller is not None:
        for k, v in enumerate(vectors):
            v["controller"] = controller[k].tolist()
    return {"tolerance": dict(TEST_VECTOR_TOLERANCE), "seed": seed, "vectors": vectors}


def _square_joint_map(mechanism):
    """The model's joint map when it is square (controller values recoverable), else None."""
    from hyperstat.solver.calibration.measurements import mechanism_joint_map

    jm = mechanism_joint_map(mechanism)
    return jm if jm is not None and jm.matrix.shape[0] == jm.matrix.shape[1] else None


def _controller_factors(jm) -> np.ndarray:
    """Per controller joint, the factor turning its declared unit into rad / mm."""
    from hyperstat.solver.kinematics.joint_map import ANGLE_UNITS, LENGTH_UNITS

    return np.array([ANGLE_UNITS[jm.units["angle"]] if k == "R" else LENGTH_UNITS[jm.units["length"]]
                     for k in jm.kinds])


def controller_values(mechanism, q_actuated: np.ndarray) -> np.ndarray | None:
    """The controller's joint values (the map's declared units) giving model actuated values ``q_actuated``
    through the model's joint map; None without a (square) joint map."""
    jm = _square_joint_map(mechanism)
    if jm is None:
        return None
    return jm.inverse(np.atleast_2d(q_actuated)) / _controller_factors(jm)


def test_vector_configurations(mechanism, seed: int, count: int = TEST_VECTOR_COUNT) -> tuple[np.ndarray, np.ndarray]:
    """The actuated values test vectors are made at, in order: the seeded draws (:func:`test_vector_draws`), then
    the corners of the actuated ranges; and a flag per row, True for a corner.

    With up to :data:`CORNER_JOINTS` actuated joints the corners are every combination of range ends
    (``2^n``, the first joint's end varying slowest); with more, each joint at either end with the others at
    mid-range (``2n``).
    """
    import itertools

    act = mechanism.actuated
    lo, hi = mechanism.ranges[act].T
    draws = test_vector_draws(mechanism, seed, count)
    n = len(act)
    if n <= CORNER_JOINTS:
        corners = np.array([[hi[k] if e else lo[k] for k, e in enumerate(ends)]
                            for ends in itertools.product((0, 1), repeat=n)], dtype=float)
    else:
        mid = 0.5 * (lo + hi)
        corners = np.repeat(mid[None, :], 2 * n, axis=0)
        for k in range(n):
            corners[2 * k, k], corners[2 * k + 1, k] = lo[k], hi[k]
    flags = np.r_[np.zeros(len(draws), dtype=bool), np.ones(len(corners), dtype=bool)]
    return np.vstack([draws, corners]), flags


def test_vector_draws(mechanism, seed: int, count: int = TEST_VECTOR_COUNT) -> np.ndarray:
    """Actuated values (count, n_actuated) the test vectors are drawn at: uniform in the middle 80 % of every
    actuated joint's range, seeded; a checker draws them again, so the vectors follow the file's ranges."""
    act = mechanism.actuated
    lo, hi = mechanism.ranges[act].T
    rng = np.random.default_rng(seed)
    return lo + (hi - lo) * (0.1 + 0.8 * rng.random((count, len(act))))


def build_effect_vectors(doc: dict, count: int = EFFECT_VECTOR_COUNT, seed: int = 1) -> list:
    """Test vectors of the machine effects: actuated values with per-pose metadata and the tool point.

    The actuated values are those of the first ``count`` rigid test vectors; the metadata
    a machine effect reads is drawn (seeded): ``temperature`` uniform in 15-30 degC,
    ``payload`` in {0, 5, 10} kg, ``dir<joint>`` = +-1 per actuated joint.  The tool point
    (base frame, mm) is the reference model's (:class:`ControllerModel`) with every
    effect of ``doc`` applied: compliance (gravity loads of the declared link masses and
    the payload), backlash (approach side), gravity-side backlash, angle scale and
    harmonics, thermal expansion, screw errors, a violated constraint.  A port that
    applies the effects must reproduce it within the file's tolerance.
    """
    model = ControllerModel(doc)
    vec = doc["test_vectors"]["vectors"][:count]
    qa = np.array([v["actuated"] for v in vec], dtype=float)
    rng = np.random.default_rng(seed)
    meta = {"temperature": np.round(15.0 + 15.0 * rng.random(len(qa)), 3),
            "payload": rng.choice([0.0, 5.0, 10.0], len(qa))}
    for i in model.mechanism.actuated:
        meta[f"dir{model.mechanism.joints[i].name}"] = rng.choice([-1.0, 1.0], len(qa))
    point, _ = model.forward(qa, meta)
    return [{"actuated": qa[k].tolist(), "metadata": {n: float(v[k]) for n, v in meta.items()},
             "tool_point": point[k].tolist()} for k in range(len(qa))]


def check_test_vectors(doc: dict, model: "ControllerModel | None" = None) -> dict:
    """Re-evaluate a file's test vectors with the reference model built from the file.

    Forward: the model at ``actuated`` against ``position``, ``rotation`` and
    ``tool_point``; inverse: the model's inverse of the pose (Newton from home, not from
    the answer) against ``actuated``.  Where a pose has several inverse solutions (the
    two crank angles of a slider-crank), Newton from home may land on another one: it
    then passes if its forward pose is the file's, and is counted apart.

    Returns
    -------
    dict
        ``count``, ``forward_mm``, ``forward_rad``, ``inverse_mm``, ``inverse_rad``
        (largest errors; mm / rad) and ``inverse_other_branch`` (vectors whose inverse
        landed on another solution reproducing the pose).

    Raises
    ------
    DataError
        One sentence naming the first vector out of tolerance.
    """
    model = model or ControllerModel(doc)
    tv = doc["test_vectors"]
    vec = tv["vectors"]
    if not vec:
        raise DataError("controller file: 'test_vectors' holds no vector.")
    corner = _vector_corners(doc, model.mechanism)
    tol = ADMISSIBLE[doc["version"]]["test_vector_tolerance"]  # the version's, never the file's
    tol_mm, tol_rad = tol["length_mm"], tol["angle_rad"]
    qa = np.array([v["actuated"] for v in vec], dtype=float)
    n_act = len(model.mechanism.actuated)
    if qa.shape[1] != n_act:
        raise DataError(f"controller file: test vectors have {qa.shape[1]} actuated values, the model {n_act}.")
    pos = np.array([v["position"] for v in vec], dtype=float)
    rot = np.array([v["rotation"] for v in vec], dtype=float)
    tool = np.array([v["tool_point"] for v in vec], dtype=float)
    point, pose = model.forward(qa, with_effects=False)
    e_pos = np.maximum(np.linalg.norm(pose[:, :3, 3] - pos, axis=1), np.linalg.norm(point - tool, axis=1))
    _check_target_points(doc, model, pose, tol_mm)
    e_rot = np.linalg.norm(so3_log(pose[:, :3, :3] @ np.transpose(rot, (0, 2, 1))), axis=1)
    for name, err, tol, unit in (("forward position", e_pos, tol_mm, "mm"),
                                  ("forward rotation", e_rot, tol_rad, "rad")):
        k = int(np.argmax(err))
        if not err[k] <= tol:
            raise DataError(f"controller file: test vector {k}: the reference model's {name} is {err[k]:.3g} {unit} "
                            f"from the file's (tolerance {tol:g} {unit}).")
    # the inverse is read on the draws (a corner of the ranges may be a singular pose); k below is the file's index
    number = np.flatnonzero(~corner)
    vec = [vec[k] for k in number]
    qa, pos, rot, tool = qa[number], pos[number], rot[number], tool[number]
    wanted = np.tile(np.eye(4), (len(vec), 1, 1))
    wanted[:, :3, :3], wanted[:, :3, 3] = rot, pos
    back = model.inverse(wanted)
    lin = np.array([model.mechanism.joints[i].type == "P" for i in model.mechanism.actuated])
    e_inv = np.abs(back - qa)
    tol_inv = np.where(lin, tol_mm, tol_rad)
    off = np.flatnonzero(~np.all(e_inv <= tol_inv, axis=1))
    branch = 0
    if len(off):
        # a pose reached by more than one set of actuated values (e.g. the two crank angles of a slider-crank):
        # the inverse may land on another branch; it must then reproduce the pose
        p2, pose2 = model.forward(back[off], with_effects=False)
        e2 = np.maximum(np.linalg.norm(pose2[:, :3, 3] - pos[off], axis=1), np.linalg.norm(p2 - tool[off], axis=1))
        r2 = np.linalg.norm(so3_log(pose2[:, :3, :3] @ np.transpose(rot[off], (0, 2, 1))), axis=1)
        for i, k in enumerate(off):
            if e2[i] <= tol_mm and r2[i] <= tol_rad or len(vec) < 2:
                continue
            # Newton from home stalled (a serial 6R arm far from home): start again from the other
            # vectors' actuated values (never from this vector's own), keep the first that reaches the pose
            others = np.delete(np.arange(len(vec)), k)
            tries = model.inverse(np.repeat(wanted[k:k + 1], len(others), axis=0), q_start=qa[others])
            pt, pose_t = model.forward(tries, with_effects=False)
            et = np.maximum(np.linalg.norm(pose_t[:, :3, 3] - pos[k], axis=1), np.linalg.norm(pt - tool[k], axis=1))
            rt = np.linalg.norm(so3_log(pose_t[:, :3, :3] @ rot[k].T), axis=1)
            good = np.flatnonzero((et <= tol_mm) & (rt <= tol_rad))
            if len(good):
                back[k], e2[i], r2[i] = tries[good[0]], et[good[0]], rt[good[0]]
                e_inv[k] = np.abs(back[k] - qa[k])
                if np.all(e_inv[k] <= tol_inv):
                    continue
            if not (e2[i] <= tol_mm and r2[i] <= tol_rad):
                j = int(np.argmax(e_inv[k] / tol_inv))
                unit = "mm" if lin[j] else "rad"
                raise DataError(f"controller file: test vector {number[k]}: the reference inverse model gives actuated "
                                f"value {j} {e_inv[k, j]:.3g} {unit} from the file's (tolerance {tol_inv[j]:g} {unit}), and "
                                f"its pose misses the file's by {e2[i]:.3g} mm.")
        off = np.flatnonzero(~np.all(e_inv <= tol_inv, axis=1))  # after the restarts
        branch = len(off)
    same = np.setdiff1d(np.arange(len(vec)), off)
    e_same = e_inv[same] if len(same) else np.zeros((1, len(lin)))
    e_eff = 0.0
    ev = tv.get("effect_vectors") or []
    if ev:
        qe = np.array([v["actuated"] for v in ev], dtype=float)
        keys = sorted({k for v in ev for k in v["metadata"]})
        missing = [(k, n) for k, v in enumerate(ev) for n in keys if n not in v["metadata"]]
        if missing:
            raise DataError(f"controller file: effect vector {missing[0][0]} has no metadata '{missing[0][1]}'.")
        meta = {n: np.array([v["metadata"][n] for v in ev], dtype=float) for n in keys}
        point_e, _ = model.forward(qe, meta)
        err_e = np.linalg.norm(point_e - np.array([v["tool_point"] for v in ev], dtype=float), axis=1)
        k = int(np.argmax(err_e))
        if not err_e[k] <= tol_mm:
            raise DataError(f"controller file: effect vector {k}: the reference model's tool point with the machine "
                            f"effects ({', '.join(e['effect'] for e in doc['effects'])}) is {err_e[k]:.3g} mm from "
                            f"the file's (tolerance {tol_mm:g} mm).")
        e_eff = float(err_e.max())
    return {"count": len(tv["vectors"]), "corners": int(corner.sum()), "forward_mm": float(e_pos.max()),
            "forward_rad": float(e_rot.max()),
            "effect_vectors": len(ev), "effects_mm": e_eff,
            "inverse_mm": float(e_same[:, lin].max()) if lin.any() else 0.0,
            "inverse_rad": float(e_same[:, ~lin].max()) if (~lin).any() else 0.0,
            "inverse_other_branch": int(branch)}


def controller_document(mechanism, identification, effects: tuple = (), source: dict | None = None,
                        data_files: tuple = (), tolerances: dict | None = None, forced: bool = False,
                        defects: np.ndarray | None = None) -> dict:
    """Controller file content from an identification (and the effects fitted with it).

    Parameters
    ----------
    mechanism : Mechanism
        Nominal model.
    identification : IdentificationResult
        Result of :func:`hyperstat.solver.calibration.identify.identify` (with the effects, if any).
    effects : tuple
        The effect objects of the identification's model (machine effects are exported).
    source : dict, optional
        Provenance of the model (template path and parameters).
    data_files : tuple of path-like
        Measurement files used (their SHA-256 is recorded).
    tolerances : dict, optional
        :meth:`~hyperstat.solver.tolerances.classification.Classification.to_dict` of the model: its
        counts per class and the class and tolerance id of every parameter are recorded (the same
        vocabulary as ``analyze`` and the report).
    forced : bool
        Write a calibration the export gate refuses (:mod:`~hyperstat.solver.export.calibration_gate`); its
        reasons are recorded in ``calibration``.
    defects : ndarray, optional
        The defect vector to write (rad / mm) instead of the identification's, e.g. the identified one
        moved onto a geometry whose loops close (:func:`hyperstat.solver.calibration.virtual.onto_closure`).
        The geometry identified parameters then carry the applied value, and ``calibration.closure_move``
        records by how much each one was moved (mm / rad), so that the file does not contradict itself.

    Raises
    ------
    DataError
        When the gate refuses the calibration and ``forced`` is false.
    """
    from hyperstat.solver.export.calibration_gate import calibration_record

    try:
        record = calibration_record(identification, forced)
    except ValueError as exc:
        raise DataError(f"'{mechanism.name}': the calibration is not exported: {exc} (force=True writes it with the "
                        f"reasons recorded).") from None
    model = identification.model
    theta = identification.theta
    xi = model.defects(theta) if defects is None else np.asarray(defects, dtype=float)
    names = [p.name for p in mechanism.parameters]
    targets = target_offsets(identification)
    # several targets: the tool point is the output frame's origin, the targets are named offsets in it
    tool_point = np.zeros(3) if targets else theta[model.sl_target]
    exported = []
    for eff, sl in zip(model.effects, model._effect_slices):
        if eff.name not in MACHINE_EFFECTS:
            continue
        options = {}
        if eff.name == "violated-constraint":
            options["only"] = list(eff.defects)
        if eff.name == "screw-periodic":
            options["lead"] = eff.lead
        exported.append({"effect": eff.name, "parameters": dict(zip(model.names[sl], map(float, theta[sl]))),
                         "options": options})
    applied = dict(zip(names, map(float, xi)))
    moved = {}
    identified = []
    for p in identification.parameters:
        if not p["identifiable"]:
            continue
        estimate = float(p["estimate"])
        if defects is not None and p["kind"] == "geometry" and p["name"] in applied \
                and applied[p["name"]] != estimate:
            moved[p["name"]] = applied[p["name"]] - estimate
            estimate = applied[p["name"]]
        identified.append({"name": p["name"], "kind": p["kind"], "unit": p["unit"], "estimate": estimate,
                           "std": None if p["std"] is None else float(p["std"])})
    if moved:
        record = dict(record, closure_move=moved)
    stats = {"identification": identification.identification, "validation": identification.validation,
             "noise_rms": identification.noise_rms, "rank": identification.rank,
             "unknowns": identification.n_unknowns, "condition_number": identification.condition_number}
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "units": {"length": "mm", "angle": "rad"},
        "mechanism": mechanism.name,
        "model": mechanism_to_dict(mechanism),
        "defects": {n: float(v) for n, v in zip(names, xi)},
        "target": [float(v) for v in tool_point],
        "identified": identified,
        "effects": exported,
        "statistics": json.loads(dumps_json(stats)),
        "calibration": json.loads(dumps_json(record)),
        "provenance": {"source": dict(source or {}),
                       "data": [{"file": Path(f).name, "sha256": file_sha256(f)} for f in data_files]},
        "test_vectors": build_test_vectors(mechanism, xi, tool_point, targets=targets),
    }
    if targets:
        doc["targets"] = targets
    if tolerances is not None:
        doc["tolerances"] = {"counts": dict(tolerances["counts"]), "task": list(tolerances.get("task", [])),
                             "parameters": {n: {"class": e["class"], "tolerance_id": e["tolerance_id"]}
                                            for n, e in tolerances["parameters"].items()}}
    doc = json.loads(dumps_json(doc))  # plain JSON types, as a reader will see them
    if exported:
        doc["test_vectors"]["effect_vectors"] = json.loads(dumps_json(build_effect_vectors(doc)))
    doc["sha256"] = content_hash(doc)
    return doc


def write_controller(path: str | os.PathLike, doc: dict) -> Path:
    """Write a controller file atomically (deterministic bytes)."""
    return write_text(path, dumps_json(doc))


def read_controller(path: str | os.PathLike) -> dict:
    """Read a controller file, refusing a wrong format, version, schema or hash.

    Raises
    ------
    DataError
        One sentence naming the file and what is wrong.
    """
    import jsonschema

    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such controller file.")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise DataError(f"{path}: not a JSON file (not UTF-8 text).") from None
    doc = load_json(text, str(path))  # a key declared twice is refused, not overwritten
    if not isinstance(doc, dict):
        raise DataError(f"{path}: a controller file holds a JSON object.")
    if doc.get("format") != FORMAT:
        raise DataError(f"{path}: field 'format' must be \"{FORMAT}\", got {json.dumps(doc.get('format'))}.")
    if doc.get("version") != VERSION:
        why = f" ({OLDER[doc['version']]}: export it again)" if doc.get("version") in OLDER else ""
        raise DataError(f"{path}: field 'version' is {json.dumps(doc.get('version'))}, but this hyperstat reads "
                        f"version {VERSION}{why}.")
    errors = list(jsonschema.Draft202012Validator(controller_schema()).iter_errors(doc))
    if errors:
        raise DataError(f"{path}: {_schema_message(jsonschema.exceptions.best_match(errors))}.")
    try:
        expected = content_hash(doc)
    except ValueError:
        raise DataError(f"{path}: the content holds a non-finite number.") from None
    if doc["sha256"] != expected:
        raise DataError(f"{path}: the SHA-256 does not match the content (the file was modified after export).")
    check_admissible(doc, str(path))
    return doc


def check_admissible(doc: dict, source: str = "controller file") -> None:
    """What the format version fixes, checked on a file whose hash matched (a hash anyone can recompute).

    The test-vector tolerance is the version's; ``defects`` holds exactly the model's defects, each
    within the version's magnitude; the tool point and targets are within the version's offset; the
    test vectors are the version's configurations (the draws from the model's joint ranges, then the
    corners of the ranges: a changed range, which becomes a controller's joint limit, cannot pass with
    the old vectors), every one that assembles on the file's geometry and no other, at least the
    version's number of draws; the model's joint map turns the vectors' controller values into their
    actuated ones; and the file is consistent with itself
    (:func:`~hyperstat.solver.export.controller_checks.check_consistency`).

    Raises
    ------
    DataError
        One sentence naming ``source`` and the field.
    """
    rules = ADMISSIBLE[doc["version"]]
    tol = doc["test_vectors"]["tolerance"]
    for key, value in rules["test_vector_tolerance"].items():
        if tol.get(key) != value:
            unit = key.rsplit("_", 1)[1]
            raise DataError(f"{source}: field 'test_vectors.tolerance.{key}' is {tol.get(key)!r}, but version "
                            f"{doc['version']} fixes it at {value:g} {unit}: a file cannot set its own tolerance.")
    mech = mechanism_from_dict(doc["model"], f"{source}: field 'model'")
    _same_names(doc["defects"], [p.name for p in mech.parameters],
                f"{source}: field 'defects' names '{{}}', which is not a defect of the model '{mech.name}'.",
                f"{source}: field 'defects' has no value for '{{}}', a defect of the model.")
    for p in mech.parameters:
        v, limit = doc["defects"][p.name], rules["defect_mm" if p.unit == "mm" else "defect_rad"]
        if not abs(v) <= limit:
            raise DataError(f"{source}: field 'defects.{p.name}' is {v:g} {p.unit}, beyond the {limit:g} {p.unit} "
                            f"version {doc['version']} admits for an identified defect.")
    offsets = [("target", doc["target"])] + [(f"targets.{k}", v) for k, v in doc.get("targets", {}).items()]
    for field, v in offsets:
        if not float(np.linalg.norm(v)) <= rules["offset_mm"]:
            raise DataError(f"{source}: field '{field}' is {float(np.linalg.norm(v)):g} mm from the output frame, "
                            f"beyond the {rules['offset_mm']:g} mm version {doc['version']} admits.")
    from hyperstat.solver.export.controller_checks import check_consistency

    kin = Kinematics(mech)
    check_consistency(doc, mech, kin.length_scale, source)  # cheap: before the vectors are assembled again
    xi = np.array([doc["defects"][p.name] for p in mech.parameters], dtype=float)
    _check_vector_draws(doc, mech, xi, rules, source)


def _same_names(given: dict, names: list, unknown: str, missing: str) -> None:
    """Refuse a name of ``given`` not in ``names`` (``unknown`` formatted with it), then one missing (``missing``)."""
    for message, extra in ((unknown, [n for n in given if n not in names]),
                           (missing, [n for n in names if n not in given])):
        if extra:
            raise DataError(message.format(extra[0]))


def _match_vectors(doc: dict, mech, rules: dict, source: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Match the file's test vectors, in order, to the version's configurations (:func:`test_vector_configurations`).

    Returns the configurations, their corner flags, and the index of each vector among them.

    Raises
    ------
    DataError
        For a vector that is not one of the configurations (in order), or of the wrong size.
    """
    tv = doc["test_vectors"]
    vec = tv["vectors"]
    act = mech.actuated
    for k, v in enumerate(vec):
        if len(v["actuated"]) != len(act) or len(v["joints"]) != len(mech.joints):
            raise DataError(f"{source}: test vector {k} has {len(v['actuated'])} actuated and {len(v['joints'])} "
                            f"joint values; the model has {len(act)} and {len(mech.joints)}.")
    configs, corner = test_vector_configurations(mech, tv["seed"], rules["test_vectors"]["count"])
    scale = np.maximum(np.abs(configs).max(axis=0), 1.0)
    index = np.zeros(len(vec), dtype=int)
    d = 0
    for k, v in enumerate(vec):
        qa = np.asarray(v["actuated"], dtype=float)
        while d < len(configs) and not np.all(np.abs(configs[d] - qa) <= 1e-12 * scale):
            d += 1
        if d == len(configs):
            lo, hi = mech.ranges[act].T
            out = np.flatnonzero((qa < lo - 1e-9) | (qa > hi + 1e-9))
            why = (f"its value {qa[out[0]]:g} of joint '{mech.joints[act[out[0]]].name}' lies outside the range "
                   f"[{lo[out[0]]:g}, {hi[out[0]]:g}]" if len(out) else
                   "its actuated values are not one of the version's configurations (the draws from the file's "
                   "joint ranges with its seed, then the corners of the ranges), in order")
            why += " (were the joint ranges or the vectors changed after export?)"
            raise DataError(f"{source}: test vector {k}: {why}.")
        index[k] = d
        d += 1
    return configs, corner, index


def _vector_corners(doc: dict, mech) -> np.ndarray:
    """Per test vector of ``doc``, whether it is a corner of the actuated ranges."""
    _, corner, index = _match_vectors(doc, mech, ADMISSIBLE[doc["version"]], "controller file")
    return corner[index]


def _check_vector_draws(doc: dict, mech, xi: np.ndarray, rules: dict, source: str) -> None:
    """The test vectors are exactly the version's configurations that assemble on the file's geometry, in order:
    the seeded draws from the model's joint ranges (at least ``at_least`` of them) and the corners of the ranges.

    Every configuration is assembled again (together, as the writer did): one that assembles and is missing,
    or one present that does not assemble, is refused.
    """
    vec = doc["test_vectors"]["vectors"]
    configs, corner, index = _match_vectors(doc, mech, rules, source)
    draws = int(np.sum(~corner[index]))
    if draws < rules["test_vectors"]["at_least"]:
        raise DataError(f"{source}: field 'test_vectors.vectors' holds {draws} drawn vectors; version {doc['version']} "
                        f"draws {rules['test_vectors']['count']} and needs at least {rules['test_vectors']['at_least']}.")
    assembles = Kinematics(mech).solve(configs, xi).converged
    present = np.zeros(len(configs), dtype=bool)
    present[index] = True
    missing = np.flatnonzero(assembles & ~present)
    if len(missing):
        d = int(missing[0])
        what = f"corner {d - int(np.sum(~corner))}" if corner[d] else f"draw {d}"
        raise DataError(f"{source}: field 'test_vectors.vectors' lacks {len(missing)} of the version's configurations "
                        f"that assemble on the file's geometry ({what} first: {' '.join(f'{v:.6g}' for v in configs[d])}"
                        f"); version {doc['version']} keeps every one: were vectors dropped?")
    extra = np.flatnonzero(present & ~assembles)
    if len(extra):
        k = int(np.flatnonzero(index == extra[0])[0])
        raise DataError(f"{source}: test vector {k} does not assemble on the file's geometry.")
    _check_controller_values(vec, mech, source)


def _check_controller_values(vec: list, mech, source: str) -> None:
    """The model's joint map turns every vector's ``controller`` values into its ``actuated`` ones (1e-9 rad / mm)."""
    jm = _square_joint_map(mech)
    has = ["controller" in v for v in vec]
    if jm is None:
        if any(has):
            raise DataError(f"{source}: test vectors give controller joint values, but the model has no joint map.")
        return
    if not all(has):
        raise DataError(f"{source}: test vector {has.index(False)} gives no controller joint values, though the model "
                        f"has a joint map (version {VERSION} records them to check the map).")
    values = np.array([v["controller"] for v in vec], dtype=float)
    if values.shape[1] != len(jm.controller):
        raise DataError(f"{source}: test vectors give {values.shape[1]} controller joint values; the joint map has "
                        f"{len(jm.controller)} controller joints.")
    got = jm.apply(values * _controller_factors(jm))
    qa = np.array([v["actuated"] for v in vec], dtype=float)
    err = np.abs(got - qa)
    k, j = np.unravel_index(int(np.argmax(err)), err.shape)
    if not err[k, j] <= 1e-9 * max(1.0, float(np.abs(qa[k, j]))):
        joint = jm.model[j]
        raise DataError(f"{source}: test vector {k}: the model's joint map turns its controller values "
                        f"({', '.join(f'{c} {v:.6g}' for c, v in zip(jm.controller, values[k]))}, "
                        f"{jm.units['angle']} / {jm.units['length']}) into {got[k, j]:.9g} for model joint '{joint}', "
                        f"not the vector's {qa[k, j]:.9g}: the joint map was changed after export.")


class ControllerModel:
    """Reference forward and inverse geometric model built from a controller file only.

    Parameters
    ----------
    doc : dict
        Content of :func:`read_controller`.
    source : str
        The file's name, for messages.
    """

    def __init__(self, doc: dict, source: str = "controller file") -> None:
        from hyperstat.solver.calibration.identify import MeasurementModel

        self.mechanism = mechanism_from_dict(doc["model"], f"{source}: field 'model'")
        self.kin = Kinematics(self.mechanism)
        names = [p.name for p in self.mechanism.parameters]
        missing = [n for n in names if n not in doc["defects"]]
        if missing:
            raise DataError(f"{source}: defect '{missing[0]}' of the model has no value.")
        self.xi = np.array([doc["defects"][n] for n in names])
        self.target = np.array(doc["target"], dtype=float)
        self.targets = {name: np.array(v, dtype=float) for name, v in doc.get("targets", {}).items()}
        self._linear = np.array([self.mechanism.joints[i].type == "P" for i in self.mechanism.actuated])
        self.effects = [_exported_effect(e, i, self.mechanism, source) for i, e in enumerate(doc["effects"])]
        self._model = MeasurementModel.__new__(MeasurementModel)
        self._model.mechanism, self._model.kin = self.mechanism, self.kin

    def forward(self, q_actuated: np.ndarray, metadata: dict | None = None,
                with_effects: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Tool point (base frame, mm) and output pose (4x4) at actuated values, with the machine effects.

        Parameters
        ----------
        q_actuated : ndarray, (K, n_actuated)
            Commanded actuated values (rad / mm).
        metadata : dict, optional
            ``temperature``, ``payload``, ``dir<joint>`` per pose, for the effects that need them.
        with_effects : bool
            Apply the machine effects (False: the rigid identified geometry only).
        """
        from hyperstat.solver.calibration.measurements import MeasurementSet

        qa = np.atleast_2d(np.asarray(q_actuated, dtype=float))
        data = MeasurementSet([str(i) for i in range(len(qa))], [], qa.copy(), np.zeros((len(qa), 3)),
                              metadata=dict(metadata or {}))
        effects = self.effects if with_effects else []
        for eff in effects:
            corr = eff.actuator_correction(self._model, eff.truth, data)
            if corr is not None:
                qa = qa + corr[0]
        xi = self.xi.copy()
        res = self.kin.solve(qa, xi)
        st = self.kin.evaluate(res.q, xi, jacobians=False)
        pose = st.output_pose
        point = pose[:, :3, 3] + pose[:, :3, :3] @ self.target
        for eff in effects:
            corr = eff.output_correction(self._model, eff.truth, data, res.q, st, point, False)
            if corr is not None:
                point = point + corr[0]
        return point, pose

    def inverse(self, pose: np.ndarray, q_start: np.ndarray | None = None, tol: float = 1e-12,
                max_iter: int = 60, restarts: int = 16) -> np.ndarray:
        """Actuated values that bring the output frame to ``pose`` (least squares over its 6 components).

        Effects are not inverted (the rigid identified geometry only).  Newton (Gauss-Newton on
        the pose error, steps capped at 0.3 rad / 0.3 length scales) from ``q_start`` or home;
        a pose it does not reach (a serial arm far from home can stall in a local minimum) is
        retried from up to ``restarts`` seeded starts inside the joint ranges, never from the
        answer.

        Parameters
        ----------
        pose : ndarray, (K, 4, 4)
            Wanted output poses in the base frame.
        q_start : ndarray, (K, n_actuated), optional
            Initial guess (default: home).
        """
        pose = np.asarray(pose, dtype=float).reshape(-1, 4, 4)
        act = self.mechanism.actuated
        qa = (np.broadcast_to(self.mechanism.home[act], (len(pose), len(act))) if q_start is None
              else np.atleast_2d(q_start)).astype(float).copy()
        qa, miss = self._newton(pose, qa, tol, max_iter)
        lc = self.kin.length_scale
        lo, hi = self.mechanism.ranges[act].T
        rng = np.random.default_rng(0)
        for _ in range(restarts):
            out = np.flatnonzero(~(miss <= 1e-9 * max(1.0, lc)))
            if not len(out):
                break
            start = lo + (hi - lo) * (0.1 + 0.8 * rng.random((len(out), len(act))))
            q2, m2 = self._newton(pose[out], start, tol, max_iter)
            better = m2 < miss[out]
            qa[out[better]], miss[out[better]] = q2[better], m2[better]
        return qa

    def _newton(self, pose: np.ndarray, qa: np.ndarray, tol: float, max_iter: int) -> tuple[np.ndarray, np.ndarray]:
        """Capped Newton iterations from ``qa``: (actuated values, remaining pose error per pose, mm-equivalent)."""
        from hyperstat.solver.kinematics.closure import batched_lstsq
        from hyperstat.solver.kinematics.frames import so3_log

        act = self.mechanism.actuated
        lc = self.kin.length_scale
        qa = qa.copy()
        for it in range(max_iter + 1):
            res = self.kin.solve(qa, self.xi)
            st = self.kin.evaluate(res.q, self.xi, jacobians=True)
            cur = st.output_pose
            rot_err = so3_log(pose[:, :3, :3] @ np.transpose(cur[:, :3, :3], (0, 2, 1)))
            pos_err = pose[:, :3, 3] - cur[:, :3, 3]
            err = np.concatenate([rot_err * lc, pos_err], axis=1)
            if it == max_iter:
                break
            passive = self.mechanism.passive
            if len(passive) and len(self.mechanism.closures):
                b = self.kin.scaled_rows(st.closure_q[:, :, passive])
                dp = batched_lstsq(b, self.kin.scaled_rows(st.closure_q[:, :, act]))
                k_a = st.output_q[:, :, act] - st.output_q[:, :, passive] @ dp
            else:
                k_a = st.output_q[:, :, act]
            jac = k_a.copy()
            jac[:, :3] *= lc
            step = batched_lstsq(jac, err[:, :, None])[..., 0]
            step = _capped(step, self._linear, lc)
            qa = qa + step
            if np.max(np.abs(step)) < tol * max(1.0, lc):
                res = self.kin.solve(qa, self.xi)
                cur = self.kin.evaluate(res.q, self.xi, jacobians=False).output_pose
                rot_err = so3_log(pose[:, :3, :3] @ np.transpose(cur[:, :3, :3], (0, 2, 1)))
                err = np.concatenate([rot_err * lc, pose[:, :3, 3] - cur[:, :3, 3]], axis=1)
                break
        return qa, np.linalg.norm(err, axis=1)


#: options an exported effect may carry (anything else is refused, not passed on)
_EFFECT_OPTIONS = {"violated-constraint": {"only"}, "screw-periodic": {"lead"}}


def _exported_effect(e: dict, i: int, mechanism, source: str):
    """The effect of ``effects[i]`` of a controller file, refusing unknown options or parameters and values
    outside the effect's physical domain or beyond its plausible magnitude (the library's, not the file's)."""
    from hyperstat.solver.diagnosis.effects import make_effect
    from hyperstat.solver.errors import HyperstatError

    where = f"{source}: field 'effects[{i}]' ({e['effect']})"
    extra = sorted(set(e["options"]) - _EFFECT_OPTIONS.get(e["effect"], set()))
    if extra:
        raise DataError(f"{where}: option '{extra[0]}' is not part of the format.")
    try:
        eff = make_effect(e["effect"], mechanism, None, None, **dict(e["options"]))
    except HyperstatError as exc:
        raise DataError(f"{where}: {exc}") from None
    except (TypeError, ValueError, KeyError, IndexError) as exc:
        raise DataError(f"{where}: its options cannot build the effect ({exc.__class__.__name__}: {exc}).") from None
    names = eff.parameter_names(None)
    _same_names(e["parameters"], names, f"{where}: parameter '{{}}' is not a parameter of this effect on "
                                        f"'{mechanism.name}'.", f"{where}: parameter '{{}}' has no value.")
    values = np.array([e["parameters"][n] for n in names], dtype=float)
    units = eff.parameter_units(None)
    for k, n in enumerate(names):
        v = values[k]
        if not (eff.lower[k] <= v <= eff.upper[k]) or abs(v) > eff.plausible[k]:
            raise DataError(f"{where}: parameter '{n}' = {v:g} {units[k]} lies outside the effect's physical domain "
                            f"or beyond its plausible magnitude ({eff.plausible[k]:g} {units[k]}).")
    return eff.with_truth(values)


def _capped(step: np.ndarray, linear: np.ndarray, length_scale: float, cap: float = 0.3) -> np.ndarray:
    """Newton steps (K, n_actuated) scaled down per pose so that no revolute joint turns by more than
    ``cap`` rad and no prismatic one moves by more than ``cap`` length scales: from home, an
    undamped step of a 6R arm can overshoot by turns and diverge (found on a FANUC-like file)."""
    size = np.max(np.abs(step) / np.where(linear, cap * length_scale, cap), axis=1, initial=0.0)
    return step / np.maximum(size, 1.0)[:, None]


def target_offsets(identification) -> dict | None:
    """Named target offsets (output frame, mm) of an identification with several targets, else None.

    Several SMRs on one tool are one geometry and one offset per target (issue 21): the
    controller file then keeps the output frame's origin as its tool point (``target`` is zero)
    and lists the identified offsets by name (``targets``).  The tool frame's own defects are
    held at their prior there (the offsets absorb them), so the tool point is where the model
    puts the tool frame; the SMRs are where they were measured.
    """
    model = identification.model
    if len(model.targets) < 2:
        return None
    offsets = np.asarray(identification.theta[model.sl_target], dtype=float).reshape(-1, 3)
    return {str(name): [float(v) for v in off] for name, off in zip(model.targets, offsets)}


def target_points(pose: np.ndarray, targets: dict) -> dict:
    """Base-frame positions (mm) of named targets at output poses ``pose`` (K, 4, 4): name -> (K, 3)."""
    return {name: pose[:, :3, 3] + pose[:, :3, :3] @ np.asarray(off, dtype=float) for name, off in targets.items()}


def _check_target_points(doc: dict, model: "ControllerModel", pose: np.ndarray, tol_mm: float) -> None:
    """The test vectors' target positions re-evaluated from the file's offsets (several targets only)."""
    vec = doc["test_vectors"]["vectors"]
    if not model.targets:
        if any("targets" in v for v in vec):
            raise DataError("controller file: test vectors list target positions, but the file has no 'targets'.")
        return
    points = target_points(pose, model.targets)
    for k, v in enumerate(vec):
        given = v.get("targets", {})
        if set(given) != set(points):
            raise DataError(f"controller file: test vector {k} lists targets {sorted(given)}, the file's 'targets' "
                            f"are {sorted(points)}.")
        for name, p in points.items():
            err = float(np.linalg.norm(p[k] - np.asarray(given[name], dtype=float)))
            if not err <= tol_mm:
                raise DataError(f"controller file: test vector {k}: target '{name}' is {err:.3g} mm from the file's "
                                f"(tolerance {tol_mm:g} mm).")


def check_controller(path: str | os.PathLike, reference: "Mechanism | None" = None) -> dict:
    """Check a received controller file: format, version, schema, hash, what the version admits, the model
    against a trusted ``reference`` (a :class:`Mechanism`, when given), the test vectors, the joint ranges.

    Returns
    -------
    dict
        ``mechanism``, ``sha256``, ``reference`` (whether the model was compared with one), the
        largest errors of :func:`check_test_vectors`, the calibration's ``fit_quality``, ``forced``
        and ``reasons``, its ``notes`` (the findings that stopped nothing: ``code`` and ``message``, e.g.
        ``closing-geometry-moved``, held-out residuals 1.5-3 times the noise), its ``region`` (the actuated
        values its poses covered), the joint ``ranges`` and ``outside_region`` (test vectors beyond the region).

    Raises
    ------
    DataError
        One sentence naming the file and the first check that fails.

    Examples
    --------
    >>> check_controller("no-such-file.json")
    Traceback (most recent call last):
    ...
    hyperstat.solver.errors.DataError: no-such-file.json: no such controller file.
    """
    doc = read_controller(path)
    if reference is not None:
        compare_model(doc["model"], reference, str(path))
    try:
        model = ControllerModel(doc)
        result = check_test_vectors(doc, model)
        check_reachable_ranges(model)
    except DataError as exc:
        raise DataError(f"{path}: {str(exc).removeprefix('controller file: ')}") from None
    rec = doc["calibration"]
    region = rec["region"]
    qa = np.array([v["actuated"] for v in doc["test_vectors"]["vectors"]], dtype=float)
    outside = int(np.sum(np.any((qa < np.array(region["low"]) - 1e-9) | (qa > np.array(region["high"]) + 1e-9),
                                axis=1)))
    ranges = model.mechanism.ranges[model.mechanism.actuated].tolist()
    return {"mechanism": doc["mechanism"], "sha256": doc["sha256"], "reference": reference is not None, **result,
            "fit_quality": rec["fit_quality"], "forced": rec["forced"], "reasons": list(rec["reasons"]),
            "notes": [{"code": f["code"], "message": f["message"]} for f in rec["findings"] if not f["refuses"]],
            "region": region, "ranges": ranges, "outside_region": outside}


def check_reachable_ranges(model: "ControllerModel", samples: int = 32, seed: int = 0) -> None:
    """Refuse an actuated joint range the identified parallel mechanism cannot reach at either end.

    For every actuated joint and each end of its range, ``samples`` configurations of the other
    actuated joints (uniform in their ranges, seeded) are assembled with the joint at that end;
    if none assembles, the range is wider than the machine (the LinuxCNC export would make it a
    joint limit).  A serial chain reaches any joint value: nothing to check there.  This finds a
    range the geometry cannot reach, not a stroke beyond what the actuator has: only a trusted
    model (``check-controller --source``) can tell that.

    Raises
    ------
    DataError
    """
    mech = model.mechanism
    if not mech.closures:
        return
    act = mech.actuated
    lo, hi = mech.ranges[act].T
    rng = np.random.default_rng(seed)
    blocks, ends = [], []
    for k in range(len(act)):
        for end, value in (("low", lo[k]), ("high", hi[k])):
            qa = lo + (hi - lo) * rng.random((samples, len(act)))
            qa[:, k] = value
            blocks.append(qa)
            ends.append((k, end, value))
    ok = model.kin.solve(np.concatenate(blocks), model.xi).converged.reshape(len(blocks), samples)
    for (k, end, value), reached in zip(ends, ok):
        if not reached.any():
            j = mech.joints[act[k]]
            raise DataError(f"controller file: the {end} end {value:g} {'rad' if j.type == 'R' else 'mm'} of actuated "
                            f"joint '{j.name}' is not reachable: none of {samples} configurations with the joint there "
                            f"assembles on the identified geometry (continued from home); the range is wider than the "
                            f"machine.")


def compare_model(model: dict, reference: "Mechanism", source: str) -> None:
    """Refuse a file whose embedded model differs from a trusted ``reference`` mechanism (ranges included).

    Numbers are compared to 1e-12 (relative to their size, at least 1e-12 absolute).

    Raises
    ------
    DataError
        Naming the first field that differs.
    """
    want = json.loads(dumps_json(mechanism_to_dict(reference)))

    def walk(a, b, path: str) -> str | None:
        if isinstance(a, dict) and isinstance(b, dict):
            for key in sorted(set(a) | set(b)):
                if key not in a or key not in b:
                    return f"{path}.{key}"
                found = walk(a[key], b[key], f"{path}.{key}")
                if found:
                    return found
            return None
        if isinstance(a, list) and isinstance(b, list):
            if len(a) != len(b):
                return path
            for i, (x, y) in enumerate(zip(a, b)):
                found = walk(x, y, f"{path}[{i}]")
                if found:
                    return found
            return None
        if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
            return None if abs(a - b) <= 1e-12 * max(1.0, abs(a), abs(b)) else path
        return None if a == b else path

    found = walk(model, want, "model")
    if found:
        raise DataError(f"{source}: field '{found}' differs from the reference model '{reference.name}' given with "
                        f"--source: the file is not for that machine, or it was changed (its ranges are the "
                        f"controller's joint limits).")
