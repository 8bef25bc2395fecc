"""Task panels: insert a skeleton, edit its parameters, read the results, read a command's output.

Units: lengths in mm; angles shown in degrees (FreeCAD's convention) and passed to
hyperstat in rad.

Every action a panel runs is a :class:`.jobs.Job` (the GUI never freezes); an error becomes a
message box and a line in the report view, and the panel stays open and usable.
"""

from __future__ import annotations

import math

from .messages import icon_path, show_error, show_info
from .classes import CLASS_COLORS, CLASS_LABELS, CLASS_ORDER, CLASS_RGB, relations_of, tolerance_counts, tolerance_rows

__all__ = ["InsertPanel", "ParametersPanel", "ResultsPanel", "TextPanel", "show_panel", "show_later",
           "open_parameters", "open_results", "open_text", "open_identification", "open_diagnosis", "ACTIVE",
           "IdentificationPanel", "DiagnosisPanel", "BarPlot", "legend_html"]

#: the panel on screen (kept referenced so that Qt does not lose it; tests read it)
ACTIVE: list = []


def show_panel(panel) -> bool:
    """Show a task panel, closing one of ours that is open; refuse politely if another workbench's is."""
    import FreeCADGui

    if FreeCADGui.Control.activeDialog():
        if ACTIVE and not getattr(ACTIVE[0], "job", None):
            _close()
        if FreeCADGui.Control.activeDialog():
            show_error("Task panel", "Another task panel is open: close it first.")
            return False
    ACTIVE[:] = [panel]
    FreeCADGui.Control.showDialog(panel)
    return True


def show_later(opener, *args, tries: int = 40) -> None:
    """Call ``opener(*args)`` from Qt's event loop once no task dialog is closing any more.

    A panel's OK runs inside FreeCAD's handling of that button, where the dialog is still
    the active one: opening the next panel from there is what made the first OK fail.
    """
    from PySide import QtCore

    def attempt(left=tries):
        import FreeCADGui

        if FreeCADGui.Control.activeDialog() and not ACTIVE and left > 0:
            QtCore.QTimer.singleShot(50, lambda: attempt(left - 1))  # still closing
            return
        opener(*args)

    QtCore.QTimer.singleShot(0, attempt)


def _close() -> None:
    import FreeCADGui

    for panel in ACTIVE:
        if hasattr(panel, "detach"):
            panel.detach()
    ACTIVE.clear()
    FreeCADGui.Control.closeDialog()


def _progress_widgets(layout):
    """A progress bar with a label (hidden until a job runs) at the bottom of a panel.

    The bar shows the share of the stage's estimated duration, as the status bar's does, set at each of the
    job's ticks: not Qt's busy indicator, whose animation repaints the window tens of times a second, which
    on a display without a GPU (software OpenGL: a virtual machine, a remote desktop, Xvfb) took a third of a
    core from the ``hyperstat`` command the job waits for.
    """
    from PySide import QtGui

    label = QtGui.QLabel()
    label.setWordWrap(True)
    label.setObjectName("HyperstatPanelProgressText")
    bar = QtGui.QProgressBar()
    bar.setRange(0, 100)
    bar.setValue(0)
    bar.setObjectName("HyperstatPanelProgress")
    for w in (label, bar):
        w.hide()
        layout.addWidget(w) if not isinstance(layout, QtGui.QFormLayout) else layout.addRow(w)
    return label, bar


class _JobPanel:
    """A panel whose OK starts a :class:`~.jobs.Job`: the panel stays open, greyed, with a progress bar,
    until the job ends; Cancel stops the job.  The next panel opens after this one has closed."""

    job = None
    title = "Hyperstat"

    def _inputs(self) -> list:
        return []

    def _busy(self, busy: bool) -> None:
        for w in self._inputs():
            w.setEnabled(not busy)
        self.progress_label.setVisible(busy)
        self.progress_bar.setVisible(busy)

    def _progress(self, text: str) -> None:
        """The job's tick: its text, and its share of the stage's estimate on the bar."""
        self.progress_label.setText(text)
        if self.job is not None:
            self.progress_bar.setValue(self.job.percent)

    def _run(self, steps, on_done) -> None:
        from .jobs import Job

        self._busy(True)
        self.progress_bar.setValue(0)
        self.job = Job(self.title, steps, on_done=lambda value: self._finished(on_done, value),
                       on_error=self._failed, progress=self._progress, on_cancel=self._cancelled)
        if not self.job.start():
            self.job = None
            self._busy(False)

    def _finished(self, on_done, value) -> None:
        self.job = None
        if ACTIVE and ACTIVE[0] is self:
            _close()
        on_done(value)

    def _cancelled(self) -> None:
        self.job = None
        if ACTIVE and ACTIVE[0] is self:
            self._busy(False)

    def _failed(self, exc) -> None:
        self.job = None
        if ACTIVE and ACTIVE[0] is self:
            self._busy(False)  # the panel stays open to fix the input
        show_error(self.title, exc)

    def getStandardButtons(self) -> int:
        from PySide import QtGui

        return int(QtGui.QDialogButtonBox.Ok | QtGui.QDialogButtonBox.Cancel)


class InsertPanel(_JobPanel):
    """Choose a template (shipped or any file) and insert its skeleton."""

    title = "Insert skeleton"

    def __init__(self, doc):
        from PySide import QtGui

        from .runner import list_templates

        self.doc = doc
        self.inserted = None
        self.form = QtGui.QWidget()
        self.form.setWindowTitle("Insert skeleton")
        self.form.setWindowIcon(QtGui.QIcon(icon_path("insert")))
        layout = QtGui.QVBoxLayout(self.form)
        label = QtGui.QLabel("Template (lengths in mm, angles in rad):")
        label.setWordWrap(True)
        layout.addWidget(label)
        self.combo = QtGui.QComboBox()
        self.combo.setSizeAdjustPolicy(QtGui.QComboBox.AdjustToMinimumContentsLengthWithIcon)
        self.combo.setMinimumContentsLength(8)
        for path in list_templates():
            self.combo.addItem(path.stem, str(path))
        layout.addWidget(self.combo)
        self.browse_button = QtGui.QPushButton("Other template file...")
        self.browse_button.clicked.connect(self.browse)
        layout.addWidget(self.browse_button)
        self.spreadsheet = QtGui.QCheckBox("Spreadsheet")
        self.spreadsheet.setToolTip("Drive the parameters from a spreadsheet (one aliased cell per parameter)")
        self.spreadsheet.setChecked(True)
        layout.addWidget(self.spreadsheet)
        self.analyse = QtGui.QCheckBox("Analyse at once")
        self.analyse.setToolTip("Run the stationarity analysis after inserting (same undo step)")
        self.analyse.setChecked(True)
        layout.addWidget(self.analyse)
        note = QtGui.QLabel("A template is Python and runs as code: only use templates you trust.")
        note.setWordWrap(True)
        layout.addWidget(note)
        if self.combo.count() == 0:
            empty = QtGui.QLabel("No shipped templates found: run 'make freecad-install' or browse.")
            empty.setWordWrap(True)
            layout.addWidget(empty)
        self.progress_label, self.progress_bar = _progress_widgets(layout)
        layout.addStretch(1)

    def _inputs(self) -> list:
        return [self.combo, self.browse_button, self.spreadsheet, self.analyse]

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

    def accept(self) -> bool:
        """OK: build (and analyse) in the background; the panel closes when the skeleton is in the document."""
        from .operations import insert_steps

        if self.job is not None:
            return False  # already under way
        template = self.combo.itemData(self.combo.currentIndex()) if self.combo.count() else None
        if not template:
            show_error(self.title, "Choose a template first.")
            return False
        analyse = self.analyse.isChecked()
        try:
            steps = insert_steps(self.doc, template, spreadsheet=self.spreadsheet.isChecked(), analyse=analyse)
        except Exception as exc:  # noqa: BLE001
            show_error(self.title, exc)
            return False
        self._run(steps, lambda obj: self._inserted(obj, analyse))
        return False  # FreeCAD keeps the panel open; it closes itself when done

    def _inserted(self, obj, analysed: bool) -> None:
        self.inserted = obj
        _fit_view()
        if analysed:
            show_later(open_results, obj)
        else:
            show_info(self.title, f"{obj.Label}: {obj.Summary}")

    def reject(self) -> bool:
        if self.job is not None:
            self.job.cancel()
        _close()
        return True


def _fit_view() -> None:
    import FreeCADGui

    view = getattr(FreeCADGui.ActiveDocument, "ActiveView", None) if FreeCADGui.ActiveDocument else None
    if view is not None and hasattr(view, "viewIsometric"):
        view.viewIsometric()
        view.fitAll()


class ParametersPanel(_JobPanel):
    """Edit the template parameters (spreadsheet-bound ones are written to their cells), then rebuild.

    The values are written only when the build with them succeeds, in the same undo step
    as the new geometry and its analysis: a value the template refuses leaves the document
    as it was, with one message, and the panel open to fix it.
    """

    title = "Edit parameters"

    def __init__(self, obj):
        from PySide import QtGui

        from .parameters import current_parameters, expression_of, parameter_specs

        self.obj = obj
        self.specs = parameter_specs(obj)
        values = current_parameters(obj)
        self.original = dict(values)
        self.form = QtGui.QWidget()
        self.form.setWindowTitle("Parameters")
        self.form.setWindowIcon(QtGui.QIcon(icon_path("parameters")))
        layout = QtGui.QFormLayout(self.form)
        layout.setFieldGrowthPolicy(QtGui.QFormLayout.AllNonFixedFieldsGrow)
        self.boxes = {}
        self.shown = {}
        for spec in self.specs:
            name, unit = spec["name"], spec.get("unit", "1")
            box = QtGui.QDoubleSpinBox()
            box.setDecimals(6)
            box.setMinimumWidth(90)
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
            self.shown[name] = box.value()
            layout.addRow(name, box)
        self.analyse = QtGui.QCheckBox("Analyse too")
        self.analyse.setToolTip("Analyse after rebuilding (same undo step)")
        self.analyse.setChecked(True)
        layout.addRow(self.analyse)
        self.progress_label, self.progress_bar = _progress_widgets(layout)

    def _inputs(self) -> list:
        return [box for box, _ in self.boxes.values()] + [self.analyse]

    def set_value(self, name: str, value: float) -> None:
        """Type a value (template units: mm, rad) into a field."""
        box, scale = self.boxes[name]
        box.setValue(value * scale)

    def changed(self) -> dict[str, float]:
        """The values the user changed (template units); untouched fields keep their full precision."""
        return {name: box.value() / scale for name, (box, scale) in self.boxes.items()
                if box.value() != self.shown[name]}

    def reject(self) -> bool:
        """Cancel: stop a running build; the document keeps the values it had (nothing was written)."""
        if self.job is not None:
            self.job.cancel()
        _close()
        return True

    def accept(self) -> bool:
        """OK: build with the changed values in the background, then write them, rebuild and analyse (one undo)."""
        from .operations import analyze_steps, edit_steps, needs_rebuild

        if self.job is not None:
            return False
        values = self.changed()
        analyse = self.analyse.isChecked()
        try:
            if values or needs_rebuild(self.obj):
                steps = edit_steps(self.obj, values, analyse)
            elif analyse and not self.obj.Analysis:
                steps = analyze_steps(self.obj)
            else:
                _close()
                if self.obj.Analysis:
                    show_later(open_results, self.obj)
                return True
        except Exception as exc:  # noqa: BLE001
            show_error(self.title, exc)
            return False
        self._run(steps, lambda _value: show_later(open_results, self.obj) if analyse else None)
        return False


class _NonModal:
    """A panel that only shows results: while it is open, the workbench's and FreeCAD's commands stay
    available (FreeCAD greys out document-changing commands while a task panel forbids it). Its one
    button is Close."""

    def isAllowedAlterDocument(self) -> bool:
        return True

    def isAllowedAlterView(self) -> bool:
        return True

    def isAllowedAlterSelection(self) -> bool:
        return True

    def getStandardButtons(self) -> int:
        from PySide import QtGui

        return int(QtGui.QDialogButtonBox.Close)

    def accept(self) -> bool:
        _close()
        return True

    def reject(self) -> bool:
        _close()
        return True


class _FollowDocument:
    """Document observer of an open results panel: after Edit > Undo or Redo, the panel shows the document again."""

    def __init__(self, panel):
        self.panel = panel

    def _later(self, doc) -> None:
        from PySide import QtCore

        if getattr(doc, "Name", None) == self.panel.doc_name:
            QtCore.QTimer.singleShot(0, self.panel.refresh)

    def slotUndoDocument(self, doc) -> None:  # noqa: N802 - FreeCAD's name
        self._later(doc)

    def slotRedoDocument(self, doc) -> None:  # noqa: N802 - FreeCAD's name
        self._later(doc)


class ResultsPanel(_NonModal):
    """The analysis as the report gives it: counts per class, the tolerance table with the values, T-ids and
    drawing frames, the class of every defect parameter, the part drawings (every frame and datum per part),
    the colour legend.  Follows Undo and Redo."""

    COLUMNS = ["id", "class", "statement", "feature", "without calibration", "with calibration", "drawing"]

    def __init__(self, obj):
        import FreeCAD
        from PySide import QtCore, QtGui

        self.doc_name, self.name = obj.Document.Name, obj.Name
        self.obj = obj
        self.form = QtGui.QWidget()
        self.form.setWindowTitle("Tolerances")
        self.form.setWindowIcon(QtGui.QIcon(icon_path("results")))
        layout = QtGui.QVBoxLayout(self.form)
        self.summary = QtGui.QLabel()
        self.summary.setWordWrap(True)
        self.summary.setObjectName("HyperstatResultsSummary")
        layout.addWidget(self.summary)
        self.tabs = QtGui.QTabWidget()
        self.table = self._new_table(self.COLUMNS, self.select_tolerance)
        self.parameters = self._new_table(["parameter", "joint", "class", "tolerance", "unit"], self.select_parameter)
        self._values_first(self.table)
        self.tabs.addTab(self.table, "Tolerances")
        self.tabs.addTab(self.parameters, "Defect parameters")
        from .drawings import DATUM_COLUMNS, FRAME_COLUMNS

        sheet = QtGui.QWidget()
        sheet_layout = QtGui.QVBoxLayout(sheet)
        sheet_layout.setContentsMargins(0, 0, 0, 0)
        self.drawings_note = QtGui.QLabel()
        self.drawings_note.setWordWrap(True)
        sheet_layout.addWidget(self.drawings_note)
        self.drawings = self._new_table(FRAME_COLUMNS, self.select_frame)
        self.drawings.setObjectName("HyperstatPartFrames")
        self.datums = self._new_table(DATUM_COLUMNS, self.select_datum)
        self.datums.setObjectName("HyperstatPartDatums")
        sheet_layout.addWidget(self.drawings, 3)
        sheet_layout.addWidget(self.datums, 1)
        self.tabs.addTab(sheet, "Part drawings")
        _fit_dock(self.tabs, 300)
        layout.addWidget(self.tabs, 1)
        self.relations = QtGui.QPlainTextEdit()
        self.relations.setReadOnly(True)
        self.relations.setMaximumHeight(90)
        _fit_dock(self.relations, 0)
        layout.addWidget(self.relations)
        self.legend = QtGui.QLabel()
        self.legend.setWordWrap(True)
        self.legend.setTextFormat(QtCore.Qt.RichText)
        layout.addWidget(self.legend)
        self.rows: list = []
        self.items: list = []
        self.refresh()
        self._observer = _FollowDocument(self)
        FreeCAD.addDocumentObserver(self._observer)

    #: the columns as shown: the value next to the id (whose cell carries the class colour), then the class, the
    #: long texts last (the data keep the report's order, COLUMNS); at FreeCAD's default dock width (about 190 px
    #: of table) the id and the value are in view, and the class by its colour
    SHOWN = ["id", "without calibration", "class", "with calibration", "drawing", "statement", "feature"]

    def _values_first(self, table) -> None:
        header = table.horizontalHeader()
        for visual, name in enumerate(self.SHOWN):
            header.moveSection(header.visualIndex(self.COLUMNS.index(name)), visual)

    @staticmethod
    def _new_table(headers: list[str], on_select):
        from PySide import QtGui

        table = QtGui.QTableWidget(0, len(headers))
        # two-word value heads on two lines ("without / calibration"): at FreeCAD's default dock width the values
        # stay in view next to the id and the class; no row numbers (the id column names the row)
        table.setHorizontalHeaderLabels([h.replace(" ", "\n", 1) if h.endswith("calibration") else h for h in headers])
        table.verticalHeader().setVisible(False)
        table.setEditTriggers(QtGui.QAbstractItemView.NoEditTriggers)
        table.setSelectionBehavior(QtGui.QAbstractItemView.SelectRows)
        table.itemSelectionChanged.connect(on_select)
        return table

    def detach(self) -> None:
        """Stop following the document (the panel closes)."""
        import FreeCAD

        if getattr(self, "_observer", None) is not None:
            FreeCAD.removeDocumentObserver(self._observer)
            self._observer = None

    def _object(self):
        import FreeCAD

        doc = FreeCAD.listDocuments().get(self.doc_name)
        return doc.getObject(self.name) if doc is not None else None

    def refresh(self) -> None:
        """Show what the document holds now (called again after each Undo and Redo)."""
        from .operations import results, tolerances

        try:
            self.form.isVisible()
        except RuntimeError:  # the panel's widgets are gone
            self.detach()
            return
        obj = self._object()
        self.obj = obj
        analysis = results(obj) if obj is not None else None
        tol = tolerances(obj) if obj is not None else None
        self.legend.setText(legend_html(tol))
        if obj is None or analysis is None:
            self.summary.setText("The skeleton is not in the document (undone)." if obj is None else
                                 f"{obj.Label}: not analysed since its last build ({obj.Status}). Run Analyse.")
            self._fill(self.table, [], None)
            self._fill(self.parameters, [], None)
            self._fill(self.drawings, [], None)
            self._fill(self.datums, [], None)
            self.drawings_note.setText("")
            self.rows, self.items = [], []
            self.relations.setPlainText("")
            return
        self.rows = analysis["parameters"]
        entries = (analysis.get("tolerances") or {}).get("parameters") or {}
        tol = tol or analysis.get("tolerances") or {}
        self.items = tol.get("items", [])
        self._fill(self.table, tolerance_rows(tol), 1)
        self._fill(self.parameters, [[p["name"], p["element"], entries.get(p["name"], {}).get("class", "-"),
                                      entries.get(p["name"], {}).get("tolerance_id") or "-", p.get("unit", "")]
                                     for p in self.rows], 2)
        counts = tolerance_counts(tol)
        per_class = ", ".join(f"{n} {c}" for c, n in counts.items())
        self.summary.setText(
            f"<b>{analysis.get('mechanism', obj.Mechanism)}</b>: mobility {analysis.get('mobility')}, "
            f"over-constraint {analysis.get('overconstraint')}; {len(self.items)} tolerances from {len(self.rows)} "
            f"defect parameters: {per_class} (the report's table). Values in mm / rad, rounded down as printed; "
            f"drawing: ISO 1101 frames.")
        rel = relations_of(tol)
        self.relations.setPlainText("Assembly conditions relating several defects:\n" + "\n".join(rel)
                                    if rel else "No relation between defects.")
        self._fill_drawings(obj)

    def _fill_drawings(self, obj) -> None:
        """The Part drawings tab: every frame of every part (as the printed part drawings), the datums."""
        from .drawings import datum_rows, frame_rows
        from .operations import drawings

        sheets = drawings(obj)
        parts = sheets["drawings"]
        self.frame_rows = frame_rows(parts)
        self._fill(self.drawings, self.frame_rows, None)
        self._fill(self.datums, datum_rows(parts), None)
        self.feature_of = {fr["id"]: fr.get("feature") for d in parts for fr in d.get("frames") or []}
        self.datum_feature = [x["feature"] for d in parts for x in d.get("datums") or []]
        reqs = sheets["assembly_requirements"]
        self.drawings_note.setText(
            f"{len(parts)} part drawings, {len(self.frame_rows)} frames (ISO 1101; zones in mm); select frames or "
            "datums to label their features in the 3D view" + (f"; assembly requirements: " + "; ".join(
                f"{r.get('id', '')} {r.get('statement', '')} ({', '.join(r.get('parts') or [])})" for r in reqs)
                                          if reqs else "") + "." if parts else
            "The report of this analysis carries no part drawings.")

    def _select_features(self, features: set) -> None:
        """Show (and select) the 3D labels of ``features``, hide the other part-drawing labels."""
        import FreeCADGui

        from .geometry import show_frame_labels

        if self.obj is None or not features:
            return
        shown = show_frame_labels(self.obj, features)
        FreeCADGui.Selection.clearSelection()
        for label in shown:
            FreeCADGui.Selection.addSelection(label)

    def select_frame(self) -> None:
        """Select the 3D labels of the features of the selected frames."""
        rows = {i.row() for i in self.drawings.selectedItems()}
        self._select_features({self.feature_of.get(self.frame_rows[r][1]) for r in rows
                               if r < len(getattr(self, "frame_rows", []))} - {None})

    def select_datum(self) -> None:
        """Select the 3D labels of the selected datums' features."""
        rows = {i.row() for i in self.datums.selectedItems()}
        self._select_features({self.datum_feature[r] for r in rows if r < len(getattr(self, "datum_feature", []))})

    @staticmethod
    def _fill(table, rows: list[list[str]], class_column: int | None) -> None:
        from PySide import QtGui

        table.clearContents()
        table.setRowCount(len(rows))
        for i, row in enumerate(rows):
            for j, text in enumerate(row):
                item = QtGui.QTableWidgetItem(str(text))
                klass = row[class_column] if class_column is not None else None
                if klass in CLASS_RGB and j in (0, class_column):  # the class cell, and the id cell in its colour
                    item.setBackground(QtGui.QColor.fromRgbF(*CLASS_RGB[klass]))
                    item.setForeground(QtGui.QColor("white"))
                    item.setToolTip(CLASS_LABELS.get(klass, klass))
                if len(str(text)) > 40:  # a long statement: cut in its column, whole in its tooltip
                    item.setToolTip(str(text))
                table.setItem(i, j, item)
        table.resizeColumnsToContents()
        for j in range(table.columnCount()):  # no column wider than a dock: the others stay in view
            table.setColumnWidth(j, min(table.columnWidth(j), 260))

    def _select_elements(self, elements: set) -> None:
        import FreeCADGui

        from .geometry import class_spheres

        if self.obj is None or not elements:
            return
        spheres = class_spheres(self.obj)
        FreeCADGui.Selection.clearSelection()
        for element in sorted(elements):
            if element in spheres:
                FreeCADGui.Selection.addSelection(spheres[element])

    def select_tolerance(self) -> None:
        """Select the class spheres of the joints of the selected tolerances in the 3D view."""
        element_of = {p["name"]: p["element"] for p in self.rows}
        rows = {i.row() for i in self.table.selectedItems()}
        self._select_elements({element_of[n] for r in rows if r < len(self.items)
                               for n in self.items[r].get("parameters", []) if n in element_of})

    def select_parameter(self) -> None:
        """Select the class sphere of the joint of the selected defect parameters."""
        rows = {i.row() for i in self.parameters.selectedItems()}
        self._select_elements({self.rows[r]["element"] for r in rows if r < len(self.rows)})


def _fit_dock(widget, min_height: int) -> None:
    """Let a wide widget shrink to FreeCAD's default dock width (it scrolls instead of widening the panel)."""
    from PySide import QtGui

    widget.setSizePolicy(QtGui.QSizePolicy.Ignored, QtGui.QSizePolicy.Expanding)
    widget.setMinimumWidth(120)
    if min_height:
        widget.setMinimumHeight(min_height)


def legend_html(tolerances: dict | None) -> str:
    """The class colours with their words, as the report and the pictures draw them."""
    meaning = (tolerances or {}).get("classes") or {}
    rows = []
    for c in CLASS_ORDER:
        text = meaning.get(c, "")
        if text.startswith(CLASS_LABELS[c]):  # the JSON's meaning may begin with the class's own words
            text = text[len(CLASS_LABELS[c]):].lstrip(": ")
        rows.append(f"<span style='background:{CLASS_COLORS[c]}'>&nbsp;&nbsp;&nbsp;</span> <b>{CLASS_LABELS[c]}</b>"
                    + (f": {text}" if text else ""))
    return ("Marker colours (a joint takes the most severe class of its defects; each marker is called out with its "
            "joint and tolerance ids, the rows of the table):<br>" + "<br>".join(rows))


class TextPanel(_NonModal):
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


class BarPlot:
    """A small horizontal bar chart drawn with QPainter (no plotting library in FreeCAD's Python)."""

    def __init__(self, title: str, bars: list[tuple[str, float]], unit: str, reference: tuple[str, float] | None = None):
        from PySide import QtGui

        self.bars, self.unit, self.reference = bars, unit, reference
        plot = self

        class _Widget(QtGui.QWidget):
            def paintEvent(self, event):  # noqa: N802 - Qt's name
                plot.paint(self)

        self.widget = _Widget()
        self.widget.setObjectName("HyperstatBarPlot")
        self.widget.setToolTip(title)
        self.widget.setMinimumHeight(18 * len(bars) + 30)
        self.widget.setSizePolicy(QtGui.QSizePolicy.Ignored, QtGui.QSizePolicy.Fixed)
        self.title = title

    def paint(self, widget) -> None:
        from PySide import QtCore, QtGui

        painter = QtGui.QPainter(widget)
        width = widget.width()
        label_w = min(130, int(width * 0.42))
        top = 16
        painter.drawText(2, 12, f"{self.title} [{self.unit}]")
        values = [abs(v) for _, v in self.bars] + ([abs(self.reference[1])] if self.reference else [])
        scale = max(width - label_w - 50, 10) / max(max(values, default=1.0), 1e-300)
        for i, (label, value) in enumerate(self.bars):
            y = top + 18 * i
            text = painter.fontMetrics().elidedText(label, QtCore.Qt.ElideRight, label_w - 6)
            painter.drawText(QtCore.QRect(0, y, label_w - 4, 16), QtCore.Qt.AlignRight | QtCore.Qt.AlignVCenter, text)
            painter.fillRect(label_w, y + 2, max(1, int(abs(value) * scale)), 12, QtGui.QColor(0, 150, 190))
            painter.drawText(label_w + int(abs(value) * scale) + 4, y + 13, f"{value:.3g}")
        if self.reference:
            x = label_w + int(abs(self.reference[1]) * scale)
            painter.setPen(QtGui.QPen(QtGui.QColor(200, 30, 120), 2, QtCore.Qt.DashLine))
            painter.drawLine(x, top, x, top + 18 * len(self.bars))
            painter.drawText(x + 3, top + 18 * len(self.bars) + 12, self.reference[0])
        painter.end()


def _table(headers: list[str], rows: list[list[str]]):
    from PySide import QtGui

    table = QtGui.QTableWidget(len(rows), len(headers))
    table.setHorizontalHeaderLabels(headers)
    table.setEditTriggers(QtGui.QAbstractItemView.NoEditTriggers)
    table.setSelectionBehavior(QtGui.QAbstractItemView.SelectRows)
    for i, row in enumerate(rows):
        for j, text in enumerate(row):
            table.setItem(i, j, QtGui.QTableWidgetItem(str(text)))
    table.resizeColumnsToContents()
    _fit_dock(table, 200)
    return table


class _ReportPanel(_NonModal):
    """Summary, table and plot of a command's JSON; the printed report is one click away."""

    def _build(self, title: str, icon: str, summary: str, table, plot, text: str) -> None:
        from PySide import QtGui

        self.form = QtGui.QWidget()
        self.form.setWindowTitle(title)
        self.form.setWindowIcon(QtGui.QIcon(icon_path(icon)))
        layout = QtGui.QVBoxLayout(self.form)
        self.summary = QtGui.QLabel(summary)
        self.summary.setWordWrap(True)
        layout.addWidget(self.summary)
        self.table = table
        layout.addWidget(table, 1)
        self.plot = plot
        if plot is not None:
            layout.addWidget(plot.widget)
        self.text = QtGui.QPlainTextEdit()
        self.text.setReadOnly(True)
        self.text.setFont(QtGui.QFont("Monospace"))
        self.text.setPlainText(text)
        self.text.hide()
        _fit_dock(self.text, 0)
        toggle = QtGui.QPushButton("Show the printed report")
        toggle.setCheckable(True)
        toggle.toggled.connect(self.text.setVisible)
        layout.addWidget(toggle)
        layout.addWidget(self.text)


def _um(value) -> str:
    return "" if value is None else f"{1000.0 * float(value):.1f}"


class IdentificationPanel(_ReportPanel):
    """``hyperstat identify``: residuals (identification, validation), one row per identified parameter."""

    def __init__(self, obj):
        import json

        data = json.loads(obj.Identification)
        ident, val = data.get("identification") or {}, data.get("validation") or {}
        summary = (f"<b>{obj.Label}</b>: {len(data.get('parameters', []))} parameters identified, rank "
                   f"{data.get('rank')} of {data.get('unknowns')} unknowns, condition number "
                   f"{data.get('condition_number') or 0:.3g}.<br>Residual RMS (\u00b5m): identification "
                   f"{_um(ident.get('rms'))} ({ident.get('n')} points), validation {_um(val.get('rms'))} "
                   f"({val.get('n', 0)} points, never fitted). Estimates in mm / rad, with 1-sigma.")
        rows = [[p["name"], f"{p.get('estimate', 0):.4g}", f"{p.get('std') or 0:.2g}", p.get("unit", ""),
                 "yes" if p.get("identifiable", True) else "no"] for p in data.get("parameters", [])]
        table = _table(["parameter", "estimate", "1-sigma", "unit", "identifiable"], rows)
        plot = BarPlot("residual RMS", [("identification", 1000.0 * float(ident.get("rms") or 0)),
                                        ("validation", 1000.0 * float(val.get("rms") or 0))], "\u00b5m")
        self._build("Identification", "identify", summary, table, plot, obj.IdentificationText)


class DiagnosisPanel(_ReportPanel):
    """``hyperstat diagnose``: is there a gap, which unmodelled effect (ranked), how far it shrinks."""

    def __init__(self, obj):
        import json

        data = json.loads(obj.Diagnosis)
        test = data.get("gap_test") or {}
        p_val = (test.get("validation") or {}).get("p_value")
        before = data.get("validation_before") or {}
        selected = ", ".join(str(s.get("effect", s)) if isinstance(s, dict) else str(s)
                             for s in data.get("selected") or []) or "none"
        gap = "a significant gap" if data.get("gap_significant") else "no significant gap (residuals at noise level)"
        summary = (f"<b>{obj.Label}</b>: {gap}; validation p = {p_val if p_val is None else f'{p_val:.2g}'}; "
                   f"validation RMS before {_um(before.get('rms'))} \u00b5m; selected effect: {selected}. "
                   "Effects ranked by blocked cross-validation (CV RMS in \u00b5m, lower is better).")
        ranking = data.get("ranking") or []
        rows = [[r.get("effect", ""), r.get("defect") or "", _um(r.get("cv_rms")),
                 f"{r.get('criterion', 0):.3g}", r.get("criterion_name", "")] for r in ranking]
        for name, why in (data.get("not_applicable") or {}).items():
            rows.append([name, "", "", "", f"not tried: {why}"])
        table = _table(["effect", "defect", "CV RMS (\u00b5m)", "criterion", "criterion name"], rows)
        ceiling = data.get("ceiling") or {}
        plot = BarPlot("CV RMS per effect", [(r.get("effect", ""), 1000.0 * float(r.get("cv_rms") or 0))
                                             for r in ranking], "\u00b5m",
                       ("rigid", 1000.0 * float(ceiling["cv_rms_rigid"])) if ceiling.get("cv_rms_rigid") else None)
        self._build("Diagnosis", "diagnose", summary, table, plot, obj.DiagnosisText)


def open_identification(obj) -> None:
    """Show the last identification of a skeleton (table and plot)."""
    try:
        show_panel(IdentificationPanel(obj))
    except Exception as exc:  # noqa: BLE001
        show_error("Identification", exc)


def open_diagnosis(obj) -> None:
    """Show the last diagnosis of a skeleton (table and plot)."""
    try:
        show_panel(DiagnosisPanel(obj))
    except Exception as exc:  # noqa: BLE001
        show_error("Diagnosis", exc)
