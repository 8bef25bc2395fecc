"""Diagnosis of the sim-to-real gap: what the identified rigid model still misses.

Candidate unmodelled effects, each a small parametric extension of the model
(:mod:`.effects`); the diagnosis itself (is there a gap, where, which effect, how far it
shrinks: :mod:`.diagnose`); and the withheld-effect validation suite
(:mod:`.validation_suite`).  Built on calibration.  Units: mm and rad.
"""
