"""Plain CDR (XCDR1, little endian) codecs generated from ROS 2 message field tables.

The wire format is the one ``rmw_cyclonedds_cpp`` writes on Jazzy and ``rosbags`` serializes:
a 4-byte encapsulation header ``00 01 00 00`` (CDR_LE) followed by the fields in declaration
order, each primitive aligned to ``min(size, 8)`` relative to the end of the header; a string
is a uint32 length counting the terminating NUL, the UTF-8 bytes and the NUL; a sequence is a
uint32 count followed by its elements, with no alignment padding when the count is zero.

For speed every message class gets a specialised ``serialize``/``deserialize`` pair compiled
from its field table: nested messages are inlined, runs of fixed-size fields whose alignment is
known statically are packed with one ``struct`` call, and numeric sequences go through
``array.array`` buffers. A 7-joint ``JointState`` (de)serializes in a few microseconds.
"""

import array
import struct
import sys
from typing import Any

import numpy as np

from ifc_spg.errors import ParameterError

__all__ = ['CDR_HEADER', 'PRIMITIVES', 'parse_field_type', 'compile_codec']

CDR_HEADER = b'\x00\x01\x00\x00'

# name -> (struct code, size [bytes], array typecode or None)
PRIMITIVES = {
    'bool': ('?', 1, None),
    'byte': ('c', 1, None),
    'char': ('B', 1, 'B'),
    'int8': ('b', 1, 'b'),
    'uint8': ('B', 1, 'B'),
    'int16': ('h', 2, 'h'),
    'uint16': ('H', 2, 'H'),
    'int32': ('i', 4, 'i'),
    'uint32': ('I', 4, 'I'),
    'int64': ('q', 8, 'q'),
    'uint64': ('Q', 8, 'Q'),
    'float32': ('f', 4, 'f'),
    'float64': ('d', 8, 'd'),
}

_LITTLE = sys.byteorder == 'little'
if _LITTLE:
    for _code in ('b', 'B', 'h', 'H', 'i', 'I', 'q', 'Q', 'f', 'd'):
        if array.array(_code).itemsize != struct.calcsize(_code):  # pragma: no cover
            _LITTLE = False


def parse_field_type(spec):
    """Split a ROS 2 field type string into its parts.

    Args:
        spec: e.g. ``'float64'``, ``'string<=256'``, ``'float64[]'``, ``'char[16]'``,
            ``'std_msgs/msg/Header'``, ``'diagnostic_msgs/msg/KeyValue[]'``.

    Returns:
        ``(base, kind, length)`` with kind ``'single'``, ``'sequence'`` or ``'array'`` and length
        the fixed array size or sequence bound (0 = unbounded). String bounds are dropped (they do
        not change the wire format).
    """
    kind, length, base = 'single', 0, spec
    if base.endswith(']'):
        base, _, inner = base[:-1].partition('[')
        if inner == '':
            kind = 'sequence'
        elif inner.startswith('<='):
            kind, length = 'sequence', int(inner[2:])
        else:
            kind, length = 'array', int(inner)
    if base.startswith('string'):
        base = 'string'
    if base not in PRIMITIVES and base != 'string' and base.count('/') != 2:
        raise ParameterError(f"unknown ROS 2 field type '{spec}'; expected a primitive "
                             f"({', '.join(PRIMITIVES)}), string or 'pkg/msg/Type'")
    return base, kind, length


class _Gen:
    """Source generator with static alignment tracking.

    ``self.mod``/``self.res``: the write offset (relative to the end of the CDR header) is known
    to be ``res`` modulo ``mod`` (``mod`` in 1, 2, 4, 8).
    """

    def __init__(self, env, indent):
        self.lines = []
        self.env = env
        self.indent = indent
        self.mod, self.res = 8, 0
        self.counter = env.setdefault('_counter_', [0])

    def tmp(self, stem):
        self.counter[0] += 1
        return f'_{stem}{self.counter[0]}'

    def emit(self, line):
        self.lines.append('    ' * self.indent + line)

    def const(self, value, stem='_K'):
        for key, existing in self.env.items():
            if existing is value:
                return key
        name = self.tmp(stem)
        self.env[name] = value
        return name

    def struct_const(self, fmt):
        key = '_S_' + ''.join(c if c.isalnum() else '_' for c in fmt)
        if key not in self.env:
            self.env[key] = struct.Struct('<' + fmt)
        return key

    def static_pad(self, align):
        """Return the static padding before an item of ``align``, or None if not known."""
        if align <= self.mod:
            return (-self.res) % align
        return None

    def _after_numbers(self, kind, length, align, size):
        """Alignment state after a numeric array/sequence.

        A sequence starts 4-aligned (its count) and its elements keep ``min(size, 4)`` alignment,
        whatever the count, so the offset is known modulo ``min(size, 4)`` afterwards.
        """
        if kind == 'array' and length:
            self.advance(align, size * length)
        elif kind == 'array':
            pass
        else:
            self.mod, self.res = min(size, 4), 0

    def advance(self, align, size):
        pad = self.static_pad(align)
        if pad is None:
            self.mod, self.res = align, size % align
        else:
            self.res = (self.res + pad + size) % self.mod

    def unknown(self):
        self.mod, self.res = 1, 0


def _align_of(base):
    return min(PRIMITIVES[base][1], 8)


class _SerGen(_Gen):
    """Generates ``def ser(m, b)`` appending CDR bytes of ``m`` to bytearray ``b``."""

    def __init__(self, env, indent, registry):
        super().__init__(env, indent)
        self.registry = registry
        self.fmt, self.vals = '', []

    def flush(self):
        if self.fmt:
            key = self.struct_const(self.fmt)
            self.emit(f'b += {key}.pack({", ".join(self.vals)})')
            self.fmt, self.vals = '', []

    def runtime_align(self, align):
        if align > 1:
            self.emit(f'b += _Z[(4 - len(b)) & {align - 1}]')

    def primitive(self, base, expr):
        code, size, _ = PRIMITIVES[base]
        align = _align_of(base)
        pad = self.static_pad(align)
        if pad is None:
            self.flush()
            self.runtime_align(align)
            pad = 0
        self.fmt += 'x' * pad + code
        self.vals.append(f'_byte1({expr})' if base == 'byte' else expr)
        self.advance(align, size)

    def string(self, expr):
        s = self.tmp('s')
        self.flush()
        self.emit(f'{s} = {expr}.encode()')
        pad = self.static_pad(4)
        if pad is None:
            self.runtime_align(4)
        elif pad:
            self.emit(f'b += _Z[{pad}]')
        self.emit(f'b += _U32.pack(len({s}) + 1)')
        self.emit(f'b += {s}')
        self.emit("b += b'\\x00'")
        self.unknown()

    def count(self, expr):
        """uint32 length prefix of a sequence; returns nothing, keeps the pending pack open."""
        self.primitive('uint32', f'len({expr})')

    def field(self, ftype, expr):
        """Write one field, the value of ``expr``."""
        base, kind, length = parse_field_type(ftype)
        if kind == 'single':
            if base == 'string':
                self.string(expr)
            elif base in PRIMITIVES:
                self.primitive(base, expr)
            else:
                self.message(base, expr)
            return
        x = self.tmp('x')
        self.flush()
        self.emit(f'{x} = {expr}')
        if kind == 'sequence':
            if length:
                self.emit(f'if len({x}) > {length}:')
                self.emit(f'    _too_long({x!r}, len({x}), {length})')
            self.count(x)
        else:
            self.emit(f'if len({x}) != {length}:')
            self.emit(f'    _bad_array({x!r}, len({x}), {length})')
        self.flush()
        if base in PRIMITIVES and base not in ('bool', 'byte'):
            self._numbers(base, kind, length, x)
            return
        self._elements(base, x)

    def _numbers(self, base, kind, length, x):
        """A sequence or array of numbers ``x``, aligned, in one piece."""
        code, size, tcode = PRIMITIVES[base]
        align = _align_of(base)
        if kind == 'array' and length:
            pad = self.static_pad(align)
            if pad is None:
                self.runtime_align(align)
            elif pad:
                self.emit(f'b += _Z[{pad}]')
        elif align > 4:
            self.emit(f'if len({x}):')
            self.emit(f'    b += _Z[(4 - len(b)) & {align - 1}]')
        self.emit(f'b += _seq_bytes({x}, {tcode!r}, {code!r})')
        self._after_numbers(kind, length, align, size)

    def _elements(self, base, x):
        """Bool / byte / string / message sequences: element by element."""
        item = self.tmp('e')
        self.emit(f'for {item} in {x}:')
        self.indent += 1
        self.mod, self.res = 1, 0
        if base == 'string':
            self.string(item)
        elif base in PRIMITIVES:
            self.primitive(base, item)
            self.flush()
        else:
            self.emit(f'_ser_{_ident(base)}({item}, b)')
        self.indent -= 1
        self.unknown()

    def message(self, typename, expr):
        cls = self.registry[typename]
        for name, ftype in cls._FIELDS:
            self.field(ftype, f'{expr}.{name}')
        if not cls._FIELDS:  # empty messages carry one structure_needs_at_least_one_member byte
            self.primitive('uint8', '0')


class _DeGen(_Gen):
    """Generates ``def de(v, p) -> (msg, p)`` reading CDR from memoryview ``v`` at ``p``."""

    def __init__(self, env, indent, registry):
        super().__init__(env, indent)
        self.registry = registry
        self.fmt, self.targets = '', []

    def flush(self):
        if self.fmt:
            key = self.struct_const(self.fmt)
            size = self.env[key].size
            targets = ', '.join(self.targets)
            self.emit(f'{targets}, = {key}.unpack_from(v, p)')
            self.emit(f'p += {size}')
            self.fmt, self.targets = '', []

    def runtime_align(self, align):
        if align > 1:
            self.emit(f'p += -p & {align - 1}')

    def primitive(self, base, target):
        code, size, _ = PRIMITIVES[base]
        align = _align_of(base)
        pad = self.static_pad(align)
        if pad is None:
            self.flush()
            self.runtime_align(align)
            pad = 0
        self.fmt += 'x' * pad + code
        self.targets.append(target)
        self.advance(align, size)

    def string(self, target):
        n = self.tmp('n')
        self.primitive('uint32', n)
        self.flush()
        self.emit(f'{target} = _str(v[p:p + {n} - 1], "utf-8")')
        self.emit(f'p += {n}')
        self.unknown()

    def field(self, ftype, target):
        """Read one field into ``target`` (an attribute expression or local name)."""
        base, kind, length = parse_field_type(ftype)
        if kind == 'single':
            self._single(base, target)
            return
        n = self.tmp('n')
        if kind == 'sequence':
            self.primitive('uint32', n)
            self.flush()
        else:
            self.flush()
            self.emit(f'{n} = {length}')
        if base in PRIMITIVES and base not in ('bool', 'byte'):
            self._numbers(base, kind, length, n, target)
            return
        self._elements(base, n, target)

    def _single(self, base, target):
        """Read one value of type ``base`` into ``target``."""
        if base == 'string':
            self.string(target)
        elif base == 'byte':
            t = self.tmp('c')
            self.primitive(base, t)
            self.flush()
            self.emit(f'{target} = {t}')
        elif base in PRIMITIVES:
            self.primitive(base, target)
        else:
            self.message(base, target)

    def _numbers(self, base, kind, length, n, target):
        """Read ``n`` numbers into ``target`` in one piece, aligned."""
        code, size, tcode = PRIMITIVES[base]
        align = _align_of(base)
        if kind == 'array' and length:
            pad = self.static_pad(align)
            if pad is None:
                self.runtime_align(align)
            elif pad:
                self.emit(f'p += {pad}')
        elif align > 4:
            self.emit(f'if {n}:')
            self.emit(f'    p += -p & {align - 1}')
        self.emit(f'{target} = _seq_from(v, p, {n}, {tcode!r}, {code!r}, {size})')
        self.emit(f'p += {n} * {size}')
        self._after_numbers(kind, length, align, size)

    def _elements(self, base, n, target):
        """Read ``n`` bools / bytes / strings / messages into the list ``target``."""
        lst = self.tmp('l')
        item = self.tmp('e')
        self.emit(f'{lst} = []')
        self.emit(f'for _ in range({n}):')
        self.indent += 1
        self.mod, self.res = 1, 0
        if base == 'string':
            self.string(item)
        elif base in PRIMITIVES:
            self.primitive(base, item)
            self.flush()
        else:
            self.emit(f'{item}, p = _de_{_ident(base)}(v, p)')
        self.emit(f'{lst}.append({item})')
        self.indent -= 1
        self.unknown()
        self.emit(f'{target} = {lst}')

    def message(self, typename, target):
        cls = self.registry[typename]
        obj = self.tmp('o')
        self.emit(f'{obj} = _new({self.const(cls, "_C")})')
        self.emit(f'{target} = {obj}')
        for name, ftype in cls._FIELDS:
            self.field(ftype, f'{obj}.{name}')
        if not cls._FIELDS:
            self.primitive('uint8', '_')


def _ident(typename):
    return typename.replace('/', '__')


def _byte1(value):
    """A ROS ``byte`` as rclpy holds it (``bytes`` of length 1), also accepting an int."""
    if isinstance(value, int):
        return bytes((value,))
    return value


def _too_long(expr, n, bound):
    raise ParameterError(f'{expr}: sequence of length {n} exceeds its bound {bound}')


def _bad_array(expr, n, size):
    raise ParameterError(f'{expr}: fixed array needs exactly {size} elements, got {n}')


def _seq_bytes(seq, tcode, code):
    """Little-endian bytes of a numeric sequence (array.array, numpy array, list, bytes)."""
    if _LITTLE:
        if type(seq) is array.array and seq.typecode == tcode:
            return seq.tobytes()
        if isinstance(seq, np.ndarray):
            return np.ascontiguousarray(seq, dtype=array.array(tcode).typecode).tobytes()
        if tcode == 'B' and isinstance(seq, (bytes, bytearray)):
            return bytes(seq)
    return struct.pack(f'<{len(seq)}{code}', *seq)


def _seq_from(view, pos, n, tcode, code, size):
    """An ``array.array`` of ``n`` numbers read from ``view`` at ``pos``."""
    if _LITTLE:
        out = array.array(tcode)
        out.frombytes(view[pos:pos + n * size])
        return out
    return array.array(tcode, struct.unpack_from(f'<{n}{code}', view, pos))  # pragma: no cover


def _nested_sequences(cls, registry):
    """The message types used in sequences or arrays anywhere inside ``cls`` (own codecs)."""
    nested = set()

    def collect(c):
        for _, ftype in c._FIELDS:
            base, kind, _ = parse_field_type(ftype)
            if base in PRIMITIVES or base == 'string':
                continue
            if base not in registry:
                raise ParameterError(f"message type '{base}' used by '{c._TYPE}' is not "
                                     'registered')
            if kind != 'single':
                nested.add(base)
            collect(registry[base])

    collect(cls)
    return nested


def _codec_source(env, registry, typename, top):
    """Source lines of ``_ser_<type>`` and ``_de_<type>``; ``top``: the alignment is known."""
    c = registry[typename]
    ser = _SerGen(env, 1, registry)
    if not top:
        ser.mod, ser.res = 1, 0
    ser.message(typename, 'm')
    ser.flush()
    de = _DeGen(env, 1, registry)
    if not top:
        de.mod, de.res = 1, 0
    de.message(typename, '_r')
    de.flush()
    ident = _ident(c._TYPE)
    return [f'def _ser_{ident}(m, b):', *(ser.lines or ['    pass']),
            f'def _de_{ident}(v, p):', *de.lines, '    return _r, p']


def compile_codec(cls, registry):
    """Compile ``serialize``/``deserialize`` functions for message class ``cls``.

    Args:
        cls: A message class with ``_TYPE`` (``'pkg/msg/Name'``) and ``_FIELDS`` (tuple of
            ``(name, type string)``).
        registry: Mapping type name -> class, holding every nested type.

    Returns:
        ``(ser, de)``: ``ser(msg, b)`` appends the payload of ``msg`` to bytearray ``b`` (which
        already holds the 4-byte CDR header); ``de(view, pos)`` reads a message from memoryview
        ``view`` of the payload (header stripped) and returns ``(msg, new_pos)``.
    """
    env: dict[str, Any] = {
        '_Z': tuple(b'\0' * i for i in range(8)),
        '_U32': struct.Struct('<I'),
        '_byte1': _byte1,
        '_too_long': _too_long,
        '_bad_array': _bad_array,
        '_seq_bytes': _seq_bytes,
        '_seq_from': _seq_from,
        '_str': str,
        '_new': object.__new__,
    }
    types = [cls._TYPE] + sorted(_nested_sequences(cls, registry) - {cls._TYPE})
    src = []
    for typename in types:
        src.extend(_codec_source(env, registry, typename, top=typename == cls._TYPE))
    code = '\n'.join(src) + '\n'
    exec(compile(code, f'<cdr codec {cls._TYPE}>', 'exec'), env)  # noqa: S102 - generated here
    ident = _ident(cls._TYPE)
    ser_fn, de_fn = env[f'_ser_{ident}'], env[f'_de_{ident}']
    ser_fn.__source__ = de_fn.__source__ = code
    return ser_fn, de_fn
