"""Exceptions raised by optik.

Every error that a caller can cause derives from [`OptikError`][optik.OptikError]. Errors about an argument
carry the argument's name in ``argument`` and in the message, so that a user sees at once what
to fix. Unreachable targets and non-assemblable mechanisms are *not* errors: solvers return a
result with ``success=False`` for them.
"""

from __future__ import annotations

import importlib
from types import ModuleType


class OptikError(Exception):
    """Base class of every exception raised by optik."""


class InvalidArgumentError(OptikError, ValueError):
    """An argument has a wrong value, shape or type.

    Attributes:
        argument: name of the offending argument.
    """

    def __init__(self, argument: str, message: str) -> None:
        self.argument = argument
        super().__init__(f"{argument}: {message}")


class ShapeError(InvalidArgumentError):
    """An array argument has the wrong shape."""


class NonFiniteError(InvalidArgumentError):
    """An array argument contains NaN or infinity."""


class LimitsError(InvalidArgumentError):
    """Joint limits are inconsistent (lower > upper, or NaN)."""


class UnknownFrameError(InvalidArgumentError, KeyError):
    """A frame, body or joint name does not exist in the mechanism."""

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return self.args[0]


class ReadOnlyError(InvalidArgumentError, AttributeError):
    """An attribute of a model is read-only; the message names the call that makes a changed
    copy (e.g. `Mechanism.with_limits`), so that no cached solver keeps answering for old values."""


class ModelError(OptikError):
    """A mechanism description is inconsistent (dangling bodies, duplicate names, ...)."""


class SolverUnavailableError(OptikError):
    """A requested solver or backend is not installed or does not apply to the problem."""


class MissingExtraError(OptikError, ImportError):
    """An optional part of optik is not installed (the message says which pip extra brings it)."""


def require_extra(module: str, extra: str, feature: str) -> ModuleType:
    """Import the optional ``module`` that ``feature`` needs, from the pip extra ``extra``.

    Raises:
        MissingExtraError: ``module`` cannot be imported; one line naming the feature, the module
            and the command that installs it, e.g. ``optik view needs viser (not installed):
            pip install "optik[view]"``.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        found = "not installed" if exc.name in (module, module.partition(".")[0]) else f"import failed: {exc}"
        raise MissingExtraError(f'{feature} needs {module} ({found}): pip install "optik[{extra}]"') from None


class ProblemFileError(OptikError):
    """A problem file (TOML) is malformed; the message names the file and the key."""
