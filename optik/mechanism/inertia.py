"""Point masses of a mechanism's links and its centre of mass.

A link's inertial is its mass ``m_i`` and the position ``c_i`` of its centre of mass in the
frame it is given in (a body or a named frame: URDF ``<inertial>``, MJCF ``body_mass`` and
``body_ipos``). The rotational inertia is not needed for the centre of mass and is not kept.
With ``T_i(q)`` the pose of that frame, the centre of mass and its Jacobian are

```
com(q) = sum_i m_i (R_i(q) c_i + p_i(q)) / M,      M = sum_i m_i
J_com(q) = d com / d q      (3 x n_q)
```

in the base frame.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import casadi as ca
import numpy as np

from optik.checks import as_float, real_array
from optik.errors import InvalidArgumentError, ModelError, UnknownFrameError

__all__ = ["check_inertials", "com_expr"]


def check_inertials(
    inertials: Mapping[str, tuple[Any, Any]] | None, frames: Mapping[str, tuple[str, np.ndarray]]
) -> dict[str, tuple[float, np.ndarray]]:
    """``{frame: (mass, com)}`` validated: known frames, finite masses ``>= 0``, finite 3-vectors.

    Raises:
        UnknownFrameError: an inertial is on a frame the mechanism does not have.
        InvalidArgumentError: a mass is negative or not finite, a centre is not a finite 3-vector.
    """
    out: dict[str, tuple[float, np.ndarray]] = {}
    if inertials is None:
        return out
    if not isinstance(inertials, Mapping):
        raise InvalidArgumentError("inertials", f"expected {{frame: (mass, com)}}, got {inertials!r}")
    for frame, value in inertials.items():
        if frame not in frames:
            raise UnknownFrameError("inertials", f"inertial on unknown frame {frame!r}")
        try:
            mass, com = value
        except (TypeError, ValueError) as exc:
            raise InvalidArgumentError("inertials", f"frame {frame!r}: expected (mass, com)") from exc
        mass = as_float(mass, f"inertials[{frame!r}] mass", minimum=0.0)
        if not np.isfinite(mass):
            raise InvalidArgumentError("inertials", f"frame {frame!r}: the mass must be finite")
        c = real_array(com, f"inertials[{frame!r}] com").reshape(-1)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise InvalidArgumentError("inertials", f"frame {frame!r}: com must be a finite 3-vector")
        c = c.copy()
        c.flags.writeable = False
        out[frame] = (mass, c)
    return out


def com_expr(
    inertials: Mapping[str, tuple[float, np.ndarray]],
    frames: Mapping[str, tuple[str, np.ndarray]],
    body_transforms: Mapping[str, ca.SX],
    name: str,
) -> ca.SX:
    """``com(q)`` (3 x 1 ``SX``) of the module docstring.

    Raises:
        ModelError: the mechanism has no mass (no inertial, or all masses zero).
    """
    total = sum(m for m, _ in inertials.values())
    if total <= 0.0:
        raise ModelError(f"mechanism {name!r} has no mass: give it inertials (URDF <inertial>, MJCF masses)")
    weighted: dict[str, np.ndarray] = {}  # per body: sum m_i [c_i in the body frame; 1] ...
    for frame, (mass, c) in inertials.items():
        body, offset = frames[frame]
        point = offset @ np.append(c, 1.0)
        weighted[body] = weighted.get(body, np.zeros(4)) + mass * point
    out = ca.SX.zeros(3, 1)
    for body, w in weighted.items():
        t = body_transforms[body]
        out += ca.mtimes(t[:3, :3], ca.DM(w[:3])) + t[:3, 3] * w[3]
    return out / total
