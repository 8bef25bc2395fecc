"""Issue 38's small things, each as a user meets it on the command line (in this process).

Units: lengths in mm, angles in rad.

* a bundled template's name (``tripteor_x7``, a corpus name such as ``bennett``) works in every command as in
  ``hs.load``;
* an angle given without its unit that is out of its bounds but would fit them in degrees is refused with a
  "did you mean ...deg" (never reinterpreted);
* ``analyze``'s text tables keep their columns apart and list tolerance ids in natural order;
* no "um" for micrometres in what the commands print.
"""

from __future__ import annotations

import re

import pytest

from tests.conftest import TEMPLATES, run_cli


@pytest.mark.parametrize("name", ["tripteor_x7", "bennett"])
def test_a_bundled_name_is_a_source(name, tmp_path):
    import hyperstat as hs

    code, out, err = run_cli(["analyze", name, "--json", tmp_path / "a.json", "--quiet"])
    assert code == 0, err
    assert hs.load(name).name == name
    assert run_cli(["parameters", name])[0] == 0
    assert run_cli(["build", name, "--model", tmp_path / "m.json", "--quiet"])[0] == 0


def test_an_unknown_name_is_one_sentence_with_the_closest():
    code, out, err = run_cli(["analyze", "bennet"])
    assert code == 2 and err.count("\n") == 1
    assert "(did you mean 'bennett'?)" in err and "tripteor_x7" in err


def test_an_angle_without_its_unit_gets_a_hint_not_a_reinterpretation():
    code, _, err = run_cli(["analyze", TEMPLATES / "slider_crank.py", "-p", "home_angle=30"])
    assert code == 2 and err.count("\n") == 1
    assert "must be <= 3.14159 rad, got 30; did you mean 30deg (0.5236 rad)?" in err
    # the hint only where degrees would fit the bounds; an angle in bounds is taken in rad, as written
    code, _, err = run_cli(["analyze", TEMPLATES / "slider_crank.py", "-p", "home_angle=400"])
    assert code == 2 and "did you mean" not in err
    assert run_cli(["analyze", TEMPLATES / "slider_crank.py", "-p", "home_angle=1.0", "--quiet"])[0] == 0


def _columns_apart(lines: list[str], header: str) -> None:
    """Every row's text under a column starts where the header's column starts, after a blank."""
    starts = [m.start() for m in re.finditer(r"(?<=  )\S", header)]
    for line in lines:
        for s in starts:
            if len(line) > s and line[s] != " ":
                assert line[s - 1] == " ", (line, s)


def test_analyze_text_columns_stay_apart_and_ids_read_in_order(tmp_path):
    """The Bennett linkage's long relations and long id lists: nothing runs together ('T9confirmed'), ids T2 < T10."""
    import json

    code, out, err = run_cli(["analyze", "bennett", "--verify", "--json", tmp_path / "a.json"])
    assert code == 0, err
    items = json.loads((tmp_path / "a.json").read_text())["tolerances"]["items"]
    lines = out.splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("element"))
    rows = lines[head + 2:lines.index("", head)]
    _columns_apart(rows, lines[head])
    col = lines[head].index("tolerance")
    check = lines[head].index("nonlinear check")
    for row in rows:
        ids = re.findall(r"T(\d+)", row[col:check].split("(")[0])
        assert [int(i) for i in ids] == sorted(int(i) for i in ids), row
        assert not re.search(r"T\d+confirmed", row)
    table = lines.index(next(line for line in lines if line.startswith("id ")))
    value = lines[table].index("value")
    firsts = [line for line in lines[table + 1:] if re.match(r"T\d+ ", line)]
    assert [line.split()[0] for line in firsts] == [t["id"] for t in items]  # one first line per tolerance
    for line in firsts:  # the statement (or its first part) ends two blanks before the value column
        assert line[value - 2:value] == "  ", line
        assert not re.search(r"= 0[-+]", line), line


def test_no_um_for_micrometres_in_what_commands_print(tmp_path):
    """µm, never 'um', in export-controller's and identify's printed lines (the tracker data of the slider-crank)."""
    data = tmp_path / "d.csv"
    assert run_cli(["simulate", TEMPLATES / "slider_crank.py", "--out", data, "--poses", "20", "--validation", "6",
                    "--quiet"])[0] == 0
    outputs = []
    for argv in (["identify", TEMPLATES / "slider_crank.py", data, "--validation", tmp_path / "d.validation.csv"],
                 ["export-controller", TEMPLATES / "slider_crank.py", data, "--validation",
                  tmp_path / "d.validation.csv", "--out", tmp_path / "m.json", "--force"]):
        code, out, err = run_cli(argv)
        outputs.append(out + err)
    text = "\n".join(outputs)
    assert "µm" in text and not re.search(r"\d um\b", text), text
