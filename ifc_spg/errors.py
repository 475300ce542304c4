"""The one exception hierarchy of ifc_spg.

Every error a user can trigger is an :class:`IfcSpgError`; messages name the bad value,
the valid choices and the fix.
"""

from collections.abc import Iterable
import difflib
from typing import Any

__all__ = [
    'IfcSpgError',
    'ModelError',
    'UnknownFrame',
    'UnknownJoint',
    'UnknownRobot',
    'ParameterError',
    'SolverError',
    'did_you_mean',
]


class IfcSpgError(Exception):
    """Base class of every error raised by ifc_spg on bad input or failed solves."""


class ModelError(IfcSpgError):
    """A robot model file or its IFC parameters are invalid."""


class UnknownRobot(ModelError):
    """A named robot configuration does not exist."""


class UnknownFrame(ModelError):
    """A frame (chain id) is not in the robot model."""


class UnknownJoint(ModelError):
    """A joint name is not in the robot model."""


class ParameterError(IfcSpgError):
    """A parameter has the wrong type or is out of range."""


class SolverError(IfcSpgError):
    """A QP solver is unknown or could not be constructed."""


def did_you_mean(name: Any, choices: Iterable[Any]) -> str:
    """Return ``"; did you mean 'x'?"`` for the closest of ``choices`` to ``name``, else ``''``.

    Args:
        name: The misspelled name.
        choices: The valid names.
    """
    close = difflib.get_close_matches(str(name), [str(c) for c in choices], n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ''
