"""The distribution: one package `hyperstat`, nothing else at top level, usable outside the repository.

The wheel is built for real (``pip wheel . --no-deps``), unpacked into a throwaway
directory and imported from a directory outside the repository; the analysis it gives is
compared with the one of the source tree (two installations, one answer).
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-q",
                    "-w", str(out)], check=True, capture_output=True, text=True)
    (path,) = out.glob("hyperstat-*.whl")
    return path


def test_every_module_of_the_wheel_lives_under_hyperstat(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    top = {n.split("/")[0] for n in names}
    assert {t for t in top if not t.endswith(".dist-info")} == {"hyperstat"}, top
    # every source package folder is in the wheel: none forgotten in pyproject's package list
    packages = {str(p.parent.relative_to(ROOT)).replace(os.sep, "/")
                for d in ("solver", "cad_plugin", "templates") for p in (ROOT / d).rglob("__init__.py")
                if "freecad" not in p.parts and "__pycache__" not in p.parts}
    packages |= {str(p.parent.relative_to(ROOT)) for p in (ROOT / "solver").rglob("schema/*.json")}
    shipped = {n[len("hyperstat/"):].rsplit("/", 1)[0] for n in names if n.startswith("hyperstat/")}
    assert packages <= shipped, sorted(packages - shipped)
    # the schemas and the templates' data files travel with the code
    assert "hyperstat/solver/kinematics/schema/model.schema.json" in names
    assert "hyperstat/solver/export/schema/controller.schema.json" in names
    assert "hyperstat/templates/tripteor_x7.py" in names


def _run_outside(site: Path, code: str, tmp_path: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(site)
    return subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True)


def test_the_wheel_analyses_a_bundled_template_outside_the_repository(wheel, tmp_path):
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    code = ("import json, hyperstat as hs; r = hs.analyze(hs.load('slider_crank'));"
            "print(json.dumps({'file': hs.__file__, 'counts': r.counts(), 'rank': r.rank}))")
    run = _run_outside(site, code, tmp_path)
    assert run.returncode == 0, run.stderr
    got = json.loads(run.stdout.strip().splitlines()[-1])
    assert Path(got["file"]).resolve().is_relative_to(site.resolve()), got["file"]  # the wheel, not the repo

    import hyperstat as hs  # the editable install of this checkout: the second path

    here = hs.analyze(hs.load("slider_crank"))
    assert got["counts"] == here.counts() and got["rank"] == here.rank
    # every parameter of the model has exactly one verdict
    assert got["counts"]["total"] == len(hs.load("slider_crank").parameters)
    assert sum(got["counts"][v] for v in ("gauge", "forced", "coupled", "free")) == got["counts"]["total"]


@pytest.mark.parametrize("name", ["solver", "cad_plugin", "templates"])
def test_generic_top_level_names_are_not_importable_outside_the_repository(wheel, tmp_path, name):
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    run = _run_outside(site, f"import {name}", tmp_path)
    assert run.returncode != 0 and "ModuleNotFoundError" in run.stderr


def _imports(path: Path, package: str) -> set[str]:
    """Modules of the hyperstat package that ``path`` imports (absolute and relative, at any depth)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.add(mod)
            out.update(f"{mod}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return {m for m in out if m.startswith("hyperstat")}


def _module_graph() -> dict[str, set[str]]:
    modules = {}
    for folder in ("solver", "cad_plugin", "templates"):
        for path in (ROOT / folder).rglob("*.py"):
            if "freecad" in path.parts:
                continue
            rel = path.relative_to(ROOT).with_suffix("")
            parts = ["hyperstat", *rel.parts]
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join(parts)] = path
    graph = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        graph[name] = {m for m in _imports(path, package) if m in modules and m != name}
    return graph


STAGES = ["kinematics", "analysis", "tolerances", "calibration", "diagnosis", "export", "cli"]


def test_imports_point_down_the_pipeline_and_form_no_cycle():
    graph = _module_graph()
    for name, targets in graph.items():
        for target in targets:
            if name.startswith("hyperstat.solver"):
                assert not target.startswith(("hyperstat.cad_plugin", "hyperstat.templates")), (name, target)
            if name.startswith("hyperstat.cad_plugin"):
                assert not target.startswith("hyperstat.templates"), (name, target)
            a, b = name.split("."), target.split(".")
            if len(a) > 2 and len(b) > 2 and a[1] == b[1] == "solver" and a[2] in STAGES and b[2] in STAGES:
                assert STAGES.index(b[2]) <= STAGES.index(a[2]), f"{name} imports {target}: against the pipeline"
    # no cycle (module-level and function-level imports alike), by depth-first search
    state: dict[str, int] = {}

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph[node]):
            if nxt.startswith(node + "."):
                continue  # a package re-exporting its own modules is not a cycle
            if state.get(nxt) == 1:
                raise AssertionError("import cycle: " + " -> ".join(path[path.index(nxt):] + [nxt]))
            if not state.get(nxt):
                visit(nxt, path + [nxt])
        state[node] = 2

    for node in sorted(graph):
        if not state.get(node):
            visit(node, [node])
