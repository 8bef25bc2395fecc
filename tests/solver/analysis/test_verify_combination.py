"""``--verify`` in combination: all admissible directions at once, and each relation violated inside them.

Units: mm, rad.  Expected orders come from the Taylor expansion of the closure: an admissible
defect leaves a residual of second order (or round-off for an exactly mobile family), a
violated relation a first-order residual equal to the linear prediction.

The exact closure (Gauss-Newton on the defects and all joints, the smallest correction ``c``)
is checked against what is known of the mobile linkages near each loop: a defect vector tangent
to one real family of assemblable mechanisms is within ``O(|u|^2)`` of it (``|c| / |u|`` falls
tenfold with the defect); an exact member of a family needs no correction; and, by the
classification of mobile 4R loops (planar, spherical, Bennett; Delassus), a Bennett twist on a
loop whose opposite links are made unequal is first order away from every mobile loop.
"""

from __future__ import annotations

import copy
import warnings

import numpy as np
import pytest

from hyperstat.solver.analysis.stationarity import Relation, analyze
from hyperstat.solver.analysis.verify import closing_correction, combination_checks, exact_closure_check, verify
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.modelfile import mechanism_from_dict
from tests.solver.analysis.test_fourbar import LOWER, Loop
from tests.solver.kinematics.fourbar import fourbar_document

EXACT = "combination admissible, closed exactly"

ISOGRAM = (100.0, 300.0, 100.0, 300.0)
CRANK_ROCKER = (40.0, 120.0, 80.0, 100.0)


def _analysed(dims, sigma, crank_range, home):
    m = mechanism_from_dict(fourbar_document(*dims, home, sigma, crank_range))
    kin = Kinematics(m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return m, kin, analyze(m, kinematics=kin)


@pytest.mark.parametrize("dims, sigma, crank_range, home", [
    (ISOGRAM, +1, (-np.pi, 0.0), -0.2),
    (ISOGRAM, -1, (-np.pi, 0.0), -2.9),
    (CRANK_ROCKER, +1, (-np.pi, np.pi), 0.5),
])
def test_combinations_are_confirmed_at_every_configuration(dims, sigma, crank_range, home):
    m, kin, res = _analysed(dims, sigma, crank_range, home)
    delta = 1e-4
    checks = combination_checks(m, res, delta=delta, kinematics=kin, seed=3)
    assert [c.kind for c in checks] == ["combination admissible", EXACT] + ["combination, relation violated"] * len(
        res.relations)
    exact = checks[1]
    checks = [c for c in checks if c is not exact]
    assert all(c.confirmed for c in checks), [(c.subject, c.note) for c in checks if not c.confirmed]
    lc = kin.length_scale
    adm = checks[0]
    assert f"all {res.admissible_basis.shape[1]} admissible directions" in adm.subject
    # second order: at most 100 delta^2 L, and ten times smaller defects leave ~100 times less (or round-off)
    assert adm.residual < 1e2 * delta ** 2 * lc
    assert adm.residual < 1e-9 * lc or adm.residual / adm.residual_small > 50
    for c in checks[1:]:  # first order, as predicted
        assert abs(c.residual - c.predicted) < 0.05 * c.predicted
        assert 8 < c.residual / c.residual_small < 12
    # closed exactly: round-off after the correction in every case
    assert exact.residual < 1e-12 * lc and exact.residual_small < 1e-12 * lc
    assert exact.uncorrected > 1e3 * exact.residual  # the plain re-assembly leaves a second-order gap
    if dims == CRANK_ROCKER:
        # one spherical family: the correction is second order (|c|/|u| tenfold smaller at a tenth)
        assert exact.confirmed, exact.note
        assert 8 < exact.correction / exact.correction_small < 12
        assert exact.correction < 1e-2
    else:
        # an isogram: the random vector changes the link lengths (in-plane defects) and carries a
        # Bennett twist; no mobile 4R loop has both, so the correction is first order: it removes the
        # twists (towards a planar loop) or the length changes that make opposite links unequal
        # (towards a Bennett loop), whichever is smaller for this vector, which depends on the sample
        assert not exact.confirmed
        assert 0.8 < exact.correction / exact.correction_small < 1.25
        assert "FIRST order" in exact.note
        on = exact.note.split("FIRST order")[1].split(":")[0]
        assert all(name.strip().startswith(("dJ", "dI", "da")) for name in on.split("on ")[1].split(",")), on


def _loop(tmp_path, sigma, home):
    loop = Loop(tmp_path, ISOGRAM, sigma, LOWER, home)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = analyze(loop.m, kinematics=loop.kin)
    return loop, res


@pytest.mark.parametrize("sigma, home", [(+1, -0.2), (-1, -2.9)])
def test_the_exact_bennett_linkage_needs_no_correction_and_its_tangent_a_second_order_one(tmp_path, sigma, home):
    loop, res = _loop(tmp_path, sigma, home)
    kin, q0, lc = loop.kin, res.configurations, loop.kin.length_scale
    sign = loop.bennett_signs()[0]
    # the finite Bennett linkage (sin(alpha)/a = +-sin(beta)/b), written as defects: it closes as it is
    xi = loop.bennett(2e-3, sign)
    exact = closing_correction(kin, q0, xi)
    assert exact.residual < 1e-12 * lc
    assert exact.correction < 1e-9
    # the Bennett family's tangent (central difference, error O(h^2) = 1e-8) at 1 mrad: closed exactly
    # by a second-order correction, |c|/|u| about the defect itself and tenfold smaller at a tenth
    u = loop.tangent(lambda h: loop.bennett(h, sign), 1e-4)
    check = exact_closure_check(loop.m, kin, q0, u / np.max(np.abs(u)))
    assert check.confirmed, check.note
    assert check.residual < 1e-12 * lc and check.residual_small < 1e-12 * lc
    assert 8 < check.correction / check.correction_small < 12
    assert check.correction < 10 * check.delta


@pytest.mark.parametrize("sigma, home", [(+1, -0.2), (-1, -2.9)])
def test_a_bennett_twist_with_unequal_opposite_links_needs_a_first_order_correction(tmp_path, sigma, home):
    loop, res = _loop(tmp_path, sigma, home)
    kin, q0 = loop.kin, res.configurations
    u = loop.tangent(lambda h: loop.bennett(h, loop.bennett_signs()[0]), 1e-4)
    u /= np.max(np.abs(u))
    assert np.linalg.norm(u - res.admissible_basis @ (res.admissible_basis.T @ u)) < 1e-6  # admissible
    length = np.zeros(kin.n_xi)
    length[loop.m.parameter_index["da2"]] = 1.0  # lengthens one link, not its opposite: no longer an isogram
    for w in (u + length, u):
        check = exact_closure_check(loop.m, kin, q0, w)
        assert check.residual < 1e-12 * kin.length_scale  # closed to round-off in both cases ...
        ratio = check.correction / check.correction_small
        if w is u:  # ... by a second-order correction on the Bennett family
            assert check.confirmed and 8 < ratio < 12
        else:  # ... by a first-order one with the link lengths unequal
            assert not check.confirmed and 0.8 < ratio < 1.25 and check.correction > 1e-2


@pytest.mark.parametrize("template", ["tripteor_x7", "five_bar", "hexapod", "triflex_ii", "scara"])
def test_every_template_closes_exactly_after_at_most_a_second_order_correction(template):
    import hyperstat as hs

    m = hs.load(template)
    kin = Kinematics(m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = analyze(m, kinematics=kin)
    check = next(c for c in combination_checks(m, res, kinematics=kin) if c.kind == EXACT)
    assert check.confirmed, check.note
    assert check.residual < 1e-12 * kin.length_scale and check.residual_small < 1e-12 * kin.length_scale
    # second order (tenfold smaller at a tenth of the defect) or none at all (no over-constraint left)
    assert check.correction < 1e-9 or 8 < check.correction / check.correction_small < 12


@pytest.mark.parametrize("template", ["slider_crank"])
def test_a_planar_mechanism_admissible_combination_assembles_as_it_is(template):
    import hyperstat as hs

    m = hs.load(template)
    kin = Kinematics(m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = analyze(m, kinematics=kin)
    checks = [c for c in combination_checks(m, res, kinematics=kin) if c.kind == EXACT]
    # the slider-crank's admissible defects are in-plane: every planar slider-crank assembles, exactly
    assert len(checks) == 1 and checks[0].confirmed, checks[0].note
    assert checks[0].correction < 1e-9 and checks[0].residual < 1e-12 * kin.length_scale


def test_a_forced_direction_slipped_into_the_admissible_basis_is_caught():
    m, kin, res = _analysed(CRANK_ROCKER, +1, (-np.pi, np.pi), 0.5)
    wrong = copy.copy(res)
    e = np.zeros((kin.n_xi, 1))
    e[m.parameter_index["dJ3"]] = 1.0  # a twist about the coupler: forced on a crank-rocker
    basis = np.hstack([res.admissible_basis, e])
    wrong.admissible_basis = np.linalg.qr(basis)[0]
    wrong.relations = []
    checks = combination_checks(m, wrong, kinematics=kin)
    assert len(checks) == 2 and not checks[0].confirmed
    assert checks[0].residual > 1e-3 * 1e-4 * kin.length_scale
    # closed exactly only by a first-order correction (the forced part is removed)
    assert checks[1].kind == EXACT and not checks[1].confirmed
    assert 0.8 < checks[1].correction / checks[1].correction_small < 1.25


def test_a_relation_that_does_not_exist_is_caught():
    m, kin, res = _analysed(ISOGRAM, +1, (-np.pi, 0.0), -0.2)
    wrong = copy.copy(res)
    # da1 and db2 are free (in-plane): a relation between them is not a condition of assembly
    wrong.relations = list(res.relations) + [Relation({"da1": 1.0, "db2": -1.0}, "da1 - db2 = 0")]
    checks = verify(m, wrong, kinematics=kin)
    fake = [c for c in checks if c.subject == "da1 - db2 = 0" and c.kind == "combination, relation violated"]
    assert len(fake) == 1 and not fake[0].confirmed
    # every other check confirmed, but the isogram's exact closure of a random admissible vector (first
    # order: test_combinations_are_confirmed_at_every_configuration)
    assert all(c.confirmed for c in checks if c.subject != "da1 - db2 = 0" and c.kind != EXACT)


def test_analyze_verify_reports_the_exact_closure_in_text_and_json(tmp_path, capsys):
    import json

    from hyperstat.solver.cli import main
    from tests.solver.kinematics.fourbar import write_fourbar

    path = write_fourbar(tmp_path / "crank_rocker.json", *CRANK_ROCKER, 0.5, +1, (-np.pi, np.pi), name="cr")
    out = tmp_path / "cr.analysis.json"
    assert main(["analyze", str(path), "--verify", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    line = next(t for t in text.splitlines() if EXACT in t)
    assert "confirmed" in line and "after the smallest correction" in line and "second order" in line
    entry = next(v for v in json.loads(out.read_text())["verification"] if v["kind"] == EXACT)
    assert entry["confirmed"] and entry["residual"] < 1e-12 * 100.0
    assert 8 < entry["correction"] / entry["correction_small"] < 12 and entry["uncorrected"] > 1e3 * entry["residual"]
