"""Load skeleton templates (Python files) and build them with parameter overrides.

Units: lengths in mm, angles in rad.

Trust boundary: a template is Python and runs as code with the user's rights, like
any script; only load templates you trust.  Parameter values from the command line
are parsed as numbers (:mod:`hyperstat.cad_plugin.params`), never evaluated.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import sys
import traceback
from pathlib import Path
from types import ModuleType
from typing import Any

from hyperstat.solver.errors import HyperstatError, TemplateError

from hyperstat.cad_plugin.params import make_parameters, parse_overrides
from hyperstat.cad_plugin.skeleton import Skeleton

__all__ = ["template_path", "load_template", "template_parameters", "build_template", "TEMPLATE_DIR", "CORPUS_DIR", "list_templates",
           "list_corpus", "bundled_template"]

TEMPLATE_DIR = Path(__file__).resolve().parent.parent / "templates"
#: the corpus: more mechanisms, each with its theory in its docstring (templates/corpus/__init__.py)
CORPUS_DIR = TEMPLATE_DIR / "corpus"


def list_templates() -> list[Path]:
    """Template files shipped with hyperstat (the six of ``templates/``; the corpus is :func:`list_corpus`)."""
    return sorted(p for p in TEMPLATE_DIR.glob("*.py") if not p.name.startswith("_"))


def list_corpus() -> list[Path]:
    """Template files of the corpus (``templates/corpus/*.py``)."""
    return sorted(p for p in CORPUS_DIR.glob("*.py") if not p.name.startswith("_"))


def bundled_template(name: str) -> Path | None:
    """The shipped template or corpus template called ``name`` (``"tripteor_x7"``, ``"bennett"``), or None.

    >>> bundled_template("bennett").relative_to(TEMPLATE_DIR).as_posix()
    'corpus/bennett.py'
    >>> bundled_template("no_such_thing") is None
    True
    """
    if not name or "/" in name or "\\" in name or name.startswith((".", "_")):
        return None
    for folder in (TEMPLATE_DIR, CORPUS_DIR):
        path = folder / f"{name}.py"
        if path.is_file():
            return path
    return None


def load_template(path: str | Path) -> ModuleType:
    """Import a template file as a module.

    Raises
    ------
    TemplateError
        If the file is missing, has a syntax error, fails at import, or has no
        ``build`` function or ``Parameters`` dataclass.
    """
    path = Path(path)
    if not path.is_file():
        raise TemplateError(f"{path}: no such template file.")
    digest = hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:10]
    name = f"hyperstat_template_{path.stem}_{digest}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise TemplateError(f"{path}: cannot be loaded as a Python template.")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses need the module registered
    try:
        spec.loader.exec_module(module)
    except SyntaxError as exc:
        sys.modules.pop(name, None)
        raise TemplateError(f"{path}: syntax error at line {exc.lineno}: {exc.msg}.") from None
    except HyperstatError:
        sys.modules.pop(name, None)
        raise
    except Exception as exc:  # noqa: BLE001 - a template is user code
        sys.modules.pop(name, None)
        line = _user_line(exc, path)
        raise TemplateError(f"{path}: failed while loading{line}: {exc.__class__.__name__}: {exc}.") from None
    if not callable(getattr(module, "build", None)):
        raise TemplateError(f"{path}: a template must define a function build(**parameters).")
    if not dataclasses.is_dataclass(getattr(module, "Parameters", None)):
        raise TemplateError(f"{path}: a template must define a dataclass Parameters (see hyperstat.cad_plugin.params.param).")
    return module


def _user_line(exc: BaseException, path: Path) -> str:
    for frame in reversed(traceback.extract_tb(exc.__traceback__)):
        if Path(frame.filename).resolve() == path.resolve():
            return f" (line {frame.lineno})"
    return ""


def template_parameters(module: ModuleType) -> type:
    """The ``Parameters`` dataclass of a loaded template."""
    return module.Parameters


def build_template(path: str | Path, overrides: list[str] | dict[str, Any] | None = None) -> Skeleton:
    """Build a template with overrides (``["NAME=VALUE"]`` strings or a dict of numbers).

    Raises
    ------
    TemplateError
        On an unknown parameter, a bad value, or an exception inside ``build``.
    """
    path = Path(path)
    module = load_template(path)
    cls = template_parameters(module)
    try:
        values = dict(overrides) if isinstance(overrides, dict) else parse_overrides(overrides, cls)
        params = make_parameters(cls, dict(values))  # validates names and bounds with clear messages
    except TemplateError as exc:
        raise TemplateError(f"{path.name}: {exc}") from None
    try:
        skeleton = module.build(**values)
    except HyperstatError as exc:
        raise TemplateError(f"{path}: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - a template is user code
        line = _user_line(exc, path)
        raise TemplateError(f"{path}: build() failed{line}: {exc.__class__.__name__}: {exc}.") from None
    if not isinstance(skeleton, Skeleton):
        raise TemplateError(f"{path}: build() must return a hyperstat.cad_plugin.skeleton.Skeleton, got {type(skeleton).__name__}.")
    skeleton.metadata.setdefault("template", path.name)
    if any(link.body is not None for link in skeleton.links):  # link masses from the CadQuery solids
        from hyperstat.cad_plugin.masses import apply_link_masses

        try:
            apply_link_masses(skeleton)
        except HyperstatError as exc:
            raise TemplateError(f"{path}: {exc}") from None
    if skeleton.metadata.get("masses"):  # computed or declared: finite, plausible for each body, none left out
        from hyperstat.solver.kinematics.masses import check_declared_masses

        check_declared_masses(skeleton.mechanism(), str(path), TemplateError)
    declared = getattr(module, "TOLERANCING", None)
    if declared is not None:  # task, measurements, spec, clearances (hyperstat.solver.tolerances.declaration)
        from hyperstat.solver.tolerances.declaration import parse_declaration

        try:
            parse_declaration(declared, path.name)
        except HyperstatError as exc:
            raise TemplateError(f"{path}: TOLERANCING: {exc}") from None
        skeleton.metadata.setdefault("tolerancing", dict(declared))
    if callable(getattr(module, "workspace", None)):
        skeleton.metadata["workspace"] = _workspace(module, params, path)
    return skeleton


def _workspace(module: ModuleType, params: Any, path: Path) -> dict:
    """The template's ``workspace(p)`` declaration (the ranges the machine is used over), JSON-ready.

    See :mod:`hyperstat.solver.tolerances.workspace`; the joint names are checked when the
    workspace is used, against the built mechanism.
    """
    try:
        declared = module.workspace(params)
    except Exception as exc:  # noqa: BLE001 - a template is user code
        line = _user_line(exc, path)
        raise TemplateError(f"{path}: workspace() failed{line}: {exc.__class__.__name__}: {exc}.") from None
    if not isinstance(declared, dict) or not isinstance(declared.get("ranges"), dict):
        raise TemplateError(f"{path}: workspace() must return {{'ranges': {{joint: (lo, hi)}}, 'note': ...}}, "
                            f"got {type(declared).__name__}.")
    try:
        ranges = {str(k): [float(v[0]), float(v[1])] for k, v in declared["ranges"].items()}
    except (TypeError, ValueError, IndexError):
        raise TemplateError(f"{path}: workspace() ranges must map joint names to (lo, hi) numbers.") from None
    return {"ranges": ranges, "note": str(declared.get("note", ""))}


def template_path(name: str) -> Path:
    """Path of a bundled template from its name (``"tripteor_x7"``, a corpus name such as ``"bennett"``) or of a
    file as given.

    >>> template_path("slider_crank").name
    'slider_crank.py'
    """
    path = Path(name)
    if path.suffix or path.exists():
        return path
    bundled = bundled_template(name)
    if bundled is None:
        from hyperstat.solver.cli.suggest import did_you_mean

        names = [p.stem for p in list_templates() + list_corpus()]
        raise HyperstatError(f"'{name}' is neither a file nor a bundled template{did_you_mean(name, names)} "
                             f"({', '.join(names)}).")
    return bundled
