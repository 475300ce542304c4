"""rosbag2 MCAP bags: write, read, record over DDS, play back, summarise (``ifc-spg bag``).

    ifc-spg bag record -o DIR [TOPIC ...] [--all] [--duration S] [--robot NAME] [--no-tf]
                       [--ros-args ...]
    ifc-spg bag play DIR [--rate R] [--delay S] [--topics T ...] [--ros-args ...]
    ifc-spg bag info DIR

Bags are rosbag2 directories as rosbag2 Jazzy writes them (``metadata.yaml`` version 9 with
``ros_distro: jazzy`` and each topic's ``type_description_hash``, one ``<name>_0.mcap`` file,
profile ``ros2``, schemas in ``ros2msg`` encoding, channels with ``offered_qos_profiles`` and
``topic_type_hash``, CDR messages), so ``ros2 bag``, ``rosbags``, the ``mcap`` reader and
Foxglove open them. Each topic records
its publishers' offered QoS profiles in the metadata, so ``play`` republishes with the
original reliability and durability (the latched ``spg/task_stack`` stays latched).

``record`` with no topics records the topics of ARCHITECTURE.md "Topics" (relative names,
resolved in the node's namespace) and every streamed task reference under
``spg/reference/``; types of known topics are fixed, other topics are discovered on the DDS
graph. It writes every message it receives with its receive time and
closes the bag cleanly on SIGINT/SIGTERM (and after ``--duration`` seconds): messages
already received are written, then the MCAP index and ``metadata.yaml``. It also writes
``/robot_description``, ``/tf_static`` and ``/tf`` computed from the recorded
``joint_states`` (and ``command/joint_position`` as the ``virtual/`` tree) of the robot
``--robot`` or ``spg/config`` names (:mod:`ifc_spg.offline.foxglove`; ``--no-tf``: not).
"""

from collections.abc import Collection
import importlib
from pathlib import Path
import signal
import time
from typing import Any

from mcap.writer import CompressionType, Writer
from rosbags.interfaces import (
    ConnectionExtRosbag2,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.metadata import dump_qos_v9
from rosbags.typesys import Stores, get_typestore
import yaml

from ifc_spg import ros
from ifc_spg.errors import ParameterError
from ifc_spg.ros import messages
from ifc_spg.ros.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    latched,
    qos_profile_sensor_data,
)
from ifc_spg.ros.stamps import stamp_to_ns

__all__ = [
    'TOPICS',
    'BagReader',
    'ROS_DISTRO',
    'BagWriter',
    'from_rosbags_qos',
    'info',
    'play',
    'record',
    'rosbag2_metadata',
    'stamp_ns',
    'to_rosbags_qos',
]

#: The product's topics (ARCHITECTURE.md "Topics"): relative name -> (type, QoS).
TOPICS = {
    'joint_states': ('sensor_msgs/msg/JointState', QoSProfile(depth=10)),
    'command/joint_position': ('sensor_msgs/msg/JointState', QoSProfile(depth=10)),
    'spg/task_stack': ('std_msgs/msg/String', latched(1)),
    'spg/status': ('std_msgs/msg/String', QoSProfile(depth=10)),
    'spg/config': ('std_msgs/msg/String', latched(1)),
    'spg/state': ('std_msgs/msg/Float64MultiArray', latched(1)),
    'spg/diagnostics': ('diagnostic_msgs/msg/DiagnosticArray', QoSProfile(depth=10)),
    'ft_sensor/wrench': ('geometry_msgs/msg/WrenchStamped', qos_profile_sensor_data),
    'sim/contact_wrench': ('geometry_msgs/msg/WrenchStamped', qos_profile_sensor_data),
    'sim/env_joint_states': ('sensor_msgs/msg/JointState', QoSProfile(depth=10)),
    'sim/apply_wrench': ('geometry_msgs/msg/WrenchStamped', QoSProfile(depth=10)),
}

_INFINITE_NS = (9223372036, 854775807)  # rmw's "infinite" duration as Jazzy writes it


#: A ``builtin_interfaces/Time`` as integer nanoseconds (:func:`ifc_spg.ros.stamps.stamp_to_ns`).
stamp_ns = stamp_to_ns


def to_rosbags_qos(qos):
    """Translate our :class:`~ifc_spg.ros.qos.QoSProfile` into a rosbags ``Qos`` (offered)."""
    inf = QosTime(*_INFINITE_NS)
    return Qos(history=QosHistory(int(qos.history)), depth=int(qos.depth),
               reliability=QosReliability(int(qos.reliability)),
               durability=QosDurability(int(qos.durability)), deadline=inf, lifespan=inf,
               liveliness=QosLiveliness.AUTOMATIC, liveliness_lease_duration=inf,
               avoid_ros_namespace_conventions=False)


def from_rosbags_qos(profiles, default):
    """Our QoSProfile for republishing from recorded offered profiles (rosbag2 play's rule).

    Reliable only if every recorded publisher was reliable; transient local only if every
    one was; depth from the first profile that knows it (else ``default.depth``).
    """
    if not profiles:
        return default
    names = [(p.reliability.name, p.durability.name, p.history.name, p.depth) for p in profiles]
    reliable = all(r == 'RELIABLE' for r, *_ in names)
    transient = all(d == 'TRANSIENT_LOCAL' for _, d, *_ in names)
    depth = next((d for _, _, h, d in names if h == 'KEEP_LAST' and d > 0), default.depth)
    return QoSProfile(depth=int(depth),
                      reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if transient
                      else DurabilityPolicy.VOLATILE)


def _typestore():
    return get_typestore(Stores.ROS2_JAZZY)


#: ``ros_distro`` of the bags we write: our message types are Jazzy's (rosbag2 writes the
#: ``ROS_DISTRO`` of the recording machine, rosbag2_cpp SequentialWriter::init_metadata).
ROS_DISTRO = 'jazzy'


def rosbag2_metadata(topics, files, custom_data=None):
    """The ``rosbag2_bagfile_information`` rosbag2 Jazzy writes, keys in its order.

    rosbag2_storage/include/rosbag2_storage/yaml.hpp (branch jazzy), ``convert<BagMetadata>::
    encode``, ``convert<TopicInformation>::encode``, ``convert<TopicMetadata>::encode`` (version
    9: ``offered_qos_profiles`` a sequence, ``type_description_hash`` the RIHS01 string) and
    ``convert<FileInformation>::encode``.

    Args:
        topics: ``[(name, type, offered QoS as dump_qos_v9 dicts, RIHS01 hash, count)]``.
        files: ``[(relative path, start [ns], duration [ns], message count)]``.
        custom_data: str -> str (rosbag2 writes an empty map as ``{}``).
    """
    start = min((f[1] for f in files), default=0)
    end = max((f[1] + f[2] for f in files), default=0)
    count = sum(f[3] for f in files)
    return {
        'version': 9,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': end - start},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': count,
        'topics_with_message_count': [
            {'topic_metadata': {'name': name, 'type': msgtype, 'serialization_format': 'cdr',
                                'offered_qos_profiles': qos, 'type_description_hash': digest},
             'message_count': n}
            for name, msgtype, qos, digest, n in topics],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [f[0] for f in files],
        'files': [{'path': p, 'starting_time': {'nanoseconds_since_epoch': s},
                   'duration': {'nanoseconds': d}, 'message_count': n}
                  for p, s, d, n in files],
        'custom_data': dict(custom_data or {}),
        'ros_distro': ROS_DISTRO,
    }


def _yaml_dump(doc):
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=False, width=1 << 16)


class BagWriter:
    """Writes a rosbag2 MCAP bag as rosbag2 Jazzy does.

    That is: metadata version 9, ``ros_distro: jazzy``, ``type_description_hash`` per topic,
    ``topic_type_hash`` per MCAP channel.

    Args:
        path: Bag directory to create (must not exist).

    The MCAP file (``<name>_0.mcap``, profile ``ros2``, ``ros2msg`` schemas, uncompressed
    chunks) is written with the ``mcap`` library; message definitions, RIHS01 hashes and the
    QoS encoding come from ``rosbags``' Jazzy typestore. Use as a context manager or call
    :meth:`close`; topics are added on first use.
    """

    def __init__(self, path):
        self.path = Path(path)
        if self.path.exists():
            raise ParameterError(f"cannot create bag '{self.path}': it exists (choose a new "
                                 'directory or remove the old one)')
        try:
            self.path.mkdir(parents=True)
            self._file_name = f'{self.path.name}_0.mcap'
            self._file = open(self.path / self._file_name, 'xb')
        except OSError as exc:
            raise ParameterError(f"cannot create bag '{self.path}': {exc}") from None
        # rosbag2_storage_mcap's default storage preset: chunks without compression
        self._mcap = Writer(self._file, compression=CompressionType.NONE)
        self._mcap.start(profile='ros2', library='ifc_spg (rosbag2 jazzy layout)')
        self._store = _typestore()
        self._schemas = {}
        self._connections = {}  # topic -> (channel id, type, qos dicts, hash)
        self._custom = {}
        self._start = self._end = None
        self.counts = {}
        self._closed = False

    def add_topic(self, topic, msgtype, qos=None):
        """Register ``topic`` of ROS type ``msgtype`` with offered QoS profile(s).

        Args:
            topic: Absolute topic name (``/joint_states``).
            msgtype: ROS type name (``sensor_msgs/msg/JointState``).
            qos: A QoSProfile, a list of rosbags ``Qos``, or None (reliable depth 10).
        """
        if topic in self._connections:
            return self._connections[topic][0]
        if msgtype not in self._store.types:
            raise ParameterError(f"topic '{topic}': unknown message type '{msgtype}' (the bag "
                                 'writer knows the ROS 2 Jazzy standard types)')
        if qos is None:
            qos = QoSProfile(depth=10)
        profiles = [to_rosbags_qos(qos)] if isinstance(qos, QoSProfile) else list(qos)
        digest = self._store.hash_rihs01(msgtype)
        if msgtype not in self._schemas:
            msgdef, _ = self._store.generate_msgdef(msgtype, ros_version=2)
            self._schemas[msgtype] = self._mcap.register_schema(
                name=msgtype, encoding='ros2msg', data=msgdef.encode())
        dumped = dump_qos_v9(profiles)
        # rosbag2_storage_mcap/src/mcap_storage.cpp (jazzy), MCAPStorage::create_topic: the
        # channel carries offered_qos_profiles (serialize_rclcpp_qos_vector, version 9) and
        # topic_type_hash (the topic's type_description_hash)
        channel = self._mcap.register_channel(
            topic=topic, message_encoding='cdr', schema_id=self._schemas[msgtype],
            metadata={'offered_qos_profiles': _yaml_dump(dumped).rstrip('\n'),
                      'topic_type_hash': digest})
        self._connections[topic] = (channel, msgtype, dumped, digest)
        self.counts[topic] = 0
        return channel

    def write(self, topic, t_ns, data):
        """Write serialized CDR ``data`` on registered ``topic`` at log time ``t_ns`` [ns]."""
        t = int(t_ns)
        self._mcap.add_message(self._connections[topic][0], log_time=t, data=bytes(data),
                               publish_time=t)
        self.counts[topic] += 1
        self._start = t if self._start is None else min(self._start, t)
        self._end = t if self._end is None else max(self._end, t)

    def write_msg(self, topic, t_ns, msg):
        """Serialize a built-in message (:mod:`ifc_spg.ros.messages`) and write it."""
        if topic not in self._connections:
            self.add_topic(topic, type(msg)._TYPE)  # the class constant ros.messages documents
        self.write(topic, t_ns, messages.serialize(msg))

    def set_custom_data(self, key, value):
        """Store a string in the metadata's ``custom_data``."""
        self._custom[str(key)] = str(value)

    def metadata(self):
        """The ``rosbag2_bagfile_information`` of what was written so far (dict)."""
        start = self._start or 0
        files = [(self._file_name, start, (self._end or 0) - start, sum(self.counts.values()))]
        topics = [(t, c[1], c[2], c[3], self.counts[t]) for t, c in self._connections.items()]
        return rosbag2_metadata(topics, files, self._custom)

    def close(self):
        """Write the MCAP summary and ``metadata.yaml``; idempotent."""
        if self._closed:
            return
        self._closed = True
        info = self.metadata()
        # MCAPStorage::update_metadata: a metadata record 'rosbag2' with the YAML of the
        # BagMetadata, written when the writer closes
        self._mcap.add_metadata('rosbag2', {'serialized_metadata': _yaml_dump(info)})
        self._mcap.finish()
        self._file.close()
        tmp = self.path / 'metadata.yaml.tmp'
        tmp.write_text(_yaml_dump({'rosbag2_bagfile_information': info}), 'utf8')
        tmp.replace(self.path / 'metadata.yaml')

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class BagReader:
    """Reads a rosbag2 bag (any storage ``rosbags`` reads) with the built-in messages.

    Args:
        path: Bag directory.

    Attributes:
        topics: Topic -> (type, message count, offered QoS profiles).
        custom_data: The metadata's ``custom_data`` dict.
        start_ns, end_ns: First and last log time [ns].
    """

    def __init__(self, path):
        self.path = Path(path)
        if not (self.path / 'metadata.yaml').is_file():
            raise ParameterError(f"'{self.path}' is not a rosbag2 bag (no metadata.yaml); give "
                                 'the bag directory written by ifc-spg run/bag record')
        self._reader = Reader(self.path)
        self._reader.open()
        # topic -> (type, message count, offered QoS profiles)
        self.topics: dict[str, tuple[str, int, list[Any]]] = {}
        for c in self._reader.connections:
            if not isinstance(c.ext, ConnectionExtRosbag2):  # a rosbag2 reader's connection
                raise ParameterError(f"bag '{self.path}': topic {c.topic} is not a rosbag2 "
                                     'connection')
            old = self.topics.get(c.topic)
            count = c.msgcount + (old[1] if old else 0)
            self.topics[c.topic] = (c.msgtype, count, list(c.ext.offered_qos_profiles))
        with open(self.path / 'metadata.yaml', encoding='utf8') as f:
            meta = yaml.safe_load(f)['rosbag2_bagfile_information']
        self.custom_data = dict(meta.get('custom_data') or {})
        self.start_ns = self._reader.start_time if self._reader.message_count else 0
        self.end_ns = self._reader.end_time if self._reader.message_count else 0
        self.version = meta.get('version')
        self.storage = meta.get('storage_identifier')
        self.message_count = self._reader.message_count

    def raw(self, topics=None):
        """Yield ``(topic, msgtype, log time [ns], CDR bytes)`` in log-time order."""
        conns = [c for c in self._reader.connections if topics is None or c.topic in topics]
        for c, t, data in self._reader.messages(connections=conns):
            yield c.topic, c.msgtype, t, data

    def messages(self, topics=None):
        """Yield ``(topic, log time [ns], message)`` decoded with the built-in classes.

        With ``topics`` None: every topic with a built-in class (``/tf`` and ``/tf_static``,
        tf2_msgs, have none: read them with :meth:`raw` and rosbags); a topic asked for by
        name without one is an error.
        """
        if topics is None:
            topics = {t for t, (msgtype, _, _) in self.topics.items()
                      if msgtype in messages.REGISTRY}
        for topic, msgtype, t, data in self.raw(topics):
            cls = messages.REGISTRY.get(msgtype)
            if cls is None:
                raise ParameterError(f"topic '{topic}': no built-in decoder for '{msgtype}'")
            yield topic, t, messages.deserialize(cls, data)

    def close(self):
        """Close the reader."""
        self._reader.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


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
        return n

    def spin_once(self, timeout_s=0.1):
        """Wait up to ``timeout_s`` [s] for data, write what arrived, look for new topics."""
        self._waitset.wait(int(timeout_s * 1e9))
        self.node.context.guard.take()
        return self._write_and_discover()


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
        pending = self._pending
        self._subs[topic] = self.node.create_subscription(
            cls, topic, lambda data, t=topic: pending.append((t, time.time_ns(), data)),
            reader_qos, raw=True)
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
        for topic, t, data in self._pending:
            self.writer.write(topic, t, data)
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


def _flush(rec, timeout_s=1.0):
    """Write what already arrived: spin until 50 ms pass without a message (at most 1 s).

    Samples a reliable writer saw acknowledged sit in the reader; rclpy hands them over only
    in callbacks, so a stop right after the last publish still spins them out.
    """
    deadline = time.monotonic() + timeout_s
    while rec.spin_once(0.05) and time.monotonic() < deadline:
        pass
    rec.drain()


# -- play ---------------------------------------------------------------------------------

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


# -- info ---------------------------------------------------------------------------------

def info(path):
    """Return the text ``ifc-spg bag info`` prints."""
    with BagReader(path) as bag:
        dur = (bag.end_ns - bag.start_ns) * 1e-9
        lines = [f'bag:       {bag.path}', (f'storage:   {bag.storage} (metadata version '
                 f'{bag.version})'), f'duration:  {dur:.3f} s',
                 f'start:     {bag.start_ns * 1e-9:.9f} s', f'messages:  {bag.message_count}',
                 'topics:']
        width = max([len(t) for t in bag.topics] + [5])
        for topic, (msgtype, count, profiles) in sorted(bag.topics.items()):
            q = profiles[0] if profiles else None
            qos = '' if q is None else (f'  {q.reliability.name.lower()}, '
                                        f'{q.durability.name.lower()}')
            lines.append(f'  {topic:<{width}}  {msgtype:<36} {count:>8}{qos}')
        if bag.custom_data:
            lines.append('custom data: ' + ', '.join(sorted(bag.custom_data)))
    return '\n'.join(lines)
