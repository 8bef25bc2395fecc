"""Extraction: template -> assembly / STEP -> model, equal within 1e-9 mm and 1e-12 rad; same verdicts."""

import json
import warnings

import numpy as np
import pytest

from hyperstat.cad_plugin import build_template
from hyperstat.cad_plugin.assembly import build_assembly, export_step, sidecar_path
from hyperstat.cad_plugin.cli import main
from hyperstat.cad_plugin.extract import extract_from_assembly, extract_from_step
from hyperstat.solver import ModelError, save_model

from tests.conftest import TEMPLATES
from tests.cad_plugin.test_templates import NAMES


def _compare(a, b):
    """Largest difference of origins (mm) and of axis components (rad), element by element."""
    assert [c.name for c in a.chains] == [c.name for c in b.chains]
    dp = da = 0.0
    for ca, cb in zip(a.chains, b.chains):
        assert [e.name for e in ca.elements] == [e.name for e in cb.elements]
        for ea, eb in zip(ca.elements, cb.elements):
            assert ea.kind == eb.kind
            assert getattr(ea, "defects", ()) == getattr(eb, "defects", ())
            if ea.kind == "joint":
                assert (ea.type, ea.role, ea.range) == (eb.type, eb.role, eb.range)
                assert ea.home == pytest.approx(eb.home, abs=1e-12)
            dp = max(dp, float(np.max(np.abs(np.subtract(ea.placement.origin, eb.placement.origin)))))
            for f in ("z_axis", "x_axis"):
                da = max(da, float(np.max(np.abs(np.subtract(getattr(ea.placement, f), getattr(eb.placement, f))))))
    return dp, da


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    out = tmp_path_factory.mktemp("step")
    result = {}
    for name in NAMES:
        sk = build_template(TEMPLATES / f"{name}.py")
        step, side = export_step(sk, out / f"{name}.step")
        result[name] = (sk, step, side)
    return result


@pytest.mark.parametrize("name", NAMES)
def test_assembly_and_step_extract_to_the_template_model(exported, name):
    sk, step, side = exported[name]
    mech = sk.mechanism()
    dp, da = _compare(mech, extract_from_assembly(build_assembly(sk)))
    assert dp < 1e-9 and da < 1e-12
    dp, da = _compare(mech, extract_from_step(step))
    assert dp < 1e-9 and da < 1e-12
    assert step.read_text(errors="replace").count("SI_UNIT(.MILLI.,.METRE.)") >= 1


def test_missing_sidecar_and_missing_marker_are_named(exported, tmp_path):
    sk, step, side = exported["slider_crank"]
    lonely = tmp_path / "lonely.step"
    lonely.write_bytes(step.read_bytes())
    with pytest.raises(ModelError, match=r"lonely.step.json: the sidecar of the STEP file is missing"):
        extract_from_step(lonely)
    meta = json.loads(side.read_text())
    meta["nodes"]["m_9"] = dict(meta["nodes"]["m_2"], element="9")
    sidecar_path(lonely).write_text(json.dumps(meta))
    with pytest.raises(ModelError, match=r"marker 'm_9' named by the sidecar is missing from the STEP file"):
        extract_from_step(lonely)


def test_inconsistent_marker_is_named():
    import cadquery as cq

    sk = build_template(TEMPLATES / "slider_crank.py")
    assy = build_assembly(sk)
    marker = assy.objects["m_3"]
    swapped = marker.objects["x"]
    swapped.loc = cq.Location(cq.Vector(0, 0, 0), cq.Vector(0, 0, 1), 90)  # x arrow now along y
    with pytest.raises(ModelError, match=r"marker 'm_3' is inconsistent: its x arrow does not lie along"):
        extract_from_assembly(assy)


def test_step_in_metres_is_refused(exported, tmp_path):
    sk, step, side = exported["slider_crank"]
    metres = tmp_path / "m.step"
    metres.write_bytes(step.read_bytes().replace(b"SI_UNIT(.MILLI.,.METRE.)", b"SI_UNIT($,.METRE.)"))
    sidecar_path(metres).write_text(side.read_text())
    with pytest.raises(ModelError, match=r"length unit is METRE; hyperstat expects millimetres"):
        extract_from_step(metres)


def _verdicts(path):
    return [(p["name"], p["verdict"], p["influential"]) for p in json.loads(path.read_text())["parameters"]]


@pytest.mark.parametrize("name", NAMES)
def test_analyze_gives_identical_verdicts_from_template_model_and_step(exported, name, tmp_path):
    sk, step, _ = exported[name]
    model = save_model(sk.mechanism(), tmp_path / f"{name}.json")
    outs = []
    for k, src in enumerate((TEMPLATES / f"{name}.py", model, step)):
        out = tmp_path / f"a{k}.json"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert main(["analyze", str(src), "--json", str(out), "--quiet"]) == 0
        outs.append(_verdicts(out))
    assert outs[0] == outs[1] == outs[2]
    if name in ("hexapod", "scara"):
        assert not [v for v in outs[0] if v[1] in ("forced", "coupled")]
