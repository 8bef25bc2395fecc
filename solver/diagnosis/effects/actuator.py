"""Effects in the actuated joints: screw pitch and periodic error, angle scale and harmonics, backlash, compliance.

Units: lengths in mm, angles in rad, masses in kg, forces in N, compliances in mm/N
(prismatic) or rad/(N mm) (revolute).

Every effect states its physical domain (``lower``, ``upper``: a compliance or a backlash
is never negative) and a plausible magnitude (``plausible``); the diagnosis fits within
the domain and rejects a candidate whose data ask for a value outside it.
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.errors import DataError
from hyperstat.solver.diagnosis.effects.base import Effect

__all__ = ["ScrewPitch", "ScrewPeriodic", "AngleScale", "AngleHarmonic", "Backlash", "GravityBacklash", "Compliance",
           "LinkBendingAlternative",
           "gravity_loads"]

GRAVITY = 9.81  # m/s^2


def _actuators(mechanism, prismatic_only: bool = False, revolute_only: bool = False) -> list[tuple[int, object]]:
    out = [(a, mechanism.joints[i]) for a, i in enumerate(mechanism.actuated)]
    if prismatic_only:
        return [(a, j) for a, j in out if j.type == "P"]
    if revolute_only:
        return [(a, j) for a, j in out if j.type == "R"]
    return out


class ScrewPitch(Effect):
    """Lead-screw pitch error: the travel is ``(1 + s_j) q_j`` (``s`` dimensionless, realistic 4e-4: a rolled ball screw class C10, 210 um per 300 mm, is 7e-4)."""

    name = "screw-pitch"
    domain_note = "a lead error beyond 5e-3 (5 mm per metre) is no ball screw"

    def __init__(self, mechanism, magnitude: float = 4e-4) -> None:
        self.axes = [a for a, _ in _actuators(mechanism, prismatic_only=True)]
        names = [f"pitch_{j.name}" for _, j in _actuators(mechanism, prismatic_only=True)]
        super().__init__(names, ["1"] * len(names), [magnitude] * len(names), plausible=5e-3)

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
        super().__init__(names, ["mm"] * len(names), [magnitude] * len(names), plausible=0.1)

    domain_note = "a periodic lead error beyond 0.1 mm is no ball screw"

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
    """Backlash of each actuator: ``dq_j = -beta_j / 2 * dir_j``, ``beta_j >= 0``.

    ``dir_j = +-1`` is the direction of the actuator's last motion before the pose; the
    driven side lags behind the drive by half the clearance.  Realistic ``beta``:
    0.03 mm (prismatic), 1.5e-4 rad (revolute); plausible up to 20 times that.
    """

    name = "backlash"
    requires = ("dir*",)
    domain_note = "a clearance is never negative (beta >= 0), and above 0.6 mm or 3 mrad it is a loose joint"

    def __init__(self, mechanism, magnitude_mm: float = 0.03, magnitude_rad: float = 1.5e-4) -> None:
        acts = _actuators(mechanism)
        self.columns = [f"dir{j.name}" for _, j in acts]
        names = [f"backlash_{j.name}" for _, j in acts]
        units = ["mm" if j.type == "P" else "rad" for _, j in acts]
        mags = [magnitude_mm if u == "mm" else magnitude_rad for u in units]
        super().__init__(names, units, mags, lower=0.0, plausible=20.0 * np.asarray(mags))

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
            dt[:, a, a] = -0.5 * data.metadata[col]
        return np.einsum("kae,e->ka", dt, theta), dt


class AngleScale(Effect):
    """Transmission ratio error of each revolute actuator: the joint turns ``(1 + s_j) q_j``.

    The revolute counterpart of :class:`ScrewPitch` (a gear ratio or encoder scale error;
    ``s`` dimensionless, realistic 2e-4, plausible up to 5e-3).
    """

    name = "angle-scale"
    domain_note = "a ratio error beyond 5e-3 is a wrong gear ratio in the joint map, not a manufacturing error"

    def __init__(self, mechanism, magnitude: float = 2e-4) -> None:
        acts = _actuators(mechanism, revolute_only=True)
        self.axes = [a for a, _ in acts]
        names = [f"angle_scale_{j.name}" for _, j in acts]
        super().__init__(names, ["1"] * len(names), [magnitude] * len(names), plausible=5e-3)

    def actuator_correction(self, model, theta, data):
        k, na = data.q.shape
        dq = np.zeros((k, na))
        dt = np.zeros((k, na, len(self.axes)))
        for e, a in enumerate(self.axes):
            dq[:, a] = theta[e] * data.q[:, a]
            dt[:, a, e] = data.q[:, a]
        return dq, dt


class AngleHarmonic(Effect):
    """Periodic transmission error of each revolute actuator at ``h`` cycles per revolution of the joint.

    ``dq_j = a_j sin(h q_j) + b_j cos(h q_j)`` (rad), the harmonic joint-error model of
    serial robots (eccentricity of an output bearing or gear: ``h = 1``; ellipticity of a
    strain-wave flexspline: ``h = 2``).  Realistic amplitude 1e-4 rad (20 arcsec),
    plausible up to 2e-3 rad.
    """

    domain_note = "a periodic angle error beyond 2 mrad (7 arcmin) is a damaged transmission"

    def __init__(self, mechanism, cycles: int = 1, magnitude: float = 1e-4) -> None:
        self.cycles = int(cycles)
        self.name = f"angle-harmonic-{self.cycles}"
        acts = _actuators(mechanism, revolute_only=True)
        self.axes = [a for a, _ in acts]
        names = [f"harmonic{self.cycles}_{j.name}_{t}" for _, j in acts for t in ("sin", "cos")]
        super().__init__(names, ["rad"] * len(names), [magnitude] * len(names), plausible=2e-3)

    def actuator_correction(self, model, theta, data):
        k, na = data.q.shape
        dq = np.zeros((k, na))
        dt = np.zeros((k, na, 2 * len(self.axes)))
        for e, a in enumerate(self.axes):
            s, c = np.sin(self.cycles * data.q[:, a]), np.cos(self.cycles * data.q[:, a])
            dq[:, a] = theta[2 * e] * s + theta[2 * e + 1] * c
            dt[:, a, 2 * e] = s
            dt[:, a, 2 * e + 1] = c
        return dq, dt


def _declared_masses(mechanism) -> list[dict] | None:
    """Link masses declared in the model's metadata, ``{"masses": {joint: {"mass": kg, "com": [x, y, z]}}}``.

    ``com`` is the centre of mass of the body the joint moves (up to the next joint), in the
    base frame at the home configuration (mm), as CAD gives it.  Serial mechanisms only.
    """
    masses = mechanism.metadata.get("masses")
    if not masses:
        return None
    if len(mechanism.chains) != 1:
        raise DataError(f"'{mechanism.name}': distributed link masses are supported for serial mechanisms "
                        f"(one chain) only; this one has {len(mechanism.chains)} chains.")
    out = []
    for name, spec in masses.items():
        if name not in [j.name for j in mechanism.joints]:
            raise DataError(f"'{mechanism.name}': metadata.masses names joint '{name}', which the model lacks.")
        mass = float(spec.get("mass", -1.0))
        com = np.asarray(spec.get("com", ()), dtype=float)
        if not mass >= 0.0 or com.shape != (3,):
            raise DataError(f"'{mechanism.name}': metadata.masses['{name}'] needs 'mass' >= 0 (kg) and 'com' "
                            f"[x, y, z] (mm, base frame at home).")
        out.append({"joint": name, "mass": mass, "com": com})
    return out


def gravity_loads(mechanism, kin, q_act: np.ndarray, payload: np.ndarray, cache: dict | None = None) -> np.ndarray:
    """Gravity load on each actuated joint at actuated values ``q_act`` (N for P, N mm for R), (K, n_act).

    Virtual joint method: the generalized gravity force ``tau_j = sum_b z_j . ((c_b - o_j) x F_b)``
    (revolute) or ``z_j . F_b`` (prismatic) over the bodies ``b`` downstream of joint ``j``,
    ``F_b = m_b g``, with the link masses of ``mechanism.metadata['masses']``; the payload
    (kg, per pose) and ``metadata['moving_mass']`` (kg, default 50 without declared link
    masses, 0 with them) act at ``metadata['com']`` of the output frame, carried by
    ``tau = K_a^T W`` (static duality).  Gravity along ``metadata['gravity']`` (default -z).
    """
    from hyperstat.solver.kinematics.frames import apply_motion

    key = (q_act.shape, q_act.tobytes()[:512], float(q_act.sum()), float(np.sum(payload)))
    if cache is not None and key in cache:
        return cache[key]
    meta = mechanism.metadata
    links = _declared_masses(mechanism)
    g = np.asarray(meta.get("gravity", (0.0, 0.0, -1.0)), dtype=float)
    g = GRAVITY * g / np.linalg.norm(g)
    moving = float(meta.get("moving_mass", 0.0 if links else 50.0))
    com_out = np.asarray(meta.get("com", (0.0, 0.0, 0.0)), dtype=float)
    res = kin.solve(q_act)
    st = kin.evaluate(res.q, None, jacobians=True)
    from hyperstat.solver.tolerances.accuracy import output_twist_maps

    k_a = output_twist_maps(kin, st)[1]
    force = (moving + payload)[:, None] * g[None, :]
    arm = np.einsum("kij,j->ki", st.output_pose[:, :3, :3], com_out)
    wrench = np.concatenate([np.cross(arm, force), force], axis=1)
    tau = np.einsum("kia,ki->ka", k_a, wrench)
    if links:
        chain = mechanism.chains[0]
        jidx = {j.name: i for i, j in enumerate(mechanism.joints)}
        pos = {el.name: ei for ei, el in enumerate(chain.elements)}
        home = np.array([mechanism.home])
        st_home = kin.evaluate(home, None, jacobians=False)
        bodies = []  # (chain position, local com (4,), force (3,))
        for link in links:
            ei = pos[link["joint"]]
            el = chain.elements[ei]
            frame_home = apply_motion(st_home.element_frames[(0, ei)], el.type, home[:, jidx[el.name]])[0]
            local = np.linalg.solve(frame_home, np.r_[link["com"], 1.0])
            bodies.append((ei, local, link["mass"] * g))
        for a, i in enumerate(mechanism.actuated):
            joint = mechanism.joints[i]
            ej = pos[joint.name]
            lf = st.element_frames[(0, ej)]
            z, o = lf[:, :3, 2], lf[:, :3, 3]
            for ei, local, f in bodies:
                if ei < ej:
                    continue
                el = chain.elements[ei]
                frame = apply_motion(st.element_frames[(0, ei)], el.type, res.q[:, jidx[el.name]])
                c = frame[:, :3, :] @ local
                if joint.type == "R":
                    tau[:, a] += np.einsum("ki,ki->k", z, np.cross(c - o, f[None, :]))
                else:
                    tau[:, a] += z @ f
    if cache is not None:
        cache.clear()
        cache[key] = tau
    return tau


class GravityBacklash(Effect):
    """Backlash resting on the gravity side: ``dq_j = beta_j / 2 * sign(tau_j)``, ``beta_j >= 0``.

    A joint whose gravity load ``tau_j`` (:func:`gravity_loads`) does not change sign
    rests against one flank of its clearance, whatever the approach direction; the sign
    comes from the gravity torque.  Realistic ``beta``: 0.03 mm / 1.5e-4 rad.
    """

    name = "backlash-gravity"
    domain_note = "a clearance is never negative (beta >= 0), and above 0.6 mm or 3 mrad it is a loose joint"

    def __init__(self, mechanism, magnitude_mm: float = 0.03, magnitude_rad: float = 1.5e-4) -> None:
        acts = _actuators(mechanism)
        names = [f"gravity_backlash_{j.name}" for _, j in acts]
        units = ["mm" if j.type == "P" else "rad" for _, j in acts]
        mags = [magnitude_mm if u == "mm" else magnitude_rad for u in units]
        super().__init__(names, units, mags, lower=0.0, plausible=20.0 * np.asarray(mags))
        self._cache: dict = {}

    def actuator_correction(self, model, theta, data):
        payload = data.metadata.get("payload", np.zeros(len(data)))
        tau = gravity_loads(model.mechanism, model.kin, data.q, payload, self._cache)
        scale = np.abs(tau).max(axis=0, keepdims=True).clip(min=1e-300)
        side = np.where(np.abs(tau) > 1e-6 * scale, np.sign(tau), 0.0)
        k, na = tau.shape
        dt = np.zeros((k, na, na))
        idx = np.arange(na)
        dt[:, idx, idx] = 0.5 * side
        return np.einsum("kae,e->ka", dt, theta), dt


class Compliance(Effect):
    """Elastostatic compliance of the actuated joints under gravity and a payload (virtual joint method).

    One compliance per actuated joint: ``dq_j = c_j tau_j`` with the gravity load
    ``tau_j`` of :func:`gravity_loads`: the link masses declared in the model's metadata
    (``masses``: per joint, the body it moves, its mass and centre of mass), spread over
    the links, plus the payload of the ``payload[kg]`` column at the output.  Without
    declared masses, one moving mass (``metadata['moving_mass']``, default 50 kg) acts
    at the output.  ``c_j >= 0`` (mm/N or rad/(N mm); realistic 1e-4 mm/N, a 10 N/um
    leg, or 2e-9 rad/(N mm), 500 kN m/rad; plausible up to 100 times that).
    """

    name = "compliance"
    requires = ()  # the 'payload[kg]' column adds to the moving mass when present
    domain_note = "a compliance is never negative, and 100x the realistic one is a broken joint"
    also_explains = ("any elastic deformation under gravity whose load is the joints' gravity torque: the virtual "
                     "joints lump link bending into joint stiffness")

    def __init__(self, mechanism, magnitude_mm: float = 1e-4, magnitude_rad: float = 2e-9) -> None:
        acts = _actuators(mechanism)
        names = [f"compliance_{j.name}" for _, j in acts]
        units = ["mm/N" if j.type == "P" else "rad/(N mm)" for _, j in acts]
        mags = [magnitude_mm if j.type == "P" else magnitude_rad for _, j in acts]
        super().__init__(names, units, mags, lower=0.0, plausible=100.0 * np.asarray(mags))
        _declared_masses(mechanism)  # bad declarations fail here, with the field named
        self._cache: dict = {}

    def actuator_loads(self, model, data) -> np.ndarray:
        """Actuator loads ``tau`` (N or N mm) at the poses of ``data`` on the nominal model, (K, n_act)."""
        payload = data.metadata.get("payload", np.zeros(len(data)))
        return gravity_loads(model.mechanism, model.kin, data.q, payload, self._cache)

    def actuator_correction(self, model, theta, data):
        tau = self.actuator_loads(model, data)
        k, na = tau.shape
        dt = np.zeros((k, na, na))
        idx = np.arange(na)
        dt[:, idx, idx] = tau
        return tau * theta[None, :], dt


class LinkBendingAlternative(Compliance):
    """Alternative hypothesis to :class:`Compliance`, used only by the equivalence check (never selected).

    The same gravity loads deform the links instead of the joints: the link between an
    actuated revolute joint ``a`` and the next actuated revolute ``b`` of a serial chain,
    when their axes are parallel, bends in the plane of motion as a cantilever loaded at
    its end (Euler-Bernoulli: end slope ``theta = F L^2 / (2 E I)``, end deflection
    ``w = F L^3 / (3 E I) = 2/3 L theta``).  A rotation of ``2 theta / 3`` at joint ``a``
    gives the deflection, a further ``theta / 3`` at joint ``b`` completes the slope, with
    ``theta = c_ab tau_a`` (the bending moment at the link's root is joint ``a``'s gravity
    torque): ``dq_a = 2/3 c tau_a``, ``dq_b = 1/3 c tau_a``.  The other joints keep a
    joint compliance ``dq_j = c_j tau_j``, so the two models have as many parameters.
    Joint compliance leaves ``theta / 3`` of the slope unexplained at joint ``b`` with a
    load that is joint ``a``'s, not joint ``b``'s: when that difference is below the noise,
    the data cannot tell the two apart (``docs/diagnosis.md``).
    """

    name = "link bending (alternative to compliance)"

    def __init__(self, mechanism, kin) -> None:
        super().__init__(mechanism)
        acts = _actuators(mechanism)
        self.pairs: dict = {}  # actuator a -> next actuator b (parallel revolute axes)
        if len(mechanism.chains) != 1:
            return
        chain = mechanism.chains[0]
        pos = {el.name: ei for ei, el in enumerate(chain.elements)}
        order = sorted(acts, key=lambda aj: pos.get(aj[1].name, -1))
        home = np.array([mechanism.home])
        st = kin.evaluate(home, None, jacobians=False)
        for (a, ja), (b, jb) in zip(order, order[1:]):
            if ja.type != "R" or jb.type != "R" or ja.name not in pos or jb.name not in pos:
                continue
            za = st.element_frames[(0, pos[ja.name])][0, :3, 2]
            zb = st.element_frames[(0, pos[jb.name])][0, :3, 2]
            if abs(float(za @ zb)) > 0.999:
                self.pairs[a] = b
        self._names = [f"link_bending_{j.name}" if a in self.pairs else f"compliance_{j.name}" for a, j in acts]

    def actuator_correction(self, model, theta, data):
        tau = self.actuator_loads(model, data)
        k, na = tau.shape
        dt = np.zeros((k, na, na))
        for a in range(na):
            if a in self.pairs:
                dt[:, a, a] = 2.0 / 3.0 * tau[:, a]
                dt[:, self.pairs[a], a] = 1.0 / 3.0 * tau[:, a]
            else:
                dt[:, a, a] = tau[:, a]
        return np.einsum("kae,e->ka", dt, theta), dt
