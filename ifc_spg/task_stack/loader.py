"""Safe loading of task-stack text (YAML or JSON) into plain data with source positions.

Untrusted text arrives on a topic, so loading is bounded: the text size is capped
(:data:`MAX_TEXT_BYTES`), YAML is composed with PyYAML's safe composer and constructed
here (no tags, no Python objects), aliases are expanded against a node budget
(:data:`MAX_NODES`; a "billion laughs" document fails fast instead of eating memory),
nesting depth is capped (:data:`MAX_DEPTH`), duplicate keys are rejected and NaN / inf
are refused. Plain YAML scalars are resolved like YAML 1.2 / JSON (``1e-3`` is a number,
``yes`` / ``on`` are strings).

:func:`load` returns a :class:`Document`: the data (dicts, lists, str, int, float, bool,
None) and a map from paths (``('tasks', 2, 'subspace')``) to 1-based (line, column).
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

import yaml

from ifc_spg.task_stack.errors import TaskStackError

__all__ = ['MAX_DEPTH', 'MAX_NODES', 'MAX_TEXT_BYTES', 'Document', 'load']

MAX_TEXT_BYTES = 256 * 1024
MAX_NODES = 20000
MAX_DEPTH = 24
MAX_STRING = 4096

_INT = re.compile(r'[-+]?(0|[1-9][0-9_]*)$')
_FLOAT = re.compile(r'[-+]?(\.[0-9]+|[0-9][0-9_]*(\.[0-9_]*)?)([eE][-+]?[0-9]+)?$')
_INF = re.compile(r'[-+]?\.(inf|Inf|INF)$')
_NAN = re.compile(r'\.(nan|NaN|NAN)$')
_NONFINITE = re.compile(r'[-+]?(inf|infinity|nan)$', re.IGNORECASE)
_NULL = ('', '~', 'null', 'Null', 'NULL')
_TRUE = ('true', 'True', 'TRUE')

#: A field's path, e.g. ``('tasks', 2, 'subspace')``; marks map paths to (line, column).
Path = tuple[str | int, ...]
Marks = dict[Path, tuple[int, int]]
_FALSE = ('false', 'False', 'FALSE')


class Document:
    """Loaded task-stack data with source positions.

    Attributes:
        data: The data (JSON types).
        marks: Path tuple -> (line, column), 1-based.
        source: Source name (file name) or None.
    """

    def __init__(self, data: Any, marks: Marks | None = None,
                 source: str | None = None) -> None:
        self.data = data
        self.marks = marks or {}
        self.source = source

    def mark(self, path: Path) -> tuple[int | None, int | None]:
        """(line, column) of the nearest enclosing node of ``path`` that has a position."""
        path = tuple(path)
        while True:
            if path in self.marks:
                return self.marks[path]
            if not path:
                return None, None
            path = path[:-1]

    def error(self, path: Path, reason: str) -> TaskStackError:
        """Return a :class:`TaskStackError` at ``path`` with its source position."""
        line, column = self.mark(path)
        return TaskStackError(reason, path, line, column, self.source)


def _check_size(text: Any, source: str | None) -> str:
    if isinstance(text, (bytes, bytearray)):
        if len(text) > MAX_TEXT_BYTES:
            raise TaskStackError(f'text is {len(text)} bytes, more than the limit of '
                                 f'{MAX_TEXT_BYTES} bytes (256 KiB); split the stack',
                                 source=source)
        try:
            text = bytes(text).decode('utf-8')
        except UnicodeDecodeError as exc:
            raise TaskStackError(f'text is not valid UTF-8 ({exc.reason} at byte '
                                 f'{exc.start})', source=source) from None
    if not isinstance(text, str):
        raise TaskStackError(f'expected the task stack as text (str), got '
                             f'{type(text).__name__}', source=source)
    size = len(text.encode('utf-8', errors='surrogatepass'))
    if size > MAX_TEXT_BYTES:
        raise TaskStackError(f'text is {size} bytes, more than the limit of {MAX_TEXT_BYTES} '
                             'bytes (256 KiB); split the stack', source=source)
    if '\x00' in text:
        raise TaskStackError('text contains a NUL character; task stacks are plain text',
                             source=source)
    return text


def load(text: str | bytes, fmt: str = 'auto', source: str | None = None) -> Document:
    """Load task-stack text.

    Args:
        text: YAML or JSON text (str, or UTF-8 bytes).
        fmt: 'yaml', 'json' or 'auto' (JSON if the text starts with '{', else YAML).
        source: Name used in error messages (a file name).

    Returns:
        A :class:`Document`.

    Raises:
        TaskStackError: On oversize text, a syntax error, a YAML bomb, NaN/inf, etc.
    """
    text = _check_size(text, source)
    if fmt not in ('auto', 'yaml', 'json'):
        raise TaskStackError(f"unknown format '{fmt}'; use 'yaml', 'json' or 'auto'",
                             source=source)
    if fmt == 'json' or (fmt == 'auto' and text.lstrip().startswith('{')):
        try:
            data = _load_json(text, source)
        except TaskStackError:
            if fmt == 'json':
                raise
            return _load_yaml(text, source)  # a YAML flow mapping also starts with '{'
        # positions: JSON is YAML, compose it again for line/column (best effort)
        try:
            marks = _load_yaml(text, source).marks
        except TaskStackError:
            marks = {}
        return Document(data, marks, source)
    return _load_yaml(text, source)


# -- JSON ------------------------------------------------------------------------------
def _reject_constant(name: str) -> None:
    raise ValueError(f'{name} is not allowed (numbers must be finite)')


def _load_json(text: str, source: str | None) -> Any:
    try:
        data = json.loads(text, parse_constant=_reject_constant,
                          object_pairs_hook=_json_object)
    except json.JSONDecodeError as exc:
        raise TaskStackError(f'invalid JSON: {exc.msg}', (), exc.lineno, exc.colno,
                             source) from None
    except ValueError as exc:
        raise TaskStackError(f'invalid JSON: {exc}', source=source) from None
    except RecursionError:
        raise TaskStackError(f'JSON nested too deeply (limit {MAX_DEPTH} levels)',
                             source=source) from None
    _check_json(data, 0, [0], source)
    return data


def _json_object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in pairs:
        if k in out:
            raise ValueError(f"duplicate key '{k}'")
        out[k] = v
    return out


def _check_json(x: Any, depth: int, count: list[int], source: str | None) -> None:
    count[0] += 1
    if count[0] > MAX_NODES:
        raise TaskStackError(f'document has more than {MAX_NODES} values; a task stack is '
                             'much smaller', source=source)
    if depth > MAX_DEPTH:
        raise TaskStackError(f'document nested too deeply (limit {MAX_DEPTH} levels)',
                             source=source)
    if isinstance(x, dict):
        for v in x.values():
            _check_json(v, depth + 1, count, source)
    elif isinstance(x, list):
        for v in x:
            _check_json(v, depth + 1, count, source)
    elif isinstance(x, float) and not math.isfinite(x):
        raise TaskStackError(f'number {x} is not finite', source=source)
    elif isinstance(x, str) and len(x) > MAX_STRING:
        raise TaskStackError(f'string of {len(x)} characters is longer than the limit of '
                             f'{MAX_STRING}', source=source)


# -- YAML ------------------------------------------------------------------------------
class _Composer(yaml.SafeLoader):
    """PyYAML's safe loader, used only up to the node graph (we construct ourselves)."""


_CComposer = getattr(yaml, 'CSafeLoader', None)
# libyaml's composer recurses on the C stack (a deeply nested document crashes the
# process), so it only gets texts whose nesting depth is surely small: every level needs
# a new line or one of these indicator characters.
_C_DEPTH_BOUND = 2000


def _composer(text: str) -> yaml.SafeLoader:
    if _CComposer is not None:
        bound = text.count('\n') + sum(text.count(c) for c in '[{-:?')
        if bound < _C_DEPTH_BOUND:
            return _CComposer(text)
    return _Composer(text)


def _load_yaml(text: str, source: str | None) -> Document:
    loader = _composer(text)
    try:
        node = loader.get_single_node()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        reason = ' '.join(str(s) for s in (exc.context, exc.problem) if s)
        raise TaskStackError(f'invalid YAML: {reason}', (),
                             None if mark is None else mark.line + 1,
                             None if mark is None else mark.column + 1, source) from None
    except yaml.YAMLError as exc:
        raise TaskStackError(f'invalid YAML: {exc}', source=source) from None
    except RecursionError:
        raise TaskStackError(f'YAML nested too deeply (limit {MAX_DEPTH} levels)',
                             source=source) from None
    finally:
        loader.dispose()
    if node is None:
        return Document(None, {(): (1, 1)}, source)
    marks: Marks = {}
    data = _construct(node, (), marks, [0], source)
    return Document(data, marks, source)


def _pos(node: yaml.Node) -> tuple[int, int]:
    return node.start_mark.line + 1, node.start_mark.column + 1


def _construct(node: yaml.Node, path: Path, marks: Marks, count: list[int],
               source: str | None) -> Any:
    count[0] += 1
    line, column = _pos(node)
    if count[0] > MAX_NODES:
        raise TaskStackError(f'document expands to more than {MAX_NODES} values (aliases '
                             'repeated too often?); a task stack is much smaller', path, line,
                             column, source)
    if len(path) > MAX_DEPTH:
        raise TaskStackError(f'document nested too deeply (limit {MAX_DEPTH} levels)', path,
                             line, column, source)
    marks.setdefault(path, (line, column))
    tag = node.tag
    if isinstance(node, yaml.ScalarNode):
        if tag.startswith('!') or tag not in _STD_TAGS:
            raise TaskStackError(f"YAML tag '{tag}' is not allowed; task stacks use plain "
                                 'values only', path, line, column, source)
        return _scalar(node, path, source)
    if tag.startswith('!') or tag not in _STD_TAGS:
        raise TaskStackError(f"YAML tag '{tag}' is not allowed; task stacks use plain "
                             'mappings and lists only', path, line, column, source)
    if isinstance(node, yaml.SequenceNode):
        return [_construct(item, path + (i,), marks, count, source)
                for i, item in enumerate(node.value)]
    return _mapping(node, path, marks, count, source)


def _mapping(node: yaml.Node, path: Path, marks: Marks, count: list[int],
             source: str | None) -> dict[str, Any]:
    """Construct a mapping node: plain keys, no merge keys, no duplicates."""
    out: dict[str, Any] = {}
    for key_node, value_node in node.value:
        if key_node.tag == 'tag:yaml.org,2002:merge':
            raise TaskStackError("YAML merge keys ('<<') are not supported; write the "
                                 'fields out', path, *_pos(key_node), source)
        if not isinstance(key_node, yaml.ScalarNode):
            kind = 'list' if isinstance(key_node, yaml.SequenceNode) else 'mapping'
            raise TaskStackError(f'mapping keys must be plain names, got a {kind}',
                                 path, *_pos(key_node), source)
        key = key_node.value
        if key in out:
            raise TaskStackError(f"duplicate key '{key}'", path + (key,), *_pos(key_node),
                                 source)
        marks[path + (key,)] = _pos(value_node)
        out[key] = _construct(value_node, path + (key,), marks, count, source)
        # a missing value is best reported at its key
        if out[key] is None:
            marks[path + (key,)] = _pos(key_node)
    return out


_STD_TAGS = {
    'tag:yaml.org,2002:' + t
    for t in ('str', 'int', 'float', 'bool', 'null', 'map', 'seq', 'timestamp', 'binary',
              'set', 'omap', 'pairs', 'value', 'merge')
}


def _scalar(node: yaml.ScalarNode, path: Path, source: str | None) -> Any:
    value = node.value
    line, column = _pos(node)
    if len(value) > MAX_STRING:
        raise TaskStackError(f'string of {len(value)} characters is longer than the limit '
                             f'of {MAX_STRING}', path, line, column, source)
    if node.style:  # quoted or block scalar: always a string (plain: None or '')
        return value
    if value in _NULL:
        return None
    if value in _TRUE:
        return True
    if value in _FALSE:
        return False
    if _INT.match(value):
        return int(value.replace('_', ''))
    if _FLOAT.match(value):
        x = float(value.replace('_', ''))
        if not math.isfinite(x):
            raise TaskStackError(f"number '{value}' is not finite", path, line, column,
                                 source)
        return x
    if _INF.match(value) or _NAN.match(value) or _NONFINITE.match(value):
        raise TaskStackError(f"'{value}' is not allowed: numbers must be finite (omit a "
                             'bound to leave it open, or use null in a lower/upper list)',
                             path, line, column, source)
    return value
