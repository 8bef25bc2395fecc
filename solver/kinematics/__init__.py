"""Kinematics: the joint-invariant model and how a mechanism moves (first pipeline stage).

The geometric-parameter matrices ``D``, motion matrices ``M`` and fixed frames ``T`` of
paper 1, section 2 (:mod:`.frames`); the mechanism as chains of joints with their defect
parameters (:mod:`.model`), its JSON model file and schema (:mod:`.modelfile`), building a
mechanism from world-coordinate frames (:mod:`.build`); the closure equations and their
assembly (:mod:`.closure`, eq. (7) and (9)), batched forward kinematics (:mod:`.fastfk`)
and sampling of assembled configurations (:mod:`.sampling`); robot import (:mod:`.robot_import`)
and the plausibility of declared link masses (:mod:`.masses`).  Nothing here knows about
defect verdicts, tolerances or measurements.  Units: mm and rad.
"""
