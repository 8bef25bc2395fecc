"""Step 2 of the diagnosis: where the residual lies (regions, directions, variables) and its structure tests.

Units: lengths in mm, angles in rad; spectra in cycles per revolution (revolutes) or
periods in mm (screws).

The structure tests (:func:`structure_tests`) are regressions of the weighted residual,
projected off the fitted columns, each with its F-test; the per-revolute spectrum is the
share of the residual variance a periodic error of that joint explains at each order.
Its resolution is the Rayleigh limit of the range the joint moved: two orders ``k1, k2``
alias when ``|k1 - k2| * range < 2 pi``, i.e. closer than ``2 pi / range`` cycles per
revolution (:func:`spectrum_resolution`).
"""

from __future__ import annotations

import numpy as np
from scipy.special import chdtrc, fdtrc  # survival functions; scipy.stats costs 1.3 s more to import

from hyperstat.solver.calibration.identify import IdentificationResult
from hyperstat.solver.calibration.measurements import MeasurementSet
from hyperstat.solver.diagnosis.effects.actuator import screw_lead
from hyperstat.solver.kinematics.model import Mechanism

__all__ = ["ResidualField", "structure_tests", "describe_where", "where_summary", "spectrum_resolution",
           "spectrum_peaks", "target_homogeneity", "targets_words", "P_THRESHOLD", "SPECTRUM_ORDERS"]

P_THRESHOLD = 1e-3
SPECTRUM_ORDERS = np.arange(0.5, 8.01, 0.25)  # cycles per revolution of the revolute spectra


def spectrum_resolution(joint_range: float) -> float:
    """Cycles per revolution below which two orders alias over a joint range (rad): ``2 pi / range``.

    >>> round(spectrum_resolution(1.6), 2)
    3.93
    """
    return float(2.0 * np.pi / max(joint_range, 1e-12))


class ResidualField:
    """The weighted residual projected off the fitted columns, and F-tests of regressors against it.

    Parameters
    ----------
    resid : ndarray, (K, 3)
        Residuals (mm).
    w : ndarray, (K,)
        Weights 1/sigma (1/mm).
    basis : ndarray, (3K, r)
        Orthonormal basis of the fitted (weighted) columns.
    """

    def __init__(self, resid: np.ndarray, w: np.ndarray, basis: np.ndarray) -> None:
        self.k = len(w)
        self.w = w
        self.basis = basis
        y = (resid * w[:, None]).reshape(3 * self.k)
        self.y = y - basis @ (basis.T @ y)
        self.total = float(self.y @ self.y)
        self.dof = max(3 * self.k - basis.shape[1], 10)

    def project(self, cols: np.ndarray) -> np.ndarray:
        """Weighted columns (K, 3, n) projected off the basis, unit norm (zero columns dropped), (3K, m)."""
        x = (cols * self.w[:, None, None]).reshape(3 * self.k, -1)
        x = x - self.basis @ (self.basis.T @ x)
        norms = np.linalg.norm(x, axis=0)
        keep = norms > 1e-9 * max(float(norms.max()) if norms.size else 0.0, 1e-300)
        return x[:, keep] / norms[keep]

    def fit(self, cols: np.ndarray) -> tuple[float, float, float, np.ndarray | None, float]:
        """Share of the residual variance, F, p-value, fitted field (3K,) and explained chi-square of ``cols``."""
        x = self.project(cols)
        if x.shape[1] == 0 or self.total <= 0:
            return 0.0, 0.0, 1.0, None, 0.0
        gram = x.T @ x
        coef = np.linalg.lstsq(gram, x.T @ self.y, rcond=1e-10)[0] if x.shape[1] > 1 else (x.T @ self.y) / gram[0, 0]
        fitted = x @ coef
        explained = float(fitted @ fitted)
        p = x.shape[1]
        d2 = max(self.dof - p, 1)
        f = (explained / p) / max((self.total - explained) / d2, 1e-300)
        return explained / self.total, float(f), float(fdtrc(p, d2, f)), fitted, explained

    def scale(self) -> float:
        """Residual variance per degree of freedom, at least 1 (chi-square differences are divided by it)."""
        return max(1.0, self.total / self.dof)

    def harmonic(self, act_col: np.ndarray, qv: np.ndarray, order: float) -> float:
        """Explained chi-square of a periodic error ``sin, cos(order q)`` of one joint (its column ``act_col``)."""
        g = np.column_stack([np.sin(order * qv), np.cos(order * qv)])
        return self.fit(act_col[:, :, None] * g[:, None, :])[4]


def structure_tests(mech: Mechanism, data: MeasurementSet, resid: np.ndarray, w: np.ndarray, basis: np.ndarray,
                    r_trk: np.ndarray, act_jac: np.ndarray, target_jac: np.ndarray | None = None,
                    candidates: dict | None = None, positions: int | None = None) -> dict:
    """Does the residual field have structure?  F-tests of regressions the fit cannot absorb, and isotropy.

    Three families of regressors, each projected off the fitted columns (``basis``, an
    orthonormal basis of the weighted Jacobian of the fit) before it is tested:

    * **joint errors**: the residual an error of actuator ``j`` would leave,
      ``d position / d q_j`` times ``g(v)``, with ``g`` a linear and quadratic trend in
      every joint value and metadata column ``v`` (a gear ratio error, a coupling between
      two joints, a load-dependent error), or ``sin, cos`` of the joint's own value at each
      frequency of a grid (0.5 to 8 cycles per revolution for a revolute; periods 2 mm to a
      third of the travel for a screw): the spectrum per revolute and per screw;
    * **base-frame trends**: a displacement along x, y, z of the base that follows a joint
      value or a metadata column (linear and quadratic);
    * **tool-frame trends**: a displacement along an axis of the output frame that follows
      a joint value or a metadata column (a tool that grows with the temperature);
    * **candidate signatures**: the columns of each candidate effect (``candidates``), so
      that a residual an effect fits in sample but cannot predict in held-out blocks is
      not taken for noise.

    Each regression has its F-test against the rest of the residual variance
    (scale-free: it holds whatever the true noise level); the family is judged at
    ``1e-3 / number of tests`` (Bonferroni).  Isotropy: Bartlett's test of equal variance
    in the three base-frame directions, each component divided by ``sqrt(1 - leverage)``.

    Parameters
    ----------
    mech : Mechanism
        The model (joint types).
    data : MeasurementSet
        Poses and metadata.
    resid : ndarray, (K, 3)
        Residuals in the tracker frame (mm).
    w : ndarray, (K,)
        Weights 1/sigma (1/mm).
    basis : ndarray, (3K, r)
        Orthonormal basis of the fitted (weighted) columns; ``r`` is the rank used.
    r_trk : ndarray, (3, 3)
        Tracker rotation in the base frame.
    act_jac : ndarray, (K, 3, n_act)
        ``d position / d q_a`` (tracker frame, unweighted).
    target_jac : ndarray, (K, 3, 3), optional
        ``d position / d target offset`` (the output frame's axes in the tracker frame).
    candidates : dict, optional
        Effect name -> its columns (K, 3, n_e) (tracker frame, unweighted).
    positions : int, optional
        With 6-D data the rows are the positions then the orientations (:mod:`.observations`);
        the first ``positions`` rows are positions (directions and isotropy use them alone).

    Returns
    -------
    dict
        ``tests`` (the 12 most significant: family, variable, joint, frequency or period,
        share, F, p_value, direction), ``best``, ``structured``, ``threshold``,
        ``n_tests``, ``isotropy``, ``isotropic``, ``spectra`` (screws, periods in mm),
        ``revolute_spectra`` (cycles per revolution, with the joint's ``range_rad`` and
        ``resolution_cycles_per_revolution``) and ``field`` (the :class:`ResidualField`).
    """
    k = len(w)
    npos = k if positions is None else positions
    field = ResidualField(resid, w, basis)
    tests = []
    fits: dict = {}

    def ftest(cols: np.ndarray) -> tuple[float, float, float, int]:
        share, f, p, fitted, _ = field.fit(cols)
        if fitted is None:
            return 0.0, 0.0, 1.0, -1
        key = len(fits)
        fits[key] = fitted
        return share, f, p, key

    def direction(key: int) -> list:
        """Dominant base-frame direction of a fitted field (first right singular vector)."""
        if key < 0:
            return [0.0, 0.0, 0.0]
        field_base = (fits[key].reshape(k, 3)[:npos] / w[:npos, None]) @ r_trk.T
        _, _, vt = np.linalg.svd(field_base, full_matrices=False)
        return (vt[0] * np.sign(vt[0][np.argmax(np.abs(vt[0]))])).tolist()

    def scaled(v: np.ndarray) -> np.ndarray:
        return (v - v.mean()) / max(float(np.std(v)), 1e-300)

    variables = {f"q{j}": data.q[:, a] for a, j in enumerate(data.joints) if np.ptp(data.q[:, a]) > 0}
    variables.update({name: v for name, v in data.metadata.items() if np.ptp(v) > 0})
    trends = {}
    for name, v in variables.items():
        x = scaled(v)
        trends[name] = x[:, None] if len(set(v.tolist())) <= 2 else np.column_stack([x, x**2])
    spectra, rspectra = [], []
    for a, i in enumerate(mech.actuated):
        joint = data.joints[a]
        col = act_jac[:, :, a]
        for name, g in trends.items():
            share, f, p, d = ftest(col[:, :, None] * g[:, None, :])
            tests.append({"family": "joint error", "joint": joint, "variable": name, "kind": "trend", "share": share,
                          "F": f, "p_value": p, "direction": d})
        qv = data.q[:, a]
        if np.ptp(qv) <= 0:
            continue
        revolute = mech.joints[i].type == "R"
        if revolute:
            freqs = SPECTRUM_ORDERS
            phase = np.outer(qv, freqs)  # cycles per revolution: q in rad
        else:
            periods = np.linspace(2.0, max(4.0, np.ptp(qv) / 3.0), 40)
            freqs = 1.0 / periods
            phase = 2.0 * np.pi * np.outer(qv, freqs)
        shares, ps = [], []
        for n, fr in enumerate(freqs):
            g = np.column_stack([np.sin(phase[:, n]), np.cos(phase[:, n])])
            share, f, p, d = ftest(col[:, :, None] * g[:, None, :])
            entry = {"family": "joint error", "joint": joint, "variable": f"q{joint}", "kind": "periodic",
                     "share": share, "F": f, "p_value": p, "direction": d}
            if revolute:
                entry["cycles_per_revolution"] = float(fr)
            else:
                entry["period_mm"] = float(1.0 / fr)
                entry["lead_mm"], entry["lead_declared"] = screw_lead(mech)  # the order in turns of the screw
            tests.append(entry)
            shares.append(share)
            ps.append(p)
        best = int(np.argmin(ps))
        if revolute:
            span = float(np.ptp(qv))
            rspectra.append({"joint": joint, "cycles_per_revolution": freqs.tolist(), "share": shares,
                             "p_value": ps, "peak_cycles_per_revolution": float(freqs[best]),
                             "peak_share": float(shares[best]), "peak_p_value": float(ps[best]),
                             "range_rad": span, "resolution_cycles_per_revolution": spectrum_resolution(span)})
        else:
            spectra.append({"joint": joint, "peak_period_mm": float(1.0 / freqs[best]),
                            "peak_share": float(shares[best]), "peak_p_value": float(ps[best]),
                            "periods_mm": (1.0 / freqs).tolist(), "power": shares,
                            "method": "share of the residual variance a periodic error of this joint explains"})
    frames = [("base frame", np.broadcast_to(r_trk.T, (k, 3, 3)))]
    if target_jac is not None:
        frames.append(("tool frame", target_jac))
    for family, axes in frames:
        for name, g in trends.items():
            cols = np.concatenate([axes[:, :, c, None] * g[:, None, :] for c in range(3)], axis=2)
            share, f, p, d = ftest(cols)
            tests.append({"family": f"{family} trend", "variable": name, "kind": "trend", "share": share, "F": f,
                          "p_value": p, "direction": d})
    if target_jac is not None:
        share, f, p, d = ftest(tool_gravity_columns(mech, r_trk, target_jac, npos))
        tests.append({"family": "tool under gravity", "variable": "tool orientation", "kind": "gravity",
                      "share": share, "F": f, "p_value": p, "direction": d})
    for name, cols in (candidates or {}).items():
        share, f, p, d = ftest(cols)
        tests.append({"family": "candidate signature", "variable": name, "kind": "effect", "share": share, "F": f,
                      "p_value": p, "direction": d})
    threshold = P_THRESHOLD / max(len(tests), 1)
    n_tests = len(tests)
    tests.sort(key=lambda t: t["p_value"])
    tests = tests[:12]
    for t in tests:
        t["direction"] = direction(t["direction"])
    # isotropy (Bartlett), leverage-corrected components, base-frame directions
    lev = np.sum(basis**2, axis=1).reshape(k, 3)[:npos] @ (r_trk.T**2)
    z = ((resid[:npos] * w[:npos, None]) @ r_trk.T) / np.sqrt(1.0 - np.clip(lev, 0.0, 0.95))
    s2 = np.sum(z**2, axis=0) / npos
    pooled = float(np.mean(s2))
    stat = (3 * npos * np.log(pooled) - float(np.sum(npos * np.log(s2)))) / (1.0 + (3.0 / npos - 1.0 / (3 * npos)) / 6.0)
    iso = {"statistic": float(stat), "p_value": float(chdtrc(2, stat)),
           "weighted_variance": dict(zip("xyz", map(float, s2))), "threshold": P_THRESHOLD}
    targets = target_homogeneity(data, z)
    return {"tests": tests, "n_tests": n_tests, "threshold": threshold,
            "best": tests[0] if tests else None,
            "structured": bool(tests and tests[0]["p_value"] < threshold),
            "isotropy": iso, "isotropic": bool(iso["p_value"] >= P_THRESHOLD),
            "targets": targets, "targets_homogeneous": targets is None or targets["p_value"] >= P_THRESHOLD,
            "spectra": spectra, "revolute_spectra": rspectra, "field": field}


def tool_gravity_columns(mech: Mechanism, r_trk: np.ndarray, target_jac: np.ndarray, positions: int) -> np.ndarray:
    """Columns (R, 3, 9) of a tool that deflects under its own weight: a displacement ``R C R^T g``, linear in ``C``.

    A tool, a probe's stylus or a spindle carried by the output frame bends elastically under gravity: its tip
    moves by ``C g_tool`` in the output frame (``C`` a 3x3 compliance times weight, mm; ``g_tool = R^T g`` the
    unit gravity vector, ``metadata['gravity']`` of the base frame, default -z, seen from the output frame), i.e.
    by ``R C R^T g`` in the base frame: a displacement that follows the tool's orientation relative to gravity, which
    no joint error and no trend of one variable reproduces (a stylus sag: ``c (g - (g . a) a)``, ``a`` the stylus
    axis).  ``target_jac`` holds the output frame's axes in the tracker frame on the position rows (zeros on the
    orientation rows of 6-D data: a probe body's orientation does not see its stylus bend); ``r_trk`` turns the
    tracker frame into the base frame.

    >>> axes = np.tile(np.eye(3), (2, 1, 1))  # two poses, the output frame along the tracker's (= base) axes
    >>> cols = tool_gravity_columns(type("M", (), {"metadata": {}})(), np.eye(3), axes, 2)
    >>> cols.shape, (cols[0, :, 8] + 0.0).tolist()  # C_zz: along the tool's z, times gravity's z in the tool frame
    ((2, 3, 9), [0.0, 0.0, -1.0])
    """
    g = np.asarray(getattr(mech, "metadata", {}).get("gravity", (0.0, 0.0, -1.0)), dtype=float)
    g_trk = r_trk.T @ (g / np.linalg.norm(g))
    g_tool = np.einsum("kic,i->kc", target_jac[:positions], g_trk)  # gravity in the output frame, per position row
    g_rows = np.concatenate([g_tool, np.zeros((len(target_jac) - positions, 3))])
    return np.concatenate([target_jac[:, :, c, None] * g_rows[:, None, d, None] for c in range(3) for d in range(3)],
                          axis=2)


def target_homogeneity(data: MeasurementSet, z: np.ndarray) -> dict | None:
    """Do the targets (reflectors) share one noise level?  Bartlett's test of equal variance across targets.

    ``z`` are the weighted, leverage-corrected position residuals (K, 3) of the rigid fit (the first rows
    of ``data``): under the file's noise model, right or understated by one factor, every reflector of a
    pose shares the tracker's noise, so their variances are equal whatever the factor.  A reflector whose
    residuals are larger (a loose or dirty nest, a reflector knocked in its nest) breaks that: the excess
    is in that target, not in the tracker.  None for one target.

    Returns
    -------
    dict or None
        ``p_value`` (chi-square with ``targets - 1`` dof), ``statistic``, ``factors`` (per target, the RMS
        of its weighted residuals: its noise factor), ``worst`` (the target with the largest factor), and
        ``rows`` per target.
    """
    names = list(getattr(data, "target_names", []) or [])
    idx = np.asarray(getattr(data, "target_index", []))[: len(z)]
    if len(names) < 2 or len(idx) != len(z):
        return None
    groups = [(t, z[idx == i]) for i, t in enumerate(names) if np.sum(idx == i) >= 5]
    if len(groups) < 2:
        return None
    n = np.array([3.0 * len(g) for _, g in groups])  # degrees of freedom: three components per row
    s2 = np.array([float(np.sum(g**2)) for _, g in groups]) / n
    pooled = float(np.sum(n * s2) / np.sum(n))
    m = len(groups)
    corr = 1.0 + (np.sum(1.0 / n) - 1.0 / np.sum(n)) / (3.0 * (m - 1))
    stat = float((np.sum(n) * np.log(pooled) - np.sum(n * np.log(s2))) / corr)
    factors = {t: float(np.sqrt(v)) for (t, _), v in zip(groups, s2)}
    return {"statistic": stat, "p_value": float(chdtrc(m - 1, stat)), "factors": factors,
            "worst": max(factors, key=factors.get), "rows": {t: len(g) for t, g in groups},
            "method": "Bartlett's test of equal variance of the weighted rigid residuals across targets"}


def targets_words(targets: dict) -> str:
    """Words for targets whose residuals differ (:func:`target_homogeneity`)."""
    worst = targets["worst"]
    others = ", ".join(f"{t} {f:.2f}x" for t, f in targets["factors"].items() if t != worst)
    return (f"the rows of target {worst}: its residuals are {targets['factors'][worst]:.2f}x the stated noise, "
            f"the other targets' {others} (Bartlett p = {targets['p_value']:.2g}); the tracker's noise is the "
            f"same for every reflector of a pose, so the excess is in target {worst} (a loose or dirty reflector "
            f"nest, a reflector moving in its nest, or its offset), not in the noise model")


def spectrum_peaks(structure: dict) -> dict:
    """The contract's ``spectrum_peaks``: per revolute joint, its peak, share, p-value and resolution."""
    return {s["joint"]: {"cycles_per_rev": s["peak_cycles_per_revolution"], "share": s["peak_share"],
                         "p_value": s["peak_p_value"],
                         "resolution_cycles_per_rev": s["resolution_cycles_per_revolution"],
                         "range_rad": s["range_rad"]}
            for s in structure["revolute_spectra"]}


def describe_where(test: dict | None, spectra: list | None = None) -> str:
    """One sentence for a structure test: joint, variable, frequency, direction (base frame).

    With the revolute ``spectra`` given, a periodic error carries its spectrum's resolution
    (the orders that alias over the range the joint moved).
    """
    if test is None:
        return "nowhere in particular"
    d = np.asarray(test["direction"])
    axis = "xyz"[int(np.argmax(np.abs(d)))]
    direction = f"mostly along {axis} of the base frame ({', '.join(f'{v:+.2f}' for v in d)})"
    var = test["variable"]
    follows = f"joint {var[1:]}" if var.startswith("q") else f"the metadata column '{var}'"
    if test["family"] == "candidate signature":
        what = f"the signature of the candidate '{var}' (its columns, fitted in sample)"
    elif test["family"] == "tool under gravity":
        what = ("a displacement of the measured point that follows the tool's orientation relative to gravity (a "
                "tool, a probe's stylus or a spindle bending under its weight: R C R^T g, no joint error or trend of "
                "one variable)")
    elif test["family"] == "joint error":
        if test["kind"] == "periodic" and "cycles_per_revolution" in test:
            c = test["cycles_per_revolution"]
            what = (f"an error of joint {test['joint']} at {c:g} cycle{'s' if c != 1 else ''} per revolution of joint "
                    f"{test['joint']}")
            spec = next((s for s in spectra or () if s["joint"] == test["joint"]), None)
            if spec is not None:
                what += (f" (the spectrum's peak; over the {spec['range_rad']:.2g} rad joint {test['joint']} moved, "
                         f"orders closer than {spec['resolution_cycles_per_revolution']:.2g} cycles per revolution "
                         f"alias)")
        elif test["kind"] == "periodic":
            what = f"an error of joint {test['joint']} with a period of {test['period_mm']:.1f} mm along its travel"
            if test.get("lead_mm"):
                turns = test["lead_mm"] / test["period_mm"]
                what += (f" ({turns:.2g} cycles per turn of a screw of {test['lead_mm']:g} mm lead"
                         + ("" if test.get("lead_declared", True) else ", assumed: the model declares none") + ")")
        else:
            what = f"an error of joint {test['joint']} that follows {follows}"
    else:
        what = f"a displacement along an axis of the {test['family'].split(' trend')[0]} that follows {follows}"
    return (f"{what}, {direction}: {100 * test['share']:.0f} % of the residual variance "
            f"(F-test p = {test['p_value']:.2g})")


def where_summary(rigid: IdentificationResult, data: MeasurementSet, labels: np.ndarray, structure: dict) -> dict:
    """Residual field: by region, by direction, against joint variables and metadata, spectra."""
    resid = rigid.residuals
    r_trk, _ = rigid.model.tracker_pose(rigid.theta)
    base = resid @ r_trk.T  # tracker frame -> base frame directions
    total = float(np.sum(resid**2))
    regions = []
    for b in np.unique(labels):
        rows = labels == b
        regions.append({"region": int(b), "points": int(rows.sum()),
                        "centre": {f"q{data.joints[a]}": float(data.q[rows, a].mean()) for a in range(data.q.shape[1])},
                        "rms": float(np.sqrt(np.mean(np.sum(resid[rows] ** 2, axis=1))))})
    direction = {ax: float(np.sqrt(np.mean(base[:, a] ** 2))) for a, ax in enumerate("xyz")}
    variables = {f"q{j}": data.q[:, a] for a, j in enumerate(data.joints)}
    variables.update({k: v for k, v in data.metadata.items() if np.ptp(v) > 0})
    explained = []
    for name, v in variables.items():
        x = (v - v.mean()) / (np.std(v) or 1.0)
        design = np.stack([np.ones_like(x), x, x**2], axis=1)
        coef, *_ = np.linalg.lstsq(design, base, rcond=None)
        fit = design @ coef
        explained.append({"variable": name, "share": float(np.sum(fit**2) / total) if total > 0 else 0.0})
    explained.sort(key=lambda e: -e["share"])
    return {"regions": regions, "direction_rms": direction, "explained_by": explained,
            "spectra": structure["spectra"], "revolute_spectra": structure["revolute_spectra"],
            "structure": {k: structure[k] for k in ("tests", "n_tests", "threshold", "best", "structured",
                                                     "isotropy", "isotropic", "targets", "targets_homogeneous")}}
