"""The tolerance report: self-contained HTML opened in headless Chromium, printed to PDF; MD and JSON agree.

Units: lengths in mm, angles in rad.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from hyperstat.cad_plugin.cli import main
from hyperstat.cad_plugin.report import SECTIONS

from tests.conftest import TEMPLATES

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--hide-scrollbars"]


def chromium(tmp_path, *args: str) -> subprocess.CompletedProcess:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    assert exe, "chromium (Debian package) is installed by 'make test'"
    return subprocess.run([exe, *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'profile'}", *args],
                          capture_output=True, text=True, timeout=180)


@pytest.fixture(scope="module")
def tripteor_report(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("report")
    src = str(TEMPLATES / "tripteor_x7.py")
    data = tmp / "d.csv"
    assert main(["simulate", src, "--poses", "80", "--validation", "20", "--effect", "backlash", "--out", str(data),
                 "--quiet"]) == 0
    out = tmp / "rep"
    assert main(["report", src, "--data", str(data), "--validation", str(tmp / "d.validation.csv"), "--hypotheses",
                 str(TEMPLATES / "tripteor_x7.hypotheses.yaml"), "--out", str(out), "--quiet"]) == 0
    return out


def test_report_in_headless_chromium(tripteor_report, tmp_path):
    html_path = tripteor_report / "report.html"
    text = html_path.read_text()
    assert not re.search(r"(src|href)=\"(https?:)?//", text)  # nothing loaded from the network
    dom = chromium(tmp_path, "--dump-dom", html_path.as_uri()).stdout
    for section in SECTIONS:
        assert f'<section id="{section}">' in dom
    for heading in ("Summary", "Skeleton and verdicts", "Defects per joint", "Constraint equations",
                    "Design hypotheses", "Identification", "Sim-to-real gap"):
        assert f"<h2>{heading}</h2>" in dom
    shot = tmp_path / "shot.png"
    chromium(tmp_path, "--window-size=1280,2000", f"--screenshot={shot}", html_path.as_uri())
    from PIL import Image

    img = np.asarray(Image.open(shot).convert("RGB")).astype(float)
    assert img.shape[:2] == (2000, 1280)
    assert img.std() > 20  # not blank
    colors = {tuple(c) for c in img[::7, ::7].reshape(-1, 3).astype(int)}
    assert len(colors) > 50  # text, badges and the rendered skeleton
    pdf = tmp_path / "report.pdf"
    chromium(tmp_path, f"--print-to-pdf={pdf}", "--no-pdf-header-footer", html_path.as_uri())
    raw = pdf.read_bytes()
    assert raw[:5] == b"%PDF-"
    assert len(re.findall(rb"/Type\s*/Page[^s]", raw)) >= len(SECTIONS)  # a page break before every section


def test_markdown_and_json_say_the_same(tripteor_report):
    doc = json.loads((tripteor_report / "report.json").read_text())
    md = (tripteor_report / "report.md").read_text()
    html = (tripteor_report / "report.html").read_text()
    for name in doc["forced"]:
        assert f"* {name} = 0" in md and name in html
    for cls, n in doc["summary"]["tolerance_classes"].items():
        assert f"* {cls}: {n}" in md
    classes = [p["class"] for j in doc["joints"] for p in j["parameters"]]
    assert len(classes) == doc["summary"]["parameters"] == 87
    assert doc["diagnosis"]["selected"][0] == "backlash"
    assert doc["identification"]["validation"]["rms"] <= 1.3 * doc["identification"]["noise_rms"]
    for r in doc["relations"]:
        assert r["mathml"].startswith("<mrow>") or r["mathml"].startswith("<math")


def test_report_is_deterministic(tmp_path):
    src = str(TEMPLATES / "slider_crank.py")
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        assert main(["report", src, "--out", str(out), "--quiet"]) == 0
    for name in ("report.json", "report.md", "report.html"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
