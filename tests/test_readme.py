"""Every command the README shows is a valid command line of today's parser, on files that exist.

Each ``.venv/bin/hyperstat ...`` line of a README code block is parsed by the real parser
(an unknown option or a missing argument fails), and every input path it names exists in
the repository or is written by a command shown before it.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
LINES = [line.split("  #")[0].strip() for line in (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
         if line.startswith(".venv/bin/hyperstat ")]
OUTPUT_OPTIONS = {"--json", "--out", "--truth", "--markdown", "--model", "--step", "--png", "--hal", "--ini",
                  "--plots", "--validation-out", "--map-png"}


def test_the_readme_shows_commands():
    assert len(LINES) >= 10


def test_every_readme_command_parses_and_its_inputs_exist():
    from hyperstat.cad_plugin.cli import build_parser

    written: set[str] = set()
    for line in LINES:
        argv = shlex.split(line)[1:]
        if argv == ["--version"]:
            continue
        try:
            build_parser().parse_args(argv)
        except SystemExit as exc:  # argparse's way of saying no
            pytest.fail(f"README command does not parse ({exc.code}): {line}")
        outputs = {argv[i + 1] for i, a in enumerate(argv[:-1]) if a in OUTPUT_OPTIONS}
        for out in outputs:
            written |= {out, re.sub(r"\.csv$", ".validation.csv", out), out + ".json"}
        for arg in argv:
            if arg in outputs or arg.startswith("-") or "=" in arg or "/" not in arg or "://" in arg:
                continue
            assert (ROOT / arg).exists() or arg in written, f"{line}: '{arg}' is neither in the repository nor written before"


def test_the_command_table_lists_every_command():
    """The README's table of commands names every sub-command the parser has (none forgotten)."""
    from hyperstat.cad_plugin.cli import build_parser

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    table = text.split("### All commands", 1)[1].split("\n\n", 2)[1]
    listed = set(re.findall(r"^\| `([a-z-]+)", table, flags=re.M)) | set(re.findall(r"/ `([a-z-]+)[` ]", table))
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert set(sub.choices) <= listed, sorted(set(sub.choices) - listed)
