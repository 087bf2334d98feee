"""Slider-crank closed forms: IK for a piston position (2 branches) and FK (2 assembly modes)."""

from __future__ import annotations

import math

import numpy as np

from optik.closed_form.parallel.common import CIRCLE_TOL, circle_points, coordinate_row
from optik.closed_form.registry import register
from optik.mechanism import Mechanism


def _slider_row(m: Mechanism, theta: float, alpha: float, x: float) -> list[float]:
    return coordinate_row(m, {"theta": theta, "phi": alpha - theta, "x": x})


def slider_crank_fk(m: Mechanism, actuated: np.ndarray) -> list[list[float]]:
    """Slider-crank FK (2 assembly modes, floats): ``r sin(theta) + l sin(alpha) = e`` gives the
    rod's absolute angle ``alpha = asin((e - r sin theta) / l)`` or ``pi - asin(...)``, then
    ``x = r cos(theta) + l cos(alpha)``."""
    r, l, e = m.params["crank"], m.params["rod"], m.params["offset"]
    theta = float(actuated[0])
    s = (e - r * math.sin(theta)) / l
    if abs(s) > 1 + CIRCLE_TOL:
        return []
    a0 = math.asin(min(max(s, -1.0), 1.0))
    alphas = [a0] if 1 - abs(s) <= CIRCLE_TOL else [a0, math.pi - a0]
    return [_slider_row(m, theta, a, r * math.cos(theta) + l * math.cos(a)) for a in alphas]


def slider_crank_ik(m: Mechanism, target: np.ndarray, tol: float = 1e-9) -> list[list[float]]:
    """Slider-crank IK for a piston position ``(x, e)`` (2 branches): the crank pin lies on the
    circles ``|B| = r`` and ``|B - (x, e)| = l``. A target off the line ``y = e`` is unreachable."""
    r, l, e = m.params["crank"], m.params["rod"], m.params["offset"]
    x, y = float(target[0, 3]), float(target[1, 3])
    if abs(y - e) > tol:
        return []
    return [
        _slider_row(m, math.atan2(by, bx), math.atan2(e - by, x - bx), x)
        for bx, by in circle_points(0.0, 0.0, r, x, e, l)
    ]


register("slider_crank", ik=slider_crank_ik, fk=slider_crank_fk)
