"""Doggy closed forms: IK from the body pose (4 leg combinations) and FK from the leg angles (1)."""

from __future__ import annotations

import math

import numpy as np

from optik.closed_form.parallel.common import angle, assemble, coordinate_row, direction, two_link_one
from optik.closed_form.registry import register
from optik.mechanism import Mechanism


def _leg_end(foot: np.ndarray, legs: np.ndarray, th_a: float, th_b: float) -> np.ndarray:
    return foot + legs[0] * direction(th_a) + legs[1] * direction(th_a + th_b)


def doggy_ik(m: Mechanism, target: np.ndarray) -> list[np.ndarray]:
    """Doggy IK from the body pose ``(xB, yB, phiB)``: hips ``A = B + R h_A``, ``C = B + R h_C``,
    then each leg is a 2R chain from its foot to its hip: 2 x 2 = 4 leg combinations."""
    return [np.array(row) for row in _doggy_rows(m, target)]


def _doggy_rows(m: Mechanism, target: np.ndarray) -> list[list[float]]:
    """`doggy_ik` as lists of floats (registered: the registry works on floats)."""
    f, h, lg = m.params["feet"].tolist(), m.params["hips"].tolist(), m.params["legs"].tolist()
    bx, by = float(target[0, 3]), float(target[1, 3])
    phi = math.atan2(target[1, 0], target[0, 0])
    c, s = math.cos(phi), math.sin(phi)
    hips = [(bx + (c * hx - s * hy), by + (s * hx + c * hy)) for hx, hy in h]
    out = []
    leg2 = two_link_one(*f[1], lg[1][0], lg[1][1], *hips[1])
    for th1, th2 in two_link_one(*f[0], lg[0][0], lg[0][1], *hips[0]):
        for th3, th4 in leg2:
            values = {"theta1": th1, "theta2": th2, "hipA": phi - th1 - th2, "theta3": th3, "theta4": th4}
            out.append(coordinate_row(m, values))
    return out


def doggy_fk(m: Mechanism, actuated: np.ndarray, tol: float = 1e-9) -> list[np.ndarray]:
    """Doggy FK from the four leg angles: the legs place the hips ``A`` and ``C``; the body
    assembles when ``|C - A| = |h_C - h_A|`` (to ``tol``), with heading
    ``phiB = atan2(C - A) - atan2(h_C - h_A)``. Four inputs for a mobility-3 body: the inputs are
    consistent or the body does not assemble (``[]``)."""
    f, h, lg = m.params["feet"], m.params["hips"], m.params["legs"]
    th1, th2, th3, th4 = (float(v) for v in actuated)
    a = _leg_end(f[0], lg[0], th1, th2)
    c = _leg_end(f[1], lg[1], th3, th4)
    span = h[1] - h[0]
    if abs(np.linalg.norm(c - a) - np.linalg.norm(span)) > tol:
        return []
    phi = angle(c - a) - angle(span)
    return [
        assemble(m, {"theta1": th1, "theta2": th2, "hipA": phi - th1 - th2, "theta3": th3, "theta4": th4})
    ]


register("doggy", ik=_doggy_rows, fk=doggy_fk)
