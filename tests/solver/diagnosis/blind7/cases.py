"""The 72 cases of the ninth blind generator (directory ``blind7``), frozen with the generator.

Units: mm, rad, °C, s, kg, N (compliance mm/N or rad/(N mm), base-deformation rad/(N mm)).
``truth``: the library name diagnose should name (in-library cases), ``joints`` the true joints.
"""
from __future__ import annotations

FAM_OF = {"tx7": "tx7", "tx7_m": "tx7", "hexa": "hexa", "hexa_m": "hexa", "puma": "puma",
          "puma_m": "puma", "denso": "denso", "denso_m": "denso", "scara": "scara", "scara_m": "scara"}
MASSES = {"tx7_m", "hexa_m", "puma_m", "denso_m", "scara_m"}

CASES = []


def _c(name, model, kind, effect, params, targets, design, truth=None, joints=(), factor=None):
    c = dict(name=name, model=model, family=FAM_OF[model], kind=kind, effect=effect, params=params,
             targets=targets, design=design, truth=truth, joints=list(joints),
             masses_declared=model in MASSES)
    if factor:
        c["factor"] = factor
    CASES.append(c)


def _h(k, per):
    return {"k": k, "per": per}


LEGS = ("41", "42", "43")
HLEGS = ("31", "32", "33", "34", "35", "36")

# --- in the library, parallel (20) -------------------------------------------------------------
_c("tx_legth_all", "tx7", "in", "leg-thermal", {"per": {j: 2.5e-5 for j in LEGS}}, "smr2long", "lissajous", "leg-thermal", LEGS)
_c("tx_periodic3_42", "tx7", "in", "screw-periodic", {"per": {"42": [0.012, -0.009]}, "order": 3}, "smr1", "lhs", "screw-periodic", ["42"])
_c("tx_pitch_43", "tx7", "in", "screw-pitch", {"per": {"43": 1.9e-3}}, "smr2long", "clusters", "screw-pitch", ["43"])
_c("tx_backlash_41_43", "tx7", "in", "backlash", {"per": {"41": 0.03, "43": 0.03}}, "smr3", "lissajous", "backlash", ["41", "43"])
_c("tx_harm25_6", "tx7", "in", "angle-harmonic", _h(2.5, {"6": [4.5e-4, 3e-4]}), "6d", "lhs", "angle-harmonic-2.5", ["6"])
_c("tx_harm2_7", "tx7", "in", "angle-harmonic", _h(2, {"7": [3e-4, -2.5e-4]}), "smr2long", "lhs", "angle-harmonic-2", ["7"])
_c("tx_scale_6", "tx7", "in", "angle-scale", {"per": {"6": 5e-4}}, "smr3", "clusters", "angle-scale", ["6"])
_c("tx_thermal_6d", "tx7", "in", "thermal", {"kappa": 2.5e-5}, "6d", "lissajous", "thermal")
_c("tx_harm1_6", "tx7", "in", "angle-harmonic", _h(1, {"6": [3e-4, 2.5e-4]}), "smr2long", "lhs", "angle-harmonic-1", ["6"])
_c("txm_compliance", "tx7_m", "in", "compliance", {"per": {j: 3e-4 for j in LEGS}}, "smr2long", "lhs", "compliance", LEGS)
_c("txm_periodic1_41", "tx7_m", "in", "screw-periodic", {"per": {"41": [0.015, 0.01]}}, "smr3", "clusters", "screw-periodic", ["41"])
_c("txm_backlash_7", "tx7_m", "in", "backlash", {"per": {"7": 5e-4}}, "smr1", "lissajous", "backlash", ["7"])
_c("hx_legth_6dtcp", "hexa", "in", "leg-thermal", {"per": {j: 2.5e-5 for j in HLEGS}}, "6dtcp", "tilts", "leg-thermal", HLEGS)
_c("hx_periodic_33", "hexa", "in", "screw-periodic", {"per": {"33": [0.032, 0.019]}}, "smr3", "tilts", "screw-periodic", ["33"])
_c("hx_pitch_36", "hexa", "in", "screw-pitch", {"per": {"36": 1.95e-3}}, "smr1", "lhs", "screw-pitch", ["36"])
_c("hx_backlash_31_32", "hexa", "in", "backlash", {"per": {"31": 0.04, "32": 0.04}}, "6dtcp", "tilts", "backlash", ["31", "32"])
_c("hx_drift", "hexa", "in", "tracker-drift", {"shift": [0.05, -0.03, 0.04]}, "smr3", "lhs", "tracker-drift")
_c("hxm_compliance", "hexa_m", "in", "compliance", {"per": {j: 9e-4 for j in HLEGS}}, "smr3", "tilts", "compliance", HLEGS)
_c("hxm_periodic2_35", "hexa_m", "in", "screw-periodic", {"per": {"35": [0.03, -0.02]}, "order": 2}, "smr3", "lhs", "screw-periodic", ["35"])
_c("hx_thermal_6d", "hexa", "in", "thermal", {"kappa": 2.5e-5}, "6dtcp", "tilts", "thermal")

# --- in the library, serial (20) ------------------------------------------------------------------
_c("pu_harm1_1", "puma", "in", "angle-harmonic", _h(1, {"1": [1.5e-4, 1e-4]}), "smr3", "lhs", "angle-harmonic-1", ["1"])
_c("pu_harm2_3", "puma", "in", "angle-harmonic", _h(2, {"3": [1.2e-4, -1e-4]}), "smr1", "clusters", "angle-harmonic-2", ["3"])
_c("pu_harm15_2", "puma", "in", "angle-harmonic", _h(1.5, {"2": [2e-4, 1e-4]}), "smr3", "lissajous", "angle-harmonic-1.5", ["2"])
_c("pu_scale_3", "puma", "in", "angle-scale", {"per": {"3": 5e-4}}, "smr1", "lhs", "angle-scale", ["3"])
_c("pu_backlash_2", "puma", "in", "backlash", {"per": {"2": 3e-4}}, "smr3", "lissajous", "backlash", ["2"])
_c("pu_thermal_6d", "puma", "in", "thermal", {"kappa": 2.9e-5}, "6d", "lhs", "thermal")
_c("pu_harm3_5", "puma", "in", "angle-harmonic", _h(3, {"5": [1.5e-4, 1.5e-4]}), "smr3", "clusters", "angle-harmonic-3", ["5"])
_c("pm_compliance_2_3", "puma_m", "in", "compliance", {"per": {"2": 2e-9, "3": 2e-9}}, "smr3", "lhs", "compliance", ["2", "3"])
_c("pm_linkbend_2", "puma_m", "in", "link-bending", {"per": {"2": ["3", 3e-9]}}, "smr3", "lissajous", "link-bending", ["2"])
_c("pm_gbacklash_3", "puma_m", "in", "backlash-gravity", {"per": {"3": 4e-4}}, "smr1", "lhs", "backlash-gravity", ["3"])
_c("pm_compliance_3_6d", "puma_m", "in", "compliance", {"per": {"3": 5e-9}}, "6d", "clusters", "compliance", ["3"])
_c("pm_harm25_4", "puma_m", "in", "angle-harmonic", _h(2.5, {"4": [2.5e-4, 1.5e-4]}), "smr3", "lhs", "angle-harmonic-2.5", ["4"])
_c("dm_compliance_2_3", "denso_m", "in", "compliance", {"per": {"2": 3e-9, "3": 3e-9}}, "smr3", "lhs", "compliance", ["2", "3"])
_c("dm_harm3_1", "denso_m", "in", "angle-harmonic", _h(3, {"1": [1e-4, 1.2e-4]}), "6d", "lissajous", "angle-harmonic-3", ["1"])
_c("dm_scale_5", "denso_m", "in", "angle-scale", {"per": {"5": 1e-3}}, "smr3", "lhs", "angle-scale", ["5"])
_c("dm_drift", "denso_m", "in", "tracker-drift", {"shift": [0.04, 0.05, -0.03]}, "smr1", "clusters", "tracker-drift")
_c("de_harm2_4", "denso", "in", "angle-harmonic", _h(2, {"4": [2.8e-4, 2.1e-4]}), "smr3", "lhs", "angle-harmonic-2", ["4"])
_c("sc_harm1_2", "scara", "in", "angle-harmonic", _h(1, {"2": [1.5e-4, 1e-4]}), "smr1", "lhs", "angle-harmonic-1", ["2"])
_c("sc_periodic_3", "scara", "in", "screw-periodic", {"per": {"3": [0.0225, 0.015]}}, "smr3", "lissajous", "screw-periodic", ["3"])
_c("scm_backlash_1", "scara_m", "in", "backlash", {"per": {"1": 3e-4}}, "smr3", "clusters", "backlash", ["1"])

# --- out of the library (20) ----------------------------------------------------------------------
_c("tx_out_xtalk_7", "tx7", "out", "crosstalk", {"joint": "7", "src": "6", "a": 4e-4, "phase": 0.7}, "smr2long", "lhs")
_c("tx_out_curv_42", "tx7", "out", "screw-curvature", {"joint": "42", "mid": 873.212459828649, "half": 150.0, "c": 0.05}, "smr1", "lissajous")
_c("tx_out_heat_41", "tx7", "out", "motor-heating", {"joint": "41", "c": 4e-5}, "smr3", "clusters")
_c("tx_out_hose_7", "tx7", "out", "hose-stiffening", {"joint": "7", "mid": 0.0, "half": 1.0471975511965976, "c": 8e-4}, "smr2long", "lhs")
_c("tx_out_creep_43", "tx7", "out", "zero-creep", {"joint": "43", "r": 0.03}, "6d", "lissajous")
_c("hx_out_curv_34", "hexa", "out", "screw-curvature", {"joint": "34", "mid": 765.5022201495501, "half": 60.0, "c": 0.14}, "smr3", "tilts")
_c("hx_out_heat_35", "hexa", "out", "motor-heating", {"joint": "35", "c": 1e-4}, "smr3", "tilts")
_c("hx_out_twist_6d", "hexa", "out", "payload-twist", {"c": 2e-5}, "6dtcp", "tilts")
_c("pu_out_xtalk_3", "puma", "out", "crosstalk", {"joint": "3", "src": "1", "a": 2e-4, "phase": 1.1}, "smr3", "lhs")
_c("pu_out_hose_4", "puma", "out", "hose-stiffening", {"joint": "4", "mid": 0.5235987755982988, "half": 2.443460952792061, "c": 9e-4}, "smr1", "lissajous")
_c("pu_out_zth_2", "puma", "out", "joint-zero-thermal", {"joint": "2", "c": 7e-5}, "smr3", "clusters")
_c("pu_out_creep_5", "puma", "out", "zero-creep", {"joint": "5", "r": 5e-4}, "6d", "lhs")
_c("de_out_xtalk_5", "denso", "out", "crosstalk", {"joint": "5", "src": "4", "a": 3e-4, "phase": -0.4}, "smr3", "lhs")
_c("dm_out_heat_2", "denso_m", "out", "motor-heating", {"joint": "2", "c": 3.5e-5}, "smr3", "clusters")
_c("de_out_zth_3", "denso", "out", "joint-zero-thermal", {"joint": "3", "c": 7e-5}, "smr1", "lissajous")
_c("dm_out_hose_4", "denso_m", "out", "hose-stiffening", {"joint": "4", "mid": 0.0, "half": 2.512, "c": 6e-4}, "6d", "lhs")
_c("sc_out_spline", "scara", "out", "spline-coupling", {"joint": "3", "src": "4", "c": 0.03}, "smr3", "lhs")
_c("sc_out_curv_3", "scara", "out", "screw-curvature", {"joint": "3", "mid": -75.0, "half": 75.0, "c": 0.12}, "smr1", "clusters")
_c("scm_out_xtalk_2", "scara_m", "out", "crosstalk", {"joint": "2", "src": "1", "a": 2e-4, "phase": 0.3}, "smr3", "lissajous")
_c("sc_out_creep_1", "scara", "out", "zero-creep", {"joint": "1", "r": 2e-4}, "smr3", "lhs")

# --- no effect (6) and understated noise (6) --------------------------------------------------------
_c("tx_none", "tx7", "none", None, {}, "smr2long", "lissajous")
_c("hx_none", "hexa", "none", None, {}, "6dtcp", "tilts")
_c("pu_none", "puma", "none", None, {}, "smr3", "lhs")
_c("pm_none", "puma_m", "none", None, {}, "smr1", "clusters")
_c("dm_none_6d", "denso_m", "none", None, {}, "6d", "lissajous")
_c("sc_none", "scara", "none", None, {}, "smr3", "lhs")
_c("tx_under_17", "tx7", "under", None, {}, "smr3", "lhs", factor=1.7)
_c("hx_under_14", "hexa", "under", None, {}, "smr3", "tilts", factor=1.4)
_c("pu_under_25", "puma", "under", None, {}, "smr1", "lissajous", factor=2.5)
_c("dm_under_135", "denso_m", "under", None, {}, "smr3", "clusters", factor=1.35)
_c("sc_under_20", "scara", "under", None, {}, "smr3", "lhs", factor=2.0)
_c("pm_under_16_6d", "puma_m", "under", None, {}, "6d", "lhs", factor=1.6)

assert len(CASES) == 72 and len({c["name"] for c in CASES}) == 72
