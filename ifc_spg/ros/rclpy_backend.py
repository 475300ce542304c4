"""The rclpy flavour of :mod:`ifc_spg.ros`.

rclpy's own classes, and the few helpers both backends offer alike (``executor``,
``spin_until``, ``new_context``, ``wait_for_acks``). Imported by :mod:`ifc_spg.ros` only when
rclpy imports; use that module, not this one.
"""

import os
import sys
import time as _time
from typing import TYPE_CHECKING
import weakref as _weakref

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
import rclpy
from rclpy import ok
from rclpy.callback_groups import CallbackGroup as _CallbackGroup
from rclpy.context import Context as _Context
from rclpy.executors import ExternalShutdownException as _ExternalShutdown
from rclpy.executors import SingleThreadedExecutor as _Executor
from rclpy.node import Node as _RclpyNode
from rclpy.parameter import Parameter
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from rclpy.signals import SignalHandlerOptions

from ifc_spg.ros import protocols as _protocols
from ifc_spg.ros.ros_args import parse_ros_args

__all__ = [
    'BACKEND',
    'DurabilityPolicy',
    'FloatingPointRange',
    'HistoryPolicy',
    'HotPath',
    'IntegerRange',
    'Node',
    'Parameter',
    'ParameterDescriptor',
    'QoSProfile',
    'RMW',
    'ReliabilityPolicy',
    'SetParametersResult',
    'executor',
    'init',
    'latched',
    'new_context',
    'ok',
    'qos_profile_sensor_data',
    'shutdown',
    'spin',
    'spin_hot',
    'spin_once',
    'spin_until',
    'wait_for_acks',
]

BACKEND = 'rclpy'

def _rmw():
    from rclpy.utilities import get_rmw_implementation_identifier
    try:
        return get_rmw_implementation_identifier()
    except Exception:  # noqa: BLE001 - only for the start-up log line
        return os.environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')

RMW = _rmw()
_nodes: '_weakref.WeakSet[Node]' = _weakref.WeakSet()

class Node(_RclpyNode):
    """rclpy's Node, destroyed with its context.

    :func:`shutdown` destroys the nodes of the context it shuts down (as the built-in
    backend does), so that a node does not outlive its context on the graph.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        _nodes.add(self)

def latched(depth=1):
    """Reliable, transient-local, keep-last ``depth`` profile."""
    return QoSProfile(depth=depth, durability=DurabilityPolicy.TRANSIENT_LOCAL)

def init(args=None, *, context=None, **kwargs):
    """rclpy.init, after the ``--ros-args`` are checked; returns the context.

    The same parser as the built-in backend's checks them (clear errors, e.g.
    ``malformed '-p rate=5'``).
    """
    parse_ros_args(sys.argv if args is None else args)
    # rclpy's own handlers shut the context down from a signal thread, under a loop that
    # may be publishing ('publisher's context is invalid'); the programs handle SIGINT and
    # SIGTERM in Python instead (ifc_spg.entry), as the built-in backend does
    kwargs.setdefault('signal_handler_options', SignalHandlerOptions.NO)
    rclpy.init(args=args, context=context, **kwargs)
    return context or rclpy.get_default_context()

def shutdown(*, context=None):
    """Destroy the nodes of the default (or given) context and shut it down.

    A no-op when it is not initialised.
    """
    ctx = context or rclpy.get_default_context()
    for node in list(_nodes):
        if node.context is ctx:
            _nodes.discard(node)
            try:
                node.destroy_node()
            except Exception:  # noqa: BLE001,S110 - already destroyed with its handle
                pass
    rclpy.try_shutdown(context=context)

def new_context(args=None):
    """A second, initialised context (for a node that must not share the default one)."""
    ctx = _Context()
    init(args=args, context=ctx)
    return ctx

_executors: '_weakref.WeakValueDictionary[tuple[int, ...], _NodesExecutor]' = (
    _weakref.WeakValueDictionary())

class _NodesExecutor:
    """A SingleThreadedExecutor over a fixed set of nodes.

    A node taken over by another executor in between is added back before each spin.
    """

    def __init__(self, nodes):
        self.nodes = [_weakref.ref(n) for n in nodes]
        if os.environ.get('IFC_SPG_RCLPY_EXECUTOR') == 'events':
            from rclpy.experimental import EventsExecutor
            self.executor = EventsExecutor(context=nodes[0].context)
        else:
            self.executor = _Executor(context=nodes[0].context)

    def spin_once(self, timeout_sec=None):
        for ref in self.nodes:
            node = ref()
            if node is not None and node.executor is not self.executor:
                self.executor.add_node(node)
        if not self.executor.context.ok():
            return
        try:
            self.executor.spin_once(timeout_sec=timeout_sec)
        except _ExternalShutdown:  # a signal shut the context down: callers check ok()
            pass
        except Exception:  # the same, between the check above and the wait set's creation
            if self.executor.context.ok():
                raise

def wait_for_acks(publisher, timeout_sec=1.0):
    """Wait until every matched reliable reader acknowledged what ``publisher`` sent.

    True if they did within ``timeout_sec`` [s].
    """
    from rclpy.duration import Duration

    return publisher.wait_for_all_acked(Duration(seconds=timeout_sec))

def spin(node, executor=None):
    """Run callbacks of ``node`` until its context shuts down.

    A signal ends it quietly, as with the built-in backend.
    """
    ex = globals()['executor']((node,)) if executor is None else executor
    while node.context.ok():
        ex.spin_once(timeout_sec=0.1)

class _Claimed(_CallbackGroup):
    """The callback group of a subscription served by :func:`spin_hot`: no executor runs it."""

    def can_execute(self, entity):
        return False

    def beginning_execution(self, entity):
        return False

    def ending_execution(self, entity):
        pass

def spin_hot(node, subscription, timeout_sec=0.1, until=None):
    """Run callbacks of ``node`` until its context shuts down, ``subscription`` first.

    The hot path without the executor (:class:`HotPath`), in a loop. While it runs no
    executor serves ``subscription``; a signal ends it quietly, as :func:`spin`.

    Args:
        node: The node.
        subscription: One of its subscriptions (the joint states).
        timeout_sec: Longest wait [s] between checks of the context and the QoS events.
        until: Optional ``until()``: end the loop (checked after each wait) when True, e.g.
            before shutting the context down from another thread.
    """
    hot = HotPath(node, subscription)
    try:
        while node.context.ok() and not (until is not None and until()):
            hot.spin_once(timeout_sec)
    finally:
        hot.close()

class HotPath:
    """``subscription`` of ``node`` served without the executor, one wait at a time.

    :meth:`spin_once` waits on a wait set of the node's subscriptions, timers, services,
    clients and guard conditions (rebuilt only when they change), takes a message of
    ``subscription`` itself and calls its callback, and calls the timers that are due.
    Anything else ready — and, at least every :attr:`REST_PERIOD`, what the wait set leaves
    out (the QoS event handlers) — is left to a SingleThreadedExecutor spun without waiting.
    rclpy's executor fills a new wait set on every spin (each publisher's and subscription's
    QoS event handlers included): a bridge waiting for its command through it spent more CPU
    there than on its simulation, and an idle ``spg_node`` spun it for each of its
    watchdog's and markers' timer events. Until :meth:`close` no executor serves ``subscription``.
    """

    #: [s] longest time between two spins of the executor of the rest of the node
    REST_PERIOD = 0.1

    def __init__(self, node, subscription):
        self.node, self.subscription, self.context = node, subscription, node.context
        self.rest = _Executor(context=node.context)
        self.rest.add_node(node)
        self._group, subscription.callback_group = subscription.callback_group, _Claimed()
        self.entities = _entities(node)
        self.wait_set = _WaitSet(self.context, self.entities)
        self._rest_at = 0.0

    def spin_once(self, timeout_sec=None):
        """Wait up to ``timeout_sec`` [s] (None: 0.1 s) for one round of callbacks."""
        context, sub = self.context, self.subscription
        if not context.ok():
            return
        now = _entities(self.node)
        if now != self.entities:
            self.entities, self.wait_set = now, _WaitSet(context, now)
        ready = self.wait_set.wait(round((0.1 if timeout_sec is None else timeout_sec) * 1e9))
        hot = sub.handle.pointer in ready
        if hot:
            taken = sub.handle.take_message(sub.msg_type, sub.raw)
            if taken is not None:
                sub.callback(taken[0])
        self.wait_set.run_timers()
        now_s = _time.monotonic()
        if len(ready) > hot or self.wait_set.others_ready() or now_s >= self._rest_at:
            self._rest_at = now_s + self.REST_PERIOD
            _spin_rest(self.rest, context)

    def close(self):
        """Give ``subscription`` back to the executors."""
        self.subscription.callback_group = self._group
        self.rest.shutdown(timeout_sec=0)

def _spin_rest(rest, context):
    """Run what is ready on the rest of the node without waiting (quiet at shutdown)."""
    if not context.ok():
        return
    try:
        rest.spin_once(timeout_sec=0)
    except _ExternalShutdown:
        pass
    except Exception:
        if context.ok():
            raise

def _entities(node):
    """What the hot path waits on: the node's entities but its waitables, comparable."""
    return (tuple(node._subscriptions), tuple(node._timers), tuple(node._services),
            tuple(node._clients), tuple(node._guards))

class _WaitSet:
    """An rcl wait set over ``entities`` (:func:`_entities`), filled again for each wait."""

    def __init__(self, context, entities):
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

        subs, timers, services, clients, guards = entities
        self.timers = timers
        self.wait_set = ws = _rclpy.WaitSet(len(subs), len(guards), len(timers), len(clients),
                                            len(services), 0, context.handle)
        self.adds = [(ws.add_subscription, [s.handle for s in subs]),
                     (ws.add_timer, [t.handle for t in timers]),
                     (ws.add_service, [s.handle for s in services]),
                     (ws.add_client, [c.handle for c in clients]),
                     (ws.add_guard_condition, [g.handle for g in guards])]

    def wait(self, timeout_ns):
        """Wait up to ``timeout_ns`` [ns]; the pointers of the subscriptions ready."""
        ws = self.wait_set
        ws.clear_entities()
        for add, handles in self.adds:
            for h in handles:
                add(h)
        ws.wait(timeout_ns)
        return ws.get_ready_entities('subscription')

    def run_timers(self):
        """Call the timers the last wait found due, as rclpy's executor does."""
        ready = self.wait_set.get_ready_entities('timer')
        if not ready:
            return
        for timer in self.timers:
            if timer.handle.pointer in ready:
                with timer.handle:
                    if not timer.handle.is_timer_ready():  # cancelled since
                        continue
                    timer.handle.call_timer()
                timer.callback()

    def others_ready(self):
        """Services, clients or guard conditions ready (left to the executor)."""
        ws = self.wait_set
        return any(ws.get_ready_entities(k) for k in ('service', 'client', 'guard_condition'))

def executor(nodes):
    """The (cached) executor of ``nodes``: ``executor(nodes).spin_once(timeout_sec)``."""
    nodes = (nodes,) if isinstance(nodes, Node) else tuple(nodes)
    key = tuple(id(n) for n in nodes)
    ex = _executors.get(key)
    if ex is None:
        ex = _executors[key] = _NodesExecutor(nodes)
        # the cache holds it weakly: the nodes keep it alive
        for node in nodes:
            node.__dict__.setdefault('_ifc_spg_executors', []).append(ex)
    return ex

def spin_once(node, *, executor=None, timeout_sec=None):  # noqa: F811
    """Run at most one callback of ``node`` (waiting up to ``timeout_sec`` [s])."""
    if executor is not None:
        return rclpy.spin_once(node, executor=executor, timeout_sec=timeout_sec)
    return globals()['executor']((node,)).spin_once(timeout_sec)

def spin_until(condition, timeout_sec=5.0, nodes=None):
    """Spin ``nodes`` until ``condition()`` or ``timeout_sec`` [s]; True if it held."""
    if nodes is None:
        raise ValueError('spin_until needs the nodes to spin with rclpy')
    ex = executor(nodes)
    context = ex.executor.context
    deadline = _time.monotonic() + timeout_sec
    while not condition():
        remaining = deadline - _time.monotonic()
        if remaining <= 0 or not context.ok():
            return bool(condition())
        ex.spin_once(timeout_sec=min(remaining, 0.1))
    return True


if TYPE_CHECKING:  # this backend's Node meets the Protocol node code is typed with
    def _meets_protocol(node: Node) -> _protocols.Node:
        return node
