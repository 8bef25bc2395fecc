"""What the commands do, usable from scripts and ``freecadcmd`` (no GUI needed).

Units: lengths in mm, angles in rad (template units); FreeCAD shows angles in degrees.

Every function takes a skeleton object (or a document) and runs the ``hyperstat``
command line on files in the document's transient folder (:func:`work_dir`); the
results are stored in the object's properties, so a saved document keeps them.
Failures raise :class:`~.runner.HyperstatWorkbenchError` with one sentence that the
GUI shows as a message and a script can print.

Each user action is written once, as a generator of *steps* (``insert_steps``,
``rebuild_steps``, ``analyze_steps``...): it yields a :class:`Call` for every run of the
command line, receives its :class:`~.runner.CliResult`, and touches the document only
after the last run, inside one undo transaction (``openTransaction`` /
``commitTransaction``; aborted on an error, so a failed action leaves nothing behind).
:func:`drive` runs the steps synchronously (scripts, ``freecadcmd``); the GUI runs the
same steps with :class:`~.jobs.Job`, one ``QProcess`` per call, so FreeCAD never freezes.

Example (``freecadcmd``)::

    import FreeCAD, hyperstat_freecad as hs
    doc = FreeCAD.newDocument("study")
    sk = hs.insert_skeleton(doc, "tripteor_x7", {"depth": 900.0})
    result = hs.analyze(sk)
    doc.saveAs("/tmp/study.FCStd")
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from . import geometry
from .feature import SkeletonFeature, is_skeleton
from .parameters import (add_parameter_properties, bind_spreadsheet, cli_overrides, current_parameters, expression_of,
                         parameter_specs, set_parameter)
from .runner import CliResult, HyperstatWorkbenchError, list_templates, run_cli, run_together, templates_dir
from .classes import parameter_classes, tolerance_counts

__all__ = [
    "Call",
    "Together",
    "drive",
    "transaction",
    "resolve_template",
    "describe_template",
    "work_dir",
    "insert_steps",
    "insert_skeleton",
    "set_parameters",
    "needs_rebuild",
    "rebuild_steps",
    "rebuild",
    "edit_steps",
    "analyze_steps",
    "analyze",
    "results",
    "tolerances",
    "identify_steps",
    "identify",
    "diagnose_steps",
    "diagnose",
    "report_steps",
    "export_report",
    "controller_steps",
    "export_controller",
    "skeletons",
]


@dataclass
class Call:
    """One run of the command line requested by a step generator: ``hyperstat ARGUMENTS``.

    ``subject`` (a template's name) keys the time estimate of the run (:mod:`.estimates`).
    """

    arguments: list[str]
    label: str
    subject: str = ""


@dataclass
class Together:
    """Runs of the command line that do not depend on each other, requested by a step generator at once: they are
    started together (one process each, on as many cores) and the generator receives their results as a tuple, in
    order, once all have ended; the first failure in that order is thrown into it."""

    calls: tuple

    @property
    def label(self) -> str:
        return " and ".join(c.label for c in self.calls)


def drive(steps):
    """Run a step generator synchronously (each :class:`Call` with :func:`~.runner.run_cli`); return its value.

    A failed call is thrown into the generator (which may record it, e.g. in ``Status``) and re-raised.
    """
    try:
        call = next(steps)
        while True:
            try:
                result = run_together([c.arguments for c in call.calls]) if isinstance(call, Together) else \
                    run_cli(call.arguments)
            except Exception as exc:  # noqa: BLE001 - handed to the generator, which re-raises
                call = steps.throw(exc)
            else:
                call = steps.send(result)
    except StopIteration as stop:
        return stop.value


@contextmanager
def transaction(doc, name: str):
    """One undo step for everything done in the block; aborted (rolled back) if the block raises."""
    doc.openTransaction(name)
    try:
        yield
    except BaseException:
        doc.abortTransaction()
        raise
    doc.commitTransaction()


def skeletons(doc) -> list:
    """Skeleton objects of a document."""
    return [o for o in doc.Objects if is_skeleton(o)]


def resolve_template(template: str | os.PathLike) -> Path:
    """A template file from a path, or from a shipped template's name (``"tripteor_x7"``).

    Raises
    ------
    HyperstatWorkbenchError
        If no such file exists.
    """
    path = Path(template).expanduser()
    if path.is_file():
        return path.resolve()
    folder = templates_dir()
    if folder is not None and path.suffix == "":
        for sub in (folder, folder / "corpus"):  # a shipped template, or a corpus one
            if (sub / f"{path.name}.py").is_file():
                return (sub / f"{path.name}.py").resolve()
    known = ", ".join(p.stem for p in list_templates()) or "none found (run 'make freecad-install')"
    raise HyperstatWorkbenchError(f"template '{template}' not found: give a .py file or a shipped template ({known}).")


def describe_template(path: Path) -> dict:
    """``hyperstat parameters TEMPLATE --json``: name, default, unit, meaning and bounds of each parameter."""
    with tempfile.TemporaryDirectory(prefix="hyperstat-fc-") as tmp:
        out = Path(tmp) / "parameters.json"
        run_cli(["parameters", str(path), "--json", str(out), "--quiet"])
        return json.loads(out.read_text(encoding="utf-8"))


def work_dir(obj) -> Path:
    """Folder of the object's files (STEP, sidecar, model, JSON): in the document's transient folder.

    The files are caches: everything they hold is also stored in the object's properties.
    """
    folder = Path(obj.Document.TransientDir) / "hyperstat" / obj.Name
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _write_atomic(path: Path, text: str) -> Path:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write(text)
    os.replace(tmp, path)
    return path


def _stage(folder: Path) -> Path:
    """A fresh folder for one action's files (a failed action leaves the previous files untouched)."""
    folder.mkdir(parents=True, exist_ok=True)
    return Path(tempfile.mkdtemp(prefix=".run-", dir=folder))


def _document_dir(doc) -> Path:
    return Path(doc.TransientDir) / "hyperstat"


def _model_file(obj) -> Path:
    """The model file of the last build, rewritten from the object if the cache is gone (rebuilds if outdated)."""
    if needs_rebuild(obj):
        rebuild(obj)
    return _cached_model(obj)


def _cached_model(obj) -> Path:
    path = work_dir(obj) / "skeleton.skel.json"
    if not path.is_file() or path.read_text(encoding="utf-8") != obj.ModelJson:
        _write_atomic(path, obj.ModelJson)
    return path


def _build_call(template: str, values: dict[str, float], folder: Path, name: str) -> Call:
    return Call(["build", template, *cli_overrides(values), "--step", str(folder / "skeleton.step"),
                 "--model", str(folder / "skeleton.skel.json")], f"building {name} (hyperstat build)", name)


def _analysis_calls(model: Path, folder: Path, configurations: int, seed: int, name: str):
    """Steps of an analysis: the classes (``hyperstat analyze``) and the tolerance values of the report
    (``hyperstat report``, the same command as *Export the tolerance report*), run together (neither reads the
    other's file: the classes take the time of the values, on the second core); returns both JSON texts."""
    sample = ["--configurations", str(configurations), "--seed", str(seed)]
    yield Together((Call(["analyze", str(model), "--json", str(folder / "analysis.json"), *sample, "--quiet"],
                         "tolerance classes (hyperstat analyze)", name),
                    Call(["report", str(model), "--out", str(folder / "report"), *sample, "--json-only", "--quiet"],
                         "tolerance values (hyperstat report)", name)))
    return ((folder / "analysis.json").read_text(encoding="utf-8"),
            (folder / "report" / "report.json").read_text(encoding="utf-8"))


def _same(a: dict[str, float], b: dict[str, float]) -> bool:
    return set(a) == set(b) and all(math.isclose(a[k], b[k], rel_tol=1e-12, abs_tol=1e-12) for k in a)


def _read_build(obj, folder: Path):
    """The new geometry of a build, read before the transaction (:func:`~.geometry.read_step`); None for a first
    build."""
    if obj is None or geometry.geometry_root(obj) is None:
        return None
    sidecar = json.loads((folder / "skeleton.step.json").read_text(encoding="utf-8"))
    return geometry.read_step(folder / "skeleton.step", set(sidecar["nodes"]))


def _apply_build(obj, folder: Path, values: dict[str, float], res: CliResult, new=None) -> None:
    """Bring the skeleton's geometry to the STEP file of a build in ``folder`` (inside a transaction): in place when
    the skeleton keeps the same markers and links (``new`` from :func:`_read_build`), else a new import."""
    doc = obj.Document
    sidecar = json.loads((folder / "skeleton.step.json").read_text(encoding="utf-8"))
    old = geometry.geometry_root(obj)
    _clear_results(obj)
    if old is None or not geometry.update_in_place(old, new):
        root = geometry.import_step(doc, folder / "skeleton.step", set(sidecar["nodes"]))
        if old is not None:
            geometry.remove_tree(doc, old)
        obj.addObject(root)
        root.Label = f"{obj.Label} geometry"
    obj.ModelJson = (folder / "skeleton.skel.json").read_text(encoding="utf-8")
    obj.MarkerSize = float(sidecar.get("marker_size", 1.0))
    obj.Mechanism = str(sidecar.get("name", ""))
    obj.Summary = res.stdout.splitlines()[0] if res.stdout.strip() else ""
    # the values as the properties give them back (degrees <-> rad), so that a recompute sees no change
    read = current_parameters(obj)
    obj.BuiltParameters = json.dumps(read if _same(read, values) else values, sort_keys=True)
    obj.Status = "built; not analysed"


def _apply_analysis(obj, texts: tuple[str, str]) -> dict:
    """Store the analysis and the report's tolerances (with their values), colour and call out the markers."""
    text, report = texts
    analysis = json.loads(text)
    doc = json.loads(report)
    tolerances = doc["tolerances"]
    obj.Analysis = text
    obj.Tolerances = json.dumps(tolerances, sort_keys=True)
    obj.Drawings = json.dumps({"drawings": doc.get("drawings") or [],
                               "assembly_requirements": doc.get("assembly_requirements") or []}, sort_keys=True)
    obj.Mobility = int(analysis.get("mobility") or 0)
    obj.Overconstraint = int(analysis.get("overconstraint") or 0)
    obj.Rank = int(analysis.get("rank") or 0)
    obj.ToleranceCounts = {k: str(v) for k, v in tolerance_counts(tolerances).items()}
    obj.ParameterClasses = parameter_classes(analysis)
    geometry.color_markers(obj, analysis)
    geometry.label_frames(obj, drawings(obj)["drawings"])
    obj.Status = "analysed"
    # what the report's page 1 carries: a calibration hyperstat's own commands do not run, zones no workshop holds
    for w in tolerances.get("warnings") or []:
        if w.startswith(("CALIBRATION CAMPAIGN: ", "PRACTICAL SIZE: ")):
            import FreeCAD

            FreeCAD.Console.PrintWarning(f"Hyperstat - {obj.Label}: {w}\n")
    return analysis


def _remove_created(doc, names: list[str]) -> None:
    for n in reversed(names):
        o = doc.getObject(n)
        if o is not None:
            root = geometry.geometry_root(o) if is_skeleton(o) else None
            if root is not None:
                geometry.remove_tree(doc, root)
            doc.removeObject(n)


def insert_steps(doc, template: str | os.PathLike, parameters: dict[str, float] | None = None,
                 name: str = "Skeleton", spreadsheet: bool = True, analyse: bool = False):
    """Steps of :func:`insert_skeleton` (``analyse``: also analyse, in the same undo transaction)."""
    import FreeCAD

    path = resolve_template(template)
    stage = _stage(_document_dir(doc))
    try:
        out = stage / "parameters.json"
        yield Call(["parameters", str(path), "--json", str(out), "--quiet"],
                   f"reading the parameters of {path.stem} (hyperstat parameters)", path.stem)
        specs = json.loads(out.read_text(encoding="utf-8"))["parameters"]
        known = {s["name"]: s for s in specs}
        unknown = sorted(set(parameters or {}) - set(known))
        if unknown:
            valid = ", ".join(f"{n} [{s['unit']}]" for n, s in known.items())
            raise HyperstatWorkbenchError(f"{path.name}: unknown parameter '{unknown[0]}'; valid parameters: {valid}.")
        values = {n: float(s["default"]) for n, s in known.items()}
        values.update({k: float(v) for k, v in (parameters or {}).items()})
        res = yield _build_call(str(path), values, stage, path.stem)
        text = None
        if analyse:
            text = yield from _analysis_calls(stage / "skeleton.skel.json", stage, 24, 0, path.stem)
        created: list[str] = []
        try:
            with transaction(doc, f"Insert skeleton {path.stem}"):
                obj = doc.addObject("App::DocumentObjectGroupPython", name)
                created.append(obj.Name)
                SkeletonFeature(obj)
                if FreeCAD.GuiUp:
                    from .viewprovider import ViewProviderSkeleton

                    ViewProviderSkeleton(obj.ViewObject)
                obj.Label = path.stem
                obj.Template = str(path)
                obj.ParameterSpecs = json.dumps(specs)
                add_parameter_properties(obj, specs)
                for key, value in (parameters or {}).items():
                    set_parameter(obj, known[key], value)
                if spreadsheet:
                    created.append(bind_spreadsheet(obj, specs).Name)
                doc.recompute()
                _apply_build(obj, stage, values, res)
                if text is not None:
                    _apply_analysis(obj, text)
                doc.recompute()
        except BaseException:
            _remove_created(doc, created)  # when undo is off, the aborted transaction removed nothing
            raise
        shutil.copy(stage / "skeleton.skel.json", work_dir(obj) / "skeleton.skel.json")
        return obj
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def insert_skeleton(doc, template: str | os.PathLike, parameters: dict[str, float] | None = None,
                    name: str = "Skeleton", spreadsheet: bool = True, analyse: bool = False):
    """Insert a skeleton built from a template, its parameters as properties (and a spreadsheet).

    Parameters
    ----------
    doc : FreeCAD document
    template : str or path
        A template file, or the name of a shipped template (``"tripteor_x7"``).
    parameters : dict, optional
        Values overriding the template's defaults, in the template's units (mm, rad).
    name : str
        Internal name of the new object.
    spreadsheet : bool
        Also create a spreadsheet whose aliases drive the parameters.
    analyse : bool
        Also analyse (one undo step for both).

    Returns
    -------
    The new ``App::DocumentObjectGroupPython`` object, built (STEP imported).

    Raises
    ------
    HyperstatWorkbenchError
        On an unknown template or parameter, or a build that fails; nothing is left
        in the document then.
    """
    return drive(insert_steps(doc, template, parameters, name, spreadsheet, analyse))


def _write_parameters(obj, values: dict[str, float]) -> None:
    specs = {s["name"]: s for s in parameter_specs(obj)}
    for key, value in values.items():
        if key not in specs:
            raise HyperstatWorkbenchError(f"{obj.Label}: unknown parameter '{key}'; valid: {', '.join(specs)}.")
        expr = expression_of(obj, key)
        sheet = obj.Spreadsheet
        if expr and sheet is not None and expr.startswith(f"{sheet.Name}."):
            cell = sheet.getCellFromAlias(expr.split(".", 1)[1])
            unit = specs[key].get("unit")
            sheet.set(cell, f"={float(value)!r} {unit}" if unit in ("mm", "rad") else repr(float(value)))
        else:
            set_parameter(obj, specs[key], value)
    obj.Document.recompute()


def set_parameters(obj, values: dict[str, float]):
    """Set parameters (template units: mm, rad); a spreadsheet-bound one is set in its cell.

    Returns the object; call :func:`rebuild` or :func:`analyze` to use the new values.

    Raises
    ------
    HyperstatWorkbenchError
        On an unknown parameter name.
    """
    with transaction(obj.Document, "Set parameters"):
        _write_parameters(obj, values)
    return obj


def needs_rebuild(obj) -> bool:
    """True when the object was never built, or its parameters changed since the last build."""
    if not obj.ModelJson or not obj.BuiltParameters or geometry.geometry_root(obj) is None:
        return True
    obj.Document.recompute()  # evaluate spreadsheet expressions
    return current_parameters(obj) != json.loads(obj.BuiltParameters)


def _clear_results(obj) -> None:
    geometry.clear_classes(obj)
    geometry.clear_frame_labels(obj)
    obj.Analysis = obj.Tolerances = ""
    if hasattr(obj, "Drawings"):
        obj.Drawings = ""
    obj.Mobility = obj.Overconstraint = obj.Rank = 0
    obj.ToleranceCounts = {}
    obj.ParameterClasses = {}


def rebuild_steps(obj, values: dict[str, float] | None = None, analyse: bool = False, title: str = "Rebuild"):
    """Steps of a rebuild; with ``values`` (template units) an *Edit parameters*: they are written only if the
    build succeeds, in the same undo transaction as the new geometry (and the analysis with ``analyse``)."""
    doc = obj.Document
    doc.recompute()
    full = current_parameters(obj)
    if values:
        unknown = sorted(set(values) - set(full))
        if unknown:
            raise HyperstatWorkbenchError(f"{obj.Label}: unknown parameter '{unknown[0]}'; valid: {', '.join(full)}.")
        full.update({k: float(v) for k, v in values.items()})
    stage = _stage(work_dir(obj))
    try:
        try:
            res = yield _build_call(obj.Template, full, stage, obj.Label)
            text = None
            if analyse:
                text = yield from _analysis_calls(stage / "skeleton.skel.json", stage, obj.Configurations, obj.Seed,
                                                  obj.Label)
        except HyperstatWorkbenchError as exc:
            if not values:  # the document's own parameters failed; refused new values are simply not written
                obj.Status = f"error: {exc}"
            raise
        new = _read_build(obj, stage)
        with transaction(doc, f"{title} {obj.Label}"):
            if values:
                _write_parameters(obj, values)
            _apply_build(obj, stage, full, res, new)
            if text is not None:
                _apply_analysis(obj, text)
            doc.recompute()
        shutil.copy(stage / "skeleton.skel.json", work_dir(obj) / "skeleton.skel.json")
        return obj
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def edit_steps(obj, values: dict[str, float], analyse: bool = True):
    """Steps of *Edit parameters*: build with ``values`` (mm, rad), then write them, rebuild and analyse (one undo)."""
    return rebuild_steps(obj, values, analyse, "Edit parameters of")


def rebuild(obj):
    """``hyperstat build`` with the object's parameters; re-import the STEP file; clear old results.

    Raises
    ------
    HyperstatWorkbenchError
        If the build fails (a parameter out of bounds, an assembly that does not close...):
        the object keeps its previous geometry and shows the error in ``Status``.
    """
    return drive(rebuild_steps(obj))


def analyze_steps(obj, configurations: int | None = None, seed: int | None = None):
    """Steps of :func:`analyze`: rebuild first if outdated, analyse, store and colour (one undo transaction)."""
    if needs_rebuild(obj):
        obj = yield from rebuild_steps(obj, analyse=False)
    configurations = int(obj.Configurations if configurations is None else configurations)
    seed = int(obj.Seed if seed is None else seed)
    model = _cached_model(obj)
    stage = _stage(work_dir(obj))
    try:
        try:
            text = yield from _analysis_calls(model, stage, configurations, seed, obj.Label)
        except HyperstatWorkbenchError as exc:
            obj.Status = f"error: {exc}"
            raise
        with transaction(obj.Document, f"Analyse {obj.Label}"):
            if (obj.Configurations, obj.Seed) != (configurations, seed):
                obj.Configurations, obj.Seed = configurations, seed
            analysis = _apply_analysis(obj, text)
            obj.Document.recompute()
        shutil.copy(stage / "analysis.json", work_dir(obj) / "analysis.json")
        return analysis
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def analyze(obj, configurations: int | None = None, seed: int | None = None) -> dict:
    """``hyperstat analyze`` and ``hyperstat report``: store the tolerance classes and values, colour and call out
    the markers (rebuilds first if outdated).

    Returns
    -------
    dict
        The analysis JSON (units mm, rad): ``parameters`` with each verdict, ``relations``,
        ``mobility``, ``overconstraint``, ``rank``...
    """
    return drive(analyze_steps(obj, configurations, seed))


def results(obj) -> dict | None:
    """The last analysis stored in the object (``None`` if it was not analysed since its last build)."""
    return json.loads(obj.Analysis) if obj.Analysis else None


def tolerances(obj) -> dict | None:
    """The tolerances of the last analysis with their values, as the report gives them (``None`` if none)."""
    return json.loads(obj.Tolerances) if getattr(obj, "Tolerances", "") else None


def drawings(obj) -> dict:
    """The part drawings of the last analysis's report: ``{"drawings": [...], "assembly_requirements": [...]}``
    (empty lists when it has none, or before an analysis)."""
    text = getattr(obj, "Drawings", "")
    return json.loads(text) if text else {"drawings": [], "assembly_requirements": []}


def _measurements(obj, data, validation) -> list[str]:
    if data is None:
        data, validation = obj.MeasurementFile, obj.ValidationFile
    data, validation = str(data or ""), str(validation or "")
    if not data:
        raise HyperstatWorkbenchError(f"{obj.Label}: no measurement file: load measurements first (a CSV file).")
    for label, value in (("measurement file", data), ("validation file", validation)):
        if value and not Path(value).is_file():
            raise HyperstatWorkbenchError(f"{obj.Label}: the {label} '{value}' does not exist.")
    args = [data]
    if validation:
        args += ["--validation", validation]
    return args


def _sample_args(obj) -> list[str]:
    return ["--configurations", str(obj.Configurations), "--seed", str(obj.Seed)]


def _model_steps(obj):
    if needs_rebuild(obj):
        yield from rebuild_steps(obj)
    return _cached_model(obj)


def identify_steps(obj, data: str | os.PathLike | None = None, validation: str | os.PathLike | None = None):
    """Steps of :func:`identify` (stores the results without marking the skeleton for recompute)."""
    meas = _measurements(obj, data, validation)
    model = yield from _model_steps(obj)
    out = work_dir(obj) / "identification.json"
    res = yield Call(["identify", str(model), *meas, "--json", str(out), *_sample_args(obj)],
                     "identification (hyperstat identify)", obj.Label)
    text = out.read_text(encoding="utf-8")
    with transaction(obj.Document, f"Identify {obj.Label}"):
        obj.MeasurementFile, obj.ValidationFile = meas[0], (meas[2] if len(meas) > 2 else "")
        obj.Identification = text
        obj.IdentificationText = res.stdout
    return json.loads(text)


def identify(obj, data: str | os.PathLike | None = None, validation: str | os.PathLike | None = None) -> dict:
    """``hyperstat identify``: fit the free influential defects to measurements (CSV files).

    Returns the identification JSON, also stored in ``Identification``; the printed
    summary goes to ``IdentificationText``.
    """
    return drive(identify_steps(obj, data, validation))


def diagnose_steps(obj, data: str | os.PathLike | None = None, validation: str | os.PathLike | None = None):
    """Steps of :func:`diagnose`."""
    meas = _measurements(obj, data, validation)
    model = yield from _model_steps(obj)
    out = work_dir(obj) / "diagnosis.json"
    res = yield Call(["diagnose", str(model), *meas, "--json", str(out)], "diagnosis (hyperstat diagnose)", obj.Label)
    text = out.read_text(encoding="utf-8")
    with transaction(obj.Document, f"Diagnose {obj.Label}"):
        obj.MeasurementFile, obj.ValidationFile = meas[0], (meas[2] if len(meas) > 2 else "")
        obj.Diagnosis = text
        obj.DiagnosisText = res.stdout
    return json.loads(text)


def diagnose(obj, data: str | os.PathLike | None = None, validation: str | os.PathLike | None = None) -> dict:
    """``hyperstat diagnose``: where the rigid model misses, which unmodelled effect, how far it shrinks.

    Raises
    ------
    CommandMissing
        If the installed hyperstat has no ``diagnose`` command.
    """
    return drive(diagnose_steps(obj, data, validation))


def _data_options(obj) -> list[str]:
    out = []
    if obj.MeasurementFile:
        out += ["--data", obj.MeasurementFile]
    if obj.ValidationFile:
        out += ["--validation", obj.ValidationFile]
    return out


def report_steps(obj, out_dir: str | os.PathLike):
    """Steps of :func:`export_report`."""
    model = yield from _model_steps(obj)
    yield Call(["report", str(model), *_data_options(obj), "--out", str(out_dir)], "tolerance report (hyperstat report)",
               obj.Label)
    with transaction(obj.Document, f"Report of {obj.Label}"):
        obj.ReportDir = str(out_dir)
    return Path(out_dir)


def export_report(obj, out_dir: str | os.PathLike) -> Path:
    """``hyperstat report``: the tolerance report (HTML, Markdown, JSON) in ``out_dir``.

    Measurements loaded in the object are passed with ``--data`` / ``--validation``.
    """
    return drive(report_steps(obj, out_dir))


def controller_steps(obj, out_file: str | os.PathLike):
    """Steps of :func:`export_controller`."""
    if not obj.MeasurementFile:
        raise HyperstatWorkbenchError("Load measurements first: the controller file holds the identified parameters.")
    model = yield from _model_steps(obj)
    extra = ["--validation", obj.ValidationFile] if obj.ValidationFile else []
    yield Call(["export-controller", str(model), obj.MeasurementFile, *extra, "--diagnose", "--out", str(out_file)],
               "controller file (hyperstat export-controller)", obj.Label)
    with transaction(obj.Document, f"Controller file of {obj.Label}"):
        obj.ControllerFile = str(out_file)
    return Path(out_file)


def export_controller(obj, out_file: str | os.PathLike) -> Path:
    """``hyperstat export-controller``: the controller parameter file (JSON), from the loaded measurements."""
    return drive(controller_steps(obj, out_file))
