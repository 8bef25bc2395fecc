"""Stationarity of planar four-bar loops against the mobile spatial linkages they border.

Units: mm, rad.  Every expected value is derived here, from geometry:

* a planar 4R loop stays mobile when its four axes stay parallel (a tilted plane, two
  directions), when the rocker frame slides along the last axis in both chains (one
  direction), and when the axes meet at one apex (the spherical four-bar, one direction);
* an isogram (opposite links equal) is moreover the limit of the Bennett linkage, twists
  ``alpha`` on the 100 mm links and ``beta`` on the 300 mm links with
  ``sin(alpha)/a = +-sin(beta)/b``, for the signs whose Denavit-Hartenberg loop closes near
  the isogram's assembly mode (solved here by scipy, not by hyperstat);
* in-plane defects (``da``, ``db``) keep the loop planar, hence mobile.

Each family is built as exact finite defects of the model file
(``tests/solver/kinematics/fourbar.py``), re-assembled by hyperstat at many crank angles
(round-off residual expected), and its tangent (central difference) spans, with the in-plane
directions, the admissible subspace the analysis must find: its dimension, and the forced
parameters (those orthogonal to it), follow.  Twists proportional to the link lengths on a
crank-rocker (a Bennett pattern without the equal opposite links) must not re-assemble.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.cli import main
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.modelfile import load_model
from tests.solver.kinematics.fourbar import (
    bennett_axes,
    defects_from_axes,
    fourbar_angles,
    planar_points,
    spherical_axes,
    write_fourbar,
)

ISOGRAM = (100.0, 300.0, 100.0, 300.0)
CRANK_ROCKER = (40.0, 120.0, 80.0, 100.0)
LOWER = (-np.pi, 0.0)
FULL = (-np.pi, np.pi)
# joints 1, 2, 4 are revolutes followed by an element with a, b, c: their along-axis shift is a gauge
ALONG_AXIS = (("dc1", "dc2"), ("dc2", "dc3"), ("dc4", "dc5"))


class Loop:
    """A four-bar model file and its exact defected neighbours."""

    def __init__(self, tmp_path, dims, sigma, crank_range, home, name="loop"):
        self.dims, self.sigma, self.range, self.home = dims, sigma, crank_range, home
        self.path = write_fourbar(tmp_path / f"{name}.json", *dims, home, sigma, crank_range, name=name)
        self.m = load_model(self.path)
        self.kin = Kinematics(self.m)
        self.q = fourbar_angles(*dims, home, sigma)[0]
        self.points = planar_points(*dims, self.q)

    def xi(self, defects: dict) -> np.ndarray:
        out = np.zeros(self.kin.n_xi)
        for name, value in defects.items():
            out[self.m.parameter_index[name]] = value
        return out

    def from_axes(self, points, axes) -> np.ndarray:
        return self.xi(defects_from_axes(*self.dims, self.q, points, axes)["defects"])

    def parallel(self, tx: float, ty: float) -> np.ndarray:
        n = np.array([tx, ty, 1.0]) / np.linalg.norm([tx, ty, 1.0])
        return self.from_axes(self.points, [n] * 4)

    def spherical(self, inverse_height: float) -> np.ndarray:
        apex = np.array([60.0, 30.0, 1.0 / inverse_height])
        return self.from_axes(self.points, spherical_axes(self.points, apex))

    def bennett(self, alpha: float, sign: int) -> np.ndarray:
        a, b = self.dims[0], self.dims[1]
        beta = np.arcsin(sign * (b / a) * np.sin(alpha))
        pts = self.points
        heading = [np.arctan2(*(pts[(i + 1) % 4] - pts[i])[1::-1]) for i in range(4)]
        turns = [np.angle(np.exp(1j * (heading[i] - heading[i - 1]))) for i in range(4)]  # turn at each pivot
        points, axes = bennett_axes(a, b, alpha, beta, turns[0], turns[1:], start_heading=heading[3])
        return self.from_axes(points, axes)

    def gauge_fixed(self, xi: np.ndarray) -> np.ndarray:
        """First-order equivalent with the along-axis shifts moved to the next element (dimensionless)."""
        v = xi.copy()
        idx = self.m.parameter_index
        for gauge, nxt in ALONG_AXIS:
            v[idx[nxt]] += v[idx[gauge]]
            v[idx[gauge]] = 0.0
        assert all(abs(v[idx[f"dK{e}"]]) < 1e-12 for e in "12345")  # normalisation gauge untouched
        return v / self.kin.parameter_scale

    def tangent(self, family, h: float, *args) -> np.ndarray:
        return self.gauge_fixed((family(h, *args) - family(-h, *args)) / (2 * h))

    def bennett_signs(self) -> list[int]:
        signs = []
        for sign in (1, -1):
            try:
                self.bennett(0.02, sign)
            except ValueError:
                continue
            signs.append(sign)
        return signs

    def expected_subspace(self) -> tuple[np.ndarray, list[str]]:
        """Orthonormal basis of the derived admissible subspace and the families in it."""
        cols, names = [], []
        for p in self.m.parameters:
            if p.component in "ab":
                e = np.zeros(self.kin.n_xi)
                e[self.m.parameter_index[p.name]] = 1.0
                cols.append(e)
        cols.append(self.tangent(lambda h: self.parallel(h, 0.0), 1e-6))
        cols.append(self.tangent(lambda h: self.parallel(0.0, h), 1e-6))
        cols.append(self.gauge_fixed(self.xi({"dc3": 1.0, "dc5": 1.0})))
        cols.append(self.tangent(self.spherical, 1e-7))
        names += ["tilted plane x", "tilted plane y", "common height", "spherical"]
        if self.dims[0] == self.dims[2] and self.dims[1] == self.dims[3]:
            for sign in self.bennett_signs():
                cols.append(self.tangent(lambda h, s=sign: self.bennett(h, s), 1e-4))
                names.append(f"Bennett {'+' if sign > 0 else '-'}")
        mat = np.array(cols).T
        u, s, _ = np.linalg.svd(mat, full_matrices=False)
        rank = int(np.sum(s > 1e-6 * s[0]))
        return u[:, :rank], names

    def crank_angles(self, n: int = 13) -> np.ndarray:
        lo, hi = self.range
        return np.linspace(lo + 0.3, hi - 0.3, n)[:, None]  # clear of the flat points of the neighbours too

    def reassembly(self, xi: np.ndarray) -> float:
        """Largest closure residual (mm) after certified continuation from home with defects ``xi``."""
        res = self.kin.solve(self.crank_angles(), xi)
        assert res.certificate.certified.all(), res.certificate.summary()
        return float(np.max(res.residual))


def _largest_angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.arcsin(min(1.0, np.linalg.norm(b - a @ (a.T @ b), 2))))


GEOMETRIES = [
    ("crossed isogram", ISOGRAM, +1, LOWER, -1.2),
    ("parallelogram", ISOGRAM, -1, LOWER, -1.2),
    ("crank-rocker, open", CRANK_ROCKER, +1, FULL, 0.5),
    ("crank-rocker, crossed", CRANK_ROCKER, -1, FULL, 0.5),
]


@pytest.mark.parametrize("label, dims, sigma, crank_range, home", GEOMETRIES)
def test_exact_mobile_neighbours_reassemble_to_round_off(tmp_path, label, dims, sigma, crank_range, home):
    loop = Loop(tmp_path, dims, sigma, crank_range, home)
    floor = 1e-9 * loop.kin.length_scale
    assert loop.reassembly(loop.spherical(1.0 / 5000.0)) < floor  # apex 5 m above the plane
    assert loop.reassembly(loop.parallel(0.01, -0.02)) < floor
    if dims == ISOGRAM:
        signs = loop.bennett_signs()
        assert len(signs) == 1  # one Bennett linkage borders each isogram mode; the other sign does not close
        assert loop.reassembly(loop.bennett(0.02, signs[0])) < floor


def test_the_two_isogram_modes_border_bennett_linkages_of_opposite_signs(tmp_path):
    crossed = Loop(tmp_path, ISOGRAM, +1, LOWER, -1.2, name="crossed").bennett_signs()
    parallel = Loop(tmp_path, ISOGRAM, -1, LOWER, -1.2, name="parallel").bennett_signs()
    assert len(crossed) == len(parallel) == 1 and crossed[0] == -parallel[0]


def test_twists_proportional_to_the_links_do_not_reassemble_a_crank_rocker(tmp_path):
    loop = Loop(tmp_path, CRANK_ROCKER, +1, FULL, 0.5)
    a, b, c, d = CRANK_ROCKER

    def twists(k):  # each axis tilted about its link's direction by k * length (rad)
        return loop.xi({"dJ2": k * a, "dJ3": k * b, "dJ5": k * c, "dJ4": k * d})

    big, small = loop.reassembly(twists(1e-5)), loop.reassembly(twists(1e-6))
    assert big > 1e-3 * (1e-5 * d) * loop.kin.length_scale  # of the order of the defect, not round-off
    assert 8.0 < big / small < 12.0  # first order in the defect


@pytest.mark.parametrize("label, dims, sigma, crank_range, home", GEOMETRIES)
def test_admissible_subspace_is_spanned_by_the_mobile_neighbours(tmp_path, label, dims, sigma, crank_range, home):
    loop = Loop(tmp_path, dims, sigma, crank_range, home)
    expected, families = loop.expected_subspace()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(loop.m, kinematics=loop.kin, samples=2)
    assert result.stable, result.stability["summary"]
    got = result.admissible_basis
    assert got.shape[1] == expected.shape[1], (families, got.shape[1])
    assert _largest_angle(expected, got) < 1e-6
    # dimension: the 10 in-plane shifts plus one direction per independent family
    n_out = expected.shape[1] - 10
    assert n_out == (5 if dims == ISOGRAM else 4)
    n_active = sum(p.verdict != "gauge" for p in result.parameters)
    assert n_active == 22 and result.rank == 12 - n_out  # 12 out-of-plane parameters: dI, dJ of 5, dc3, dc5
    # forced: the parameters orthogonal to the derived subspace (the twists about the links of a crank-rocker)
    gauges = {f"dK{e}" for e in "12345"} | {g for g, _ in ALONG_AXIS}
    assert set(result.by_verdict("gauge")) == gauges
    forced_expected = {p.name for j, p in enumerate(loop.m.parameters)
                       if p.name not in gauges and np.linalg.norm(expected[j]) < 1e-7}
    assert set(result.by_verdict("forced")) == forced_expected
    if dims == CRANK_ROCKER:
        assert forced_expected == {"dJ2", "dJ3", "dJ5"}
    else:
        assert forced_expected == set()
    assert set(result.by_verdict("free")) == {p.name for p in loop.m.parameters if p.component in "ab"}


HOMES = [
    ("crossed isogram", ISOGRAM, +1, LOWER, -0.12),
    ("crossed isogram", ISOGRAM, +1, LOWER, -np.pi + 0.28),
    ("crossed isogram", ISOGRAM, +1, LOWER, -1.9),
    ("parallelogram", ISOGRAM, -1, LOWER, -0.25),
    ("parallelogram", ISOGRAM, -1, LOWER, -np.pi + 0.2),
    ("crank-rocker, open", CRANK_ROCKER, +1, FULL, -2.5),
    ("crank-rocker, open", CRANK_ROCKER, +1, FULL, 1.7),
    ("crank-rocker, crossed", CRANK_ROCKER, -1, FULL, -0.4),
    ("crank-rocker, crossed", CRANK_ROCKER, -1, FULL, 2.9),
]


@pytest.mark.parametrize("label, dims, sigma, crank_range, home", HOMES)
def test_verdicts_do_not_depend_on_the_seed_or_the_home(tmp_path, label, dims, sigma, crank_range, home):
    loop = Loop(tmp_path, dims, sigma, crank_range, home)
    n_out = 5 if dims == ISOGRAM else 4
    forced = {"dJ2", "dJ3", "dJ5"} if dims == CRANK_ROCKER else set()
    for seed in range(20):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = analyze(loop.m, seed=seed, kinematics=loop.kin, samples=2)
        assert result.stable, (seed, result.stability["summary"])
        assert result.rank == 12 - n_out, seed
        assert set(result.by_verdict("forced")) == forced, seed
        assert result.stability["max_subspace_angle"] < 1e-6


def test_cli_says_stable_or_names_the_disagreement_and_exits_3(tmp_path, capsys):
    loop = Loop(tmp_path, ISOGRAM, +1, LOWER, -0.2, name="crossed")
    out = tmp_path / "a.json"
    assert main(["analyze", str(loop.path), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "stable across 2 independent samples" in text
    doc = json.loads(out.read_text())
    assert doc["stability"]["stable"] is True and doc["stability"]["samples"] == 2
    assert doc["stability"]["ranks"] == [7, 7]
    assert main(["analyze", str(loop.path), "--samples", "3", "--quiet"]) == 0
    assert capsys.readouterr().out == ""
    assert main(["analyze", str(loop.path), "--samples", "3"]) == 0
    assert "stable across 3 independent samples" in capsys.readouterr().out
    # one configuration per sample cannot fix the admissible subspace: the samples disagree
    out1 = tmp_path / "b.json"
    assert main(["analyze", str(loop.path), "--configurations", "1", "--json", str(out1), "--quiet"]) == 3
    err = capsys.readouterr().err
    assert "depends on the sample" in err and "seed 0 and seed 1" in err
    doc = json.loads(out1.read_text())
    assert doc["stability"]["stable"] is False and doc["stability"]["disagreements"]
    with pytest.raises(SystemExit) as exc:
        main(["analyze", str(loop.path), "--samples", "0"])
    assert exc.value.code == 2
    assert "--samples must be at least 1, got 0" in capsys.readouterr().err
