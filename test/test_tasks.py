"""One contract suite for every task archetype (docs/STYLE.md rule 10, Table 3.1)."""

import numpy as np
import pinocchio as pin
import pytest

from ifc_spg import RobotModel
from ifc_spg.errors import IfcSpgError, UnknownFrame
from ifc_spg.kinematics import Kinematics
from ifc_spg.tasks import (
    CartesianPoseTask,
    JointPositionTask,
    JointTorqueTask,
    Task,
    WrenchTask,
)
from ifc_spg.tasks.subspace import AXES, WRENCH_AXES, subspace_in_base

ROBOTS = {name: RobotModel.from_config(name) for name in
          ('lbr_iiwa14', 'icub_upper_body', 'accrea_dual_arm')}


def random_state(robot, rng):
    lo, hi = robot.q_min, robot.q_max
    q = rng.uniform(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo))
    q_v = q + rng.normal(scale=0.05, size=robot.n)
    qdot = rng.normal(scale=0.3, size=robot.n)
    return q, qdot, q_v


def kin_at(robot, q, qdot, q_v):
    kin = Kinematics(robot)
    kin.update(q, qdot, q_v)
    return kin


def random_axes(rng, names):
    k = int(rng.integers(1, 7))
    return list(rng.choice(names, size=k, replace=False))


def make_tasks(robot, rng):
    """One task of each archetype with random subspaces/joints on ``robot``."""
    chain = robot.chains[int(rng.integers(len(robot.chains)))]
    if robot.ifc == 'cartesian_admittance':
        chain = sorted(robot.admittance)[int(rng.integers(len(robot.admittance)))]
    joints = list(rng.choice(robot.joint_names, size=int(rng.integers(1, robot.n + 1)),
                             replace=False))
    compliant = [j for j in joints if not robot.stiff_mask[robot.joint_index(j)]] or None
    frames = ['base', 'ee', 'ee_orientation']
    return [
        JointPositionTask(robot, joints=joints, equal='init'),
        CartesianPoseTask(robot, frame=chain, axes=random_axes(rng, AXES), equal='init',
                          subspace_frame=frames[int(rng.integers(3))]),
        JointTorqueTask(robot, joints=compliant, equal='init'),
        WrenchTask(robot, frame=chain, axes=random_axes(rng, WRENCH_AXES), equal='init',
                   subspace_frame=frames[int(rng.integers(3))]),
    ]


def frozen_twin(task, robot, kin):
    """The same task with its subspace in base coordinates and its reference held fixed.

    An end-effector subspace turns with the robot, and a free rotation axis turns the
    reference orientation with R_v every tick; the Jacobian is the derivative with both held
    at the nominal configuration, so the finite differences run on a twin that holds them.
    """
    if isinstance(task, CartesianPoseTask):
        R = kin.frame(task.frame_id, virtual=True)[1]
        twin = CartesianPoseTask(robot, frame=task.frame, equal=0.0,
                                 subspace=subspace_in_base(task.S, task.subspace_frame, R),
                                 orientation=task.reference_orientation(R))
        twin.free_axis = None
        return twin
    if isinstance(task, WrenchTask):
        R = kin.frame(robot.frame_id(task.frame), virtual=False)[1]
        return WrenchTask(robot, frame=task.frame, equal=0.0,
                          subspace=subspace_in_base(task.S, task.subspace_frame, R),
                          include_damping=task.include_damping)
    return task


def fd_jacobian(task, robot, q, qdot, q_v, eps=1e-6):
    """Central differences of the task value w.r.t. q_v, with subspace and reference fixed."""
    twin = frozen_twin(task, robot, kin_at(robot, q, qdot, q_v))
    cols = []
    for i in range(robot.n):
        dq = np.zeros(robot.n)
        dq[i] = eps
        plus = twin.compute_value(kin_at(robot, q, qdot, q_v + dq))
        minus = twin.compute_value(kin_at(robot, q, qdot, q_v - dq))
        cols.append((plus - minus) / (2 * eps))
    return np.array(cols).T


@pytest.mark.parametrize('name', list(ROBOTS))
def test_jacobian_matches_finite_differences(name):
    robot = ROBOTS[name]
    rng = np.random.default_rng(len(name))
    worst = 0.0
    for _ in range(8):
        q, qdot, q_v = random_state(robot, rng)
        for task in make_tasks(robot, rng):
            # activate elsewhere, so that orientation errors are far from zero
            task.activate(kin_at(robot, q, qdot, q_v + rng.normal(scale=0.3, size=robot.n)))
            kin = kin_at(robot, q, qdot, q_v)
            A = task.compute_jacobian(kin)
            A_fd = fd_jacobian(task, robot, q, qdot, q_v)
            scale = max(1.0, np.abs(A).max())
            err = np.abs(A - A_fd).max() / scale
            worst = max(worst, err)
            assert err < 1e-6, (task, err)
    print(f'{name}: worst relative Jacobian error {worst:.1e}')


@pytest.mark.parametrize('name', list(ROBOTS))
def test_zero_error_at_target_and_dimensions_follow_subspace(name):
    robot = ROBOTS[name]
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, qdot, q_v = random_state(robot, rng)
        kin = kin_at(robot, q, qdot, q_v)
        for task in make_tasks(robot, rng):
            lev = task.level(kin, 0.0)  # 'init': the target is the current value
            m = task.dim
            assert lev.A.shape == (m, robot.n)
            assert lev.lower.shape == lev.upper.shape == (m,)
            _, _, gamma = task.compute(kin)
            # at the target only the velocity compensation remains (4.25-4.28)
            np.testing.assert_allclose(lev.lower, gamma, atol=1e-10)
            assert lev.equality


def test_ee_subspace_equals_rotated_base_subspace():
    robot = ROBOTS['lbr_iiwa14']
    rng = np.random.default_rng(5)
    for _ in range(10):
        q, qdot, q_v = random_state(robot, rng)
        kin = kin_at(robot, q, qdot, q_v)
        S_ee = np.linalg.qr(rng.normal(size=(6, 3)))[0]
        for cls, virtual in ((CartesianPoseTask, True), (WrenchTask, False)):
            R = kin.frame(robot.frame_id('tool'), virtual=virtual)[1]
            S_base = np.zeros((6, 3))
            S_base[:3] = R @ S_ee[:3]
            S_base[3:] = R @ S_ee[3:]
            ee = cls(robot, frame='tool', subspace=S_ee, subspace_frame='ee', equal=[0, 0, 0])
            base = cls(robot, frame='tool', subspace=S_base, equal=[0, 0, 0])
            for a, b in zip(ee.compute(kin), base.compute(kin)):
                np.testing.assert_allclose(a, b, atol=1e-12)


def test_torque_and_wrench_gamma_is_the_measured_motion():
    """Table 3.1: gamma = K qdot for torque tasks and J^{+T} K qdot for wrench tasks."""
    robot = ROBOTS['lbr_iiwa14']
    rng = np.random.default_rng(9)
    q, qdot, q_v = random_state(robot, rng)
    kin = kin_at(robot, q, qdot, q_v)
    tau_task = JointTorqueTask(robot, equal=0.0)
    _, A, g = tau_task.compute(kin)
    np.testing.assert_allclose(g, robot.stiffness * qdot)
    # the static torque changes by -K qdot when q moves with q_v fixed: d(tau_s)/dt = -gamma
    h = 1e-7
    k2 = kin_at(robot, q + h * qdot, qdot, q_v)
    np.testing.assert_allclose((tau_task.compute_value(k2) - tau_task.compute_value(kin)) / h,
                               -g, rtol=1e-6)
    w = WrenchTask(robot, frame='tool', equal=0.0)
    _, A, g = w.compute(kin)
    np.testing.assert_allclose(g, A @ qdot, atol=1e-9)
    # h_s = J^{+T} tau_s: J^T h_s reproduces tau_s for a 7-DoF arm (6 <= n)
    J = kin.frame(robot.frame_id('tool'), virtual=False)[2]
    h_s = w.compute_value(kin)
    tau_s = robot.stiffness * (q_v - q)
    P = J.T @ np.linalg.pinv(J.T)  # projector onto the range of J^T
    np.testing.assert_allclose(J.T @ h_s, P @ tau_s, atol=1e-4 * np.abs(tau_s).max())


def test_stiff_joints_have_no_static_torque():
    robot = ROBOTS['icub_upper_body']
    stiff = [j for j, s in zip(robot.joint_names, robot.stiff_mask) if s]
    assert stiff
    with pytest.raises(IfcSpgError, match='stiff'):
        JointTorqueTask(robot, joints=stiff[:1], equal=0.0)
    rng = np.random.default_rng(2)
    q, qdot, q_v = random_state(robot, rng)
    kin = kin_at(robot, q, qdot, q_v)
    for frame in ('l_contact', 'r_palm'):
        _, A, _ = WrenchTask(robot, frame=frame, equal=0.0).compute(kin)
        assert np.all(A[:, robot.stiff_mask] == 0.0)
    _, A, _ = JointTorqueTask(robot, equal=0.0).compute(kin)
    assert np.all(A[:, robot.stiff_mask] == 0.0)


def test_rotation_error_is_log3_not_euler():
    robot = ROBOTS['lbr_iiwa14']
    kin = kin_at(robot, robot.q_home, np.zeros(7), robot.q_home)
    R0 = kin.frame(robot.frame_id('tool'), virtual=True)[1]
    R_ref = pin.exp3(np.array([0.0, 0.0, 2.5])) @ R0  # 2.5 rad about z: Euler would wrap
    task = CartesianPoseTask(robot, frame='tool', axes=['rx', 'ry', 'rz'], orientation=R_ref,
                             equal=[0, 0, 0])
    np.testing.assert_allclose(task.compute_value(kin), [0, 0, -2.5], atol=1e-12)


@pytest.mark.parametrize('kwargs,match', [
    (dict(frame='tool9', equal=0.0), "'tool9' not in model 'lbr_iiwa14'; did you mean 'tool'"),
    (dict(frame='tool', axes=['x', 'q'], equal=0.0), "unknown axis 'q'"),
    (dict(frame='tool', axes=['x', 'x'], equal=0.0), 'listed twice'),
    (dict(frame='tool', subspace=[[1, 1]] + [[0, 0]] * 5, equal=0.0), 'orthonormal'),
    (dict(frame='tool', axes=['x'], equal=[1, 2]), 'expected 1 values'),
    (dict(frame='tool', axes=['x'], equal=1.0, lower=0.0), "either 'equal' or"),
    (dict(frame='tool', axes=['x']), 'no bounds'),
    (dict(frame='tool', axes=['x'], equal=1.0, gain=-1.0), 'gain must be'),
    (dict(frame='tool', axes=['x'], equal=1.0, subspace_frame='world'), 'unknown; use one of'),
])
def test_bad_task_arguments_name_the_problem(kwargs, match):
    with pytest.raises((IfcSpgError, UnknownFrame), match=match):
        CartesianPoseTask(ROBOTS['lbr_iiwa14'], **kwargs)


def test_include_damping_adds_the_measured_damping_torque():
    robot = ROBOTS['lbr_iiwa14']
    rng = np.random.default_rng(21)
    q, qdot, q_v = random_state(robot, rng)
    kin = kin_at(robot, q, qdot, q_v)
    plain = WrenchTask(robot, frame='tool', equal=0.0)
    damped = WrenchTask(robot, frame='tool', equal=0.0, include_damping=True)
    h0, A0, g0 = plain.compute(kin)
    h1, A1, g1 = damped.compute(kin)
    J = kin.frame(robot.frame_id('tool'), virtual=False)[2]
    P = np.linalg.solve(J @ J.T + 1e-6 * np.eye(6), J)  # J^{+T}, damped as in the task
    np.testing.assert_allclose(h1 - h0, -P @ (robot.damping * qdot), atol=1e-9)
    np.testing.assert_array_equal(A0, A1)
    np.testing.assert_array_equal(g0, g1)
    t0 = JointTorqueTask(robot, equal=0.0).compute_value(kin)
    t1 = JointTorqueTask(robot, equal=0.0, include_damping=True).compute_value(kin)
    np.testing.assert_allclose(t1 - t0, -robot.damping * qdot)


@pytest.mark.parametrize('frame', ['ee', 'ee_orientation', 'base'])
def test_free_rotation_axis_never_enters_the_error(frame):
    """Table 3.4: with the rotation about the pen axis released, a twist of any size about
    it leaves the constrained components at the pure tilt angle (no wrap at pi)."""
    robot = ROBOTS['lbr_iiwa14']
    kin = kin_at(robot, robot.q_home, np.zeros(7), robot.q_home)
    R0 = kin.frame(robot.frame_id('tool'), virtual=True)[1]
    task = CartesianPoseTask(robot, frame='tool', axes=['rx', 'ry'], subspace_frame=frame,
                             orientation=R0, equal=[0, 0])
    axis = R0[:, 2] if frame != 'base' else np.array([0.0, 0.0, 1.0])
    for twist in (0.0, 1.0, 3.0, np.pi - 1e-6, -2.5):
        for tilt in (0.0, 0.05, 0.3):
            Rt = pin.exp3(twist * axis)
            tilt_axis = R0[:, 0] if frame != 'base' else np.array([1.0, 0.0, 0.0])
            Rv = pin.exp3(tilt * tilt_axis) @ Rt @ R0 if frame == 'base' \
                else Rt @ pin.exp3(tilt * tilt_axis) @ R0
            R_e = Rv @ task.reference_orientation(Rv).T
            err = pin.log3(R_e)
            d_v = Rv @ (R0.T @ axis) if frame != 'base' else axis
            assert abs(np.dot(err, d_v)) < 1e-9          # nothing about the free axis
            np.testing.assert_allclose(np.linalg.norm(err), tilt, atol=1e-9)


def test_full_pose_equals_the_same_axes_in_another_order():
    """The full base-frame pose (a shortcut skips S) agrees with a permuted subspace."""
    rng = np.random.default_rng(11)
    robot = ROBOTS['lbr_iiwa14']
    order = ['rz', 'x', 'ry', 'z', 'rx', 'y']
    perm = [AXES.index(a) for a in order]
    for _ in range(20):
        q, qdot, q_v = random_state(robot, rng)
        kin = kin_at(robot, robot.q_home, qdot, robot.q_home)
        full = CartesianPoseTask(robot, frame='tool', equal='init')
        shuffled = CartesianPoseTask(robot, frame='tool', axes=order, equal='init')
        full.activate(kin), shuffled.activate(kin)
        kin = kin_at(robot, q, qdot, q_v)
        a_f, A_f, _ = full.compute(kin)
        a_s, A_s, _ = shuffled.compute(kin)
        assert np.abs(a_f).max() > 1e-3  # away from the target
        np.testing.assert_allclose(a_f[perm], a_s, atol=1e-12)
        np.testing.assert_allclose(A_f[perm], A_s, atol=1e-12)


def testminimal_rotation_takes_u_onto_v_by_the_least_angle():
    from ifc_spg.tasks.cartesian_pose_task import minimal_rotation
    rng = np.random.default_rng(5)
    for k in range(500):
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        v = rng.normal(size=3) if k % 50 else -u  # include the antiparallel case
        v /= np.linalg.norm(v)
        R = minimal_rotation(u, v)
        np.testing.assert_allclose(R @ u, v, atol=1e-12)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
        np.testing.assert_allclose(angle, np.arccos(np.clip(u @ v, -1, 1)), atol=1e-7)


def test_deactivate_recaptures_init_targets_at_the_next_level():
    robot = ROBOTS['lbr_iiwa14']
    rng = np.random.default_rng(8)
    q0, qdot, q_v0 = random_state(robot, rng)
    q1, _, q_v1 = random_state(robot, rng)
    task = JointPositionTask(robot, equal='init', gain=2.0)
    task.level(kin_at(robot, q0, qdot, q_v0), 0.0)
    assert task.active
    np.testing.assert_allclose(task.bounds_at(0.0)[0], q_v0)
    held = task.level(kin_at(robot, q1, qdot, q_v1), 0.0)  # still pulled back to q_v0
    np.testing.assert_allclose(held.lower, 2.0 * (q_v0 - q_v1), atol=1e-12)
    task.deactivate()
    assert not task.active
    fresh = task.level(kin_at(robot, q1, qdot, q_v1), 0.0)  # target captured anew at q_v1
    assert task.active
    np.testing.assert_allclose(task.bounds_at(0.0)[0], q_v1)
    np.testing.assert_allclose(fresh.lower, 0.0, atol=1e-12)


def test_deactivate_recaptures_the_init_orientation_and_relative_position():
    """A restarted stack holds the pose of its restart, not of its first start.

    With ``orientation: init`` and a target of zero rotation error (and ``relative: true``
    with a target of zero offset), the reference itself is what ``init`` captures.
    """
    robot = ROBOTS['lbr_iiwa14']
    rng = np.random.default_rng(12)
    q0, qdot, q_v0 = random_state(robot, rng)
    q1, _, q_v1 = random_state(robot, rng)
    frame = robot.frame_id('tool')
    task = CartesianPoseTask(robot, frame='tool', equal=np.zeros(6), relative=True, gain=2.0)
    task.level(kin_at(robot, q0, qdot, q_v0), 0.0)
    kin1 = kin_at(robot, q1, qdot, q_v1)
    pulled = task.level(kin1, 0.0)  # back towards the pose at q_v0
    assert np.abs(pulled.lower).max() > 0.1
    task.deactivate()
    held = task.level(kin1, 0.0)  # the pose at q_v1 is the new reference
    np.testing.assert_allclose(held.lower, 0.0, atol=1e-12)
    np.testing.assert_array_equal(task.reference_rotation,
                                  kin1.frame(frame, virtual=True)[1])
    fixed = np.eye(3)  # a given rotation stays given
    task = CartesianPoseTask(robot, frame='tool', axes=['rx', 'ry', 'rz'], equal=np.zeros(3),
                             orientation=fixed)
    task.level(kin_at(robot, q0, qdot, q_v0), 0.0)
    task.deactivate()
    task.level(kin1, 0.0)
    np.testing.assert_array_equal(task.reference_rotation, fixed)


def test_a_task_without_value_or_jacobian_fails_at_construction():
    """The contract is explicit: no default calls another in a loop (no RecursionError)."""
    robot = ROBOTS['lbr_iiwa14']

    class Nothing(Task):
        pass

    class OnlyCompute(Task):  # the fused computation alone is not enough
        def compute(self, kin):
            return np.zeros(1), np.zeros((1, robot.n)), np.zeros(1)

    class OnlyValue(Task):
        def compute_value(self, kin):
            return kin.q_v[:1]

    for cls, missing in ((Nothing, 'compute_jacobian, compute_value'),
                         (OnlyCompute, 'compute_jacobian, compute_value'),
                         (OnlyValue, 'compute_jacobian')):
        with pytest.raises(TypeError, match=missing):
            cls(robot, dim=1, equal=0.0)
    with pytest.raises(TypeError, match='abstract'):
        Task(robot, dim=1, equal=0.0)


def test_a_task_with_value_and_jacobian_gets_compute_and_a_level():
    robot = ROBOTS['lbr_iiwa14']

    class FirstJoint(Task):
        def compute_value(self, kin):
            return kin.q_v[:1]

        def compute_jacobian(self, kin):
            return np.eye(1, robot.n)

    rng = np.random.default_rng(4)
    q, qdot, q_v = random_state(robot, rng)
    kin = kin_at(robot, q, qdot, q_v)
    task = FirstJoint(robot, dim=1, equal=0.5, gain=3.0)
    alpha, A, gamma = task.compute(kin)
    np.testing.assert_array_equal(alpha, q_v[:1])
    np.testing.assert_array_equal(A, np.eye(1, robot.n))
    np.testing.assert_array_equal(gamma, [0.0])
    lev = task.level(kin, 0.0)
    np.testing.assert_allclose(lev.lower, 3.0 * (0.5 - q_v[:1]) + 0.0, atol=1e-15)
    reference = JointPositionTask(robot, joints=[robot.joint_names[0]], equal=0.5, gain=3.0)
    np.testing.assert_array_equal(lev.lower, reference.level(kin, 0.0).lower)


def test_fused_compute_agrees_with_the_separate_methods():
    robot = ROBOTS['lbr_iiwa14']
    rng = np.random.default_rng(6)
    q, qdot, q_v = random_state(robot, rng)
    kin = kin_at(robot, q, qdot, q_v)
    for task in make_tasks(robot, rng):
        task.activate(kin_at(robot, q, qdot, q_v + 0.1))
        alpha, A, gamma = task.compute(kin)
        np.testing.assert_array_equal(task.compute_value(kin), alpha)
        np.testing.assert_array_equal(task.compute_jacobian(kin), A)
        np.testing.assert_array_equal(task.compute_gamma(kin), gamma)


def test_reference_rotation_is_captured_at_activation_and_read_only():
    robot = ROBOTS['lbr_iiwa14']
    kin = kin_at(robot, robot.q_home, np.zeros(7), robot.q_home)
    task = CartesianPoseTask(robot, frame='tool', axes=['rx', 'ry', 'rz'], equal='init')
    assert task.reference_rotation is None
    task.activate(kin)
    R0 = kin.frame(robot.frame_id('tool'), virtual=True)[1]
    np.testing.assert_array_equal(task.reference_rotation, R0)
    with pytest.raises(ValueError):
        task.reference_rotation[0, 0] = 2.0


def test_bound_is_abstract_and_init_resolves_only_on_activation():
    from ifc_spg.tasks import INIT, Bound, Constant

    class NoEvaluate(Bound):
        pass

    with pytest.raises(TypeError, match='evaluate'):
        NoEvaluate()
    with pytest.raises(IfcSpgError, match='before activation'):
        INIT.evaluate(0.0)
    resolved = INIT.activate(np.array([1.0, 2.0]))
    assert isinstance(resolved, Constant)
    np.testing.assert_array_equal(resolved.evaluate(3.0)[0], [1.0, 2.0])
