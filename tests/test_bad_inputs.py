"""The bad-input catalogue (tests/catalogue.py): one clear sentence, exit code 2, no traceback, no output.

Units: lengths in mm, angles in rad.
"""

from __future__ import annotations

import subprocess
import sys
import warnings

import pytest

from tests.catalogue import CASES, ROOT, clean, goods, markdown, run_case


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    base = tmp_path_factory.mktemp("catalogue")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        good = goods(base / "good")
        return {case.id: (run_case(case, base / case.id, good), base / case.id) for case in CASES}


def test_catalogue_is_large_and_distinct():
    assert len(CASES) >= 30
    assert len({c.id for c in CASES}) == len(CASES)
    assert len({c.kind for c in CASES}) >= 7


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input(results, case):
    (code, out, err, left), _ = results[case.id]
    assert code == 2, (code, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hyperstat: error: "), err
    assert case.names in err, err
    assert "Traceback" not in err + out
    assert left == [], f"output written: {left}"


def test_errors_doc_is_current(results):
    rows = [(case, clean(results[case.id][0][2], results[case.id][1])) for case in CASES]
    assert (ROOT / "docs" / "errors.md").read_text() == markdown(rows), \
        "docs/errors.md is stale: run '.venv/bin/python -m tests.catalogue docs/errors.md'"


def test_real_process_exit_code(tmp_path):
    """The console script, not only main(): exit status 2 and one line."""
    proc = subprocess.run([sys.executable, "-m", "hyperstat.cad_plugin.cli", "analyze", str(tmp_path / "absent.json")],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "absent.json" in proc.stderr
