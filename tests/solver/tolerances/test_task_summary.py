"""The accuracy maps and the values' task rows reduced block by block (issue 39): the same answers, bounded memory.

Units: mm and rad; memory in bytes (tracemalloc: Python and numpy allocations).  Expected values come from the
per-configuration arrays of the same maps (``per_configuration=True``, the task rows kept whole) reduced in one
go with numpy, a second computation of the same quantities; no timing is asserted.
"""

from __future__ import annotations

import functools
import tracemalloc
import warnings

import numpy as np
import pytest

from hyperstat.solver.tolerances import accuracy, spilled, worst_case
from hyperstat.solver.tolerances.accuracy import accuracy_maps, sample_workspace
from hyperstat.solver.tolerances.classification import classify
from hyperstat.solver.tolerances.spilled import SpilledArray
from hyperstat.solver.tolerances.task_summary import TaskSummary, task_coefficients, value_columns
from hyperstat.solver.tolerances.values import assign_values, task_maps

from tests.solver.tolerances.test_values import _setup


@pytest.fixture(scope="module")
def triflex():
    mech, kin, result, q = _setup("triflex_ii.py", 300)
    cl = classify(mech, result, kin)
    influential = [t for t in cl.items if t.cls in ("accuracy-critical", "compensable")]
    dirs = np.stack([t.direction for t in influential], axis=1)
    return mech, kin, result, q, cl, dirs, value_columns(influential)


def _maps(triflex, q, streamed: bool, chunk: int = 2048, workers=None):
    mech, kin, _, _, cl, dirs, columns = triflex
    return accuracy_maps(mech, q, kinematics=kin, task=cl.declaration.task, task_directions=dirs, chunk=chunk,
                         workers=workers, per_configuration=not streamed, task_columns=columns if streamed else None)


def test_streamed_and_whole_maps_agree(triflex):
    mech, kin, _, q, cl, dirs, (is_len, sets) = triflex
    whole = _maps(triflex, q, streamed=False)
    streamed = _maps(triflex, q, streamed=True, chunk=37)  # many uneven blocks, on threads
    for name, values in whole.coefficients.items():
        np.testing.assert_array_equal(streamed.coefficients[name], values)
    assert streamed.per_parameter == {} and streamed.position.shape == (0, 3)
    reduced, direct = streamed.per_parameter_summary(), whole.per_parameter_summary()
    assert reduced.keys() == direct.keys()
    for name in direct:
        for kind in ("rotation", "position"):
            norms = whole.per_parameter[name][kind]
            assert reduced[name][kind]["max"] == float(norms.max())
            assert reduced[name][kind]["mean"] == pytest.approx(float(np.mean(norms)), rel=1e-12, abs=1e-300)
    # the task summary against the whole rows (task_maps: its own evaluation of the Jacobians)
    rot, pos = task_maps(mech, kin, q, cl.declaration.task, dirs)
    summary = streamed.task_rows
    assert isinstance(summary, TaskSummary) and summary.configurations == len(q)
    assert (summary.n_rot, summary.n_pos) == (rot.shape[1], pos.shape[1])
    for cols in [c for c in sets if c.any()]:
        expected = task_coefficients(rot[:, :, cols], pos[:, :, cols], is_len[cols])
        for name, values in summary.of(cols).items():
            np.testing.assert_allclose(values, expected[name], rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(summary.moves_rotation, np.any(rot != 0, axis=(0, 1)))
    np.testing.assert_array_equal(summary.moves_position, np.any(pos != 0, axis=(0, 1)))
    rows = pos if pos.shape[1] else rot
    np.testing.assert_allclose(summary.mean_squares(), np.mean(np.sum(rows**2, axis=1), axis=0), rtol=1e-12)


def test_values_from_the_summary_are_those_from_the_whole_rows(triflex):
    mech, kin, result, q, cl, dirs, _ = triflex
    streamed = _maps(triflex, q, streamed=True)
    whole = _maps(triflex, q, streamed=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = assign_values(classify(mech, result, kin), mech, kin, q, assembly=False, refine=False, calibrate=False,
                          task_maps_at=streamed.task_rows)
        b = assign_values(classify(mech, result, kin), mech, kin, q, assembly=False, refine=False, calibrate=False,
                          task_maps_at=whole.task_rows)
    assert any(t.value for t in a.items)
    assert [t.value for t in a.items] == [t.value for t in b.items]
    assert [t.contribution for t in a.items] == pytest.approx([t.contribution for t in b.items], rel=1e-12)
    with pytest.raises(ValueError, match="task_maps_at"):
        assign_values(classify(mech, result, kin), mech, kin, q[:10], assembly=False, refine=False,
                      calibrate=False, task_maps_at=streamed.task_rows)


def _spilled(a: np.ndarray) -> SpilledArray:
    s = SpilledArray(len(a), a.shape[1:])
    s[:] = a
    return s


def _peak(fn) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_what_the_streamed_maps_keep_grows_only_by_the_coefficients(triflex):
    q = triflex[3]
    small, large = (q[np.arange(k) % len(q)] for k in (128, 1024))  # allocated before tracing
    kept = {}
    for label, streamed in (("streamed", True), ("whole", False)):
        peaks = [_peak(lambda x=x: _maps(triflex, x, streamed, chunk=64, workers=1)) for x in (small, large)]
        kept[label] = (peaks[1] - peaks[0]) / (len(large) - len(small))  # bytes per configuration
    # streamed: the 8 coefficients and the 2 x 4 task coefficients of the two allocations, 8 bytes each (128 B);
    # the blocks' arrays do not depend on the count
    assert kept["streamed"] <= 160, kept
    # the whole maps keep the parameters' column norms, O_p and the task rows: the measure sees them
    assert kept["whole"] > 3 * kept["streamed"], kept
    # and the reductions themselves have the same size for both counts
    a, b = (_maps(triflex, x, True, chunk=64) for x in (small, large))
    assert a.per_parameter_summary().keys() == b.per_parameter_summary().keys()
    for field in ("moves_rotation", "moves_position", "square_sums"):
        assert getattr(a.task_rows, field).shape == getattr(b.task_rows, field).shape


def test_the_closed_form_sampler_in_blocks_gives_the_same_sample(triflex, monkeypatch):
    from hyperstat.solver.tolerances.workspace import workspace_of

    mech, kin = triflex[0], triflex[1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        one = sample_workspace(mech, 700, seed=5, kinematics=kin, closed_form=True)
        monkeypatch.setattr(accuracy, "CLOSED_FORM_BLOCK", 96)
        blocks = sample_workspace(mech, 700, seed=5, kinematics=kin, closed_form=True)
        monkeypatch.setattr(accuracy, "SAMPLING_CHUNK", 250)
        chunks = sample_workspace(mech, 700, seed=5, kinematics=kin, closed_form=True)
    assert len(one) > 400
    np.testing.assert_array_equal(blocks, one)  # each draw is assembled alone: the same bits
    # drawn a chunk at a time: the same draws as one (700, 3) draw, in draw order (a seeded generator, drawn here)
    lo, hi = workspace_of(mech).actuated_box(mech)
    draws = lo + (hi - lo) * np.random.default_rng(5).random((700, len(lo)))
    act = chunks[:, mech.actuated]
    at = [int(np.nonzero(np.all(draws == a, axis=1))[0][0]) for a in act]
    assert at == sorted(at) and len(set(at)) == len(at) and len(at) > 400


def test_the_corrector_rows_merged_in_place_are_those_of_the_concatenation(triflex, monkeypatch):
    """The draws the closed form leaves to the certified corrector are put back in place (issue 39: no three copies
    of a chunk's certificate): the configurations and every certificate field as the concatenation of the other rows
    and the corrector's, put back in draw order (computed here from the two solvers directly); the warning without
    certificates (the reasons counted) reads as the certificates' own summary."""
    import functools

    import hyperstat.solver.kinematics.closed_form as closed_form
    from hyperstat.solver.kinematics.continuation import BranchCertificate, continue_nearest
    from hyperstat.solver.tolerances.workspace import workspace_of

    mech, kin = triflex[0], triflex[1]
    # a high conditioning threshold sends many reachable draws to the corrector
    monkeypatch.setattr(closed_form, "assemble_closed_form",
                        functools.partial(closed_form.assemble_closed_form, cond_tol=0.3))
    ws = workspace_of(mech)
    lo, hi = ws.actuated_box(mech)
    draws = lo + (hi - lo) * np.random.default_rng(3).random((200, len(lo)))
    form = closed_form.closed_form_of(mech, kin)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        q, cert = accuracy._closed_form_chunk(kin, form, draws, ws, None)
        q0, c0, generic = closed_form.assemble_closed_form(kin, form, draws, ws.inside)
        idx, keep = np.nonzero(generic)[0], np.nonzero(~generic)[0]
        first = q0[c0.certified][:accuracy.SAMPLING_POOL]
        qg, cg = continue_nearest(kin, draws[idx], None, mech.home, inside=ws.inside, pool=first)
    assert 10 < len(idx) < len(draws) - 10  # both kinds of rows are there
    q0[idx] = qg
    expected = BranchCertificate.concatenate([c0.take(keep), cg]).take(np.argsort(np.r_[keep, idx], kind="stable"))
    np.testing.assert_array_equal(q, q0)
    for name in ("certified", "min_condition", "min_sigma", "max_contraction", "max_branch_ratio", "steps", "rejected",
                 "path_length", "end_condition"):
        a, b = getattr(cert, name), getattr(expected, name)
        assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name
    assert cert.reason == expected.reason
    monkeypatch.undo()  # the sampler as it runs (no draw to the corrector: cheap), with and without certificates
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        kept, _, every = sample_workspace(mech, 300, seed=3, kinematics=kin, closed_form=True, certificate=True)
        alone = sample_workspace(mech, 300, seed=3, kinematics=kin, closed_form=True)
    np.testing.assert_array_equal(kept, alone)
    texts = [str(w.message) for w in caught if "workspace sampling" in str(w.message)]
    assert len(texts) == 2 and texts[0] == texts[1] and every.summary(total=300) in texts[1]


def test_the_spilled_sampler_gives_the_same_sample(triflex, monkeypatch):
    """The closed form's blocks appended as they are assembled, over several chunks, with and without draws left to
    the corrector (a high conditioning threshold sends many there): the in-memory sampler's rows and warning."""
    import hyperstat.solver.kinematics.closed_form as closed_form

    mech, kin = triflex[0], triflex[1]
    monkeypatch.setattr(accuracy, "CLOSED_FORM_BLOCK", 64)
    monkeypatch.setattr(accuracy, "SAMPLING_CHUNK", 250)
    from hyperstat.solver.tolerances.workspace import workspace_of

    plain = closed_form.assemble_closed_form
    lo, hi = workspace_of(mech).actuated_box(mech)
    mid, chosen = 0.5 * (lo[0] + hi[0]), []

    def some(kin, form, qa, inside=None):  # the blocks whose first draw is high: many draws to the corrector
        chosen.append(bool(qa[0, 0] > mid))
        return plain(kin, form, qa, inside, cond_tol=0.3 if chosen[-1] else 1e-6)

    for corrector in ("none", "every block", "some blocks"):
        if corrector != "none":
            monkeypatch.setattr(closed_form, "assemble_closed_form", some if corrector == "some blocks" else
                                functools.partial(plain, cond_tol=0.3))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            whole = sample_workspace(mech, 600, seed=4, kinematics=kin, closed_form=True)
            spill = sample_workspace(mech, 600, seed=4, kinematics=kin, closed_form=True, spill=True)
        assert isinstance(spill, SpilledArray) and len(whole) > 300
        np.testing.assert_array_equal(np.asarray(spill), whole)
        texts = [str(w.message) for w in caught if "workspace sampling" in str(w.message)]
        assert len(texts) == 2 and texts[0] == texts[1]
    # within a chunk (4 blocks), blocks written as assembled and then the rest held for the corrector
    assert any(not a and b for a, b in zip(chosen, chosen[1:])), chosen


def test_maps_and_searches_read_block_by_block_are_the_whole_arrays(triflex, monkeypatch):
    """On a Triflex-II sample: the maps of the spilled sample (their coefficients in temporary files) and the worst
    cases searched from them, with blocks of 64 rows and only 2 rows kept per function (the walk over the best
    separate starts runs past them: a second pass), against the maps and searches of the sample in memory."""
    from hyperstat.solver.tolerances.bounds import LinearWorstCase
    from hyperstat.solver.tolerances.values import task_maps

    mech, kin, result, q, cl, dirs, columns = triflex
    monkeypatch.setattr(spilled, "BLOCK", 64)
    monkeypatch.setattr(worst_case, "STREAMED_TOP", 2)
    task = cl.declaration.task
    whole = accuracy_maps(mech, q, result, kinematics=kin, task=task, task_directions=dirs, per_configuration=False,
                          task_columns=columns)
    spill = accuracy_maps(mech, _spilled(q), result, kinematics=kin, task=task, task_directions=dirs,
                          per_configuration=False, task_columns=columns, chunk=37)
    assert isinstance(spill.coefficients["delta_gR"], SpilledArray)
    for name, values in whole.coefficients.items():
        np.testing.assert_array_equal(np.asarray(spill.coefficients[name]), values)
    assert spill.summary() == whole.summary()  # min, max and numpy's mean: the same bits
    for cols in [c for c in columns[1] if c.any()]:
        for name, values in whole.task_rows.of(cols).items():
            np.testing.assert_array_equal(np.asarray(spill.task_rows.of(cols)[name]), values)
    names = ("delta_gR", "epsilon_gP", "delta_gP")  # delta_gP is zero here: left out by both
    a = worst_case.refine_extremes(mech, whole, result, kinematics=kin, kinds=("max", "min"), names=names)
    b = worst_case.refine_extremes(mech, spill, result, kinematics=kin, kinds=("max", "min"), names=names)
    assert a.keys() == b.keys() and len(a) == 4 and ("delta_gP", "max") not in a
    for key in a:
        assert a[key].as_dict() == b[key].as_dict(), key
        assert a[key].starts == b[key].starts >= 3, key  # the sample's three separate starts and the structured ones

    def rows(qq):
        rot, pos = task_maps(mech, kin, qq, task, dirs)
        return pos if pos.shape[1] else rot

    objective = LinearWorstCase(rows, np.full(dirs.shape[1], 0.01))  # values computed a block at a time
    a = worst_case.search_extremes(kin, objective, q, starts=1, structured=1)
    b = worst_case.search_extremes(kin, objective, _spilled(q), starts=1, structured=1)
    assert a.keys() == b.keys() == {("attainable", "max"), ("triangle", "max")}
    for key in a:
        assert a[key].as_dict() == b[key].as_dict(), key


def test_equal_values_take_the_same_starts_in_both_paths(triflex, monkeypatch):
    """A function with many equal values (a coefficient rounded to 0.25: ties to the last bit, as a coefficient's
    plateau gives): the whole-array path (stable sort) and the streamed one (best rows kept by value, then row
    number) hand the same starts to the searches."""
    from hyperstat.solver.tolerances.worst_case import Coefficients

    mech, kin, result, q = triflex[:4]

    class Rounded(Coefficients):
        def values(self, qq):
            return {n: np.round(v * 4) / 4 for n, v in super().values(qq).items()}

        def pick(self, qq, which):
            return np.round(super().pick(qq, which) * 4) / 4

    objective = Rounded(kin, result, ("delta_gR",))
    values = objective.values(q)["delta_gR"]
    assert len(values) - len(np.unique(values)) > len(values) // 2  # ties
    monkeypatch.setattr(spilled, "BLOCK", 64)
    monkeypatch.setattr(worst_case, "STREAMED_TOP", 3)
    starts = []  # the starts each path hands to the searches, and the best candidates

    def record(space, objective, sample, out, paths, owner, sense, origin, best_of, kinds, iterations):
        starts.append((np.array(paths), list(owner), list(sense), list(origin),
                       {k: (v, q_b.tolist(), label) for k, (v, q_b, label) in best_of.items()}))
        return out
    monkeypatch.setattr(worst_case, "_searched", record)
    worst_case.search_extremes(kin, objective, q, kinds=("max", "min"), starts=4)
    worst_case.search_extremes(kin, objective, _spilled(q), kinds=("max", "min"), starts=4)
    (pa, *ra), (pb, *rb) = starts
    assert len(pa) >= 8 and ra[2].count("sample") == 8  # four separate sample starts per kind, and structured ones
    np.testing.assert_array_equal(pa, pb)
    assert ra == rb
