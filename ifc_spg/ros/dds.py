"""The built-in ROS 2 backend: rclpy's node API over PyPI ``cyclonedds``.

On the wire it is ``rmw_cyclonedds_cpp`` (Jazzy).

What a real ROS 2 peer sees:

- one DDS participant per context, USER_DATA ``enclave=/;``, domain ``ROS_DOMAIN_ID`` (default 0);
- topic ``/a/b`` is DDS topic ``rt/a/b`` of type ``pkg::msg::dds_::T_``, keyless, plain CDR;
  readers/writers carry ``typehash=RIHS01_<hex>;`` in USER_DATA and QoS as in ``qos.py``;
- ``ros_discovery_info`` (rmw_dds_common/msg/ParticipantEntitiesInfo: participant gid, and per
  node its name, namespace and reader/writer gids = DDS GUIDs) is republished whenever a node,
  publisher or subscription is created or destroyed, reliable transient-local depth 1, so
  ``ros2 node list`` / ``ros2 topic list`` show our nodes.

Execution is single threaded as rclpy's SingleThreadedExecutor: ``spin_once`` waits on a DDS
WaitSet (subscription read conditions and a guard condition) until data arrives or the next timer
is due, and runs one callback.
"""

from collections.abc import Callable
import os
import re
import sys
import time
from typing import Any
import weakref

from ifc_spg.errors import IfcSpgError, ParameterError, did_you_mean
from ifc_spg.ros import messages
from ifc_spg.ros.cdr import CDR_HEADER, PRIMITIVES, parse_field_type
from ifc_spg.ros.clock import Clock
from ifc_spg.ros.logging import Logger
from ifc_spg.ros.names import (
    expand_topic_name,
    fully_qualified_node_name,
    remap_name,
    validate_namespace,
    validate_node_name,
)
from ifc_spg.ros.parameters import (
    Parameter,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
    check_parameter_value,
)
from ifc_spg.ros.qos import QoSProfile, as_qos, latched, to_dds_qos
from ifc_spg.ros.ros_args import parse_ros_args

__all__ = ['Context', 'Node', 'Publisher', 'Subscription', 'Timer', 'init', 'shutdown', 'ok',
           'spin', 'spin_once', 'spin_until', 'get_default_context', 'domain_id_from_env']

_MAX_WAIT_NS = 100_000_000  # wake at least every 0.1 s so Python signal handlers run
_TAKE_BATCH = 32
_default_context = None


def domain_id_from_env(environ=None):
    """``ROS_DOMAIN_ID`` as an int (0 when unset or empty).

    Raises:
        ParameterError: if it is not an integer in [0, 232].
    """
    text = (os.environ if environ is None else environ).get('ROS_DOMAIN_ID', '').strip()
    if not text:
        return 0
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= 232:
        raise ParameterError(f"ROS_DOMAIN_ID='{text}' is invalid: use an integer in [0, 232] "
                             '(0-101 avoids ephemeral ports)')
    return value


# DDS (IDL) types for topic creation: wire layout + XTypes info for tools like `cyclonedds typeof`

_IDL_TYPES: dict[type[messages.Message], Any] = {}  # IdlStruct classes made at run time


def _idl_field(ftype):
    # cyclonedds' IDL annotations (bounded_str, sequence, array) are indexed through a
    # metaclass mypy does not see: hence the type: ignore[misc] below
    from cyclonedds.idl import types as t

    base, kind, length = parse_field_type(ftype)
    if base == 'string':
        bound = re.match(r'string<=(\d+)', ftype)
        inner: Any = t.bounded_str[int(bound.group(1))] if bound else str  # type: ignore[misc]
    elif base in PRIMITIVES:
        inner = {'bool': bool, 'byte': t.byte, 'char': t.uint8, 'int8': t.int8, 'uint8': t.uint8,
                 'int16': t.int16, 'uint16': t.uint16, 'int32': t.int32, 'uint32': t.uint32,
                 'int64': t.int64, 'uint64': t.uint64, 'float32': t.float32,
                 'float64': t.float64}[base]
    else:
        inner = idl_type(messages.REGISTRY[base])
    if kind == 'sequence':
        return t.sequence[inner, length] if length else t.sequence[inner]  # type: ignore[misc]
    if kind == 'array':
        return t.array[inner, length]  # type: ignore[misc]
    return inner


def idl_type(cls):
    """A cyclonedds IdlStruct with the DDS type name and layout of message class ``cls``."""
    if cls not in _IDL_TYPES:
        from cyclonedds.idl import make_idl_struct

        fields = {name: _idl_field(ftype) for name, ftype in messages.fields(cls)}
        _IDL_TYPES[cls] = make_idl_struct(messages.dds_type(cls).split('::')[-1],
                                           messages.dds_type(cls), fields)
    return _IDL_TYPES[cls]


def _handle(entity):
    """The C handle of a cyclonedds-python entity, for ``ddspy_write``/``ddspy_take``.

    cyclonedds-python keeps it in ``_ref`` and has no public accessor; this is the one place
    the module reads it.
    """
    return entity._ref


def _message_class(msg_type):
    if not (isinstance(msg_type, type) and issubclass(msg_type, messages.Message)):
        raise ParameterError(f'{msg_type!r} is not a message class of this backend; import '
                             'message classes from ifc_spg.ros.msg')
    return msg_type


class Context:
    """One ROS 2 context: parsed ROS arguments and one DDS participant.

    Args:
        args: Command line (with ``--ros-args`` sections); None reads sys.argv as rclpy does.
        domain_id: DDS domain; None reads ``ROS_DOMAIN_ID``.
    """

    def __init__(self, args=None, domain_id=None):
        from cyclonedds.core import GuardCondition
        from cyclonedds.domain import DomainParticipant
        from cyclonedds.qos import Policy, Qos

        self.ros_args = parse_ros_args(sys.argv if args is None else args)
        self.domain_id = domain_id_from_env() if domain_id is None else int(domain_id)
        enclave = self.ros_args.enclave or '/'
        self.participant: DomainParticipant | None = DomainParticipant(
            self.domain_id, qos=Qos(Policy.Userdata(data=f'enclave={enclave};'.encode())))
        self.gid = self.participant.get_guid().bytes
        self.guard = GuardCondition(self.participant)
        self.nodes = []
        self.generation = 0
        self._ok = True
        self._topics = {}
        self._executors = {}
        info_type = messages.ParticipantEntitiesInfo
        self._info_topic = self.topic('ros_discovery_info', info_type)
        from cyclonedds.pub import DataWriter

        self._info_writer: DataWriter | None = DataWriter(self.participant, self._info_topic,
                                       to_dds_qos(latched(1), messages.type_hash(info_type)))
        self._info_ser = messages.codec(info_type)[0]

    def topic(self, dds_name, cls):
        """The (cached) DDS Topic ``dds_name`` of message class ``cls``."""
        key = (dds_name, cls)
        if key not in self._topics:
            from cyclonedds.topic import Topic

            for (name, other), _ in self._topics.items():
                if name == dds_name and other is not cls:
                    raise ParameterError(f"topic '{dds_name}' is already used with type "
                                         f'{messages.type_name(other)}, not '
                                         f'{messages.type_name(cls)}')
            if self.participant is None:
                raise IfcSpgError('the DDS context is shut down')
            self._topics[key] = Topic(self.participant, dds_name, idl_type(cls))
        return self._topics[key]

    def ok(self):
        """True until shutdown."""
        return self._ok

    def changed(self):
        """Note a graph change: republish ros_discovery_info and wake waiting executors."""
        self.generation += 1
        self.publish_graph()
        self.guard.set(True)

    def publish_graph(self):
        """Write this participant's ParticipantEntitiesInfo on ``ros_discovery_info``."""
        if not self._ok:
            return
        gid = messages.Gid.__new__(messages.Gid)
        gid.data = self.gid
        info = messages.ParticipantEntitiesInfo(gid=gid, node_entities_info_seq=[
            node._entities_info() for node in self.nodes])
        _write(self._info_writer, self._info_ser, info)

    def executor(self, nodes):
        """The cached executor for a tuple of nodes."""
        key = tuple(id(n) for n in nodes)
        ex = self._executors.get(key)
        if ex is None:
            ex = self._executors[key] = _Executor(self, nodes)
        return ex

    def shutdown(self):
        """Destroy the nodes and the participant; idempotent."""
        if not self._ok:
            return
        for node in list(self.nodes):
            node.destroy_node()
        self._ok = False
        self.guard.set(True)
        self._executors.clear()
        self._topics.clear()
        self._info_writer = None
        self.participant = None  # entities are deleted with the participant


def _write(writer, ser, msg):
    from cyclonedds._clayer import ddspy_write

    b = bytearray(CDR_HEADER)
    ser(msg, b)
    pad = -len(b) & 3  # rmw_cyclonedds pads serialized data to a multiple of 4
    if pad:
        b += b'\0' * pad
    ret = ddspy_write(_handle(writer), bytes(b))
    if ret < 0:
        raise IfcSpgError(f'DDS write failed with code {ret}')


def _gid_msg(entity):
    gid = messages.Gid.__new__(messages.Gid)
    gid.data = entity.get_guid().bytes
    return gid


class Publisher:
    """Publishes messages of one type on one topic (``publish(msg)``)."""

    def __init__(self, node, msg_type, topic, qos):
        from cyclonedds.pub import DataWriter

        self.msg_type = _message_class(msg_type)
        self.qos = as_qos(qos)
        self.topic_name = node.resolve_topic_name(topic)
        self._node = node
        dds_topic = node.context.topic('rt' + self.topic_name, self.msg_type)
        self._writer = DataWriter(node.context.participant, dds_topic,
                                  to_dds_qos(self.qos, messages.type_hash(self.msg_type)))
        self._ser = messages.codec(self.msg_type)[0]
        self.gid = _gid_msg(self._writer)

    @property
    def topic(self):
        """The fully qualified topic name (rclpy's ``Publisher.topic``)."""
        return self.topic_name

    def publish(self, msg: messages.Message) -> None:
        """Serialize and write one message.

        Raises:
            ParameterError: if ``msg`` is not an instance of the publisher's message class.
        """
        if type(msg) is not self.msg_type:
            raise ParameterError(f"publisher on '{self.topic_name}' expects "
                                 f'{messages.type_name(self.msg_type)}, got {type(msg).__name__}')
        _write(self._writer, self._ser, msg)

    def publish_serialized(self, data):
        """Write one message already serialized (CDR with its 4-byte header, e.g. from a bag).

        Padded to a multiple of 4 bytes as rmw_cyclonedds pads.

        Raises:
            IfcSpgError: The DDS write failed.
        """
        # cyclonedds' public DataWriter.write serializes an IdlStruct itself; bytes that are
        # CDR already can only be written through its C layer (as DataWriter.write does)
        from cyclonedds._clayer import ddspy_write

        b = bytes(data)
        pad = -len(b) & 3
        ret = ddspy_write(_handle(self._writer), b + b'\0' * pad if pad else b)
        if ret < 0:
            raise IfcSpgError(f"DDS write on '{self.topic_name}' failed with code {ret}")

    def get_subscription_count(self) -> int:
        """Number of matched DDS readers (subscriptions) of this publisher."""
        return len(self._writer.get_matched_subscriptions())

    def wait_for_acks(self, timeout_sec=1.0):
        """Block until reliable readers acknowledged everything written; True if they did."""
        return bool(self._writer.wait_for_acks(int(timeout_sec * 1e9)))

    def destroy(self):
        """Delete the DDS writer."""
        self._node._destroy_entity(self)


class Subscription:
    """Calls ``callback(msg)`` for each message received on one topic."""

    def __init__(self, node, msg_type, topic, callback, qos):
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState
        from cyclonedds.sub import DataReader

        self.msg_type = _message_class(msg_type)
        self.qos = as_qos(qos)
        self.topic_name = node.resolve_topic_name(topic)
        self.callback = callback
        self._node = node
        dds_topic = node.context.topic('rt' + self.topic_name, self.msg_type)
        self._reader = DataReader(node.context.participant, dds_topic,
                                  to_dds_qos(self.qos, messages.type_hash(self.msg_type)))
        self._condition = ReadCondition(
            self._reader, SampleState.Any | ViewState.Any | InstanceState.Any)
        self._mask = SampleState.Any | ViewState.Any | InstanceState.Any
        self._de = messages.codec(self.msg_type)[1]
        self._queue = []
        self.gid = _gid_msg(self._reader)

    @property
    def topic(self):
        """The fully qualified topic name."""
        return self.topic_name

    def _take(self):
        from cyclonedds._clayer import ddspy_take

        ret = ddspy_take(_handle(self._reader), self._mask, _TAKE_BATCH)
        if isinstance(ret, int):
            raise IfcSpgError(f"DDS take on '{self.topic_name}' failed with code {ret}")
        for data, info in ret:
            if info.valid_data:
                self._queue.append(data)
        return len(ret)

    def _run_one(self):
        data = self._queue.pop(0)
        try:
            msg, _ = self._de(memoryview(data)[4:], 0)
        except Exception as exc:  # malformed sample from a foreign writer
            self._node.get_logger().error(
                f'dropping undecodable {messages.type_name(self.msg_type)} on '
                f"'{self.topic_name}': {exc}")
            return
        self.callback(msg)

    @property
    def read_condition(self):
        """The DDS ReadCondition that triggers while samples wait (to attach to a WaitSet)."""
        return self._condition

    def take_serialized(self):
        """Take every sample that arrived, without running the callback.

        Returns:
            The serialized messages (CDR with header, as on the wire), oldest first.
        """
        while self._take():
            pass
        out = list(self._queue)
        self._queue.clear()
        return out

    def get_publisher_count(self) -> int:
        """Number of matched DDS writers (publishers) of this subscription."""
        return len(self._reader.get_matched_publications())

    def destroy(self):
        """Delete the DDS reader."""
        self._node._destroy_entity(self)


class Timer:
    """Calls ``callback()`` every ``timer_period_ns`` on the steady clock.

    Missed periods are skipped, as rcl does.
    """

    def __init__(self, node, period_s, callback, autostart=True):
        if not period_s > 0:
            raise ParameterError(f'timer period {period_s!r} s must be > 0')
        self.timer_period_ns = int(round(period_s * 1e9))
        self.callback = callback
        self._node = node
        self._canceled = not autostart
        self._next = time.monotonic_ns() + self.timer_period_ns

    def is_canceled(self) -> bool:
        """True after cancel()."""
        return self._canceled

    def cancel(self) -> None:
        """Stop calling the callback."""
        self._canceled = True

    def reset(self):
        """Restart the period from now."""
        self._canceled = False
        self._next = time.monotonic_ns() + self.timer_period_ns

    def time_until_next_call(self):
        """[ns] until the next call (negative when due), None when canceled."""
        return None if self._canceled else self._next - time.monotonic_ns()

    def _run(self, now):
        self._next += self.timer_period_ns
        if self._next <= now:  # missed periods are skipped, phase kept
            self._next += ((now - self._next) // self.timer_period_ns + 1) * self.timer_period_ns
        self.callback()

    def destroy(self):
        """Remove the timer from its node."""
        self._node._destroy_entity(self)


class Node:
    """A ROS 2 node with rclpy's call shapes.

    Args:
        node_name: Node name (``-r __node:=`` may change it).
        namespace: Namespace (``-r __ns:=`` may change it); relative ones are made absolute.
        context: Context (default: the one made by ``init``).
        cli_args: Node-local ROS arguments, applied after the global ones.
        parameter_overrides: List of Parameter overriding everything else.
        automatically_declare_parameters_from_overrides: Declare every override at creation.
    """

    def __init__(self, node_name, *, namespace=None, context=None, cli_args=None,
                 parameter_overrides=None, use_global_arguments=True,
                 automatically_declare_parameters_from_overrides=False, **_ignored):
        self.context = context or get_default_context()
        if not self.context.ok():
            raise IfcSpgError('the ROS context is shut down; call init() first')
        validate_node_name(node_name)
        local = parse_ros_args(['--ros-args', *cli_args] if cli_args and
                               '--ros-args' not in cli_args else (cli_args or []))
        sources = ([self.context.ros_args] if use_global_arguments else []) + [local]
        name, ns = node_name, validate_namespace(namespace)
        for args in sources:
            ns = args.namespace(ns, node=node_name)
        for args in sources:
            name = args.node_name(name, node=node_name)
        self._name, self._namespace = validate_node_name(name), validate_namespace(ns)
        self._remaps = tuple(r for args in reversed(sources) for r in args.remaps)
        fqn = self.get_fully_qualified_name()
        self._overrides = {}
        for args in sources:
            self._overrides.update(args.parameter_overrides(fqn))
        for param in parameter_overrides or []:
            self._overrides[param.name] = param.value
        level = None
        for args in sources:
            level = args.log_level(self._name) or level
        self._logger = Logger(self._name, level or 'info')
        self._clock = Clock()
        self._parameters = {}
        self._descriptors = {}
        self._on_set = []
        self.publishers, self.subscriptions, self.timers = [], [], []
        self._destroyed = False
        self.context.nodes.append(self)
        if automatically_declare_parameters_from_overrides:
            for pname, value in self._overrides.items():
                self.declare_parameter(pname, value)
        self.context.changed()

    # names ------------------------------------------------------------------------------------

    def get_name(self) -> str:
        """The node name."""
        return self._name

    def get_namespace(self) -> str:
        """The absolute namespace."""
        return self._namespace

    def get_fully_qualified_name(self) -> str:
        """``/ns/name``."""
        return fully_qualified_node_name(self._name, self._namespace)

    def parameter_overrides(self):
        """``{name: value}`` of the parameter values given (-p, --params-file, the argument).

        rclpy keeps these private; :func:`ifc_spg.ros.parameters.overrides` reads both.
        """
        return dict(self._overrides)

    def resolve_topic_name(self, topic: str, *, only_expand: bool = False) -> str:
        """Expand (and remap) a topic name as rcl does for this node."""
        expanded = expand_topic_name(topic, self._name, self._namespace)
        if only_expand:
            return expanded
        return remap_name(expanded, self._remaps, self._name, self._namespace)

    # entities ---------------------------------------------------------------------------------

    def create_publisher(self, msg_type: type[messages.Message], topic: str,
                         qos_profile: QoSProfile | int, **_ignored: object) -> Publisher:
        """Create a Publisher of ``msg_type`` on ``topic`` with a QoSProfile or int depth."""
        pub = Publisher(self, msg_type, topic, qos_profile)
        self.publishers.append(pub)
        self.context.changed()
        return pub

    def create_subscription(self, msg_type: type[messages.Message], topic: str,
                            callback: Callable[[Any], object], qos_profile: QoSProfile | int,
                            **_ignored: object) -> 'Subscription':
        """Create a Subscription calling ``callback(msg)`` for each message."""
        sub = Subscription(self, msg_type, topic, callback, qos_profile)
        self.subscriptions.append(sub)
        self.context.changed()
        return sub

    def create_timer(self, timer_period_sec: float, callback: Callable[[], object],
                     callback_group: object = None, clock: object = None,
                     autostart: bool = True) -> 'Timer':
        """Create a Timer calling ``callback()`` every ``timer_period_sec`` [s]."""
        timer = Timer(self, timer_period_sec, callback, autostart)
        self.timers.append(timer)
        self.context.generation += 1
        self.context.guard.set(True)
        return timer

    def _destroy_entity(self, entity):
        for group in (self.publishers, self.subscriptions, self.timers):
            if entity in group:
                group.remove(entity)
                for attr in ('_writer', '_reader'):
                    dds = getattr(entity, attr, None)
                    if dds is not None:
                        if attr == '_reader':
                            self._detach_everywhere(entity)
                        dds.__del__()  # cyclonedds: deletes the DDS entity once
                        setattr(entity, attr, None)
                self.context.changed()
                return True
        return False

    def _detach_everywhere(self, sub):
        self.context.generation += 1
        for ex in self.context._executors.values():
            entry = ex.attached.pop(id(sub), None)
            if entry is not None:
                ex.waitset.detach(entry[1])
                ex.subs = [s for s in ex.subs if s is not sub]

    def count_publishers(self, topic_name: str) -> int:
        """Publishers matched on ``topic_name``, as seen by this node's subscriptions to it.

        rclpy counts the whole graph; the built-in backend knows the writers its readers
        matched, which is what a test waiting for a connection needs.
        """
        name = self.resolve_topic_name(topic_name)
        return max((s.get_publisher_count() for s in self.subscriptions
                    if s.topic_name == name), default=0)

    def count_subscribers(self, topic_name: str) -> int:
        """Subscriptions matched on ``topic_name`` by this node's publishers to it."""
        name = self.resolve_topic_name(topic_name)
        return max((p.get_subscription_count() for p in self.publishers
                    if p.topic_name == name), default=0)

    def destroy_publisher(self, pub):
        """Destroy a publisher of this node."""
        return self._destroy_entity(pub)

    def destroy_subscription(self, sub):
        """Destroy a subscription of this node."""
        return self._destroy_entity(sub)

    def destroy_timer(self, timer):
        """Destroy a timer of this node."""
        return self._destroy_entity(timer)

    def destroy_node(self):
        """Destroy all entities and remove the node from the graph."""
        if self._destroyed:
            return
        for entity in self.publishers + self.subscriptions + self.timers:
            self._destroy_entity(entity)
        self._destroyed = True
        if self in self.context.nodes:
            self.context.nodes.remove(self)
        self.context.changed()

    def _entities_info(self):
        info = messages.NodeEntitiesInfo.__new__(messages.NodeEntitiesInfo)
        info.node_namespace = self._namespace
        info.node_name = self._name
        info.reader_gid_seq = [s.gid for s in self.subscriptions]
        info.writer_gid_seq = [p.gid for p in self.publishers]
        return info

    # parameters -------------------------------------------------------------------------------

    def declare_parameter(self, name, value=None, descriptor=None, ignore_override=False):
        """Declare a parameter; an override from the command line wins over ``value``.

        Raises:
            ParameterError: if already declared, or the value has the wrong type or is out of
                the descriptor's range.
        """
        if name in self._parameters:
            raise ParameterError(f"parameter '{name}' of node '{self._name}' is already "
                                 'declared')
        descriptor = descriptor or ParameterDescriptor()
        expected = ParameterType.of(value)
        if descriptor.type:
            expected = ParameterType(descriptor.type)
        final = value
        if not ignore_override and name in self._overrides:
            final = self._overrides[name]
            if isinstance(final, list) and isinstance(value, tuple):
                final = list(final)
        check_parameter_value(name, final, descriptor, expected)
        self._parameters[name] = Parameter(name, value=final)
        self._descriptors[name] = descriptor
        return self._parameters[name]

    def declare_parameters(self, namespace, parameters):
        """Declare several ``(name, value[, descriptor])`` under ``namespace`` ('' for none)."""
        out = []
        for item in parameters:
            pname = f'{namespace}.{item[0]}' if namespace else item[0]
            out.append(self.declare_parameter(pname, *item[1:]))
        return out

    def has_parameter(self, name):
        """True if declared."""
        return name in self._parameters

    def get_parameter(self, name):
        """The declared Parameter ``name``.

        Raises:
            ParameterError: if not declared (with a did-you-mean hint).
        """
        if name not in self._parameters:
            raise ParameterError(f"parameter '{name}' is not declared on node '{self._name}'"
                                 f'{did_you_mean(name, self._parameters)}; declared: '
                                 f"{', '.join(sorted(self._parameters)) or 'none'}")
        return self._parameters[name]

    def get_parameters(self, names):
        """List of Parameter for ``names``."""
        return [self.get_parameter(n) for n in names]

    def describe_parameter(self, name):
        """The ParameterDescriptor of a declared parameter."""
        self.get_parameter(name)
        return self._descriptors[name]

    def add_on_set_parameters_callback(self, callback):
        """Call ``callback(parameters) -> SetParametersResult`` before parameters change.

        As rclpy does; an unsuccessful result refuses the change.
        """
        self._on_set.append(callback)

    def set_parameters(self, parameters):
        """Set declared parameters, one at a time as rclpy does.

        Type, range and read_only are checked, then the on-set callbacks; one
        SetParametersResult per parameter.
        """
        results = []
        for param in parameters:
            old = self.get_parameter(param.name)  # undeclared: raises, as rclpy does
            try:
                descriptor = self._descriptors[param.name]
                if descriptor.read_only:
                    raise ParameterError(f"parameter '{param.name}' is read-only")
                check_parameter_value(param.name, param.value, descriptor, old.type_)
            except ParameterError as exc:
                results.append(SetParametersResult(successful=False, reason=str(exc)))
                continue
            new = Parameter(param.name, value=param.value)
            result = SetParametersResult(successful=True)
            for callback in self._on_set:
                result = callback([new])
                if not result.successful:
                    break
            if result.successful:
                self._parameters[param.name] = new
            results.append(result)
        return results

    # misc -------------------------------------------------------------------------------------

    def get_logger(self) -> Logger:
        """The node's Logger."""
        return self._logger

    def get_clock(self) -> Clock:
        """The node's Clock (system time)."""
        return self._clock

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.destroy_node()


class _Executor:
    """Single-threaded executor over a fixed set of nodes (rclpy SingleThreadedExecutor)."""

    def __init__(self, context, nodes):
        from cyclonedds.core import WaitSet

        self.context = context
        self.nodes = [weakref.ref(n) for n in nodes]
        self.waitset = WaitSet(context.participant)
        self.waitset.attach(context.guard)
        self.attached = {}
        self.generation = -1
        self.rr = 0

    def _sync(self):
        if self.generation == self.context.generation:
            return
        self.generation = self.context.generation
        subs = {id(s): s for ref in self.nodes if (node := ref()) is not None
                for s in node.subscriptions}
        for key in list(self.attached):
            if key not in subs:
                sub, cond = self.attached.pop(key)
                self.waitset.detach(cond)
        for key, sub in subs.items():
            if key not in self.attached:
                self.waitset.attach(sub._condition)
                self.attached[key] = (sub, sub._condition)
        self.subs = [sub for sub, _ in self.attached.values()]
        self.timers = [t for ref in self.nodes if (node := ref()) is not None for t in node.timers]

    def _run_ready(self):
        subs = self.subs
        n = len(subs)
        for i in range(n):
            sub = subs[(self.rr + i) % n]
            if sub._queue:
                self.rr = (self.rr + i + 1) % n
                sub._run_one()
                return True
        now = time.monotonic_ns()
        for timer in self.timers:
            if not timer._canceled and timer._next <= now:
                timer._run(now)
                return True
        return False

    def _wait_ns(self, deadline):
        """How long [ns] to wait: until the deadline or the next timer, at most a while."""
        now = time.monotonic_ns()
        wait = _MAX_WAIT_NS
        if deadline is not None:
            wait = min(wait, deadline - now)
        for timer in self.timers:
            if not timer._canceled:
                wait = min(wait, timer._next - now)
        return wait

    def spin_once(self, timeout_sec=None):
        """Run at most one callback, waiting up to ``timeout_sec`` [s] (None: forever)."""
        if not self.context.ok():
            return False
        self._sync()
        if self._run_ready():
            return True
        deadline = None if timeout_sec is None else time.monotonic_ns() + int(timeout_sec * 1e9)
        while self.context.ok():
            wait = self._wait_ns(deadline)
            if wait > 0:
                self.waitset.wait(wait)
            self.context.guard.take()
            if not self.context.ok():
                return False
            self._sync()
            for sub in self.subs:
                sub._take()
            if self._run_ready():
                return True
            if deadline is not None and time.monotonic_ns() >= deadline:
                return False
        return False


def get_default_context():
    """The context made by init(); raises if init() was not called."""
    if _default_context is None or not _default_context.ok():
        raise IfcSpgError('ROS is not initialised: call ifc_spg.ros.init(args) first')
    return _default_context


def init(args=None, *, context=None, domain_id=None, **_ignored):
    """Initialise the default context from a command line (``--ros-args`` sections)."""
    global _default_context
    if context is not None:
        return context
    if _default_context is not None and _default_context.ok():
        raise IfcSpgError('init() was already called; call shutdown() first')
    _default_context = Context(args, domain_id)
    return _default_context


def shutdown(*, context=None):
    """Shut down the default (or given) context."""
    global _default_context
    ctx = context or _default_context
    if ctx is not None:
        ctx.shutdown()
    if ctx is _default_context:
        _default_context = None


def ok(*, context=None):
    """True while the default (or given) context is initialised and not shut down."""
    ctx = context or _default_context
    return ctx is not None and ctx.ok()


def spin_once(node, *, executor=None, timeout_sec=None):
    """Run at most one callback of ``node`` (waiting up to ``timeout_sec`` [s])."""
    return node.context.executor((node,)).spin_once(timeout_sec)


def spin(node, executor=None):
    """Run callbacks of ``node`` until shutdown."""
    ex = node.context.executor((node,))
    while node.context.ok() and not node._destroyed:
        ex.spin_once(0.1)


def spin_until(condition, timeout_sec=5.0, nodes=None):
    """Spin ``nodes`` (default: all nodes of the default context) until ``condition()``.

    Returns:
        True if the condition held before ``timeout_sec`` [s], else False.
    """
    if nodes is None:
        nodes = tuple(get_default_context().nodes)
    elif isinstance(nodes, Node):
        nodes = (nodes,)
    nodes = tuple(nodes)
    if not nodes:
        raise ParameterError('spin_until needs at least one node')
    ex = nodes[0].context.executor(nodes)
    deadline = time.monotonic() + timeout_sec
    while not condition():
        remaining = deadline - time.monotonic()
        if remaining <= 0 or not nodes[0].context.ok():
            return bool(condition())
        ex.spin_once(min(remaining, 0.1))
    return True

