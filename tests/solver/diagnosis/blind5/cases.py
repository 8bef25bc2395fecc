"""The cases of the seventh blind generator (frozen with RULES.md; units mm, rad, degC, s).

kind: ``in`` (an effect of the library, ``truth`` its library name), ``out`` (an effect the
library does not have), ``none`` (geometry, tracker and noise only), ``under`` (no effect, the file
states ``1 / understate`` of the noise applied).  ``targets``: a layout of generate.LAYOUTS
(``smr1``, ``smr2``, ``smr3`` reflectors, or ``6d``: one target with its orientation).
``design``: ``lhs`` (Latin hypercube over the actuated ranges), ``edges`` (half the coordinates in
the outer 6 % of their range), ``clusters`` (five clusters of poses).  ``poses``: (identification,
validation).  ``noise``: stated (a mm, b mm/m) per axis.
"""
from __future__ import annotations

_TX_NOISE = (0.004, 0.003)
_HX_NOISE = (0.004, 0.003)
_SR_NOISE = (0.008, 0.004)


def _c(cid, family, kind, effect=None, truth=None, joints=None, targets="smr3", design="lhs",
       poses=None, noise=None, understate=1.0, seed=None):
    fam_poses = {"tripteor_x7": (42, 18), "hexapod": (32, 12), "puma_like": (44, 18), "scara_like": (40, 16)}
    fam_noise = {"tripteor_x7": _TX_NOISE, "hexapod": _HX_NOISE, "puma_like": _SR_NOISE, "scara_like": _SR_NOISE}
    return {"id": cid, "family": family, "kind": kind, "effect": effect, "truth": truth, "joints": joints,
            "targets": targets, "design": design, "poses": poses or fam_poses[family],
            "noise": noise or fam_noise[family], "understate": understate,
            "seed": seed if seed is not None else 7000 + sum(ord(ch) * (i + 1) for i, ch in enumerate(cid))}


TX, HX, PU, SC = "tripteor_x7", "hexapod", "puma_like", "scara_like"

CASES = [
    # ---------------------------------------------------------------- Tripteor X7, in the library
    _c("tx_legthermal_42", TX, "in", {"effect": "leg-thermal", "kappa": {"42": 1.5e-5}}, "leg-thermal", ["42"]),
    _c("tx_legthermal_all", TX, "in", {"effect": "leg-thermal", "kappa": {"41": 1.2e-5, "42": 1.2e-5, "43": 1.2e-5}},
       "leg-thermal", ["41", "42", "43"], targets="6d", design="edges"),
    _c("tx_legthermal_41", TX, "in", {"effect": "leg-thermal", "kappa": {"41": 2.0e-5}}, "leg-thermal", ["41"],
       targets="smr2", design="edges"),
    _c("tx_pitch_41", TX, "in", {"effect": "screw-pitch", "s": {"41": 1.5e-3}}, "screw-pitch", ["41"], targets="smr2"),
    _c("tx_pitch_43", TX, "in", {"effect": "screw-pitch", "s": {"43": -1.4e-3}}, "screw-pitch", ["43"],
       design="edges"),
    _c("tx_periodic_42", TX, "in", {"effect": "screw-periodic", "ab": {"42": (0.02, 0.014)}}, "screw-periodic",
       ["42"]),
    _c("tx_periodic_41", TX, "in", {"effect": "screw-periodic", "ab": {"41": (0.024, -0.008)}}, "screw-periodic",
       ["41"], targets="6d", design="edges"),
    _c("tx_backlash_legs", TX, "in", {"effect": "backlash", "beta": {"41": 0.04, "42": 0.04, "43": 0.04}},
       "backlash", ["41", "42", "43"], targets="smr2"),
    _c("tx_backlash_6", TX, "in", {"effect": "backlash", "beta": {"6": 6e-4}}, "backlash", ["6"], design="edges"),
    _c("tx_thermal", TX, "in", {"effect": "thermal", "kappa": 1.0e-5}, "thermal"),
    _c("tx_harm3_6", TX, "in", {"effect": "angle-harmonic", "k": 3, "ab": {"6": (2.5e-4, 2.5e-4)}},
       "angle-harmonic-3", ["6"], targets="smr2", design="edges"),
    _c("tx_drift", TX, "in", {"effect": "tracker-drift", "shift": (0.06, -0.045, 0.03)}, "tracker-drift"),
    _c("tx_scale_6", TX, "in", {"effect": "angle-scale", "s": {"6": 3e-4}}, "angle-scale", ["6"]),
    _c("tx_harm1_6", TX, "in", {"effect": "angle-harmonic", "k": 1, "ab": {"6": (4.5e-4, 2e-4)}}, "angle-harmonic-1",
       ["6"], targets="smr2", design="edges"),
    _c("tx_scale_7", TX, "in", {"effect": "angle-scale", "s": {"7": 1.5e-3}}, "angle-scale", ["7"]),
    _c("tx_harm2_6", TX, "in", {"effect": "angle-harmonic", "k": 2, "ab": {"6": (3.5e-4, -2.5e-4)}},
       "angle-harmonic-2", ["6"], targets="6d"),
    # ---------------------------------------------------------------- hexapod, in the library (at most 8 in all)
    _c("hx_legthermal_33", HX, "in", {"effect": "leg-thermal", "kappa": {"33": 1.5e-5}}, "leg-thermal", ["33"]),
    _c("hx_pitch_35", HX, "in", {"effect": "screw-pitch", "s": {"35": 1.8e-3}}, "screw-pitch", ["35"], targets="smr2",
       design="edges"),
    _c("hx_periodic_31", HX, "in", {"effect": "screw-periodic", "ab": {"31": (0.022, 0.018)}}, "screw-periodic",
       ["31"]),
    _c("hx_backlash_legs", HX, "in",
       {"effect": "backlash", "beta": {j: 0.04 for j in ("31", "32", "33", "34", "35", "36")}}, "backlash",
       ["31", "32", "33", "34", "35", "36"], design="edges"),
    _c("hx_thermal", HX, "in", {"effect": "thermal", "kappa": 1.8e-5}, "thermal", targets="smr2"),
    # ---------------------------------------------------------------- PUMA-like 6R (standard DH, rad), in the library
    _c("pu_harm1_1", PU, "in", {"effect": "angle-harmonic", "k": 1, "ab": {"1": (2e-4, 1.2e-4)}},
       "angle-harmonic-1", ["1"]),
    _c("pu_harm2_2", PU, "in", {"effect": "angle-harmonic", "k": 2, "ab": {"2": (1.5e-4, -1e-4)}},
       "angle-harmonic-2", ["2"], targets="smr1", design="clusters"),
    _c("pu_scale_3", PU, "in", {"effect": "angle-scale", "s": {"3": 6e-4}}, "angle-scale", ["3"]),
    _c("pu_backlash_2", PU, "in", {"effect": "backlash", "beta": {"2": 3e-4}}, "backlash", ["2"], targets="6d"),
    _c("pu_thermal", PU, "in", {"effect": "thermal", "kappa": 2.2e-5}, "thermal"),
    _c("pu_harm3_2", PU, "in", {"effect": "angle-harmonic", "k": 3, "ab": {"2": (1.5e-4, 1e-4)}},
       "angle-harmonic-3", ["2"], design="clusters"),
    _c("pu_harm15_1", PU, "in", {"effect": "angle-harmonic", "k": 1.5, "ab": {"1": (2e-4, 1e-4)}},
       "angle-harmonic-1.5", ["1"]),
    # ---------------------------------------------------------------- SCARA-like RRPR (standard DH, deg), in the library
    _c("sc_harm1_1", SC, "in", {"effect": "angle-harmonic", "k": 1, "ab": {"1": (2e-4, -1e-4)}},
       "angle-harmonic-1", ["1"], targets="smr2"),
    _c("sc_scale_2", SC, "in", {"effect": "angle-scale", "s": {"2": 8e-4}}, "angle-scale", ["2"],
       design="clusters"),
    _c("sc_backlash_1", SC, "in", {"effect": "backlash", "beta": {"1": 4e-4}}, "backlash", ["1"], targets="smr2"),
    _c("sc_pitch_3", SC, "in", {"effect": "screw-pitch", "s": {"3": 1.5e-3}}, "screw-pitch", ["3"]),
    _c("sc_drift", SC, "in", {"effect": "tracker-drift", "shift": (0.06, 0.07, -0.04)}, "tracker-drift",
       targets="smr2"),
    # ---------------------------------------------------------------- out of the library
    _c("tx_out_cabledrag", TX, "out", {"effect": "cable-drag", "leg": "42", "drive": "6", "a": 0.03}, "cable-drag"),
    _c("tx_out_toolsag", TX, "out", {"effect": "tool-sag", "d": 0.18, "tilt": "7", "turn": "6"}, "tool-sag",
       targets="smr2"),
    _c("tx_out_slidingnest", TX, "out", {"effect": "sliding-nest", "target": 1, "u": (1.0, 0.0, 0.0), "a": 0.1,
                                         "drive": "6"}, "sliding-nest"),
    _c("tx_out_legcoupling", TX, "out", {"effect": "cross-coupling", "joint": "43", "from": "41", "k": 1e-3},
       "cross-coupling", targets="smr2", design="edges"),
    _c("hx_out_quadlead", HX, "out", {"effect": "quadratic-lead", "joint": "34", "k": 4e-5}, "quadratic-lead"),
    _c("pu_out_refraction", PU, "out", {"effect": "refraction-gradient", "c": 6e-5}, "refraction-gradient"),
    _c("pu_out_coupling", PU, "out", {"effect": "cross-coupling", "joint": "2", "from": "3", "k": 2e-4},
       "cross-coupling", targets="smr1"),
    _c("pu_out_geardent", PU, "out", {"effect": "gear-dent", "joint": "3", "a": 3e-4, "q0": 0.8, "w": 0.2},
       "gear-dent"),
    _c("sc_out_warmup", SC, "out", {"effect": "warm-up-drift", "joint": "2", "a": 4e-4, "tau": 1500.0},
       "warm-up-drift"),
    # ---------------------------------------------------------------- no effect
    _c("tx_none", TX, "none"),
    _c("hx_none", HX, "none", targets="smr2"),
    _c("pu_none", PU, "none", targets="6d"),
    _c("sc_none", SC, "none", targets="smr2"),
    # ---------------------------------------------------------------- understated noise
    _c("tx_under_18", TX, "under", understate=1.8),
    _c("tx_under_20_6d", TX, "under", targets="6d", understate=2.0),
    _c("pu_under_20", PU, "under", targets="smr1", understate=2.0),
    _c("sc_under_17", SC, "under", understate=1.7),
]

PARALLEL = {"tripteor_x7", "hexapod"}
