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

from hyperstat.solver.diagnosis.effects import MASS_FIELD, gravity_loads, gravity_regressor, harmonic_order
from hyperstat.solver.diagnosis.periodic import EQUIVALENT_CHI2
from hyperstat.solver.diagnosis.screening import Screen

__all__ = ["equivalence_sets", "gravity_family", "separating_measurement", "GRAVITY_FAMILY", "DEFORMATIONS"]

GRAVITY_FAMILY = "gravity-deformation"
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


def separating_measurement(x: str, y: str, data, spectra: dict, effects: dict, masses_known: bool) -> str:
    """Words for the measurement that would separate effect ``x`` from ``y`` on this machine."""
    def joints_of(name):
        eff = effects.get(name)
        return list(getattr(eff, "joints", [])) if eff is not None else []

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
                     data, spectra: dict, effects: dict, masses_known: bool) -> list:
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

        for name in members_of:
            if name == x or name not in columns:
                continue
            miss = misses(screen.weighted(columns[name][0]))
            evidence.append({"effect": name, "misses_chi2": miss})
            if miss < EQUIVALENT_CHI2:
                members.append(name)
        gravity_members = [m for m in members if m in DEFORMATIONS and m != x]
        if family is not None and family.shape[2]:
            miss = misses(screen.weighted(family))
            evidence.append({"effect": GRAVITY_FAMILY, "misses_chi2": miss})
            if (x in DEFORMATIONS and gravity_members) or (x not in DEFORMATIONS and miss < EQUIVALENT_CHI2):
                members.append(GRAVITY_FAMILY)
        ways = list(dict.fromkeys(separating_measurement(x, m, data, spectra, effects, masses_known)
                                  for m in members[1:]))
        out.append({"effect": x, "members": members, "separating_measurement": "; ".join(ways),
                    "signature_chi2": strength, "threshold_chi2": EQUIVALENT_CHI2,
                    "evidence": sorted(evidence, key=lambda e: e["misses_chi2"])[:6]})
    return out
