"""The topics Foxglove's (and RViz's) 3D panel draws a robot from, written into our bags.

:class:`FoxgloveTopics` adds to a :class:`~ifc_spg.offline.bag.BagWriter`:

- ``/robot_description`` (std_msgs/String, latched): the URDF of :func:`~sim_bridge.urdf.
  urdf_from_robot`, generated from the robot's MJCF;
- ``/tf_static`` (tf2_msgs/TFMessage, latched): the fixed joints of the URDF, for the
  measured robot and for a second tree ``virtual/...`` (q_v), joined by ``world`` ->
  ``virtual/world`` (identity);
- ``/tf`` (tf2_msgs/TFMessage): every moving joint of the URDF at the recorded joint states
  (measured q, frames as in the URDF) and at the commanded q_v (``virtual/`` frames), with
  the messages' header stamps, at most every ``tf_period`` [s] of stamp time;
- ``/spg/markers`` (visualization_msgs/MarkerArray): each Cartesian task's target frame and
  the force arrows (:func:`ifc_spg.node.markers.marker_array`) in ``world``, the robot's
  base frame.

There is no tf2_msgs wheel for rclpy here, and the built-in DDS backend has no tf2_msgs
classes: ``/tf`` and ``/tf_static`` are serialized with ``rosbags`` (its Jazzy typestore), in
the bag writer only.
"""

import sys

import pinocchio as pin

from ifc_spg.node.markers import cartesian_targets, marker_array
from ifc_spg.ros.qos import QoSProfile, latched
from ifc_spg.ros.stamps import stamp_to_ns
from sim_bridge.urdf import urdf_from_robot

__all__ = ['VIRTUAL_PREFIX', 'FoxgloveTopics', 'RecordingObserver', 'cartesian_targets',
           'tf_transforms']

#: Frame prefix of the q_v tree.
VIRTUAL_PREFIX = 'virtual/'
_TF = 'tf2_msgs/msg/TFMessage'
_STRING = 'std_msgs/msg/String'
_MARKERS = 'visualization_msgs/msg/MarkerArray'


def tf_transforms(tree, q_by_name, prefix=''):
    """``[(parent, child, SE3)]`` of the moving joints of ``tree`` at joint positions.

    Args:
        tree: :class:`~sim_bridge.urdf.UrdfTree`.
        q_by_name: Joint name -> position; joints not given are at 0.
        prefix: Prepended to every frame name.
    """
    return [(prefix + j.parent, prefix + j.child, j.transform(q_by_name.get(j.name, 0.0)))
            for j in tree.moving]


class FoxgloveTopics:
    """Writes the robot description, tf and task-target markers into a bag (module docstring).

    Args:
        writer: The :class:`~ifc_spg.offline.bag.BagWriter`.
        robot: The :class:`~ifc_spg.model.RobotModel` whose joint states are recorded.
        tf_period: Least stamp time [s] between two ``/tf`` messages of a tree.
        markers_period: Least stamp time [s] between two ``/spg/markers`` messages (the live
            node's ``1 / markers.rate``); None: no ``/spg/markers`` (a live recording records
            the node's own ``spg/markers`` instead, if asked to).
    """

    def __init__(self, writer, robot, tf_period=0.01, markers_period=None):
        from rosbags.typesys import Stores, get_typestore

        self.writer, self.robot = writer, robot
        self.tree = urdf_from_robot(robot)
        self.tf_period_ns = int(round(tf_period * 1e9))
        self.markers_period_ns = None if markers_period is None else \
            int(round(markers_period * 1e9))
        self._last = {}
        self._static_written = False
        store = get_typestore(Stores.ROS2_JAZZY)
        self._store = store
        self._T = store.types
        topics = [('/robot_description', _STRING, latched(1)), ('/tf_static', _TF, latched(1)),
                  ('/tf', _TF, QoSProfile(depth=100))]
        if markers_period is not None:
            topics.append(('/spg/markers', _MARKERS, QoSProfile(depth=10)))
        for topic, msgtype, qos in topics:
            writer.add_topic(topic, msgtype, qos)

    # -- message construction (rosbags dataclasses) ---------------------------------------
    def _header(self, t_ns, frame):
        T = self._T
        sec, nsec = divmod(int(t_ns), 1_000_000_000)
        return T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
            sec=sec, nanosec=nsec), frame_id=frame)

    def _tf_message(self, t_ns, transforms):
        T = self._T
        items = []
        for parent, child, M in transforms:
            qx, qy, qz, qw = pin.Quaternion(M.rotation).coeffs()
            tr = M.translation
            items.append(T['geometry_msgs/msg/TransformStamped'](
                header=self._header(t_ns, parent), child_frame_id=child,
                transform=T['geometry_msgs/msg/Transform'](
                    translation=T['geometry_msgs/msg/Vector3'](
                        x=float(tr[0]), y=float(tr[1]), z=float(tr[2])),
                    rotation=T['geometry_msgs/msg/Quaternion'](x=qx, y=qy, z=qz, w=qw))))
        return T[_TF](transforms=items)

    def _write(self, topic, t_ns, msg):
        self.writer.write(topic, t_ns, self._store.serialize_cdr(msg, msg.__msgtype__))

    # -- the channels ---------------------------------------------------------------------
    def write_static(self, t_ns):
        """``/robot_description`` and ``/tf_static`` at log time ``t_ns``."""
        self._static_written = True
        self._write('/robot_description', t_ns, self._T[_STRING](data=self.tree.xml))
        fixed = []
        for prefix in ('', VIRTUAL_PREFIX):
            fixed += [(prefix + j.parent, prefix + j.child, j.origin) for j in self.tree.fixed]
        root = self.tree.root
        fixed.append((root, VIRTUAL_PREFIX + root, pin.SE3.Identity()))
        self._write('/tf_static', t_ns, self._tf_message(t_ns, fixed))

    def _due(self, key, stamp_ns, period_ns):
        last = self._last.get(key)
        if last is not None and stamp_ns - last < period_ns:
            return False
        self._last[key] = stamp_ns
        return True

    def joint_state(self, t_ns, stamp_ns, names, positions, virtual=False):
        """``/tf`` of one joint state (``virtual``: the q_v tree), if due; True if written."""
        prefix = VIRTUAL_PREFIX if virtual else ''
        if not self._due(prefix, stamp_ns, self.tf_period_ns):
            return False
        q = dict(zip(names, (float(x) for x in positions)))
        self._write('/tf', t_ns, self._tf_message(stamp_ns, tf_transforms(self.tree, q,
                                                                           prefix)))
        return True

    def markers_due(self, stamp_ns):
        """True if a ``/spg/markers`` message is due at ``stamp_ns`` (never without markers)."""
        return self.markers_period_ns is not None and \
            self._due('markers', stamp_ns, self.markers_period_ns)

    def markers(self, t_ns, stamp_ns, targets, forces=()):
        """Write ``/spg/markers``: ``targets`` (:func:`cartesian_targets`) and ``forces``."""
        from ifc_spg.ros import messages

        self.writer.write_msg('/spg/markers', t_ns, marker_array(
            messages, targets, stamp_ns, self.tree.root, forces=forces))


class RecordingObserver:
    """Adds the Foxglove topics to a bag being recorded (``ifc-spg bag record``).

    Called with every message the recorder writes: ``joint_states`` become ``/tf`` of the
    measured tree, ``command/joint_position`` of the ``virtual/`` tree. The robot is
    ``robot`` if given, else the one the SPG names in its ``spg/config`` or first
    ``spg/status`` (``config.robot``); joint states that arrive before that are held (at most
    ``max_pending``) and written when the robot is known. Markers need the SPG's tasks and
    are written by offline runs only.

    Args:
        writer: The :class:`~ifc_spg.offline.bag.BagWriter`.
        robot: A robot configuration name (``RobotModel.from_config``), or None.
        tf_period: As :class:`FoxgloveTopics`.
        max_pending: Joint states held while the robot is unknown.
    """

    def __init__(self, writer, robot=None, tf_period=0.01, max_pending=10000):
        self.writer, self.tf_period, self.max_pending = writer, tf_period, max_pending
        self.topics: FoxgloveTopics | None = None
        self.failed = None
        self._pending = []
        if robot is not None:
            self._start(robot, None)

    def _start(self, name, t_ns):
        from ifc_spg.errors import IfcSpgError
        from ifc_spg.model import RobotModel

        try:
            self.topics = FoxgloveTopics(self.writer, RobotModel.from_config(name),
                                         self.tf_period)
        except IfcSpgError as exc:
            if t_ns is None:  # --robot given: the caller's error
                raise
            self.failed = f'no robot_description and tf: {exc}'
            print(f'ifc-spg bag record: {self.failed}', file=sys.stderr, flush=True)
            return
        self.robot_name = name
        if t_ns is not None:
            self.topics.write_static(t_ns)

    def __call__(self, topic, t_ns, data):
        """Observe one written message (CDR ``data`` on ``topic`` at log time ``t_ns``)."""
        import json

        from ifc_spg.ros import messages

        if self.failed:
            return
        parts = topic.split('/')
        leaf = '/'.join(parts[-2:])
        if self.topics is None and leaf in ('spg/config', 'spg/status'):
            try:
                doc = json.loads(messages.deserialize(messages.String, data).data)
                robot = (doc.get('config') or {}).get('robot')
            except (ValueError, AttributeError, TypeError):
                robot = None
            if isinstance(robot, str):
                self._start(robot, t_ns)
                for item in self._pending:
                    self._joint_state(*item)
                self._pending.clear()
            return
        virtual = leaf == 'command/joint_position'
        if not virtual and parts[-1] != 'joint_states':
            return
        item = (t_ns, data, virtual)
        if self.topics is None:
            if len(self._pending) < self.max_pending:
                self._pending.append(item)
            return
        self._joint_state(*item)

    def _joint_state(self, t_ns, data, virtual):
        from ifc_spg.errors import IfcSpgError
        from ifc_spg.ros import messages

        if self.topics is None:  # called once the robot is known
            raise IfcSpgError('internal: Foxglove topics written before the robot is known')
        if self.topics._static_written is False:
            self.topics.write_static(t_ns)
        try:
            js = messages.deserialize(messages.JointState, data)
        except (IfcSpgError, ValueError):
            return
        stamp = stamp_to_ns(js.header.stamp)
        self.topics.joint_state(t_ns, stamp, js.name, js.position, virtual)
