"""A stand-in for a robot driver the SPG does not start (a ros2_control joint_state_broadcaster):
publishes the iiwa's joint_states at 100 Hz until SIGINT/SIGTERM, echoing the last command.

    python test/external_robot.py [--ros-args ...]    # prints 'external_robot: publishing'
"""

import signal
import sys
import time

from ifc_spg import ros
from ifc_spg.model import RobotModel
from ifc_spg.ros import msg


def main():
    """Publish joint states at 100 Hz until a signal; exit 0."""
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.append(signum))
    robot = RobotModel.from_config('lbr_iiwa14')
    names, q = list(robot.joint_names), [0.0] * robot.n
    ros.init(args=sys.argv)
    node = ros.Node('external_robot')
    pub = node.create_publisher(msg.JointState, 'joint_states', 10)

    def on_command(m):
        q[:] = list(m.position)

    node.create_subscription(msg.JointState, 'command/joint_position', on_command, 10)
    print('external_robot: publishing', flush=True)
    period, next_t = 0.01, time.monotonic()
    while not stop and ros.ok():
        state = msg.JointState(name=names, position=list(q), velocity=[0.0] * len(q),
                               effort=[0.0] * len(q))
        now = time.time_ns()
        state.header.stamp.sec, state.header.stamp.nanosec = divmod(now, 1_000_000_000)
        pub.publish(state)
        next_t += period
        ros.spin_until(lambda: False, max(0.0, next_t - time.monotonic()), nodes=node)
    node.destroy_node()
    ros.shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
