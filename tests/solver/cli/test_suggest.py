"""'Did you mean' for mistyped commands, options and template parameters: one sentence, exit code 2.

Units: none.  Runs the real ``hyperstat`` parser (solver and CAD commands) in-process.
"""

from __future__ import annotations

import pytest

from hyperstat.cad_plugin.cli import main

from tests.conftest import TEMPLATES

SC = str(TEMPLATES / "slider_crank.py")


def _refused(argv, capsys) -> str:
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    return capsys.readouterr().err


@pytest.mark.parametrize("typed, meant", [("analyse", "analyze"), ("reprot", "report"), ("Build", "build"),
                                          ("diagnosis", "diagnose"), ("montecarl", "montecarlo")])
def test_a_mistyped_command_names_the_closest(typed, meant, capsys):
    err = _refused([typed, SC], capsys)
    assert f"invalid choice: '{typed}'" in err and err.rstrip().endswith(f"(did you mean '{meant}'?)")


def test_a_mistyped_option_is_reported_by_its_command_with_the_closest(capsys):
    err = _refused(["analyze", SC, "--josn", "x.json"], capsys)
    assert err.startswith("usage: hyperstat analyze")  # the sub-command's usage, not the top-level one
    assert "unrecognized arguments: --josn x.json (did you mean '--json'?)" in err
    err = _refused(["report", SC, "--outt", "d"], capsys)  # the required --out is missing because of the typo
    assert err.startswith("usage: hyperstat report") and "'--outt' is not an option (did you mean '--out'?)" in err


def test_nothing_close_adds_nothing(capsys):
    err = _refused(["frobnicate", SC], capsys)
    assert "did you mean" not in err and "invalid choice: 'frobnicate'" in err


def test_a_mistyped_template_parameter_names_the_closest(capsys):
    assert main(["analyze", str(TEMPLATES / "tripteor_x7.py"), "-p", "dpeth=850", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "unknown parameter 'dpeth' (did you mean 'depth'?)" in err and err.count("\n") == 1
