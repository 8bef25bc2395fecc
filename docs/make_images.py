"""Regenerate the README's and the docs' pictures from the real commands (``make images``).

Units: lengths in mm, angles in rad.

Each picture ``docs/img/NAME.png`` gets a record ``docs/img/NAME.png.json``: the command that
drew it, the SHA-256 of the PNG, and the words it shows (legend, classes, callouts, view
names).  ``tests/test_docs_images.py`` fails when a committed picture no longer matches its
record, or was drawn with words the project no longer uses (a retired class name, a legend
that changed): the picture is then stale and ``make images`` draws it again.

* the templates' skeleton pictures: ``hyperstat analyze --json`` then ``hyperstat view --analysis
  --png --words`` (the words recorded by the command itself);
* the README's report picture: ``hyperstat report`` on the Tripteor, page 1 of ``report.html``
  shot by headless Chromium, the words from its ``report.json``;
* the accuracy maps of docs/accuracy.md: ``hyperstat accuracy --map-png``;
* the FreeCAD screenshots: ``make freecad-screenshot`` (the clicking test writes their records).

Run with the project's Python: ``.venv/bin/python docs/make_images.py [--only NAME ...]``.
"""

from __future__ import annotations

import argparse
import json
import shlex
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from hyperstat.cad_plugin.view import write_record

ROOT = Path(__file__).resolve().parent.parent
IMG = ROOT / "docs" / "img"
CLI = Path(sys.executable).parent / "hyperstat"
TEMPLATES = ["slider_crank", "tripteor_x7", "triflex_ii", "scara", "hexapod", "five_bar"]
ACCURACY = {
    "accuracy_triflex_ii": ["accuracy", "templates/triflex_ii.py", "--range", "1=-1.6:1.6", "--range", "5=-1.1:2.1",
                            "--range", "10=-0.65:2.45", "--map", "5,10", "--slice", "1=0", "--slice", "1=0.75",
                            "--slice", "1=-0.75", "--quiet"],
    "accuracy_tripteor_x7": ["accuracy", "templates/tripteor_x7.py", "--map", "41,42", "--quiet"],
}
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--hide-scrollbars"]


def run(args: list[str]) -> str:
    """Run ``hyperstat ARGS`` in the repository; return the command as written in the record."""
    subprocess.run([str(CLI), *args], cwd=ROOT, check=True)
    return "hyperstat " + " ".join(shlex.quote(a) for a in args)


def template_picture(name: str, tmp: Path) -> None:
    analysis = tmp / f"{name}.analysis.json"
    run(["analyze", f"templates/{name}.py", "--json", str(analysis), "--quiet"])
    png, words = IMG / f"{name}.png", tmp / f"{name}.words.json"
    command = run(["view", f"templates/{name}.py", "--analysis", str(analysis), "--png", str(png.relative_to(ROOT)),
                   "--words", str(words), "--quiet"])
    write_record(png, command.replace(str(analysis), f"out/{name}.analysis.json").replace(str(words), "WORDS.json"),
           json.loads(words.read_text(encoding="utf-8")))


def report_picture(tmp: Path) -> None:
    """Page 1 of the Tripteor report, as a reader opens it in a browser."""
    out = tmp / "report"
    command = run(["report", "templates/tripteor_x7.py", "--out", str(out), "--quiet"])
    png = IMG / "report_tripteor_x7.png"
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    subprocess.run([exe, *CHROMIUM_FLAGS, f"--user-data-dir={tmp / 'profile'}", "--window-size=1280,1500",
                    f"--screenshot={png}", (out / "report.html").as_uri()], check=True, capture_output=True)
    doc = json.loads((out / "report.json").read_text(encoding="utf-8"))
    from hyperstat.cad_plugin.palette import CLASS_LABELS

    counts = doc["summary"]["tolerance_classes"]
    write_record(png, command.replace(str(out), "out/report") + " (page 1 in Chromium, 1280 x 1500 px)",
           {"title": f"Tolerance report: {doc['mechanism']}", "classes": [c for c in CLASS_LABELS if c in counts],
            "legend": [f"{n} {c}" for c, n in counts.items()],
            "callouts": [t["id"] for t in doc["tolerances"]["items"]], "views": [], "frames": []})


def accuracy_picture(name: str) -> None:
    png = IMG / f"{name}.png"
    command = run([*ACCURACY[name], "--map-png", str(png.relative_to(ROOT))])
    write_record(png, command, {"title": name, "classes": [], "legend": [], "callouts": [], "views": [], "frames": []})


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", help="picture names (without .png) to draw; default all but FreeCAD's")
    args = parser.parse_args(argv)
    wanted = set(args.only or TEMPLATES + list(ACCURACY) + ["report_tripteor_x7"])
    IMG.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="hyperstat-images-") as tmp:
        for name in TEMPLATES:
            if name in wanted:
                template_picture(name, Path(tmp))
        for name in ACCURACY:
            if name in wanted:
                accuracy_picture(name)
        if "report_tripteor_x7" in wanted:
            report_picture(Path(tmp))
    return 0


if __name__ == "__main__":
    sys.exit(main())
