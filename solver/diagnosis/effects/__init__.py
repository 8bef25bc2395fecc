"""Library of unmodelled effects that extend the rigid geometric model (issue: sim-to-real gap).

Units: lengths in mm, angles in rad, temperatures in degC, masses in kg, forces in N.

Names used in every output: ``compliance``, ``link-bending``, ``violated-constraint``,
``thermal``, ``screw-pitch``, ``screw-periodic``, ``angle-scale``, ``angle-harmonic-<k>``
(``k`` cycles per revolution: 1 and 2 always tried, other orders from the residual
spectrum), ``backlash``, ``backlash-gravity``, ``tracker-scale``, ``tracker-drift``, the
effects of a machine's structure and legs (:mod:`.structure`, :class:`LegThermal`):
``leg-thermal``, ``guide-straightness``, ``joint-clearance``, ``base-deformation``, and
the names of user-defined effects registered in the entry-point group
``hyperstat.effects`` (see :func:`plugin_effects` and ``docs/diagnosis.md``).  Magnitude
priors and their sources: :mod:`.priors`.
"""

from __future__ import annotations

from hyperstat.solver.errors import DataError
from hyperstat.solver.diagnosis.effects.actuator import (JOINTWISE, MASS_FIELD, MASS_FIELD_SHORT, AngleHarmonic, AngleScale,
                                                         Backlash, Compliance, GravityBacklash, LegThermal, LinkBending,
                                                         ScrewPeriodic, ScrewPitch, gravity_loads, gravity_moment,
                                                         gravity_regressor, gravity_source, harmonic_name, screw_lead)
from hyperstat.solver.diagnosis.effects.base import Effect
from hyperstat.solver.diagnosis.effects.other import Thermal, TrackerDrift, TrackerScale, ViolatedConstraint
from hyperstat.solver.diagnosis.effects.structure import BaseDeformation, GuideStraightness, JointClearance

__all__ = ["Effect", "AngleHarmonic", "AngleScale", "Backlash", "Compliance", "GravityBacklash", "LinkBending",
           "ScrewPeriodic", "ScrewPitch", "Thermal", "TrackerDrift", "TrackerScale", "ViolatedConstraint",
           "LegThermal", "GuideStraightness", "JointClearance", "BaseDeformation", "JOINTWISE", "gravity_moment",
           "is_jointwise",
           "EFFECT_NAMES", "GRAVITY_EFFECTS", "ENTRY_POINT_GROUP", "MASS_FIELD", "MASS_FIELD_SHORT", "available_effects", "make_effect",
           "applicable_effects", "plugin_effects", "gravity_loads", "gravity_regressor", "gravity_source",
           "harmonic_name", "harmonic_order", "is_known_effect", "is_library_effect", "screw_lead"]

EFFECT_NAMES = ("compliance", "link-bending", "violated-constraint", "thermal", "screw-pitch", "screw-periodic",
                "angle-scale", "angle-harmonic-1", "angle-harmonic-2", "backlash", "backlash-gravity",
                "tracker-scale", "tracker-drift", "leg-thermal", "guide-straightness", "joint-clearance",
                "base-deformation")
#: effects driven by the gravity loads: they need declared masses (``cannot_size`` otherwise)
GRAVITY_EFFECTS = ("compliance", "link-bending", "backlash-gravity", "joint-clearance", "base-deformation")
ENTRY_POINT_GROUP = "hyperstat.effects"


def harmonic_order(name: str) -> float | None:
    """The order ``k`` of an ``angle-harmonic-<k>`` name (None for any other name).

    >>> harmonic_order("angle-harmonic-2.75"), harmonic_order("compliance")
    (2.75, None)
    """
    if not name.startswith("angle-harmonic-"):
        return None
    try:
        k = float(name[len("angle-harmonic-"):])
    except ValueError:
        return None
    return k if k > 0 and k == k and k != float("inf") else None


def is_jointwise(name: str) -> bool:
    """Whether a library effect has its own parameters per actuated joint (tried joint by joint, ``joints`` option).

    >>> is_jointwise("angle-harmonic-1.5"), is_jointwise("compliance")
    (True, False)
    """
    return name in JOINTWISE or harmonic_order(name) is not None


def is_library_effect(name: str) -> bool:
    """Whether ``name`` is an effect of the library (any ``angle-harmonic-<k>`` included), not a plug-in."""
    return name in EFFECT_NAMES or harmonic_order(name) is not None


def is_known_effect(name: str) -> bool:
    """Whether ``name`` is a library effect (any ``angle-harmonic-<k>`` included) or a plug-in."""
    return is_library_effect(name) or name in plugin_effects()


def plugin_effects() -> dict:
    """User-defined effects: name -> factory, from the entry-point group ``hyperstat.effects``.

    An entry point names a callable ``factory(mechanism, analysis, data, **options) -> Effect``
    (an :class:`Effect` subclass is such a callable when its ``__init__`` takes those
    arguments).  A name that shadows a library effect is refused.

    Raises
    ------
    DataError
        If a plug-in cannot be loaded or reuses a library name.
    """
    from importlib.metadata import entry_points

    found = {}
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name in EFFECT_NAMES:
            raise DataError(f"entry point '{ep.value}' in group {ENTRY_POINT_GROUP} reuses the library effect "
                            f"name '{ep.name}'; give it another name.")
        try:
            found[ep.name] = ep.load()
        except Exception as exc:  # a broken plug-in must say which one
            raise DataError(f"the effect plug-in '{ep.name}' ({ep.value}) cannot be loaded: "
                            f"{type(exc).__name__}: {exc}") from exc
    return found


def available_effects() -> tuple:
    """Library effect names followed by the plug-in names (:func:`plugin_effects`)."""
    return EFFECT_NAMES + tuple(sorted(plugin_effects()))


def make_effect(name: str, mechanism, analysis=None, data=None, **options) -> Effect:
    """Build effect ``name`` for a mechanism (and the sessions of ``data`` for ``tracker-drift``).

    Raises
    ------
    DataError
        For an unknown name or an effect the mechanism or data cannot have.
    """
    if name == "compliance":
        return Compliance(mechanism, **options)
    if name == "link-bending":
        return LinkBending(mechanism, **options)
    if name == "violated-constraint":
        return ViolatedConstraint(mechanism, analysis, **options)
    if name == "thermal":
        return Thermal(mechanism, **options)
    if name == "screw-pitch":
        return ScrewPitch(mechanism, **options)
    if name == "screw-periodic":
        return ScrewPeriodic(mechanism, **options)
    if name == "angle-scale":
        return AngleScale(mechanism, **options)
    if harmonic_order(name) is not None:
        return AngleHarmonic(mechanism, cycles=harmonic_order(name), **options)
    if name == "backlash":
        return Backlash(mechanism, **options)
    if name == "backlash-gravity":
        return GravityBacklash(mechanism, **options)
    if name == "tracker-scale":
        return TrackerScale(mechanism, **options)
    if name == "leg-thermal":
        return LegThermal(mechanism, **options)
    if name == "guide-straightness":
        return GuideStraightness(mechanism, **options)
    if name == "joint-clearance":
        return JointClearance(mechanism, **options)
    if name == "base-deformation":
        return BaseDeformation(mechanism, **options)
    if name == "tracker-drift":
        sessions = options.pop("sessions", None)
        if sessions is None and data is not None and "session" in data.metadata:
            sessions = sorted(set(data.metadata["session"].tolist()))
        return TrackerDrift(mechanism, sessions, **options)
    plugins = plugin_effects()
    if name in plugins:
        try:
            effect = plugins[name](mechanism, analysis, data, **options)
        except DataError:
            raise
        except Exception as exc:  # a plug-in that fails says so in one sentence, never a traceback
            raise DataError(f"the effect plug-in '{name}' failed when built for '{mechanism.name}': "
                            f"{type(exc).__name__}: {exc}") from exc
        if not isinstance(effect, Effect):
            raise DataError(f"the effect plug-in '{name}' returned {type(effect).__name__}, not an Effect.")
        effect.name = name
        return effect
    raise DataError(f"unknown effect '{name}'; effects are {', '.join(EFFECT_NAMES + tuple(sorted(plugins)))}.")


def applicable_effects(mechanism, analysis, data) -> dict:
    """Effect name -> reason it cannot be fitted on ``data`` (absent when it can)."""
    reasons = {}
    if not any(mechanism.joints[i].type == "P" for i in mechanism.actuated):
        for name in ("screw-pitch", "screw-periodic", "leg-thermal", "guide-straightness", "joint-clearance"):
            reasons[name] = "no prismatic (screw-driven) actuator"
    if len(mechanism.chains) == 1 or not mechanism.closures:
        reasons.setdefault("joint-clearance", "the clearance of the platform joints needs a parallel mechanism (legs)")
        reasons.setdefault("leg-thermal", "the thermal growth of legs needs a parallel mechanism (legs); a serial "
                                          "axis's growth is 'thermal' or 'screw-pitch'")
    if not any(mechanism.joints[i].type == "R" for i in mechanism.actuated):
        reasons["angle-scale"] = reasons["angle-harmonic-1"] = reasons["angle-harmonic-2"] = "no revolute actuator"
    if len(mechanism.chains) != 1:
        reasons["link-bending"] = "link bending between parallel joints is modelled on serial chains only"
    if not any(p.verdict == "forced" for p in analysis.parameters):
        reasons["violated-constraint"] = "the mechanism has no forced defect (not over-constrained)"
    if "temperature" not in data.metadata or len(set(data.metadata["temperature"].tolist())) < 2:
        reasons["thermal"] = "no varying 'temperature[degC]' column in the data"
        reasons.setdefault("leg-thermal", reasons["thermal"])
    if not all(f"dir{mechanism.joints[i].name}" in data.metadata for i in mechanism.actuated):
        reasons["backlash"] = "no approach-direction columns 'dir<joint>' in the data"
    if mechanism.metadata.get("masses") and len(mechanism.chains) != 1:
        for name in ("compliance", "backlash-gravity", "joint-clearance", "base-deformation"):
            reasons[name] = "link masses are declared, but distributed masses are supported on serial mechanisms only"
    elif gravity_source(mechanism) is None:
        for name in GRAVITY_EFFECTS:
            reasons.setdefault(name, "cannot be sized: the model declares no mass (" + MASS_FIELD_SHORT + ")")
    if "session" not in data.metadata or len(set(data.metadata["session"].tolist())) < 2:
        reasons["tracker-drift"] = "fewer than two measurement sessions in the 'session' column"
    return reasons
