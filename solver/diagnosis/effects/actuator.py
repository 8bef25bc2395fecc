"""Effects in the actuated joints: screw pitch, screw periodic error, backlash, compliance.

Units: lengths in mm, angles in rad, masses in kg, forces in N, compliances in mm/N
(prismatic) or rad/(N mm) (revolute).
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.errors import DataError
from hyperstat.solver.diagnosis.effects.base import Effect

__all__ = ["ScrewPitch", "ScrewPeriodic", "Backlash", "Compliance"]

GRAVITY = 9.81  # m/s^2


def _actuators(mechanism, prismatic_only: bool = False) -> list[tuple[int, object]]:
    out = [(a, mechanism.joints[i]) for a, i in enumerate(mechanism.actuated)]
    return [(a, j) for a, j in out if j.type == "P"] if prismatic_only else out


class ScrewPitch(Effect):
    """Lead-screw pitch error: the travel is ``(1 + s_j) q_j`` (``s`` dimensionless, realistic 4e-4: a rolled ball screw class C10, 210 um per 300 mm, is 7e-4)."""

    name = "screw-pitch"

    def __init__(self, mechanism, magnitude: float = 4e-4) -> None:
        self.axes = [a for a, _ in _actuators(mechanism, prismatic_only=True)]
        names = [f"pitch_{j.name}" for _, j in _actuators(mechanism, prismatic_only=True)]
        super().__init__(names, ["1"] * len(names), [magnitude] * len(names))

    def actuator_correction(self, model, theta, data):
        k, na = data.q.shape
        dq = np.zeros((k, na))
        dt = np.zeros((k, na, len(self.axes)))
        for e, a in enumerate(self.axes):
            dq[:, a] = theta[e] * data.q[:, a]
            dt[:, a, e] = data.q[:, a]
        return dq, dt


class ScrewPeriodic(Effect):
    """Periodic lead-screw error over each screw lead: ``a_j sin(2 pi q / lead) + b_j cos(2 pi q / lead)`` (mm)."""

    name = "screw-periodic"

    def __init__(self, mechanism, lead: float | None = None, magnitude: float = 0.01) -> None:
        self.lead = float(lead or mechanism.metadata.get("screw_lead", 10.0))
        acts = _actuators(mechanism, prismatic_only=True)
        self.axes = [a for a, _ in acts]
        names = [f"periodic_{j.name}_{t}" for _, j in acts for t in ("sin", "cos")]
        super().__init__(names, ["mm"] * len(names), [magnitude] * len(names))

    def actuator_correction(self, model, theta, data):
        k, na = data.q.shape
        dq = np.zeros((k, na))
        dt = np.zeros((k, na, 2 * len(self.axes)))
        for e, a in enumerate(self.axes):
            phase = 2.0 * np.pi * data.q[:, a] / self.lead
            s, c = np.sin(phase), np.cos(phase)
            dq[:, a] = theta[2 * e] * s + theta[2 * e + 1] * c
            dt[:, a, 2 * e] = s
            dt[:, a, 2 * e + 1] = c
        return dq, dt


class Backlash(Effect):
    """Backlash of each actuator: ``dq_j = beta_j / 2 * dir_j`` with the approach direction ``dir_j = +-1``.

    Realistic ``beta``: 0.02 mm (prismatic), 1e-4 rad (revolute).
    """

    name = "backlash"
    requires = ("dir*",)

    def __init__(self, mechanism, magnitude_mm: float = 0.03, magnitude_rad: float = 1.5e-4) -> None:
        acts = _actuators(mechanism)
        self.columns = [f"dir{j.name}" for _, j in acts]
        names = [f"backlash_{j.name}" for _, j in acts]
        units = ["mm" if j.type == "P" else "rad" for _, j in acts]
        super().__init__(names, units, [magnitude_mm if u == "mm" else magnitude_rad for u in units])

    def applicable(self, data) -> bool:
        """Whether ``data`` records every approach direction."""
        return all(c in data.metadata for c in self.columns)

    def actuator_correction(self, model, theta, data):
        if not self.applicable(data):
            missing = [c for c in self.columns if c not in data.metadata]
            raise DataError(f"{data.source}: the backlash effect needs the column(s) {', '.join(missing)}.")
        k, na = data.q.shape
        dt = np.zeros((k, na, na))
        for a, col in enumerate(self.columns):
            dt[:, a, a] = 0.5 * data.metadata[col]
        return np.einsum("kae,e->ka", dt, theta), dt


class Compliance(Effect):
    """Elastostatic compliance of the actuated joints (legs) under gravity and a payload.

    The weight ``F = (m_moving + payload) g`` acts at the output frame's centre of mass
    (``mechanism.metadata['com']`` in the output frame, default its origin) along
    ``mechanism.metadata['gravity']`` (default ``-z`` of the base).  The actuators carry
    ``tau = K_a^T W`` (static duality with the output twist per unit actuator ``K_a`` of the
    nominal model, ``W = (c x F, F)``), and yield ``dq_j = c_j tau_j``: one compliance per
    actuated joint (mm/N or rad/(N mm); realistic 1e-4 mm/N, a 10 N/um leg).
    """

    name = "compliance"
    requires = ()  # the 'payload[kg]' column adds to the moving mass when present

    def __init__(self, mechanism, magnitude_mm: float = 1e-4, magnitude_rad: float = 2e-9) -> None:
        acts = _actuators(mechanism)
        names = [f"compliance_{j.name}" for _, j in acts]
        units = ["mm/N" if j.type == "P" else "rad/(N mm)" for _, j in acts]
        super().__init__(names, units, [magnitude_mm if j.type == "P" else magnitude_rad for _, j in acts])
        self.moving_mass = float(mechanism.metadata.get("moving_mass", 50.0))
        self.gravity = np.asarray(mechanism.metadata.get("gravity", (0.0, 0.0, -1.0)), dtype=float)
        self.com = np.asarray(mechanism.metadata.get("com", (0.0, 0.0, 0.0)), dtype=float)
        self._cache: dict = {}

    def actuator_loads(self, model, data) -> np.ndarray:
        """Actuator loads ``tau`` (N or N mm) at the poses of ``data`` on the nominal model, (K, n_act)."""
        key = (id(data), len(data), data.q.tobytes()[:64])
        if key in self._cache:
            return self._cache[key]
        kin = model.kin
        res = kin.solve(data.q)
        st = kin.evaluate(res.q, None, jacobians=True)
        k_a = model.actuation_twists(st)
        payload = data.metadata.get("payload", np.zeros(len(data)))
        force = (self.moving_mass + payload)[:, None] * GRAVITY * self.gravity / np.linalg.norm(self.gravity)
        arm = np.einsum("kij,j->ki", st.output_pose[:, :3, :3], self.com)
        wrench = np.concatenate([np.cross(arm, force), force], axis=1)  # (moment, force) at the output origin
        tau = np.einsum("kia,ki->ka", k_a, wrench)
        self._cache = {key: tau}
        return tau

    def actuator_correction(self, model, theta, data):
        tau = self.actuator_loads(model, data)
        k, na = tau.shape
        dt = np.zeros((k, na, na))
        idx = np.arange(na)
        dt[:, idx, idx] = tau
        return tau * theta[None, :], dt
