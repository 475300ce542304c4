"""Node parameters: Parameter, ParameterDescriptor and ranges with rcl_interfaces' field names.

Declaring follows rclpy: the override (``-p`` / params file) wins over the default, its type must
equal the default's type (rclpy does not coerce ``1`` to ``1.0``), ranges and ``read_only`` of
the descriptor are enforced.
"""

from array import array as _array
import dataclasses
import enum
import math
from typing import Any

from ifc_spg.errors import ParameterError
from ifc_spg.ros.protocols import Node

__all__ = ['Parameter', 'ParameterDescriptor', 'FloatingPointRange', 'IntegerRange',
           'ParameterType', 'check_parameter_value', 'declare_checked', 'overrides']


class ParameterType(enum.IntEnum):
    """rcl_interfaces/msg/ParameterType values."""

    PARAMETER_NOT_SET = 0
    PARAMETER_BOOL = 1
    PARAMETER_INTEGER = 2
    PARAMETER_DOUBLE = 3
    PARAMETER_STRING = 4
    PARAMETER_BYTE_ARRAY = 5
    PARAMETER_BOOL_ARRAY = 6
    PARAMETER_INTEGER_ARRAY = 7
    PARAMETER_DOUBLE_ARRAY = 8
    PARAMETER_STRING_ARRAY = 9

    @classmethod
    def of(cls, value):
        """The ParameterType of a Python value; raises ParameterError if unsupported."""
        if value is None:
            return cls.PARAMETER_NOT_SET
        for py, single, array in ((bool, cls.PARAMETER_BOOL, cls.PARAMETER_BOOL_ARRAY),
                                  (int, cls.PARAMETER_INTEGER, cls.PARAMETER_INTEGER_ARRAY),
                                  (float, cls.PARAMETER_DOUBLE, cls.PARAMETER_DOUBLE_ARRAY),
                                  (str, cls.PARAMETER_STRING, cls.PARAMETER_STRING_ARRAY)):
            if type(value) is py:
                return single
            if isinstance(value, (list, tuple)) and value and all(type(v) is py for v in value):
                return array
        if isinstance(value, (bytes, bytearray)):
            return cls.PARAMETER_BYTE_ARRAY
        raise ParameterError(f'unsupported parameter value {value!r} ({type(value).__name__}); '
                             'use bool, int, float, str or a non-empty list of one of them')


@dataclasses.dataclass
class FloatingPointRange:
    """rcl_interfaces/msg/FloatingPointRange: ``from_value`` <= v <= ``to_value``, ``step``."""

    from_value: float = 0.0
    to_value: float = 0.0
    step: float = 0.0


@dataclasses.dataclass
class IntegerRange:
    """rcl_interfaces/msg/IntegerRange: ``from_value`` <= v <= ``to_value``, ``step``."""

    from_value: int = 0
    to_value: int = 0
    step: int = 0


@dataclasses.dataclass
class ParameterDescriptor:
    """rcl_interfaces/msg/ParameterDescriptor (the fields rclpy nodes set)."""

    name: str = ''
    type: int = 0
    description: str = ''
    additional_constraints: str = ''
    read_only: bool = False
    dynamic_typing: bool = False
    floating_point_range: list = dataclasses.field(default_factory=list)
    integer_range: list = dataclasses.field(default_factory=list)


@dataclasses.dataclass
class SetParametersResult:
    """rcl_interfaces/msg/SetParametersResult: ``successful`` and, if not, the ``reason``."""

    successful: bool = False
    reason: str = ''


class Parameter:
    """A named, typed parameter value (``.name``, ``.value``, ``.type_``)."""

    Type = ParameterType

    def __init__(self, name, type_=None, value=None):
        if isinstance(type_, ParameterType) or type_ is None:
            self.value = value
        else:  # Parameter(name, value) convenience
            self.value = type_
        self.name = name
        self.type_ = ParameterType.of(self.value)

    def __repr__(self):
        return f'Parameter({self.name!r}, {self.value!r})'


def _in_range(value, rng, tol):
    lo, hi, step = rng.from_value, rng.to_value, rng.step
    if value < lo - tol or value > hi + tol:
        return False
    if step and not (abs(value - hi) <= tol):
        k = (value - lo) / step
        return abs(k - round(k)) <= (tol / step if tol else 0)
    return True


def check_parameter_value(name, value, descriptor, expected_type=None):
    """Raise ParameterError unless ``value`` fits the descriptor's type and range.

    Args:
        name: Parameter name (for messages).
        value: The value.
        descriptor: ParameterDescriptor.
        expected_type: The declared ParameterType (None: any).
    """
    ptype = ParameterType.of(value)
    if expected_type not in (None, ParameterType.PARAMETER_NOT_SET) and \
            ptype != expected_type and not descriptor.dynamic_typing:
        T = ParameterType
        hint = ''
        if (expected_type, ptype) in ((T.PARAMETER_DOUBLE, T.PARAMETER_INTEGER),
                                      (T.PARAMETER_DOUBLE_ARRAY, T.PARAMETER_INTEGER_ARRAY)):
            hint = ' (write 1.0, not 1, for a double)'
        elif expected_type >= T.PARAMETER_BYTE_ARRAY and ptype in (
                T.PARAMETER_BOOL, T.PARAMETER_INTEGER, T.PARAMETER_DOUBLE, T.PARAMETER_STRING):
            hint = f' (write a list, e.g. [{value!r}])'
        raise ParameterError(f"parameter '{name}': value {value!r} has type {ptype.name}, "
                             f'expected {ParameterType(expected_type).name}{hint}')
    for rng, _kind, tol in ((descriptor.floating_point_range, float, 1e-9),
                           (descriptor.integer_range, int, 0)):
        if rng and isinstance(value, (int, float)) and not isinstance(value, bool):
            r = rng[0]
            if not math.isfinite(value) or not _in_range(value, r, tol):
                raise ParameterError(
                    f"parameter '{name}': value {value!r} is outside its range "
                    f'[{r.from_value}, {r.to_value}]' + (f' step {r.step}' if r.step else '') +
                    (f' ({descriptor.description})' if descriptor.description else ''))


def overrides(node: Node) -> dict[str, Any]:  # values of ROS parameter types
    """``{name: value}`` of the -p / --params-file values given to ``node``.

    The built-in backend's node offers them as ``parameter_overrides()``. Used to refuse
    parameters nobody declares and to check a value with the same messages on both backends
    before rclpy sees it.

    Args:
        node: An rclpy node or one of the built-in backend.
    """
    if hasattr(node, 'parameter_overrides'):
        return node.parameter_overrides()
    # rclpy 7 (Jazzy) has no public accessor for a node's overrides (-p, --params-file):
    table = getattr(node, '_parameter_overrides', None) or {}
    out = {}
    for name, param in table.items():
        value = getattr(param, 'value', param)
        out[name] = list(value) if isinstance(value, _array) else value
    return out


def declare_checked(node: Node, name: str, default: Any, descriptor: Any) -> Any:
    """``node.declare_parameter(name, default, descriptor).value``, an override checked first.

    The override's type and range are checked with
    :func:`~ifc_spg.ros.parameters.check_parameter_value`, so that a bad value gives the same
    clear message on rclpy and on the built-in backend.

    Args:
        node: The node to declare the parameter on.
        name: The parameter's name.
        default: Its default value (also gives its type).
        descriptor: Its ``ParameterDescriptor`` (description, range).

    Raises:
        ParameterError: A bad type or range.
    """
    given = overrides(node)
    if name in given:
        check_parameter_value(name, given[name], descriptor, ParameterType.of(default))
    try:
        return node.declare_parameter(name, default, descriptor).value
    except ParameterError:
        raise
    except Exception as exc:  # noqa: BLE001 - rclpy's InvalidParameter*Exception and friends
        raise ParameterError(f"parameter '{name}': {exc}") from None
