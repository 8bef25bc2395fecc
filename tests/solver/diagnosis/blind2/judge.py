"""Mechanical judging rules (RULES.md), applied to diagnose's JSON.  No hyperstat import."""
from __future__ import annotations

import re

from .effects import CASES, GRAVITY_CASES

VISIBLE = 0.6          # signature: noise-free rigid-fit RMS / stated noise RMS (max of identification, validation)
HARMONIC_TOL = 0.25    # cycles per revolution (the spectrum's step is 0.25)
GRAVITY_LIBRARY = {"compliance", "link-bending", "backlash-gravity"}
EXPLAINING = ("explained", "partly explained")


def _order(name):
    m = re.fullmatch(r"angle-harmonic-([0-9]+(?:\.[0-9]*)?)", name)
    return float(m.group(1)) if m else None


def same_effect(name, truth):
    """Library names compared; angle-harmonic orders within HARMONIC_TOL (stage-4.6: within 0.3)."""
    if truth == "angle-harmonic-4.6":
        k = _order(name)
        return k is not None and abs(k - 4.6) <= 0.3
    kt, k = _order(truth), _order(name)
    if kt is not None:
        return k is not None and abs(k - kt) <= HARMONIC_TOL
    return name == truth


def acceptable(case):
    names = list(CASES[case][1])
    if case == "stage-4.6":
        names.append("angle-harmonic-4.6")
    return names


def _sets(d):
    sets = d.get("equivalence_sets") or []
    named = d.get("named_effects") or []
    out = []
    for i, n in enumerate(named):
        members = sets[i].get("members", [n]) if i < len(sets) and isinstance(sets[i], dict) else [n]
        out.append((n, list(members)))
    return out


def confidently_wrong(d, ok_names):
    """'explained' with a named effect outside ok_names whose equivalence set has one member;
    or 'understated noise' when there is a real effect."""
    if d.get("outcome") == "understated noise":
        return True
    if d.get("outcome") != "explained":
        return False
    for n, members in _sets(d):
        if len(members) <= 1 and not any(same_effect(n, t) for t in ok_names):
            return True
    return False


def truth_named(d, truth):
    if d.get("outcome") not in EXPLAINING:
        return False
    for n, members in _sets(d):
        if any(same_effect(m, truth) for m in [n] + members):
            return True
    return False


def judge(case, variant, d, visibility):
    """Return a dict: category, judgement (a word), flags.  d is diagnose's JSON or None (error)."""
    cat = CASES[case][0]
    r = {"category": cat, "visible": None, "judgement": None}
    if d is None:
        r["judgement"] = "error"
        return r
    outcome = d.get("outcome")
    named = d.get("named_effects") or []
    nomass = not variant.masses
    cannot = [c.get("effect") for c in (d.get("cannot_size") or []) if isinstance(c, dict)]
    if nomass:
        r["sized_without_masses"] = any(n in GRAVITY_LIBRARY for n in named)
        r["cannot_size_gravity"] = any(c in GRAVITY_LIBRARY for c in cannot)
    if cat == "none":
        r["judgement"] = "false alarm" if named else ("clean" if outcome == "no significant gap" else "no effect named")
        return r
    if cat == "understated":
        r["judgement"] = "flagged" if outcome == "understated noise" else "not flagged"
        nf, truef = d.get("noise_factor"), None
        r["noise_factor"] = nf
        return r
    r["visible"] = visibility is not None and visibility >= VISIBLE
    if cat == "in" and nomass and case in GRAVITY_CASES:
        r["category"] = "in-nomass-gravity"
        truth = CASES[case][1][0]
        honest = (truth in cannot and not any(same_effect(n, truth) for n in named)
                  and not confidently_wrong(d, []) and outcome not in ("no significant gap", "inputs wrong"))
        r["judgement"] = "cannot size (honest)" if honest else (
            "missed" if outcome == "no significant gap" else "not honest")
        return r
    if cat == "in":
        truth = CASES[case][1][0]
        r["judgement"] = "named" if truth_named(d, truth) else (
            "missed" if outcome == "no significant gap" else "not named")
        return r
    # out of the library
    ok = acceptable(case)
    if confidently_wrong(d, ok):
        r["judgement"] = "confident wrong"
    elif outcome in EXPLAINING or outcome == "unexplained":
        r["judgement"] = "honest"
    elif outcome == "no significant gap":
        r["judgement"] = "missed"
    else:
        r["judgement"] = "other"        # over-fitting, inputs wrong
    if nomass and case in GRAVITY_CASES:
        r["category"] = "out-nomass-gravity"
    return r


def multi_target_consistent(d):
    """3-reflector campaigns: every effect a single reflector names is named by the whole file or sits in
    one of its equivalence sets; no reflector alone explains a gap the whole does not see."""
    if d is None:
        return None
    pt = d.get("per_target") or []
    if not pt:
        return False
    allowed = []
    for n, members in _sets(d):
        allowed += [n] + members
    for e in pt:
        if e.get("outcome") in EXPLAINING:
            if d.get("outcome") == "no significant gap":
                return False
            for n in e.get("named_effects") or []:
                if not any(same_effect(n, a) or same_effect(a, n) for a in allowed):
                    return False
    return True
