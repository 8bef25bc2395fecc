"""What the commands do, usable from scripts and ``freecadcmd`` (no GUI needed).

Units: lengths in mm, angles in rad (template units); FreeCAD shows angles in degrees.

Every function takes a skeleton object (or a document) and runs the ``hyperstat``
command line on files in the document's transient folder (:func:`work_dir`); the
results are stored in the object's properties, so a saved document keeps them.
Failures raise :class:`~.runner.HyperstatWorkbenchError` with one sentence that the
GUI shows as a message and a script can print.

Example (``freecadcmd``)::

    import FreeCAD, hyperstat_freecad as hs
    doc = FreeCAD.newDocument("study")
    sk = hs.insert_skeleton(doc, "tripteor_x7", {"depth": 900.0})
    result = hs.analyze(sk)
    doc.saveAs("/tmp/study.FCStd")
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

from . import geometry
from .feature import SkeletonFeature, is_skeleton, parameter_specs
from .parameters import add_parameter_properties, bind_spreadsheet, cli_overrides, current_parameters, set_parameter
from .runner import HyperstatWorkbenchError, list_templates, run_cli, templates_dir
from .verdicts import parameter_class, verdict_counts

__all__ = [
    "resolve_template",
    "describe_template",
    "work_dir",
    "insert_skeleton",
    "set_parameters",
    "needs_rebuild",
    "rebuild",
    "analyze",
    "results",
    "identify",
    "diagnose",
    "export_report",
    "export_controller",
    "skeletons",
]


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
    if folder is not None and path.suffix == "" and (folder / f"{path.name}.py").is_file():
        return (folder / f"{path.name}.py").resolve()
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


def _model_file(obj) -> Path:
    """The model file of the last build, rewritten from the object if the cache is gone."""
    if needs_rebuild(obj):
        rebuild(obj)
    path = work_dir(obj) / "skeleton.skel.json"
    if not path.is_file() or path.read_text(encoding="utf-8") != obj.ModelJson:
        _write_atomic(path, obj.ModelJson)
    return path


def insert_skeleton(doc, template: str | os.PathLike, parameters: dict[str, float] | None = None,
                    name: str = "Skeleton", spreadsheet: bool = True):
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

    Returns
    -------
    The new ``App::DocumentObjectGroupPython`` object, built (STEP imported).

    Raises
    ------
    HyperstatWorkbenchError
        On an unknown template or parameter, or a build that fails; nothing is left
        in the document then.
    """
    import FreeCAD

    path = resolve_template(template)
    info = describe_template(path)
    specs = info["parameters"]
    known = {s["name"]: s for s in specs}
    unknown = sorted(set(parameters or {}) - set(known))
    if unknown:
        valid = ", ".join(f"{n} [{s['unit']}]" for n, s in known.items())
        raise HyperstatWorkbenchError(f"{path.name}: unknown parameter '{unknown[0]}'; valid parameters: {valid}.")
    obj = doc.addObject("App::DocumentObjectGroupPython", name)
    created = [obj.Name]
    try:
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
        rebuild(obj)
    except BaseException:
        for n in reversed(created):
            o = doc.getObject(n)
            if o is not None:
                root = geometry.geometry_root(o) if is_skeleton(o) else None
                if root is not None:
                    geometry.remove_tree(doc, root)
                doc.removeObject(n)
        raise
    return obj


def set_parameters(obj, values: dict[str, float]):
    """Set parameters (template units: mm, rad); a spreadsheet-bound one is set in its cell.

    Returns the object; call :func:`rebuild` or :func:`analyze` to use the new values.

    Raises
    ------
    HyperstatWorkbenchError
        On an unknown parameter name.
    """
    from .parameters import expression_of

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
    return obj


def needs_rebuild(obj) -> bool:
    """True when the object was never built, or its parameters changed since the last build."""
    if not obj.ModelJson or not obj.BuiltParameters or geometry.geometry_root(obj) is None:
        return True
    obj.Document.recompute()  # evaluate spreadsheet expressions
    return current_parameters(obj) != json.loads(obj.BuiltParameters)


def _clear_results(obj) -> None:
    geometry.clear_verdicts(obj)
    obj.Analysis = ""
    obj.Mobility = obj.Overconstraint = obj.Rank = 0
    obj.VerdictCounts = {}
    obj.ParameterVerdicts = {}


def rebuild(obj):
    """``hyperstat build`` with the object's parameters; re-import the STEP file; clear old results.

    Raises
    ------
    HyperstatWorkbenchError
        If the build fails (a parameter out of bounds, an assembly that does not close...):
        the object keeps its previous geometry and shows the error in ``Status``.
    """
    doc = obj.Document
    doc.recompute()
    values = current_parameters(obj)
    folder = work_dir(obj)
    step, model = folder / "skeleton.step", folder / "skeleton.skel.json"
    try:
        res = run_cli(["build", obj.Template, *cli_overrides(values), "--step", str(step), "--model", str(model)])
        sidecar = json.loads((folder / "skeleton.step.json").read_text(encoding="utf-8"))
        root = geometry.import_step(doc, step, set(sidecar["nodes"]))
    except HyperstatWorkbenchError as exc:
        obj.Status = f"error: {exc}"
        raise
    old = geometry.geometry_root(obj)
    if old is not None:
        geometry.remove_tree(doc, old)
    obj.addObject(root)
    root.Label = f"{obj.Label} geometry"
    obj.ModelJson = model.read_text(encoding="utf-8")
    obj.MarkerSize = float(sidecar.get("marker_size", 1.0))
    obj.Mechanism = str(sidecar.get("name", ""))
    obj.Summary = res.stdout.splitlines()[0] if res.stdout.strip() else ""
    obj.BuiltParameters = json.dumps(values, sort_keys=True)
    _clear_results(obj)
    obj.Status = "built; not analysed"
    doc.recompute()
    return obj


def analyze(obj, configurations: int | None = None, seed: int | None = None) -> dict:
    """``hyperstat analyze``: store the verdicts and colour the markers (rebuilds first if outdated).

    Returns
    -------
    dict
        The analysis JSON (units mm, rad): ``parameters`` with each verdict, ``relations``,
        ``mobility``, ``overconstraint``, ``rank``...
    """
    if configurations is not None:
        obj.Configurations = int(configurations)
    if seed is not None:
        obj.Seed = int(seed)
    model = _model_file(obj)
    out = work_dir(obj) / "analysis.json"
    try:
        run_cli(["analyze", str(model), "--json", str(out), "--configurations", str(obj.Configurations),
                 "--seed", str(obj.Seed), "--quiet"])
    except HyperstatWorkbenchError as exc:
        obj.Status = f"error: {exc}"
        raise
    text = out.read_text(encoding="utf-8")
    analysis = json.loads(text)
    obj.Analysis = text
    obj.Mobility = int(analysis.get("mobility") or 0)
    obj.Overconstraint = int(analysis.get("overconstraint") or 0)
    obj.Rank = int(analysis.get("rank") or 0)
    obj.VerdictCounts = {k: str(v) for k, v in verdict_counts(analysis).items()}
    obj.ParameterVerdicts = {p["name"]: parameter_class(p) for p in analysis["parameters"]}
    geometry.color_markers(obj, analysis)
    obj.Status = "analysed"
    obj.Document.recompute()
    return analysis


def results(obj) -> dict | None:
    """The last analysis stored in the object (``None`` if it was not analysed since its last build)."""
    return json.loads(obj.Analysis) if obj.Analysis else None


def _measurements(obj, data, validation) -> list[str]:
    if data is None:
        data, validation = obj.MeasurementFile, obj.ValidationFile
    data, validation = str(data or ""), str(validation or "")
    if not data:
        raise HyperstatWorkbenchError(f"{obj.Label}: no measurement file: load measurements first (a CSV file).")
    for label, value in (("measurement file", data), ("validation file", validation)):
        if value and not Path(value).is_file():
            raise HyperstatWorkbenchError(f"{obj.Label}: the {label} '{value}' does not exist.")
    obj.MeasurementFile, obj.ValidationFile = data, validation
    args = [obj.MeasurementFile]
    if obj.ValidationFile:
        args += ["--validation", obj.ValidationFile]
    return args


def _sample_args(obj) -> list[str]:
    return ["--configurations", str(obj.Configurations), "--seed", str(obj.Seed)]


def identify(obj, data: str | os.PathLike | None = None, validation: str | os.PathLike | None = None) -> dict:
    """``hyperstat identify``: fit the free influential defects to measurements (CSV files).

    Returns the identification JSON, also stored in ``Identification``; the printed
    summary goes to ``IdentificationText``.
    """
    meas = _measurements(obj, data, validation)
    model = _model_file(obj)
    out = work_dir(obj) / "identification.json"
    res = run_cli(["identify", str(model), *meas, "--json", str(out), *_sample_args(obj)])
    text = out.read_text(encoding="utf-8")
    obj.Identification = text
    obj.IdentificationText = res.stdout
    return json.loads(text)


def diagnose(obj, data: str | os.PathLike | None = None, validation: str | os.PathLike | None = None) -> dict:
    """``hyperstat diagnose``: where the rigid model misses, which unmodelled effect, how far it shrinks.

    Raises
    ------
    CommandMissing
        If the installed hyperstat has no ``diagnose`` command.
    """
    meas = _measurements(obj, data, validation)
    model = _model_file(obj)
    out = work_dir(obj) / "diagnosis.json"
    res = run_cli(["diagnose", str(model), *meas, "--json", str(out)])
    text = out.read_text(encoding="utf-8")
    obj.Diagnosis = text
    obj.DiagnosisText = res.stdout
    return json.loads(text)


def _data_options(obj) -> list[str]:
    out = []
    if obj.MeasurementFile:
        out += ["--data", obj.MeasurementFile]
    if obj.ValidationFile:
        out += ["--validation", obj.ValidationFile]
    return out


def export_report(obj, out_dir: str | os.PathLike) -> Path:
    """``hyperstat report``: the tolerance report (HTML, Markdown, JSON) in ``out_dir``.

    Measurements loaded in the object are passed with ``--data`` / ``--validation``.
    """
    model = _model_file(obj)
    run_cli(["report", str(model), *_data_options(obj), "--out", str(out_dir)])
    obj.ReportDir = str(out_dir)
    return Path(out_dir)


def export_controller(obj, out_file: str | os.PathLike) -> Path:
    """``hyperstat export-controller``: the controller parameter file (JSON), from the loaded measurements."""
    model = _model_file(obj)
    if not obj.MeasurementFile:
        raise HyperstatWorkbenchError("Load measurements first: the controller file holds the identified parameters.")
    extra = ["--validation", obj.ValidationFile] if obj.ValidationFile else []
    run_cli(["export-controller", str(model), obj.MeasurementFile, *extra, "--diagnose", "--out", str(out_file)])
    obj.ControllerFile = str(out_file)
    return Path(out_file)
