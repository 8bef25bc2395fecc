"""The 72 cases of the tenth blind generator (``blind8``), frozen with the directory.

Units of the parameters (as ``effects.py``): rad, mm, 1/degC, mm/N or rad/(N mm), rad/(N mm) for the
base tilt, mm per kg, rad per rad.  ``poses`` = (identification, held out).  ``kind``: ``in`` (library
effect), ``out`` (own effect), ``none``, ``under`` (noise drawn ``noise_factor`` x the header's).
"""
from __future__ import annotations

CASES = []


def _c(name, fam, model, kind, design, targets, poses, effect="none", params=None, **kw):
    d = dict(name=name, family=fam, model=model, kind=kind, design=design, targets=targets,
             poses=list(poses), effect=effect, params=params or {})
    d.update(kw)
    CASES.append(d)


N = (40, 16)
FEW = (26, 10)
HX = (30, 12)
HXF = (24, 10)
MANY = (60, 20)
LEGS_TX = ("41", "42", "43")
LEGS_HX = ("31", "32", "33", "34", "35", "36")

# ---- in the library, parallel: Tripteor X7 (12) ---------------------------------------------------------
_c("tx_pitch_42", "tx7", "tx7", "in", "sobol", "plate3", N, "screw-pitch", {"per": {"42": 1.7e-3}})
_c("tx_periodic2_41", "tx7", "tx7", "in", "spiral", "smr1", N, "screw-periodic",
   {"per": {"41": [0.018, -0.013]}, "order": 2})
_c("tx_backlash_42", "tx7", "tx7", "in", "levels", "plate3", N, "backlash", {"per": {"42": 0.035}},
   overshoot=True)
_c("tx_legth", "tx7", "tx7", "in", "boundary", "stylus6d", N, "leg-thermal",
   {"per": {"41": 1.7e-5, "42": 1.8e-5, "43": 1.9e-5}})
_c("tx_harm3_6", "tx7", "tx7", "in", "sobol", "plate3", N, "angle-harmonic",
   {"k": 3, "per": {"6": [2.5e-4, 1.5e-4]}})
_c("tx_scale_7", "tx7", "tx7", "in", "boundary", "smr1", N, "angle-scale", {"per": {"7": 1.3e-3}})
_c("tx_drift3", "tx7", "tx7", "in", "spiral", "stylus6d", FEW, "tracker-drift",
   {"shift": {"2": [0.04, -0.02, 0.03], "3": [-0.03, 0.05, 0.02]}})
_c("txm_compliance", "tx7", "tx7_m", "in", "sobol", "plate3", N, "compliance",
   {"per": {j: 3e-4 for j in LEGS_TX}})
_c("txm_compliance_7", "tx7", "tx7_m", "in", "levels", "smr1", N, "compliance", {"per": {"7": 7e-9}})
_c("txm_gbacklash_41", "tx7", "tx7_m", "in", "boundary", "plate3", N, "backlash-gravity",
   {"per": {"41": 0.05}})
_c("txm_clearance", "tx7", "tx7_m", "in", "spiral", "smr1", N, "joint-clearance",
   {"per": {j: 0.06 for j in LEGS_TX}})
_c("txm_harm2_6", "tx7", "tx7_m", "in", "boundary", "stylus6d", MANY, "angle-harmonic",
   {"k": 2, "per": {"6": [3.2e-4, -2.4e-4]}})

# ---- in the library, parallel: hexapod (8) --------------------------------------------------------------
_c("hx_pitch_34", "hexa", "hexa", "in", "boundary", "wide2", HX, "screw-pitch", {"per": {"34": 1.5e-3}})
_c("hx_periodic1_32", "hexa", "hexa", "in", "spiral", "far6d", HX, "screw-periodic",
   {"per": {"32": [0.026, 0.016]}, "order": 1})
_c("hx_backlash_35_36", "hexa", "hexa", "in", "sobol", "wide2", HX, "backlash",
   {"per": {"35": 0.04, "36": 0.04}}, overshoot=True)
_c("hx_legth", "hexa", "hexa", "in", "boundary", "far6d", HX, "leg-thermal",
   {"per": {"31": 2.0e-5, "32": 2.1e-5, "33": 1.9e-5, "34": 2.0e-5, "35": 2.05e-5, "36": 1.95e-5}})
_c("hx_thermal", "hexa", "hexa", "in", "sobol", "wide2", HXF, "thermal", {"kappa": 2.2e-5})
_c("hxm_compliance", "hexa", "hexa_m", "in", "boundary", "far6d", HX, "compliance",
   {"per": {j: 8.5e-4 for j in LEGS_HX}})
_c("hxm_clearance", "hexa", "hexa_m", "in", "spiral", "wide2", HX, "joint-clearance",
   {"per": {j: 0.08 for j in LEGS_HX}})
_c("hx_drift", "hexa", "hexa", "in", "spiral", "far6d", HX, "tracker-drift",
   {"shift": {"2": [-0.03, 0.03, 0.04], "3": [0.05, 0.01, -0.03]}})

# ---- in the library, serial: 5-axis gantry (10) ----------------------------------------------------------
_c("gt_pitch_1", "gantry", "gantry", "in", "levels", "bar2", N, "screw-pitch", {"per": {"1": 3e-4}})
_c("gt_periodic_2", "gantry", "gantry", "in", "spiral", "nose1", N, "screw-periodic",
   {"per": {"2": [0.036, 0.027]}, "order": 1, "lead": 20.0})
_c("gt_backlash_3", "gantry", "gantry", "in", "sobol", "bar2", N, "backlash", {"per": {"3": 0.06}},
   overshoot=True)
_c("gt_harm1_4", "gantry", "gantry", "in", "boundary", "bar2", N, "angle-harmonic",
   {"k": 1, "per": {"4": [3.3e-4, 2.2e-4]}})
_c("gt_scale_5", "gantry", "gantry", "in", "levels", "nose1", N, "angle-scale", {"per": {"5": 6e-4}})
_c("gt_straight_2", "gantry", "gantry", "in", "sobol", "bar2", N, "guide-straightness",
   {"per": {"2": [0.04, 0.03]}})
_c("gt_thermal", "gantry", "gantry", "in", "boundary", "nose1", N, "thermal", {"kappa": 2.0e-5})
_c("gm_compliance_3_5", "gantry", "gantry_m", "in", "spiral", "bar2", N, "compliance",
   {"per": {"3": 4e-4, "5": 1e-8}})
_c("gm_gbacklash_5", "gantry", "gantry_m", "in", "levels", "bar2", N, "backlash-gravity",
   {"per": {"5": 6e-4}})
_c("gm_basedef", "gantry", "gantry_m", "in", "sobol", "nose1", N, "base-deformation",
   {"c": [3e-10, 3e-10]})

# ---- in the library, serial: desktop 6R (10) --------------------------------------------------------------
_c("dk_harm1_2", "desk", "desk", "in", "sobol", "tri3", N, "angle-harmonic", {"k": 1, "per": {"2": [2.4e-4, 1.6e-4]}})
_c("dk_harm15_3", "desk", "desk", "in", "spiral", "grip6d", N, "angle-harmonic",
   {"k": 1.5, "per": {"3": [3.4e-4, -2.2e-4]}})
_c("dk_scale_1", "desk", "desk", "in", "boundary", "tri3", N, "angle-scale", {"per": {"1": 4e-4}})
_c("dk_backlash_4", "desk", "desk", "in", "levels", "tri3", N, "backlash", {"per": {"4": 1.2e-3}},
   overshoot=True)
_c("dk_harm2_2", "desk", "desk", "in", "sobol", "grip6d", N, "angle-harmonic",
   {"k": 2, "per": {"2": [2.4e-4, -1.6e-4]}})
_c("dk_drift", "desk", "desk", "in", "spiral", "tri3", FEW, "tracker-drift",
   {"shift": {"2": [0.04, -0.05, 0.03], "3": [-0.03, 0.04, 0.065]}})
_c("dm_compliance_2_3", "desk", "desk_m", "in", "boundary", "tri3", N, "compliance",
   {"per": {"2": 4e-8, "3": 4e-8}})
_c("dm_linkbend_2", "desk", "desk_m", "in", "sobol", "tri3", N, "link-bending", {"per": {"2": ["3", 4e-8]}})
_c("dm_gbacklash_2", "desk", "desk_m", "in", "levels", "grip6d", N, "backlash-gravity", {"per": {"2": 6e-4}})
_c("dm_harm3_1", "desk", "desk_m", "in", "boundary", "grip6d", (56, 20), "angle-harmonic",
   {"k": 3, "per": {"1": [1.8e-4, 1.5e-4]}})

# ---- out of the library (20) --------------------------------------------------------------------------------
_c("go_twist_1", "gantry", "gantry", "out", "levels", "bar2", N, "guide-twist", {"joint": "1", "eps": 8e-5})
_c("go_yaw_2", "gantry", "gantry", "out", "sobol", "nose1", N, "bridge-yaw",
   {"joint": "1", "src": "2", "c": 2.5e-4, "centre": [0.0, 450.0, 0.0]})
_c("go_wobble_4", "gantry", "gantry", "out", "boundary", "bar2", N, "race-wobble",
   {"joint": "4", "a": 2.2e-4, "phase": 1.2})
_c("go_hosewind_5", "gantry", "gantry", "out", "spiral", "bar2", N, "hose-wind",
   {"joint": "5", "src": "4", "c": 3e-4})
_c("gmo_rambend", "gantry", "gantry_m", "out", "levels", "nose1", N, "ram-bending",
   {"ram": "3", "head": "5", "L0": 300.0, "c": 1e-11})
_c("go_skew", "gantry", "gantry", "out", "sobol", "bar2", N, "skew-thermal", {"src": "2", "c": 7e-5})
_c("do_beltload_3", "desk", "desk", "out", "sobol", "tri3", N, "belt-load", {"joint": "3", "src": "2", "c": 3e-8})
_c("do_wristcoup_6", "desk", "desk", "out", "spiral", "grip6d", N, "wrist-coupling",
   {"joint": "6", "src": "4", "c": 2.5e-3})
_c("do_absharm_3", "desk", "desk", "out", "boundary", "tri3", N, "absolute-harmonic",
   {"joint": "3", "sum": ["2", "3"], "a": 3.5e-4, "phase": 0.6})
_c("do_hosewind_5", "desk", "desk", "out", "levels", "tri3", N, "hose-wind", {"joint": "5", "src": "4", "c": 1.5e-3})
_c("dmo_holder", "desk", "desk_m", "out", "sobol", "grip6d", N, "holder-sag", {"c": 0.1})
_c("do_wobble_1", "desk", "desk", "out", "spiral", "tri3", N, "race-wobble",
   {"joint": "1", "a": 2.2e-4, "phase": 0.3})
_c("tx_o_absharm_7", "tx7", "tx7", "out", "sobol", "plate3", N, "absolute-harmonic",
   {"joint": "7", "sum": ["6", "7"], "a": 3e-4, "phase": -0.4})
_c("tx_o_wobble_6", "tx7", "tx7", "out", "sobol", "plate3", N, "race-wobble",
   {"joint": "6", "a": 1.2e-4, "phase": -0.8})
_c("tx_o_holder", "tx7", "tx7", "out", "spiral", "stylus6d", N, "holder-sag", {"c": 0.004})
_c("tx_o_tilt", "tx7", "tx7", "out", "levels", "smr1", N, "table-tilt-thermal", {"c": 1.5e-5})
_c("tx_o_coup_7", "tx7", "tx7", "out", "sobol", "plate3", N, "wrist-coupling",
   {"joint": "7", "src": "6", "c": 2e-4})
_c("hx_o_drag_33", "hexa", "hexa", "out", "boundary", "wide2", HX, "passive-drag",
   {"joint": "33", "src": "43", "c": 0.6})
_c("hx_o_weather", "hexa", "hexa", "out", "sobol", "far6d", HX, "tracker-weather", {"k": 3e-6})
_c("hx_o_tilt", "hexa", "hexa", "out", "spiral", "wide2", HX, "table-tilt-thermal", {"c": 2.2e-5})

# ---- no effect (6) -------------------------------------------------------------------------------------------
_c("tx_none", "tx7", "tx7", "none", "sobol", "plate3", N)
_c("txm_none_6d", "tx7", "tx7_m", "none", "boundary", "stylus6d", N)
_c("hx_none_6d", "hexa", "hexa", "none", "boundary", "far6d", HX)
_c("gm_none", "gantry", "gantry_m", "none", "levels", "bar2", N)
_c("dk_none_6d", "desk", "desk", "none", "spiral", "grip6d", N)
_c("dm_none", "desk", "desk_m", "none", "sobol", "tri3", N)

# ---- understated noise (6) ------------------------------------------------------------------------------------
_c("tx_under_18", "tx7", "tx7", "under", "sobol", "plate3", N, noise_factor=1.8)
_c("hx_under_22", "hexa", "hexa", "under", "sobol", "wide2", HX, noise_factor=2.2)
_c("gt_under_26", "gantry", "gantry", "under", "boundary", "nose1", N, noise_factor=2.6)
_c("gm_under_16", "gantry", "gantry_m", "under", "levels", "bar2", N, noise_factor=1.6)
_c("dk_under_30", "desk", "desk", "under", "spiral", "grip6d", N, noise_factor=3.0)
_c("dm_under_20", "desk", "desk_m", "under", "sobol", "tri3", N, noise_factor=2.0)

assert len({c["name"] for c in CASES}) == len(CASES) == 72, len(CASES)

__all__ = ["CASES"]
