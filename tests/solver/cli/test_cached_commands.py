"""Compute once per model (issue 39): a cached run writes the same JSON as an uncached one, and a changed model,
data file or option is never answered from the cache (units: mm, rad)."""

from __future__ import annotations

import argparse
import json
import warnings

import numpy as np
import pytest

from hyperstat.solver import save_model
from hyperstat.solver.cli.cached import cached_selection, cached_values

from tests.conftest import TEMPLATES, run_cli

#: a small Monte Carlo on the slider-crank: the sample, the tolerance values and the document are cached
MC = ["--workspace-configurations", "60", "--samples", "200", "--quiet"]


@pytest.fixture()
def cache_dir(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv("HYPERSTAT_CACHE", str(folder))
    return folder


def _montecarlo(source, out, *extra):
    code, _, err = run_cli(["montecarlo", source, *MC, "--json", out, *extra])
    assert code == 0, err
    return out.read_text()


def _entries(folder, stage):
    return sorted(p.name for p in (folder / stage).rglob("*.json")) if (folder / stage).exists() else []


def test_cached_and_uncached_runs_write_the_same_json(tmp_path, cache_dir):
    source = TEMPLATES / "slider_crank.py"
    first = _montecarlo(source, tmp_path / "a.json")
    assert _entries(cache_dir, "sample") and _entries(cache_dir, "values") and _entries(cache_dir, "montecarlo")
    again = _montecarlo(source, tmp_path / "b.json")  # read from the cache
    fresh = _montecarlo(source, tmp_path / "c.json", "--no-cache")
    assert again == first == fresh  # the same text: stored floats come back bit for bit
    assert len(_entries(cache_dir, "montecarlo")) == 1  # --no-cache stored nothing new


def test_a_changed_option_or_model_is_computed_again(tmp_path, cache_dir, slider_crank):
    model = save_model(slider_crank, tmp_path / "sc.json")
    base = _montecarlo(model, tmp_path / "a.json")
    # an option the answer depends on: a new entry, and the answer of an uncached run
    seeded = _montecarlo(model, tmp_path / "b.json", "--seed", "3")
    assert seeded != base and seeded == _montecarlo(model, tmp_path / "c.json", "--seed", "3", "--no-cache")
    assert len(_entries(cache_dir, "montecarlo")) == 2
    # the same file name with another model in it (the crank's range narrowed around home): not the stored answer
    doc = json.loads(model.read_text())
    crank = next(el for chain in doc["chains"] for el in chain["elements"] if el.get("role") == "actuated")
    crank["range"] = [crank["home"] - 0.5, crank["home"] + 0.5]
    model.write_text(json.dumps(doc))
    edited = _montecarlo(model, tmp_path / "d.json")
    assert edited != base
    assert edited == _montecarlo(model, tmp_path / "e.json", "--no-cache")
    assert len(_entries(cache_dir, "sample")) == 3  # seed 3, then the edited model: each its own sample


def test_a_template_and_its_built_model_are_one_key_and_a_changed_parameter_another(tmp_path, cache_dir):
    """The key is the model's content, not how it was obtained: the model file ``hyperstat build`` writes of a
    template (FreeCAD's Analyse reads that one) reads the template's sample and values, and answers as an uncached
    run of it; a template parameter changed with ``-p`` is another model, computed again."""
    source = TEMPLATES / "slider_crank.py"
    model = tmp_path / "sc.skel.json"
    code, _, err = run_cli(["build", source, "--model", model, "--quiet"])
    assert code == 0, err
    first = json.loads(_montecarlo(source, tmp_path / "a.json"))
    assert len(_entries(cache_dir, "sample")) == len(_entries(cache_dir, "values")) == 1
    built = _montecarlo(model, tmp_path / "b.json")
    assert len(_entries(cache_dir, "sample")) == len(_entries(cache_dir, "values")) == 1  # read, not computed
    assert len(_entries(cache_dir, "montecarlo")) == 2  # a document names its source: one per source
    assert built == _montecarlo(model, tmp_path / "c.json", "--no-cache")
    assert {k: v for k, v in json.loads(built).items() if k != "source"} == \
           {k: v for k, v in first.items() if k != "source"}
    longer = _montecarlo(source, tmp_path / "d.json", "-p", "L2=130")
    assert len(_entries(cache_dir, "sample")) == len(_entries(cache_dir, "values")) == 2
    assert json.loads(longer)["drawn_values"] != first["drawn_values"]


def test_report_and_accuracy_on_the_same_sample_read_one_values_entry(tmp_path, cache_dir):
    """``accuracy`` on the report's sample (200 configurations, seed 0) and spec computes the same values (bit for bit,
    the corpus runs both): one entry, read by the second command, which answers as its uncached run; another spec is
    computed again."""
    import inspect

    from hyperstat.solver.cli.cached import _DEFAULTS
    from hyperstat.solver.tolerances.values import assign_values

    signature = inspect.signature(assign_values).parameters
    assert all(signature[name].default is value for name, value in _DEFAULTS.items())
    source = TEMPLATES / "slider_crank.py"
    code, _, err = run_cli(["report", source, "--out", tmp_path / "rep", "--json-only", "--quiet"])
    assert code == 0, err
    assert len(_entries(cache_dir, "values")) == 1

    def accuracy(name, *extra):
        code, _, err = run_cli(["accuracy", source, "--workspace-configurations", "200", "--no-refine", "--json",
                                tmp_path / name, "--quiet", *extra])
        assert code == 0, err
        return (tmp_path / name).read_text()

    cached = accuracy("a.json")
    assert len(_entries(cache_dir, "values")) == 1  # the report's entry, read
    assert cached == accuracy("b.json", "--no-cache")
    report = json.loads((tmp_path / "rep" / "report.json").read_text())["tolerances"]["items"]
    assert [t["value"] for t in json.loads(cached)["tolerances"]["items"]] == [t["value"] for t in report]
    accuracy("c.json", "--position-accuracy", "0.04")
    assert len(_entries(cache_dir, "values")) == 2


def test_the_stages_free_of_the_sample_are_computed_once_across_commands(tmp_path, cache_dir):
    """``accuracy`` at 60 configurations, then ``report`` at its 200: two samples, two values entries; but the assembly
    conditions' values and the whole drawing's start from the analysis' configurations and the workspace's fixed
    checkpoints in both, so each is one entry, which the report reads (not written again) and its JSON is the
    uncached report's, to the byte."""
    source = TEMPLATES / "slider_crank.py"
    code, _, err = run_cli(["accuracy", source, "--workspace-configurations", "60", "--json", tmp_path / "a.json",
                            "--quiet"])
    assert code == 0, err
    stages = ("assembly-values", "whole-drawing")
    stored = {stage: _entries(cache_dir, stage) for stage in stages}
    assert all(len(names) == 1 for names in stored.values()), stored
    stamps = {p: p.stat().st_mtime_ns for stage in stages for p in (cache_dir / stage).rglob("*.json")}
    code, _, err = run_cli(["report", source, "--out", tmp_path / "rep", "--json-only", "--quiet"])
    assert code == 0, err
    assert len(_entries(cache_dir, "values")) == 2  # another sample: its own values
    assert {stage: _entries(cache_dir, stage) for stage in stages} == stored
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps  # read, not computed and stored again
    code, _, err = run_cli(["report", source, "--out", tmp_path / "fresh", "--json-only", "--quiet", "--no-cache"])
    assert code == 0, err
    cached = (tmp_path / "rep" / "report.json").read_text()
    assert cached == (tmp_path / "fresh" / "report.json").read_text()
    # the whole drawing changed the conditions it read (their values together): restored from the entry
    together = json.loads(cached)["tolerances"]["allocation"]["whole_drawing"]
    assert together["factors"] and any(f < 1.0 for f in together["factors"].values()), together["factors"]


def _same(a, b, where: str = "mechanism") -> list:
    """Where two objects differ, attribute by attribute (arrays by their values, callables not compared)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return [] if np.shape(a) == np.shape(b) and np.array_equal(a, b) else [where]
    if type(a) is not type(b):
        return [f"{where}: {type(a).__name__} / {type(b).__name__}"]
    if isinstance(a, dict):
        if set(a) != set(b):
            return [f"{where}: keys {sorted(map(str, set(a) ^ set(b)))}"]
        return [d for k in a for d in _same(a[k], b[k], f"{where}[{k!r}]")]
    if isinstance(a, (list, tuple)):
        if len(a) != len(b):
            return [f"{where}: length"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _same(x, y, f"{where}[{i}]")]
    if hasattr(a, "__dict__") and not callable(a):
        return _same(vars(a), vars(b), where)
    if callable(a) or a == b or (a != a and b != b):
        return []
    return [f"{where}: {a!r} / {b!r}"]


def test_the_model_file_holds_every_attribute_the_stages_read(tmp_path):
    """Why the key can be the model-file text alone: the mechanism of every shipped template and the one read back
    from its model file are equal in every attribute (joints, elements, defects, ranges, metadata...)."""
    from hyperstat.cad_plugin.templates import build_template, list_templates
    from hyperstat.solver.kinematics.modelfile import load_model

    for template in list_templates():
        mech = build_template(template).mechanism()
        again = load_model(save_model(mech, tmp_path / f"{template.stem}.json"))
        assert _same(mech, again) == [], template.stem


def test_the_values_stage_restores_what_it_computed(cache_dir, slider_crank, slider_crank_analysis):
    """The changes :func:`assign_values` makes to a classification, stored and applied to a fresh one, give the
    same classification (every tolerance's value, source, evidence, drawing, the allocation, the warnings)."""
    from hyperstat.solver.kinematics.closure import Kinematics
    from hyperstat.solver.tolerances.classification import classify
    from hyperstat.solver.tolerances.values import assign_values

    kin = Kinematics(slider_crank)
    q = slider_crank_analysis.configurations[:12]
    args = argparse.Namespace(source=str(TEMPLATES / "slider_crank.py"), param=None)
    calls = []

    def assign(*a, **k):
        calls.append(1)
        return assign_values(*a, **k)

    docs = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(2):
            cl = classify(slider_crank, slider_crank_analysis, kin)
            cached_values(args, cl, slider_crank, kin, q, assign, position_accuracy=0.05, assembly=False)
            docs.append(json.dumps(cl.to_dict(), sort_keys=True, default=str))
        assert len(calls) == 1  # the second classification was filled from the cache
        cl = classify(slider_crank, slider_crank_analysis, kin)
        cached_values(args, cl, slider_crank, kin, q, assign, position_accuracy=0.04, assembly=False)
    assert docs[0] == docs[1]
    assert len(calls) == 2 and json.dumps(cl.to_dict(), sort_keys=True, default=str) != docs[0]  # another spec


def test_the_diagnosis_selection_follows_the_data_files(tmp_path, cache_dir, slider_crank, slider_crank_analysis):
    data = tmp_path / "m.csv"
    data.write_text("x\n1\n")
    args = argparse.Namespace(source=str(TEMPLATES / "slider_crank.py"), param=None)
    runs = []

    class Diagnosis:
        selected = ["backlash"]
        violated_defect = {"defect": "dI21"}

    def diagnose():
        runs.append(1)
        return Diagnosis()

    first = cached_selection(args, slider_crank, slider_crank_analysis, [data, None], diagnose)
    assert first == (["backlash"], {"defect": "dI21"}) and len(runs) == 1
    assert cached_selection(args, slider_crank, slider_crank_analysis, [data, None], diagnose) == first
    assert len(runs) == 1
    data.write_text("x\n2\n")  # the same file, other measurements
    cached_selection(args, slider_crank, slider_crank_analysis, [data, None], diagnose)
    assert len(runs) == 2
    args.no_cache = True
    args._cache = None
    cached_selection(args, slider_crank, slider_crank_analysis, [data, None], diagnose)
    assert len(runs) == 3


def test_export_controller_reads_the_selection_and_writes_the_same_file(tmp_path, cache_dir):
    """``export-controller --diagnose`` with the diagnosis' selection from the cache writes the very bytes of the run
    that diagnosed (the controller file is hashed: a result must not depend on what the process computed before)."""
    data = tmp_path / "m.csv"
    code, _, err = run_cli(["simulate", TEMPLATES / "tripteor_x7.py", "--effect", "backlash", "--out", data,
                            "--truth", tmp_path / "truth.json", "--quiet"])
    assert code == 0, err
    outs = []
    for name in ("a.json", "b.json"):
        code, _, err = run_cli(["export-controller", TEMPLATES / "tripteor_x7.py", data, "--validation",
                                tmp_path / "m.validation.csv", "--diagnose", "--out", tmp_path / name, "--quiet"])
        assert code == 0, err
        outs.append((tmp_path / name).read_bytes())
    assert _entries(cache_dir, "diagnosis-selection")  # the first run stored it, the second read it
    assert outs[0] == outs[1]
