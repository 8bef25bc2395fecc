"""The tolerance report printed on A4 as a PDF, by headless Chromium (the browser the report is laid out for).

Units: the report's (lengths mm, angles rad); the page is A4 with 12 mm margins (the report's print style).

Chromium is used rather than a Python HTML renderer because the report's print style (``@page``, flex boxes,
inline SVG frames, the break rules of every table) is written for and tested with it (``tests/cad_plugin/
test_report.py``): a second layout engine would print another document.
"""

from __future__ import annotations

import os
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


def print_pdf(html: str | os.PathLike, pdf: str | os.PathLike, timeout: float = 300.0) -> Path:
    """Print ``html`` to ``pdf`` (A4), written to a temporary file beside it, then renamed.

    Raises
    ------
    HyperstatError
        When Chromium is missing, fails or writes no PDF (nothing is left at ``pdf``).
    """
    html, pdf = Path(html), Path(pdf)
    exe = chromium()
    with tempfile.TemporaryDirectory(prefix=".pdf-", dir=pdf.parent) as tmp:
        out = Path(tmp) / "report.pdf"
        try:
            run = subprocess.run([exe, *FLAGS, f"--user-data-dir={Path(tmp) / 'profile'}", f"--print-to-pdf={out}",
                                  html.resolve().as_uri()], capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise HyperstatError(f"{pdf}: not written: Chromium did not print {html.name} within {timeout:.0f} s.") \
                from None
        if not out.is_file() or out.read_bytes()[:5] != b"%PDF-":
            last = (run.stderr.strip().splitlines() or ["no message"])[-1]
            raise HyperstatError(f"{pdf}: not written: Chromium printed no PDF of {html.name} (exit {run.returncode}: "
                                 f"{last}).")
        os.replace(out, pdf)
    return pdf
