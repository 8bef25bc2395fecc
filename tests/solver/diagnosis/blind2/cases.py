"""The campaign list: cases x variants x seeds (fixed before any scoring run)."""
from __future__ import annotations

from .campaign import Variant
from .effects import CASES, GRAVITY_CASES

V_A = Variant("longarm6", "full", True, 1, True)      # industrial, full range, masses, 1 SMR, payload 0/30/60 kg
V_B = Variant("cobot6", "full", True, 3, True)        # cobot, full range, masses, 3 SMRs, payload 0/2/5 kg
V_C = Variant("longarm6", "short2", True, 3, False)   # industrial, joint 2 over 1.4 rad, 3 SMRs, no payload
V_N = Variant("longarm6", "full", False, 1, True)     # industrial, model WITHOUT masses
V_D = Variant("cobot6", "short2", False, 1, True)     # cobot, short joint-2 range, model WITHOUT masses
V_A2 = Variant("longarm6", "short2", True, 1, True)   # the short-range designs of the 3/rev case
V_B2 = Variant("cobot6", "short2", True, 3, True)


def variants_of(case: str):
    if case == "harmonic3-short":
        return [V_A2, V_B2, V_C]
    vs = [V_A, V_B, V_C]
    if case in GRAVITY_CASES or case in ("none", "angle-harmonic-1"):
        vs.append(V_N)
    if case in GRAVITY_CASES:
        vs.append(V_D)
    return vs


def campaign_list(seeds: int, cases=None):
    out = []
    for case in CASES:
        if cases and case not in cases:
            continue
        for v in variants_of(case):
            for s in range(seeds):
                out.append((case, v, s))
    return out
