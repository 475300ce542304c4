"""Message classes, backend-neutral: ``from ifc_spg.ros.msg import JointState``.

With rclpy these are the real generated classes (sensor_msgs.msg.JointState, ...); otherwise the
built-in ones of :mod:`ifc_spg.ros.messages`, with the same field names and wire format.
"""

from ifc_spg.ros import BACKEND

__all__ = ['Time', 'Duration', 'Header', 'String', 'Bool', 'MultiArrayDimension',
           'MultiArrayLayout',
           'Float64MultiArray', 'JointState', 'Vector3', 'Point', 'Quaternion', 'Pose',
           'PoseStamped', 'Wrench', 'WrenchStamped', 'KeyValue', 'DiagnosticStatus',
           'DiagnosticArray', 'JointTrajectory', 'JointTrajectoryPoint', 'ColorRGBA', 'Marker',
           'MarkerArray']

if BACKEND == 'rclpy':
    from builtin_interfaces.msg import Duration, Time
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from geometry_msgs.msg import (
        Point,
        Pose,
        PoseStamped,
        Quaternion,
        Vector3,
        Wrench,
        WrenchStamped,
    )
    from sensor_msgs.msg import JointState
    from std_msgs.msg import (
        Bool,
        ColorRGBA,
        Float64MultiArray,
        Header,
        MultiArrayDimension,
        MultiArrayLayout,
        String,
    )
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    try:  # ros-jazzy-visualization-msgs (requirements.txt); spg_node checks for it
        from visualization_msgs.msg import Marker, MarkerArray
    except ImportError:
        Marker = MarkerArray = None
else:
    from ifc_spg.ros.messages import (
        Bool,
        ColorRGBA,
        DiagnosticArray,
        DiagnosticStatus,
        Duration,
        Float64MultiArray,
        Header,
        JointState,
        JointTrajectory,
        JointTrajectoryPoint,
        KeyValue,
        Marker,
        MarkerArray,
        MultiArrayDimension,
        MultiArrayLayout,
        Point,
        Pose,
        PoseStamped,
        Quaternion,
        String,
        Time,
        Vector3,
        Wrench,
        WrenchStamped,
    )
