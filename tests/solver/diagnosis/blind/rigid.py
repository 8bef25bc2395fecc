"""Our own rigid-model fit, for two numbers per campaign that do not come from hyperstat:

* **visibility**: how much of the effect a full rigid calibration (every placement error,
  zero offsets, tracker frame, reflector offsets) cannot absorb, predicted on the validation
  poses: ``effect_left_val_um``.  The validation RMS a perfect calibration would then show is
  ``sqrt(noise^2 + left^2)``.
* **aliases**: the same after also fitting the columns of one library-like effect (our own
  implementation of each: angle scale, periodic errors of 0.5-4 cycles/rev, joint compliance
  under our masses, uniform thermal scaling, dead bands, our beam signatures).  A candidate
  that leaves less than 0.35x the noise RMS fits the effect within the noise on these poses.

The fit is linear (Jacobian by central differences of our forward kinematics at the true
geometry), weighted by the header's noise model, fitted on the identification poses only.
Informational: it is reported beside the scores, never used to judge an answer.
"""

from __future__ import annotations

from typing import Dict, List

import numpy as np

from . import effects as fx
from .kinematics import exp_so3, frames, gravity_torques, points


def _measure(c, geom, q, r, t, targets):
    fr = frames(c.arm, geom, q)
    pw = points(fr[-1], targets)
    return np.einsum("ji,ktj->kti", r, pw - t)


def _geometry_params(c):
    g = c.geom
    return np.concatenate([g.dxyz.ravel(), g.drot.ravel(), g.dq0])


def _set_geometry(c, theta):
    from .kinematics import Geometry
    n = c.arm.n
    m = (n + 1) * 3
    return Geometry(theta[:m].reshape(n + 1, 3), theta[m:2 * m].reshape(n + 1, 3), theta[2 * m:2 * m + n])


def rigid_jacobian(c, q=None) -> np.ndarray:
    """(K*T*3, P): d measured / d (geometry, tracker rotation, tracker origin, target offsets)."""
    q = c.q if q is None else q
    th0 = _geometry_params(c)
    h = 1e-7
    cols = []

    def m_of(theta, dr=np.zeros(3), dt=np.zeros(3), dtg=None):
        geom = _set_geometry(c, theta)
        r = c.tracker_R @ exp_so3(dr)
        tg = c.targets if dtg is None else c.targets + dtg
        return _measure(c, geom, q, r, c.tracker_t + dt, tg).ravel()

    for i in range(len(th0)):
        e = np.zeros_like(th0)
        e[i] = h
        cols.append((m_of(th0 + e) - m_of(th0 - e)) / (2 * h))
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        cols.append((m_of(th0, dr=e) - m_of(th0, dr=-e)) / (2 * h))
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        cols.append((m_of(th0, dt=e) - m_of(th0, dt=-e)) / (2 * h))
    for tgi in range(len(c.targets)):
        for i in range(3):
            e = np.zeros_like(c.targets)
            e[tgi, i] = h
            cols.append((m_of(th0, dtg=e) - m_of(th0, dtg=-e)) / (2 * h))
    return np.array(cols).T


def joint_derivatives(c) -> np.ndarray:
    """(K, T, 3, 6): d measured / d q_j at the true geometry."""
    h = 1e-7
    out = []
    for j in range(c.arm.n):
        dq = np.zeros(c.arm.n)
        dq[j] = h
        a = _measure(c, c.geom, c.q + dq, c.tracker_R, c.tracker_t, c.targets)
        b = _measure(c, c.geom, c.q - dq, c.tracker_R, c.tracker_t, c.targets)
        out.append((a - b) / (2 * h))
    return np.stack(out, axis=-1)


def candidates(c) -> Dict[str, np.ndarray]:
    """Columns (K*T*3, m) of library-like effects, our own implementation of each."""
    d = joint_derivatives(c)
    q = c.q
    out: Dict[str, np.ndarray] = {}

    def joint_cols(j, fns):
        return np.stack([(d[:, :, :, j] * f[:, None, None]).ravel() for f in fns], axis=1)

    for j in range(c.arm.n):
        out[f"angle-scale(j{j + 1})"] = joint_cols(j, [q[:, j]])
        for k in (0.5, 1, 1.5, 2, 2.5, 3, 4):
            out[f"angle-harmonic-{k:g}(j{j + 1})"] = joint_cols(j, [np.sin(k * q[:, j]), np.cos(k * q[:, j])])
        if c.case.dirs:
            out[f"backlash(j{j + 1})"] = joint_cols(j, [c.meta["dirs"][:, j]])
    tau = gravity_torques(c.arm, c.geom, q, c.meta["payload"])
    out["compliance"] = np.concatenate([joint_cols(j, [tau[:, j]]) for j in range(1, c.arm.n)], axis=1)
    for j in (1, 2):
        out[f"backlash-gravity(j{j + 1})"] = joint_cols(j, [np.sign(tau[:, j])])
    fr = frames(c.arm, c.geom, q)
    pw = points(fr[-1], c.targets)
    dT = c.meta["temperature"] - 20.0
    out["thermal"] = np.einsum("ji,ktj->kti", c.tracker_R, pw * dT[:, None, None]).ravel()[:, None]
    for which in c.arm.beams:
        ch = fx.beam(c.ctx, which, bending=1.0)
        sig = _signature(c, ch)
        out[f"beam-{which}-bending"] = sig.ravel()[:, None]
        ch = fx.beam(c.ctx, which, bending=0.0, torsion=1.0)
        out[f"beam-{which}-torsion"] = _signature(c, ch).ravel()[:, None]
    ch = fx.base_tilt(c.ctx, 1.0)
    out["base-tilt"] = _signature(c, ch).ravel()[:, None]
    return out


def _signature(c, change):
    from .generator import measure_clean
    return measure_clean(c.arm, c.geom, c.q, c.targets, c.tracker_R, c.tracker_t, change) - c.rigid


def visibility(c) -> Dict[str, object]:
    """Effect left after our rigid fit (and after each library-like candidate), in um."""
    k, nt = c.q.shape[0], len(c.targets)
    sig = np.repeat(c.sigma_header[:, :, None], 3, axis=2).ravel()
    s = (c.clean - c.rigid).ravel()
    ok = ~np.isnan(c.measured).ravel()
    rows_val = np.repeat(c.is_val, nt * 3)
    idm = ok & ~rows_val
    vam = ok & rows_val
    j = rigid_jacobian(c)
    w = 1.0 / sig

    def left(extra=None):
        a = j if extra is None else np.concatenate([j, extra], axis=1)
        aw = a * w[:, None]
        scale = np.linalg.norm(aw[idm], axis=0)
        scale[scale == 0] = 1.0
        beta, *_ = np.linalg.lstsq(aw[idm] / scale, (s * w)[idm], rcond=1e-9)
        r = s - (a / scale) @ beta
        r3 = r.reshape(k, nt, 3)
        okp = ~np.isnan(c.measured[:, :, 0])

        def rms(mask_pose):
            m = okp & mask_pose[:, None]
            return float(np.sqrt(np.mean(np.sum(r3[m] ** 2, axis=1)))) * 1e6

        return rms(~c.is_val), rms(c.is_val)

    left_id, left_val = left()
    out: Dict[str, object] = {"effect_left_id_um": left_id, "effect_left_val_um": left_val}
    noise_val = float(np.sqrt(np.mean(3 * c.sigma_header[c.is_val].ravel() ** 2))) * 1e6
    f = c.case.noise_factor
    out["expected_val_ratio"] = float(np.sqrt((f * noise_val) ** 2 + left_val ** 2) / noise_val)
    if left_val > 0.1 * noise_val:
        res: List[dict] = []
        for name, cols in candidates(c).items():
            li, lv = left(cols)
            res.append({"candidate": name, "left_val_um": round(lv, 2), "left_id_um": round(li, 2)})
        res.sort(key=lambda r: r["left_val_um"])
        out["aliases"] = res[:6]
        out["fits_within_noise"] = [r["candidate"] for r in res if r["left_val_um"] <= 0.35 * noise_val]
    else:
        out["aliases"] = []
        out["fits_within_noise"] = []
    return out
