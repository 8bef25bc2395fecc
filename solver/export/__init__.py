"""Export: what leaves hyperstat for people and controllers.

Plain-text summaries (:mod:`.text`), the content of the tolerance report
(:mod:`.report_content`, laid out by :mod:`hyperstat.cad_plugin.report`), the controller
parameter file with its schema, hash and test vectors (:mod:`.controller`) and its
self-consistency checks (:mod:`.controller_checks`), the export gate that reads identify's
findings (:mod:`.calibration_gate`), straight moves against joint ranges and the calibrated
region (:mod:`.straight_moves`), and what a
LinuxCNC controller loads: ``genhexkins`` (:mod:`.linuxcnc`) and ``genserkins``
(:mod:`.genserkins`) parameters, a generated kinematics component (:mod:`.linuxcnc_kins`),
a simulated machine and its headless run (:mod:`.linuxcnc_sim`, :mod:`.linuxcnc_driver`).
The last stage: it may use every stage before it.  Units: mm and rad.
"""

from hyperstat.solver.export.text import format_analysis

__all__ = ["format_analysis"]
