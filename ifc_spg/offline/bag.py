"""rosbag2 MCAP bags on disk: write, read, summarise (no DDS; ``ifc-spg bag info``).

Bags are rosbag2 directories as rosbag2 Jazzy writes them (``metadata.yaml`` version 9 with
``ros_distro: jazzy`` and each topic's ``type_description_hash``, one ``<name>_0.mcap`` file,
profile ``ros2``, schemas in ``ros2msg`` encoding, channels with ``offered_qos_profiles`` and
``topic_type_hash``, CDR messages), so ``ros2 bag``, ``rosbags``, the ``mcap`` reader and
Foxglove open them. Each topic records its publishers' offered QoS profiles in the
metadata, so a player republishes with the original reliability and durability (the latched
``spg/task_stack`` stays latched).

:class:`BagWriter` writes the offline runs' bags (``ifc-spg run``) and the live recordings,
:class:`BagReader` reads them for replay, plots, the cockpit and the player; recording and
playing over DDS (``ifc-spg bag record/play``) are :mod:`ifc_spg.live.bag`.
"""
from pathlib import Path
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

from ifc_spg.errors import ParameterError
from ifc_spg.ros import messages
from ifc_spg.ros.qos import (
    DurabilityPolicy,
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
            self.add_topic(topic, messages.type_name(type(msg)))
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
