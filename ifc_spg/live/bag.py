"""Record and play rosbag2 bags over DDS (``ifc-spg bag record/play``).

    ifc-spg bag record -o DIR [TOPIC ...] [--all] [--duration S] [--robot NAME] [--no-tf]
                       [--ros-args ...]
    ifc-spg bag play DIR [--rate R] [--delay S] [--topics T ...] [--ros-args ...]

The bags are :mod:`ifc_spg.offline.bag`'s (its :class:`~ifc_spg.offline.bag.BagWriter` and
:class:`~ifc_spg.offline.bag.BagReader`); this module is the live side, over either ROS
backend (:mod:`ifc_spg.ros`). ``play`` republishes each topic with the reliability and
durability its publishers offered when it was recorded (the latched ``spg/task_stack`` stays
latched, with its recorded depth); volatile topics keep :data:`PLAY_DEPTH` samples for
readers that fell behind, so a reliable reader on a busy machine loses none.

``record`` with no topics records the topics of ARCHITECTURE.md "Topics" (relative names,
resolved in the node's namespace) and every streamed task reference under
``spg/reference/``; types of known topics are fixed, other topics are discovered on the DDS
graph. It writes every message it receives with its receive time and
closes the bag cleanly on SIGINT/SIGTERM (and after ``--duration`` seconds): messages
received before the stop are written, however far behind the recorder was (at most
:data:`FLUSH_TIMEOUT` s), then the MCAP index and ``metadata.yaml``. A message's log time is
the time the DDS layer received it (rclpy; the built-in backend: when it was taken). It also writes
``/robot_description``, ``/tf_static`` and ``/tf`` computed from the recorded
``joint_states`` (and ``command/joint_position`` as the ``virtual/`` tree) of the robot
``--robot`` or ``spg/config`` names (:mod:`ifc_spg.offline.foxglove`; ``--no-tf``: not).
"""

from collections.abc import Collection
import functools
import importlib
import signal
import time
from typing import Any

from ifc_spg import ros
from ifc_spg.errors import ParameterError
from ifc_spg.offline.bag import TOPICS, BagReader, BagWriter, from_rosbags_qos
from ifc_spg.ros import messages
from ifc_spg.ros.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['RclpyRecorder', 'Recorder', 'play', 'record']


# -- record -------------------------------------------------------------------------------

class _Stop:
    """Set by SIGINT/SIGTERM (the handlers only set a flag; the loop closes the bag)."""

    def __init__(self):
        self.requested = False

    def __call__(self, signum, frame):
        self.requested = True


def _absolute(node, topic):
    return node.resolve_topic_name(topic)


def _discovered(participant, reader):
    """New ``(topic, ros type, offered QoSProfile)`` of ROS writers seen by ``reader``."""
    out = []
    for sample in reader.take(N=256):
        name = getattr(sample, 'topic_name', None) or ''
        dds_type = getattr(sample, 'type_name', None) or ''
        if not name.startswith('rt/') or '::dds_::' not in dds_type:
            continue
        pkg, sub, _, tname = dds_type.split('::')
        qos = sample.qos
        policies = [type(p).__name__ for p in (qos or ())]
        reliable = any(p.endswith('.Reliable') for p in policies)
        transient = any(p.endswith('.TransientLocal') for p in policies)
        out.append((name[2:], f'{pkg}/{sub}/{tname.rstrip("_")}', QoSProfile(
            depth=10, reliability=ReliabilityPolicy.RELIABLE if reliable
            else ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.TRANSIENT_LOCAL if transient
            else DurabilityPolicy.VOLATILE)))
    return out


class _Recording:
    """What both recorders share.

    The topics they record, and writing what arrived, then looking for new topics on the
    graph (at most every 0.2 s).
    """

    _last_discovery = 0.0
    #: Receive time [ns, system clock] of the newest message written (0: none yet).
    newest_received_ns = 0
    # set by the recorders: the node (of either backend), the subscriptions (None: a topic
    # that cannot be recorded), the topics asked for, whether to record every topic
    node: Any
    _subs: dict[str, Any]
    _wanted: Collection[str]
    discover_all: bool

    def drain(self) -> int:
        """Write what arrived; return how many messages."""
        raise NotImplementedError

    def discover(self) -> None:
        """Subscribe to the wanted topics that appeared on the graph."""
        raise NotImplementedError

    @property
    def recording(self):
        """The topics subscribed to."""
        return [t for t, s in self._subs.items() if s is not None]

    _references = None  # '<ns>/spg/reference/' when recording the default topics

    def _wants(self, topic):
        """Record a discovered ``topic``: asked for, a streamed task reference, or --all."""
        return topic in self._wanted or bool(
            self._references and topic.startswith(self._references)) or (
            self.discover_all and topic not in ('/rosout', '/parameter_events'))

    def _write_and_discover(self):
        n = self.drain()
        now = time.monotonic()
        if now - self._last_discovery > 0.2:
            self._last_discovery = now
            self.discover()
        return n


class Recorder(_Recording):
    """Records topics of the built-in DDS backend into a bag (``ifc-spg bag record``).

    Args:
        node: A node of :mod:`ifc_spg.ros.dds`.
        writer: A :class:`BagWriter`.
        topics: Topic names to record (relative or absolute); None: ``TOPICS``.
        discover_all: Also record every other ROS topic that appears on the graph.
    """

    def __init__(self, node, writer, topics=None, discover_all=False):
        # the built-in backend's DDS library: imported on its path only (rclpy has its own)
        from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication
        from cyclonedds.core import WaitSet

        self.node = node
        self.writer = writer
        self.discover_all = discover_all
        self._subs = {}
        self._wanted: dict[str, bool] = {}
        self._waitset = WaitSet(node.context.participant)
        self._waitset.attach(node.context.guard)
        if topics is None:
            self._references = _absolute(node, 'spg/reference').rstrip('/') + '/'
        for topic in (TOPICS if topics is None else topics):
            name = _absolute(node, topic)
            known = TOPICS.get(topic) or TOPICS.get(name.lstrip('/'))
            self._wanted[name] = True
            if known is not None:
                self._subscribe(name, *known)
        self._pubs = BuiltinDataReader(node.context.participant, BuiltinTopicDcpsPublication)
        self._last_discovery = 0.0


    def _subscribe(self, topic, msgtype, qos):
        cls = messages.REGISTRY.get(msgtype)
        if cls is None:
            self.node.get_logger().warning(f"not recording '{topic}': type '{msgtype}' has no "
                                           'built-in message class')
            self._subs[topic] = None
            return
        # keep everything until it is written: reliable readers never drop samples
        reader_qos = QoSProfile(depth=1, reliability=qos.reliability, durability=qos.durability,
                                history=HistoryPolicy.KEEP_ALL)
        # no executor spins this node: drain() takes the serialized samples
        sub = self.node.create_subscription(cls, topic, lambda msg: None, reader_qos)
        self._waitset.attach(sub.read_condition)
        self.writer.add_topic(topic, msgtype, qos)
        self._subs[topic] = sub

    def discover(self):
        """Subscribe to newly discovered topics we want (typed by the graph)."""
        for topic, msgtype, qos in _discovered(self.node.context.participant, self._pubs):
            if topic in self._subs:
                continue
            if self._wants(topic):
                self._subscribe(topic, msgtype, qos)

    def drain(self):
        """Take every available sample and write it (receive time as log time)."""
        n = 0
        for topic, sub in self._subs.items():
            if sub is None:
                continue
            samples = sub.take_serialized()
            if samples:
                t = time.time_ns()
                for data in samples:
                    self.writer.write(topic, t, data)
                n += len(samples)
                # one take holds every sample the reader had: all received by now
                self.newest_received_ns = t
        return n

    def spin_once(self, timeout_s=0.1):
        """Wait up to ``timeout_s`` [s] for data, write what arrived, look for new topics."""
        self._waitset.wait(int(timeout_s * 1e9))
        self.node.context.guard.take()
        return self._write_and_discover()


def _received(pending, topic, data, info):
    """Keep ``(topic, receive time [ns], bytes)`` of an rclpy raw callback for drain()."""
    t = info.get('received_timestamp', 0) if isinstance(info, dict) else 0
    pending.append((topic, t if t > 0 else time.time_ns(), data))


def _rclpy_message_class(msgtype):
    """The rclpy class of ROS type ``pkg/msg/T``.

    rosidl_runtime_py is not among the Jazzy wheels, so the generated module is imported by
    name.
    """
    pkg, kind, name = msgtype.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


def _from_rclpy_qos(profile):
    """Our QoSProfile of an rclpy QoSProfile (the offered profile of a discovered writer)."""
    depth = int(profile.depth) or 10
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy(int(profile.reliability)),
                      durability=DurabilityPolicy(int(profile.durability)))


class RclpyRecorder(_Recording):
    """Records topics over rclpy into a bag.

    Raw (serialized CDR) subscriptions, written with their receive time, so the bytes are
    those on the wire (as ``ros2 bag record``).

    Args:
        node: An rclpy node (``ifc_spg.ros.Node`` with the rclpy backend).
        writer: A :class:`BagWriter`.
        topics: Topic names to record (relative or absolute); None: ``TOPICS``.
        discover_all: Also record every other ROS topic that appears on the graph.
    """

    def __init__(self, node, writer, topics=None, discover_all=False):
        self.node, self.writer, self.discover_all = node, writer, discover_all
        self._executor = ros.executor((node,))
        self._subs, self._wanted, self._pending = {}, set(), []
        self._last_ns: dict[str, int] = {}  # the last log time written per topic
        if topics is None:
            self._references = _absolute(node, 'spg/reference').rstrip('/') + '/'
        for topic in (TOPICS if topics is None else topics):
            name = _absolute(node, topic)
            known = TOPICS.get(topic) or TOPICS.get(name.lstrip('/'))
            self._wanted.add(name)
            if known is not None:
                self._subscribe(name, *known)
        self._last_discovery = 0.0

    def _subscribe(self, topic, msgtype, qos):
        try:
            cls = _rclpy_message_class(msgtype)
        except (ImportError, AttributeError, ValueError):
            self.node.get_logger().warning(f"not recording '{topic}': no rclpy message class "
                                           f"for '{msgtype}'")
            self._subs[topic] = None
            return
        reader_qos = ros.QoSProfile(depth=1000,
                                    reliability=ros.ReliabilityPolicy(int(qos.reliability)),
                                    durability=ros.DurabilityPolicy(int(qos.durability)))
        # two parameters: rclpy passes the message info, with the time the DDS layer received
        # the message (not the later time the executor ran the callback)
        self._subs[topic] = self.node.create_subscription(
            cls, topic, functools.partial(_received, self._pending, topic), reader_qos,
            raw=True)
        self.writer.add_topic(topic, msgtype, qos)


    def discover(self):
        """Subscribe to newly discovered topics we want (typed and QoS'd by the graph)."""
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self._subs or not types:
                continue
            if self._wants(topic):
                infos = self.node.get_publishers_info_by_topic(topic)
                qos = _from_rclpy_qos(infos[0].qos_profile) if infos else QoSProfile(depth=10)
                self._subscribe(topic, types[0], qos)

    def drain(self):
        """Write what arrived; the number of messages written."""
        n = len(self._pending)
        last = self._last_ns
        for topic, t, data in self._pending:
            # a sample a reliable writer sent again arrives after the ones behind it but is
            # handed over in order: its topic's log times stay in order
            t = last[topic] = max(t, last.get(topic, 0))
            self.writer.write(topic, t, data)
            self.newest_received_ns = max(self.newest_received_ns, t)
        self._pending.clear()
        return n

    def spin_once(self, timeout_s=0.1):
        """Run the callbacks ready within ``timeout_s`` [s], write them, look for new topics."""
        deadline = time.monotonic() + timeout_s
        self._executor.spin_once(timeout_sec=timeout_s)
        while time.monotonic() < deadline and len(self._pending) < 10000:
            self._executor.spin_once(timeout_sec=0.0)
            if not self._pending:
                break
        return self._write_and_discover()


class _Observed:
    """A :class:`BagWriter` that shows every message it writes to ``observer``."""

    def __init__(self, writer, observer):
        self._writer, self._observer = writer, observer

    def write(self, topic, t_ns, data):
        self._writer.write(topic, t_ns, data)
        self._observer(topic, t_ns, data)

    def __getattr__(self, name):
        return getattr(self._writer, name)


def record(path, topics=None, discover_all=False, duration=None, args=None, quiet=False,
           robot=None, foxglove=True):
    """Record until SIGINT/SIGTERM or ``duration`` [s]; returns {topic: count}.

    Args:
        path: Bag directory to create.
        topics: Topic names (None: the product's topics).
        discover_all: Also record every other topic discovered.
        duration: Stop after this many seconds (None: until a signal).
        args: Command line with ``--ros-args`` for the recorder node.
        quiet: Do not print the summary.
        robot: Robot configuration name for ``/robot_description`` and ``/tf`` (None: the
            one the SPG's ``spg/config`` or ``spg/status`` names).
        foxglove: Write ``/robot_description``, ``/tf_static`` and ``/tf`` from the recorded
            joint states (:class:`~ifc_spg.offline.foxglove.RecordingObserver`).
    """
    stop = _Stop()
    observer = None
    if foxglove:
        from ifc_spg.model import RobotModel
        from ifc_spg.offline.foxglove import RecordingObserver
        if robot is not None:
            RobotModel.from_config(robot)  # a bad --robot fails before the bag is created
        observer = RecordingObserver
    ros.init(args=['ifc-spg', *(args or [])])
    # after init: rclpy's own SIGINT handler would invalidate the context mid-spin
    old = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    node = ros.Node('bag_recorder')
    writer = BagWriter(path)
    try:
        sink = writer if observer is None else _Observed(writer, observer(writer, robot))
        rec = (Recorder if ros.BACKEND == 'cyclonedds' else RclpyRecorder)(
            node, sink, topics, discover_all)
        print(f'recording {", ".join(sorted(rec.recording)) or "(none)"}'
              f'{" + discovered topics" if discover_all or topics else ""} into {path}; '
              'stop with Ctrl-C', flush=True)
        start = time.monotonic()
        while not stop.requested and ros.ok():
            if duration is not None and time.monotonic() - start >= duration:
                break
            rec.spin_once(0.05)
        _flush(rec)
    finally:
        writer.close()
        for s, h in old.items():
            signal.signal(s, h)
        if ros.ok():
            node.destroy_node()
            ros.shutdown()
    if not quiet:
        print(f'bag closed: {path}; ' + ', '.join(f'{t}: {c}' for t, c in writer.counts.items()),
              flush=True)
    return dict(writer.counts)


#: At most this long [s] for writing, after a stop, what was received before it.
FLUSH_TIMEOUT = 30.0


def _flush(rec, timeout_s=FLUSH_TIMEOUT):
    """Write every message received before the stop.

    Samples a reliable writer saw acknowledged sit in the reader; rclpy hands them over only
    in callbacks, one executor turn each, so a recorder that fell behind (a busy machine)
    still holds a backlog at the stop. Spin until 50 ms pass without a message or a message
    received after the stop is written (a live stream: the backlog is done); at most
    ``timeout_s`` [s], with a warning.
    """
    stop_ns = time.time_ns()
    deadline = time.monotonic() + timeout_s
    while rec.spin_once(0.05) and rec.newest_received_ns <= stop_ns:
        if time.monotonic() > deadline:
            rec.node.get_logger().warning(
                f'still writing messages received before the stop after {timeout_s} s; '
                'closing the bag without the rest')
            break
    rec.drain()


# -- play ---------------------------------------------------------------------------------

#: History depth of ``play``'s volatile publishers (latched topics keep their recorded depth,
#: which is what a late subscriber receives): 2 s of a 500 Hz topic played at rate 2.
PLAY_DEPTH = 2000

def play(path, rate=1.0, delay=0.5, topics=None, args=None, wait_s=2.0, wait_subscribers=0,
         wait_timeout=30.0):
    """Publish a bag's messages with their original timing (scaled by ``rate``) and QoS.

    ``delay`` [s] is waited in any case; with ``wait_subscribers`` N, also until every topic
    has N matched subscriptions (at most ``wait_timeout`` [s]), then 0.5 s more. Discovery
    between two processes can take a DDS announcement period (Fast DDS: 3 s), so a fixed
    delay alone may publish to nobody.

    Args:
        path: Bag directory.
        rate: Playback speed factor (> 0).
        delay: Seconds to wait for discovery before the first message.
        topics: Only these topics (absolute or relative names); None: all.
        args: Command line with ``--ros-args`` for the player node.
        wait_s: Seconds to wait for reliable readers' acknowledgements at the end.
        wait_subscribers: Wait until every topic has this many matched subscriptions.
        wait_timeout: At most this long [s] for ``wait_subscribers``.

    Returns:
        {topic: messages published}.
    """
    if not rate > 0:
        raise ParameterError(f'--rate must be > 0, got {rate}')
    bag = BagReader(path)
    stop = _Stop()
    old = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    ros.init(args=['ifc-spg', *(args or [])])
    node = ros.Node('bag_player')
    counts = {}
    try:
        pubs = _publishers(node, bag, topics)
        counts.update(dict.fromkeys(pubs, 0))
        _wait_for_discovery(node, pubs, delay, stop, wait_subscribers, wait_timeout)
        _publish_timed(bag, pubs, rate, stop, counts)
        for pub in pubs.values():
            if not stop.requested:
                ros.wait_for_acks(pub, wait_s)
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        bag.close()
        if ros.ok():
            node.destroy_node()
            ros.shutdown()
    return counts


def _publishers(node, bag, topics):
    """A publisher per bag topic to play (in ``topics``, if given), with the recorded QoS."""
    pubs = {}
    for topic, (msgtype, _, profiles) in bag.topics.items():
        if topics and topic not in topics and topic.lstrip('/') not in topics:
            continue
        if ros.BACKEND == 'cyclonedds':
            cls = messages.REGISTRY.get(msgtype)
            if cls is None:
                node.get_logger().warning(f"skipping '{topic}': no message class for {msgtype}")
                continue
        else:
            cls = _rclpy_message_class(msgtype)
        default = TOPICS.get(topic.lstrip('/'), (None, QoSProfile(depth=10)))[1]
        qos = from_rosbags_qos(profiles, default)
        if qos.durability != DurabilityPolicy.TRANSIENT_LOCAL:
            # the writer keeps what a reliable reader has not acknowledged yet: depth is no
            # part of QoS matching, and a recorded depth of 10 at 1 kHz lets a reader that
            # falls 10 ms behind (its UDP socket full) lose samples the writer dropped
            qos = QoSProfile(depth=max(qos.depth, PLAY_DEPTH), reliability=qos.reliability,
                             durability=qos.durability)
        if ros.BACKEND != 'cyclonedds':
            qos = ros.QoSProfile(depth=qos.depth,
                                 reliability=ros.ReliabilityPolicy(int(qos.reliability)),
                                 durability=ros.DurabilityPolicy(int(qos.durability)))
        pubs[topic] = node.create_publisher(cls, topic, qos)
    return pubs


def _wait_for_discovery(node, pubs, delay, stop, wait_subscribers, wait_timeout):
    """Spin ``delay`` [s]; with ``wait_subscribers``, until every topic has that many."""
    deadline = time.monotonic() + delay
    while time.monotonic() < deadline and not stop.requested:
        ros.spin_once(node, timeout_sec=min(0.05, max(0.0, deadline - time.monotonic())))
    if wait_subscribers <= 0:
        return

    def matched():
        return all(p.get_subscription_count() >= wait_subscribers for p in pubs.values())

    if not ros.spin_until(lambda: matched() or stop.requested, wait_timeout, [node]):
        node.get_logger().warning(f'not every topic has {wait_subscribers} subscriber(s) after '
                                  f'{wait_timeout} s; playing anyway')
    ros.spin_until(lambda: stop.requested, 0.5, [node])


def _publish_timed(bag, pubs, rate, stop, counts):
    """Publish the messages of ``pubs``' topics at their log times / ``rate``."""
    start_wall = time.monotonic()
    for topic, _, t, data in bag.raw(set(pubs)):
        if stop.requested:
            break
        due = start_wall + (t - bag.start_ns) * 1e-9 / rate
        while not stop.requested:
            wait = due - time.monotonic()
            if wait <= 0:
                break
            time.sleep(min(wait, 0.05))  # pacing to the bag's timing, not polling
        _publish_raw(pubs[topic], data)
        counts[topic] += 1


def _publish_raw(pub, data):
    if ros.BACKEND == 'cyclonedds':
        pub.publish_serialized(data)
    else:  # rclpy publishes serialized bytes as they are
        pub.publish(bytes(data))
