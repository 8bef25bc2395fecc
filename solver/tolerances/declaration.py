"""What a template declares for tolerancing: task components, measurements, spec, joint clearances.

Units: lengths in mm, angles in rad.

A template (``TOLERANCING`` at module level, passed through by
:func:`hyperstat.cad_plugin.templates.build_template`) or a model file (optional field
``tolerancing``, see ``docs/model-format.md``) declares

* ``task``: the pose components the machine's task uses, from :data:`TASK_COMPONENTS`
  (e.g. ``["position", "tool-axis"]`` for a 5-axis machine tool: the rotation about the
  spindle does not matter; ``["position"]`` for a translational manipulator;
  ``["x"]`` for a slider whose task is its stroke);
* ``measurements``: what a calibration measures, ``{"kind": "positions" | "poses",
  "targets_mm": [[x, y, z], ...] (in the output frame), "noise_mm": sigma,
  "noise_rad": sigma, "frame": "registered" | "unknown"}`` (``registered``, the default: the
  tracker frame is measured on references of the base, as a calibration campaign does
  before measuring poses; ``unknown``: it is identified with the defects) and
  ``"offsets": "known" | "unknown"`` (``known``, the default: the targets sit in nests at
  known offsets from the output frame; ``unknown``: their offsets are identified too) and
  ``"poses"`` (number of calibration poses, default 60);
* ``spec``: the required accuracy over the workspace, ``{"position_mm": ...,
  "orientation_rad": ...}`` (``hyperstat accuracy --position-accuracy`` and
  ``--orientation-accuracy`` override it);
* ``clearances``: per joint kind (``"R"``, ``"P"``) and optionally per joint name
  (``"joints": {"21": {...}}``), ``{"radial_mm", "axial_mm", "tilt_rad", "twist_rad",
  "span_mm", "side", "centre_mm", "source"}``: the physical model of
  :mod:`hyperstat.solver.tolerances.clearance`.  A joint is held by two supports
  ``span_mm`` apart along its axis (a revolute's two bearings, or a pin's engagement length;
  a prismatic joint's carriage, between its two pads), each with a radial play of at most
  ``radial_mm`` in every direction, centred ``centre_mm`` along the axis from the joint's
  frame on its ``side``: ``"fixed"`` (the frame before the joint's motion: a bearing, a leg
  guided at its base joint) or ``"moving"`` (after it: a carriage riding on a fixed rail,
  tilting about itself wherever it is).  The largest tilt is ``tilt_rad = 2 radial_mm /
  span_mm`` (give one of them; a declared one wins over an inherited one); ``axial_mm`` is the
  axial play, ``twist_rad`` a prismatic joint's play about its own axis.

Defaults (:data:`DEFAULT_CLEARANCES`) are plain-bearing fits: ISO 286-2 H7/g6 on a
20 mm diameter (hole 0/+21 µm, shaft -7/-20 µm: diametral clearance 7 to 41 µm, so a
radial play of at most 20.5 µm) and an engagement length of 20 mm (revolute) or 40 mm
(prismatic guide: a carriage on the moving side) for the tilt the play allows (diametral
clearance / length).  Revolutes are taken as axially located by shoulders (no axial play)
unless declared.

>>> from hyperstat.solver.tolerances.declaration import parse_declaration
>>> parse_declaration({"task": ["position"]}, "demo").task
('position',)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.errors import ModelError

__all__ = ["TASK_COMPONENTS", "DEFAULT_CLEARANCES", "MACHINE_TOOL_CLEARANCES", "DEFAULT_SPEC", "DEFAULT_WORKSPACE_LOSS",
           "Declaration", "parse_declaration", "declaration_of", "task_rows", "check_workspace_loss"]

#: task component -> meaning
TASK_COMPONENTS = {
    "position": "position of the output point (3 components)",
    "orientation": "orientation of the output frame (3 components)",
    "tool-axis": "direction of the output frame's z axis (2 components: the rotation about it does not matter)",
    "x": "position along the base x axis", "y": "position along the base y axis",
    "z": "position along the base z axis",
    "rx": "rotation about the base x axis", "ry": "rotation about the base y axis",
    "rz": "rotation about the base z axis",
}

_ISO286 = ("ISO 286-2 fit H7/g6 on a 20 mm diameter: diametral clearance 7 to 41 µm, radial play up to "
           "20.5 µm; tilt = 41 µm / engagement length")
DEFAULT_CLEARANCES = {
    "R": {"radial_mm": 0.0205, "axial_mm": 0.0, "tilt_rad": 0.041 / 20.0, "twist_rad": 0.0, "side": "fixed",
          "centre_mm": 0.0,
          "source": _ISO286 + " (20 mm engagement, centred on the joint); axially located by shoulders (no axial "
                              "play, assumed)"},
    "P": {"radial_mm": 0.0205, "axial_mm": 0.0, "tilt_rad": 0.041 / 40.0, "twist_rad": 0.041 / 40.0,
          "side": "moving", "centre_mm": 0.0,
          "source": _ISO286 + " (a 40 mm carriage riding on the guide, centred on the moving frame, tilting about "
                              "itself); the twist about the guide as its tilt (assumed)"},
}
#: joints of a machine tool or precision positioner on rolling elements (the ``clearances`` the Tripteor, hexapod
#: and SCARA templates declare, written out in each template so that a template stays readable on its own;
#: tests/solver/tolerances/test_values.py checks that they agree with this).
#: Revolute: ISO 5753-1:2009 radial internal clearance, Group 2 (C2), of a deep groove ball bearing with a bore
#: over 18 up to 24 mm is 0 to 10 µm (the same group and bore give 5 to 20 µm in Group N): the inner ring moves
#: +-5 µm about the outer one; the tilt is two such bearings +-5 µm each, 50 mm apart (the span is assumed), and
#: the axial play is assumed equal to the radial one.  A preloaded bearing has no play (negative clearance): the
#: assembly tolerance then comes from the structure's compliance, which this model does not contain.
#: Prismatic: no public standard gives the play of a preloaded linear guide or ball screw (ISO 3408-3 classes
#: the travel deviation of ball screws, not their play), so the values are assumed.
MACHINE_TOOL_CLEARANCES = {
    "R": {"radial_mm": 0.005, "axial_mm": 0.005, "span_mm": 50.0, "twist_rad": 0.0, "side": "fixed",
          "source": "ISO 5753-1 Group 2 (C2) radial internal clearance of a deep groove ball bearing, bore over 18 "
                    "to 24 mm: 0 to 10 µm, i.e. +-5 µm radial play; tilt: two such bearings 50 mm apart (span "
                    "assumed); axial play assumed equal to the radial; a preloaded bearing has none"},
    "P": {"radial_mm": 0.002, "axial_mm": 0.0, "span_mm": 200.0, "twist_rad": 2e-5, "side": "fixed",
          "source": "assumed (no public standard gives the play of a preloaded linear guide or ball screw): "
                    "2 µm on two pads 200 mm apart in a guide at the joint's fixed frame (a leg sliding through its "
                    "base joint), so 20 µrad of tilt, and 20 µrad of twist"},
}
DEFAULT_SPEC = {"position_mm": 0.05, "orientation_rad": 5e-4}
#: the share of an actuator's range (or of the task's extent at a dead centre) a calibrated machine may lose to the
#: compensation of its compensable defects, all together: 0.1 % (assumed; ``workspace_loss`` of the declaration,
#: ``--workspace-loss`` of report, accuracy and montecarlo)
DEFAULT_WORKSPACE_LOSS = 1e-3
_CLEARANCE_KEYS = ("radial_mm", "axial_mm", "tilt_rad", "twist_rad", "span_mm", "centre_mm")
_CLEARANCE_WORDS = ("side",)  # "fixed" or "moving"


@dataclass(frozen=True)
class Declaration:
    """A mechanism's tolerancing declaration (see the module docstring); ``declared`` lists what was given."""

    task: tuple = ("position", "orientation")
    measurement_kind: str = "positions"
    targets_mm: tuple = ((0.0, 0.0, 0.0),)
    noise_mm: float = 0.005
    noise_rad: float = 5e-6
    frame: str = "registered"
    offsets: str = "known"
    poses: int = 60
    position_mm: float | None = DEFAULT_SPEC["position_mm"]
    orientation_rad: float | None = DEFAULT_SPEC["orientation_rad"]
    clearances: dict = field(default_factory=dict)
    declared: tuple = ()
    workspace_loss: float = DEFAULT_WORKSPACE_LOSS

    def clearance(self, joint_name: str, joint_type: str) -> dict:
        """Clearance of one joint, resolved: the default, then its kind's entry, then its own (with the source).

        Every key is present: ``radial_mm``, ``axial_mm``, ``tilt_rad``, ``span_mm`` (``inf`` when
        the tilt is zero), ``twist_rad``, ``side``, ``centre_mm``, ``source``.  Of ``tilt_rad`` and
        ``span_mm`` the one declared last wins and gives the other (``tilt = 2 radial / span``).

        >>> c = Declaration().clearance("2", "P")
        >>> round(c["span_mm"], 9), c["side"]
        (40.0, 'moving')
        """
        out: dict = {}
        levels = [DEFAULT_CLEARANCES[joint_type], self.clearances.get(joint_type),
                  self.clearances.get("joints", {}).get(joint_name)]
        for level, entry in enumerate(levels):
            if not entry:
                continue
            if "span_mm" in entry:
                out.pop("tilt_rad", None)
            if "tilt_rad" in entry:
                out.pop("span_mm", None)
            out.update(entry)
            if level and "source" not in entry:
                out["source"] = (f"declared for joint {joint_name}" if level == 2 else
                                 f"declared by the template for {joint_type} joints")
        radial = out["radial_mm"]
        if "span_mm" in out:
            out["tilt_rad"] = 2.0 * radial / out["span_mm"] if out["span_mm"] > 0 else float("inf")
        else:
            out["span_mm"] = 2.0 * radial / out["tilt_rad"] if out["tilt_rad"] > 0 else float("inf")
        out.setdefault("side", "fixed" if joint_type == "R" else "moving")
        out.setdefault("centre_mm", 0.0)
        return out

    def to_dict(self) -> dict:
        """JSON-ready form (the model file's ``tolerancing`` field)."""
        return {"task": list(self.task),
                "measurements": {"kind": self.measurement_kind, "targets_mm": [list(t) for t in self.targets_mm],
                                 "noise_mm": self.noise_mm, "noise_rad": self.noise_rad, "frame": self.frame,
                                 "offsets": self.offsets, "poses": self.poses},
                "spec": {"position_mm": self.position_mm, "orientation_rad": self.orientation_rad},
                "clearances": {"R": _declared_form(self.clearance("", "R")), "P": _declared_form(self.clearance("", "P")),
                               "joints": dict(self.clearances.get("joints", {}))},
                "workspace_loss": self.workspace_loss, "declared": list(self.declared)}


def _number(value, where: str, positive: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{where} must be a number, got {value!r}.") from None
    if not np.isfinite(v) or v < 0 or (positive and v == 0):
        raise ModelError(f"{where} must be a {'positive' if positive else 'non-negative'} number, got {value!r}.")
    return v


def parse_declaration(doc: dict | None, source: str = "model") -> Declaration:
    """Check and complete a declaration; errors name ``source`` and the field.

    Raises
    ------
    ModelError
        On an unknown task component, measurement kind or clearance key, or a bad number.
    """
    doc = dict(doc or {})
    declared = tuple(k for k in ("task", "measurements", "spec", "clearances", "workspace_loss") if k in doc)
    unknown = [k for k in doc if k not in ("task", "measurements", "spec", "clearances", "workspace_loss", "declared")]
    if unknown:
        raise ModelError(f"{source}: tolerancing field '{unknown[0]}' is not part of the format "
                         "(task, measurements, spec, clearances, workspace_loss).")
    kw: dict = {"declared": declared}
    if "workspace_loss" in doc:
        kw["workspace_loss"] = check_workspace_loss(doc["workspace_loss"], f"{source}: tolerancing.workspace_loss")
    if "task" in doc:
        task = doc["task"]
        if isinstance(task, str) or not task:
            raise ModelError(f"{source}: tolerancing.task must be a non-empty list of components "
                             f"({', '.join(TASK_COMPONENTS)}).")
        for t in task:
            if t not in TASK_COMPONENTS:
                raise ModelError(f"{source}: tolerancing.task component '{t}' is unknown; use "
                                 f"{', '.join(TASK_COMPONENTS)}.")
        kw["task"] = tuple(task)
    meas = doc.get("measurements") or {}
    if meas:
        kind = meas.get("kind", "positions")
        if kind not in ("positions", "poses"):
            raise ModelError(f"{source}: tolerancing.measurements.kind must be 'positions' or 'poses', got {kind!r}.")
        kw["measurement_kind"] = kind
        if "targets_mm" in meas:
            targets = np.asarray(meas["targets_mm"], dtype=float)
            if targets.ndim != 2 or targets.shape[1] != 3 or not len(targets):
                raise ModelError(f"{source}: tolerancing.measurements.targets_mm must be a list of [x, y, z] (mm).")
            kw["targets_mm"] = tuple(tuple(float(v) for v in t) for t in targets)
        frame = meas.get("frame", "registered")
        if frame not in ("registered", "unknown"):
            raise ModelError(f"{source}: tolerancing.measurements.frame must be 'registered' or 'unknown', got {frame!r}.")
        kw["frame"] = frame
        offsets = meas.get("offsets", "known")
        if offsets not in ("known", "unknown"):
            raise ModelError(f"{source}: tolerancing.measurements.offsets must be 'known' or 'unknown', got {offsets!r}.")
        kw["offsets"] = offsets
        if "poses" in meas:
            poses = meas["poses"]
            if not isinstance(poses, int) or isinstance(poses, bool) or poses < 1:
                raise ModelError(f"{source}: tolerancing.measurements.poses must be a positive integer, got {poses!r}.")
            kw["poses"] = poses
        for key in ("noise_mm", "noise_rad"):
            if key in meas:
                kw[key] = _number(meas[key], f"{source}: tolerancing.measurements.{key}")
    spec = doc.get("spec") or {}
    for key in ("position_mm", "orientation_rad"):
        if key in spec:
            kw[key] = None if spec[key] is None else _number(spec[key], f"{source}: tolerancing.spec.{key}", True)
    clear = doc.get("clearances") or {}
    out_clear: dict = {}
    for kind, entry in clear.items():
        if kind == "joints":
            out_clear["joints"] = {str(j): _clearance_entry(e, f"{source}: tolerancing.clearances.joints.{j}")
                                   for j, e in dict(entry).items()}
        elif kind in ("R", "P"):
            out_clear[kind] = _clearance_entry(entry, f"{source}: tolerancing.clearances.{kind}")
        else:
            raise ModelError(f"{source}: tolerancing.clearances key '{kind}' must be 'R', 'P' or 'joints'.")
    kw["clearances"] = out_clear
    return Declaration(**kw)


def check_workspace_loss(value, where: str) -> float:
    """A workspace-loss budget: a fraction strictly between 0 and 1 (0.001 = 0.1 %); ``where`` names it in the error.

    >>> check_workspace_loss(0.002, "--workspace-loss")
    0.002
    """
    v = _number(value, where, positive=True)
    if not v < 1.0:
        raise ModelError(f"{where} must be a fraction below 1 (0.001 = 0.1 % of an actuator's range), got {value!r}.")
    return v


def _clearance_entry(entry, where: str) -> dict:
    keys = ", ".join(_CLEARANCE_KEYS + _CLEARANCE_WORDS)
    if not isinstance(entry, dict):
        raise ModelError(f"{where} must be an object with {keys} and source.")
    out = {}
    for k, v in entry.items():
        if k == "source":
            out[k] = str(v)
        elif k == "side":
            if v not in ("fixed", "moving"):
                raise ModelError(f"{where}.side must be 'fixed' or 'moving', got {v!r}.")
            out[k] = v
        elif k == "centre_mm":
            try:
                out[k] = float(v)
            except (TypeError, ValueError):
                raise ModelError(f"{where}.centre_mm must be a number, got {v!r}.") from None
            if not np.isfinite(out[k]):
                raise ModelError(f"{where}.centre_mm must be a finite number, got {v!r}.")
        elif k in _CLEARANCE_KEYS:
            out[k] = _number(v, f"{where}.{k}", positive=k == "span_mm")
        else:
            raise ModelError(f"{where}: key '{k}' is unknown; use {keys} and source.")
    if "tilt_rad" in out and "span_mm" in out and "radial_mm" in out:
        implied = 2.0 * out["radial_mm"] / out["span_mm"]
        if abs(implied - out["tilt_rad"]) > 1e-9 * max(implied, out["tilt_rad"], 1e-300):
            raise ModelError(f"{where}: tilt_rad {out['tilt_rad']:g} disagrees with 2 radial_mm / span_mm = "
                             f"{implied:g}; give one of tilt_rad and span_mm.")
    return out


def _declared_form(c: dict) -> dict:
    """A resolved clearance as the model file writes it (JSON has no infinity: an infinite span is left out)."""
    return {k: v for k, v in c.items() if not (k == "span_mm" and not np.isfinite(v))}


def declaration_of(mechanism) -> Declaration:
    """The declaration a mechanism carries (``metadata["tolerancing"]``), defaults otherwise."""
    return parse_declaration(mechanism.metadata.get("tolerancing"), mechanism.name)


def task_rows(task: tuple, output_pose: np.ndarray) -> np.ndarray:
    """Selection rows of the task components applied to output twists ``(omega, v)``.

    Parameters
    ----------
    task : tuple of str
        Components from :data:`TASK_COMPONENTS`.
    output_pose : ndarray, (K, 4, 4)
        Output frame per configuration (the tool axis is its z column).

    Returns
    -------
    ndarray, (K, r, 6)
        Rows selecting the task components; ``r`` counts them (``tool-axis`` gives the two
        rotations perpendicular to the output z axis).  Rotation rows come first.
    """
    k = output_pose.shape[0]
    rot, pos = [], []
    eye = np.eye(3)
    for t in task:
        if t == "orientation":
            rot += [np.broadcast_to(eye[i], (k, 3)) for i in range(3)]
        elif t == "tool-axis":
            rot += [output_pose[:, :3, 0], output_pose[:, :3, 1]]
        elif t in ("rx", "ry", "rz"):
            rot.append(np.broadcast_to(eye["xyz".index(t[1])], (k, 3)))
        elif t == "position":
            pos += [np.broadcast_to(eye[i], (k, 3)) for i in range(3)]
        else:
            pos.append(np.broadcast_to(eye["xyz".index(t)], (k, 3)))
    rows = np.zeros((k, len(rot) + len(pos), 6))
    for i, r in enumerate(rot):
        rows[:, i, :3] = r
    for i, r in enumerate(pos):
        rows[:, len(rot) + i, 3:] = r
    return rows


def n_rotation_rows(task: tuple) -> int:
    """Number of rotation rows :func:`task_rows` puts first."""
    return sum(3 if t == "orientation" else 2 if t == "tool-axis" else 1 if t.startswith("r") else 0 for t in task)
