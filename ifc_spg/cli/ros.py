"""``ifc-spg ros``: small ROS 2 tools on the active backend.

    ifc-spg ros talker   [--ros-args -p rate:=500.0 -p count:=5000 -p joints:=7 ...]
    ifc-spg ros listener [--ros-args -p count:=5000 -p timeout_s:=30.0 ...]
    ifc-spg ros echo TOPIC TYPE [--count N] [--ros-args ...]
    ifc-spg ros bench [--n N]

``talker`` publishes a JointState (``joints`` joints, stamp = wall clock, ``header.frame_id`` =
sequence number) on ``joint_states`` at ``rate`` [Hz], ``count`` times (0 = until stopped).
``listener`` counts them, measures the latency receive wall time - header stamp, and prints a
JSON summary (received, lost, p50/p99/max latency in [ms]) on exit: after ``count`` messages,
after ``timeout_s`` [s], or on SIGINT/SIGTERM. ``bench`` times CDR (de)serialization of the
message classes against rosbags.
"""

import argparse
from collections.abc import Sequence
import functools
import json
import math
import random
import signal
import sys
import time
import timeit
from types import FrameType

from ifc_spg import ros
from ifc_spg.errors import IfcSpgError
from ifc_spg.ros import messages
from ifc_spg.ros import msg as msgs
from ifc_spg.ros.msg import JointState
from ifc_spg.ros.stamps import stamp_to_ns

__all__ = ['main', 'talker', 'listener', 'echo', 'bench']


def _install_signal_shutdown():
    def handler(signum: int, frame: FrameType | None) -> None:
        if ros.ok():
            ros.shutdown()

    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)


def _descriptor(description, low=None, high=None, integer=False):
    desc = ros.ParameterDescriptor(description=description)
    if low is not None:
        if integer:
            desc.integer_range = [ros.IntegerRange(from_value=low, to_value=high, step=0)]
        else:
            desc.floating_point_range = [ros.FloatingPointRange(from_value=low, to_value=high,
                                                                step=0.0)]
    return desc


def talker(argv: Sequence[str]) -> int:
    """Publish JointState messages; see the module docstring. Returns the exit code."""
    ros.init(args=['ifc-spg', *argv])
    _install_signal_shutdown()
    node = ros.Node('talker')
    try:
        rate = node.declare_parameter('rate', 500.0, _descriptor(
            'Publish rate [Hz].', 0.1, 10000.0)).value
        count = node.declare_parameter('count', 0, _descriptor(
            'Messages to publish (0: until stopped).', 0, 10**9, integer=True)).value
        n_joints = node.declare_parameter('joints', 7, _descriptor(
            'Joints per message.', 1, 1000, integer=True)).value
        wait_subs = node.declare_parameter('wait_for_subscribers', 0, _descriptor(
            'Wait for this many matched subscriptions before publishing.', 0, 1000,
            integer=True)).value
        wait_timeout = node.declare_parameter('wait_timeout_s', 10.0, _descriptor(
            'Give up waiting for subscribers after this long [s].', 0.0, 3600.0)).value
        settle = node.declare_parameter('settle_s', 0.5, _descriptor(
            'After the subscribers matched, wait this long before publishing [s]: discovery '
            'is not symmetric (a Fast DDS writer may see a reader before the reader knows '
            'the writer, and the first samples are then lost).', 0.0, 60.0)).value
        depth = node.declare_parameter('depth', 10, _descriptor(
            'History depth of the reliable publisher (keep last): a reader that falls '
            'further behind loses the oldest samples.', 1, 100000, integer=True)).value
        pub = node.create_publisher(JointState, 'joint_states', depth)
        names = [f'joint_{i + 1}' for i in range(n_joints)]
        clock = node.get_clock()
        if wait_subs and not ros.spin_until(lambda: pub.get_subscription_count() >= wait_subs,
                                            wait_timeout, [node]):
            node.get_logger().error(f'no {wait_subs} subscriber(s) after {wait_timeout} s')
            return 1
        if wait_subs and settle > 0:
            ros.spin_until(lambda: False, settle, [node])
        sent = [0]

        def tick():
            if count and sent[0] >= count:
                return
            t = sent[0] / rate
            msg = JointState(name=names,
                             position=[math.sin(t + i) for i in range(n_joints)],
                             velocity=[math.cos(t + i) for i in range(n_joints)],
                             effort=[0.1 * i for i in range(n_joints)])
            msg.header.frame_id = str(sent[0])
            msg.header.stamp = clock.now().to_msg()
            pub.publish(msg)
            sent[0] += 1

        node.create_timer(1.0 / rate, tick)
        node.get_logger().info(f'publishing {count or "unlimited"} JointState at {rate} Hz on '
                               f'{pub.topic_name}')
        while ros.ok() and not (count and sent[0] >= count):
            ros.spin_once(node, timeout_sec=0.1)
        if ros.ok():
            ros.wait_for_acks(pub, 5.0)
        node.get_logger().info(f'published {sent[0]} messages')
        return 0
    finally:
        if ros.ok():
            node.destroy_node()
            ros.shutdown()


def _percentile(sorted_values, q):
    if not sorted_values:
        return None
    k = (len(sorted_values) - 1) * q
    lo, hi = math.floor(k), math.ceil(k)
    return sorted_values[lo] + (sorted_values[hi] - sorted_values[lo]) * (k - lo)


def listener(argv: Sequence[str]) -> int:
    """Receive JointState messages and print a JSON latency summary. Returns the exit code."""
    ros.init(args=['ifc-spg', *argv])
    _install_signal_shutdown()
    node = ros.Node('listener')
    latencies, seqs = [], set()
    summary = {}
    try:
        count = node.declare_parameter('count', 0, _descriptor(
            'Exit after this many messages (0: on timeout or signal).', 0, 10**9,
            integer=True)).value
        timeout_s = node.declare_parameter('timeout_s', 60.0, _descriptor(
            'Exit after this long [s].', 0.0, 86400.0)).value
        first: list[float | None] = [None]

        def callback(msg):
            now = time.time_ns()
            stamp = stamp_to_ns(msg.header.stamp)
            latencies.append((now - stamp) * 1e-6)
            if msg.header.frame_id.isdigit():
                seqs.add(int(msg.header.frame_id))
            if first[0] is None:
                first[0] = time.monotonic()

        depth = node.declare_parameter('depth', 10, _descriptor(
            'History depth of the reliable subscription (keep last).', 1, 100000,
            integer=True)).value
        sub = node.create_subscription(JointState, 'joint_states', callback, depth)
        print(json.dumps({'ready': True, 'topic': sub.topic_name}), flush=True)
        start = time.monotonic()
        while ros.ok() and time.monotonic() - start < timeout_s:
            if count and len(latencies) >= count:
                break
            ros.spin_once(node, timeout_sec=0.1)
        duration = (time.monotonic() - first[0]) if first[0] else 0.0
        lat = sorted(latencies)
        expected = count or ((max(seqs) + 1) if seqs else 0)
        summary = {
            'received': len(latencies),
            'expected': expected,
            'lost': max(expected - len(seqs), 0) if seqs else expected - len(latencies),
            'duplicates': len(latencies) - len(seqs) if seqs else 0,
            'p50_ms': _percentile(lat, 0.5),
            'p99_ms': _percentile(lat, 0.99),
            'max_ms': lat[-1] if lat else None,
            'rate_hz': (len(latencies) - 1) / duration if duration > 0 else None,
        }
        print(json.dumps(summary), flush=True)
        return 0
    finally:
        if ros.ok():
            node.destroy_node()
            ros.shutdown()


def echo(argv: Sequence[str]) -> int:
    """Print messages of TOPIC (type TYPE, e.g. std_msgs/msg/String) as they arrive."""
    parser = argparse.ArgumentParser(prog='ifc-spg ros echo')
    parser.add_argument('topic')
    parser.add_argument('type', help="message type, e.g. 'sensor_msgs/msg/JointState'")
    parser.add_argument('--count', type=int, default=0, help='exit after N messages')
    args = parser.parse_args(ros.remove_ros_args(argv))
    cls = getattr(msgs, args.type.rsplit('/', 1)[-1], None)
    if cls is None:
        raise IfcSpgError(f"unknown message type '{args.type}'; known: "
                          f"{', '.join(msgs.__all__)}")
    ros.init(args=['ifc-spg', *argv])
    _install_signal_shutdown()
    node = ros.Node('echo')
    seen = [0]

    def callback(msg):
        print(msg, flush=True)
        seen[0] += 1

    node.create_subscription(cls, args.topic, callback, 10)
    try:
        while ros.ok() and not (args.count and seen[0] >= args.count):
            ros.spin_once(node, timeout_sec=0.1)
    finally:
        if ros.ok():
            ros.shutdown()
    return 0


def bench(argv: Sequence[str]) -> int:
    """Time CDR serialize/deserialize of every built-in message class, vs rosbags."""
    from rosbags.typesys import Stores, get_typestore  # optional: the comparison only

    parser = argparse.ArgumentParser(prog='ifc-spg ros bench')
    parser.add_argument('--n', type=int, default=20000, help='repetitions per measurement')
    args = parser.parse_args(argv)
    store = get_typestore(Stores.ROS2_JAZZY)
    rng = random.Random(0)
    msgs = {
        'JointState(7)': messages.JointState(
            name=[f'joint_{i}' for i in range(7)], position=[rng.random() for _ in range(7)],
            velocity=[rng.random() for _ in range(7)], effort=[rng.random() for _ in range(7)]),
        'WrenchStamped': messages.WrenchStamped(),
        'String(200)': messages.String(data='x' * 200),
        'Float64MultiArray(100)': messages.Float64MultiArray(data=[1.0] * 100),
        'DiagnosticArray(3x4)': messages.DiagnosticArray(status=[messages.DiagnosticStatus(
            name='s', values=[messages.KeyValue(key='k', value='v')] * 4)] * 3),
    }
    print(f'{"message":<24} {"ser us":>8} {"de us":>8} {"rosbags ser":>12} {"rosbags de":>11}')
    for label, msg in msgs.items():
        data = messages.serialize(msg)
        typename = messages.type_name(type(msg))
        rb = store.deserialize_cdr(data, typename)
        ser = timeit.timeit(functools.partial(messages.serialize, msg),
                            number=args.n) / args.n * 1e6
        de = timeit.timeit(functools.partial(messages.deserialize, type(msg), data),
                           number=args.n) / args.n * 1e6
        rser = timeit.timeit(functools.partial(store.serialize_cdr, rb, typename),
                             number=args.n) / args.n * 1e6
        rde = timeit.timeit(functools.partial(store.deserialize_cdr, data, typename),
                            number=args.n) / args.n * 1e6
        print(f'{label:<24} {ser:8.2f} {de:8.2f} {rser:12.2f} {rde:11.2f}')
    return 0


_COMMANDS = {'talker': talker, 'listener': listener, 'echo': echo, 'bench': bench}


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ifc-spg ros``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ('-h', '--help'):
        print(__doc__)
        return 0 if argv else 2
    command, rest = argv[0], argv[1:]
    if command not in _COMMANDS:
        print(f"ifc-spg ros: unknown command '{command}'; valid: {', '.join(_COMMANDS)}",
              file=sys.stderr)
        return 2
    if '-h' in rest or '--help' in rest:
        print(__doc__)
        return 0
    try:
        return int(_COMMANDS[command](rest) or 0)
    except IfcSpgError as exc:
        print(f'ifc-spg ros {command}: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    sys.exit(main())
