"""The tolerance report printed by headless Chromium on A4 and read back with poppler; MD and JSON agree.

Units: lengths in mm, angles in rad; residuals in µm.

Two Tripteor reports are printed: the real one of today's pipeline without measurements, and
one with measurements, hypotheses and tolerance items that carry every field of the tolerance
contract (``value_with_calibration``, ``drawing``..., built by ``tests/cad_plugin/contract.py``
and injected where the pipeline makes the report's content), the fullest report there is.
"""

from __future__ import annotations

import hashlib
import html
import json
import re
import shutil
import subprocess
from importlib.metadata import version
from pathlib import Path

import numpy as np
import pytest

from hyperstat.cad_plugin.cli import main
from hyperstat.cad_plugin.report import SECTIONS

from tests.cad_plugin.contract import with_contract_fields
from tests.conftest import TEMPLATES

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync"]
HEADINGS = ("Skeleton and tolerances", "Assembly conditions", "Accuracy and allocation", "Monte Carlo", "Calibration",
            "Design hypotheses", "Identification", "Sim-to-real gap", "Defects per joint", "Glossary",
            "Appendix: normalisation components (not tolerances)", "Contributors: tolerances",
            "Contributors: actuator errors", "Effect parameters")


def print_pdf(html_path: Path, pdf: Path) -> Path:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    assert exe, "chromium (Debian package) is installed by 'make test'"
    subprocess.run([exe, *CHROMIUM_FLAGS, f"--user-data-dir={pdf.parent / 'profile'}", f"--print-to-pdf={pdf}",
                    "--no-pdf-header-footer", html_path.as_uri()], capture_output=True, text=True, timeout=180,
                   check=True)
    return pdf


def page_text(pdf: Path, page: int, layout: bool = True) -> str:
    return subprocess.run(["pdftotext", *(["-layout"] if layout else []), "-f", str(page), "-l", str(page), str(pdf),
                           "-"], capture_output=True, text=True, check=True).stdout


def pages_of(pdf: Path) -> int:
    info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True, check=True).stdout
    return int(re.search(r"Pages:\s+(\d+)", info).group(1))


def text_runs(pdf: Path, page: int) -> list[tuple[str, int]]:
    """(text, font size in pt) of every text run of a page (poppler's pdftohtml -xml)."""
    xml = subprocess.run(["pdftohtml", "-xml", "-i", "-stdout", "-zoom", "1", "-f", str(page), "-l", str(page),
                          str(pdf)], capture_output=True, text=True, check=True).stdout
    sizes = {m.group(1): int(m.group(2)) for m in re.finditer(r'<fontspec id="(\d+)" size="(-?\d+)"', xml)}
    return [(html.unescape(re.sub(r"<[^>]+>", "", m.group(2))), sizes[m.group(1)])
            for m in re.finditer(r'<text [^>]*font="(\d+)"[^>]*>(.*?)</text>', xml)]


@pytest.fixture(scope="module")
def full_report(tmp_path_factory):
    """Tripteor with measurements, hypotheses and contract fields on its tolerance items, printed on A4."""
    import hyperstat.solver.export.report_content as content

    tmp = tmp_path_factory.mktemp("full")
    src = str(TEMPLATES / "tripteor_x7.py")
    data = tmp / "d.csv"
    assert main(["simulate", src, "--poses", "80", "--validation", "20", "--effect", "backlash", "--out", str(data),
                 "--quiet"]) == 0
    out = tmp / "rep"
    real = content.report_document
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(content, "report_document", lambda *a, **k: with_contract_fields(real(*a, **k)))
        assert main(["report", src, "--data", str(data), "--validation", str(tmp / "d.validation.csv"), "--hypotheses",
                     str(TEMPLATES / "tripteor_x7.hypotheses.yaml"), "--out", str(out), "--revision", "B",
                     "--quiet"]) == 0
    return out, print_pdf(out / "report.html", tmp / "report.pdf")


@pytest.fixture(scope="module")
def plain_report(tmp_path_factory, tripteor_report):
    """The real Tripteor report of today's pipeline (no measurements; the session's, tests/cad_plugin/conftest.py),
    printed on A4."""
    tmp = tmp_path_factory.mktemp("plain")
    out, _ = tripteor_report
    return out, print_pdf(out / "report.html", tmp / "report.pdf")


def _ink(png) -> float:
    from PIL import Image

    return float(np.mean(np.asarray(Image.open(png).convert("L")) < 200))


def first_part_page(pdf: Path, heading: str = "Part drawing") -> int:
    """The first page that begins with ``heading``: "Part drawings" (the section: the report's own pages end
    before it) or "Part drawing:" (the first part's page); one past the last page when there is none."""
    pages = pages_of(pdf)
    return next((p for p in range(1, pages + 1) if page_text(pdf, p).lstrip().startswith(heading)), pages + 1)


@pytest.mark.parametrize("which", ["full_report", "plain_report"])
def test_printed_report_fits_ten_pages_with_no_blank_page_and_no_orphaned_heading(which, request, tmp_path):
    out, pdf = request.getfixturevalue(which)
    pages = pages_of(pdf)
    assert 3 <= first_part_page(pdf) - 1 <= 10, pages  # the report's own pages; then one page per part drawing
    subprocess.run(["pdftoppm", "-r", "30", "-png", str(pdf), str(tmp_path / "p")], check=True)
    inks = [_ink(s) for s in sorted(tmp_path.glob("p-*.png"))]
    assert len(inks) == pages and min(inks) > 0.01, inks  # a lone heading is about 0.3 %
    for page in range(1, pages):
        lines = [ln.strip() for ln in page_text(pdf, page).splitlines() if ln.strip()]
        assert lines[-1] not in HEADINGS, (page, lines[-3:])  # a heading never ends a page
    text = "\n".join(page_text(pdf, p) for p in range(1, pages + 1))
    for heading in HEADINGS[:5]:
        assert heading in text


@pytest.mark.parametrize("which", ["full_report", "plain_report"])
def test_page_one_has_the_title_block_and_the_tolerance_table(which, request):
    out, pdf = request.getfixturevalue(which)
    doc = json.loads((out / "report.json").read_text())
    page1 = page_text(pdf, 1)
    flat = re.sub(r"\s+", "", page1)
    assert "Tolerance report: tripteor_x7" in page1
    title = doc["title"]
    assert title["template"] == "templates/tripteor_x7.py" and "templates/tripteor_x7.py" in page1
    assert title["source_sha256"] == hashlib.sha256((TEMPLATES / "tripteor_x7.py").read_bytes()).hexdigest()
    assert title["source_sha256"] in re.sub(r"\s+", "", page_text(pdf, 1, layout=False))
    assert title["hyperstat_version"] == version("hyperstat") and f"hyperstat {version('hyperstat')}" in \
        re.sub(r"\s+", " ", page1)
    assert re.fullmatch(r"\d{4}-\d{2}-\d{2}", title["date"]) and title["date"] in page1
    assert "revision" in page1 and title["revision"] == ("B" if which == "full_report" else "-")
    assert "depth = 800" in page1 and "position ± 0.05 mm" in page1
    for t in doc["tolerances"]["items"][:8]:
        assert t["id"] in page1 and t["statement"].replace(" ", "") in flat
    for cls, n in doc["summary"]["tolerance_classes"].items():
        assert re.search(rf"{n}\s+{cls}", page1), cls
    assert re.search(r"± \d\S* (mm|rad)", page1)
    rows = set(re.findall(r"^\s*(T\d+)\s", page1, flags=re.M))  # the tolerances whose table row is on page 1
    if which == "full_report":  # both values of a compensable tolerance, and the frames of the others
        comp = next(t for t in doc["tolerances"]["items"] if t["class"] == "compensable"
                    and t["value_with_calibration"] is not None and t["id"] in rows)
        from hyperstat.cad_plugin.report_words import tolerance_value

        row = next(ln for ln in page1.splitlines() if re.match(rf"\s*{comp['id']}\s", ln))
        assert tolerance_value(comp) in row and tolerance_value(comp, "value_with_calibration") in row
        frames = [c for t in doc["tolerances"]["items"] if t["id"] in rows for c in t["drawing"]]
        assert frames and all(f"{c['zone']:.3g}" in flat for c in frames)


def test_printed_values_are_rounded_to_the_safe_side(full_report):
    from hyperstat.cad_plugin.report_words import safe_round

    out, _ = full_report
    doc = json.loads((out / "report.json").read_text())
    page = (out / "report.html").read_text()
    for t in doc["tolerances"]["items"]:
        if t["value"] is None:
            continue
        shown = safe_round(t["value"])
        assert 0 <= t["value"] - shown < 0.01 * t["value"] and f"± {shown:.3g} {t['unit']}" in page


@pytest.mark.parametrize("which", ["full_report", "plain_report"])
def test_skeleton_callouts_print_at_8_pt_and_call_out_every_tolerance(which, request):
    out, pdf = request.getfixturevalue(which)
    doc = json.loads((out / "report.json").read_text())
    words = json.loads((out / "skeleton_views.png.json").read_text())
    page = next(p for p in range(1, pages_of(pdf) + 1) if "Skeleton and tolerances" in page_text(pdf, p))
    runs = text_runs(pdf, page)
    drawn = set(words["callouts"]) | {f.split(" ")[0] for f in words["frames"]}
    largest: dict = {}
    for t, size in runs:  # a frame's label (T3) may also be a 7 pt table cell on the same page
        largest[t.strip()] = max(size, largest.get(t.strip(), 0))
    assert drawn <= set(largest) and len(drawn) > 3  # every callout is text on the printed page
    assert min(largest[t] for t in drawn) >= 8, sorted((largest[t], t) for t in drawn)[:5]
    shown = set()
    for line in words["callouts"]:
        for a, b in re.findall(r"T(\d+)(?:-T(\d+))?", line):
            shown |= {f"T{k}" for k in range(int(a), int(b or a) + 1)}
    ids = {t for p in doc["tolerances"]["parameters"].values() for t in p.get("tolerance_ids") or []}
    assert shown == ids  # every tolerance that sits on a joint is called out, none invented
    if doc.get("drawings"):  # the frames are on the part drawings' pages (test below), the skeleton shows the ids
        assert words["frames"] == [] and not any("datum" in line for line in words["callouts"])
    elif which == "full_report":
        drawn = [c for t in doc["tolerances"]["items"] for c in t["drawing"]]
        assert len(words["frames"]) == len(drawn) > 0
        zones = {f"{c['zone']:.3g}" for c in drawn}
        printed = {w.lstrip("\u2300") for t, size in runs if size >= 8 for w in t.split()}
        assert zones <= printed, zones - printed


def test_the_report_speaks_in_words(full_report):
    out, pdf = full_report
    doc = json.loads((out / "report.json").read_text())
    page = (out / "report.html").read_text()
    text = " ".join(page_text(pdf, p) for p in range(1, pages_of(pdf) + 1))
    body = re.sub(r"<[^>]+>", " ", re.sub(r"<svg.*?</svg>", " ", page.split("</style>", 1)[1], flags=re.S))
    md = (out / "report.md").read_text()
    assert not re.search(r"\bum\b", body + md) and "µm" in body and "µm" in md  # µm, never um
    assert "0 to 10 µm" in body  # the clearances' own words too
    for section in SECTIONS:
        assert f'<section id="{section}">' in page
    glossary = page[page.index('<section id="glossary">'):]
    for name in doc["accuracy"]["coefficients"]:
        assert f"<dt>{name}</dt>" in glossary
    for term in ("\u0394BIC", "CV RMS", "gap test", "n.s.", "Tn", "feature control frame", "with calibration"):
        assert f"<dt>{html.escape(term)}</dt>" in glossary, term
    assert not re.search(r"\b\d+=\d", body)  # no raw joint coordinates: where in words, with units
    # significance marks on every identified estimate
    from hyperstat.cad_plugin.report_words import significance

    for p in doc["identification"]["parameters"]:
        if p["identifiable"]:
            row = re.search(rf"<td>{re.escape(p['name'])}</td>.*?</tr>", page).group(0)
            assert f"<td>{html.escape(significance(p['estimate'], p['std']))}</td>" in row
    marks = {significance(p["estimate"], p["std"]) for p in doc["identification"]["parameters"] if p["identifiable"]}
    assert "n.s." in marks and "**" in marks
    # Monte Carlo contributors: tolerances by id, actuator errors in their own group
    mc = page[page.index('<section id="montecarlo">'):page.index('<section id="calibration">')]
    tol_part, act_part = mc.split("Contributors: actuator errors")
    assert not re.search(r"<tr><td>\d+</td>", mc)  # no contributor by a bare number
    ids = {t["id"] for t in doc["tolerances"]["items"]}
    assert re.findall(r"<tr><td>(T\d+) ", tol_part) and set(re.findall(r"<tr><td>(T\d+) ", tol_part)) <= ids
    actuated = [c["parameter"] for c in doc["montecarlo"]["contributors"] if c["parameter"] not in ids]
    assert actuated and all(f"actuator of joint {a}" in act_part for a in actuated)
    assert "Tripteor" in text


def test_markdown_and_json_say_the_same(full_report):
    out, _ = full_report
    doc = json.loads((out / "report.json").read_text())
    md = (out / "report.md").read_text()
    page = (out / "report.html").read_text()
    for a in doc["assembly_conditions"]:
        assert f"* {a['id']}: {a['statement']}" in md and a["statement"] in page
    for cls, n in doc["summary"]["tolerance_classes"].items():
        assert f"* {cls}: {n}" in md
    classes = [p["class"] for j in doc["joints"] for p in j["parameters"]]
    assert len(classes) == doc["summary"]["parameters"] == 87
    assert doc["diagnosis"]["selected"][0] == "backlash"
    d = doc["diagnosis"]  # the confidence and its reasons reach the reader of the Markdown and the HTML
    assert f"answer: {d['outcome']} (confidence {d['confidence']})" in md
    assert f"(confidence <b>{d['confidence']}</b>)" in page
    assert d["verdict"]["evidence"] in md
    assert doc["identification"]["validation"]["rms"] <= 1.3 * doc["identification"]["noise_rms"]
    for r in doc["relations"]:
        assert r["mathml"].startswith("<math")
    for t in doc["tolerances"]["items"]:
        assert f"| {t['id']} |" in md and f'<td class="nw">{t["id"]}</td>' in page
        for c in t["drawing"]:
            assert c["frame"].replace("|", "\\|") in md  # escaped in the Markdown table: the cell stays whole
        if t["bounds"]:
            b = t["bounds"]
            text = f"attainable linear worst case {b['attainable_linear_worst_case']:.3g} mm, triangle bound"
            assert text in md and text in page


def test_every_tolerance_of_the_json_is_in_the_html(plain_report):
    out, _ = plain_report
    doc = json.loads((out / "report.json").read_text())
    page = (out / "report.html").read_text()
    assert not re.search(r"(src|href)=\"(https?:)?//", page)  # nothing loaded from the network
    assert "{&quot;" not in page and '{"' not in page.split("</style>", 1)[1]  # no raw JSON anywhere
    from hyperstat.cad_plugin.report_words import tolerance_value

    items = doc["tolerances"]["items"]
    assert len(items) == sum(doc["summary"]["tolerance_classes"].values()) > 50
    for t in items:
        row = page[page.index(f'<tr><td class="nw">{t["id"]}</td>'):]
        row = row[: row.index("</tr>")]
        assert html.escape(t["statement"]) in row and t["class"] in row and tolerance_value(t) in row


def test_report_is_deterministic_and_prints_no_absolute_path(tmp_path, monkeypatch, no_cache):
    """Two runs computed from scratch (no cache) give the same bytes."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")  # 2026-01-01
    outside = tmp_path / "designs" / "my_crank.py"  # a template outside the repository
    outside.parent.mkdir()
    shutil.copy(TEMPLATES / "slider_crank.py", outside)
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        assert main(["report", str(outside), "--out", str(out), "--quiet"]) == 0
    for name in ("report.json", "report.md", "report.html", "skeleton_views.png"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    # --json-only (the FreeCAD workbench's Analyse): the same report.json, nothing else drawn or written
    c = tmp_path / "c"
    assert main(["report", str(outside), "--out", str(c), "--quiet", "--json-only"]) == 0
    assert sorted(p.name for p in c.iterdir()) == ["report.json"]
    assert (c / "report.json").read_bytes() == (a / "report.json").read_bytes()
    doc = json.loads((a / "report.json").read_text())
    assert doc["title"]["date"] == "2026-01-01" and doc["title"]["template"] == "my_crank.py"
    for name in ("report.json", "report.md", "report.html"):
        assert str(tmp_path) not in (a / name).read_text(), name
    # the task-restricted worst case and the full coefficient carry the same name: the report says why they differ
    md = (a / "report.md").read_text()
    full = doc["accuracy"]["coefficients"]["epsilon_gR"]["max"]
    task = next(w["max"] for w in doc["worst_cases"] if w["coefficient"] == "epsilon_gR")
    assert abs(full - task) > 1 and f"epsilon_gR {task:.3g} (task) and {full:.3g} (all components)" in md


def test_a_bad_date_is_one_sentence(tmp_path, capsys):
    assert main(["report", str(TEMPLATES / "slider_crank.py"), "--out", str(tmp_path / "r"), "--date", "26/11/2026",
                 "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--date '26/11/2026'" in err and err.count("\n") == 1 and not (tmp_path / "r" / "report.html").exists()


def test_each_part_drawing_prints_on_its_own_page_legible_at_8_pt(plain_report):
    """Issue 36, item 8: every part drawing of report.json starts its own A4 page, where its frames (ids, zones) and
    datum letters are real text of at least 8 pt; a page never holds two parts; a part takes at most two pages
    (a part with many frames continues its table)."""
    out, pdf = plain_report
    doc = json.loads((out / "report.json").read_text())
    drawings = doc["drawings"]
    assert len(drawings) >= 10  # the Tripteor's parts: base, crosses, legs, platform, wrist
    pages = pages_of(pdf)
    start = first_part_page(pdf, "Part drawing:")
    texts = {p: page_text(pdf, p, layout=False) for p in range(start, pages + 1)}
    heads = {p: m.group(1) for p, t in texts.items() if (m := re.match(r"\s*Part drawing: (\S+)", t))}
    assert list(heads.values()) == [d["part"] for d in drawings]  # in order, each once, each at a page's top
    owner, part = {}, None
    for p in range(start, pages + 1):
        part = heads.get(p, part)
        owner.setdefault(part, []).append(p)
    assert max(len(v) for v in owner.values()) <= 2, owner
    ids = {d["part"]: {f["id"] for f in d["frames"]} for d in drawings}
    for d in drawings:
        first = owner[d["part"]][0]
        text = " ".join(texts[p] for p in owner[d["part"]])
        sizes: dict = {}
        for t, size in text_runs(pdf, first):
            for word in t.split():
                sizes[word.strip(",;()")] = max(size, sizes.get(word.strip(",;()"), 0))
        for f in d["frames"]:
            assert sizes.get(f["id"], 0) >= 8, (d["part"], f["id"], sizes.get(f["id"]))
            assert f"{f['zone_mm']:.3g}" in text, (f["id"], f["zone_mm"])
        for letter in {x["letter"] for x in d["datums"]}:
            assert sizes.get(letter, 0) >= 8, (d["part"], letter)
        others = {i for part, frames in ids.items() if part != d["part"] for i in frames}
        for p in owner[d["part"]]:
            assert not {w for w in re.findall(r"[\w-]+-F\d+", texts[p])} & others, (d["part"], p)
    md = (out / "report.md").read_text()
    for d in drawings:
        assert f"### Part drawing: {d['part']}" in md
        assert all(f"| {f['id']} " in md for f in d["frames"])


def test_a_second_report_reads_the_diagnosis_from_the_cache_and_writes_the_same_json(full_report, tmp_path,
                                                                                      monkeypatch):
    """The full report's diagnosis (the session's cache holds it) is read, not computed, by a second report of the
    same model and data files (``--json-only``: about 3 s), and its report.json is the first one's, byte for byte."""
    import hyperstat.solver.diagnosis.diagnose as diagnose_module
    import hyperstat.solver.export.report_content as content

    out, _ = full_report
    real = content.report_document
    monkeypatch.setattr(content, "report_document", lambda *a, **k: with_contract_fields(real(*a, **k)))

    def not_again(*args, **kwargs):
        raise AssertionError("the diagnosis was computed again")

    monkeypatch.setattr(diagnose_module, "diagnose", not_again)
    data = out.parent / "d.csv"
    again = tmp_path / "again"
    assert main(["report", str(TEMPLATES / "tripteor_x7.py"), "--data", str(data), "--validation",
                 str(out.parent / "d.validation.csv"), "--hypotheses", str(TEMPLATES / "tripteor_x7.hypotheses.yaml"),
                 "--out", str(again), "--revision", "B", "--quiet", "--json-only"]) == 0
    assert (again / "report.json").read_bytes() == (out / "report.json").read_bytes()
    # other data (one measurement changed): not the stored diagnosis
    lines = data.read_text().splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith("P1,"))
    cells = lines[i].split(",")
    cells[6] = repr(float(cells[6]) + 1e-6)  # the first pose's x, 1 nm further
    changed = tmp_path / "d.csv"
    changed.write_text("\n".join(lines[:i] + [",".join(cells)] + lines[i + 1:]) + "\n")
    with pytest.raises(AssertionError, match="computed again"):
        main(["report", str(TEMPLATES / "tripteor_x7.py"), "--data", str(changed), "--validation",
              str(out.parent / "d.validation.csv"), "--out", str(tmp_path / "other"), "--quiet", "--json-only"])


def test_a_second_report_of_the_same_model_draws_the_skeleton_views_from_the_cache(tmp_path, monkeypatch):
    """The skeleton views and their drawing are kept per model and analysis: a report run again on the same model
    renders nothing (the renderer made to fail proves it) and writes the same files, byte for byte, as the first and
    as a run without the cache; another model (a changed parameter) is another entry, rendered."""
    import hyperstat.cad_plugin.report as report_module

    cache = tmp_path / "cache"
    monkeypatch.setenv("HYPERSTAT_CACHE", str(cache))
    source = str(TEMPLATES / "slider_crank.py")

    def run(out: str, *extra: str) -> dict:
        assert main(["report", source, "--out", str(tmp_path / out), "--date", "2026-01-01", "--quiet", *extra]) == 0
        return {p.name: p.read_bytes() for p in (tmp_path / out).iterdir()}

    first = run("first")
    assert len(list((cache / "skeleton-views").rglob("*.json"))) == 1
    fresh = run("fresh", "--no-cache")

    def no_rendering(*args, **kwargs):
        raise AssertionError("the skeleton views were rendered again")

    monkeypatch.setattr(report_module, "skeleton_views", no_rendering)  # the forked child inherits it too
    again = run("again")
    assert again == first == fresh
    with pytest.raises(AssertionError, match="rendered again"):
        run("other", "-p", "L1=41")
    monkeypatch.undo()
    monkeypatch.setenv("HYPERSTAT_CACHE", str(cache))
    run("other", "-p", "L1=41")
    assert len(list((cache / "skeleton-views").rglob("*.json"))) == 2


def test_the_title_block_flags_a_calibration_hyperstat_cannot_run(plain_report):
    """The Tripteor declares a registered tracker frame; hyperstat identify fits it: the classification's warning is
    printed whole in the title block's calibration line on page 1, once (tests/solver/tolerances/
    test_calibration_campaign.py measures it through the real commands)."""
    out, pdf = plain_report
    doc = json.loads((out / "report.json").read_text())
    fitted = doc["tolerances"]["calibration"]["as_identify_fits"]
    assert fitted["worse"] and "the tracker frame registered on references of the base" in fitted["declared_holds"]
    warning = next(w for w in doc["tolerances"]["warnings"] if w.startswith("CALIBRATION CAMPAIGN: "))
    first = " ".join(page_text(pdf, 1, layout=False).split())
    tail = warning[len("CALIBRATION CAMPAIGN: "):]
    assert "WARNING: " + tail[:60] in first and f"{fitted['position_mm']:.3g} mm" in first
    whole = " ".join(page_text(pdf, p, layout=False) for p in range(1, pages_of(pdf) + 1))
    assert " ".join(whole.split()).count(tail[:60]) == 1
