"""Self-checks of the blind6 generator (no diagnose run): `python -m tests.solver.diagnosis.blind6.selfcheck`.

1. own forward kinematics of the imported model files against an own DH product straight from the
   robots/*.dh.yaml tables (standard and modified DH), mm;
2. the visibility fit absorbs what the rigid model holds: a constant joint offset (frac 0 step) must
   have a visibility near 0 on every family.
"""
from __future__ import annotations

import copy

import numpy as np
import yaml

from .cases import CASES
from .generate import HERE, Campaign, model


def dh_fk(table, q):
    u = table["units"]
    L = 1000.0 if u["length"] == "m" else 1.0
    A = np.pi / 180 if u["angle"] == "deg" else 1.0
    T = np.eye(4)
    for j, qj in zip(table["joints"], q):
        a, al, d, th = j["a"] * L, j["alpha"] * A, j["d"] * L, j["theta"] * A + qj
        ca, sa, ct, st = np.cos(al), np.sin(al), np.cos(th), np.sin(th)
        if table["convention"] == "dh":  # Rz(th) Tz(d) Tx(a) Rx(al)
            M = np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])
        else:  # Craig: Rx(al) Tx(a) Rz(th) Tz(d)
            M = np.array([[ct, -st, 0, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d], [0, 0, 0, 1]])
        T = T @ M
    tool = np.eye(4)
    tool[:3, 3] = np.asarray(table["tool"]["origin"], float) * L
    return T @ tool


def main():
    rng = np.random.default_rng(1)
    print("1. own model-file kinematics against own DH product (max |position| deviation, 20 poses):")
    for fam, f in (("st6", "st6"), ("abb6", "abb6"), ("pal4", "pal4")):
        tab = yaml.safe_load(open(HERE / "robots" / (f + ".dh.yaml")))
        m = model(fam)
        dev = 0.0
        for _ in range(20):
            q = {j: rng.uniform(*m.range[j]) for j in m.actuated}
            a = m.output_pose(q)
            b = dh_fk(tab, [q[j["name"]] for j in tab["joints"]])
            dev = max(dev, np.max(np.abs(a[:3, 3] - b[:3, 3])), 1000 * np.max(np.abs(a[:3, :3] - b[:3, :3])))
        print("   %-5s %.2e mm (rotation entries x 1000 included)" % (fam, dev))
    print("2. visibility of a constant joint offset (the rigid fit must absorb it):")
    for base, joint, size in (("tx_none", "42", 0.1), ("hx_none", "33", 0.1), ("st_none", "2", 5e-4),
                              ("ab_none", "3", 5e-4), ("pa_none", "2", 5e-4)):
        c = copy.deepcopy(CASES[base])
        c.update(kind="out", effect="step-offset", params={"joint": joint, "size": size, "frac": 0.0})
        print("   %-8s joint %s + %g: %.3f" % (base, joint, size, Campaign(c, 0).visibility()))


if __name__ == "__main__":
    main()
