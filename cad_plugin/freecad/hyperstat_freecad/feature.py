"""The skeleton object: an ``App::DocumentObjectGroupPython`` with a Python proxy.

Units: template parameters are FreeCAD quantities (``App::PropertyDistance`` in mm,
``App::PropertyAngle`` shown in degrees and passed to hyperstat in rad, plain floats
otherwise); the stored results are hyperstat's JSON in mm and rad.

Everything the object needs lives in its properties, so that a saved document is
self-contained: the template path, the parameters (possibly driven by spreadsheet
expressions), the model file written by the last build, the last analysis and
identification JSON.  The imported skeleton (markers and links) is a child group,
saved by FreeCAD like any shape.  The proxy itself carries only a type tag and a
version, saved through ``__getstate__/__setstate__`` (FreeCAD 0.20) and
``dumps/loads`` (FreeCAD 0.21 and later).

A recompute does not run hyperstat (a build takes seconds and changes the document's
tree, which a recompute must not do): it only marks the object *outdated* when its
parameters differ from the last build; the Rebuild and Analyse commands (or
:func:`hyperstat_freecad.operations.rebuild`) do the work.
"""

from __future__ import annotations

import json

from .parameters import current_parameters, parameter_specs

__all__ = ["SkeletonFeature", "BASE_PROPERTIES", "is_skeleton", "parameter_specs", "OutdatedObserver", "settle_touched"]

TYPE = "HyperstatSkeleton"
VERSION = 1

READ_ONLY, HIDDEN = 1, 2
#: (type, name, group, tooltip, editor mode)
BASE_PROPERTIES = [
    ("App::PropertyFile", "Template", "Hyperstat", "Template file (.py) the skeleton is built from", 0),
    ("App::PropertyString", "Mechanism", "Hyperstat", "Mechanism name given by the template", READ_ONLY),
    ("App::PropertyString", "Status", "Hyperstat", "State of the last build / analysis, or the last error", READ_ONLY),
    ("App::PropertyString", "Summary", "Hyperstat", "Joints, defect parameters and loop closures (from the build)", READ_ONLY),
    ("App::PropertyInteger", "Configurations", "Hyperstat", "Configurations sampled by the analysis", 0),
    ("App::PropertyInteger", "Seed", "Hyperstat", "Seed of the configuration sample", 0),
    ("App::PropertyLength", "MarkerSize", "Hyperstat", "Size of the joint markers (mm)", READ_ONLY),
    ("App::PropertyLink", "Spreadsheet", "Hyperstat", "Spreadsheet whose aliases drive the template parameters", READ_ONLY),
    ("App::PropertyString", "ParameterSpecs", "Hyperstat", "Template parameters: name, unit, meaning, bounds (JSON)", HIDDEN),
    ("App::PropertyString", "BuiltParameters", "Hyperstat", "Parameter values of the last build (JSON, mm / rad)", HIDDEN),
    ("App::PropertyString", "ModelJson", "Hyperstat", "Model file written by the last build (JSON)", HIDDEN),
    ("App::PropertyString", "Analysis", "Results", "Last stationarity analysis (hyperstat analyze --json)", HIDDEN),
    ("App::PropertyInteger", "Mobility", "Results", "Mobility of the nominal mechanism", READ_ONLY),
    ("App::PropertyInteger", "Overconstraint", "Results", "Degree of over-constraint", READ_ONLY),
    ("App::PropertyInteger", "Rank", "Results", "Rank of the stacked stationarity rows", READ_ONLY),
    ("App::PropertyString", "Tolerances", "Results", "Tolerances with their values (the report's JSON, hyperstat "
     "report)", HIDDEN),
    ("App::PropertyString", "Drawings", "Results", "Part drawings of the last report: per part its datums and frames "
     "(report.json's drawings and assembly_requirements)", HIDDEN),
    ("App::PropertyMap", "ToleranceCounts", "Results", "Number of tolerances per class (as the report counts them)",
     READ_ONLY),
    ("App::PropertyMap", "ParameterClasses", "Results", "Tolerance class of every defect parameter", READ_ONLY),
    ("App::PropertyFile", "MeasurementFile", "Measurements", "Identification measurements (CSV)", 0),
    ("App::PropertyFile", "ValidationFile", "Measurements", "Validation measurements (CSV), never fitted", 0),
    ("App::PropertyString", "Identification", "Measurements", "Last identification (hyperstat identify --json)", HIDDEN),
    ("App::PropertyString", "IdentificationText", "Measurements", "Printed summary of the last identification", HIDDEN),
    ("App::PropertyString", "Diagnosis", "Measurements", "Last diagnosis (hyperstat diagnose --json)", HIDDEN),
    ("App::PropertyString", "DiagnosisText", "Measurements", "Printed summary of the last diagnosis", HIDDEN),
    ("App::PropertyPath", "ReportDir", "Exports", "Folder of the last tolerance report", 0),
    ("App::PropertyFile", "ControllerFile", "Exports", "Last controller parameter file", 0),
]


#: the properties a user (or a spreadsheet) sets; every other one is an *output*: writing it (a build, an
#: analysis, an identification) does not mark the skeleton "needs recompute"
INPUTS = ("Template", "Configurations", "Seed")


def add_base_properties(obj) -> None:
    """Add the properties of :data:`BASE_PROPERTIES` that ``obj`` does not have yet; mark outputs as such."""
    for type_, name, group, tip, mode in BASE_PROPERTIES:
        if name not in obj.PropertiesList:
            obj.addProperty(type_, name, group, tip)
            if mode:
                obj.setEditorMode(name, mode)
        if name not in INPUTS and "Output" not in obj.getPropertyStatus(name):
            obj.setPropertyStatus(name, "Output")


def is_skeleton(obj) -> bool:
    """True for an object whose proxy is a :class:`SkeletonFeature`."""
    return getattr(getattr(obj, "Proxy", None), "Type", None) == TYPE


class SkeletonFeature:
    """Proxy of a hyperstat skeleton object (see the module docstring)."""

    def __init__(self, obj):
        self.Type = TYPE
        self.version = VERSION
        obj.Proxy = self
        add_base_properties(obj)
        obj.Configurations = 24
        obj.Seed = 0
        obj.Status = "new"

    def execute(self, obj) -> None:
        """Mark the object outdated when its parameters differ from the last build."""
        if not obj.BuiltParameters:
            return
        try:
            changed = current_parameters(obj) != json.loads(obj.BuiltParameters)
        except (ValueError, TypeError):
            changed = True
        if changed and not obj.Status.startswith("outdated"):
            obj.Status = "outdated: parameters changed since the last build (Rebuild or Analyse)"
        elif not changed and obj.Status.startswith(("outdated", "error")):
            # back to the parameters of the last build (an edit undone, a failed rebuild cancelled)
            obj.Status = "analysed" if obj.Analysis else "built; not analysed"

    def onDocumentRestored(self, obj) -> None:
        """Add properties introduced by later versions to objects saved by earlier ones."""
        add_base_properties(obj)

    # FreeCAD 0.20 saves proxies with __getstate__/__setstate__, 0.21+ with dumps/loads
    def __getstate__(self) -> dict:
        return {"Type": self.Type, "version": self.version}

    def __setstate__(self, state) -> None:
        state = state or {}
        self.Type = state.get("Type", TYPE)
        self.version = int(state.get("version", VERSION))

    def dumps(self) -> dict:
        return self.__getstate__()

    def loads(self, state) -> None:
        self.__setstate__(state)


class OutdatedObserver:
    """Document observer: after a recompute, an *outdated* skeleton keeps FreeCAD's "needs recompute" mark.

    A spreadsheet edit changes the parameters; the recompute evaluates them and the skeleton's
    ``execute`` sets ``Status`` to *outdated* (it does not rebuild, see the module docstring).
    FreeCAD then clears the touched flag, which would show the old geometry as up to date:
    this observer touches the skeleton again, so the tree shows it as needing work until a
    Rebuild or an Analyse.  Results written by Identify or Diagnose are *output* properties
    and do not touch it.  Registered once by the GUI (``FreeCAD.addDocumentObserver``).
    """

    def slotRecomputedDocument(self, doc) -> None:
        for obj in doc.Objects:
            if is_skeleton(obj) and obj.Status.startswith("outdated") and "Touched" not in obj.State:
                obj.touch()

    # Edit > Undo and Redo restore the skeleton's properties and leave it touched ("needs recompute" in the
    # tree) even where what they restored is consistent (the status says "analysed"): once the step is
    # done, the touched mark is made to say what the status says.
    def slotUndoDocument(self, doc) -> None:  # noqa: N802 - FreeCAD's name
        self._later(doc)

    def slotRedoDocument(self, doc) -> None:  # noqa: N802 - FreeCAD's name
        self._later(doc)

    def _later(self, doc) -> None:
        from PySide import QtCore

        name = getattr(doc, "Name", None)
        QtCore.QTimer.singleShot(0, lambda: settle_touched(name))


def settle_touched(doc_name: str | None) -> None:
    """Touched exactly when the skeleton needs work: its parameters differ from its last build.

    A skeleton whose parameters are those of its last build is up to date whatever an undo or redo
    left: its touched mark is cleared (and an *outdated* status set back); one whose parameters
    differ keeps (or gets) the mark and the *outdated* status.
    """
    import FreeCAD

    doc = FreeCAD.listDocuments().get(doc_name) if doc_name else None
    for obj in doc.Objects if doc is not None else []:
        if not is_skeleton(obj) or not obj.BuiltParameters:
            continue
        try:
            changed = current_parameters(obj) != json.loads(obj.BuiltParameters)
        except (ValueError, TypeError):
            changed = True
        if changed:
            if not obj.Status.startswith("outdated"):
                obj.Status = "outdated: parameters changed since the last build (Rebuild or Analyse)"
            if "Touched" not in obj.State:
                obj.touch()
        else:
            if obj.Status.startswith("outdated"):
                obj.Status = "analysed" if obj.Analysis else "built; not analysed"
            if "Touched" in obj.State:
                obj.purgeTouched()
