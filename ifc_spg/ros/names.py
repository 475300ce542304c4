"""ROS 2 names: validation, expansion against a node's namespace, remapping.

Follows rcl: a relative name ``a/b`` expands to ``<ns>/a/b``, ``~`` to ``<ns>/<node>``,
``~/x`` to ``<ns>/<node>/x``, ``{node}``/``{ns}``/``{namespace}`` are substituted; remap rules
compare fully expanded names and the first matching rule wins.
"""

import re

from ifc_spg.errors import ParameterError

__all__ = ['validate_node_name', 'validate_namespace', 'expand_topic_name', 'remap_name',
           'fully_qualified_node_name']

_NODE_RE = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*$')
_TOKEN_RE = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*$')


def validate_node_name(name: str) -> str:
    """Raise ParameterError unless ``name`` is a valid node name: ``[A-Za-z_][A-Za-z0-9_]*``."""
    if not isinstance(name, str) or not _NODE_RE.match(name):
        raise ParameterError(f"invalid node name '{name}': use letters, digits and '_', not "
                             'starting with a digit (e.g. spg_node)')
    return name


def validate_namespace(namespace: str) -> str:
    """Return ``namespace`` normalised to an absolute namespace ('' or None -> '/').

    Raises:
        ParameterError: if a token is invalid.
    """
    if not namespace:
        return '/'
    if not namespace.startswith('/'):
        namespace = '/' + namespace
    if namespace != '/':
        namespace = namespace.rstrip('/')
        for token in namespace[1:].split('/'):
            if not _TOKEN_RE.match(token):
                raise ParameterError(f"invalid namespace '{namespace}': token '{token}' must "
                                     "match [A-Za-z_][A-Za-z0-9_]* (e.g. /robot1)")
    return namespace


def fully_qualified_node_name(name: str, namespace: str) -> str:
    """``/ns/name`` of a node."""
    namespace = validate_namespace(namespace)
    return f'/{name}' if namespace == '/' else f'{namespace}/{name}'


def expand_topic_name(name: str, node_name: str, namespace: str) -> str:
    """Expand a topic name against a node, as rcl_expand_topic_name does.

    Args:
        name: Absolute (``/a/b``), relative (``a/b``) or private (``~``, ``~/a``) topic name.
        node_name: The node's name.
        namespace: The node's absolute namespace.

    Returns:
        The fully qualified topic name.

    Raises:
        ParameterError: on an empty or malformed name.
    """
    if not isinstance(name, str) or not name:
        raise ParameterError(f'invalid topic name {name!r}: must be a non-empty string')
    namespace = validate_namespace(namespace)
    ns = '' if namespace == '/' else namespace
    for key, value in (('{node}', node_name), ('{ns}', ns or '/'), ('{namespace}', ns or '/')):
        name = name.replace(key, value)
    if name == '~':
        expanded = f'{ns}/{node_name}'
    elif name.startswith('~/'):
        expanded = f'{ns}/{node_name}/{name[2:]}'
    elif name.startswith('/'):
        expanded = name
    else:
        expanded = f'{ns}/{name}'
    tokens = expanded[1:].split('/')
    for token in tokens:
        if not _TOKEN_RE.match(token):
            raise ParameterError(
                f"invalid topic name '{name}' (expanded '{expanded}'): token '{token}' must match "
                "[A-Za-z_][A-Za-z0-9_]*; tokens are separated by single '/', no trailing '/'")
    return expanded


def remap_name(expanded, rules, node_name, namespace):
    """Apply the first matching remap rule to an expanded topic name.

    Args:
        expanded: Fully qualified topic name.
        rules: Sequence of ``Remap`` (``node``, ``source``, ``target``) from parse_ros_args.
        node_name: The node's (possibly remapped) name; rules with another node prefix are
            skipped.
        namespace: The node's absolute namespace.

    Returns:
        The remapped fully qualified name (``expanded`` when no rule matches).
    """
    for rule in rules:
        if rule.node is not None and rule.node != node_name:
            continue
        if rule.source.startswith('__'):
            continue
        if expand_topic_name(rule.source, node_name, namespace) == expanded:
            return expand_topic_name(rule.target, node_name, namespace)
    return expanded
