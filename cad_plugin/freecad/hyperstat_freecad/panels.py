"""Task panels: insert a skeleton, edit its parameters, read the results, read a command's output.

Units: lengths in mm; angles shown in degrees (FreeCAD's convention) and passed to
hyperstat in rad.

Every action a panel runs goes through :func:`.messages.guarded`: an error becomes a
message box and a line in the report view, and the panel stays open and usable.
"""

from __future__ import annotations

import math

from .messages import guarded, icon_path, show_error, show_info
from .verdicts import VERDICT_COLORS, VERDICT_ORDER, VERDICT_TEXT, parameter_class

__all__ = ["InsertPanel", "ParametersPanel", "ResultsPanel", "TextPanel", "show_panel", "open_parameters",
           "open_results", "open_text", "ACTIVE"]

#: the panel on screen (kept referenced so that Qt does not lose it; tests read it)
ACTIVE: list = []


def show_panel(panel) -> bool:
    """Show a task panel, closing one of ours that is open; refuse politely if another is."""
    import FreeCADGui

    if FreeCADGui.Control.activeDialog():
        if ACTIVE:
            FreeCADGui.Control.closeDialog()
        else:
            show_error("Task panel", "Another task panel is open: close it first.")
            return False
    ACTIVE[:] = [panel]
    FreeCADGui.Control.showDialog(panel)
    return True


def _close() -> None:
    import FreeCADGui

    FreeCADGui.Control.closeDialog()
    ACTIVE.clear()


class InsertPanel:
    """Choose a template (shipped or any file) and insert its skeleton."""

    def __init__(self, doc):
        from PySide import QtGui

        from .runner import list_templates

        self.doc = doc
        self.form = QtGui.QWidget()
        self.form.setWindowTitle("Insert a hyperstat skeleton")
        self.form.setWindowIcon(QtGui.QIcon(icon_path("insert")))
        layout = QtGui.QVBoxLayout(self.form)
        layout.addWidget(QtGui.QLabel("Template (lengths in mm, angles in rad):"))
        self.combo = QtGui.QComboBox()
        for path in list_templates():
            self.combo.addItem(path.stem, str(path))
        layout.addWidget(self.combo)
        browse = QtGui.QPushButton("Other template file...")
        browse.clicked.connect(self.browse)
        layout.addWidget(browse)
        self.spreadsheet = QtGui.QCheckBox("Drive the parameters from a spreadsheet")
        self.spreadsheet.setChecked(True)
        layout.addWidget(self.spreadsheet)
        self.analyse = QtGui.QCheckBox("Analyse after inserting")
        self.analyse.setChecked(True)
        layout.addWidget(self.analyse)
        note = QtGui.QLabel("A template is Python and runs as code: only use templates you trust.")
        note.setWordWrap(True)
        layout.addWidget(note)
        if self.combo.count() == 0:
            layout.addWidget(QtGui.QLabel("No shipped templates found: run 'make freecad-install' or browse."))

    def select(self, name_or_path: str) -> None:
        """Choose a template by name or path (what the user does with the combo box)."""
        index = self.combo.findText(name_or_path)
        if index < 0:
            self.combo.addItem(name_or_path, name_or_path)
            index = self.combo.count() - 1
        self.combo.setCurrentIndex(index)

    def browse(self) -> None:
        from PySide import QtGui

        path, _ = QtGui.QFileDialog.getOpenFileName(self.form, "Template", "", "hyperstat templates (*.py)")
        if path:
            self.select(path)

    def getStandardButtons(self) -> int:
        from PySide import QtGui

        return int(QtGui.QDialogButtonBox.Ok | QtGui.QDialogButtonBox.Cancel)

    def accept(self) -> bool:
        from .operations import analyze, insert_skeleton

        template = self.combo.itemData(self.combo.currentIndex()) if self.combo.count() else None
        if not template:
            show_error("Insert skeleton", "Choose a template first.")
            return False
        then_analyse = self.analyse.isChecked()
        obj = guarded("Insert skeleton", insert_skeleton, self.doc, template, spreadsheet=self.spreadsheet.isChecked())
        if obj is None:
            return False  # the message was shown; the panel stays open
        self.inserted = obj
        _fit_view()
        _close()  # the form's widgets are gone after this
        if then_analyse and guarded("Analyse", analyze, obj) is not None:
            open_results(obj)
        else:
            show_info("Insert skeleton", f"{obj.Label}: {obj.Summary}")
        return True

    def reject(self) -> bool:
        _close()
        return True


def _fit_view() -> None:
    import FreeCADGui

    view = getattr(FreeCADGui.ActiveDocument, "ActiveView", None) if FreeCADGui.ActiveDocument else None
    if view is not None and hasattr(view, "viewIsometric"):
        view.viewIsometric()
        view.fitAll()


class ParametersPanel:
    """Edit the template parameters (spreadsheet-bound ones are written to their cells), then rebuild."""

    def __init__(self, obj):
        from PySide import QtGui

        from .feature import parameter_specs
        from .parameters import current_parameters, expression_of

        self.obj = obj
        self.specs = parameter_specs(obj)
        values = current_parameters(obj)
        self.original = dict(values)
        self.form = QtGui.QWidget()
        self.form.setWindowTitle(f"Parameters of {obj.Label}")
        self.form.setWindowIcon(QtGui.QIcon(icon_path("parameters")))
        layout = QtGui.QFormLayout(self.form)
        self.boxes = {}
        for spec in self.specs:
            name, unit = spec["name"], spec.get("unit", "1")
            box = QtGui.QDoubleSpinBox()
            box.setDecimals(6)
            scale = (180.0 / math.pi) if unit == "rad" else 1.0
            lo = spec.get("minimum")
            hi = spec.get("maximum")
            box.setRange(-1e9 if lo is None else lo * scale, 1e9 if hi is None else hi * scale)
            box.setSuffix({"mm": " mm", "rad": " °"}.get(unit, ""))
            box.setValue(values[name] * scale)
            expr = expression_of(obj, name)
            tip = spec.get("doc", "")
            if expr:
                tip += f"\nDriven by the spreadsheet ({expr}): a change here is written to that cell."
            box.setToolTip(tip)
            self.boxes[name] = (box, scale)
            layout.addRow(name, box)
        self.analyse = QtGui.QCheckBox("Analyse after rebuilding")
        self.analyse.setChecked(True)
        layout.addRow(self.analyse)

    def set_value(self, name: str, value: float) -> None:
        """Type a value (template units: mm, rad) into a field."""
        box, scale = self.boxes[name]
        box.setValue(value * scale)

    def reject(self) -> bool:
        """Cancel: put back the values the panel opened with (a failed OK may have written some)."""
        from .operations import set_parameters
        from .parameters import current_parameters

        _close()
        if current_parameters(self.obj) != self.original:
            guarded("Parameters", set_parameters, self.obj, self.original)
        return True

    def getStandardButtons(self) -> int:
        from PySide import QtGui

        return int(QtGui.QDialogButtonBox.Ok | QtGui.QDialogButtonBox.Cancel)

    def accept(self) -> bool:
        from .operations import analyze, rebuild, set_parameters

        values = {name: box.value() / scale for name, (box, scale) in self.boxes.items()}
        then_analyse = self.analyse.isChecked()
        if guarded("Parameters", set_parameters, self.obj, values) is None:
            return False
        if guarded("Rebuild", rebuild, self.obj) is None:
            return False  # message shown, panel stays open to fix the value
        _close()  # the form's widgets are gone after this
        if then_analyse and guarded("Analyse", analyze, self.obj) is not None:
            open_results(self.obj)
        return True


class ResultsPanel:
    """The analysis: summary, one row per defect parameter coloured by verdict, the relations."""

    def __init__(self, obj):
        from PySide import QtCore, QtGui

        from .operations import results

        self.obj = obj
        analysis = results(obj)
        self.form = QtGui.QWidget()
        self.form.setWindowTitle(f"Stationarity analysis of {obj.Label}")
        self.form.setWindowIcon(QtGui.QIcon(icon_path("results")))
        layout = QtGui.QVBoxLayout(self.form)
        self.summary = QtGui.QLabel()
        self.summary.setWordWrap(True)
        layout.addWidget(self.summary)
        self.table = QtGui.QTableWidget(0, 6)
        self.table.setHorizontalHeaderLabels(["parameter", "element", "unit", "verdict", "influence", "reason"])
        self.table.setEditTriggers(QtGui.QAbstractItemView.NoEditTriggers)
        self.table.setSelectionBehavior(QtGui.QAbstractItemView.SelectRows)
        self.table.itemSelectionChanged.connect(self.select_marker)
        self.table.setMinimumHeight(380)
        layout.addWidget(self.table, 1)
        self.relations = QtGui.QPlainTextEdit()
        self.relations.setReadOnly(True)
        self.relations.setMaximumHeight(110)
        layout.addWidget(self.relations)
        legend = QtGui.QLabel(" ".join(
            f"<span style='background:{_hex(VERDICT_COLORS[c])}'>&nbsp;&nbsp;&nbsp;</span> {VERDICT_TEXT[c]}<br>"
            for c in VERDICT_ORDER))
        legend.setTextFormat(QtCore.Qt.RichText)
        layout.addWidget(legend)
        if analysis is None:
            self.summary.setText(f"{obj.Label}: not analysed since its last build ({obj.Status}). Run Analyse.")
            self.rows = []
            return
        counts = {c: 0 for c in VERDICT_ORDER}
        self.rows = analysis["parameters"]
        self.table.setRowCount(len(self.rows))
        for i, p in enumerate(self.rows):
            cls = parameter_class(p)
            counts[cls] += 1
            influence = p.get("influence")
            cells = [p["name"], p["element"], p.get("unit", ""), cls,
                     "" if influence is None else f"{influence:.3g}", p.get("reason", "")]
            for j, text in enumerate(cells):
                item = QtGui.QTableWidgetItem(str(text))
                if j == 3:
                    item.setBackground(QtGui.QColor.fromRgbF(*VERDICT_COLORS[cls]))
                self.table.setItem(i, j, item)
        self.table.resizeColumnsToContents()
        per_class = ", ".join(f"{counts[c]} {c}" for c in VERDICT_ORDER if counts[c])
        self.summary.setText(
            f"<b>{analysis.get('mechanism', obj.Mechanism)}</b>: mobility {analysis.get('mobility')}, "
            f"over-constraint {analysis.get('overconstraint')}, rank {analysis.get('rank')} "
            f"(singular-value gap {analysis.get('singular_value_gap') or 0:.3g}); {len(self.rows)} defect parameters: "
            f"{per_class}. Lengths in mm, angles in rad.")
        rel = analysis.get("relations") or []
        self.relations.setPlainText("Relations between coupled defects:\n" + "\n".join(r["text"] for r in rel)
                                    if rel else "No relation between defects.")

    def select_marker(self) -> None:
        """Select the verdict sphere of the element of the selected row in the 3D view."""
        import FreeCADGui

        from .geometry import verdict_spheres

        rows = {i.row() for i in self.table.selectedItems()}
        if not rows:
            return
        spheres = verdict_spheres(self.obj)
        FreeCADGui.Selection.clearSelection()
        for r in rows:
            sphere = spheres.get(self.rows[r]["element"])
            if sphere is not None:
                FreeCADGui.Selection.addSelection(sphere)

    def getStandardButtons(self) -> int:
        from PySide import QtGui

        return int(QtGui.QDialogButtonBox.Close)

    def accept(self) -> bool:
        _close()
        return True

    def reject(self) -> bool:
        _close()
        return True


def _hex(rgb) -> str:
    return "#" + "".join(f"{round(255 * c):02x}" for c in rgb)


class TextPanel:
    """What a command printed (identification, diagnosis), in a fixed-width font."""

    def __init__(self, title: str, text: str, icon: str = "hyperstat"):
        from PySide import QtGui

        self.form = QtGui.QWidget()
        self.form.setWindowTitle(title)
        self.form.setWindowIcon(QtGui.QIcon(icon_path(icon)))
        layout = QtGui.QVBoxLayout(self.form)
        self.text = QtGui.QPlainTextEdit()
        self.text.setReadOnly(True)
        self.text.setFont(QtGui.QFont("Monospace"))
        self.text.setPlainText(text)
        layout.addWidget(self.text)

    def getStandardButtons(self) -> int:
        from PySide import QtGui

        return int(QtGui.QDialogButtonBox.Close)

    def accept(self) -> bool:
        _close()
        return True

    def reject(self) -> bool:
        _close()
        return True


def open_parameters(obj) -> None:
    """Show the parameters panel of a skeleton."""
    try:
        show_panel(ParametersPanel(obj))
    except Exception as exc:  # noqa: BLE001
        show_error("Parameters", exc)


def open_results(obj) -> None:
    """Show the results panel of a skeleton."""
    try:
        show_panel(ResultsPanel(obj))
    except Exception as exc:  # noqa: BLE001
        show_error("Results", exc)


def open_text(title: str, text: str, icon: str = "hyperstat") -> None:
    """Show a command's printed output."""
    try:
        show_panel(TextPanel(title, text, icon))
    except Exception as exc:  # noqa: BLE001
        show_error(title, exc)
