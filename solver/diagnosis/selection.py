"""Step 3 of the diagnosis: forward selection of effects, joint by joint, grouped, with a guard at every step.

Units: lengths in mm, angles in rad; BIC and chi-square in units of the noise variance.

The candidates are the library's effects on the whole machine and, for the effects with
parameters per actuated joint (a gear harmonic, a scale error, a backlash, a screw's errors:
:func:`~hyperstat.solver.diagnosis.effects.is_jointwise`), the same effect on each joint alone
(``angle-harmonic-1@1``).  At each step the candidate that lowers the blocked cross-validated
RMS most is added when it lowers it by 5 % **and** lowers the BIC by 10 (the guard against
over-fitting at every step: held-out blocks and an information criterion), and when its own
checks pass (a periodic effect's spectrum, ``refuse``).  A periodic candidate the spectrum
refuses because it peaks elsewhere on that joint is replaced by the order at the peak
(``replace``), which is tried at once; and when no candidate passes the guard, the best
periodic ones on a joint whose spectrum has a significant peak at another order are
replaced the same way.  When still nothing passes the guard, a per-joint candidate that the structure
tests already locate (``located``: a periodic error of a joint whose residual spectrum has a
significant peak, the structure test of :mod:`.where`, judged at ``1e-3 / tests``) is added if it
lowers the cross-validated RMS by :data:`LOCATED_CV_DROP` (2 %) and the BIC by 10 and passes its
own gate (its order agrees with the spectrum and is established): the 5 % bar is an effect-size
bar, and an effect that the structure test, the BIC and the spectrum all find but that is small
against the noise must not be answered "unexplained" (the answer then says it is below the 5 %
and lowers its confidence: ``steps[...]["below_guard"]``).  The joints that need the same effect are then grouped
into one named effect, and a joint whose parameters do not pay for themselves (the BIC or the
cross-validated RMS is no worse without them) is dropped from its group again.
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.diagnosis.screening import AMBIGUOUS_SHARE, Screen, bic_of, cv_rms, split_key

__all__ = ["forward_selection", "CV_DROP", "BIC_DROP", "MAX_STEPS", "LOCATED_CV_DROP"]

CV_DROP = 0.95  #: an added effect must bring the cross-validated RMS below this times the current one
BIC_DROP = 10.0  #: ... and the BIC down by this much (Kass-Raftery "strong evidence")
MAX_STEPS = 8  #: most candidates added (joints of one effect counted apart)
#: a candidate the structure tests locate (a significant spectral peak on its joint, at its order) is added, as the
#: first effect and with a low confidence, when it brings the cross-validated RMS below this times the current one
#: (and the BIC down by :data:`BIC_DROP`, its gate passed): on the KUKA-like arm's 2/rev error of joint 2 at 1.5e-5
#: rad over 2.8 rad (seeds 0-11) the truth lowers it by 2.8 to 6.2 %, the BIC by 16 to 52.  Only a joint whose
#: spectrum has a significant peak (the structure tests' threshold) is eligible: a campaign without effect, or with an
#: understated noise, has none (the same arm's 12 + 12: smallest spectral p-value 4e-3, threshold 4e-6)
LOCATED_CV_DROP = 0.98
PRESELECT = 8  #: candidates cross-validated at each step: those with the lowest BIC


def _stack(cols: list, priors: list):
    if not cols:
        return None, None
    return np.concatenate(cols, axis=2), np.concatenate(priors)


def forward_selection(screen: Screen, pool: dict, base_cv: float, base_bic: float, max_effects: int,
                      refuse=None, replace=None, peaks: tuple = (), located=None) -> dict:
    """Forward selection over ``pool`` (see the module docstring).

    Parameters
    ----------
    pool : dict
        Candidate key -> ``{"entry": screening entry, "columns": (cols (R, 3, n), prior (n,)),
        "joints": parameter joint per column or None}``; a key ``name@joint`` is ``name`` on one
        joint.  Entries with ``note`` (absorbed by the geometry) or ``rejected`` are not added.
    max_effects : int
        Most effects named (an effect on several joints counts once).
    refuse : callable, optional
        ``refuse(key, chosen) -> dict | None``: why the candidate must not be added now, given the
        candidates ``chosen`` so far (``{"effect", "stage", "reason", ...}``); it is then marked
        rejected.
    peaks : tuple of str
        Joints whose residual spectrum has a significant peak: when no candidate passes the guard,
        the periodic candidates on those joints are checked against their spectrum (and replaced
        by the order at the peak).
    replace : callable, optional
        ``replace(key, refusal, chosen) -> str | None``: a candidate key to try instead (added to
        ``pool`` by the caller), e.g. the order at the spectrum's peak.
    located : callable, optional
        ``located(key) -> bool``: whether the structure tests locate the candidate (its joint's
        spectrum has a significant peak, the candidate is a periodic error of that joint).  When
        nothing passes the guard at the first step, such a candidate that lowers the
        cross-validated RMS by :data:`LOCATED_CV_DROP` and the BIC by :data:`BIC_DROP` and passes
        ``refuse`` is added (its step marked ``below_guard``).

    Returns
    -------
    dict
        ``selected`` (effect names in the order they were first added), ``joints`` (effect ->
        joints of its group, or None for an effect of the whole machine), ``columns`` (effect ->
        the group's columns and prior), ``steps`` (what each step added, its cross-validated RMS
        and BIC), ``refused``, ``ties``, ``pruned`` (joints dropped from a group, with the reason).
    """
    chosen: list = []  # keys, in order
    steps, refused, ties = [], [], []
    current_cv, current_bic = base_cv, base_bic
    cols, priors = [], []
    for _ in range(MAX_STEPS):
        names = {split_key(k)[0] for k in chosen}
        trials, looks = [], []
        for key, cand in pool.items():
            name, joint = split_key(key)
            entry = cand["entry"]
            if key in chosen or entry.get("note") or entry.get("rejected"):
                continue
            if name not in names and len(names) >= max_effects:
                continue
            if _covered(key, chosen, pool):
                continue
            ex, pr = _stack(cols + [cand["columns"][0]], priors + [cand["columns"][1]])
            looks.append((bic_of(screen, ex, pr), key, ex, pr))
        # the cross-validation (a refit per fold) for the candidates the BIC finds best; one that lowers the BIC by
        # less than the step's threshold cannot be added anyway
        looks.sort(key=lambda t: t[0])
        for bic0, key, ex, pr in looks[:PRESELECT]:
            cv, bic, _, _ = cv_rms(screen, ex, pr)
            trials.append((cv, bic, key))
        trials.sort(key=lambda t: t[0])
        pick = None
        queue = list(trials)
        while queue:
            cv, bic, key = queue.pop(0)
            if not (cv < CV_DROP * current_cv and bic < current_bic - BIC_DROP):
                break
            why = refuse(key, chosen) if refuse is not None else None
            if why is None:
                pick = (cv, bic, key)
                break
            refused.append(why)
            pool[key]["entry"]["rejected"] = why["reason"]
            new = replace(key, why, chosen) if replace is not None else None
            if new is not None and new in pool and new not in chosen and not pool[new]["entry"].get("rejected") \
                    and not pool[new]["entry"].get("note"):
                ex, pr = _stack(cols + [pool[new]["columns"][0]], priors + [pool[new]["columns"][1]])
                cv2, bic2, _, _ = cv_rms(screen, ex, pr)
                queue.insert(0, (cv2, bic2, new))  # tried at once, in the refused one's place
        if pick is None and refuse is not None and replace is not None:
            on_peaks = [t for t in trials if split_key(t[2])[1] in peaks][:3]
            pick = _at_the_peak(screen, pool, on_peaks, chosen, cols, priors, current_cv, current_bic, refuse,
                                replace, refused)
        below_guard = False
        if pick is None and located is not None and not chosen:
            pick = _located_below_guard(trials, current_cv, current_bic, refuse, located, chosen)
            below_guard = pick is not None
        if pick is None:
            break
        cv, bic, key = pick
        gain = current_cv**2 - cv**2
        for cv2, _, key2 in trials:
            if key2 == key or split_key(key2)[0] == split_key(key)[0]:
                continue
            gain2 = current_cv**2 - cv2**2
            if gain2 >= AMBIGUOUS_SHARE * gain:
                both, *_ = cv_rms(screen, *_stack(cols + [pool[key]["columns"][0], pool[key2]["columns"][0]],
                                                  priors + [pool[key]["columns"][1], pool[key2]["columns"][1]]))
                if cv**2 - both**2 < 0.2 * gain2:
                    ties.append({"effects": [split_key(key)[0], split_key(key2)[0]], "cv_rms": [cv, cv2],
                                 "note": f"{key} and {key2} explain the same part of the gap"})
            break
        steps.append({"added": key, "cv_rms_before": current_cv, "cv_rms_after": cv,
                      "delta_bic": bic - current_bic, **({"below_guard": True} if below_guard else {})})
        chosen.append(key)
        cols.append(pool[key]["columns"][0])
        priors.append(pool[key]["columns"][1])
        current_cv, current_bic = cv, bic
    groups = _group(chosen, pool)
    pruned = _prune(screen, groups, pool)
    return {"selected": list(groups), "joints": {n: g["joints"] for n, g in groups.items()},
            "columns": {n: (g["cols"], g["prior"]) for n, g in groups.items()}, "keys": chosen, "steps": steps,
            "refused": refused, "ties": ties, "pruned": pruned}


def _at_the_peak(screen: Screen, pool: dict, best: list, chosen: list, cols: list, priors: list, current_cv: float,
                 current_bic: float, refuse, replace, refused: list):
    """When no candidate passes the step's guard: the best periodic candidates whose spectrum peaks at another order
    on their joint are replaced by the order at the peak, which is added if it passes the guard and its own gate."""
    for _, _, key in best:
        why = refuse(key, chosen)
        if why is None or why.get("alias") is not None:
            continue
        new = replace(key, why, chosen)
        if new is None or new not in pool or new in chosen or pool[new]["entry"].get("rejected") \
                or pool[new]["entry"].get("note"):
            continue
        refused.append(why)
        pool[key]["entry"]["rejected"] = why["reason"]
        ex, pr = _stack(cols + [pool[new]["columns"][0]], priors + [pool[new]["columns"][1]])
        cv, bic, _, _ = cv_rms(screen, ex, pr)
        if cv < CV_DROP * current_cv and bic < current_bic - BIC_DROP and refuse(new, chosen) is None:
            return cv, bic, new
    return None


def _located_below_guard(trials: list, current_cv: float, current_bic: float, refuse, located, chosen: list):
    """The candidate the structure tests locate that lowers the CV RMS by :data:`LOCATED_CV_DROP` (not the 5 % of
    the guard) and the BIC by :data:`BIC_DROP`, its gate passed; the one with the lowest CV RMS (None if none)."""
    for cv, bic, key in trials:  # sorted by CV RMS
        if not located(key) or not (cv < LOCATED_CV_DROP * current_cv and bic < current_bic - BIC_DROP):
            continue
        if refuse is None or refuse(key, chosen) is None:
            return cv, bic, key
    return None


def _covered(key: str, chosen: list, pool: dict) -> bool:
    """Whether ``key``'s joints are already in the selection under the same effect (nothing to add)."""
    name, joint = split_key(key)
    have = set()
    for k in chosen:
        n, j = split_key(k)
        if n != name:
            continue
        if j is None:
            return True  # the effect is already on every joint
        have.add(j)
    if joint is not None:
        return joint in have
    return bool(pool[key].get("joints")) and set(pool[key]["joints"]) <= have


def _group(chosen: list, pool: dict) -> dict:
    """Effect name -> ``{"joints", "cols", "prior", "parts"}``: the chosen candidates of each effect merged by joint."""
    groups: dict = {}
    for key in chosen:
        name, joint = split_key(key)
        cand = pool[key]
        g = groups.setdefault(name, {"parts": {}, "whole": None})
        if joint is None:
            g["whole"] = key
        else:
            g["parts"][joint] = key
    out = {}
    for name, g in groups.items():
        whole = pool[g["whole"]] if g["whole"] else None
        if whole is not None and whole.get("joints"):
            # the whole effect on every joint: its columns, per joint
            per = {}
            for j in dict.fromkeys(whole["joints"]):
                idx = [i for i, pj in enumerate(whole["joints"]) if pj == j]
                per[j] = (whole["columns"][0][:, :, idx], whole["columns"][1][idx])
        elif whole is not None:
            out[name] = {"joints": None, "cols": whole["columns"][0], "prior": whole["columns"][1], "per": None}
            continue
        else:
            per = {j: pool[k]["columns"] for j, k in g["parts"].items()}
        joints = list(per)
        out[name] = {"joints": joints, "per": per, "cols": np.concatenate([per[j][0] for j in joints], axis=2),
                     "prior": np.concatenate([per[j][1] for j in joints])}
    return out


def _prune(screen: Screen, groups: dict, pool: dict) -> list:
    """Drop from each group the joints whose parameters do not pay for themselves (BIC and CV no worse without)."""
    pruned = []

    def score(skip: tuple | None = None):
        cols, priors = [], []
        for n, g in groups.items():
            if g["per"] is None:
                cols.append(g["cols"])
                priors.append(g["prior"])
                continue
            for j in g["joints"]:
                if skip == (n, j):
                    continue
                cols.append(g["per"][j][0])
                priors.append(g["per"][j][1])
        cv, bic, _, _ = cv_rms(screen, *_stack(cols, priors))
        return cv, bic

    while True:
        cv, bic = score()
        worst = None
        for n, g in groups.items():
            if g["per"] is None or len(g["joints"]) < 2:
                continue
            for j in g["joints"]:
                cv_j, bic_j = score((n, j))
                if bic_j <= bic or cv_j <= cv:
                    margin = (bic_j - bic, cv_j - cv)
                    if worst is None or margin < worst[0]:
                        worst = (margin, n, j, cv_j, bic_j)
        if worst is None:
            break
        _, n, j, cv_j, bic_j = worst
        g = groups[n]
        g["joints"].remove(j)
        g["cols"] = np.concatenate([g["per"][x][0] for x in g["joints"]], axis=2)
        g["prior"] = np.concatenate([g["per"][x][1] for x in g["joints"]])
        pruned.append({"effect": n, "joint": j, "reason": (
            f"joint {j}'s parameters do not pay for themselves: without them the BIC changes by {bic_j - bic:+.1f} "
            f"and the cross-validated RMS by {1000 * (cv_j - cv):+.2f} um")})
    return pruned
