"""Closed-form (analytic) kinematics returning every branch.

``ik(m, target)`` and ``fk(m, actuated)`` dispatch on ``m.kind``; the vectorized functions
(e.g. :func:`ik_planar_3r`) work on arrays of targets at once and return all branches with a
reachability mask.
"""

from optik.closed_form.registry import fk, has_fk, has_ik, ik, register

__all__ = ["fk", "has_fk", "has_ik", "ik", "register"]
