"""Stationarity analysis: which defects the over-constrained structure forces, couples or frees.

Linearised closure stacked over sampled configurations, projected on the passive joints'
left null space (paper 1, sections 3-4) in :mod:`.stationarity`; the exact rank over the
rationals (:mod:`.symbolic`); nonlinear re-assembly that confirms each verdict
(:mod:`.verify`); design hypotheses (:mod:`.hypotheses`) and comparison with a paper's
tables (:mod:`.compare`).  Built on :mod:`hyperstat.solver.kinematics`.  Units: mm and rad.
"""
