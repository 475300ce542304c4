"""CDR bytes of the built-in message classes equal rosbags' (Stores.ROS2_JAZZY) bytes."""

import array
import random
import struct

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from ifc_spg.errors import ParameterError
from ifc_spg.ros import messages
from ifc_spg.ros.cdr import PRIMITIVES, parse_field_type
from ifc_spg.ros.messages import REGISTRY, deserialize, serialize

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
N_RANDOM = 1000
PUBLIC_TYPES = [name for name in REGISTRY if not name.startswith('rmw_dds_common/')]
ALL_TYPES = list(REGISTRY)
CHARS = 'abcXYZ019 _-/.:äπ漢😀\t\n"\''
INT_RANGES = {
    'int8': (-2**7, 2**7 - 1), 'uint8': (0, 255), 'char': (0, 255),
    'int16': (-2**15, 2**15 - 1), 'uint16': (0, 2**16 - 1),
    'int32': (-2**31, 2**31 - 1), 'uint32': (0, 2**32 - 1),
    'int64': (-2**63, 2**63 - 1), 'uint64': (0, 2**64 - 1),
}
NUMPY_DTYPES = {'float64': np.float64, 'float32': np.float32, 'uint8': np.uint8,
                'char': np.uint8, 'int32': np.int32, 'uint32': np.uint32}


def random_float(rng, fmt):
    """A finite float, exactly representable in ``fmt`` ('d' or 'f'), often extreme."""
    size = struct.calcsize(fmt)
    while True:
        if rng.random() < 0.5:
            value = struct.unpack('<' + fmt, struct.pack('<' + fmt, rng.uniform(-1e3, 1e3)))[0]
        else:
            value = struct.unpack('<' + fmt, rng.randbytes(size))[0]
        if np.isfinite(value):
            return value


def random_primitive(rng, base):
    if base == 'string':
        return ''.join(rng.choice(CHARS) for _ in range(rng.randint(0, 12)))
    if base == 'bool':
        return rng.random() < 0.5
    if base == 'byte':
        return bytes((rng.randint(0, 255),))
    if base in ('float64', 'float32'):
        return random_float(rng, PRIMITIVES[base][0])
    low, high = INT_RANGES[base]
    return rng.randint(low, high)


def random_value(rng, ftype):
    base, kind, length = parse_field_type(ftype)
    if kind == 'single':
        if base in PRIMITIVES or base == 'string':
            return random_primitive(rng, base)
        return random_message(rng, base)
    n = length if kind == 'array' else rng.choice([0, 0, 1, 2, 3, 7])
    items = [random_value(rng, base) for _ in range(n)]
    code = PRIMITIVES.get(base, (None, None, None))[2]
    if code is not None:
        return array.array(code, items)
    return items


def random_message(rng, typename):
    cls = REGISTRY[typename]
    return cls(**{name: random_value(rng, ftype) for name, ftype in cls._FIELDS})


def to_rosbags(value, ftype):
    """Convert one of our values to the rosbags representation."""
    base, kind, _ = parse_field_type(ftype)
    if kind == 'single':
        if base == 'byte':  # rosbags holds a ROS byte as a signed int
            return struct.unpack('b', value)[0]
        if base in PRIMITIVES or base == 'string':
            return value
        cls = REGISTRY[base]
        rb_cls = TYPESTORE.types[base]
        return rb_cls(**{name: to_rosbags(getattr(value, name), t) for name, t in cls._FIELDS})
    if base in NUMPY_DTYPES:
        return np.array(list(value), dtype=NUMPY_DTYPES[base])
    return [to_rosbags(item, base) for item in value]


def from_rosbags(value, ftype):
    """Convert a rosbags value to our representation."""
    base, kind, _ = parse_field_type(ftype)
    if kind == 'single':
        if base == 'byte':
            return struct.pack('b', value)
        if base in PRIMITIVES or base == 'string':
            return value
        cls = REGISTRY[base]
        return cls(**{name: from_rosbags(getattr(value, name), t) for name, t in cls._FIELDS})
    code = PRIMITIVES.get(base, (None, None, None))[2]
    if code is not None:
        return array.array(code, [v.item() if hasattr(v, 'item') else v for v in value])
    return [from_rosbags(item, base) for item in value]


@pytest.mark.parametrize('typename', ALL_TYPES)
def test_cdr_bytes_equal_rosbags_both_ways(typename):
    rng = random.Random(f'cdr-{typename}')
    cls = REGISTRY[typename]
    for _ in range(N_RANDOM):
        msg = random_message(rng, typename)
        ours = serialize(msg)
        theirs = bytes(TYPESTORE.serialize_cdr(to_rosbags(msg, typename), typename))
        assert ours == theirs, msg
        # each side decodes the other's bytes
        assert deserialize(cls, theirs) == msg
        assert from_rosbags(TYPESTORE.deserialize_cdr(ours, typename), typename) == msg


@pytest.mark.parametrize('typename', ALL_TYPES)
def test_type_hash_and_dds_name(typename):
    cls = REGISTRY[typename]
    if not typename.startswith('rmw_dds_common/'):  # char fields: see test_ros_type_hashes
        assert cls._HASH == TYPESTORE.hash_rihs01(typename)
    pkg, _, name = typename.split('/')
    assert cls._DDS_TYPE == f'{pkg}::msg::dds_::{name}_'


@pytest.mark.parametrize('typename', PUBLIC_TYPES)
def test_field_names_match_ros_definition(typename):
    cls = REGISTRY[typename]
    consts, fields = TYPESTORE.fielddefs[typename]
    assert [name for name, _ in cls._FIELDS] == [name for name, _ in fields]
    for name, _, value in consts:
        ours = getattr(cls, name)
        assert (struct.unpack('b', ours)[0] if isinstance(ours, bytes) else ours) == value


def test_defaults_follow_rclpy():
    js = messages.JointState()
    assert js.header.stamp.sec == 0 and js.header.frame_id == ''
    assert isinstance(js.position, array.array) and js.position.typecode == 'd'
    assert js.name == []
    assert messages.Quaternion().w == 1.0
    assert messages.DiagnosticStatus().level == b'\x00'
    assert messages.Pose().orientation.w == 1.0


def test_sequence_inputs_list_numpy_array_agree():
    names = [f'j{i}' for i in range(7)]
    q = np.linspace(-1.0, 1.0, 7)
    from_numpy = messages.JointState(name=names, position=q, velocity=q * 2, effort=q * 3)
    from_list = messages.JointState(name=names, position=list(q), velocity=list(q * 2),
                                    effort=list(q * 3))
    assert serialize(from_numpy) == serialize(from_list)
    # assignment after construction (no conversion) serializes the same
    raw = messages.JointState(name=names)
    raw.position, raw.velocity, raw.effort = q, list(q * 2), tuple(q * 3)
    assert serialize(raw) == serialize(from_list)


def test_unknown_field_is_a_clear_error():
    with pytest.raises(ParameterError, match="JointState has no field 'positions'"):
        messages.JointState(positions=[1.0])


def test_truncated_bytes_are_a_clear_error():
    data = serialize(messages.JointState(name=['a'], position=[1.0]))
    with pytest.raises(ParameterError, match='cannot decode'):
        deserialize(messages.JointState, data[:-3])
    with pytest.raises(ParameterError, match='plain CDR'):
        deserialize(messages.JointState, b'\x00\x07\x00\x00' + data[4:])
