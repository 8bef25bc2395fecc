"""Calibration: measurement files, identification of the free defects, pose selection.

Measurement files and noise models (:mod:`.measurements`), the identification of the
influential admissible defects with the tracker frame and target (:mod:`.identify`),
D-optimal pose selection (:mod:`.poses`) and a virtual machine that simulates campaigns
(:mod:`.virtual`).  Built on kinematics, analysis and tolerances.  Units: mm and rad.
"""
