"""Several reflectors and 6-D rows: one answer per robot, and a check per target.

Units: lengths in mm, angles in rad.

The whole file is diagnosed once: every (pose, target) observation is a row, and a 6-D
observation adds an orientation row (:mod:`.observations`).  That is the answer.  Then each
target is diagnosed alone (:func:`per_target_check`) and the stories are compared
(:func:`targets_agree`): a target that names an effect outside every equivalence set of
the whole, finds an explained gap where the whole finds none, or whose inputs are wrong
alone, contradicts it.  A target that, with a fraction of the data, finds less (no
significant gap, unexplained, understated noise, or over-fitting of its few equations)
does not: a test with less data has less power, it does not tell another story.

A single 6-D target is checked through three of its points (:func:`as_points`): its origin
and the points at a lever ``L = sigma_position / sigma_orientation`` along its x and y
axes, each diagnosed alone as a 3-D target with its own noise per row (origin: the
position noise; the others: ``sqrt(sigma_p^2 + 2/3 (L sigma_r)^2)``, the mean per axis of
a rotation error ``omega x L u``).  Within one point the rows are independent.
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.calibration.measurements import MeasurementSet
from hyperstat.solver.errors import HyperstatError
from hyperstat.solver.kinematics.frames import so3_exp

__all__ = ["PointSet", "as_points", "only_targets", "targets_to_check", "per_target_check", "targets_agree"]


class PointSet(MeasurementSet):
    """A measurement set with its own 1-sigma per row (mm): the points derived from 6-D rows."""

    row_sigma: np.ndarray | None = None

    def subset(self, rows: np.ndarray) -> "PointSet":
        out = MeasurementSet.subset(self, rows)
        new = PointSet(**{k: getattr(out, k) for k in out.__dataclass_fields__})
        idx = np.nonzero(rows)[0] if np.asarray(rows).dtype == bool else np.asarray(rows)
        new.row_sigma = None if self.row_sigma is None else np.asarray(self.row_sigma)[idx]
        return new


def as_points(data: MeasurementSet | None, lever: float | None = None) -> MeasurementSet | None:
    """The set with every 6-D row replaced by three points of its target frame (see the module docstring).

    ``lever`` (mm): the distance of the x and y points from the origin; by default ``sigma_position /
    sigma_orientation`` of this set (median over its rows).  A validation set must be read at its identification
    set's lever: its own median noise differs, and a point read elsewhere on the target frame is another point (on
    the Tripteor X7, 329 against 340 mm: every held-out pose 11 mm off, "inputs wrong").

    Examples
    --------
    >>> from hyperstat.solver.calibration.measurements import MeasurementSet, NoiseModel
    >>> d = MeasurementSet(["P1"], ["q1"], np.zeros((1, 1)), np.array([[1000.0, 0.0, 0.0]]),
    ...                    noise=NoiseModel(0.005, 0.005), rotation=np.zeros((1, 3)), rotation_noise=5e-5)
    >>> as_points(d).lever_mm, as_points(d, lever=200.0).position[1].tolist()
    (200.0, [1200.0, 0.0, 0.0])
    """
    if data is None or data.rotation is None:
        return data
    if data.noise is None or not data.rotation_noise:
        return data  # the diagnosis refuses a set without a noise model anyway
    sigma_p = data.noise.sigma(np.linalg.norm(data.position, axis=1))
    if lever is None:
        lever = float(np.clip(np.median(sigma_p) / data.rotation_noise, 10.0, 500.0))
    rot = so3_exp(data.rotation)  # (K, 3, 3), target frame in the tracker frame
    k = len(data)
    names = list(data.target_names)
    new_names = [f"{t or 'T'}.{p}" for t in names for p in ("o", "x", "y")]
    offsets = [np.zeros(3), np.array([lever, 0.0, 0.0]), np.array([0.0, lever, 0.0])]
    pos, idx, rows, sig = [], [], [], []
    for p, off in enumerate(offsets):
        pos.append(data.position + np.einsum("kij,j->ki", rot, off))
        idx.append(3 * np.asarray(data.target_index) + p)
        rows.append(np.arange(k))
        sig.append(sigma_p if p == 0 else np.sqrt(sigma_p**2 + 2.0 / 3.0 * (lever * data.rotation_noise) ** 2))
    order = np.argsort(np.concatenate(rows), kind="stable")
    pos = np.concatenate(pos)[order]
    idx = np.concatenate(idx)[order]
    src = np.concatenate(rows)[order]
    sig = np.concatenate(sig)[order]
    out = PointSet([f"{data.pose_id[i]}/{new_names[t]}" for i, t in zip(src, idx)], list(data.joints), data.q[src], pos,
                   None, {k2: v[src] for k2, v in data.metadata.items()}, data.noise, data.tracker, None,
                   data.mechanism, data.source, idx.astype(int), new_names, {}, [data.pose_id[i] for i in src], None)
    out.row_sigma = sig
    out.lever_mm = lever
    return out


def targets_to_check(data: MeasurementSet, validation: MeasurementSet | None) -> list:
    """``(name, data, validation)`` of each target diagnosed alone: the file's reflectors when it has several, or
    the three points of a single 6-D target (:func:`as_points`); none for one 3-D target.

    Three points of one 6-D target are not independent reflectors (one pose estimate gives
    them), but each alone carries part of it, with independent rows: the check then asks
    whether the answer depends on which point of the target frame is read.
    """
    if data.n_targets > 1:
        return [(t, only_targets(data, t), only_targets(validation, t)) for t in data.target_names]
    if data.rotation is not None and data.noise is not None and data.rotation_noise:
        pts = as_points(data)
        vpts = as_points(validation, pts.lever_mm)  # the same points of the target frame as the identification's
        return [(t, only_targets(pts, t), only_targets(vpts, t)) for t in pts.target_names]
    return []


def only_targets(data: MeasurementSet | None, target: str) -> MeasurementSet | None:
    """The rows of one target, re-indexed as a set of its own (None if it has none)."""
    if data is None or target not in data.target_names:
        return None
    rows = np.asarray(data.target_index) == data.target_names.index(target)
    if not rows.any():
        return None
    sub = data.subset(rows)
    sub.target_index = np.zeros(int(rows.sum()), dtype=int)
    sub.target_names = [target]
    sub.target_priors = {t: v for t, v in sub.target_priors.items() if t == target}
    if target in sub.target_priors and len(sub.target_priors) == 1:
        sub.target = sub.target_priors[target]
    return sub


def targets_agree(whole: dict, per_target: list) -> tuple[bool, str]:
    """Whether each target alone tells the same story as the whole file, and the words for it.

    ``whole`` has the whole file's ``outcome``, ``named_effects``, ``equivalence_sets`` and
    ``effect_joints``; each entry of ``per_target`` its ``target``, ``outcome``, ``named_effects``
    and, when known, ``effect_joints`` and ``refused`` (the periodic effects its own spectrum refused:
    ``{"effect", "joint", "reason"}``).  The effects and their orders are compared: a target
    contradicts the whole when it names an effect outside every equivalence set of the whole
    (another order of a periodic error is another effect), names the same effect on other joints
    only, finds a gap the whole does not, answers "inputs wrong" alone, or when its own spectrum
    refuses an effect the whole names on that joint because it peaks at another order.  The order
    not being established with its fraction of the data is less power, not another story: a
    target that then names the simpler alternative on that joint (a scale error for a
    once-per-revolution error over a short range) does not contradict the whole.
    """
    allowed = set(whole["named_effects"])
    for s in whole["equivalence_sets"]:
        allowed |= set(s["members"])
    joints_whole = whole.get("effect_joints") or {}
    gap_whole = whole["outcome"] != "no significant gap"
    found = {"explained", "partly explained"}
    bad, weaker = [], []
    for t in per_target:
        # on a joint where its own data leave the whole's order unresolved (the order aliases with another, or a
        # scale error fits as well), a target that names the simpler alternative there tells less, not another story
        unresolved = {j for r in t.get("refused", []) if r.get("alias") is not None and r["effect"] in
                      whole["named_effects"] for j in (joints_whole.get(r["effect"]) or [r.get("joint")])}
        simpler = [n for n in t["named_effects"] if n not in allowed and unresolved
                   and set((t.get("effect_joints") or {}).get(n) or ["?"]) <= unresolved]
        other = [n for n in t["named_effects"] if n not in allowed and n not in simpler]
        elsewhere = [n for n, j in (t.get("effect_joints") or {}).items()
                     if n in joints_whole and j and not set(j) & set(joints_whole[n])]
        refuses = [r for r in t.get("refused", []) if r["effect"] in whole["named_effects"] and r.get("alias") is None
                   and (not joints_whole.get(r["effect"]) or r.get("joint") in joints_whole[r["effect"]])]
        if other:
            bad.append(f"target {t['target']} names {', '.join(other)}, outside the whole file's answer")
        elif elsewhere:
            bad.append(f"target {t['target']} finds {', '.join(elsewhere)} on joint(s) "
                       + ", ".join(", ".join(t["effect_joints"][n]) for n in elsewhere)
                       + ", not where the whole file does")
        elif refuses:
            bad.append(f"target {t['target']}'s own spectrum refuses {refuses[0]['effect']}: {refuses[0]['reason']}")
        elif t["outcome"] in found and not gap_whole:
            bad.append(f"target {t['target']} finds a gap ({t['outcome']}) the whole file does not")
        elif t["outcome"] == "inputs wrong" and whole["outcome"] != "inputs wrong":
            bad.append(f"target {t['target']} answers 'inputs wrong' (its columns or its offset are at fault)")
        elif t["outcome"] != whole["outcome"] or set(t["named_effects"]) != set(whole["named_effects"]):
            weaker.append(f"target {t['target']}: {t['outcome']}"
                          + (f" by {' + '.join(t['named_effects'])}" if t["named_effects"] else "")
                          + (f" ({', '.join(simpler)} where its data do not establish the order the whole file "
                             f"names)" if simpler else ""))
    if bad:
        return False, "the targets disagree: " + "; ".join(bad)
    words = "each target alone tells the same story as the whole file"
    if weaker:
        words += (" or less of it (with a fraction of the data a test has less power and a fit over-fits sooner; "
                  "that is not another answer): "
                  + "; ".join(weaker))
    return True, words


def per_target_check(run, checks: list) -> list:
    """Diagnose each target alone with ``run(data, validation) -> Diagnosis`` (``checks`` of :func:`targets_to_check`).

    Returns ``[{"target", "outcome", "named_effects", "effect_joints", "refused", "validation_before",
    "validation_after"}]`` (RMS in mm; ``refused``: the periodic effects and scale errors its own spectrum refused,
    ``alias`` set when the order was only not established); a target with too few rows to fit alone is reported as
    ``over-fitting`` (fewer equations than parameters) with the ``reason``.
    """
    out = []
    for t, d_t, v_t in checks:
        entry = {"target": t}
        try:
            diag = run(d_t, v_t)
        except (HyperstatError, np.linalg.LinAlgError, ValueError) as exc:
            # too few rows to fit this target alone: fewer equations than parameters, i.e. over-fitting; the
            # whole file's answer stands
            entry.update(outcome="over-fitting", named_effects=[], reason=f"not diagnosed alone: {exc}")
        else:
            joints = {n: j for n, j in getattr(diag, "effect_joints", {}).items() if n in diag.named_effects}
            refused = [{"effect": r["effect"], "joint": r.get("joint"), "reason": r["reason"], "alias": r.get("alias")}
                       for r in diag.rejected if r["stage"] == "spectrum"]
            entry.update(outcome=diag.outcome, named_effects=list(diag.named_effects), effect_joints=joints,
                         refused=refused, validation_before=(diag.validation_before or {}).get("rms"),
                         validation_after=(diag.validation_after or {}).get("rms"))
        out.append(entry)
    return out
