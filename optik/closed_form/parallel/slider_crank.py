"""Slider-crank closed forms: IK for a piston position (2 branches) and FK (2 assembly modes)."""

from __future__ import annotations

import numpy as np

from optik.closed_form.parallel.common import CIRCLE_TOL, angle, assemble, circle_intersections
from optik.closed_form.registry import register
from optik.mechanism import Mechanism


def _slider_q(m: Mechanism, theta: float, alpha: float, x: float) -> np.ndarray:
    return assemble(m, {"theta": theta, "phi": alpha - theta, "x": x})


def slider_crank_fk(m: Mechanism, actuated: np.ndarray) -> list[np.ndarray]:
    """Slider-crank FK (2 assembly modes): ``r sin(theta) + l sin(alpha) = e`` gives the rod's
    absolute angle ``alpha = asin((e - r sin theta) / l)`` or ``pi - asin(...)``, then
    ``x = r cos(theta) + l cos(alpha)``."""
    r, l, e = m.params["crank"], m.params["rod"], m.params["offset"]
    theta = float(actuated[0])
    s = (e - r * np.sin(theta)) / l
    if abs(s) > 1 + CIRCLE_TOL:
        return []
    a0 = float(np.arcsin(np.clip(s, -1.0, 1.0)))
    alphas = [a0] if 1 - abs(s) <= CIRCLE_TOL else [a0, np.pi - a0]
    return [_slider_q(m, theta, a, r * np.cos(theta) + l * np.cos(a)) for a in alphas]


def slider_crank_ik(m: Mechanism, target: np.ndarray, tol: float = 1e-9) -> list[np.ndarray]:
    """Slider-crank IK for a piston position ``(x, e)`` (2 branches): the crank pin lies on the
    circles ``|B| = r`` and ``|B - (x, e)| = l``. A target off the line ``y = e`` is unreachable."""
    r, l, e = m.params["crank"], m.params["rod"], m.params["offset"]
    x, y = float(target[0, 3]), float(target[1, 3])
    if abs(y - e) > tol:
        return []
    piston = np.array([x, e])
    return [
        _slider_q(m, angle(b), angle(piston - b), x) for b in circle_intersections(np.zeros(2), r, piston, l)
    ]


register("slider_crank", ik=slider_crank_ik, fk=slider_crank_fk)
