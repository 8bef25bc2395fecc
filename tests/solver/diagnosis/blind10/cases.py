"""The 72 cases of the twelfth blind set (directory ``blind10``), frozen.

Units of the parameters: rad, mm, 1/degC, mm/N or rad/(N mm), rad/(N mm) for the base tilt, mm for
the hot spot's width and centre, degC for its heating.  The amplitudes here are the first (physical)
guesses; ``magnitudes.json`` (written by ``tune.py`` before the freeze) holds the factor each case's
amplitudes are multiplied by.  ``kind``: in (library), out (own), none, under (understated noise).
"""
from __future__ import annotations

CASES = []


def _c(name, family, model, kind, effect, params, targets, design, n, truth=None, joints=None, **kw):
    CASES.append(dict(name=name, family=family, model=model, kind=kind, effect=effect, params=params,
                      targets=targets, design=design, n=n, truth=truth or effect, joints=joints, **kw))


def _legs(v, legs, spread=(1.0, 1.04, 0.97, 1.02, 0.98, 1.01)):
    return {j: v * spread[k] for k, j in enumerate(legs)}


TX = ("41", "42", "43")
HX = ("31", "32", "33", "34", "35", "36")

# ---- in the library, parallel (20) ----
_c("tx_pitch_41", "tx7", "tx7", "in", "screw-pitch", {"per": {"41": 8e-4}}, "tee4", "walk", 48, joints=["41"])
_c("tx_periodic1_42", "tx7", "tx7", "in", "screw-periodic", {"order": 1, "per": {"42": [0.015, -0.01]}},
   "q6tool", "arcsine", 64, joints=["42"])
_c("tx_backlash_43", "tx7", "tx7", "in", "backlash", {"per": {"43": 0.04}}, "tee4", "walk", 48, joints=["43"])
_c("tx_legth", "tx7", "tx7", "in", "leg-thermal", {"per": _legs(1.2e-5, TX)}, "tee4", "clusters", 48,
   joints=list(TX))
_c("tx_thermal", "tx7", "tx7", "in", "thermal", {"kappa": 1.2e-5}, "q6tool", "walk", 48)
_c("tx_periodic2_43", "tx7", "tx7", "in", "screw-periodic", {"order": 2, "per": {"43": [0.012, 0.01]}}, "tee4",
   "arcsine", 48, joints=["43"])
_c("tx_harm1_6", "tx7", "tx7", "in", "angle-harmonic", {"k": 1, "per": {"6": [2e-4, 1e-4]}}, "tee4",
   "clusters", 48, truth="angle-harmonic-1", joints=["6"])
_c("tx_scale_7", "tx7", "tx7", "in", "angle-scale", {"per": {"7": 1e-3}}, "tee4", "walk", 64, joints=["7"])
_c("txm_compliance", "tx7", "tx7_m", "in", "compliance", {"per": _legs(1e-4, TX)}, "q6tool", "walk", 48,
   joints=list(TX))
_c("txm_clearance", "tx7", "tx7_m", "in", "joint-clearance", {"per": _legs(0.04, TX)}, "tee4", "arcsine", 48,
   joints=list(TX))
_c("hx_pitch_34", "hexa", "hexa", "in", "screw-pitch", {"per": {"34": 8e-4}}, "tri3w", "arcsine", 48, joints=["34"])
_c("hx_periodic2_36", "hexa", "hexa", "in", "screw-periodic", {"order": 2, "per": {"36": [0.012, 0.008]}},
   "q6top", "walk", 48, joints=["36"])
_c("hx_backlash_32", "hexa", "hexa", "in", "backlash", {"per": {"32": 0.03}}, "tri3w", "walk", 48, joints=["32"])
_c("hx_legth", "hexa", "hexa", "in", "leg-thermal", {"per": _legs(1.2e-5, HX)}, "q6top", "clusters", 48,
   joints=list(HX))
_c("hx_drift", "hexa", "hexa", "in", "tracker-drift",
   {"shift": {"2": [0.03, -0.02, 0.01], "3": [-0.02, 0.04, 0.02]}}, "tri3w", "clusters", 48)
_c("hxm_compliance", "hexa", "hexa_m", "in", "compliance", {"per": _legs(3e-4, HX)}, "tri3w", "walk", 48,
   joints=list(HX))
_c("hxm_gbacklash_35", "hexa", "hexa_m", "in", "backlash-gravity", {"per": {"35": 0.04}}, "q6top", "arcsine", 48,
   joints=["35"])
_c("hx_thermal", "hexa", "hexa", "in", "thermal", {"kappa": 1.2e-5}, "tri3w", "arcsine", 48)
_c("hx_periodic1_31", "hexa", "hexa", "in", "screw-periodic", {"order": 1, "per": {"31": [0.012, -0.01]}}, "q6top",
   "clusters", 48, joints=["31"])
_c("hx_backlash_35_36", "hexa", "hexa", "in", "backlash", {"per": {"35": 0.03, "36": 0.03}}, "tri3w", "clusters",
   48, joints=["35", "36"])

# ---- in the library, serial (20) ----
_c("st_pitch_3", "stan", "stan", "in", "screw-pitch", {"per": {"3": 4e-4}}, "duo", "walk", 56, joints=["3"])
_c("st_periodic1_3", "stan", "stan", "in", "screw-periodic", {"order": 1, "per": {"3": [0.02, 0.01]}}, "one",
   "arcsine", 56, joints=["3"])
_c("st_backlash_1", "stan", "stan", "in", "backlash", {"per": {"1": 3e-4}}, "duo", "clusters", 56, joints=["1"])
_c("st_harm1_1", "stan", "stan", "in", "angle-harmonic", {"k": 1, "per": {"1": [1.5e-4, -1e-4]}}, "duo",
   "arcsine", 56, truth="angle-harmonic-1", joints=["1"])
_c("st_scale_2", "stan", "stan", "in", "angle-scale", {"per": {"2": 4e-4}}, "one", "walk", 56, joints=["2"])
_c("st_backlash_4", "stan", "stan", "in", "backlash", {"per": {"4": 5e-4}}, "duo", "walk", 56, joints=["4"])
_c("st_harm2_5", "stan", "stan", "in", "angle-harmonic", {"k": 2, "per": {"5": [1.5e-4, 1e-4]}}, "one", "clusters",
   72, truth="angle-harmonic-2", joints=["5"])
_c("st_thermal", "stan", "stan", "in", "thermal", {"kappa": 1.2e-5}, "duo", "arcsine", 72)
_c("stm_compliance_2", "stan", "stan_m", "in", "compliance", {"per": {"2": 2e-9}}, "duo", "walk", 56, joints=["2"])
_c("stm_gbacklash_5", "stan", "stan_m", "in", "backlash-gravity", {"per": {"5": 4e-4}}, "one", "clusters", 56,
   joints=["5"])
_c("ce_harm2_2", "ceil", "ceil", "in", "angle-harmonic", {"k": 2, "per": {"2": [1e-4, -6e-5]}}, "tri3", "walk", 56,
   truth="angle-harmonic-2", joints=["2"])
_c("ce_harm15_3", "ceil", "ceil", "in", "angle-harmonic", {"k": 1.5, "per": {"3": [1e-4, 8e-5]}}, "q6tool",
   "arcsine", 56, truth="angle-harmonic-1.5", joints=["3"])
_c("ce_harm1_1", "ceil", "ceil", "in", "angle-harmonic", {"k": 1, "per": {"1": [1e-4, 1e-4]}}, "tri3",
   "clusters", 56, truth="angle-harmonic-1", joints=["1"])
_c("ce_scale_1", "ceil", "ceil", "in", "angle-scale", {"per": {"1": 2e-4}}, "q6tool", "walk", 56, joints=["1"])
_c("ce_backlash_2", "ceil", "ceil", "in", "backlash", {"per": {"2": 3e-4}}, "tri3", "arcsine", 56, joints=["2"])
_c("ce_drift", "ceil", "ceil", "in", "tracker-drift",
   {"shift": {"2": [-0.02, 0.03, 0.015], "3": [0.025, 0.01, -0.03]}}, "tri3", "walk", 56)
_c("cem_compliance_3", "ceil", "ceil_m", "in", "compliance", {"per": {"3": 2e-9}}, "q6tool", "clusters", 56,
   joints=["3"])
_c("cem_linkbend_3", "ceil", "ceil_m", "in", "link-bending", {"per": {"3": ["4", 2e-9]}}, "tri3", "walk", 56)
_c("cem_basedef", "ceil", "ceil_m", "in", "base-deformation", {"c": [3e-10, 3e-10]}, "tri3", "arcsine", 72)
_c("cem_gbacklash_4", "ceil", "ceil_m", "in", "backlash-gravity", {"per": {"4": 4e-4}}, "q6tool", "walk", 56,
   joints=["4"])

# ---- out of the library (20) ----
_c("txo_azwarm", "tx7", "tx7", "out", "tracker-azimuth-warmup", {"psi0": 3e-5, "tau": 1200.0}, "tee4", "walk", 48)
_c("txo_bow", "tx7", "tx7", "out", "platform-bow-thermal", {"beta": 0.01, "R": 300.0}, "tee4", "clusters", 48)
_c("txo_adm", "tx7", "tx7", "out", "adm-warmup-scale", {"s0": 6e-5, "tau": 1500.0}, "tee4", "clusters", 48)
_c("txo_anchor", "tx7", "tx7", "out", "anchor-yaw-step",
   {"from_session": 3, "psi": 5e-5, "psi2": 3e-5, "cx": 400.0, "cy": -300.0}, "q6tool", "walk", 48)
_c("txo_bow_b", "tx7", "tx7", "out", "platform-bow-thermal", {"beta": 0.01, "R": 260.0}, "tee4", "arcsine", 64)
_c("hxo_adm_b", "hexa", "hexa", "out", "adm-warmup-scale", {"s0": -5e-5, "tau": 700.0}, "q6top", "walk", 48)
_c("hxo_azwarm", "hexa", "hexa", "out", "tracker-azimuth-warmup", {"psi0": 3e-5, "tau": 1500.0}, "q6top", "clusters",
   48)
_c("hxo_adm", "hexa", "hexa", "out", "adm-warmup-scale", {"s0": 6e-5, "tau": 1200.0}, "tri3w", "arcsine", 48)
_c("hxo_anchor", "hexa", "hexa", "out", "anchor-yaw-step",
   {"from_session": 2, "psi": 5e-5, "psi2": -3e-5, "cx": -300.0, "cy": 200.0}, "q6top", "arcsine", 48)
_c("hxo_azwarm_b", "hexa", "hexa", "out", "tracker-azimuth-warmup", {"psi0": -3e-5, "tau": 900.0}, "tri3w",
   "arcsine", 48)
_c("sto_overlap", "stan", "stan", "out", "telescope-overlap-tilt", {"joint": "3", "g": 0.02, "L0": 600.0, "b": 250.0},
   "duo", "walk", 56)
_c("sto_azwarm", "stan", "stan", "out", "tracker-azimuth-warmup", {"psi0": 3e-5, "tau": 1200.0}, "one", "clusters", 56)
_c("sto_adm", "stan", "stan", "out", "adm-warmup-scale", {"s0": 6e-5, "tau": 1500.0}, "duo", "arcsine", 56)
_c("sto_anchor", "stan", "stan", "out", "anchor-yaw-step",
   {"from_session": 2, "psi": 5e-5, "psi2": 3e-5, "cx": 250.0, "cy": 250.0}, "duo", "clusters", 56)
_c("sto_overlap_b", "stan", "stan", "out", "telescope-overlap-tilt", {"joint": "3", "g": 0.03, "L0": 700.0, "b": 300.0},
   "one", "arcsine", 72)
_c("sto_bow", "stan", "stan", "out", "platform-bow-thermal", {"beta": 0.01, "R": 120.0}, "duo", "walk", 56)
_c("ceo_adm", "ceil", "ceil", "out", "adm-warmup-scale", {"s0": 6e-5, "tau": 1500.0}, "tri3", "clusters", 56)
_c("ceo_anchor", "ceil", "ceil", "out", "anchor-yaw-step",
   {"from_session": 3, "psi": 5e-5, "psi2": -3e-5, "cx": 300.0, "cy": 0.0}, "q6tool", "arcsine", 56)
_c("ceo_anchor2", "ceil", "ceil", "out", "anchor-yaw-step",
   {"from_session": 2, "psi": -4e-5, "psi2": 4e-5, "cx": -200.0, "cy": 350.0}, "tri3", "walk", 56)
_c("ceo_adm_q6", "ceil", "ceil", "out", "adm-warmup-scale", {"s0": 6e-5, "tau": 900.0}, "q6tool", "walk", 56)

# ---- no effect (6) and understated noise (6) ----
_c("tx_none", "tx7", "tx7", "none", None, None, "tee4", "walk", 48)
_c("hxm_none_6d", "hexa", "hexa_m", "none", None, None, "q6top", "clusters", 48)
_c("hx_none", "hexa", "hexa", "none", None, None, "tri3w", "arcsine", 48)
_c("st_none", "stan", "stan", "none", None, None, "duo", "walk", 56)
_c("stm_none", "stan", "stan_m", "none", None, None, "one", "arcsine", 72)
_c("ce_none_6d", "ceil", "ceil", "none", None, None, "q6tool", "clusters", 56)
_c("tx_under_18", "tx7", "tx7", "under", None, None, "tee4", "arcsine", 48, noise_factor=1.8)
_c("txm_under_25", "tx7", "tx7_m", "under", None, None, "q6tool", "walk", 48, noise_factor=2.5)
_c("hx_under_21", "hexa", "hexa", "under", None, None, "tri3w", "clusters", 48, noise_factor=2.1)
_c("st_under_16", "stan", "stan", "under", None, None, "duo", "clusters", 56, noise_factor=1.6)
_c("ce_under_23", "ceil", "ceil", "under", None, None, "tri3", "arcsine", 56, noise_factor=2.3)
_c("cem_under_19", "ceil", "ceil_m", "under", None, None, "q6tool", "walk", 56, noise_factor=1.9)

PARALLEL = {"tx7", "hexa"}
__all__ = ["CASES", "PARALLEL"]
