"""``hyperstat report --pdf``: the report printed on A4 by headless Chromium, read back with poppler.

Units: the report's (lengths mm, angles rad); page size in PostScript points (A4 = 595 x 842 pt).
"""

from __future__ import annotations

import re
import subprocess

from hyperstat.cad_plugin.cli import main

from tests.conftest import TEMPLATES


def test_report_pdf_is_a4_and_carries_the_tables(tmp_path, capsys):
    out = tmp_path / "rep"
    assert main(["report", str(TEMPLATES / "slider_crank.py"), "--out", str(out), "--pdf", "--quiet"]) == 0
    pdf = out / "report.pdf"
    info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True, check=True).stdout
    width, height = map(float, re.search(r"Page size:\s+([\d.]+) x ([\d.]+) pts", info).groups())
    assert abs(width - 595.3) < 2 and abs(height - 841.9) < 2, info  # A4 portrait
    text = subprocess.run(["pdftotext", str(pdf), "-"], capture_output=True, text=True, check=True).stdout
    assert "Tolerance report: slider_crank" in text
    assert "Skeleton and tolerances" in text
    assert sorted(p.name for p in out.iterdir()) == ["report.html", "report.json", "report.md", "report.pdf",
                                                     "skeleton_views.png", "skeleton_views.png.json"]


def test_report_pdf_with_json_only_is_refused_before_any_work(tmp_path, capsys):
    out = tmp_path / "rep"
    assert main(["report", str(TEMPLATES / "slider_crank.py"), "--out", str(out), "--pdf", "--json-only"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--json-only" in err
    assert not out.exists() or not any(out.iterdir())
