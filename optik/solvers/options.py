"""Validation of numerical IK method options (named errors instead of ``float()`` failures)."""

from __future__ import annotations

from typing import Any

from optik.checks import as_vector
from optik.errors import InvalidArgumentError
from optik.solvers.base import positive_int


def check_floats(opts: dict[str, Any], *names: str, strict: tuple[str, ...] = ()) -> None:
    """Replace ``opts[name]`` by a finite float ``>= 0`` (``> 0`` for names in ``strict``);
    ``None`` is kept for options where it means "default".

    Raises:
        InvalidArgumentError: naming the option.
    """
    for name in (*names, *strict):
        if opts[name] is None:
            continue
        v = float(as_vector(opts[name], name, 1)[0])
        if v < 0 or (v == 0 and name in strict):
            raise InvalidArgumentError(name, f"must be {'>' if name in strict else '>='} 0, got {v}")
        opts[name] = v


def check_max_restarts(value: Any) -> int | None:
    """``max_restarts``: None (no cap) or an integer ``>= 0``."""
    if value is None:
        return None
    return positive_int(float(as_vector(value, "max_restarts", 1)[0]) + 1, "max_restarts") - 1
