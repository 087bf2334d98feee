"""Five-bar closed forms: IK (4 working modes) and FK (2 assembly modes)."""

from __future__ import annotations

import math

import numpy as np

from optik.closed_form.parallel.common import circle_points, coordinate_row, two_link_one
from optik.closed_form.registry import register
from optik.mechanism import Mechanism

BRANCH_CHECK = 1e-10
"""Largest loop-closure and tool-position error of a returned branch, relative to the size of
the mechanism (`five_bar_size`): a branch whose formulas lost more (a degenerate chain, e.g. the
tool point on the pivot ``A1``, where ``theta1`` is arbitrary) is dropped, never returned wrong."""


def five_bar_size(m: Mechanism) -> float:
    """``max(1, |A1|, |A2|, l1, l2, l3, l4, tool)``: the length scale of the checks."""
    return max(1.0, float(np.max(np.abs(m.params["base"]))), *m.params["lengths"], m.params["tool"])


def _errors(m: Mechanism, th1: float, th2: float, psi1: float, psi2: float) -> tuple[float, float, float]:
    """Closure error ``|P_1 - P_2|`` of the two chains and the tool point ``(x, y)``."""
    (a1x, a1y), (a2x, a2y) = m.params["base"].tolist()
    l1, l2, l3, l4 = m.params["lengths"]
    tool = m.params["tool"]
    c1, s1, c12, s12 = math.cos(th1), math.sin(th1), math.cos(th1 + psi1), math.sin(th1 + psi1)
    p1x, p1y = a1x + l1 * c1 + l3 * c12, a1y + l1 * s1 + l3 * s12
    p2x = a2x + l2 * math.cos(th2) + l4 * math.cos(th2 + psi2)
    p2y = a2y + l2 * math.sin(th2) + l4 * math.sin(th2 + psi2)
    return math.hypot(p1x - p2x, p1y - p2y), a1x + l1 * c1 + tool * c12, a1y + l1 * s1 + tool * s12


def five_bar_ik(m: Mechanism, target: np.ndarray) -> list[np.ndarray]:
    """Five-bar IK: the 4 working modes for a tool position.

    Chain 1 is a 2R chain (``l1``, ``tool``) from ``A1`` to the tool point (2 solutions); it fixes
    ``P = B1 + l3 u(theta1 + psi1)``; chain 2 is a 2R chain (``l2``, ``l4``) from ``A2`` to ``P``
    (2 solutions). Every branch is checked in floats: closure and tool position within
    `BRANCH_CHECK` times the size of the mechanism, else it is dropped.
    """
    return [np.array(row) for row in _five_bar_rows(m, target)]


def _five_bar_rows(m: Mechanism, target: np.ndarray) -> list[list[float]]:
    """`five_bar_ik` as lists of floats (registered: the registry works on floats)."""
    (a1x, a1y), (a2x, a2y) = m.params["base"].tolist()
    l1, l2, l3, l4 = m.params["lengths"]
    tool = m.params["tool"]
    x, y = float(target[0, 3]), float(target[1, 3])
    tol = BRANCH_CHECK * five_bar_size(m)
    out = []
    for th1, psi1 in two_link_one(a1x, a1y, l1, tool, x, y):
        px = a1x + l1 * math.cos(th1) + l3 * math.cos(th1 + psi1)
        py = a1y + l1 * math.sin(th1) + l3 * math.sin(th1 + psi1)
        for th2, psi2 in two_link_one(a2x, a2y, l2, l4, px, py):
            gap, tx, ty = _errors(m, th1, th2, psi1, psi2)
            if gap <= tol and math.hypot(tx - x, ty - y) <= tol:
                out.append(coordinate_row(m, {"theta1": th1, "theta2": th2, "psi1": psi1, "psi2": psi2}))
    return out


def five_bar_fk(m: Mechanism, actuated: np.ndarray) -> list[list[float]]:
    """Five-bar FK: the 2 assembly modes, ``P`` on both circles ``|P - B1| = l3``, ``|P - B2| = l4``
    (floats; each checked like the IK branches)."""
    (a1x, a1y), (a2x, a2y) = m.params["base"].tolist()
    l1, l2, l3, l4 = m.params["lengths"]
    th1, th2 = (float(v) for v in actuated)
    b1x, b1y = a1x + l1 * math.cos(th1), a1y + l1 * math.sin(th1)
    b2x, b2y = a2x + l2 * math.cos(th2), a2y + l2 * math.sin(th2)
    tol = BRANCH_CHECK * five_bar_size(m)
    out = []
    for px, py in circle_points(b1x, b1y, l3, b2x, b2y, l4):
        psi1, psi2 = math.atan2(py - b1y, px - b1x) - th1, math.atan2(py - b2y, px - b2x) - th2
        if _errors(m, th1, th2, psi1, psi2)[0] <= tol:
            out.append(coordinate_row(m, {"theta1": th1, "theta2": th2, "psi1": psi1, "psi2": psi2}))
    return out


register("five_bar", ik=_five_bar_rows, fk=five_bar_fk)
