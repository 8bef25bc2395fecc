"""Export: what leaves hyperstat for people and controllers.

Plain-text summaries (:mod:`.text`), the content of the tolerance report
(:mod:`.report_content`, laid out by :mod:`hyperstat.cad_plugin.report`), the controller
parameter file with its schema and hash (:mod:`.controller`) and LinuxCNC parameters
(:mod:`.linuxcnc`).  The last stage: it may use every stage before it.  Units: mm and rad.
"""

from hyperstat.solver.export.text import format_analysis

__all__ = ["format_analysis"]
