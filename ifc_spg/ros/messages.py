"""Built-in ROS 2 message classes (used when rclpy's message packages are not importable).

Field names, defaults and value types follow rclpy's generated classes: numeric sequences are
``array.array`` (lists, tuples and numpy arrays are accepted and converted by the constructor
and accepted as they are by the serializer), string sequences are lists, ``byte`` fields are
``bytes`` of length 1, ``Quaternion.w`` defaults to 1.0. Each class knows its ROS type name
(:func:`type_name`), its fields (:func:`fields`), its DDS type name (:func:`dds_type`, as
``rmw_cyclonedds_cpp`` names it), its Jazzy type hash (:func:`type_hash`, RIHS01, checked
against rosbags in the tests) and its compiled CDR :func:`codec`: the message protocol other
modules use (the class constants behind them are this module's and the codec compiler's).

    msg = JointState(name=['a1'], position=[0.1])
    data = serialize(msg)          # CDR bytes with the 4-byte encapsulation header
    same = deserialize(JointState, data)
"""

import array
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from ifc_spg.errors import ParameterError
from ifc_spg.ros.cdr import CDR_HEADER, PRIMITIVES, compile_codec, parse_field_type

__all__ = [
    'Message', 'REGISTRY', 'serialize', 'deserialize', 'codec', 'dds_type', 'dds_type_name',
    'fields', 'type_hash', 'type_name',
    'Time', 'Duration', 'Header', 'String', 'MultiArrayDimension', 'MultiArrayLayout',
    'Float64MultiArray', 'JointState', 'Vector3', 'Point', 'Quaternion', 'Pose', 'PoseStamped',
    'Wrench', 'WrenchStamped', 'KeyValue', 'DiagnosticStatus', 'DiagnosticArray',
    'Gid', 'NodeEntitiesInfo', 'ParticipantEntitiesInfo', 'ColorRGBA', 'CompressedImage',
    'UVCoordinate', 'MeshFile', 'Marker', 'MarkerArray',
]

REGISTRY: dict[str, type['Message']] = {}


def dds_type_name(ros_type):
    """Return the DDS type name rmw_cyclonedds uses: ``pkg/msg/T`` -> ``pkg::msg::dds_::T_``."""
    pkg, sub, name = ros_type.split('/')
    return f'{pkg}::{sub}::dds_::{name}_'


def type_hash(cls):
    """The RIHS01 type hash of message class ``cls`` (what rosidl generates for it)."""
    return cls._HASH


def type_name(cls):
    """The ROS type name of message class ``cls``: ``'pkg/msg/Name'``."""
    return cls._TYPE


def fields(cls):
    """The fields of message class ``cls`` in wire order: ``((name, ROS type string), ...)``."""
    return cls._FIELDS


def dds_type(cls):
    """The DDS type name of message class ``cls`` (as ``rmw_cyclonedds_cpp`` names it)."""
    return cls._DDS_TYPE


def codec(cls):
    """``(write, read)`` of message class ``cls``, compiled once.

    ``write(msg, bytearray)`` appends the CDR body; ``read(memoryview, offset)`` returns
    ``(msg, offset)``.
    """
    if cls._codec is None:
        cls._codec = compile_codec(cls, REGISTRY)
    return cls._codec


def _default_factory(ftype):
    """A function making the default value of a field of type ``ftype`` (as rclpy's)."""
    base, kind, length = parse_field_type(ftype)
    if kind == 'sequence':
        code = PRIMITIVES.get(base, (None, None, None))[2]
        if code is not None:
            return lambda: array.array(code)
        return list
    if kind == 'array':
        return _array_factory(base, length)
    if base == 'string':
        return str
    if base == 'bool':
        return bool
    if base == 'byte':
        return lambda: b'\x00'
    if base in ('float32', 'float64'):
        return float
    if base in PRIMITIVES:
        return int
    return lambda: REGISTRY[base]()


def _array_factory(base, length):
    """A function making the default of a fixed-size array of ``length`` ``base`` values."""
    code = PRIMITIVES.get(base, (None, None, None))[2]
    if code is not None:
        return lambda: array.array(code, bytes(length * array.array(code).itemsize))
    if base == 'string':
        return lambda: [''] * length
    if base in PRIMITIVES:
        zero = _default_factory(base)
        return lambda: [zero() for _ in range(length)]
    return lambda: [REGISTRY[base]() for _ in range(length)]


def _converter(ftype):
    """Return a function normalising a constructor value like rclpy's setters, or None."""
    base, kind, _ = parse_field_type(ftype)
    code = PRIMITIVES.get(base, (None, None, None))[2]
    if kind != 'single' and code is not None:
        def to_array(value, code=code):
            if type(value) is array.array and value.typecode == code:
                return value
            out = array.array(code)
            if hasattr(value, 'dtype'):  # numpy array: one buffer copy
                out.frombytes(np.ascontiguousarray(value, dtype=out.typecode).tobytes())
            else:
                out.extend(value)
            return out
        return to_array
    if kind != 'single':
        return list
    if base in ('float32', 'float64'):
        return float
    return None


class Message:
    """Base of the built-in message classes: keyword constructor, equality, repr."""

    __slots__ = ()
    _TYPE: ClassVar[str] = ''
    _FIELDS: ClassVar[tuple[tuple[str, str], ...]] = ()
    _DEFAULTS: ClassVar[dict[str, Any]] = {}
    _HASH: ClassVar[str]
    _DDS_TYPE: ClassVar[str]
    _FACTORIES: ClassVar[tuple[tuple[str, Callable[[], Any], Callable[[Any], Any] | None], ...]]
    _codec: ClassVar[tuple[Callable[..., Any], Callable[..., Any]] | None]

    if TYPE_CHECKING:
        # the fields (the subclass's __slots__, from _FIELDS) are set in __init__: a message's
        # field values are the dynamic seam shared with rclpy's generated classes
        def __getattr__(self, name: str) -> Any: ...
        def __setattr__(self, name: str, value: Any) -> None: ...

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        cls._DDS_TYPE = dds_type_name(cls._TYPE)
        cls._FACTORIES = tuple((name, _default_factory(ftype), _converter(ftype))
                               for name, ftype in cls._FIELDS)
        REGISTRY[cls._TYPE] = cls
        cls._codec = None

    def __init__(self, **kwargs):
        for name, factory, convert in self._FACTORIES:
            if name in kwargs:
                value = kwargs.pop(name)
                setattr(self, name, convert(value) if convert is not None else value)
            elif name in self._DEFAULTS:
                setattr(self, name, self._DEFAULTS[name])
            else:
                setattr(self, name, factory())
        if kwargs:
            bad = sorted(kwargs)[0]
            fields = [n for n, _ in self._FIELDS]
            raise ParameterError(f"{type(self).__name__} has no field '{bad}'; fields: "
                                 f"{', '.join(fields)}")

    @classmethod
    def get_fields_and_field_types(cls):
        """Return ``{field name: ROS type string}`` like rclpy's generated classes."""
        return dict(cls._FIELDS)

    def __eq__(self, other):
        if type(other) is not type(self):
            return NotImplemented
        for name, _ in self._FIELDS:
            a, b = getattr(self, name), getattr(other, name)
            if isinstance(a, array.array) or isinstance(b, array.array):
                a, b = list(a), list(b)
            if a != b:
                return False
        return True

    def __repr__(self):
        inner = ', '.join(f'{name}={getattr(self, name)!r}' for name, _ in self._FIELDS)
        return f'{self._TYPE.replace("/msg/", ".msg.").replace("/", ".")}({inner})'


def serialize(msg):
    """Return the CDR bytes (with the 4-byte header) of a built-in message, as rosbags does."""
    b = bytearray(CDR_HEADER)
    codec(type(msg))[0](msg, b)
    return bytes(b)


def deserialize(cls, data):
    """Decode CDR bytes (with header) into an instance of built-in message class ``cls``."""
    view = memoryview(data)
    if len(view) < 4 or view[1] != 1:
        raise ParameterError(f'{cls._TYPE}: expected little-endian plain CDR (header 00 01), got '
                             f'{bytes(view[:4]).hex()}')
    try:
        msg, _ = codec(cls)[1](view[4:], 0)
    except Exception as exc:  # struct.error, ValueError, UnicodeDecodeError on truncated data
        raise ParameterError(f'{cls._TYPE}: cannot decode {len(view)} CDR bytes: {exc}') from exc
    return msg


# builtin_interfaces ---------------------------------------------------------------------------

class Time(Message):
    """builtin_interfaces/msg/Time: ``sec`` [s] and ``nanosec`` [ns]."""

    __slots__ = ('sec', 'nanosec')
    _TYPE = 'builtin_interfaces/msg/Time'
    _FIELDS = (('sec', 'int32'), ('nanosec', 'uint32'))
    _HASH = 'RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197'


class Duration(Message):
    """builtin_interfaces/msg/Duration: ``sec`` [s] and ``nanosec`` [ns]."""

    __slots__ = ('sec', 'nanosec')
    _TYPE = 'builtin_interfaces/msg/Duration'
    _FIELDS = (('sec', 'int32'), ('nanosec', 'uint32'))
    _HASH = 'RIHS01_e8d009f659816f758b75334ee1a9ca5b5c0b859843261f14c7f937349599d93b'


# std_msgs -------------------------------------------------------------------------------------

class Header(Message):
    """std_msgs/msg/Header: ``stamp`` and ``frame_id``."""

    __slots__ = ('stamp', 'frame_id')
    _TYPE = 'std_msgs/msg/Header'
    _FIELDS = (('stamp', 'builtin_interfaces/msg/Time'), ('frame_id', 'string'))
    _HASH = 'RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01'


class String(Message):
    """std_msgs/msg/String: ``data``."""

    __slots__ = ('data',)
    _TYPE = 'std_msgs/msg/String'
    _FIELDS = (('data', 'string'),)
    _HASH = 'RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18'


class Bool(Message):
    """std_msgs/msg/Bool: ``data``."""

    __slots__ = ('data',)
    _TYPE = 'std_msgs/msg/Bool'
    _FIELDS = (('data', 'bool'),)
    _HASH = 'RIHS01_feb91e995ff9ebd09c0cb3d2aed18b11077585839fb5db80193b62d74528f6c9'


class MultiArrayDimension(Message):
    """std_msgs/msg/MultiArrayDimension: ``label``, ``size``, ``stride``."""

    __slots__ = ('label', 'size', 'stride')
    _TYPE = 'std_msgs/msg/MultiArrayDimension'
    _FIELDS = (('label', 'string'), ('size', 'uint32'), ('stride', 'uint32'))
    _HASH = 'RIHS01_5e773a60a4c7fc8a54985f307c7837aa2994252a126c301957a24e31282c9cbe'


class MultiArrayLayout(Message):
    """std_msgs/msg/MultiArrayLayout: ``dim`` and ``data_offset``."""

    __slots__ = ('dim', 'data_offset')
    _TYPE = 'std_msgs/msg/MultiArrayLayout'
    _FIELDS = (('dim', 'std_msgs/msg/MultiArrayDimension[]'), ('data_offset', 'uint32'))
    _HASH = 'RIHS01_4c66e6f78e740ac103a94cf63259f968e48c617e7699e829b63c21a5cb50dac6'


class Float64MultiArray(Message):
    """std_msgs/msg/Float64MultiArray: ``layout`` and ``data``."""

    __slots__ = ('layout', 'data')
    _TYPE = 'std_msgs/msg/Float64MultiArray'
    _FIELDS = (('layout', 'std_msgs/msg/MultiArrayLayout'), ('data', 'float64[]'))
    _HASH = 'RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f'


# sensor_msgs ----------------------------------------------------------------------------------

class JointState(Message):
    """sensor_msgs/msg/JointState: ``name``, ``position`` [rad|m], ``velocity``, ``effort``."""

    __slots__ = ('header', 'name', 'position', 'velocity', 'effort')
    _TYPE = 'sensor_msgs/msg/JointState'
    _FIELDS = (('header', 'std_msgs/msg/Header'), ('name', 'string[]'),
               ('position', 'float64[]'), ('velocity', 'float64[]'), ('effort', 'float64[]'))
    _HASH = 'RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e'


# trajectory_msgs ------------------------------------------------------------------------------

class JointTrajectoryPoint(Message):
    """trajectory_msgs/msg/JointTrajectoryPoint.

    Fields ``positions``, ``velocities``, ``accelerations``, ``effort``,
    ``time_from_start`` (Duration).
    """

    __slots__ = ('positions', 'velocities', 'accelerations', 'effort', 'time_from_start')
    _TYPE = 'trajectory_msgs/msg/JointTrajectoryPoint'
    _FIELDS = (('positions', 'float64[]'), ('velocities', 'float64[]'),
               ('accelerations', 'float64[]'), ('effort', 'float64[]'),
               ('time_from_start', 'builtin_interfaces/msg/Duration'))
    _HASH = 'RIHS01_de8907036d8bd45aac6f30cc9044a3d4a329c42cbf719aff7d95a584cfa532d7'


class JointTrajectory(Message):
    """trajectory_msgs/msg/JointTrajectory: ``header``, ``joint_names``, ``points``."""

    __slots__ = ('header', 'joint_names', 'points')
    _TYPE = 'trajectory_msgs/msg/JointTrajectory'
    _FIELDS = (('header', 'std_msgs/msg/Header'), ('joint_names', 'string[]'),
               ('points', 'trajectory_msgs/msg/JointTrajectoryPoint[]'))
    _HASH = 'RIHS01_179b33eba59d676f6d967ac71fe35e7ca2f64b2f3928f4a018cec115e213796e'


# geometry_msgs --------------------------------------------------------------------------------

class Vector3(Message):
    """geometry_msgs/msg/Vector3: ``x``, ``y``, ``z``."""

    __slots__ = ('x', 'y', 'z')
    _TYPE = 'geometry_msgs/msg/Vector3'
    _FIELDS = (('x', 'float64'), ('y', 'float64'), ('z', 'float64'))
    _HASH = 'RIHS01_cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d'


class Point(Message):
    """geometry_msgs/msg/Point: ``x``, ``y``, ``z`` [m]."""

    __slots__ = ('x', 'y', 'z')
    _TYPE = 'geometry_msgs/msg/Point'
    _FIELDS = (('x', 'float64'), ('y', 'float64'), ('z', 'float64'))
    _HASH = 'RIHS01_6963084842a9b04494d6b2941d11444708d892da2f4b09843b9c43f42a7f6881'


class Quaternion(Message):
    """geometry_msgs/msg/Quaternion: ``x``, ``y``, ``z``, ``w`` (``w`` defaults to 1)."""

    __slots__ = ('x', 'y', 'z', 'w')
    _TYPE = 'geometry_msgs/msg/Quaternion'
    _FIELDS = (('x', 'float64'), ('y', 'float64'), ('z', 'float64'), ('w', 'float64'))
    _DEFAULTS = {'w': 1.0}
    _HASH = 'RIHS01_8a765f66778c8ff7c8ab94afcc590a2ed5325a1d9a076ffff38fbce36f458684'


class Pose(Message):
    """geometry_msgs/msg/Pose: ``position`` and ``orientation``."""

    __slots__ = ('position', 'orientation')
    _TYPE = 'geometry_msgs/msg/Pose'
    _FIELDS = (('position', 'geometry_msgs/msg/Point'),
               ('orientation', 'geometry_msgs/msg/Quaternion'))
    _HASH = 'RIHS01_d501954e9476cea2996984e812054b68026ae0bfae789d9a10b23daf35cc90fa'


class PoseStamped(Message):
    """geometry_msgs/msg/PoseStamped: ``header`` and ``pose``."""

    __slots__ = ('header', 'pose')
    _TYPE = 'geometry_msgs/msg/PoseStamped'
    _FIELDS = (('header', 'std_msgs/msg/Header'), ('pose', 'geometry_msgs/msg/Pose'))
    _HASH = 'RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8'


class Wrench(Message):
    """geometry_msgs/msg/Wrench: ``force`` [N] and ``torque`` [Nm]."""

    __slots__ = ('force', 'torque')
    _TYPE = 'geometry_msgs/msg/Wrench'
    _FIELDS = (('force', 'geometry_msgs/msg/Vector3'), ('torque', 'geometry_msgs/msg/Vector3'))
    _HASH = 'RIHS01_018e8519d57c16adbe97c9fe1460ef21fec7e31bc541de3d653a35895677ce52'


class WrenchStamped(Message):
    """geometry_msgs/msg/WrenchStamped: ``header`` and ``wrench``."""

    __slots__ = ('header', 'wrench')
    _TYPE = 'geometry_msgs/msg/WrenchStamped'
    _FIELDS = (('header', 'std_msgs/msg/Header'), ('wrench', 'geometry_msgs/msg/Wrench'))
    _HASH = 'RIHS01_8dc3deaf06b2ab281f9f9a742a8961c328ca7cec16e3fd6586d3a5c83fa78f77'


# std_msgs / sensor_msgs / visualization_msgs: markers (spg/markers) ---------------------------

class ColorRGBA(Message):
    """std_msgs/msg/ColorRGBA: ``r``, ``g``, ``b``, ``a`` in [0, 1] (float32)."""

    __slots__ = ('r', 'g', 'b', 'a')
    _TYPE = 'std_msgs/msg/ColorRGBA'
    _FIELDS = (('r', 'float32'), ('g', 'float32'), ('b', 'float32'), ('a', 'float32'))
    _HASH = 'RIHS01_77a7a5b9ae477306097665106e0413ba74440245b1f3d0c6d6405fe5c7813fe8'


class CompressedImage(Message):
    """sensor_msgs/msg/CompressedImage: ``header``, ``format``, ``data`` (uint8[])."""

    __slots__ = ('header', 'format', 'data')
    _TYPE = 'sensor_msgs/msg/CompressedImage'
    _FIELDS = (('header', 'std_msgs/msg/Header'), ('format', 'string'), ('data', 'uint8[]'))
    _HASH = 'RIHS01_15640771531571185e2efc8a100baf923961a4d15d5569652e6cb6691e8e371a'


class UVCoordinate(Message):
    """visualization_msgs/msg/UVCoordinate: ``u``, ``v`` (float32)."""

    __slots__ = ('u', 'v')
    _TYPE = 'visualization_msgs/msg/UVCoordinate'
    _FIELDS = (('u', 'float32'), ('v', 'float32'))
    _HASH = 'RIHS01_f27f7ed21fe360c6066944f856b801a0c0d1e94e815b6886444b42d90b196a26'


class MeshFile(Message):
    """visualization_msgs/msg/MeshFile: ``filename`` and ``data`` (uint8[])."""

    __slots__ = ('filename', 'data')
    _TYPE = 'visualization_msgs/msg/MeshFile'
    _FIELDS = (('filename', 'string'), ('data', 'uint8[]'))
    _HASH = 'RIHS01_7710ece15a148fb7c9b546364cfb215bb06098087bd6394fe5b73a493508f8c4'


class Marker(Message):
    """visualization_msgs/msg/Marker (Jazzy): a shape, its pose, scale and colour.

    ``type`` is one of the class constants ARROW ... ARROW_STRIP, ``action`` ADD, DELETE or
    DELETEALL.
    """

    __slots__ = ('header', 'ns', 'id', 'type', 'action', 'pose', 'scale', 'color', 'lifetime',
                 'frame_locked', 'points', 'colors', 'texture_resource', 'texture',
                 'uv_coordinates', 'text', 'mesh_resource', 'mesh_file',
                 'mesh_use_embedded_materials')
    _TYPE = 'visualization_msgs/msg/Marker'
    _FIELDS = (('header', 'std_msgs/msg/Header'), ('ns', 'string'), ('id', 'int32'),
               ('type', 'int32'), ('action', 'int32'), ('pose', 'geometry_msgs/msg/Pose'),
               ('scale', 'geometry_msgs/msg/Vector3'), ('color', 'std_msgs/msg/ColorRGBA'),
               ('lifetime', 'builtin_interfaces/msg/Duration'), ('frame_locked', 'bool'),
               ('points', 'geometry_msgs/msg/Point[]'), ('colors', 'std_msgs/msg/ColorRGBA[]'),
               ('texture_resource', 'string'), ('texture', 'sensor_msgs/msg/CompressedImage'),
               ('uv_coordinates', 'visualization_msgs/msg/UVCoordinate[]'), ('text', 'string'),
               ('mesh_resource', 'string'), ('mesh_file', 'visualization_msgs/msg/MeshFile'),
               ('mesh_use_embedded_materials', 'bool'))
    _HASH = 'RIHS01_45b13ccf791f225962bf74e746f9644518855d783a6f42ba0cc14fde2b4f3ce0'
    ARROW, CUBE, SPHERE, CYLINDER, LINE_STRIP, LINE_LIST = 0, 1, 2, 3, 4, 5
    CUBE_LIST, SPHERE_LIST, POINTS, TEXT_VIEW_FACING, MESH_RESOURCE = 6, 7, 8, 9, 10
    TRIANGLE_LIST, ARROW_STRIP = 11, 12
    ADD, MODIFY, DELETE, DELETEALL = 0, 0, 2, 3


class MarkerArray(Message):
    """visualization_msgs/msg/MarkerArray: ``markers``."""

    __slots__ = ('markers',)
    _TYPE = 'visualization_msgs/msg/MarkerArray'
    _FIELDS = (('markers', 'visualization_msgs/msg/Marker[]'),)
    _HASH = 'RIHS01_86cb8800b6fb05b5eff1abd7a56f62a5641d3ae9a1c29e78e67e704f1d067dcf'


# diagnostic_msgs ------------------------------------------------------------------------------

class KeyValue(Message):
    """diagnostic_msgs/msg/KeyValue: ``key`` and ``value``."""

    __slots__ = ('key', 'value')
    _TYPE = 'diagnostic_msgs/msg/KeyValue'
    _FIELDS = (('key', 'string'), ('value', 'string'))
    _HASH = 'RIHS01_d68081eaa540288c5440753baecef0c4e16e81a5f78ad68902ded5100413bb42'


class DiagnosticStatus(Message):
    """diagnostic_msgs/msg/DiagnosticStatus: ``level`` (bytes: OK, WARN, ERROR, STALE), texts."""

    __slots__ = ('level', 'name', 'message', 'hardware_id', 'values')
    _TYPE = 'diagnostic_msgs/msg/DiagnosticStatus'
    _FIELDS = (('level', 'byte'), ('name', 'string'), ('message', 'string'),
               ('hardware_id', 'string'), ('values', 'diagnostic_msgs/msg/KeyValue[]'))
    _HASH = 'RIHS01_b0e3e692ea2d54a8af2f4ef1930e81556a2db55216b771f8a7d2724ed47bf0e4'
    OK = b'\x00'
    WARN = b'\x01'
    ERROR = b'\x02'
    STALE = b'\x03'


class DiagnosticArray(Message):
    """diagnostic_msgs/msg/DiagnosticArray: ``header`` and ``status`` list."""

    __slots__ = ('header', 'status')
    _TYPE = 'diagnostic_msgs/msg/DiagnosticArray'
    _FIELDS = (('header', 'std_msgs/msg/Header'),
               ('status', 'diagnostic_msgs/msg/DiagnosticStatus[]'))
    _HASH = 'RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e'


# rmw_dds_common (graph discovery, ``ros_discovery_info``) -------------------------------------

class Gid(Message):
    """rmw_dds_common/msg/Gid: 16 bytes, the DDS GUID of an entity (Jazzy layout)."""

    __slots__ = ('data',)
    _TYPE = 'rmw_dds_common/msg/Gid'
    _FIELDS = (('data', 'char[16]'),)
    _HASH = 'RIHS01_ab6f21cfbb0a6dbb837161e1110c2051a2850ed9f9c53944d7115d9bcebedf71'


class NodeEntitiesInfo(Message):
    """rmw_dds_common/msg/NodeEntitiesInfo: one node and the gids of its readers/writers."""

    __slots__ = ('node_namespace', 'node_name', 'reader_gid_seq', 'writer_gid_seq')
    _TYPE = 'rmw_dds_common/msg/NodeEntitiesInfo'
    _FIELDS = (('node_namespace', 'string<=256'), ('node_name', 'string<=256'),
               ('reader_gid_seq', 'rmw_dds_common/msg/Gid[]'),
               ('writer_gid_seq', 'rmw_dds_common/msg/Gid[]'))
    _HASH = 'RIHS01_8ffef65ee2d088c63b1e8fcd31e800ba9fc8dbe0ee15ca60d1676de5218087a7'


class ParticipantEntitiesInfo(Message):
    """rmw_dds_common/msg/ParticipantEntitiesInfo: a participant's gid and its nodes."""

    __slots__ = ('gid', 'node_entities_info_seq')
    _TYPE = 'rmw_dds_common/msg/ParticipantEntitiesInfo'
    _FIELDS = (('gid', 'rmw_dds_common/msg/Gid'),
               ('node_entities_info_seq', 'rmw_dds_common/msg/NodeEntitiesInfo[]'))
    _HASH = 'RIHS01_91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e'
