"""The cases (frozen with the generator).  Units: the docs' table: kappa 1/°C, s dimensionless,
(a, b) and beta in rad (revolute) or mm (screw), shift mm, times s, c of tool-flex mm/kg.

Each case: (name, family, kind, effect kind or None, effect parameters, targets, design, noise factor).
kind: "in" (the library's effect, truth = its name), "out" (own effect, in no library effect),
"none" (no effect), "under" (no effect, noise drawn `factor` x larger than the header states).
"""
from __future__ import annotations

L41 = 838.1527307120105  # Tripteor leg 41's middle of stroke (model file), mm

C = []


def case(name, fam, kind, eff, params, targets, design, factor=1.0):
    C.append(dict(name=name, family=fam, kind=kind, effect=eff, params=params,
                  targets=targets, design=design, factor=factor))


# ---------------- in the library, parallel: Tripteor X7 (16) and hexapod (4)
case("tx_legth_all", "tx7", "in", "leg-thermal", {"per": {"41": 2.8e-5, "42": 2.8e-5, "43": 2.8e-5}}, "smr3", "shell")
case("tx_legth_all_6d", "tx7", "in", "leg-thermal", {"per": {"41": 3e-5, "42": 3e-5, "43": 3e-5}}, "6d", "walk")
case("tx_pitch_41", "tx7", "in", "screw-pitch", {"per": {"41": 1.5e-3}}, "smr1", "walk")
case("tx_pitch_42_43", "tx7", "in", "screw-pitch", {"per": {"42": 1.2e-3, "43": -1.0e-3}}, "smr3", "uniform")
case("tx_periodic_43", "tx7", "in", "screw-periodic", {"per": {"43": (0.02, -0.012)}}, "smr3", "walk")
case("tx_periodic2_41", "tx7", "in", "screw-periodic", {"per": {"41": (0.018, 0.015)}, "order": 2}, "smr1", "shell")
case("tx_backlash_legs", "tx7", "in", "backlash", {"per": {"41": 0.04, "42": 0.04, "43": 0.04}}, "smr3", "walk")
case("tx_backlash_7", "tx7", "in", "backlash", {"per": {"7": 6e-4}}, "smr1", "uniform")
case("tx_harm1_6", "tx7", "in", "angle-harmonic", {"k": 1, "per": {"6": (4.5e-4, 2.5e-4)}}, "6d", "shell")
case("tx_harm2_6", "tx7", "in", "angle-harmonic", {"k": 2, "per": {"6": (4e-4, 3e-4)}}, "smr3", "walk")
case("tx_harm3_6", "tx7", "in", "angle-harmonic", {"k": 3, "per": {"6": (3.5e-4, 3e-4)}}, "smr1", "uniform")
case("tx_harm15_6", "tx7", "in", "angle-harmonic", {"k": 1.5, "per": {"6": (4.5e-4, 2e-4)}}, "smr3", "walk")
case("tx_scale_6", "tx7", "in", "angle-scale", {"per": {"6": 4.5e-4}}, "smr1", "shell")
case("tx_scale_7", "tx7", "in", "angle-scale", {"per": {"7": 1.5e-3}}, "smr3", "uniform")
case("tx_thermal", "tx7", "in", "thermal", {"kappa": 2.8e-5}, "smr3", "walk")
case("tx_drift_6d", "tx7", "in", "tracker-drift", {"shift": (0.05, -0.04, 0.03)}, "6d", "uniform")
case("hx_legth_all", "hexa", "in", "leg-thermal", {"per": {j: 3e-5 for j in ("31", "32", "33", "34", "35", "36")}}, "smr3", "shell")
case("hx_periodic_32", "hexa", "in", "screw-periodic", {"per": {"32": (0.025, 0.018)}}, "smr1", "walk")
case("hx_backlash_34_36", "hexa", "in", "backlash", {"per": {"34": 0.05, "36": 0.05}}, "smr3", "uniform")
case("hx_drift_6d", "hexa", "in", "tracker-drift", {"shift": (-0.04, 0.05, 0.03)}, "6d", "walk")

# ---------------- in the library, serial: st6 (7), abb6 (7), pal4 (6)
case("st_harm1_1", "st6", "in", "angle-harmonic", {"k": 1, "per": {"1": (2e-4, -1.2e-4)}}, "smr3", "walk")
case("st_harm2_4", "st6", "in", "angle-harmonic", {"k": 2, "per": {"4": (4e-4, 3e-4)}}, "6d", "uniform")
case("st_harm3_2", "st6", "in", "angle-harmonic", {"k": 3, "per": {"2": (1.5e-4, 1.2e-4)}}, "smr1", "walk")
case("st_scale_3", "st6", "in", "angle-scale", {"per": {"3": 6e-4}}, "smr3", "shell")
case("st_backlash_2", "st6", "in", "backlash", {"per": {"2": 3.5e-4}}, "smr1", "walk")
case("st_thermal", "st6", "in", "thermal", {"kappa": 3e-5}, "smr3", "uniform")
case("st_drift", "st6", "in", "tracker-drift", {"shift": (0.09, 0.07, -0.07)}, "smr1", "walk")
case("ab_harm1_2", "abb6", "in", "angle-harmonic", {"k": 1, "per": {"2": (2e-4, 1.5e-4)}}, "smr1", "uniform")
case("ab_harm2_1", "abb6", "in", "angle-harmonic", {"k": 2, "per": {"1": (1.5e-4, -1.5e-4)}}, "smr3", "walk")
case("ab_harm15_3", "abb6", "in", "angle-harmonic", {"k": 1.5, "per": {"3": (2.5e-4, 1e-4)}}, "smr3", "uniform")
case("ab_scale_5", "abb6", "in", "angle-scale", {"per": {"5": 1.2e-3}}, "smr1", "walk")
case("ab_backlash_1", "abb6", "in", "backlash", {"per": {"1": 3e-4}}, "smr3", "walk")
case("ab_thermal_6d", "abb6", "in", "thermal", {"kappa": 2.5e-5}, "6d", "uniform")
case("ab_drift", "abb6", "in", "tracker-drift", {"shift": (-0.07, 0.08, 0.05)}, "smr3", "shell")
case("pa_harm1_1", "pal4", "in", "angle-harmonic", {"k": 1, "per": {"1": (1.2e-4, 8e-5)}}, "smr3", "walk")
case("pa_harm2_2", "pal4", "in", "angle-harmonic", {"k": 2, "per": {"2": (1e-4, -8e-5)}}, "smr1", "uniform")
case("pa_harm3_1", "pal4", "in", "angle-harmonic", {"k": 3, "per": {"1": (8e-5, 8e-5)}}, "smr3", "uniform")
case("pa_scale_3", "pal4", "in", "angle-scale", {"per": {"3": 3e-4}}, "smr3", "walk")
case("pa_backlash_4", "pal4", "in", "backlash", {"per": {"4": 6e-4}}, "smr1", "walk")
case("pa_thermal", "pal4", "in", "thermal", {"kappa": 2.5e-5}, "smr3", "shell")

# ---------------- out of the library (own): tx7 (8), st6 (4), abb6 (4), pal4 (4)
case("tx_out_step_42", "tx7", "out", "step-offset", {"joint": "42", "size": 0.05, "frac": 0.62}, "smr3", "walk")
case("tx_out_toolflex", "tx7", "out", "tool-flex", {"c": 0.009, "axis": 2}, "smr1", "uniform")
case("tx_out_cable_7", "tx7", "out", "cable-pull", {"joint": "7", "src": "41", "mid": L41, "w": 50.0, "a": 6e-4}, "smr3", "shell")
case("tx_out_standtilt", "tx7", "out", "stand-tilt-lag", {"c": 3.5e-5, "tau": 3600.0, "axis": (1.0, 0.0, 0.0)}, "smr3", "walk")
case("tx_out_glitch_6", "tx7", "out", "encoder-glitch", {"joint": "6", "lo": 0.5, "hi": 1.1, "w": 0.05, "size": 1e-3}, "smr1", "uniform")
case("tx_out_hyst_43", "tx7", "out", "travel-hysteresis", {"joint": "43", "beta": 0.08, "lam": 60.0}, "smr3", "walk")
case("tx_out_knock", "tx7", "out", "nest-knock", {"target": 1, "shift": (0.06, -0.05, 0.04), "frac": 0.4}, "smr3", "uniform")
case("tx_out_settle", "tx7", "out", "base-settling", {"c": 2.5e-4, "tau": 7200.0}, "6d", "walk")
case("st_out_glitch_2", "st6", "out", "encoder-glitch", {"joint": "2", "lo": -0.3, "hi": 0.2, "w": 0.04, "size": 4e-4}, "smr3", "walk")
case("st_out_step_3", "st6", "out", "step-offset", {"joint": "3", "size": 3e-4, "frac": 0.65}, "smr1", "uniform")
case("st_out_toolflex", "st6", "out", "tool-flex", {"c": 0.01, "axis": 2}, "smr3", "walk")
case("st_out_hyst_1", "st6", "out", "travel-hysteresis", {"joint": "1", "beta": 6e-4, "lam": 0.3}, "smr3", "walk")
case("ab_out_cable_5", "abb6", "out", "cable-pull", {"joint": "5", "src": "1", "mid": 0.0, "w": 0.6, "a": 5e-4}, "smr3", "walk")
case("ab_out_standtilt", "abb6", "out", "stand-tilt-lag", {"c": 5e-5, "tau": 3000.0, "axis": (0.0, 1.0, 0.0)}, "smr1", "uniform")
case("ab_out_knock", "abb6", "out", "nest-knock", {"target": 2, "shift": (-0.1, 0.09, 0.1), "frac": 0.45}, "smr3", "walk")
case("ab_out_settle", "abb6", "out", "base-settling", {"c": 1.2e-4, "tau": 5400.0}, "smr3", "uniform")
case("pa_out_step_2", "pal4", "out", "step-offset", {"joint": "2", "size": 1.5e-4, "frac": 0.6}, "smr3", "walk")
case("pa_out_toolflex", "pal4", "out", "tool-flex", {"c": 0.0025, "axis": 0}, "smr3", "uniform")
case("pa_out_hyst_1", "pal4", "out", "travel-hysteresis", {"joint": "1", "beta": 3e-4, "lam": 0.4}, "smr1", "walk")
case("pa_out_glitch_3", "pal4", "out", "encoder-glitch", {"joint": "3", "lo": -0.9, "hi": -0.5, "w": 0.03, "size": 2.5e-4}, "smr3", "uniform")

# ---------------- no effect (6) and understated noise (6)
case("tx_none", "tx7", "none", None, {}, "smr3", "walk")
case("tx_none_6d", "tx7", "none", None, {}, "6d", "uniform")
case("hx_none", "hexa", "none", None, {}, "smr3", "uniform")
case("st_none", "st6", "none", None, {}, "smr1", "walk")
case("ab_none", "abb6", "none", None, {}, "smr3", "shell")
case("pa_none", "pal4", "none", None, {}, "smr3", "walk")
case("tx_under_16", "tx7", "under", None, {}, "smr3", "uniform", 1.6)
case("tx_under_20_6d", "tx7", "under", None, {}, "6d", "walk", 2.0)
case("st_under_15", "st6", "under", None, {}, "smr3", "uniform", 1.5)
case("st_under_135", "st6", "under", None, {}, "smr1", "walk", 1.35)
case("ab_under_18", "abb6", "under", None, {}, "smr1", "walk", 1.8)
case("pa_under_22", "pal4", "under", None, {}, "smr3", "shell", 2.2)

CASES = {c["name"]: c for c in C}
assert len(CASES) == len(C)
