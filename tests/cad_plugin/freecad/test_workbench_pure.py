"""Pure-Python parts of the workbench (no FreeCAD): marker spreading and the class vocabulary.

Units: mm.
"""

from __future__ import annotations

import itertools
import math
import sys

import pytest

from tests.cad_plugin.freecad.test_workbench import WORKBENCH

sys.path.insert(0, str(WORKBENCH))
from hyperstat_freecad.geometry import coincident_offsets  # noqa: E402
from hyperstat_freecad.verdicts import TOLERANCE_CLASSES, parameter_class, tolerance_class  # noqa: E402

sys.path.pop(0)


@pytest.mark.parametrize("n", [2, 3, 4, 6, 9])
def test_coincident_spheres_never_touch_and_lone_ones_stay(n):
    radius = 7.0
    centres = {f"j{k}": (100.0, -20.0, 5.0) for k in range(n)}
    centres["alone"] = (100.0, -20.0, 5.0 + 1.0)  # 1 mm away: not coincident, keeps its place
    offsets = coincident_offsets(centres, radius, 1e-6)
    assert offsets["alone"] == (0.0, 0.0, 0.0)
    placed = {k: [c + o for c, o in zip(centres[k], offsets[k])] for k in centres if k != "alone"}
    for a, b in itertools.combinations(placed, 2):
        assert math.dist(placed[a], placed[b]) >= 2.3 * radius * (1 - 1e-12), (a, b)
    # all on one ring around the shared point, in the global xy plane
    rings = {round(math.hypot(*offsets[k][:2]), 9) for k in placed}
    assert len(rings) == 1 and all(offsets[k][2] == 0.0 for k in placed)


def test_tolerance_class_is_read_when_present_and_falls_back_to_the_verdict():
    forced = {"name": "dK41", "verdict": "forced"}
    free = {"name": "db21", "verdict": "free", "influential": True}
    analysis = {"tolerances": {"parameters": {"dK41": {"class": "assembly"}}}}
    assert tolerance_class(analysis, forced) == "assembly" and "assembly" in TOLERANCE_CLASSES
    assert tolerance_class(analysis, free) == parameter_class(free) == "free-influential"
    assert tolerance_class(None, forced) == "forced"


def test_the_workbench_speaks_the_classification_vocabulary():
    """FreeCAD cannot import the package, so the words are repeated there: guarded here."""
    from hyperstat.solver.tolerances.classification import CLASSES

    assert set(TOLERANCE_CLASSES) == set(CLASSES) | {"normalisation"}
