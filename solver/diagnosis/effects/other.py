"""Effects outside the actuators: thermal expansion, tracker scale and drift, violated forced defects.

Units: lengths in mm, angles in rad, temperatures in degC.
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.errors import DataError
from hyperstat.solver.diagnosis.effects.base import Effect

__all__ = ["Thermal", "TrackerScale", "TrackerDrift", "ViolatedConstraint", "deformation_twists"]


def deformation_twists(kin, q: np.ndarray, index: list) -> np.ndarray:
    """Output twist per unit defect ``index[e]`` at configurations ``q``, the machine closing its loops, (K, 6, n_e).

    The passive joints ``dq_p`` and an elastic deformation ``d`` of the defects (energy ``d^T W d``,
    rotations weighted by the squared length scale) close the loops, ``A (e + d) + B_p dq_p = 0``,
    with the least energy: ``d = -W^-1 (P A)^T [(P A) W^-1 (P A)^T]^+ P A e``, ``P = I - B_p B_p^+``
    (the motions the passive joints cannot absorb).  An admissible defect needs no deformation
    (``d = 0``, the passive joints absorb it: the twist is ``K_xi e``); a forced one deforms the
    machine.  On the nominal geometry (first order); a serial chain has no loop (``d = 0``,
    ``dq_p = 0``).
    """
    m = kin.mechanism
    st = kin.evaluate(q, None, jacobians=True)
    k, n_xi = len(q), len(m.parameters)
    unit = np.zeros((n_xi, len(index)))
    unit[list(index), np.arange(len(index))] = 1.0
    if st.closure_xi is None or not st.closure_xi.shape[1]:
        return st.output_xi @ unit
    passive = m.passive
    a = kin.scaled_rows(st.closure_xi)  # (K, 6L, n_xi)
    b = kin.scaled_rows(st.closure_q[:, :, passive])
    w_inv = 1.0 / np.array([kin.length_scale**2 if p.unit == "rad" else 1.0 for p in m.parameters])
    bpinv = np.linalg.pinv(b, rcond=1e-10)
    proj = np.eye(a.shape[1])[None] - b @ bpinv
    pa = proj @ a  # (K, 6L, n_xi)
    gram = np.einsum("kin,n,kjn->kij", pa, w_inv, pa)
    gap = pa[:, :, list(index)]  # P A e
    # pseudo-inverse with a cut relative to the closure's own scale (A W^-1 A^T), not to P A's: where the
    # passive joints absorb everything, P A is round-off and must give no deformation, not amplified noise
    size = np.einsum("kin,n,kin->k", a, w_inv, a)
    ev, vec = np.linalg.eigh(gram)
    inv = np.where(ev > 1e-12 * size[:, None], 1.0 / np.where(ev > 0, ev, 1.0), 0.0)
    lam = np.einsum("kij,kj,klj,kle->kie", vec, inv, vec, gap)
    d = -w_inv[None, :, None] * np.einsum("kin,kie->kne", pa, lam)  # (K, n_xi, n_e)
    total = d + unit[None]
    dq_p = -bpinv @ (a @ total)  # (K, n_p, n_e)
    return st.output_xi @ total + st.output_q[:, :, passive] @ dq_p


class Thermal(Effect):
    """Thermal expansion of the structure about the base origin: ``dp = kappa (T - T_ref) p`` (world frame).

    One global coefficient ``kappa`` (1/degC, realistic 1e-5 for a steel frame); the
    temperature comes from the ``temperature[degC]`` column, ``T_ref`` = 20 degC.
    """

    name = "thermal"
    requires = ("temperature",)
    reference = 20.0
    domain_note = ("a structural expansion coefficient lies between -2e-6 /degC (carbon fibre, Invar) and 3e-5 /degC "
                   "(aluminium 2.3e-5, magnesium 2.6e-5)")

    def __init__(self, mechanism, magnitude: float = 1e-5) -> None:
        super().__init__(["thermal_kappa"], ["1/degC"], [magnitude], lower=-2e-6, upper=3e-5, plausible=3e-5)

    def output_correction(self, model, theta, data, q, state, world, jacobian):
        if "temperature" not in data.metadata:
            raise DataError(f"{data.source}: the thermal effect needs the column 'temperature[degC]'.")
        dtemp = data.metadata["temperature"] - self.reference
        base = world * dtemp[:, None]
        return theta[0] * base, base[:, :, None]


class TrackerScale(Effect):
    """Scale error of the tracker's distance measurement: ``p' = (1 + s) p`` (tracker frame; realistic 1e-5)."""

    name = "tracker-scale"

    domain_note = "a laser tracker's scale error beyond 1e-4 (0.1 mm per metre) is a failed instrument"

    def __init__(self, mechanism, magnitude: float = 1e-5) -> None:
        super().__init__(["tracker_scale"], ["1"], [magnitude], plausible=1e-4)

    def measurement_correction(self, model, theta, data, position, jacobian):
        k = len(position)
        return (1.0 + theta[0]) * position, position[:, :, None], np.broadcast_to((1.0 + theta[0]) * np.eye(3), (k, 3, 3))


class TrackerDrift(Effect):
    """Tracker frame drift between measurement sessions: a translation per session after the first (mm).

    Realistic magnitude 0.02 mm; sessions from the ``session`` column.
    """

    name = "tracker-drift"
    requires = ("session",)

    def __init__(self, mechanism, sessions: list | None = None, magnitude: float = 0.03) -> None:
        self.sessions = sorted(float(s) for s in (sessions or []))
        later = self.sessions[1:]
        names = [f"drift_s{int(s) if float(s).is_integer() else s}_{a}" for s in later for a in "xyz"]
        super().__init__(names, ["mm"] * len(names), [magnitude] * len(names), plausible=1.0)

    domain_note = "a tracker moved by more than 1 mm between sessions was knocked, not drifting"

    def measurement_correction(self, model, theta, data, position, jacobian):
        if "session" not in data.metadata:
            raise DataError(f"{data.source}: the tracker-drift effect needs the column 'session'.")
        k = len(position)
        dt = np.zeros((k, 3, len(self._names)))
        for n, s in enumerate(self.sessions[1:]):
            rows = data.metadata["session"] == s
            for a in range(3):
                dt[rows, a, 3 * n + a] = 1.0
        return position + dt @ theta, dt, np.broadcast_to(np.eye(3), (k, 3, 3))


class ViolatedConstraint(Effect):
    """Forced defects that are not zero: the over-constrained machine assembles only by deforming.

    A forced defect ``xi_v`` opens the loop-closure gap ``A xi_v`` (eq. 3).  The machine
    closes it by elastic deformation of its joints and links, which we describe in the
    defect space itself (a small deformation at a joint is a small displacement of its
    frame): the deformation ``d`` and the passive joint motion ``dq_p`` minimise the elastic
    energy ``d^T W d`` subject to the closure ``A (xi_v + d) + B_p dq_p = 0``; ``W`` is uniform
    with rotations weighted by the squared length scale (``k_rot = k_lin L^2``).  With
    ``P = I - B_p B_p^+`` (motions the passive joints cannot absorb),
    ``d = -W^-1 (P A)^T [(P A) W^-1 (P A)^T]^+ P A xi_v``; the target then moves with the
    output twist ``O_xi (xi_v + d) + O_p dq_p``.  The model is first order in ``xi_v`` and
    evaluated on the nominal geometry.  Realistic magnitude 5e-4 rad or 0.05 mm.
    """

    name = "violated-constraint"

    def __init__(self, mechanism, analysis, only: list | None = None, magnitude_rad: float = 5e-4,
                 magnitude_mm: float = 0.05) -> None:
        if analysis is None:  # a controller file: the defects were checked when it was written
            if not only:
                raise DataError("the violated-constraint effect needs the stationarity analysis or the defect names.")
            forced = list(only)
        else:
            forced = [p.name for p in analysis.parameters if p.verdict == "forced"]
        if only is not None:
            unknown = [n for n in only if n not in forced]
            if unknown:
                raise DataError(f"{', '.join(unknown)} is not a forced defect of '{mechanism.name}'.")
            forced = [n for n in forced if n in only]
        self.defects = forced
        units = {p.name: p.unit for p in mechanism.parameters}
        self._index = [mechanism.parameter_index[n] for n in forced]
        self._cache: dict = {}
        super().__init__([f"violated_{n}" for n in forced], [units[n] for n in forced],
                         [magnitude_rad if units[n] == "rad" else magnitude_mm for n in forced],
                         plausible=[5e-2 if units[n] == "rad" else 2.5 for n in forced])

    domain_note = "a forced defect violated by more than 50 mrad or 2.5 mm would not assemble"

    def deformation_twists(self, model, q: np.ndarray) -> np.ndarray:
        """Output twist per unit violated defect after minimum-energy deformation, (K, 6, n_e)."""
        key = (q.shape, q.tobytes()[:256], float(q.sum()))
        if key in self._cache:
            return self._cache[key]
        twist = deformation_twists(model.kin, q, self._index)
        self._cache = {key: twist}
        return twist

    def output_correction(self, model, theta, data, q, state, world, jacobian):
        twist = self.deformation_twists(model, q)
        arm = world - state.output_pose[:, :3, 3]
        point = twist[:, 3:, :] + np.cross(twist[:, :3, :], arm[:, :, None], axis=1)
        return point @ theta, point
