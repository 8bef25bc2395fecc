"""The tolerance report: self-contained HTML opened in headless Chromium, printed to PDF; MD and JSON agree.

Units: lengths in mm, angles in rad.
"""

from __future__ import annotations

import html
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
    for heading in ("Skeleton and tolerances", "Defects per joint", "Assembly conditions", "Design hypotheses",
                    "Identification", "Sim-to-real gap", "Calibration"):
        assert f"<h2>{heading}</h2>" in dom
    shot = tmp_path / "shot.png"
    chromium(tmp_path, "--window-size=1280,2000", f"--screenshot={shot}", html_path.as_uri())
    from PIL import Image

    img = np.asarray(Image.open(shot).convert("RGB")).astype(float)
    assert img.shape[:2] == (2000, 1280)
    assert img.std() > 20  # not blank
    colors = {tuple(c) for c in img[::7, ::7].reshape(-1, 3).astype(int)}
    assert len(colors) > 50  # text, badges and the rendered skeleton


def test_markdown_and_json_say_the_same(tripteor_report):
    doc = json.loads((tripteor_report / "report.json").read_text())
    md = (tripteor_report / "report.md").read_text()
    html = (tripteor_report / "report.html").read_text()
    for a in doc["assembly_conditions"]:
        assert f"* {a['id']}: {a['statement']}" in md and a["statement"] in html
    for cls, n in doc["summary"]["tolerance_classes"].items():
        assert f"* {cls}: {n}" in md
    classes = [p["class"] for j in doc["joints"] for p in j["parameters"]]
    assert len(classes) == doc["summary"]["parameters"] == 87
    assert doc["diagnosis"]["selected"][0] == "backlash"
    assert doc["identification"]["validation"]["rms"] <= 1.3 * doc["identification"]["noise_rms"]
    for r in doc["relations"]:
        assert r["mathml"].startswith("<mrow>") or r["mathml"].startswith("<math")
    for t in doc["tolerances"]["items"]:
        assert f"| {t['id']} |" in md and f"<td>{t['id']}</td>" in html


def test_report_is_deterministic(tmp_path):
    src = str(TEMPLATES / "slider_crank.py")
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        assert main(["report", src, "--out", str(out), "--quiet"]) == 0
    for name in ("report.json", "report.md", "report.html"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


# ---------------------------------------------------------------------------- printed on A4
def _ink(png) -> float:
    from PIL import Image

    img = np.asarray(Image.open(png).convert("L"))
    return float(np.mean(img < 200))


@pytest.fixture(scope="module")
def tripteor_pdf(tmp_path_factory):
    """The real Tripteor report (no measurements), printed by headless Chromium as the brief prints it."""
    tmp = tmp_path_factory.mktemp("print")
    out = tmp / "rep"
    assert main(["report", str(TEMPLATES / "tripteor_x7.py"), "--out", str(out), "--quiet"]) == 0
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    assert exe, "chromium (Debian package) is installed by 'make test'"
    pdf = tmp / "report.pdf"
    subprocess.run([exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                    "--disable-background-networking", "--disable-component-update", "--disable-sync",
                    f"--user-data-dir={tmp / 'profile'}", f"--print-to-pdf={pdf}", "--no-pdf-header-footer",
                    (out / "report.html").as_uri()], capture_output=True, text=True, timeout=180, check=True)
    return out, pdf


def test_printed_report_has_the_tolerance_table_on_page_one_and_no_blank_page(tripteor_pdf, tmp_path):
    out, pdf = tripteor_pdf
    assert shutil.which("pdftoppm") and shutil.which("pdftotext"), "poppler-utils is installed by 'make test'"
    doc = json.loads((out / "report.json").read_text())
    info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True, check=True).stdout
    pages = int(re.search(r"Pages:\s+(\d+)", info).group(1))
    assert 3 <= pages <= 10, pages  # was 14 with a page per section, one of them a lone heading
    subprocess.run(["pdftoppm", "-r", "30", "-png", str(pdf), str(tmp_path / "p")], check=True)
    shots = sorted(tmp_path.glob("p-*.png"))
    assert len(shots) == pages
    inks = [_ink(s) for s in shots]
    assert min(inks) > 0.01, inks  # no blank or near-blank page (a lone heading is about 0.3 %)
    page1 = subprocess.run(["pdftotext", "-layout", "-f", "1", "-l", "1", str(pdf), "-"], capture_output=True,
                           text=True, check=True).stdout
    assert "Tolerance report: tripteor_x7" in page1 and "statement" in page1 and "class" in page1
    first = doc["tolerances"]["items"][:5]
    for t in first:
        assert t["id"] in page1 and t["statement"].replace(" ", "") in page1.replace(" ", "")
    assert re.search(r"± \d\S* (mm|rad)", page1)  # values with units on page 1
    assert "spec" in page1 and "position ± 0.05 mm" in page1


def test_every_tolerance_of_the_json_is_in_the_html(tripteor_pdf):
    out, _ = tripteor_pdf
    doc = json.loads((out / "report.json").read_text())
    page = (out / "report.html").read_text()
    assert "{&quot;" not in page and '{"' not in page.split("</style>")[1]  # no raw JSON anywhere
    items = doc["tolerances"]["items"]
    assert len(items) == sum(doc["summary"]["tolerance_classes"].values()) > 50
    for t in items:
        row = page[page.index(f"<tr><td>{t['id']}</td>"):]
        row = row[: row.index("</tr>")]
        assert html.escape(t["statement"]) in row and t["class"] in row
        if t["value"] is not None:
            assert f"± {t['value']:.3g} {t['unit']}" in row
