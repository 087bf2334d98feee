"""Method ``"closed_form"``: the analytic IK of a catalog mechanism, branch nearest ``q0``.

:func:`optik.closed_form.ik` returns every branch (angles shifted by multiples of 2 pi into the
limits where possible); this method keeps those within the joint limits and answers the one
nearest the start ``q0`` (max-norm, angles modulo 2 pi). It applies when the mechanism's catalog
kind has a registered closed form and the task is the mechanism's own task space. No branch
within the limits gives ``success=False`` with a message that says whether the target is out of
reach or only out of the limits (then the nearest branch, clipped into the limits, is returned).
"""

from __future__ import annotations

import numpy as np

from optik import closed_form
from optik.mechanism import Mechanism
from optik.results import IKResult
from optik.solvers.base import IKRequest, joint_distance, make_result, method_options, register_method


def closed_form_applies(m: Mechanism, task: str) -> bool:
    """True when ``m`` has a registered closed-form IK for its own task space ``task``."""
    return closed_form.has_ik(m) and task == m.task


def nearest(m: Mechanism, qs: list[np.ndarray], q0: np.ndarray) -> np.ndarray:
    """The configuration of ``qs`` nearest ``q0`` (see :func:`joint_distance`)."""
    return min(qs, key=lambda q: joint_distance(m, q, q0))


def solve_closed_form(request: IKRequest) -> IKResult:
    """All closed-form branches, then the one within limits nearest ``q0`` (no options)."""
    method_options(request, {})
    m = request.mechanism
    inside = closed_form.ik(m, request.target, respect_limits=True)
    if inside:
        return make_result(request, nearest(m, inside, request.q0), "closed_form", 0)
    every = closed_form.ik(m, request.target, respect_limits=False)
    if every:
        return make_result(
            request,
            nearest(m, every, request.q0),
            "closed_form",
            0,
            status="outside_limits",
            message=f"the target is reachable by {len(every)} closed-form branch(es), none within the "
            "joint limits; returned the branch nearest q0 clipped into the limits",
        )
    return make_result(
        request,
        request.q0,
        "closed_form",
        0,
        status="unreachable",
        message="the target is out of reach: the closed form has no real solution; returned q0",
    )


register_method(
    "closed_form",
    solve_closed_form,
    closed_form_applies,
    description="analytic IK of a catalog mechanism, branch within limits nearest q0",
)
