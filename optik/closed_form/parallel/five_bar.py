"""Five-bar closed forms: IK (4 working modes) and FK (2 assembly modes)."""

from __future__ import annotations

import math

import numpy as np

from optik.closed_form.parallel.common import (
    angle,
    assemble,
    circle_intersections,
    coordinate_row,
    direction,
    two_link_one,
)
from optik.closed_form.registry import register
from optik.mechanism import Mechanism


def five_bar_ik(m: Mechanism, target: np.ndarray) -> list[np.ndarray]:
    """Five-bar IK: the 4 working modes for a tool position.

    Chain 1 is a 2R chain (``l1``, ``tool``) from ``A1`` to the tool point (2 solutions); it fixes
    ``P = B1 + l3 u(theta1 + psi1)``; chain 2 is a 2R chain (``l2``, ``l4``) from ``A2`` to ``P``
    (2 solutions).
    """
    return [np.array(row) for row in _five_bar_rows(m, target)]


def _five_bar_rows(m: Mechanism, target: np.ndarray) -> list[list[float]]:
    """`five_bar_ik` as lists of floats (registered: the registry works on floats)."""
    (a1x, a1y), (a2x, a2y) = m.params["base"].tolist()
    l1, l2, l3, l4 = m.params["lengths"]
    tool = m.params["tool"]
    out = []
    for th1, psi1 in two_link_one(a1x, a1y, l1, tool, float(target[0, 3]), float(target[1, 3])):
        px = a1x + l1 * math.cos(th1) + l3 * math.cos(th1 + psi1)
        py = a1y + l1 * math.sin(th1) + l3 * math.sin(th1 + psi1)
        for th2, psi2 in two_link_one(a2x, a2y, l2, l4, px, py):
            out.append(coordinate_row(m, {"theta1": th1, "theta2": th2, "psi1": psi1, "psi2": psi2}))
    return out


def five_bar_fk(m: Mechanism, actuated: np.ndarray) -> list[np.ndarray]:
    """Five-bar FK: the 2 assembly modes, ``P`` on both circles ``|P - B1| = l3``, ``|P - B2| = l4``."""
    b = m.params["base"]
    l1, l2, l3, l4 = m.params["lengths"]
    th1, th2 = (float(v) for v in actuated)
    b1, b2 = b[0] + l1 * direction(th1), b[1] + l2 * direction(th2)
    return [
        assemble(m, {"theta1": th1, "theta2": th2, "psi1": angle(p - b1) - th1, "psi2": angle(p - b2) - th2})
        for p in circle_intersections(b1, l3, b2, l4)
    ]


register("five_bar", ik=_five_bar_rows, fk=five_bar_fk)
