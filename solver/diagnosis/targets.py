"""Several reflectors and 6-D rows in the diagnosis: one answer per robot, and a check per target.

Units: lengths in mm, angles in rad.

* **6-D rows** (:func:`as_points`): a measured pose of the target frame is the same
  information as three of its points: its origin and the points at a lever ``L`` along
  its x and y axes, ``L = sigma_position / sigma_orientation`` (the header's noises), so
  that the orientation counts as much as the position.  Each becomes a target of its own
  (``<target>.o``, ``<target>.x``, ``<target>.y``) with its own 1-sigma per row
  (origin: the position noise; the others: ``sqrt(sigma_p^2 + (L sigma_r)^2)``).  The
  three points of one pose share the position error, which the chi-square tests ignore:
  their expectation is right, their spread slightly larger than assumed (stated in
  ``docs/diagnosis.md``).
* **Per target** (:func:`per_target_check`): the whole file is diagnosed once (the
  answer); each reflector alone is diagnosed again, and the answers are compared
  (:func:`targets_agree`): a target that names an effect outside every equivalence set of
  the whole, finds an explained gap where the whole finds none, or whose inputs are
  wrong alone, contradicts it.  A target that, with a fraction of the data, finds less
  (no significant gap, unexplained, understated noise, or over-fitting of its few
  equations) does not: a test with less data has less power, it does not tell another
  story.
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.calibration.measurements import MeasurementSet
from hyperstat.solver.errors import HyperstatError
from hyperstat.solver.kinematics.frames import so3_exp

__all__ = ["PointSet", "as_points", "only_targets", "real_targets", "per_target_check", "targets_agree"]


class PointSet(MeasurementSet):
    """A measurement set with its own 1-sigma per row (mm): the points derived from 6-D rows."""

    row_sigma: np.ndarray | None = None
    real_target: list | None = None  # the file's target each row comes from

    def subset(self, rows: np.ndarray) -> "PointSet":
        out = MeasurementSet.subset(self, rows)
        new = PointSet(**{k: getattr(out, k) for k in out.__dataclass_fields__})
        idx = np.nonzero(rows)[0] if np.asarray(rows).dtype == bool else np.asarray(rows)
        new.row_sigma = None if self.row_sigma is None else np.asarray(self.row_sigma)[idx]
        new.real_target = None if self.real_target is None else [self.real_target[i] for i in idx]
        return new


def as_points(data: MeasurementSet | None) -> MeasurementSet | None:
    """The set with every 6-D row replaced by three points of its target frame (see the module docstring)."""
    if data is None or data.rotation is None:
        return data
    if data.noise is None or not data.rotation_noise:
        return data  # the diagnosis refuses a set without a noise model anyway
    sigma_p = data.noise.sigma(np.linalg.norm(data.position, axis=1))
    lever = float(np.clip(np.median(sigma_p) / data.rotation_noise, 10.0, 500.0))
    rot = so3_exp(data.rotation)  # (K, 3, 3), target frame in the tracker frame
    k = len(data)
    names = list(data.target_names)
    new_names = [f"{t or 'T'}.{p}" for t in names for p in ("o", "x", "y")]
    offsets = [np.zeros(3), np.array([lever, 0.0, 0.0]), np.array([0.0, lever, 0.0])]
    pos, idx, rows, sig, real = [], [], [], [], []
    for p, off in enumerate(offsets):
        pos.append(data.position + np.einsum("kij,j->ki", rot, off))
        idx.append(3 * np.asarray(data.target_index) + p)
        rows.append(np.arange(k))
        sig.append(sigma_p if p == 0 else np.sqrt(sigma_p**2 + (lever * data.rotation_noise) ** 2))
        real.append([names[int(t)] for t in data.target_index])
    order = np.argsort(np.concatenate(rows), kind="stable")
    pos = np.concatenate(pos)[order]
    idx = np.concatenate(idx)[order]
    src = np.concatenate(rows)[order]
    sig = np.concatenate(sig)[order]
    real = [r for part in real for r in part]
    real = [real[i] for i in order]
    out = PointSet([f"{data.pose_id[i]}/{new_names[t]}" for i, t in zip(src, idx)], list(data.joints), data.q[src], pos,
                   None, {k2: v[src] for k2, v in data.metadata.items()}, data.noise, data.tracker, None,
                   data.mechanism, data.source, idx.astype(int), new_names, {}, [data.pose_id[i] for i in src], None)
    out.row_sigma = sig
    out.real_target = real
    out.lever_mm = lever
    return out


def real_targets(data: MeasurementSet) -> list:
    """The targets checked one by one: the file's own reflectors, or, for a single 6-D target, its three points.

    Three points of one 6-D target are not independent reflectors (one pose estimate gives
    them), but each alone carries part of it: the check then asks whether the answer
    depends on which point of the target frame is read.
    """
    rt = getattr(data, "real_target", None)
    if rt is not None and len(set(rt)) > 1:
        return list(dict.fromkeys(rt))
    return [t for t in data.target_names]


def only_targets(data: MeasurementSet | None, target: str) -> MeasurementSet | None:
    """The rows of one target (a reflector, or one point of a 6-D target), re-indexed as a set of its own."""
    if data is None:
        return None
    rt = getattr(data, "real_target", None)
    if rt is not None and target in rt:
        rows = np.array([r == target for r in rt])
    elif target in data.target_names:
        rows = np.asarray(data.target_index) == data.target_names.index(target)
    else:
        return None
    if not rows.any():
        return None
    sub = data.subset(rows)
    used = list(dict.fromkeys(sub.target_names[int(i)] for i in sub.target_index))
    sub.target_index = np.array([used.index(sub.target_names[int(i)]) for i in sub.target_index], dtype=int)
    sub.target_names = used
    sub.target_priors = {t: v for t, v in sub.target_priors.items() if t in used}
    return sub


def targets_agree(whole: dict, per_target: list) -> tuple[bool, str]:
    """Whether each target alone tells the same story as the whole file, and the words for it.

    ``whole`` has the whole file's ``outcome``, ``named_effects`` and ``equivalence_sets``;
    each entry of ``per_target`` its ``target``, ``outcome`` and ``named_effects``.
    """
    allowed = set(whole["named_effects"])
    for s in whole["equivalence_sets"]:
        allowed |= set(s["members"])
    gap_whole = whole["outcome"] != "no significant gap"
    found = {"explained", "partly explained"}
    bad, weaker = [], []
    for t in per_target:
        other = [n for n in t["named_effects"] if n not in allowed]
        if other:
            bad.append(f"target {t['target']} names {', '.join(other)}, outside the whole file's answer")
        elif t["outcome"] in found and not gap_whole:
            bad.append(f"target {t['target']} finds a gap ({t['outcome']}) the whole file does not")
        elif t["outcome"] == "inputs wrong" and whole["outcome"] != "inputs wrong":
            bad.append(f"target {t['target']} answers 'inputs wrong' (its columns or its offset are at fault)")
        elif t["outcome"] != whole["outcome"] or set(t["named_effects"]) != set(whole["named_effects"]):
            weaker.append(f"target {t['target']}: {t['outcome']}"
                          + (f" by {' + '.join(t['named_effects'])}" if t["named_effects"] else ""))
    if bad:
        return False, "the targets disagree: " + "; ".join(bad)
    words = "each target alone tells the same story as the whole file"
    if weaker:
        words += (" or less of it (with a fraction of the data a test has less power and a fit over-fits sooner; "
                  "that is not another answer): "
                  + "; ".join(weaker))
    return True, words


def per_target_check(run, data: MeasurementSet, validation: MeasurementSet | None) -> list:
    """Diagnose each of the file's targets alone with ``run(data, validation) -> Diagnosis``.

    Returns ``[{"target", "outcome", "named_effects", "validation_before", "validation_after"}]``
    (RMS in mm); a target with too few rows to fit is reported with the reason.
    """
    out = []
    for t in real_targets(data):
        d_t, v_t = only_targets(data, t), only_targets(validation, t)
        entry = {"target": t}
        try:
            diag = run(d_t, v_t)
        except (HyperstatError, np.linalg.LinAlgError, ValueError) as exc:  # too few rows to fit: the whole stands
            entry.update(outcome="not diagnosed", named_effects=[], reason=f"{type(exc).__name__}: {exc}")
        else:
            entry.update(outcome=diag.outcome, named_effects=list(diag.named_effects),
                         validation_before=(diag.validation_before or {}).get("rms"),
                         validation_after=(diag.validation_after or {}).get("rms"))
        out.append(entry)
    return out
