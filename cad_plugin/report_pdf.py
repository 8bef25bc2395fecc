"""The tolerance report printed on A4 as a PDF, by headless Chromium (the browser the report is laid out for).

Units: the report's (lengths mm, angles rad); the page is A4 with 12 mm margins (the report's print style).

Chromium is used rather than a Python HTML renderer because the report's print style (``@page``, flex boxes,
inline SVG frames, the break rules of every table) is written for and tested with it (``tests/cad_plugin/
test_report.py``): a second layout engine would print another document.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from hyperstat.solver.errors import HyperstatError

__all__ = ["chromium", "print_pdf"]

#: headless printing, no profile or network side effects (as root, Chromium needs --no-sandbox)
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-pdf-header-footer")


def chromium() -> str:
    """The Chromium executable, or one sentence saying how to get it.

    >>> isinstance(chromium(), str)
    True
    """
    exe = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if not exe:
        raise HyperstatError("--pdf: Chromium is not installed (Debian: apt-get install chromium; 'make setup "
                             "system-deps' installs it); the HTML report prints on A4 from any browser.")
    return exe


def print_pdf(html: str, timeout: float = 300.0) -> bytes:
    """The bytes of the PDF Chromium prints (A4) from the self-contained report ``html``.

    Printed in a temporary folder outside the output directory: the caller writes the bytes with the
    report's other files, all of them or none.

    Raises
    ------
    HyperstatError
        When Chromium is missing, fails or prints no PDF.
    """
    exe = chromium()
    with tempfile.TemporaryDirectory(prefix="hyperstat-pdf-") as tmp:
        page, out = Path(tmp) / "report.html", Path(tmp) / "report.pdf"
        page.write_text(html, encoding="utf-8")
        try:
            run = subprocess.run([exe, *FLAGS, f"--user-data-dir={Path(tmp) / 'profile'}", f"--print-to-pdf={out}",
                                  page.as_uri()], capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise HyperstatError(f"--pdf: Chromium did not print the report within {timeout:.0f} s; nothing was "
                                 "written.") from None
        data = out.read_bytes() if out.is_file() else b""
        if data[:5] != b"%PDF-":
            last = (run.stderr.strip().splitlines() or ["no message"])[-1]
            raise HyperstatError(f"--pdf: Chromium printed no PDF (exit {run.returncode}: {last}); nothing was "
                                 "written.")
    return data
