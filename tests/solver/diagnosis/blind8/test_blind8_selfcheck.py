"""Cheap self-checks of the tenth blind generator (``blind8``): no diagnose run.  Units: mm, rad, N mm.

The generator's own serial kinematics against an own modified-DH product and a hand reading of the
gantry's URDF; the hexapod's leg lengths from the closed frames against the leg values; gravity forces
against -dV/dq; an effect at zero amplitude gives the rigid data; a constant joint offset is absorbed
by the rigid visibility fit.
"""
import os

from . import generate as gen
from . import selfcheck as sc
from .cases import CASES


def test_kinematics_and_gravity(tmp_path):
    out = str(tmp_path)
    gen.make_models(out)
    for variant, (own, kin) in sc.check_fk(out, n=5).items():
        assert own < 1e-8 and kin < 1e-8, (variant, own, kin)
    legs, closure = sc.check_hexapod_legs(out, n=3)
    assert legs < 1e-6 and closure < 1e-8
    for variant, rel in sc.check_gravity(out).items():
        assert rel < 1e-5, (variant, rel)


def test_zero_amplitude_and_absorbed_offset(tmp_path):
    out, other = str(tmp_path / "a"), str(tmp_path / "b")
    gen.make_models(out)
    gen.make_models(other)
    base = {c["name"]: c for c in CASES}
    gen.campaign(out, base["dm_none"], 0, visibility=False)
    gen.campaign(other, dict(base["dm_none"], effect="angle-harmonic", params={"k": 1, "per": {"2": [0.0, 0.0]}}),
                 0, visibility=False)
    for fn in ("data.csv", "val.csv"):
        with open(os.path.join(out, "campaigns", "dm_none", fn)) as f0, \
                open(os.path.join(other, "campaigns", "dm_none", fn)) as f1:
            assert f0.read() == f1.read()
    off = dict(base["dm_none"], name="dm_off", effect="offset", params={"per": {"2": 1e-3}})
    assert gen.campaign(out, off, 0)["visibility"] < 0.05
    # and a 1/rev error of the same size on the same joint is not absorbed
    h1 = dict(base["dm_none"], name="dm_h1", effect="angle-harmonic", params={"k": 1, "per": {"2": [2.4e-4, 1.6e-4]}})
    assert gen.campaign(out, h1, 0)["visibility"] > 0.6
