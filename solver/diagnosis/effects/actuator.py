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
from hyperstat.solver.diagnosis.effects.priors import PRIORS, compliance_bounds

__all__ = ["ScrewPitch", "ScrewPeriodic", "AngleScale", "AngleHarmonic", "Backlash", "GravityBacklash", "Compliance",
           "LegThermal", "JOINTWISE", "gravity_moment",
           "LinkBending", "LinkBendingAlternative", "gravity_loads", "gravity_source", "gravity_regressor",
           "harmonic_name", "MASS_FIELD", "MASS_FIELD_SHORT", "screw_lead", "DEFAULT_SCREW_LEAD"]

#: where link masses come from (named in every "cannot size" answer)
MASS_FIELD = ("metadata.masses of the model file (per joint: the body it moves, 'mass' kg and 'com' mm), the URDF "
              "links' <inertial> (kept by import-robot), or the template's sk.material(...) for the CadQuery solids")
#: the same, short (for the text output)
MASS_FIELD_SHORT = "metadata.masses, the URDF links' <inertial> or the template's sk.material(...)"

GRAVITY = 9.81  # m/s^2

#: the screw lead assumed when the model declares none (``metadata.screw_lead``), mm
DEFAULT_SCREW_LEAD = 10.0


def screw_lead(mechanism) -> tuple[float, bool]:
    """The lead of the actuated screws (mm) and whether the model declares it (``metadata.screw_lead``).

    Where it is not declared, :data:`DEFAULT_SCREW_LEAD` is assumed, and an answer that states a
    screw order in turns says so.

    >>> from types import SimpleNamespace
    >>> screw_lead(SimpleNamespace(metadata={"screw_lead": 5}))
    (5.0, True)
    >>> screw_lead(SimpleNamespace(metadata={}))
    (10.0, False)
    """
    declared = mechanism.metadata.get("screw_lead")
    return (float(declared), True) if declared is not None else (DEFAULT_SCREW_LEAD, False)


#: effects with their own parameters per actuated joint: the diagnosis tries them joint by joint and groups the
#: joints that need them (``joints`` option, ``param_joints`` attribute)
JOINTWISE = ("screw-pitch", "screw-periodic", "angle-scale", "angle-harmonic", "backlash", "backlash-gravity",
             "leg-thermal", "guide-straightness", "joint-clearance")


def _actuators(mechanism, prismatic_only: bool = False, revolute_only: bool = False,
               joints: list | None = None, name: str = "effect") -> list[tuple[int, object]]:
    """``(actuator index, joint)`` of the actuated joints (of one type), restricted to ``joints`` when given."""
    out = [(a, mechanism.joints[i]) for a, i in enumerate(mechanism.actuated)]
    if prismatic_only:
        out = [(a, j) for a, j in out if j.type == "P"]
    if revolute_only:
        out = [(a, j) for a, j in out if j.type == "R"]
    if joints is not None:
        names = [j.name for _, j in out]
        unknown = [str(j) for j in joints if str(j) not in names]
        if unknown:
            kind = "prismatic " if prismatic_only else "revolute " if revolute_only else ""
            raise DataError(f"{name}: '{unknown[0]}' is not a {kind}actuated joint of '{mechanism.name}'.")
        out = [(a, j) for a, j in out if j.name in [str(x) for x in joints]]
    return out


class ScrewPitch(Effect):
    """Lead-screw pitch error: the travel is ``(1 + s_j) q_j`` (``s`` dimensionless, realistic 4e-4: a rolled ball screw class C10, 210 um per 300 mm, is 7e-4)."""

    name = "screw-pitch"
    domain_note = "a lead error beyond 2e-3 (2 mm per metre) is no ball screw of any class"

    def __init__(self, mechanism, magnitude: float = 4e-4, joints: list | None = None) -> None:
        acts = _actuators(mechanism, prismatic_only=True, joints=joints, name=self.name)
        self.axes = [a for a, _ in acts]
        self.joints = [j.name for _, j in acts]
        names = [f"pitch_{j.name}" for _, j in acts]
        p = PRIORS["screw-pitch"]
        super().__init__(names, ["1"] * len(names), [magnitude] * len(names), plausible=p.plausible, what=p.what,
                         source=p.source)
        self.param_joints = list(self.joints)

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

    def __init__(self, mechanism, lead: float | None = None, magnitude: float = 0.01, joints: list | None = None) -> None:
        declared = screw_lead(mechanism)[0]
        self.lead = float(lead or declared)
        if not (np.isfinite(self.lead) and self.lead > 0):
            raise DataError(f"screw-periodic: the screw lead must be a positive length in mm, got {lead!r}.")
        acts = _actuators(mechanism, prismatic_only=True, joints=joints, name=self.name)
        self.axes = [a for a, _ in acts]
        self.joints = [j.name for _, j in acts]
        tag = "" if self.lead == declared else f"_p{self.lead:g}"  # another period than the lead: its name says it
        names = [f"periodic_{j.name}{tag}_{t}" for _, j in acts for t in ("sin", "cos")]
        p = PRIORS["screw-periodic"]
        super().__init__(names, ["mm"] * len(names), [magnitude] * len(names), plausible=p.plausible, what=p.what,
                         source=p.source, groups=[[2 * e, 2 * e + 1] for e in range(len(acts))])
        self.param_joints = [j for j in self.joints for _ in (0, 1)]

    domain_note = "a periodic lead error beyond 0.05 mm is no ball screw"

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


class LegThermal(Effect):
    """Thermal growth of each prismatic actuator's length: ``dq_j = kappa_j (T - 20 degC) q_j``.

    A PKM's legs (or any screw-driven axis) lengthen with their temperature: the actuated
    length ``q_j`` (mm, as the model measures it: a leg from its base joint's centre) grows by
    ``kappa_j (T - T_ref) q_j``, ``T`` from the ``temperature[degC]`` column, ``T_ref`` = 20 degC,
    one coefficient per leg (1/degC).  Domain: a structural expansion coefficient,
    ``-2e-6 <= kappa <= 3e-5`` /degC (carbon fibre and Invar to aluminium, :mod:`.priors`);
    realistic 1.2e-5 (a steel strut or ball screw).  Unlike ``thermal`` (the whole structure
    about the base origin) it moves the platform through the legs: each leg by its own length.
    """

    name = "leg-thermal"
    requires = ("temperature",)
    reference = 20.0
    domain_note = ("a leg's expansion coefficient lies between -2e-6 /degC (carbon fibre, Invar) and 3e-5 /degC "
                   "(aluminium 2.3e-5, magnesium 2.6e-5)")

    def __init__(self, mechanism, magnitude: float = 1.2e-5, joints: list | None = None) -> None:
        acts = _actuators(mechanism, prismatic_only=True, joints=joints, name=self.name)
        self.axes = [a for a, _ in acts]
        self.joints = [j.name for _, j in acts]
        p = PRIORS["leg-thermal"]
        names = [f"leg_thermal_{j}" for j in self.joints]
        super().__init__(names, ["1/degC"] * len(names), [magnitude] * len(names), lower=-2e-6, upper=3e-5,
                         plausible=p.plausible, what=p.what, source=p.source)
        self.param_joints = list(self.joints)

    def actuator_correction(self, model, theta, data):
        if "temperature" not in data.metadata:
            raise DataError(f"{data.source}: the leg-thermal effect needs the column 'temperature[degC]'.")
        k, na = data.q.shape
        dtemp = data.metadata["temperature"] - self.reference
        dt = np.zeros((k, na, len(self.axes)))
        for e, a in enumerate(self.axes):
            dt[:, a, e] = dtemp * data.q[:, a]
        return np.einsum("kae,e->ka", dt, theta), dt


class Backlash(Effect):
    """Backlash of each actuator: ``dq_j = -beta_j / 2 * dir_j``, ``beta_j >= 0``.

    ``dir_j = +-1`` is the direction of the actuator's last motion before the pose; the
    driven side lags behind the drive by half the clearance.  Realistic ``beta``:
    0.03 mm (prismatic), 1.5e-4 rad (revolute); plausible up to 0.1 mm and 1.5 mrad
    (:mod:`.priors`: ball-screw clearance classes, reducer lost motion).
    """

    name = "backlash"
    requires = ("dir*",)
    domain_note = "a clearance is never negative (beta >= 0), and above 0.1 mm or 1.5 mrad it is a loose joint"

    def __init__(self, mechanism, magnitude_mm: float = 0.03, magnitude_rad: float = 1.5e-4,
                 joints: list | None = None) -> None:
        acts = _actuators(mechanism, joints=joints, name=self.name)
        self.axes = [a for a, _ in acts]
        self.columns = [f"dir{j.name}" for _, j in acts]
        names = [f"backlash_{j.name}" for _, j in acts]
        _backlash_init(self, acts, names, magnitude_mm, magnitude_rad)

    def applicable(self, data) -> bool:
        """Whether ``data`` records every approach direction."""
        return all(c in data.metadata for c in self.columns)

    def actuator_correction(self, model, theta, data):
        if not self.applicable(data):
            missing = [c for c in self.columns if c not in data.metadata]
            raise DataError(f"{data.source}: the backlash effect needs the column(s) {', '.join(missing)}.")
        k, na = data.q.shape
        dt = np.zeros((k, na, len(self.axes)))
        for e, (a, col) in enumerate(zip(self.axes, self.columns)):
            dt[:, a, e] = -0.5 * data.metadata[col]
        return np.einsum("kae,e->ka", dt, theta), dt


class AngleScale(Effect):
    """Transmission ratio error of each revolute actuator: the joint turns ``(1 + s_j) q_j``.

    The revolute counterpart of :class:`ScrewPitch` (a gear ratio or encoder scale error;
    ``s`` dimensionless, realistic 2e-4, plausible up to 5e-3).
    """

    name = "angle-scale"
    domain_note = "a ratio error beyond 5e-3 is a wrong gear ratio in the joint map, not a manufacturing error"

    def __init__(self, mechanism, magnitude: float = 2e-4, joints: list | None = None) -> None:
        acts = _actuators(mechanism, revolute_only=True, joints=joints, name=self.name)
        self.axes = [a for a, _ in acts]
        self.joints = [j.name for _, j in acts]
        names = [f"angle_scale_{j.name}" for _, j in acts]
        p = PRIORS["angle-scale"]
        super().__init__(names, ["1"] * len(names), [magnitude] * len(names), plausible=p.plausible, what=p.what,
                         source=p.source)
        self.param_joints = list(self.joints)

    def actuator_correction(self, model, theta, data):
        k, na = data.q.shape
        dq = np.zeros((k, na))
        dt = np.zeros((k, na, len(self.axes)))
        for e, a in enumerate(self.axes):
            dq[:, a] = theta[e] * data.q[:, a]
            dt[:, a, e] = data.q[:, a]
        return dq, dt


def _backlash_init(effect: Effect, acts: list, names: list, magnitude_mm: float, magnitude_rad: float) -> None:
    """Units, realistic magnitudes and priors of a clearance per actuator (revolute: rad, prismatic: mm)."""
    units = ["mm" if j.type == "P" else "rad" for _, j in acts]
    priors = [PRIORS["backlash-mm"] if u == "mm" else PRIORS["backlash-rad"] for u in units]
    mags = [magnitude_mm if u == "mm" else magnitude_rad for u in units]
    Effect.__init__(effect, names, units, mags, lower=0.0, plausible=[p.plausible for p in priors],
                    what=[p.what for p in priors], source=[p.source for p in priors])
    effect.joints = [j.name for _, j in acts]
    effect.param_joints = list(effect.joints)


def harmonic_name(cycles: float) -> str:
    """Library name of a periodic angle error at ``cycles`` per revolution: ``angle-harmonic-<k>``.

    >>> harmonic_name(3.0), harmonic_name(2.75)
    ('angle-harmonic-3', 'angle-harmonic-2.75')
    """
    return f"angle-harmonic-{float(cycles):g}"


class AngleHarmonic(Effect):
    """Periodic transmission error of revolute actuators at ``k`` cycles per revolution of the joint.

    ``dq_j = a_j sin(k q_j) + b_j cos(k q_j)`` (rad), the harmonic joint-error model of
    serial robots (eccentricity of an output bearing or gear: ``k = 1``; ellipticity of a
    strain-wave flexspline: ``k = 2``; an intermediate gear stage: its ratio to the
    output, any positive number).  ``k = 1`` and ``2`` act on every revolute actuator;
    the diagnosis adds, per joint, the order its residual spectrum peaks at (``joints``).
    Realistic amplitude 1e-4 rad (20 arcsec), plausible up to 5.8e-4 rad (:mod:`.priors`).
    """

    domain_note = "a periodic angle error beyond 2 arcmin is a damaged transmission"

    def __init__(self, mechanism, cycles: float = 1, magnitude: float = 1e-4, joints: list | None = None) -> None:
        self.cycles = float(cycles)
        if not (np.isfinite(self.cycles) and self.cycles > 0):
            raise DataError(f"a periodic angle error needs a positive number of cycles per revolution, got {cycles!r}.")
        self.name = harmonic_name(self.cycles)
        acts = _actuators(mechanism, revolute_only=True, joints=joints, name=self.name)
        self.axes = [a for a, _ in acts]
        self.joints = [j.name for _, j in acts]
        names = [f"harmonic{self.cycles:g}_{j.name}_{t}" for _, j in acts for t in ("sin", "cos")]
        p = PRIORS["angle-harmonic"]
        super().__init__(names, ["rad"] * len(names), [magnitude] * len(names), plausible=p.plausible, what=p.what,
                         source=p.source, groups=[[2 * e, 2 * e + 1] for e in range(len(acts))])
        self.param_joints = [j for j in self.joints for _ in (0, 1)]

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


def gravity_source(mechanism) -> str | None:
    """What gives the gravity loads: ``"link masses"``, ``"moving mass"`` (declared), or None (nothing declared).

    Without either, compliance and every gravity-driven effect cannot be sized: the
    diagnosis says so (``cannot_size``) instead of assuming a mass.
    """
    if _declared_masses(mechanism):
        return "link masses"
    moving = mechanism.metadata.get("moving_mass")
    if moving is not None:
        if not (isinstance(moving, (int, float)) and np.isfinite(moving) and moving >= 0):
            raise DataError(f"'{mechanism.name}': metadata.moving_mass must be a mass >= 0 in kg, got {moving!r}.")
        if moving > 0:
            return "moving mass"
    return None


def total_mass(mechanism) -> float:
    """Declared moving mass of the machine (kg): the link masses plus ``metadata.moving_mass``."""
    links = _declared_masses(mechanism) or []
    return float(sum(b["mass"] for b in links) + float(mechanism.metadata.get("moving_mass", 0.0) or 0.0))


def _body_frames(mechanism, kin, q_act: np.ndarray):
    """Assembled configurations, their state, and the serial chain's body frames after each joint's motion."""
    from hyperstat.solver.kinematics.frames import apply_motion

    res = kin.solve(q_act)
    st = kin.evaluate(res.q, None, jacobians=True)
    frames = {}
    if len(mechanism.chains) == 1:
        chain = mechanism.chains[0]
        jidx = {j.name: i for i, j in enumerate(mechanism.joints)}
        for ei, el in enumerate(chain.elements):
            if el.name in jidx and getattr(el, "type", None) in ("R", "P"):
                frames[el.name] = (ei, apply_motion(st.element_frames[(0, ei)], el.type, res.q[:, jidx[el.name]]))
    return res, st, frames


def gravity_regressor(mechanism, kin, q_act: np.ndarray) -> tuple[np.ndarray, list]:
    """Gravity load on each actuated joint per unit inertial parameter of each moving body (serial chains).

    The generalized gravity force is linear in each body's mass ``m`` and first moment
    ``h = m c`` (its centre of mass ``c`` in the body's own frame, the frame of the joint
    that moves it, after the motion): ``tau_j = z_j . ((R_b h + m (t_b - o_j)) x m g)``
    for a revolute ``j`` upstream of body ``b``, ``z_j . g m`` for a prismatic one.

    Returns
    -------
    regressor : ndarray, (K, n_act, n_bodies, 4)
        ``d tau_j / d (m_b, h_bx, h_by, h_bz)`` (N mm per kg and N per kg mm for revolutes,
        N per kg for prismatic joints), gravity ``metadata['gravity']`` (default -z).
    bodies : list of str
        The joint moving each body (every actuated joint of the serial chain).
    """
    meta = mechanism.metadata
    g = np.asarray(meta.get("gravity", (0.0, 0.0, -1.0)), dtype=float)
    g = GRAVITY * g / np.linalg.norm(g)
    _, _, frames = _body_frames(mechanism, kin, q_act)
    acts = [mechanism.joints[i] for i in mechanism.actuated]
    bodies = [j.name for j in acts if j.name in frames]
    k = len(q_act)
    reg = np.zeros((k, len(acts), len(bodies), 4))
    for a, joint in enumerate(acts):
        if joint.name not in frames:
            continue
        ej, fj = frames[joint.name]
        # the joint's axis and origin: its frame before the motion has the same z axis and origin
        z, o = fj[:, :3, 2], fj[:, :3, 3]
        for b, name in enumerate(bodies):
            eb, fb = frames[name]
            if eb < ej:
                continue
            if joint.type == "R":
                reg[:, a, b, 0] = np.einsum("ki,ki->k", z, np.cross(fb[:, :3, 3] - o, g[None, :]))
                for i in range(3):
                    reg[:, a, b, 1 + i] = np.einsum("ki,ki->k", z, np.cross(fb[:, :3, i], g[None, :]))
            else:
                reg[:, a, b, 0] = z @ g
    return reg, bodies


def gravity_loads(mechanism, kin, q_act: np.ndarray, payload: np.ndarray, cache: dict | None = None) -> np.ndarray:
    """Gravity load on each actuated joint at actuated values ``q_act`` (N for P, N mm for R), (K, n_act).

    Virtual joint method: the generalized gravity force ``tau_j = sum_b z_j . ((c_b - o_j) x F_b)``
    (revolute) or ``z_j . F_b`` (prismatic) over the bodies ``b`` downstream of joint ``j``,
    ``F_b = m_b g``, with the link masses of ``mechanism.metadata['masses']``
    (:func:`gravity_regressor`); the payload (kg, per pose) and a declared
    ``metadata['moving_mass']`` (kg, default 0) act at ``metadata['com']`` of the output
    frame, carried by ``tau = K_a^T W`` (static duality).  Gravity along
    ``metadata['gravity']`` (default -z).  Nothing is assumed: without declared masses
    only the payload loads the joints (:func:`gravity_source` tells the caller).
    """
    from hyperstat.solver.tolerances.accuracy import output_twist_maps

    key = (q_act.shape, q_act.tobytes()[:512], float(q_act.sum()), float(np.sum(payload)))
    if cache is not None and key in cache:
        return cache[key]
    meta = mechanism.metadata
    links = _declared_masses(mechanism)
    g = np.asarray(meta.get("gravity", (0.0, 0.0, -1.0)), dtype=float)
    g = GRAVITY * g / np.linalg.norm(g)
    moving = float(meta.get("moving_mass", 0.0) or 0.0)
    com_out = np.asarray(meta.get("com", (0.0, 0.0, 0.0)), dtype=float)
    res, st, _ = _body_frames(mechanism, kin, q_act)
    k_a = output_twist_maps(kin, st)[1]
    force = (moving + payload)[:, None] * g[None, :]
    arm = np.einsum("kij,j->ki", st.output_pose[:, :3, :3], com_out)
    wrench = np.concatenate([np.cross(arm, force), force], axis=1)
    tau = np.einsum("kia,ki->ka", k_a, wrench)
    if links:
        reg, bodies = gravity_regressor(mechanism, kin, q_act)
        _, _, home = _body_frames(mechanism, kin, np.array([mechanism.home[mechanism.actuated]]))
        params = np.zeros((len(bodies), 4))
        for link in links:
            if link["joint"] not in bodies:
                continue
            frame = home[link["joint"]][1][0]
            local = np.linalg.solve(frame, np.r_[link["com"], 1.0])[:3]
            params[bodies.index(link["joint"])] = np.r_[link["mass"], link["mass"] * local]
        tau = tau + np.einsum("kabp,bp->ka", reg, params)
    if cache is not None:
        cache.clear()
        cache[key] = tau
    return tau


def gravity_moment(mechanism, kin, q_act: np.ndarray, payload: np.ndarray) -> np.ndarray:
    """Moment of the moving masses' weight about the base origin (N mm, base frame), (K, 3).

    ``M = sum_b x_b x m_b g``: the declared link masses at their centres of mass at the pose
    (serial chains, :func:`gravity_loads`' bodies), a declared ``metadata['moving_mass']`` and
    the payload (kg, per pose) at ``metadata['com']`` of the output frame; gravity along
    ``metadata['gravity']`` (default -z).  Nothing is assumed: without declared masses only the
    payload counts.
    """
    meta = mechanism.metadata
    g = np.asarray(meta.get("gravity", (0.0, 0.0, -1.0)), dtype=float)
    g = GRAVITY * g / np.linalg.norm(g)
    moving = float(meta.get("moving_mass", 0.0) or 0.0)
    com_out = np.asarray(meta.get("com", (0.0, 0.0, 0.0)), dtype=float)
    res, st, frames = _body_frames(mechanism, kin, q_act)
    out_point = st.output_pose[:, :3, 3] + np.einsum("kij,j->ki", st.output_pose[:, :3, :3], com_out)
    moment = np.cross(out_point, (moving + payload)[:, None] * g[None, :])
    links = _declared_masses(mechanism)
    if links:
        _, _, home = _body_frames(mechanism, kin, np.array([mechanism.home[mechanism.actuated]]))
        for link in links:
            if link["joint"] not in frames:
                continue
            local = np.linalg.solve(home[link["joint"]][1][0], np.r_[link["com"], 1.0])
            point = np.einsum("kij,j->ki", frames[link["joint"]][1], local)[:, :3]
            moment += np.cross(point, link["mass"] * g[None, :])
    return moment


def _require_gravity(mechanism, name: str) -> None:
    """Refuse a gravity-driven effect on a model that declares no mass (never assume one)."""
    if gravity_source(mechanism) is None:
        raise DataError(f"'{mechanism.name}': the {name} effect needs the gravity loads, and the model declares no "
                        f"mass; declare them in {MASS_FIELD}.")


def _gravity_side(tau: np.ndarray, axes: list, theta: np.ndarray):
    """``dq_a = beta_e / 2 * sign(tau_a)`` for the actuators ``axes`` (a load near zero rests on neither flank)."""
    scale = np.abs(tau).max(axis=0, keepdims=True).clip(min=1e-300)
    side = np.where(np.abs(tau) > 1e-6 * scale, np.sign(tau), 0.0)
    k, na = tau.shape
    dt = np.zeros((k, na, len(axes)))
    for e, a in enumerate(axes):
        dt[:, a, e] = 0.5 * side[:, a]
    return np.einsum("kae,e->ka", dt, theta), dt


class GravityBacklash(Effect):
    """Backlash resting on the gravity side: ``dq_j = beta_j / 2 * sign(tau_j)``, ``beta_j >= 0``.

    A joint whose gravity load ``tau_j`` (:func:`gravity_loads`) does not change sign
    rests against one flank of its clearance, whatever the approach direction; the sign
    comes from the gravity torque.  Realistic ``beta``: 0.03 mm / 1.5e-4 rad.
    """

    name = "backlash-gravity"
    sign_of_load = True  # its columns are steps with the sign of the gravity load (screening prior: the bound)
    domain_note = "a clearance is never negative (beta >= 0), and above 0.1 mm or 1.5 mrad it is a loose joint"

    def __init__(self, mechanism, magnitude_mm: float = 0.03, magnitude_rad: float = 1.5e-4,
                 joints: list | None = None) -> None:
        _require_gravity(mechanism, self.name)
        acts = _actuators(mechanism, joints=joints, name=self.name)
        self.axes = [a for a, _ in acts]
        names = [f"gravity_backlash_{j.name}" for _, j in acts]
        _backlash_init(self, acts, names, magnitude_mm, magnitude_rad)
        self._cache: dict = {}

    def actuator_correction(self, model, theta, data):
        payload = data.metadata.get("payload", np.zeros(len(data)))
        tau = gravity_loads(model.mechanism, model.kin, data.q, payload, self._cache)
        return _gravity_side(tau, self.axes, theta)


def _main_axes(mechanism) -> set:
    """Names of the main axes: the first three actuated joints from the base of a serial chain; on a parallel
    machine the actuated joints of the chains that start at the base (its legs), not those of a serial wrist
    carried by the platform (the Tripteor X7's two revolutes are wrist axes)."""
    acts = [mechanism.joints[i].name for i in mechanism.actuated]
    if len(mechanism.chains) != 1:
        legs = {el.name for ch in mechanism.chains if ch.start == mechanism.base for el in ch.elements}
        return {a for a in acts if a in legs} or set(acts)
    order = [el.name for el in mechanism.chains[0].elements if el.name in acts]
    return set(order[:3])


class Compliance(Effect):
    """Elastostatic compliance of the actuated joints under gravity and a payload (virtual joint method).

    One compliance per actuated joint: ``dq_j = c_j tau_j`` with the gravity load
    ``tau_j`` of :func:`gravity_loads`: the link masses declared in the model's metadata
    (``masses``: per joint, the body it moves, its mass and centre of mass), spread over
    the links, plus the payload of the ``payload[kg]`` column at the output, plus a
    declared ``metadata['moving_mass']``.  Without any declared mass the effect cannot be
    sized and is refused (:data:`MASS_FIELD`).  ``c_j >= 0`` (mm/N or rad/(N mm);
    realistic 1e-4 mm/N, a 10 N/um leg, or 2e-9 rad/(N mm), 500 kN m/rad); plausible up
    to the size class's bound (:func:`~.priors.compliance_bounds`: the arm's declared
    mass sets the class, main axes and wrist apart).
    """

    name = "compliance"
    requires = ()  # the 'payload[kg]' column adds to the moving mass when present
    domain_note = "a compliance is never negative, and beyond the size class's bound it is a broken joint"
    also_explains = ("any elastic deformation under gravity whose load is the joints' gravity torque: the virtual "
                     "joints lump link bending into joint stiffness")

    def __init__(self, mechanism, magnitude_mm: float = 1e-4, magnitude_rad: float = 2e-9) -> None:
        _declared_masses(mechanism)  # bad declarations fail here, with the field named
        _require_gravity(mechanism, self.name)
        acts = _actuators(mechanism)
        names = [f"compliance_{j.name}" for _, j in acts]
        units = ["mm/N" if j.type == "P" else "rad/(N mm)" for _, j in acts]
        mags = [magnitude_mm if j.type == "P" else magnitude_rad for _, j in acts]
        plausible, what, source = _compliance_priors(mechanism, [j for _, j in acts])
        super().__init__(names, units, mags, lower=0.0, plausible=plausible, what=what, source=source)
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


def _compliance_priors(mechanism, joints: list) -> tuple[list, list, list]:
    """Plausible bound, words and source of each joint's compliance (size class of the declared mass)."""
    mass = total_mass(mechanism)
    main = _main_axes(mechanism)
    plausible, what, source = [], [], []
    for j in joints:
        if j.type == "P":
            p = PRIORS["compliance-mm"]
            plausible.append(p.plausible)
            what.append(p.what)
            source.append(p.source)
        else:
            bound, words = compliance_bounds(mass, wrist=j.name not in main)
            plausible.append(bound)
            what.append(words)
            source.append("dumas2011")
    return plausible, what, source


class LinkBending(Effect):
    """Bending of a link under gravity (Euler-Bernoulli cantilever) between two parallel revolute actuators.

    The link between an actuated revolute joint ``a`` and the next actuated revolute
    ``b`` of a serial chain, when their axes are parallel, bends in the plane of motion as
    a cantilever loaded at its end: end slope ``theta = F L^2 / (2 E I)``, end deflection
    ``w = F L^3 / (3 E I) = 2/3 L theta``.  A rotation of ``2 theta / 3`` at joint ``a``
    gives the deflection, a further ``theta / 3`` at joint ``b`` completes the slope, with
    ``theta = c_ab tau_a`` (the bending moment at the link's root is joint ``a``'s gravity
    torque): ``dq_a = 2/3 c tau_a``, ``dq_b = 1/3 c tau_a``, ``c >= 0`` (rad/(N mm)).
    Joint compliance leaves ``theta / 3`` of the slope unexplained at joint ``b`` with a
    load that is joint ``a``'s, not joint ``b``'s: when that difference is below the noise,
    the two form one equivalence set (``docs/diagnosis.md``).
    """

    name = "link-bending"
    domain_note = "a bending compliance is never negative, and beyond the size class's joint bound the link is broken"

    def __init__(self, mechanism, kin=None, magnitude: float = 2e-9) -> None:
        from hyperstat.solver.kinematics.closure import Kinematics

        _require_gravity(mechanism, self.name)
        kin = kin or Kinematics(mechanism)
        acts = _actuators(mechanism)
        self.pairs: dict = {}  # actuator a -> next actuator b (parallel revolute axes)
        if len(mechanism.chains) == 1:
            chain = mechanism.chains[0]
            pos = {el.name: ei for ei, el in enumerate(chain.elements)}
            order = sorted(acts, key=lambda aj: pos.get(aj[1].name, -1))
            st = kin.evaluate(np.array([mechanism.home]), None, jacobians=False)
            for (a, ja), (b, jb) in zip(order, order[1:]):
                if ja.type != "R" or jb.type != "R" or ja.name not in pos or jb.name not in pos:
                    continue
                za = st.element_frames[(0, pos[ja.name])][0, :3, 2]
                zb = st.element_frames[(0, pos[jb.name])][0, :3, 2]
                if abs(float(za @ zb)) > 0.999:
                    self.pairs[a] = b
        self.roots = sorted(self.pairs)
        names = [f"link_bending_{acts[a][1].name}" for a in self.roots]
        plausible, what, _ = _compliance_priors(mechanism, [acts[a][1] for a in self.roots])
        super().__init__(names, ["rad/(N mm)"] * len(names), [magnitude] * len(names), lower=0.0,
                         plausible=plausible, what=[f"bending compliance (as the {w})" for w in what],
                         source="dumas2011")
        self._cache: dict = {}

    def actuator_correction(self, model, theta, data):
        payload = data.metadata.get("payload", np.zeros(len(data)))
        tau = gravity_loads(model.mechanism, model.kin, data.q, payload, self._cache)
        k, na = tau.shape
        dt = np.zeros((k, na, len(self.roots)))
        for e, a in enumerate(self.roots):
            dt[:, a, e] = 2.0 / 3.0 * tau[:, a]
            dt[:, self.pairs[a], e] = 1.0 / 3.0 * tau[:, a]
        return np.einsum("kae,e->ka", dt, theta), dt


LinkBendingAlternative = LinkBending  # the name of issue 20 (the equivalence check's alternative)
