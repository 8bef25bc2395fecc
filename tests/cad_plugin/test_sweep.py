"""Design sweeps: serial and on a local Dask cluster, CSV table, bad input (units: mm, rad)."""

import csv
import math
import os

import pytest

from hyperstat.cad_plugin.cli import main
from hyperstat.cad_plugin.sweep import grid_variants, parse_grid, run_sweep
from tests.conftest import TEMPLATES

SLIDER = str(TEMPLATES / "slider_crank.py")
# L1 = 130 mm exceeds the rod (L2 = 120 mm): that variant cannot be built
GRID = {"L1": [40.0, 70.0, 100.0, 130.0], "home_angle": [0.5, 1.0]}


def _read(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_grid_values_and_units():
    from hyperstat.cad_plugin import load_template

    cls = load_template(SLIDER).Parameters
    grid = parse_grid(["L1=3cm:5cm:3", "home_angle=0deg:90deg:2"], cls)
    assert grid["L1"] == pytest.approx([30.0, 40.0, 50.0])
    assert grid["home_angle"] == pytest.approx([0.0, math.pi / 2])
    variants = grid_variants(grid, {"L2": 150.0})
    assert len(variants) == 6 and all(v["L2"] == 150.0 for v in variants)
    assert [v["home_angle"] for v in variants[:2]] == pytest.approx([0.0, math.pi / 2])  # last parameter fastest


def test_serial_sweep_table(tmp_path):
    out = tmp_path / "table.csv"
    code = main(["sweep", SLIDER, "--grid", "L1=40:130:4", "--grid", "home_angle=0.5:1.0:2", "--out", str(out),
                 "--quiet"])
    assert code == 0
    rows = _read(out)
    assert len(rows) == 8
    assert list(rows[0])[:3] == ["variant", "L1_mm", "home_angle_rad"]
    for r in rows:
        if float(r["L1_mm"]) >= 120.0:
            assert "'L2'" in r["error"] and r["rank"] == ""
            continue
        assert r["error"] == ""
        counts = [int(r[c]) for c in ("gauge", "forced", "coupled", "free")]
        assert sum(counts) == int(r["n_parameters"]) == 15
        assert int(r["free_influential"]) + int(r["free_non_influent"]) == int(r["free"])
        # one loop closed in space whose joint axes are all parallel (a planar loop): 4 joints,
        # mobility 1, so its 6 closure equations have rank 3 and 3 of them are redundant
        assert int(r["mobility"]) == 1 and int(r["overconstraint"]) == 3
        assert float(r["gap"]) > 1e6
        assert float(r["time_s"]) > 0


def test_sweep_on_a_local_dask_cluster_equals_the_serial_run():
    from distributed import Client, LocalCluster

    variants = grid_variants(GRID)
    serial = run_sweep(SLIDER, variants, progress=False)
    with LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        pids = set(client.run(os.getpid).values())
        assert len(pids) == 2 and os.getpid() not in pids  # two worker processes, not this one
        distributed = run_sweep(SLIDER, variants, progress=False, client=client)
    assert len(distributed) == len(serial) == 8
    for a, b in zip(serial, distributed):
        a, b = dict(a), dict(b)
        a.pop("time_s"), b.pop("time_s")
        assert a == b
    assert sum(bool(r["error"]) for r in serial) == 2


@pytest.mark.parametrize("args, message", [
    (["--grid", "L1=40:60"], "must read NAME=LOW:HIGH:COUNT"),
    (["--grid", "bogus=1:2:3"], "unknown parameter 'bogus'"),
    (["--grid", "L1=40:60:x"], "COUNT must be a whole number"),
    (["--grid", "L1=40:60:1"], "COUNT must be at least 2"),
    (["--grid", "L1=40kg:60:3"], "unit 'kg' is not accepted"),
    (["--grid", "L1=40:60:3", "-p", "L1=50"], "given both as --grid and as -p"),
    (["--grid", "L1=40:60:3", "--scheduler", "tcp://127.0.0.1:9"], "cannot reach the Dask scheduler"),
])
def test_bad_sweep_input_is_one_sentence_and_writes_nothing(tmp_path, capsys, args, message):
    out = tmp_path / "table.csv"
    assert main(["sweep", SLIDER, *args, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists() and not list(tmp_path.iterdir())


def test_sweep_output_must_be_csv(tmp_path, capsys):
    assert main(["sweep", SLIDER, "--grid", "L1=40:60:3", "--out", str(tmp_path / "t.parquet")]) == 2
    assert "ending in .csv" in capsys.readouterr().err


def test_montecarlo_columns(tmp_path):
    out = tmp_path / "t.csv"
    code = main(["sweep", SLIDER, "--grid", "L1=40:60:2", "--montecarlo", "--samples", "200", "--out", str(out),
                 "--quiet"])
    rows = _read(out)
    assert code == 0 and all(r["error"] == "" for r in rows), rows
    assert all(float(r["mc_position_max_mm"]) >= float(r["mc_position_p95_mm"]) >= 0 for r in rows)
