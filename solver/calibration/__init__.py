"""Calibration: measurement files, identification of the free defects, pose selection.

Measurement files and noise models (:mod:`.measurements`), the identification of the
influential admissible defects with the tracker frame and target (:mod:`.identify`), whether
a fit can be trusted (:mod:`.fit_checks`: noise ratios per target, equations per parameter,
conditioning, coinciding targets, the region covered; :mod:`.outliers`: outliers by the
deleted residual, poses repeated within the noise),
D-optimal pose selection (:mod:`.poses`) and a virtual machine that simulates campaigns
(:mod:`.virtual`).  Built on kinematics, analysis and tolerances.  Units: mm and rad.
"""
