"""Trust boundary: only templates run as code; no data file is ever evaluated or unpickled.

Static check of the package sources (ast): no ``eval``/``exec``/``compile`` calls, no
``pickle``/``marshal``/``shelve`` imports, no unsafe ``yaml.load``; the one place that runs
code is the template loader, which executes a template module the user chose.
"""

from __future__ import annotations

import ast

from .conftest import ROOT

PACKAGES = ("solver", "cad_plugin")
LOADER = ROOT / "cad_plugin" / "templates.py"


def _sources():
    for pkg in PACKAGES:
        yield from sorted((ROOT / pkg).rglob("*.py"))

# The two places that run Python files, both documented in the README's trust boundary: templates,
# and the independent campaign generator of `validate-diagnosis --independent` (the project's own
# tests/solver/diagnosis/independent_generator.py, or a file given with --generator).
CODE_RUNNERS = {LOADER, ROOT / "solver" / "diagnosis" / "validation_suite.py"}


def test_no_evaluation_of_strings_and_no_pickle():
    offenders = []
    for path in _sources():
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Call):
                fn = node.func
                name = fn.id if isinstance(fn, ast.Name) else fn.attr if isinstance(fn, ast.Attribute) else ""
                if isinstance(fn, ast.Name) and name in ("eval", "exec", "compile", "__import__"):  # the builtins
                    offenders.append(f"{path.name}:{node.lineno} calls {name}")
                if name in ("load", "load_all") and isinstance(fn, ast.Attribute) and \
                        isinstance(fn.value, ast.Name) and fn.value.id == "yaml":
                    offenders.append(f"{path.name}:{node.lineno} uses yaml.{name} (use safe_load)")
                if name == "exec_module" and path not in CODE_RUNNERS:
                    offenders.append(f"{path.name}:{node.lineno} executes a module outside the template loader")
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                mods = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                for mod in mods:
                    if mod.split(".")[0] in ("pickle", "marshal", "shelve", "dill", "cloudpickle"):
                        offenders.append(f"{path.name}:{node.lineno} imports {mod}")
    assert offenders == []


def test_the_template_loader_is_the_only_code_runner():
    text = LOADER.read_text()
    assert "exec_module" in text  # templates are Python, run as code (documented in the README)
