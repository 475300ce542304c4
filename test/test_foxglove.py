"""Foxglove-ready bags: the URDF, /tf, /tf_static and /spg/markers of a lockstep run.

The bag is read back with rosbags (not our reader) and every transform is compared with
pinocchio's FK of the bag's own URDF at the recorded joint positions.
"""

import os
import signal

from helpers import start_cli, wait_cli_line
import numpy as np
import pinocchio as pin
import pytest
from ros_testing import loopback_env
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from ifc_spg.model import RobotModel
from ifc_spg.offline.bag import info
from ifc_spg.offline.runner import find_config_dir, load_scenario, run_scenario
from sim_bridge.urdf import urdf_from_robot


@pytest.mark.parametrize('name', ['lbr_iiwa14', 'lbr4', 'accrea_dual_arm', 'icub_upper_body'])
def test_generated_urdf_has_the_kinematics_of_the_robot_model(name):
    robot = RobotModel.from_config(name)
    model = pin.buildModelFromXML(urdf_from_robot(robot).xml)
    data, ref = model.createData(), robot.create_data()
    assert sorted(model.names[1:]) == sorted(robot.joint_names)
    bodies = [f.name for f in robot.model.frames if f.type in (pin.BODY, pin.OP_FRAME)]
    assert set(robot.frames.values()) <= set(bodies)
    rng = np.random.default_rng(7)
    for _ in range(20):
        q = rng.uniform(robot.q_min, robot.q_max)
        qu = pin.neutral(model)
        for joint, v in zip(robot.joint_names, q):
            qu[model.joints[model.getJointId(joint)].idx_q] = v
        pin.framesForwardKinematics(model, data, qu)
        pin.framesForwardKinematics(robot.model, ref, q)
        for frame in bodies:
            a = data.oMf[model.getFrameId(frame)]
            b = ref.oMf[robot.model.getFrameId(frame)]
            assert np.linalg.norm(pin.log6(a.inverse() * b).vector) < 1e-9, frame
    # the inertias too: the mass matrices agree up to the rotor armature (not in URDF)
    perm = [model.joints[model.getJointId(j)].idx_q for j in robot.joint_names]
    M = pin.crba(model, data, qu)[np.ix_(perm, perm)]
    M_ref = pin.crba(robot.model, ref, q)
    assert np.abs(np.triu(M) + np.diag(robot.model.armature) - np.triu(M_ref)).max() < 1e-9


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    out = tmp_path_factory.mktemp('foxglove')
    sc = load_scenario(find_config_dir() / 'scenarios' / 'surface_short.yaml',
                       {'duration': 1.2})
    return run_scenario(sc, out, quiet=True).bag


def _read(bag):
    store = get_typestore(Stores.ROS2_JAZZY)
    msgs = {}
    with AnyReader([bag], default_typestore=store) as reader:
        for conn, t, raw in reader.messages():
            msgs.setdefault(conn.topic, []).append((t, reader.deserialize(raw, conn.msgtype)))
    return msgs


def _stamp(header):
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def _pose(tr):
    t, r = tr.translation, tr.rotation
    return pin.SE3(pin.Quaternion(r.w, r.x, r.y, r.z).toRotationMatrix(),
                   np.array([t.x, t.y, t.z]))


def _check_transforms(msgs, per_tree):
    """Every /tf and /tf_static transform is pinocchio's FK of the bag's URDF at the
    recorded joint state (measured) or command (virtual/) of the same stamp."""
    (_, desc), = msgs['/robot_description']
    model = pin.buildModelFromXML(desc.data)
    data = model.createData()
    states = {'': {_stamp(m.header): m for _, m in msgs['/joint_states']},
              'virtual/': {_stamp(m.header): m for _, m in msgs['/command/joint_position']}}

    def fk(js):
        q = pin.neutral(model)
        for joint, v in zip(js.name, js.position):
            q[model.joints[model.getJointId(joint)].idx_q] = v
        pin.framesForwardKinematics(model, data, q)
        return {f.name: data.oMf[i] for i, f in enumerate(model.frames)}

    def check(tf, frames, prefix):
        assert tf.header.frame_id.startswith(prefix) and tf.child_frame_id.startswith(prefix)
        parent = frames[tf.header.frame_id[len(prefix):]]
        child = frames[tf.child_frame_id[len(prefix):]]
        err = pin.log6((parent.inverse() * child).inverse() * _pose(tf.transform)).vector
        assert np.linalg.norm(err) < 1e-9, (tf.header.frame_id, tf.child_frame_id)

    n_checked = {'': 0, 'virtual/': 0}
    for _, msg in msgs['/tf']:
        prefix = 'virtual/' if msg.transforms[0].child_frame_id.startswith('virtual/') else ''
        stamp = _stamp(msg.transforms[0].header)
        frames = fk(states[prefix][stamp])  # the joint state of the same stamp
        assert len(msg.transforms) == model.njoints - 1
        for tf in msg.transforms:
            assert _stamp(tf.header) == stamp
            check(tf, frames, prefix)
            n_checked[prefix] += 1
    assert min(n_checked.values()) >= (model.njoints - 1) * per_tree, n_checked
    (_, static), = msgs['/tf_static']
    frames = fk(next(iter(states[''].values())))
    children = set()
    for tf in static.transforms:
        children.add(tf.child_frame_id)
        if tf.child_frame_id == 'virtual/world':
            assert tf.header.frame_id == 'world'
            assert pin.log6(_pose(tf.transform)).vector == pytest.approx(np.zeros(6))
            continue
        check(tf, frames, 'virtual/' if tf.header.frame_id.startswith('virtual/') else '')
    assert {'tool', 'flange', 'link0', 'virtual/tool', 'virtual/link0'} <= children


def test_every_transform_is_pinocchio_fk_of_the_bags_urdf(bag):
    _check_transforms(_read(bag), per_tree=120)  # every 10 ms of 1.2 s


@pytest.mark.ros
def test_recorded_bag_gets_tf_of_the_robot_spg_status_names(bag, tmp_path):
    """A live recording (``bag record``) of a lockstep bag played over DDS: the robot comes
    from the played spg/status; /tf from the received joint states."""
    env = loopback_env()
    dst = tmp_path / 'live'
    topics = ['/joint_states', '/command/joint_position', '/spg/status']
    rec = start_cli(['bag', 'record', '-o', str(dst), *topics], env)
    try:
        wait_cli_line(rec, 'recording')
        player = start_cli(['bag', 'play', str(bag), '--rate', '2', '--topics', *topics,
                            '--wait-for-subscribers', '1'], env)
        assert player.wait(60) == 0, player.stderr.read()
        rec.send_signal(signal.SIGINT)
        assert rec.wait(20) == 0, rec.stderr.read()
    finally:
        for p in (rec,):
            if p.poll() is None:
                os.kill(p.pid, signal.SIGKILL)
                p.wait()
    msgs = _read(dst)
    assert len(msgs['/joint_states']) == 600
    _check_transforms(msgs, per_tree=100)


def test_markers_show_the_cartesian_targets(bag):
    msgs = _read(bag)
    model = pin.buildModelFromXML(msgs['/robot_description'][0][1].data)
    data = model.createData()
    commands = {_stamp(m.header): m for _, m in msgs['/command/joint_position']}
    spheres = {}
    for _, arr in msgs['/spg/markers']:
        assert arr.markers[0].action == arr.markers[0].DELETEALL
        for mk in arr.markers[1:]:
            assert mk.header.frame_id == 'world'
            if mk.type == mk.SPHERE:
                spheres.setdefault(mk.ns, []).append((_stamp(mk.header), mk.pose))
    assert set(spheres) == {'hold', 'circle'}  # the Cartesian tasks of the two stacks
    hold = np.array([[p.position.x, p.position.y] for _, p in spheres['hold']])
    assert np.ptp(hold, axis=0).max() < 1e-9  # 'equal: init' holds still
    t_end, _ = spheres['hold'][-1]
    js = commands[t_end]
    q = pin.neutral(model)
    for joint, v in zip(js.name, js.position):
        q[model.joints[model.getJointId(joint)].idx_q] = v
    pin.framesForwardKinematics(model, data, q)
    tool = data.oMf[model.getFrameId('tool')].translation
    assert np.abs(hold[-1] - tool[:2]).max() < 2e-3  # q_v tracks the held target
    circle = np.array([[p.position.x, p.position.y] for _, p in spheres['circle']])
    t = np.array([s for s, _ in spheres['circle']]) * 1e-9
    speed = np.linalg.norm(np.diff(circle, axis=0), axis=1) / np.diff(t)
    assert speed == pytest.approx(2 * np.pi * 0.03 * 0.5, rel=0.02)  # radius 3 cm, 0.5 Hz


def test_markers_draw_the_commanded_and_measured_force(bag):
    msgs = _read(bag)
    model = pin.buildModelFromXML(msgs['/robot_description'][0][1].data)
    data = model.createData()
    states = {_stamp(m.header): m for _, m in msgs['/joint_states']}
    contact = {_stamp(m.header): m.wrench.force for _, m in msgs['/sim/contact_wrench']}
    n = 0
    for _, arr in msgs['/spg/markers']:
        arrows = {mk.ns: mk for mk in arr.markers if mk.type == mk.ARROW and len(mk.points)}
        labels = {mk.ns: mk.text for mk in arr.markers if mk.type == mk.TEXT_VIEW_FACING}
        assert set(arrows) == set(labels) == {'contact_force', 'tool measured'}
        stamp = _stamp(arrows['contact_force'].header)
        js = states[stamp]
        q = pin.neutral(model)
        for joint, v in zip(js.name, js.position):
            q[model.joints[model.getJointId(joint)].idx_q] = v
        pin.framesForwardKinematics(model, data, q)
        tool = data.oMf[model.getFrameId('tool')]
        for ns, mk in arrows.items():
            a, b = (np.array([p.x, p.y, p.z]) for p in mk.points)
            np.testing.assert_allclose(a, tool.translation, atol=1e-9)  # at the tool, at q
            force = (b - a) / 0.01  # 1 cm per N
            assert labels[ns] == f'{ns}: {np.linalg.norm(force):.1f} N'
            if ns == 'contact_force':  # 8 N along the tool's z axis (equal: 8.0, frame ee)
                np.testing.assert_allclose(force, 8.0 * tool.rotation[:, 2], atol=1e-6)
            else:  # the contact force the robot exerts, from sim/contact_wrench
                f = contact[stamp]
                np.testing.assert_allclose(force, [-f.x, -f.y, -f.z], atol=1e-6)
        n += 1
    # at the live node's default markers.rate (30 Hz), on the 2 ms ticks: every 34 ms
    stamps = np.array([_stamp(arr.markers[-1].header) for _, arr in msgs['/spg/markers']])
    assert np.diff(stamps) * 1e-9 == pytest.approx(0.034, abs=1e-6)
    assert n >= 30


def test_bag_info_lists_the_new_topics(bag):
    text = info(bag)
    for line in ('/robot_description       std_msgs/msg/String',
                 '/tf_static               tf2_msgs/msg/TFMessage',
                 '/tf                      tf2_msgs/msg/TFMessage',
                 '/spg/markers             visualization_msgs/msg/MarkerArray'):
        assert line in text
