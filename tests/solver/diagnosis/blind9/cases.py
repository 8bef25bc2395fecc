"""The 72 cases of the eleventh blind generator (directory ``blind9``), frozen with the generator.

Units of the parameters: rad, mm, 1/degC, mm/N or rad/(N mm) (compliance), rad/(N mm) (base tilt).
``kind``: ``in`` (a library effect), ``out`` (own physical idea), ``none`` (no effect), ``under``
(the noise drawn ``noise_factor`` x larger than the header states).  Magnitudes were set from this
generator's own visibility line only (``RULES.md``), never from a diagnose answer.
"""
from __future__ import annotations

TX = {"n_id": 44, "n_val": 14}
HX = {"n_id": 34, "n_val": 12}
LF = {"n_id": 48, "n_val": 16}
CY = {"n_id": 44, "n_val": 14}
LEGS_TX = ["41", "42", "43"]
LEGS_HX = ["31", "32", "33", "34", "35", "36"]


def _c(name, family, model, kind, effect, targets, design, counts, **kw):
    d = dict(name=name, family=family, model=model, kind=kind, effect=effect, targets=targets,
             design=design, **counts)
    d.update(kw)
    return d


DRIFT = {"2": [0.04, -0.03, 0.02], "3": [-0.03, 0.05, 0.03], "4": [0.02, 0.03, -0.05]}

CASES = [
    {'name': 'tx_pitch_43', 'family': 'tx7', 'model': 'tx7', 'kind': 'in', 'effect': {'name': 'screw-pitch', 'per': {'43': 0.000948}}, 'targets': 'cross5', 'design': 'antithetic', 'n_id': 44, 'n_val': 14},
    {'name': 'tx_periodic3_42', 'family': 'tx7', 'model': 'tx7', 'kind': 'in', 'effect': {'name': 'screw-periodic', 'order': 3, 'per': {'42': [0.0218, -0.0145]}}, 'targets': 'tcp6r', 'design': 'star', 'n_id': 44, 'n_val': 14},
    {'name': 'tx_backlash_41_43', 'family': 'tx7', 'model': 'tx7', 'kind': 'in', 'effect': {'name': 'backlash', 'per': {'41': 0.0194, '43': 0.0194}}, 'targets': 'cross5', 'design': 'corners', 'n_id': 44, 'n_val': 14, 'overshoot': True},
    {'name': 'tx_legth', 'family': 'tx7', 'model': 'tx7', 'kind': 'in', 'effect': {'name': 'leg-thermal', 'per': {'41': 2.33e-05, '42': 2.41e-05, '43': 2.26e-05}}, 'targets': 'tcp6r', 'design': 'shells', 'n_id': 44, 'n_val': 14},
    {'name': 'tx_harm2_6', 'family': 'tx7', 'model': 'tx7', 'kind': 'in', 'effect': {'name': 'angle-harmonic', 'k': 2, 'per': {'6': [0.000243, -0.000162]}}, 'targets': 'cross5', 'design': 'star', 'n_id': 44, 'n_val': 14},
    {'name': 'tx_scale_6', 'family': 'tx7', 'model': 'tx7', 'kind': 'in', 'effect': {'name': 'angle-scale', 'per': {'6': 0.00141}}, 'targets': 'tcp6r', 'design': 'antithetic', 'n_id': 30, 'n_val': 10},
    {'name': 'tx_drift4', 'family': 'tx7', 'model': 'tx7', 'kind': 'in', 'effect': {'name': 'tracker-drift', 'shift': {'2': [0.0242, -0.0181, 0.0121], '3': [-0.0181, 0.0302, 0.0181], '4': [0.0121, 0.0181, -0.0302]}}, 'targets': 'cross5', 'design': 'shells', 'n_id': 44, 'n_val': 14},
    {'name': 'tx_thermal', 'family': 'tx7', 'model': 'tx7', 'kind': 'in', 'effect': {'name': 'thermal', 'kappa': 1.65e-05}, 'targets': 'cross5', 'design': 'corners', 'n_id': 44, 'n_val': 14},
    {'name': 'txm_compliance', 'family': 'tx7', 'model': 'tx7_m', 'kind': 'in', 'effect': {'name': 'compliance', 'per': {'41': 0.000151, '42': 0.000151, '43': 0.000151}}, 'targets': 'tcp6r', 'design': 'antithetic', 'n_id': 44, 'n_val': 14},
    {'name': 'txm_clearance', 'family': 'tx7', 'model': 'tx7_m', 'kind': 'in', 'effect': {'name': 'joint-clearance', 'per': {'41': 0.0414, '42': 0.0414, '43': 0.0414}}, 'targets': 'cross5', 'design': 'star', 'n_id': 44, 'n_val': 14},
    {'name': 'txm_basedef', 'family': 'tx7', 'model': 'tx7_m', 'kind': 'in', 'effect': {'name': 'base-deformation', 'c': [8e-10, 8e-10]}, 'targets': 'tcp6r', 'design': 'corners', 'n_id': 44, 'n_val': 14},
    {'name': 'txm_gbacklash_42', 'family': 'tx7', 'model': 'tx7_m', 'kind': 'in', 'effect': {'name': 'backlash-gravity', 'per': {'42': 0.043}}, 'targets': 'cross5', 'design': 'shells', 'n_id': 44, 'n_val': 14},
    {'name': 'hx_pitch_33', 'family': 'hexa', 'model': 'hexa', 'kind': 'in', 'effect': {'name': 'screw-pitch', 'per': {'33': 0.00156}}, 'targets': 'ring4', 'design': 'star', 'n_id': 34, 'n_val': 12},
    {'name': 'hx_periodic1_35', 'family': 'hexa', 'model': 'hexa', 'kind': 'in', 'effect': {'name': 'screw-periodic', 'order': 1, 'per': {'35': [0.024, 0.018]}}, 'targets': 'tip6q', 'design': 'antithetic', 'n_id': 34, 'n_val': 12},
    {'name': 'hx_backlash_31', 'family': 'hexa', 'model': 'hexa', 'kind': 'in', 'effect': {'name': 'backlash', 'per': {'31': 0.0325}}, 'targets': 'ring4', 'design': 'corners', 'n_id': 34, 'n_val': 12, 'overshoot': True},
    {'name': 'hx_legth', 'family': 'hexa', 'model': 'hexa', 'kind': 'in', 'effect': {'name': 'leg-thermal', 'per': {'31': 2.07e-05, '32': 2.13e-05, '33': 2.02e-05, '34': 2.07e-05, '35': 2.09e-05, '36': 2.05e-05}}, 'targets': 'tip6q', 'design': 'shells', 'n_id': 34, 'n_val': 12},
    {'name': 'hx_drift', 'family': 'hexa', 'model': 'hexa', 'kind': 'in', 'effect': {'name': 'tracker-drift', 'shift': {'2': [0.0132, -0.0099, 0.0066], '3': [-0.0099, 0.0165, 0.0099], '4': [0.0066, 0.0099, -0.0165]}}, 'targets': 'ring4', 'design': 'antithetic', 'n_id': 34, 'n_val': 12},
    {'name': 'hxm_compliance', 'family': 'hexa', 'model': 'hexa_m', 'kind': 'in', 'effect': {'name': 'compliance', 'per': {'31': 0.000806, '32': 0.000806, '33': 0.000806, '34': 0.000806, '35': 0.000806, '36': 0.000806}}, 'targets': 'ring4', 'design': 'shells', 'n_id': 34, 'n_val': 12},
    {'name': 'hx_periodic2_32', 'family': 'hexa', 'model': 'hexa', 'kind': 'in', 'effect': {'name': 'screw-periodic', 'order': 2, 'per': {'32': [0.0195, -0.0156]}}, 'targets': 'tip6q', 'design': 'star', 'n_id': 34, 'n_val': 12},
    {'name': 'hx_thermal', 'family': 'hexa', 'model': 'hexa', 'kind': 'in', 'effect': {'name': 'thermal', 'kappa': 2.25e-05}, 'targets': 'ring4', 'design': 'corners', 'n_id': 34, 'n_val': 12},
    {'name': 'lf_pitch_1', 'family': 'lift', 'model': 'lift', 'kind': 'in', 'effect': {'name': 'screw-pitch', 'per': {'1': 0.000352}}, 'targets': 'fork3', 'design': 'antithetic', 'n_id': 48, 'n_val': 16},
    {'name': 'lf_periodic_1', 'family': 'lift', 'model': 'lift', 'kind': 'in', 'effect': {'name': 'screw-periodic', 'order': 1, 'per': {'1': [0.034, 0.0204]}}, 'targets': 'flange6r', 'design': 'star', 'n_id': 48, 'n_val': 16},
    {'name': 'lf_harm2_2', 'family': 'lift', 'model': 'lift', 'kind': 'in', 'effect': {'name': 'angle-harmonic', 'k': 2, 'per': {'2': [8.25e-05, -5.5e-05]}}, 'targets': 'fork3', 'design': 'shells', 'n_id': 48, 'n_val': 16},
    {'name': 'lf_harm1_4', 'family': 'lift', 'model': 'lift', 'kind': 'in', 'effect': {'name': 'angle-harmonic', 'k': 1, 'per': {'4': [0.00036, 0.000216]}}, 'targets': 'flange6r', 'design': 'corners', 'n_id': 48, 'n_val': 16},
    {'name': 'lf_scale_3', 'family': 'lift', 'model': 'lift', 'kind': 'in', 'effect': {'name': 'angle-scale', 'per': {'3': 0.000115}}, 'targets': 'fork3', 'design': 'star', 'n_id': 48, 'n_val': 16},
    {'name': 'lf_backlash_5', 'family': 'lift', 'model': 'lift', 'kind': 'in', 'effect': {'name': 'backlash', 'per': {'5': 0.000554}}, 'targets': 'fork3', 'design': 'antithetic', 'n_id': 48, 'n_val': 16, 'overshoot': True},
    {'name': 'lf_thermal', 'family': 'lift', 'model': 'lift', 'kind': 'in', 'effect': {'name': 'thermal', 'kappa': 1.8e-05}, 'targets': 'flange6r', 'design': 'shells', 'n_id': 36, 'n_val': 12},
    {'name': 'lfm_compliance_3', 'family': 'lift', 'model': 'lift_m', 'kind': 'in', 'effect': {'name': 'compliance', 'per': {'3': 4.7e-10}}, 'targets': 'fork3', 'design': 'corners', 'n_id': 48, 'n_val': 16},
    {'name': 'lfm_linkbend_3', 'family': 'lift', 'model': 'lift_m', 'kind': 'in', 'effect': {'name': 'link-bending', 'per': {'3': ['4', 9.2e-10]}}, 'targets': 'flange6r', 'design': 'antithetic', 'n_id': 48, 'n_val': 16},
    {'name': 'lfm_gbacklash_3', 'family': 'lift', 'model': 'lift_m', 'kind': 'in', 'effect': {'name': 'backlash-gravity', 'per': {'3': 0.00019}}, 'targets': 'fork3', 'design': 'star', 'n_id': 48, 'n_val': 16},
    {'name': 'cy_pitch_3', 'family': 'cyl', 'model': 'cyl', 'kind': 'in', 'effect': {'name': 'screw-pitch', 'per': {'3': 0.000325}}, 'targets': 'pair', 'design': 'antithetic', 'n_id': 44, 'n_val': 14},
    {'name': 'cy_periodic2_2', 'family': 'cyl', 'model': 'cyl', 'kind': 'in', 'effect': {'name': 'screw-periodic', 'order': 2, 'lead': 16.0, 'per': {'2': [0.033, 0.022]}}, 'targets': 'single', 'design': 'star', 'n_id': 44, 'n_val': 14},
    {'name': 'cy_straight_3', 'family': 'cyl', 'model': 'cyl', 'kind': 'in', 'effect': {'name': 'guide-straightness', 'per': {'3': [0.033, 0.022]}}, 'targets': 'pair', 'design': 'shells', 'n_id': 44, 'n_val': 14},
    {'name': 'cy_harm15_1', 'family': 'cyl', 'model': 'cyl', 'kind': 'in', 'effect': {'name': 'angle-harmonic', 'k': 1.5, 'per': {'1': [0.000122, -7.35e-05]}}, 'targets': 'single', 'design': 'corners', 'n_id': 44, 'n_val': 14},
    {'name': 'cy_scale_1', 'family': 'cyl', 'model': 'cyl', 'kind': 'in', 'effect': {'name': 'angle-scale', 'per': {'1': 5.04e-05}}, 'targets': 'pair', 'design': 'star', 'n_id': 44, 'n_val': 14},
    {'name': 'cy_backlash_1', 'family': 'cyl', 'model': 'cyl', 'kind': 'in', 'effect': {'name': 'backlash', 'per': {'1': 0.000124}}, 'targets': 'pair', 'design': 'antithetic', 'n_id': 44, 'n_val': 14, 'overshoot': True},
    {'name': 'cy_drift', 'family': 'cyl', 'model': 'cyl', 'kind': 'in', 'effect': {'name': 'tracker-drift', 'shift': {'2': [0.0304, -0.0228, 0.0152], '3': [-0.0228, 0.038, 0.0228], '4': [0.0152, 0.0228, -0.038]}}, 'targets': 'single', 'design': 'shells', 'n_id': 44, 'n_val': 14},
    {'name': 'cym_compliance_2', 'family': 'cyl', 'model': 'cyl_m', 'kind': 'in', 'effect': {'name': 'compliance', 'per': {'2': 0.00152}}, 'targets': 'pair', 'design': 'corners', 'n_id': 44, 'n_val': 14},
    {'name': 'cym_gbacklash_5', 'family': 'cyl', 'model': 'cyl_m', 'kind': 'in', 'effect': {'name': 'backlash-gravity', 'per': {'5': 0.000564}}, 'targets': 'single', 'design': 'star', 'n_id': 44, 'n_val': 14},
    {'name': 'cy_thermal', 'family': 'cyl', 'model': 'cyl', 'kind': 'in', 'effect': {'name': 'thermal', 'kappa': 2.4e-05}, 'targets': 'pair', 'design': 'antithetic', 'n_id': 60, 'n_val': 20},
    {'name': 'lo_balancer_3', 'family': 'lift', 'model': 'lift', 'kind': 'out', 'effect': {'name': 'balancer-spring', 'joint': '3', 'c': 5.6e-07, 'r1': 200.0, 'r2': 350.0, 'phi': 0.6, 'L0': 222.0}, 'targets': 'fork3', 'design': 'corners', 'n_id': 48, 'n_val': 16},
    {'name': 'lo_dent_1', 'family': 'lift', 'model': 'lift', 'kind': 'out', 'effect': {'name': 'rail-dent-pitch', 'joint': '1', 'a': 0.000174, 'q0': 380.0, 'w': 60.0}, 'targets': 'flange6r', 'design': 'antithetic', 'n_id': 48, 'n_val': 16},
    {'name': 'lo_rock_1', 'family': 'lift', 'model': 'lift', 'kind': 'out', 'effect': {'name': 'carriage-rock', 'joint': '1', 'c': 5.8e-05}, 'targets': 'fork3', 'design': 'star', 'n_id': 48, 'n_val': 16, 'overshoot': True},
    {'name': 'lo_runout_2', 'family': 'lift', 'model': 'lift', 'kind': 'out', 'effect': {'name': 'axial-runout', 'joint': '2', 'a': 0.0802, 'phase': 0.4}, 'targets': 'fork3', 'design': 'shells', 'n_id': 48, 'n_val': 16},
    {'name': 'lo_smr', 'family': 'lift', 'model': 'lift', 'kind': 'out', 'effect': {'name': 'smr-incidence', 'c': 0.158}, 'targets': 'fork3', 'design': 'antithetic', 'n_id': 48, 'n_val': 16},
    {'name': 'co_rock_3', 'family': 'cyl', 'model': 'cyl', 'kind': 'out', 'effect': {'name': 'carriage-rock', 'joint': '3', 'c': 0.000198}, 'targets': 'pair', 'design': 'star', 'n_id': 44, 'n_val': 14},
    {'name': 'co_worn_2', 'family': 'cyl', 'model': 'cyl', 'kind': 'out', 'effect': {'name': 'worn-screw-play', 'joint': '2', 'beta': 0.15, 's0': 0.3, 'w': 0.1}, 'targets': 'single', 'design': 'antithetic', 'n_id': 44, 'n_val': 14, 'overshoot': True},
    {'name': 'co_dent_2', 'family': 'cyl', 'model': 'cyl', 'kind': 'out', 'effect': {'name': 'rail-dent-pitch', 'joint': '2', 'a': 0.00022, 'q0': 300.0, 'w': 50.0}, 'targets': 'pair', 'design': 'corners', 'n_id': 44, 'n_val': 14},
    {'name': 'co_dent_3', 'family': 'cyl', 'model': 'cyl', 'kind': 'out', 'effect': {'name': 'rail-dent-pitch', 'joint': '3', 'a': 0.000627, 'q0': 250.0, 'w': 40.0}, 'targets': 'single', 'design': 'shells', 'n_id': 44, 'n_val': 14},
    {'name': 'co_smr', 'family': 'cyl', 'model': 'cyl', 'kind': 'out', 'effect': {'name': 'smr-incidence', 'c': 0.148}, 'targets': 'pair', 'design': 'star', 'n_id': 44, 'n_val': 14},
    {'name': 'txo_worn_42', 'family': 'tx7', 'model': 'tx7', 'kind': 'out', 'effect': {'name': 'worn-screw-play', 'joint': '42', 'beta': 0.0294, 's0': -0.2, 'w': 0.12}, 'targets': 'cross5', 'design': 'star', 'n_id': 44, 'n_val': 14, 'overshoot': True},
    {'name': 'txo_ptilt', 'family': 'tx7', 'model': 'tx7', 'kind': 'out', 'effect': {'name': 'payload-tilt', 'c': 2.48e-05}, 'targets': 'tcp6r', 'design': 'antithetic', 'n_id': 44, 'n_val': 14},
    {'name': 'txo_spindle', 'family': 'tx7', 'model': 'tx7', 'kind': 'out', 'effect': {'name': 'spindle-growth', 'kappa': 2.3e-05, 'L': 624.0}, 'targets': 'tcp6r', 'design': 'corners', 'n_id': 44, 'n_val': 14},
    {'name': 'txo_twist', 'family': 'tx7', 'model': 'tx7', 'kind': 'out', 'effect': {'name': 'platform-twist-thermal', 'c': 9.9e-05}, 'targets': 'cross5', 'design': 'shells', 'n_id': 44, 'n_val': 14},
    {'name': 'txo_smr', 'family': 'tx7', 'model': 'tx7', 'kind': 'out', 'effect': {'name': 'smr-incidence', 'c': 0.143}, 'targets': 'cross5', 'design': 'antithetic', 'n_id': 44, 'n_val': 14},
    {'name': 'hxo_worn_35', 'family': 'hexa', 'model': 'hexa', 'kind': 'out', 'effect': {'name': 'worn-screw-play', 'joint': '35', 'beta': 0.0706, 's0': 0.2, 'w': 0.12}, 'targets': 'ring4', 'design': 'shells', 'n_id': 34, 'n_val': 12, 'overshoot': True},
    {'name': 'hxo_ptilt', 'family': 'hexa', 'model': 'hexa', 'kind': 'out', 'effect': {'name': 'payload-tilt', 'c': 9.3e-06}, 'targets': 'tip6q', 'design': 'corners', 'n_id': 34, 'n_val': 12},
    {'name': 'hxo_twist', 'family': 'hexa', 'model': 'hexa', 'kind': 'out', 'effect': {'name': 'platform-twist-thermal', 'c': 6.24e-05}, 'targets': 'ring4', 'design': 'antithetic', 'n_id': 34, 'n_val': 12},
    {'name': 'hxo_spindle', 'family': 'hexa', 'model': 'hexa', 'kind': 'out', 'effect': {'name': 'spindle-growth', 'kappa': 2.3e-05, 'L': 500.0}, 'targets': 'tip6q', 'design': 'star', 'n_id': 34, 'n_val': 12},
    {'name': 'txo_balancer_7', 'family': 'tx7', 'model': 'tx7', 'kind': 'out', 'effect': {'name': 'balancer-spring', 'joint': '7', 'c': 3.4e-06, 'r1': 150.0, 'r2': 300.0, 'phi': 0.9, 'L0': 230.0}, 'targets': 'cross5', 'design': 'corners', 'n_id': 44, 'n_val': 14},
    {'name': 'tx_none', 'family': 'tx7', 'model': 'tx7', 'kind': 'none', 'effect': None, 'targets': 'cross5', 'design': 'antithetic', 'n_id': 44, 'n_val': 14},
    {'name': 'hxm_none_6d', 'family': 'hexa', 'model': 'hexa_m', 'kind': 'none', 'effect': None, 'targets': 'tip6q', 'design': 'shells', 'n_id': 34, 'n_val': 12},
    {'name': 'hx_none', 'family': 'hexa', 'model': 'hexa', 'kind': 'none', 'effect': None, 'targets': 'ring4', 'design': 'corners', 'n_id': 34, 'n_val': 12},
    {'name': 'lf_none', 'family': 'lift', 'model': 'lift', 'kind': 'none', 'effect': None, 'targets': 'fork3', 'design': 'star', 'n_id': 48, 'n_val': 16},
    {'name': 'lfm_none_6d', 'family': 'lift', 'model': 'lift_m', 'kind': 'none', 'effect': None, 'targets': 'flange6r', 'design': 'corners', 'n_id': 48, 'n_val': 16},
    {'name': 'cy_none', 'family': 'cyl', 'model': 'cyl', 'kind': 'none', 'effect': None, 'targets': 'single', 'design': 'antithetic', 'n_id': 44, 'n_val': 14},
    {'name': 'tx_under_17', 'family': 'tx7', 'model': 'tx7', 'kind': 'under', 'effect': None, 'targets': 'tcp6r', 'design': 'star', 'n_id': 44, 'n_val': 14, 'noise_factor': 1.7},
    {'name': 'txm_under_22', 'family': 'tx7', 'model': 'tx7_m', 'kind': 'under', 'effect': None, 'targets': 'cross5', 'design': 'corners', 'n_id': 44, 'n_val': 14, 'noise_factor': 2.2},
    {'name': 'hx_under_24', 'family': 'hexa', 'model': 'hexa', 'kind': 'under', 'effect': None, 'targets': 'ring4', 'design': 'antithetic', 'n_id': 34, 'n_val': 12, 'noise_factor': 2.4},
    {'name': 'lf_under_20', 'family': 'lift', 'model': 'lift', 'kind': 'under', 'effect': None, 'targets': 'flange6r', 'design': 'antithetic', 'n_id': 48, 'n_val': 16, 'noise_factor': 2.0},
    {'name': 'cy_under_28', 'family': 'cyl', 'model': 'cyl', 'kind': 'under', 'effect': None, 'targets': 'pair', 'design': 'corners', 'n_id': 44, 'n_val': 14, 'noise_factor': 2.8},
    {'name': 'cym_under_15', 'family': 'cyl', 'model': 'cyl_m', 'kind': 'under', 'effect': None, 'targets': 'single', 'design': 'shells', 'n_id': 44, 'n_val': 14, 'noise_factor': 1.5},
]

assert len({c["name"] for c in CASES}) == len(CASES) == 72
