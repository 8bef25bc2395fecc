"""Cheap self-checks of the ninth blind generator (no diagnose run): own kinematics against own
DH / URDF products, gravity forces against their closed form (about 1-2 s)."""
import numpy as np

from . import selfcheck


def test_own_kinematics_match_the_dh_table_and_the_urdf():
    for stem, worst in selfcheck.check_fk(np.random.default_rng(3)):
        assert worst < 1e-6, stem


def test_gravity_forces_match_their_closed_form():
    for stem, worst in selfcheck.check_gravity(np.random.default_rng(4)):
        assert worst < 1e-4, stem
