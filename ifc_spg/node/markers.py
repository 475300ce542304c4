"""``spg/markers``: the Cartesian task targets as visualization_msgs/MarkerArray.

:func:`marker_array` builds the message with the classes of either backend (rclpy's
generated ones or :mod:`ifc_spg.ros.messages`); the offline bags
(:mod:`ifc_spg.offline.foxglove`) and ``spg_node`` (:class:`MarkerPublisher`, at most
``markers.rate`` Hz, 0: off) write the same markers: a DELETEALL, then per Cartesian task
(namespace = task name) its target frame as three arrows x/y/z (red, green, blue, 8 cm) and
a yellow sphere at its origin (2 cm), in ``frame`` (the robot's base frame, default
``world``); ``spg_node`` adds the running stack's base-frame obstacles where the SPG has
them (:func:`~ifc_spg.node.obstacles.obstacle_markers`: ``ns`` the obstacle's name, the
markers ``spg/obstacles`` takes). Force arrows (1 cm per N, labelled in N): each wrench
task's commanded force (green), live and in the bags, and in the bags of ``ifc-spg run``
the measured contact force (orange).
"""

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from ifc_spg.node.obstacles import obstacle_markers
from ifc_spg.ros.protocols import Node as RosNode
from ifc_spg.ros.stamps import set_stamp

if TYPE_CHECKING:  # core imports this module
    from ifc_spg.node.core import SpgRunner

__all__ = ['MarkerPublisher', 'cartesian_targets', 'marker_array', 'wrench_arrows']

# an ARROW points along its pose's x axis: the y and z arrows are x turned onto them
_TURNS = (np.eye(3), pin.exp3(np.array([0.0, 0.0, np.pi / 2])),
          pin.exp3(np.array([0.0, -np.pi / 2, 0.0])))
_RGB = ((1.0, 0.1, 0.1, 1.0), (0.1, 0.9, 0.1, 1.0), (0.2, 0.3, 1.0, 1.0))
_SPHERE_RGBA = (1.0, 0.85, 0.1, 0.8)


def cartesian_targets(tasks, kin, t):
    """``[(task name, position (3,), rotation (3, 3))]``: each Cartesian task's target frame.

    The target is the pose whose task value is the task value at q_v clipped into the bounds
    (the nearest point of the band; the target itself for an equality task); directions
    outside the task's subspace keep the virtual pose's.

    Args:
        tasks: The SPG's tasks (inactive ones are skipped).
        kin: :class:`~ifc_spg.kinematics.Kinematics` updated at (q, qdot, q_v).
        t: Task time [s].
    """
    out = []
    for task in tasks:
        if task.kind != 'cartesian_pose' or not task.active:
            continue
        lower, upper = task.bounds_at(t)
        p, R, _ = kin.frame(task.frame_id, virtual=True)
        value = np.asarray(task.compute_value(kin), dtype=float)
        goal = np.clip(value, lower, upper)
        R_ref = task.reference_orientation(R)
        x = np.concatenate((p - task._p_ref, pin.log3(R @ R_ref.T)))
        x = x + task._S_base(R) @ (goal - value)
        out.append((task.name, task._p_ref + x[:3], pin.exp3(x[3:]) @ R_ref))
    return out


def _marker(classes, stamp_ns, frame, ns, i, kind, p, R, scale, rgba):
    mk = classes.Marker()
    set_stamp(mk.header.stamp, stamp_ns)
    mk.header.frame_id = frame
    mk.ns, mk.id, mk.type = ns, int(i), int(kind)
    mk.action = int(classes.Marker.ADD)
    pos, o = mk.pose.position, mk.pose.orientation
    pos.x, pos.y, pos.z = (float(v) for v in p)
    o.x, o.y, o.z, o.w = (float(v) for v in pin.Quaternion(np.asarray(R, float)).coeffs())
    mk.scale.x, mk.scale.y, mk.scale.z = (float(v) for v in scale)
    mk.color.r, mk.color.g, mk.color.b, mk.color.a = (float(v) for v in rgba)
    return mk


#: Force arrows: metres of arrow per newton.
FORCE_SCALE = 0.01
COMMANDED_RGBA = (0.1, 0.8, 0.2, 0.9)
MEASURED_RGBA = (1.0, 0.45, 0.0, 0.9)


def wrench_arrows(tasks, kin, t, measured=None):
    """``[(name, start (3,), force (3,) [N], rgba)]``: the forces to draw.

    Each active wrench task's commanded force (green: the task value clipped into its bounds,
    force rows only, in the base frame) at its frame at the measured q; and ``measured``
    ``(chain, force (3,))``, the force the robot exerts there (orange).

    Args:
        tasks: The SPG's tasks.
        kin: :class:`~ifc_spg.kinematics.Kinematics` at this tick's (q, qdot, q_v).
        t: Task time [s].
        measured: ``(chain id, force (3,) [N])`` or None.
    """
    from ifc_spg.tasks.subspace import subspace_in_base

    out = []
    for task in tasks:
        if task.kind != 'wrench' or not task.active:
            continue
        p, R, _ = kin.frame(task.robot.frame_id(task.frame), virtual=False)
        value = np.asarray(task.compute_value(kin), dtype=float)
        lower, upper = task.bounds_at(t)
        goal = np.clip(value, lower, upper)
        w = subspace_in_base(task.S, task.subspace_frame, R) @ goal
        out.append((task.name, p.copy(), w[:3], COMMANDED_RGBA))
    if measured is not None:
        chain, force = measured
        robot = tasks[0].robot if tasks else None
        if robot is not None:
            p, _, _ = kin.frame(robot.frame_id(chain), virtual=False)
            out.append((f'{chain} measured', p.copy(), np.asarray(force, float),
                        MEASURED_RGBA))
    return out


def _arrow(classes, stamp_ns, frame, name, start, force, rgba):
    """An arrow of ``force`` from ``start`` (FORCE_SCALE m/N) and a label with its size."""
    M = classes.Marker
    end = np.asarray(start, float) + FORCE_SCALE * np.asarray(force, float)
    arrow = _marker(classes, stamp_ns, frame, name, 10, M.ARROW, np.zeros(3), np.eye(3),
                    (0.006, 0.014, 0.02), rgba)
    points = []
    for x in (start, end):
        pt = classes.Point()
        pt.x, pt.y, pt.z = (float(v) for v in x)
        points.append(pt)
    arrow.points = points
    label = _marker(classes, stamp_ns, frame, name, 11, M.TEXT_VIEW_FACING,
                    end + [0.0, 0.0, 0.02], np.eye(3), (0.0, 0.0, 0.025), rgba)
    label.text = f'{name}: {np.linalg.norm(force):.1f} N'
    return [arrow, label]


def marker_array(classes, targets, stamp_ns, frame='world', length=0.08, forces=()):
    """The MarkerArray of ``targets`` (``[(task name, position, rotation)]``) and forces.

    Args:
        classes: A namespace with ``Marker``, ``MarkerArray`` and ``Point``
            (``ifc_spg.ros.msg`` or ``ifc_spg.ros.messages``).
        targets: :func:`cartesian_targets`.
        stamp_ns: Header stamp [ns].
        frame: Header frame id.
        length: Arrow length [m].
        forces: :func:`wrench_arrows` (arrows of FORCE_SCALE m/N, labelled in N).
    """
    M = classes.Marker
    clear = M()
    clear.header.frame_id = frame
    clear.action = int(M.DELETEALL)
    items = [clear]
    for name, p, R in targets:
        for k in range(3):
            items.append(_marker(classes, stamp_ns, frame, name, k, M.ARROW, p, R @ _TURNS[k],
                                 (length, 0.006, 0.006), _RGB[k]))
        items.append(_marker(classes, stamp_ns, frame, name, 3, M.SPHERE, p, R,
                             (0.02, 0.02, 0.02), _SPHERE_RGBA))
    for name, start, force, rgba in forces:
        items.extend(_arrow(classes, stamp_ns, frame, name, start, force, rgba))
    out = classes.MarkerArray()
    out.markers = items
    return out


class MarkerPublisher:
    """``spg_node``'s ``spg/markers`` timer: the running stack's Cartesian targets.

    Args:
        node: The ``ifc_spg.ros.Node``.
        runner: The :class:`~ifc_spg.node.core.SpgRunner`.
        rate: Publish rate [Hz] (0: no publisher, no timer).
        frame: Frame id of the markers (the robot's base frame in your tf tree).
    """

    def __init__(self, node: RosNode, runner: 'SpgRunner', rate: float,
                 frame: str = 'world') -> None:
        from ifc_spg import ros
        from ifc_spg.ros import msg

        self.node, self.runner, self.frame = node, runner, frame
        self.pub = self.timer = None
        self.published = 0
        if rate <= 0:
            return
        if msg.MarkerArray is None:
            node.get_logger().warning(
                'spg/markers is off: rclpy has no visualization_msgs here (install '
                'ros-jazzy-visualization-msgs, requirements.txt); markers.rate:=0 silences this')
            return
        self._msg = msg
        self.pub = node.create_publisher(msg.MarkerArray, 'spg/markers', ros.QoSProfile(depth=1))
        self.timer = node.create_timer(1.0 / rate, self.publish)

    def publish(self) -> None:
        """Publish the targets of the last tick (nothing before the first tick)."""
        spg = self.runner.spg
        if self.pub is None or spg.q_v is None or not spg.tasks:
            return
        t = spg.info.task_time if spg.info.task_time is not None else 0.0
        targets = cartesian_targets(spg.tasks, spg.kin, t)
        stamp = self.runner._last_stamp or 0
        out = marker_array(self._msg, targets, stamp, self.frame,
                           forces=wrench_arrows(spg.tasks, spg.kin, t))
        out.markers = list(out.markers) + obstacle_markers(self._msg, spg.tasks, self.frame,
                                                           stamp)
        self.pub.publish(out)
        self.published += 1
