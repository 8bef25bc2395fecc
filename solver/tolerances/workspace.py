"""The workspace a machine is used over: joint ranges, actuated and passive.

Units: joint values in mm (prismatic) and rad (revolute).

Paper 2 (Simas & Di Gregorio, section 5.3) evaluates the accuracy coefficients "inside the
whole workspace": for the Triflex-II the intersection of three cylinders reached with the
elbows ``theta3`` and ``theta7`` kept in ``[0, pi]`` (one assembly branch).  A template
declares such a workspace with a function ``workspace(p)`` returning

    {"ranges": {"1": (lo, hi), "3": (lo, hi), ...}, "note": "where the ranges come from"}

(joint name -> range in the model's joint coordinates, mm or rad); the template loader
stores it in the mechanism's ``metadata["workspace"]`` (and the model file keeps it).
Actuated ranges bound the sampling box; passive ranges select the assembly branch (a
configuration with a passive joint outside its range is not in the workspace).  The
reachable set itself is not declared: a sample that does not assemble is not in it.

Revolute ranges are compared modulo 2 pi (a joint at ``theta + 2 pi`` is at ``theta``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.errors import HyperstatError
from hyperstat.solver.kinematics.model import Mechanism

__all__ = ["Workspace", "workspace_of", "check_declaration"]


@dataclass
class Workspace:
    """Bounds of every joint over the workspace.

    Attributes
    ----------
    lower, upper : ndarray, (n_q,)
        Bounds per joint (mm / rad), the model's joint ranges unless declared or given.
    declared : dict
        Joint name -> (lo, hi) of the template's declaration and the command line.
    passive_declared : ndarray of bool, (n_q,)
        Passive joints whose range is declared (they select the assembly branch).
    source : str
        Where the ranges come from, in words.
    """

    lower: np.ndarray
    upper: np.ndarray
    declared: dict = field(default_factory=dict)
    passive_declared: np.ndarray | None = None
    source: str = ""
    revolute: np.ndarray | None = None

    def actuated_box(self, mechanism: Mechanism) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the actuated joints (mm / rad)."""
        act = mechanism.actuated
        return self.lower[act].copy(), self.upper[act].copy()

    def wrapped(self, q: np.ndarray) -> np.ndarray:
        """``q`` with every revolute joint whose range is at most 2 pi wide moved by a multiple of 2 pi to the
        smallest value >= its lower bound (so that a range check is a check modulo 2 pi)."""
        q = np.array(q, dtype=float, copy=True)
        rev = self.revolute
        if rev is not None:
            rev = rev & (self.upper - self.lower <= 2 * math.pi + 1e-12)  # a wider range holds every angle already
        if rev is not None and rev.any():
            lo = self.lower[rev]
            q[..., rev] = lo + np.mod(q[..., rev] - lo, 2 * math.pi)
        return q

    def inside(self, q: np.ndarray, passive_only: bool = True, slack: float = 1e-9) -> np.ndarray:
        """Whether configurations ``q`` (K, n_q) keep the declared passive joints (or all joints) in range."""
        q = np.atleast_2d(q)
        sel = self.passive_declared if passive_only else np.ones(len(self.lower), dtype=bool)
        if sel is None or not sel.any():
            return np.ones(len(q), dtype=bool)
        w = self.wrapped(q)
        return np.all((w[:, sel] >= self.lower[sel] - slack) & (w[:, sel] <= self.upper[sel] + slack), axis=1)


def check_declaration(mechanism: Mechanism, declaration: dict, where: str) -> dict:
    """Validate a workspace declaration against a mechanism; return ``{joint: (lo, hi)}``.

    Raises
    ------
    HyperstatError
        One sentence naming ``where``, the joint and the value when the declaration is not
        a mapping ``{"ranges": {joint: (lo, hi)}}`` of known joints with finite ``lo < hi``.
    """
    if not isinstance(declaration, dict) or not isinstance(declaration.get("ranges"), dict):
        raise HyperstatError(f"{where}: the workspace must be a dict with a 'ranges' dict (joint -> (lo, hi)).")
    names = {j.name for j in mechanism.joints}
    out = {}
    for name, rng in declaration["ranges"].items():
        name = str(name)
        if name not in names:
            raise HyperstatError(f"{where}: workspace range for '{name}', which is not a joint of "
                                 f"'{mechanism.name}' ({', '.join(sorted(names))}).")
        try:
            lo, hi = (float(v) for v in rng)
        except (TypeError, ValueError):
            raise HyperstatError(f"{where}: workspace range of joint '{name}' must be two numbers (lo, hi), "
                                 f"got {rng!r}.") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise HyperstatError(f"{where}: workspace range of joint '{name}' must have finite lo < hi, "
                                 f"got ({lo:g}, {hi:g}).")
        out[name] = (lo, hi)
    return out


def workspace_of(mechanism: Mechanism, ranges: dict | None = None) -> Workspace:
    """The workspace of a mechanism: model ranges, then its declaration, then ``ranges``.

    Parameters
    ----------
    mechanism : Mechanism
        Its ``metadata["workspace"]`` (from the template) is used when present.
    ranges : dict, optional
        Joint name -> (lo, hi) overriding both (e.g. ``--range`` on the command line).

    Examples
    --------
    >>> from hyperstat.cad_plugin.templates import build_template, TEMPLATE_DIR
    >>> mech = build_template(TEMPLATE_DIR / "triflex_ii.py").mechanism()
    >>> ws = workspace_of(mech)
    >>> round(float(ws.upper[mech.joint_index["1"]]), 6)  # a6 + a7 = 72/47 l.u.
    1.531915
    """
    lower = mechanism.ranges[:, 0].astype(float).copy()
    upper = mechanism.ranges[:, 1].astype(float).copy()
    declared: dict = {}
    sources = []
    meta = mechanism.metadata.get("workspace") if isinstance(mechanism.metadata, dict) else None
    if meta:
        declared.update(check_declaration(mechanism, meta, f"workspace of '{mechanism.name}'"))
        sources.append(str(meta.get("note") or "declared by the template"))
    if ranges:
        declared.update(check_declaration(mechanism, {"ranges": dict(ranges)}, "--range"))
        sources.append("ranges given on the command line: " + ", ".join(sorted(ranges)))
    for name, (lo, hi) in declared.items():
        i = mechanism.joint_index[name]
        lower[i], upper[i] = lo, hi
    passive = np.zeros(len(lower), dtype=bool)
    for name in declared:
        i = mechanism.joint_index[name]
        passive[i] = i in set(int(a) for a in mechanism.passive)
    revolute = np.array([j.type == "R" for j in mechanism.joints])
    return Workspace(lower, upper, declared, passive, "; ".join(sources) or "the model's joint ranges", revolute)
