"""Tolerances: what each admissible defect does to the tool, and how large it may be.

Accuracy coefficients and their maps over the workspace, allocation against a required
pose accuracy and compensability (paper 2, Simas & Di Gregorio) in :mod:`.accuracy`;
Monte Carlo tolerance analysis through the nonlinear model (:mod:`.montecarlo`).  Built on
the kinematics and the stationarity analysis.  Units: mm and rad.
"""
