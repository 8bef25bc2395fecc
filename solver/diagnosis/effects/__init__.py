"""Library of unmodelled effects that extend the rigid geometric model (issue: sim-to-real gap).

Units: lengths in mm, angles in rad, temperatures in degC, masses in kg, forces in N.

Names used in every output: ``compliance``, ``violated-constraint``, ``thermal``,
``screw-pitch``, ``screw-periodic``, ``backlash``, ``tracker-scale``, ``tracker-drift``.
"""

from __future__ import annotations

from hyperstat.solver.errors import DataError
from hyperstat.solver.diagnosis.effects.actuator import Backlash, Compliance, ScrewPeriodic, ScrewPitch
from hyperstat.solver.diagnosis.effects.base import Effect
from hyperstat.solver.diagnosis.effects.other import Thermal, TrackerDrift, TrackerScale, ViolatedConstraint

__all__ = ["Effect", "Backlash", "Compliance", "ScrewPeriodic", "ScrewPitch", "Thermal", "TrackerDrift",
           "TrackerScale", "ViolatedConstraint", "EFFECT_NAMES", "make_effect", "applicable_effects"]

EFFECT_NAMES = ("compliance", "violated-constraint", "thermal", "screw-pitch", "screw-periodic", "backlash",
                "tracker-scale", "tracker-drift")


def make_effect(name: str, mechanism, analysis=None, data=None, **options) -> Effect:
    """Build effect ``name`` for a mechanism (and the sessions of ``data`` for ``tracker-drift``).

    Raises
    ------
    DataError
        For an unknown name or an effect the mechanism or data cannot have.
    """
    if name == "compliance":
        return Compliance(mechanism, **options)
    if name == "violated-constraint":
        return ViolatedConstraint(mechanism, analysis, **options)
    if name == "thermal":
        return Thermal(mechanism, **options)
    if name == "screw-pitch":
        return ScrewPitch(mechanism, **options)
    if name == "screw-periodic":
        return ScrewPeriodic(mechanism, **options)
    if name == "backlash":
        return Backlash(mechanism, **options)
    if name == "tracker-scale":
        return TrackerScale(mechanism, **options)
    if name == "tracker-drift":
        sessions = options.pop("sessions", None)
        if sessions is None and data is not None and "session" in data.metadata:
            sessions = sorted(set(data.metadata["session"].tolist()))
        return TrackerDrift(mechanism, sessions, **options)
    raise DataError(f"unknown effect '{name}'; effects are {', '.join(EFFECT_NAMES)}.")


def applicable_effects(mechanism, analysis, data) -> dict:
    """Effect name -> reason it cannot be fitted on ``data`` (absent when it can)."""
    reasons = {}
    if not any(mechanism.joints[i].type == "P" for i in mechanism.actuated):
        reasons["screw-pitch"] = reasons["screw-periodic"] = "no prismatic (screw-driven) actuator"
    if not any(p.verdict == "forced" for p in analysis.parameters):
        reasons["violated-constraint"] = "the mechanism has no forced defect (not over-constrained)"
    if "temperature" not in data.metadata or len(set(data.metadata["temperature"].tolist())) < 2:
        reasons["thermal"] = "no varying 'temperature[degC]' column in the data"
    if not all(f"dir{mechanism.joints[i].name}" in data.metadata for i in mechanism.actuated):
        reasons["backlash"] = "no approach-direction columns 'dir<joint>' in the data"
    if "session" not in data.metadata or len(set(data.metadata["session"].tolist())) < 2:
        reasons["tracker-drift"] = "fewer than two measurement sessions in the 'session' column"
    return reasons
