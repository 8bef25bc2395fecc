"""Step 4 of the diagnosis: equivalence sets, the effects these poses cannot tell apart.

Units: chi-square differences in units of the (weighted) noise variance.

For each named effect ``X`` the best fit of the rigid residual with the geometry, the
other named effects and ``X`` gives ``X``'s fitted signature ``s_X`` (its part of the fit,
projected off the geometry and the others, weighted by the noise).  Another candidate
``Y`` belongs to ``X``'s equivalence set when the geometry, the others and ``Y`` reproduce
that signature within the noise: ``|(I - P_[B, Y]) s_X|^2 < 10`` (the Kass-Raftery
"strong evidence" threshold, the same as a chi-square difference of swapping ``X``'s
columns for ``Y``'s).  This is the principal-angle comparison of the two noise-weighted
column spaces after projecting off the geometric model, weighted by what ``X`` actually
fits.  The candidates are every library effect tried on these data (periodic orders from
the spectrum included) and the family ``gravity-deformation``: joint deflections driven
by the gravity load of each joint, also seen by the next joint (link bending), with the
declared masses, or, without them, with any mass distribution (the gravity regressor of
each body, :func:`~hyperstat.solver.diagnosis.effects.gravity_regressor`).  Nothing is
listed by hand: a 1/rev error of a shoulder, joint compliance and link bending fall in
one set exactly when these poses cannot separate them.

Each set says which measurement would separate its members (:func:`separating_measurement`).
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.diagnosis.effects import (MASS_FIELD, gravity_loads, gravity_regressor, harmonic_order,
                                                is_jointwise)
from hyperstat.solver.diagnosis.leg_pattern import LEG_OFFSET, LEG_OFFSET_WORDS
from hyperstat.solver.diagnosis.periodic import EQUIVALENT_CHI2
from hyperstat.solver.diagnosis.screening import Screen

__all__ = ["equivalence_sets", "gravity_family", "stand_motion_family", "bending_alternatives", "separating_measurement",
           "GRAVITY_FAMILY", "STAND_MOTION", "DEFORMATIONS", "BEAM_BENDING"]

GRAVITY_FAMILY = "gravity-deformation"
#: the family "the machine's stand (its base) moved relative to the floor during the campaign": a rigid motion of
#: the base frame relative to the tracker between sessions or with time, which the tracker moving gives as well
STAND_MOTION = "stand-motion"
STAND_MOTION_WORDS = ("measuring reference reflectors fixed to the floor (drift nests) and reflectors fixed to the "
                      "machine's base at the start and end of each session (a tracker that moved sees both move "
                      "alike; a stand that moved moves the base's reflectors against the floor's)")
DEFORMATIONS = ("compliance", "link-bending")  # gravity-driven deformations of the library
_GRAVITY = DEFORMATIONS + ("backlash-gravity", GRAVITY_FAMILY)
ZERO_LOAD = 1e-6  # N mm (per kg, per kg mm): a gravity load below this is round-off (a joint about the vertical)


def _orth(m: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Orthonormal basis of the column space of ``m`` (SVD, relative tolerance)."""
    if m.shape[1] == 0:
        return m
    u, s, _ = np.linalg.svd(m, full_matrices=False)
    return u[:, s > tol * max(float(s[0]), 1e-300)]


def _chain_order(mech) -> list:
    """Actuator indices in the order of the serial chain (base first)."""
    names = [mech.joints[i].name for i in mech.actuated]
    if len(mech.chains) != 1:
        return list(range(len(names)))
    order = [el.name for el in mech.chains[0].elements if el.name in names]
    return [names.index(n) for n in order]


def gravity_family(mech, kin, data, act_jac: np.ndarray, masses_known: bool) -> np.ndarray | None:
    """Columns (K, 3, m) of "some gravity-driven deformation" on these poses, or None (no gravity load).

    With declared masses: each joint deflected by its own gravity load and by the load of
    the joint before it (a bending link); without: the same with each body's unknown mass
    and first moment (the gravity regressor) and the payload of the ``payload`` column.
    Serial chains only.
    """
    if len(mech.chains) != 1:
        return None
    payload = data.metadata.get("payload", np.zeros(len(data)))
    order = _chain_order(mech)
    nxt = {a: b for a, b in zip(order, order[1:])}
    cols = []
    if masses_known:
        tau = gravity_loads(mech, kin, data.q, payload)
        drivers = {a: tau[:, a:a + 1] for a in range(tau.shape[1])}
    else:
        reg, _ = gravity_regressor(mech, kin, data.q)
        tau_p = gravity_loads(mech, kin, data.q, payload)  # the payload alone (no mass declared)
        drivers = {a: np.concatenate([reg[:, a].reshape(len(data), -1), tau_p[:, a:a + 1]], axis=1)
                   for a in range(reg.shape[1])}
    for a, y in drivers.items():
        # a joint whose axis is along gravity carries no load: its columns are round-off (1e-12 N mm)
        keep = np.abs(y).max(axis=0) > ZERO_LOAD
        if not np.any(keep):
            continue
        y = _orth(y[:, keep], 1e-8) * np.sqrt(len(data))
        y = np.tile(y, (len(act_jac) // len(data), 1))  # the same load on a pose's orientation row (6-D)
        cols.append(act_jac[:, :, a, None] * y[:, None, :])
        if a in nxt:
            cols.append(act_jac[:, :, nxt[a], None] * y[:, None, :])
    if not cols:
        return None
    return np.concatenate(cols, axis=2)


def stand_motion_family(data, world: np.ndarray, r_trk: np.ndarray, n_rows: int) -> np.ndarray | None:
    """Columns (R, 3, m) of "the stand moved": a rigid motion of the base frame relative to the tracker over time.

    A translation and a small rotation about the base origin (``t + omega x p``, ``p`` the target in the base
    frame, mm) per session after the first (the ``session`` column) and growing with the ``time[s]`` column
    (linear), seen in the tracker frame (``R_trk^T``); an orientation row (6-D) turns by ``omega``.  The
    measurements alone cannot tell this from the tracker moving the other way: both are the same relative
    motion of the two frames.  None without a session or time column that varies.

    Parameters
    ----------
    data : MeasurementSet
        Poses and metadata (``session``, ``time``).
    world : ndarray, (K, 3)
        Target points in the base frame (mm) at the rigid solution.
    r_trk : ndarray, (3, 3)
        Tracker rotation in the base frame.
    n_rows : int
        Rows of the fit (K, or 2K with orientation rows).
    """
    k = len(data)
    drivers = []
    sessions = data.metadata.get("session")
    if sessions is not None:
        for s in sorted(set(sessions.tolist()))[1:]:
            drivers.append((sessions == s).astype(float))
    time_s = data.metadata.get("time")
    if time_s is not None and np.ptp(time_s) > 0:
        drivers.append((time_s - time_s.mean()) / np.ptp(time_s))
    if not drivers:
        return None
    cols = []
    for d in drivers:
        for c in range(3):
            e = np.zeros(3)
            e[c] = 1.0
            pos = np.tile(r_trk.T @ e, (k, 1)) * d[:, None]  # translation along base axis c
            rot = (np.cross(e[None, :], world) @ r_trk) * d[:, None]  # rotation about base axis c, R^T (e x p)
            if n_rows > k:
                pos = np.concatenate([pos, np.zeros((n_rows - k, 3))])
                rot = np.concatenate([rot, np.tile(r_trk.T @ e, (n_rows - k, 1)) * d[:, None]])
            cols += [pos, rot]
    return np.stack(cols, axis=2)


#: Joint rotations equivalent to the bending of a link between parallel revolutes ``a`` and ``b``
#: (Euler-Bernoulli, bending compliance ``c = L / EI``), as fractions of ``c tau_a`` and ``c tau_b``:
#: the bending moment is ``tau_a`` at the link's root and ``tau_b`` (the next joint's gravity
#: torque, a couple from the links beyond) at its end.  The root turns by the end deflection over
#: the length (``w / L``), the next joint by the rest of the end slope.  A moment linear along the
#: link (the weights beyond its end) gives ``w / L = c (tau_a / 3 + tau_b / 6)`` and a slope
#: ``c (tau_a + tau_b) / 2``; a parabolic one (the link's own weight) ``w / L = c (tau_a + tau_b) / 4``
#: and a slope ``c (tau_a + 2 tau_b) / 3``.  Rows: ((root from tau_a, root from tau_b),
#: (next from tau_a, next from tau_b)).
BEAM_BENDING = {
    "bending of the links under the weights beyond them (linear bending moment)": ((1 / 3, 1 / 6), (1 / 6, 1 / 3)),
    "bending of the links under their own weight (parabolic bending moment)": ((1 / 4, 1 / 4), (1 / 12, 5 / 12)),
}


def bending_alternatives(mech, kin, data, act_jac: np.ndarray, pairs: dict) -> list:
    """Columns of "the deformation is link bending, not joint yield", one set per beam load of :data:`BEAM_BENDING`.

    Each actuated joint ``a`` that starts a link to a parallel revolute ``b`` (``pairs``: ``a -> b``)
    has its compliance column replaced by the bending of that link, one bending compliance per
    link; the other loaded joints keep their compliance.  As many parameters as joint compliance,
    so the two fits compare by their chi-square.  Needs declared masses (returns [] otherwise).

    Returns
    -------
    list of (str, ndarray)
        The beam load in words and the columns (K, 3, n).
    """
    if not pairs:
        return []
    payload = data.metadata.get("payload", np.zeros(len(data)))
    tau = gravity_loads(mech, kin, data.q, payload)
    tau = np.tile(tau, (len(act_jac) // len(data), 1))  # the same load on a pose's orientation row (6-D)
    out = []
    for words, ((ra, rb), (na, nb)) in BEAM_BENDING.items():
        cols, bends = [], False
        for a in range(tau.shape[1]):
            if np.abs(tau[:, a]).max() <= ZERO_LOAD:
                continue
            if a in pairs:
                b = pairs[a]
                root, nxt = ra * tau[:, a] + rb * tau[:, b], na * tau[:, a] + nb * tau[:, b]
                cols.append(act_jac[:, :, a] * root[:, None] + act_jac[:, :, b] * nxt[:, None])
                bends = True
            else:
                cols.append(act_jac[:, :, a] * tau[:, a, None])
        if bends:  # no loaded link (a SCARA's arms turn about the vertical): nothing but compliance itself
            out.append((words, np.stack(cols, axis=2)))
    return out


def _on_joints(cols: np.ndarray, effect, joints: set) -> np.ndarray | None:
    """The columns of a per-joint effect on ``joints`` only (None when it has none there, or no joint labels)."""
    labels = getattr(effect, "param_joints", None)
    if not labels or len(labels) != cols.shape[2]:
        return None
    idx = [i for i, j in enumerate(labels) if j in joints]
    return cols[:, :, idx] if idx and len(idx) < len(labels) else None


def separating_measurement(x: str, y: str, data, spectra: dict, effects: dict, masses_known: bool) -> str:
    """Words for the measurement that would separate effect ``x`` from ``y`` on this machine."""
    def joints_of(name):
        eff = effects.get(name)
        return list(getattr(eff, "joints", [])) if eff is not None else []

    if {x, y} == {"joint-clearance", "backlash-gravity"}:
        return ("measuring the play of each leg's joints and of its screw's nut directly (a dial gauge across the "
                "joint under a reversed load): both follow the sign of the leg's force")
    if LEG_OFFSET in (x, y):
        return LEG_OFFSET_WORDS
    if STAND_MOTION in (x, y):
        other = y if x == STAND_MOTION else x
        if other in ("thermal", "leg-thermal"):
            return ("the same poses measured again at another temperature, the temperature no longer following the "
                    "time, or " + STAND_MOTION_WORDS)
        return STAND_MOTION_WORDS
    kx, ky = harmonic_order(x), harmonic_order(y)
    gx, gy = x in _GRAVITY, y in _GRAVITY
    if kx is not None and ky is not None and kx != ky:
        span = 2.0 * np.pi / abs(kx - ky)
        joints = [j for j in joints_of(x) if j in joints_of(y)] or joints_of(x)
        where = f"joint {joints[0]}" if len(joints) == 1 else "the joint"
        return f"poses over more than {span:.2g} rad of {where} ({x} and {y} alias over a shorter range)"
    if gx != gy:
        other = y if gx else x
        words = (f"measuring the same poses with another payload at the flange (a gravity-driven deformation follows "
                 f"the load, {other} does not)")
        if not masses_known:
            words += f", and declaring the link masses ({MASS_FIELD})"
        return words
    if gx and gy:
        return ("loads at several lever arms (a payload on a long and on a short tool) and poses where the moment on "
                "each link changes sign")
    if {"tracker-scale", "tracker-drift"} & {x, y}:
        return "measuring the same poses from a second tracker station (or a calibrated scale bar)"
    if "thermal" in (x, y):
        return "the same poses measured again at another temperature"
    if "backlash" in (x, y):
        return "the same poses approached from both directions"
    k = kx if kx is not None else ky
    if k is not None:
        name = x if kx is not None else y
        joints = joints_of(name)
        where = f"joint {joints[0]}" if len(joints) == 1 else "the revolutes"
        return f"poses over at least one period of {name} ({2.0 * np.pi / k:.2g} rad of {where})"
    return "more poses spread over the joints' ranges, where the two predictions differ"


def equivalence_sets(screen: Screen, selected: list, columns: dict, members_of: list, family: np.ndarray | None,
                     data, spectra: dict, effects: dict, masses_known: bool, bending: list = (),
                     stand: np.ndarray | None = None, legs: np.ndarray | None = None) -> list:
    """One equivalence set per named effect (see the module docstring).

    Parameters
    ----------
    screen : Screen
        Rigid residuals, weights and geometric columns.
    selected : list of str
        The named effects.
    columns : dict
        Effect name -> (columns (K, 3, n), prior std) of every candidate.
    members_of : list of str
        Candidates that may join a set (tried, not absorbed, not refused as implausible).
    family : ndarray or None
        Columns of the ``gravity-deformation`` family (:func:`gravity_family`).
    bending : list of (str, ndarray)
        Link bending in place of joint compliance (:func:`bending_alternatives`): a named
        ``compliance`` whose fit one of them matches within the threshold (by the signature or
        by the chi-square of the data) shares its set with ``gravity-deformation``.
    stand : ndarray or None
        Columns of the family ``stand-motion`` (:func:`stand_motion_family`).
    legs : ndarray or None
        Columns of the family ``leg-temperature-offset`` (:func:`.leg_pattern.leg_offset_family`): each leg of a
        parallel machine longer by an offset that follows the temperature.

    Returns
    -------
    list of dict
        ``{"effect", "members", "separating_measurement", "evidence"}``: ``members`` starts
        with the named effect; ``evidence`` gives, per other candidate, the chi-square by
        which it misses the named effect's signature.
    """
    pre = screen.prepared()
    y = pre["rw"]
    out = []
    for x in selected:
        others = [n for n in selected if n != x]
        b = np.concatenate([pre["jw"]] + [screen.weighted(columns[n][0]) for n in others], axis=1)
        qb = _orth(b / np.linalg.norm(b, axis=0).clip(min=1e-300))
        xw = screen.weighted(columns[x][0])
        xw = xw - qb @ (qb.T @ xw)
        qx = _orth(xw)
        s_x = qx @ (qx.T @ y)  # X's fitted signature, off the geometry and the others
        strength = float(s_x @ s_x)
        members, evidence = [x], []

        def misses(cols: np.ndarray) -> float:
            c = cols - qb @ (qb.T @ cols)
            qc = _orth(c)
            r = s_x - qc @ (qc.T @ s_x)
            return float(r @ r)

        y_off = y - qb @ (qb.T @ y)
        chi2_x = float((y_off - s_x) @ (y_off - s_x))

        def fits_worse(cols: np.ndarray) -> float:
            """Chi-square of the data with ``cols`` in X's place, minus X's (negative: fits better)."""
            qc = _orth(cols - qb @ (qb.T @ cols))
            r = y_off - qc @ (qc.T @ y_off)
            return float(r @ r) - chi2_x

        n_rows = len(y)
        k_x = qx.shape[1]
        joints_x = set(getattr(effects.get(x), "joints", None) or []) if is_jointwise(x) else set()
        for name in members_of:
            if name == x or name not in columns:
                continue
            cols = columns[name][0]
            local = _on_joints(cols, effects.get(name), joints_x) if is_jointwise(name) and joints_x else None
            variants = [cols] + ([local] if local is not None else [])
            miss = min(misses(screen.weighted(c)) for c in variants)
            # the data's own verdict: the candidate in X's place (on X's joints when it has per-joint parameters)
            # fits them within the threshold, its parameters counted (BIC)
            c = local if local is not None else cols
            worse = fits_worse(screen.weighted(c)) + (_orth(screen.weighted(c) - qb @ (qb.T @ screen.weighted(c))
                                                            ).shape[1] - k_x) * np.log(n_rows)
            evidence.append({"effect": name, "misses_chi2": miss, "fits_worse_bic": worse})
            if miss < EQUIVALENT_CHI2 or worse < EQUIVALENT_CHI2:
                members.append(name)
        gravity_members = [m for m in members if m in DEFORMATIONS and m != x]
        if family is not None and family.shape[2]:
            miss = misses(screen.weighted(family))
            evidence.append({"effect": GRAVITY_FAMILY, "misses_chi2": miss})
            unseen = False
            for words, cols in (bending if x == "compliance" else []):
                w = screen.weighted(cols)
                swap = {"effect": f"{GRAVITY_FAMILY}: {words}", "misses_chi2": misses(w), "fits_worse_chi2": fits_worse(w)}
                evidence.append(swap)
                unseen |= min(swap["misses_chi2"], swap["fits_worse_chi2"]) < EQUIVALENT_CHI2
            if (x in DEFORMATIONS and (gravity_members or unseen)) or (x not in DEFORMATIONS and miss < EQUIVALENT_CHI2):
                members.append(GRAVITY_FAMILY)
        for family_name, family_cols in ((STAND_MOTION, stand), (LEG_OFFSET, legs)):
            if family_cols is None or not family_cols.shape[2]:
                continue
            w = screen.weighted(family_cols)
            k_s = _orth(w - qb @ (qb.T @ w)).shape[1]
            swap = {"effect": family_name, "misses_chi2": misses(w),
                    "fits_worse_bic": fits_worse(w) + (k_s - k_x) * np.log(n_rows)}
            evidence.append(swap)
            if swap["misses_chi2"] < EQUIVALENT_CHI2 or swap["fits_worse_bic"] < EQUIVALENT_CHI2:
                members.append(family_name)
        ways = list(dict.fromkeys(separating_measurement(x, m, data, spectra, effects, masses_known)
                                  for m in members[1:]))
        out.append({"effect": x, "members": members, "separating_measurement": "; ".join(ways),
                    "signature_chi2": strength, "threshold_chi2": EQUIVALENT_CHI2,
                    "evidence": sorted(evidence, key=lambda e: e["misses_chi2"])[:6]})
    return out
