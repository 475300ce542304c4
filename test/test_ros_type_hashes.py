"""RIHS01 type hashes of the built-in message classes equal rosidl's (Jazzy).

The table below is what rosidl_generator_type_description wrote into the Jazzy message
packages (share/<pkg>/msg/<T>.json of ros-jazzy-*-msgs 5.3.6 incl. trajectory_msgs and
visualization_msgs,
builtin_interfaces 2.0.3, rmw_dds_common 3.1.0). Where those packages are installed the
table is checked against their files, against the hash an rclpy publisher announces, and
against the hash rclpy (Fast DDS) reads from a built-in backend writer's USER_DATA on the wire.
"""

import json
import os
from pathlib import Path
import sys

from helpers import use_loopback, wait_for
import pytest

from ifc_spg.ros import messages
from ifc_spg.ros.messages import REGISTRY

ROSIDL_HASHES = {
    'std_msgs/msg/Bool':
        'RIHS01_feb91e995ff9ebd09c0cb3d2aed18b11077585839fb5db80193b62d74528f6c9',
    'trajectory_msgs/msg/JointTrajectory':
        'RIHS01_179b33eba59d676f6d967ac71fe35e7ca2f64b2f3928f4a018cec115e213796e',
    'trajectory_msgs/msg/JointTrajectoryPoint':
        'RIHS01_de8907036d8bd45aac6f30cc9044a3d4a329c42cbf719aff7d95a584cfa532d7',
    'builtin_interfaces/msg/Duration':
        'RIHS01_e8d009f659816f758b75334ee1a9ca5b5c0b859843261f14c7f937349599d93b',
    'builtin_interfaces/msg/Time':
        'RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197',
    'diagnostic_msgs/msg/DiagnosticArray':
        'RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e',
    'diagnostic_msgs/msg/DiagnosticStatus':
        'RIHS01_b0e3e692ea2d54a8af2f4ef1930e81556a2db55216b771f8a7d2724ed47bf0e4',
    'diagnostic_msgs/msg/KeyValue':
        'RIHS01_d68081eaa540288c5440753baecef0c4e16e81a5f78ad68902ded5100413bb42',
    'geometry_msgs/msg/Point':
        'RIHS01_6963084842a9b04494d6b2941d11444708d892da2f4b09843b9c43f42a7f6881',
    'geometry_msgs/msg/Pose':
        'RIHS01_d501954e9476cea2996984e812054b68026ae0bfae789d9a10b23daf35cc90fa',
    'geometry_msgs/msg/PoseStamped':
        'RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8',
    'geometry_msgs/msg/Quaternion':
        'RIHS01_8a765f66778c8ff7c8ab94afcc590a2ed5325a1d9a076ffff38fbce36f458684',
    'geometry_msgs/msg/Vector3':
        'RIHS01_cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d',
    'geometry_msgs/msg/Wrench':
        'RIHS01_018e8519d57c16adbe97c9fe1460ef21fec7e31bc541de3d653a35895677ce52',
    'geometry_msgs/msg/WrenchStamped':
        'RIHS01_8dc3deaf06b2ab281f9f9a742a8961c328ca7cec16e3fd6586d3a5c83fa78f77',
    'rmw_dds_common/msg/Gid':
        'RIHS01_ab6f21cfbb0a6dbb837161e1110c2051a2850ed9f9c53944d7115d9bcebedf71',
    'rmw_dds_common/msg/NodeEntitiesInfo':
        'RIHS01_8ffef65ee2d088c63b1e8fcd31e800ba9fc8dbe0ee15ca60d1676de5218087a7',
    'rmw_dds_common/msg/ParticipantEntitiesInfo':
        'RIHS01_91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e',
    'sensor_msgs/msg/JointState':
        'RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e',
    'std_msgs/msg/Float64MultiArray':
        'RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f',
    'std_msgs/msg/Header':
        'RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01',
    'std_msgs/msg/MultiArrayDimension':
        'RIHS01_5e773a60a4c7fc8a54985f307c7837aa2994252a126c301957a24e31282c9cbe',
    'std_msgs/msg/MultiArrayLayout':
        'RIHS01_4c66e6f78e740ac103a94cf63259f968e48c617e7699e829b63c21a5cb50dac6',
    'std_msgs/msg/String':
        'RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18',
    'std_msgs/msg/ColorRGBA':
        'RIHS01_77a7a5b9ae477306097665106e0413ba74440245b1f3d0c6d6405fe5c7813fe8',
    'sensor_msgs/msg/CompressedImage':
        'RIHS01_15640771531571185e2efc8a100baf923961a4d15d5569652e6cb6691e8e371a',
    'visualization_msgs/msg/UVCoordinate':
        'RIHS01_f27f7ed21fe360c6066944f856b801a0c0d1e94e815b6886444b42d90b196a26',
    'visualization_msgs/msg/MeshFile':
        'RIHS01_7710ece15a148fb7c9b546364cfb215bb06098087bd6394fe5b73a493508f8c4',
    'visualization_msgs/msg/Marker':
        'RIHS01_45b13ccf791f225962bf74e746f9644518855d783a6f42ba0cc14fde2b4f3ce0',
    'visualization_msgs/msg/MarkerArray':
        'RIHS01_86cb8800b6fb05b5eff1abd7a56f62a5641d3ae9a1c29e78e67e704f1d067dcf',
}


def _rclpy():
    try:
        import rclpy
        import sensor_msgs.msg  # noqa: F401
    except ImportError:
        pytest.skip('rclpy and the Jazzy message packages are not installed (the ros-jazzy '
                    'wheels exist for Linux x86_64, CPython 3.10-3.13 only)')
    try:
        import visualization_msgs.msg  # noqa: F401
    except ImportError:
        pytest.skip('ros-jazzy-visualization-msgs (requirements.txt) is not installed: run '
                    './run setup')
    return rclpy


def _rclpy_class(typename):
    import importlib

    pkg, kind, name = typename.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


@pytest.mark.parametrize('typename', sorted(REGISTRY))
def test_hash_is_rosidls(typename):
    assert messages.type_hash(REGISTRY[typename]) == ROSIDL_HASHES[typename]


def test_table_covers_every_type_and_no_other():
    assert set(ROSIDL_HASHES) == set(REGISTRY)


@pytest.mark.parametrize('typename', sorted(REGISTRY))
def test_table_equals_the_installed_rosidl_output(typename):
    _rclpy()
    pkg, kind, name = typename.split('/')
    # an apt-installed Jazzy sets AMENT_PREFIX_PATH; the pip wheels install into sys.prefix
    prefixes = [*filter(None, os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)),
                sys.prefix]
    paths = [Path(p) / 'share' / pkg / kind / f'{name}.json' for p in prefixes]
    path = next((p for p in paths if p.is_file()), None)
    assert path is not None, f'rclpy imports but no {pkg} type description in {prefixes}'
    with open(path, encoding='utf-8') as f:
        hashes = {h['type_name']: h['hash_string'] for h in json.load(f)['type_hashes']}
    assert hashes[typename] == ROSIDL_HASHES[typename]


def test_rclpy_publishers_announce_the_same_hashes(monkeypatch):
    rclpy = _rclpy()
    use_loopback(monkeypatch)
    from rclpy.context import Context

    ctx = Context()
    rclpy.init(context=ctx)
    try:
        node = rclpy.create_node('hash_probe', context=ctx)
        seen = {}
        for i, typename in enumerate(sorted(REGISTRY)):
            topic = f'/hash_probe_{i}'
            node.create_publisher(_rclpy_class(typename), topic, 10)
            info = node.get_publishers_info_by_topic(topic)
            seen[typename] = str(info[0].topic_type_hash)
        assert seen == ROSIDL_HASHES
    finally:
        rclpy.try_shutdown(context=ctx)


def test_rclpy_reads_the_built_in_backends_hash_from_the_wire(monkeypatch):
    """A built-in backend writer's USER_DATA typehash=...;, as Fast DDS parses it."""
    rclpy = _rclpy()
    use_loopback(monkeypatch)
    from rclpy.context import Context

    from ifc_spg.ros import dds

    data_types = ['sensor_msgs/msg/JointState', 'std_msgs/msg/String',
                  'geometry_msgs/msg/WrenchStamped', 'diagnostic_msgs/msg/DiagnosticArray',
                  'std_msgs/msg/Float64MultiArray']
    ours = dds.Context(['ours'])
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        node = dds.Node('hash_writer', context=ours)
        for i, typename in enumerate(data_types):
            node.create_publisher(REGISTRY[typename], f'wire_{i}', 10)
        probe = rclpy.create_node('hash_reader', context=ctx)
        seen = {}

        def all_seen():
            for i, typename in enumerate(data_types):
                info = probe.get_publishers_info_by_topic(f'/wire_{i}')
                if info:
                    seen[typename] = (info[0].topic_type, str(info[0].topic_type_hash))
            return len(seen) == len(data_types)

        wait_for(all_seen, 20.0)
        assert seen == {t: (t, ROSIDL_HASHES[t]) for t in data_types}
    finally:
        rclpy.try_shutdown(context=ctx)
        ours.shutdown()


def test_rosbags_hashes_char_fields_differently():
    """Why the table, not rosbags, is the reference: rosbags hashes char as FIELD_TYPE_CHAR,
    rosidl maps it to uint8 (only rmw_dds_common/Gid among our types has a char field)."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    differ = {t for t in REGISTRY if store.hash_rihs01(t) != ROSIDL_HASHES[t]}
    assert differ == {'rmw_dds_common/msg/Gid', 'rmw_dds_common/msg/NodeEntitiesInfo',
                      'rmw_dds_common/msg/ParticipantEntitiesInfo'}
    assert messages.Gid._FIELDS == (('data', 'char[16]'),)
