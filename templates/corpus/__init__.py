"""The corpus: mechanisms beyond the six shipped templates, each with its theory in its docstring.

Units: lengths in mm, angles in rad.

Classic over-constrained linkages (Bennett, Sarrus, spherical four-bar, Goldberg 5R, a
line-symmetric Bricard), parallel robots (a Delta with parallelograms, a 3-UPU translational,
a 3-PRS, a planar 3-RPR), single-loop spatial linkages that are not over-constrained (RSSR,
RCCC), a planar Watt six-bar, and serial arms as a DH table (``puma560.dh.yaml``), a
modified-DH table (``panda.mdh.yaml``) and a URDF (``iiwa14.urdf``; ``hyperstat import-robot``
turns these into model files).

Each template states in its docstring the mobility, the degree of over-constraint (from screw
theory: ``6 L - r`` for ``L`` independent loops whose joint twists have rank ``r``) and the
number of assembly conditions with the known conditions behind it, in one line of the form
``Theory: mobility M, degree of over-constraint D, assembly conditions C.``; the test suite
(``tests/templates/test_corpus.py``) checks ``hyperstat analyze`` against that line and the line
against an independent screw-theory computation, and runs every command on every member.

A bundled name works wherever a template is expected: ``hyperstat analyze bennett``,
``hs.load("bennett")``.  Copy a file to start a template of your own (docs/authoring.md).
"""
