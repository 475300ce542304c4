"""The ``--ros-args`` command-line grammar of rcl, as a pure function.

    prog [user args] --ros-args [-p [node:]name:=value] [--params-file FILE]
                                [-r [node:]from:=to] [-r __ns:=/ns] [-r __node:=name]
                                [--log-level [logger:=]LEVEL] [-e ENCLAVE] [--] [user args]

Semantics mirror rcl (``rcl/src/rcl/arguments.c``): ``-p`` values are YAML-typed; parameter
rules and files are merged, in command-line order, into one table of node sections, so a later
assignment of the same name in the same section beats an earlier one (``-p`` given after
``--params-file`` beats the file). Resolving a node's overrides applies, in the order the sections
were first created, every section whose pattern (``/**``, ``/*``, ``node``, ``/ns/node``, with
``*`` and ``**`` wildcards) matches the node's fully qualified name. Remap rules: the first
matching rule wins.
"""

import dataclasses
import re
from typing import Any

import yaml

from ifc_spg.errors import ParameterError, did_you_mean
from ifc_spg.ros.names import validate_namespace, validate_node_name

__all__ = ['RosArgs', 'Remap', 'parse_ros_args', 'remove_ros_args', 'load_params_file',
           'parse_param_value', 'LOG_LEVELS']

LOG_LEVELS = ('debug', 'info', 'warn', 'error', 'fatal', 'unset')
_FLAGS_WITH_VALUE = ('-p', '--param', '-r', '--remap', '--params-file', '--log-level', '-e',
                     '--enclave', '--log-config-file', '--log-file-name')
_FLAGS_ALONE = ('--enable-rosout-logs', '--disable-rosout-logs', '--enable-stdout-logs',
                '--disable-stdout-logs', '--enable-external-lib-logs',
                '--disable-external-lib-logs')
_PARAM_NAME_RE = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$')
_REMAP_SOURCE_RE = re.compile(r'^(~|~/)?[A-Za-z0-9_/{}~]+$')


@dataclasses.dataclass(frozen=True)
class Remap:
    """One ``-r [node:]source:=target`` rule."""

    node: str | None
    source: str
    target: str


@dataclasses.dataclass(frozen=True)
class RosArgs:
    """The parsed ROS arguments of one command line.

    Attributes:
        user_args: Arguments outside ``--ros-args`` sections, in order (rclpy's
            ``remove_ros_args``).
        param_sections: Ordered ``{node pattern: {param name: value}}`` (patterns normalised to
            start with '/'), ``-p`` and ``--params-file`` merged in command-line order.
        params_files: The ``--params-file`` paths, in order.
        remaps: ``-r`` rules in order, including ``__ns``/``__node``/``__name`` rules.
        log_levels: ``{logger name or '': level}`` from ``--log-level``.
        enclave: The ``-e``/``--enclave`` value or None.
        extra_flags: Accepted but unused logging flags, in order.
    """

    user_args: tuple = ()
    param_sections: dict = dataclasses.field(default_factory=dict)
    params_files: tuple = ()
    remaps: tuple = ()
    log_levels: dict = dataclasses.field(default_factory=dict)
    enclave: str | None = None
    extra_flags: tuple = ()

    def node_name(self, default, node=None):
        """The node name after ``-r [node:]__node:=`` / ``__name`` rules, else ``default``."""
        for rule in self.remaps:
            if rule.source in ('__node', '__name') and rule.node in (None, node or default):
                return rule.target
        return default

    def namespace(self, default, node=None):
        """The namespace after ``-r [node:]__ns:=`` rules; ``default`` if none."""
        for rule in self.remaps:
            if rule.source == '__ns' and rule.node in (None, node):
                return rule.target
        return default

    def log_level(self, logger=''):
        """The ``--log-level`` for ``logger`` (falling back to the default level), or None."""
        return self.log_levels.get(logger, self.log_levels.get(''))

    def parameter_overrides(self, node_fqn):
        """The parameter overrides for the node with fully qualified name ``node_fqn``."""
        out = {}
        for pattern, params in self.param_sections.items():
            if _node_pattern_matches(pattern, node_fqn):
                out.update(params)
        return out


def _node_pattern_matches(pattern, node_fqn):
    """Fnmatch of rcl: ``*`` matches one name token, ``**`` any number of tokens."""
    if pattern == '/**':
        return True
    regex = ''
    i = 0
    while i < len(pattern):
        if pattern.startswith('/**', i):
            regex += '(/[^/]+)*'
            i += 3
        elif pattern[i] == '*':
            regex += '[^/]*'
            i += 1
        else:
            regex += re.escape(pattern[i])
            i += 1
    return re.fullmatch(regex, node_fqn) is not None


def _normalise_node_key(key):
    key = str(key)
    return key if key.startswith('/') else '/' + key


def parse_param_value(text, where):
    """YAML-type one ``-p`` value as rcl does (bool, int, float, string, homogeneous list).

    Args:
        text: The text after ``:=``.
        where: The full rule, for error messages.
    """
    try:
        value = yaml.safe_load(text) if text.strip() else ''
    except yaml.YAMLError as exc:
        raise ParameterError(f"cannot parse the value of '{where}' as YAML: {exc}") from exc
    return _check_value(value, where)


def _check_value(value, where):
    if value is None:
        raise ParameterError(f"'{where}': empty value; give a value (quote an empty string as "
                             "'\"\"')")
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list):
        kinds = {type(v) for v in value}
        if not value:
            raise ParameterError(f"'{where}': empty list has no type; give at least one element")
        if len(kinds) != 1 or not kinds <= {bool, int, float, str}:
            names = sorted(k.__name__ for k in kinds)
            raise ParameterError(f"'{where}': a list parameter must hold one type of bool, int, "
                                 f"float or str, got {', '.join(names)} (write 1.0, not 1, in "
                                 'a float list)')
        return value
    raise ParameterError(f"'{where}': unsupported value {value!r} ({type(value).__name__}); use a "
                         'bool, int, float, string or a list of one of them')


def _flatten(prefix, mapping, out, where):
    for key, value in mapping.items():
        name = f'{prefix}.{key}' if prefix else str(key)
        if isinstance(value, dict):
            _flatten(name, value, out, where)
        else:
            if not _PARAM_NAME_RE.match(name):
                raise ParameterError(f"{where}: invalid parameter name '{name}'")
            out[name] = _check_value(value, f'{where}: {name}')


def load_params_file(path):
    """Read a ROS 2 parameters YAML file into ``{node pattern: {flat name: value}}``.

    Accepts ``/**:``, ``node:``, ``/ns/node:`` and nested namespace keys (``/ns: {node: ...}``)
    above ``ros__parameters``; nested parameter keys are flattened with '.'.

    Raises:
        ParameterError: if the file is missing, not YAML or lacks ``ros__parameters``.
    """
    try:
        with open(path, encoding='utf-8') as stream:
            data = yaml.safe_load(stream)
    except OSError as exc:
        raise ParameterError(f"cannot read params file '{path}': {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise ParameterError(f"params file '{path}' is not valid YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise ParameterError(f"params file '{path}': expected a mapping of node names, e.g. "
                             "'/**: {ros__parameters: {rate: 500.0}}'")
    sections: dict[str, dict[str, Any]] = {}  # YAML values

    def walk(prefix, mapping):
        for key, value in mapping.items():
            key = str(key)
            if key == 'ros__parameters':
                if not isinstance(value, dict):
                    raise ParameterError(f"params file '{path}': 'ros__parameters' of "
                                         f"'{prefix or '/'}' must be a mapping")
                node_key = _normalise_node_key(prefix or '/**')
                _flatten('', value, sections.setdefault(node_key, {}), f"'{path}' [{node_key}]")
            elif isinstance(value, dict):
                walk(f'{prefix.rstrip("/")}/{key.strip("/")}' if prefix else key, value)
            else:
                raise ParameterError(
                    f"params file '{path}': '{key}' under '{prefix or '/'}' is not inside "
                    "'ros__parameters'; expected '<node>: {ros__parameters: {...}}'")

    walk('', data)
    if not sections:
        raise ParameterError(f"params file '{path}' has no 'ros__parameters' section")
    return sections


def _split_rule(rule, flag):
    if ':=' not in rule:
        raise ParameterError(f"malformed '{flag} {rule}': expected {flag} name:=value")
    left, value = rule.split(':=', 1)
    node, _, name = left.rpartition(':')
    return (node or None), name, value


def _parse_remap(rule):
    node, source, target = _split_rule(rule, '-r')
    if node is not None:
        validate_node_name(node)
    if not source or not target:
        raise ParameterError(f"malformed remap '-r {rule}': both sides of ':=' are needed")
    if source == '__ns':
        if not target.startswith('/'):
            raise ParameterError(f"malformed '-r {rule}': the namespace must be absolute, e.g. "
                                 f"__ns:=/{target}")
        target = validate_namespace(target)
    elif source in ('__node', '__name'):
        validate_node_name(target)
    elif source.startswith('__'):
        raise ParameterError(f"unknown special remap '{source}' in '-r {rule}'; valid: __ns, "
                             '__node, __name')
    elif not _REMAP_SOURCE_RE.match(source) or not _REMAP_SOURCE_RE.match(target):
        raise ParameterError(f"malformed remap '-r {rule}': names may hold letters, digits, "
                             "'_', '/' and '~'")
    return Remap(node, source, target)


def parse_ros_args(argv):
    """Parse a command line with ``--ros-args`` sections.

    Args:
        argv: The full argument list (program name included or not; it is a user arg).

    Returns:
        RosArgs.

    Raises:
        ParameterError: naming the bad argument, for unknown flags, missing values, malformed
            rules, bad params files or values.
    """
    acc = _Collected()
    in_ros = False
    i = 0
    argv = list(argv or [])
    while i < len(argv):
        arg = argv[i]
        i += 1
        if arg == '--ros-args':
            in_ros = True
        elif not in_ros:
            acc.user.append(arg)
        elif arg == '--':
            in_ros = False
        elif arg in _FLAGS_ALONE:
            acc.extra.append(arg)
        else:
            _check_flag(arg, argv, i)
            acc.add(arg, argv[i])
            i += 1
    return RosArgs(user_args=tuple(acc.user), param_sections=acc.sections,
                   params_files=tuple(acc.files), remaps=tuple(acc.remaps),
                   log_levels=acc.log_levels, enclave=acc.enclave, extra_flags=tuple(acc.extra))


def _check_flag(arg, argv, i):
    """Raise ParameterError unless ``arg`` is a known flag with a value at ``argv[i]``."""
    if arg not in _FLAGS_WITH_VALUE:
        known = _FLAGS_WITH_VALUE + _FLAGS_ALONE
        raise ParameterError(f"unknown ROS argument '{arg}'{did_you_mean(arg, known)}; valid: "
                             f"{', '.join(known)} (end the ROS section with '--')")
    if i >= len(argv) or argv[i] == '--ros-args':
        raise ParameterError(f"'{arg}' at the end of the ROS arguments needs a value, e.g. "
                             f"{_EXAMPLES.get(arg, arg + ' VALUE')}")


class _Collected:
    """What :func:`parse_ros_args` has read so far."""

    def __init__(self):
        self.user, self.extra, self.remaps, self.files = [], [], [], []
        self.sections, self.log_levels, self.enclave = {}, {}, None

    def add(self, arg, value):
        """One ROS flag with its value."""
        if arg in ('-p', '--param'):
            self.param(arg, value)
        elif arg == '--params-file':
            for key, params in load_params_file(value).items():
                self.sections.setdefault(key, {}).update(params)
            self.files.append(value)
        elif arg in ('-r', '--remap'):
            self.remaps.append(_parse_remap(value))
        elif arg == '--log-level':
            self.log_level(value)
        elif arg in ('-e', '--enclave'):
            self.enclave = value
        else:
            self.extra.append(f'{arg}={value}')

    def param(self, arg, value):
        """``-p [node:]name:=value``."""
        node, name, text = _split_rule(value, arg)
        if not _PARAM_NAME_RE.match(name):
            raise ParameterError(f"malformed '{arg} {value}': invalid parameter name "
                                 f"'{name}' (letters, digits, '_', '.' separated)")
        key = _normalise_node_key(node) if node else '/**'
        self.sections.setdefault(key, {})[name] = parse_param_value(text, f'{arg} {value}')

    def log_level(self, value):
        """``--log-level [logger:=]level``."""
        logger, _, level = value.rpartition(':=')
        if level.lower() not in LOG_LEVELS:
            raise ParameterError(f"invalid log level '{level}' in '--log-level {value}'"
                                 f"{did_you_mean(level.lower(), LOG_LEVELS)}; valid: "
                                 f"{', '.join(LOG_LEVELS)}")
        self.log_levels[logger] = level.lower()


_EXAMPLES = {
    '-p': '-p rate:=500.0', '--param': '--param rate:=500.0',
    '-r': '-r joint_states:=/robot/joint_states', '--remap': '--remap __ns:=/robot',
    '--params-file': '--params-file config/spg.yaml', '--log-level': '--log-level debug',
}


def remove_ros_args(argv):
    """Return ``argv`` without its ROS arguments (like ``rclpy.utilities.remove_ros_args``)."""
    return list(parse_ros_args(argv).user_args)
