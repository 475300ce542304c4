"""Live parameters of ``spg_node`` (a separate process on rclpy): another rclpy node reads and
changes them with rcl_interfaces GetParameters/SetParameters; the live ones apply from the
next tick, the others are refused with the reason; the node's log reaches /rosout."""

import json
import time

from helpers import CONFIG, reach_stack, use_loopback
import numpy as np
import pytest
from ros_testing import ProcessGroup

from ifc_spg.model import RobotModel

pytestmark = [pytest.mark.dds, pytest.mark.backend_pinned]


@pytest.fixture
def rclpy_env(monkeypatch):
    try:
        import rclpy  # noqa: F401
        import sensor_msgs.msg  # noqa: F401
    except ImportError:
        pytest.skip("parameter services are rclpy's (the built-in backend has none): rclpy "
                    'is not installed (ros-jazzy wheels: Linux x86_64, CPython 3.10-3.13)')
    env = use_loopback(monkeypatch)
    env['IFC_SPG_ROS_BACKEND'] = 'rclpy'
    monkeypatch.setenv('IFC_SPG_ROS_BACKEND', 'rclpy')
    return env


def _call(executor, client, request, timeout=10.0):
    assert client.wait_for_service(timeout_sec=timeout), client.srv_name
    future = client.call_async(request)
    executor.spin_until_future_complete(future, timeout_sec=timeout)
    assert future.done(), client.srv_name
    return future.result()


def test_live_parameters_from_another_rclpy_node(tmp_path, rclpy_env):
    from rcl_interfaces.msg import Log, Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import GetParameters, SetParameters
    import rclpy
    from rclpy.context import Context
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    stack = tmp_path / 'reach.yaml'
    stack.write_text(reach_stack('lbr_iiwa14'))
    procs = ProcessGroup(tmp_path, rclpy_env)
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        from rclpy.executors import SingleThreadedExecutor

        node = rclpy.create_node('param_client', context=ctx)
        executor = SingleThreadedExecutor(context=ctx)
        executor.add_node(node)
        status, rosout = [], []
        node.create_subscription(String, 'spg/status',
                                 lambda m: status.append(json.loads(m.data)), 100)
        node.create_subscription(Log, '/rosout', rosout.append, 100)
        pub = node.create_publisher(JointState, 'joint_states', 10)
        get = node.create_client(GetParameters, '/spg_node/get_parameters')
        put = node.create_client(SetParameters, '/spg_node/set_parameters')
        spg = procs.start('spg_node', '--ros-args', '--params-file',
                          str(CONFIG / 'lbr_iiwa14.yaml'), '-p', f'task_stack_file:={stack}')

        def spin(seconds, until=lambda: False):
            end = time.monotonic() + seconds
            while time.monotonic() < end and not until():
                executor.spin_once(timeout_sec=0.05)
            return until()

        assert spin(60, lambda: pub.get_subscription_count() >= 1 or spg.poll() is not None) \
            and spg.poll() is None, procs.log('spg_node')
        got = _call(executor, get, GetParameters.Request(
            names=['status.decimation', 'watchdog.timeout', 'robot']))
        assert [v.integer_value for v in got.values[:1]] == [10]
        assert got.values[2].string_value == 'lbr_iiwa14'

        def value(name, v):
            if isinstance(v, int):
                pv = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=v)
            elif isinstance(v, list):
                pv = ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY,
                                    double_array_value=v)
            elif isinstance(v, float):
                pv = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=v)
            else:
                pv = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=v)
            return Parameter(name=name, value=pv)

        res = _call(executor, put, SetParameters.Request(parameters=[
            value('status.decimation', 1), value('watchdog.timeout', 0.25),
            value('robot', 'lbr4'), value('dt', 0.5), value('impedance.damping', [1.0])]))
        ok = [r.successful for r in res.results]
        assert ok == [True, True, False, False, False], [r.reason for r in res.results]
        assert 'restart spg_node' in res.results[2].reason
        assert 'restart spg_node' in res.results[4].reason and 'K and D' in res.results[4].reason
        assert 'out of range' in res.results[3].reason or 'range' in res.results[3].reason
        got = _call(executor, get, GetParameters.Request(
            names=['status.decimation', 'watchdog.timeout', 'robot', 'dt']))
        assert got.values[0].integer_value == 1 and got.values[1].double_value == 0.25
        assert got.values[2].string_value == 'lbr_iiwa14' and got.values[3].double_value == 0.002
        # from the next tick: a status per tick (decimation 1), with the new watchdog timeout
        robot = RobotModel.from_config('lbr_iiwa14')
        for k in range(20):
            msg = JointState(name=list(robot.joint_names),
                             position=[float(x) for x in robot.q_home],
                             velocity=[0.0] * robot.n)
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(k * 2_000_000, 10**9)
            pub.publish(msg)
            spin(0.02)
        assert spin(10, lambda: len([s for s in status if s.get('tick', 0) > 0]) >= 20), status
        ticks = [s['tick'] for s in status if 'event' not in s and s.get('tick', 0) > 0]
        assert ticks == list(range(1, len(ticks) + 1))[:len(ticks)] and len(ticks) >= 20
        assert status[-1]['watchdog']['timeout'] == 0.25
        assert np.all(np.isfinite(status[-1].get('q_v', [0.0])))
        # the node's log is on /rosout
        assert spin(5, lambda: any(m.name == 'spg_node' and 'parameters changed' in m.msg
                                   for m in rosout)), [m.msg for m in rosout]
        assert procs.stop('spg_node') == 0
    finally:
        procs.close()
        rclpy.try_shutdown(context=ctx)
