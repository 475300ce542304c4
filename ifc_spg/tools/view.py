"""``ifc-spg view BAG``: a browser cockpit of a recorded run (viser).

    ifc-spg view out/run/bag [--port 8080] [--host 127.0.0.1]
    ifc-spg view --live lbr_iiwa14 [--port 8080] [--spg-node spg_node]
                                                      (a running SPG, from its topics)

Serves a 3D view on ``http://HOST:PORT`` (loopback by default; ``--host 0.0.0.0`` to expose)
and prints the URL: the robot at the measured q (solid) and at q_v (a translucent blue
ghost), the Cartesian task targets of ``/spg/markers`` (axes), a floor grid, the
``spg/status`` of the time shown (stack, SPG state, tank energies, PSPM stall), and a
timeline slider with play/pause over the bag's joint states (live: a gizmo per streamed pose
target, and controls for spg_node's ``enable`` and live parameters, :class:`LiveCockpit`).
The robot is the bag's ``/robot_description`` (URDF; else generated from the robot its SPG
configuration names), drawn with its primitive shapes, placed by pinocchio's FK of that URDF.

viser (pinned in requirements.txt) ships its built web client inside the wheel, so the page
works without internet. Chosen over rerun: viser is a Python scene graph with GUI controls
(sliders, buttons) and transform gizmos served by the same process, which a cockpit that
also steers needs; rerun is a logging viewer with its own binary and data model.
"""

import threading
import time
from typing import Any
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

from ifc_spg.errors import IfcSpgError, ParameterError
from ifc_spg.ros.stamps import stamp_to_sec

__all__ = ['Cockpit', 'LiveCockpit', 'ViewData', 'load_bag', 'status_text']

_SOLID = (200, 200, 205)
_GHOST = (60, 120, 255)


class ViewData:
    """What the cockpit shows of a bag (:func:`load_bag`).

    Attributes:
        urdf: The URDF text.
        joint_names: Joint names (the order of ``q`` and ``q_v`` columns).
        t: Joint-state stamps [s], shape (N,).
        q: Measured joint positions, shape (N, n).
        q_v: Commanded q_v at the same stamps (NaN rows where no command has that stamp).
        targets: ``[(stamp [s], [(task name, position (3,), wxyz (4,))])]`` from
            ``/spg/markers``.
        status: ``[(stamp [s], spg/status document)]`` (documents with a stamp).
        forces: ``[(stamp [s], [(name, start (3,), end (3,), rgb)])]``: the force arrows of
            ``/spg/markers`` (commanded and measured, :data:`ifc_spg.node.markers.FORCE_SCALE`
            metres per newton).
    """

    def __init__(self, urdf, joint_names, t, q, q_v, targets, status=(), forces=()):
        self.urdf, self.joint_names = urdf, list(joint_names)
        self.t, self.q, self.q_v, self.targets = t, q, q_v, targets
        self.status = list(status)
        self.forces = list(forces)


def _stamp(msg):
    return stamp_to_sec(msg.header.stamp)


def _targets(markers):
    """``[(task, position, wxyz)]``: the target origins (SPHERE markers) of ``spg/markers``."""
    return [(m.ns, np.array([m.pose.position.x, m.pose.position.y, m.pose.position.z]),
             np.array([m.pose.orientation.w, m.pose.orientation.x, m.pose.orientation.y,
                       m.pose.orientation.z])) for m in markers if m.type == 2]  # SPHERE


def _forces(markers):
    """``[(name, start, end, rgb)]``: the force arrows (ARROWs given by two points)."""
    return [(m.ns, np.array([m.points[0].x, m.points[0].y, m.points[0].z]),
             np.array([m.points[1].x, m.points[1].y, m.points[1].z]),
             tuple(int(round(255 * c)) for c in (m.color.r, m.color.g, m.color.b)))
            for m in markers if m.type == 0 and len(m.points) == 2]  # ARROW


def _markers(data):
    """``(stamp [s], targets, forces)`` of a recorded ``spg/markers`` message (None if empty)."""
    from ifc_spg.ros import messages

    arr = messages.deserialize(messages.MarkerArray, data)
    stamped = [m for m in arr.markers if m.action == messages.Marker.ADD]
    if not stamped:
        return None
    return _stamp(stamped[0]), _targets(arr.markers), _forces(arr.markers)


def _json_doc(text):
    """The JSON object in ``text`` ({} if it is not one)."""
    import json

    try:
        doc = json.loads(text)
    except ValueError:
        return {}
    return doc if isinstance(doc, dict) else {}


def _read(path):
    """The bag's joint states and commands by stamp, markers, URDF, robot name, status."""
    from ifc_spg.offline.bag import BagReader
    from ifc_spg.ros import messages

    states: dict[int, Any] = {}  # stamp [ns] -> JointState
    commands: dict[int, Any] = {}
    targets: list[tuple[float, Any]] = []
    forces: list[tuple[float, Any]] = []
    status: list[tuple[float, Any]] = []  # (t, JSON document)
    urdf = robot = None
    with BagReader(path) as bag:
        topics = {t.lstrip('/'): t for t in bag.topics}
        if 'joint_states' not in topics:
            raise ParameterError(f"bag '{path}' has no joint_states; topics: "
                                 f"{', '.join(sorted(bag.topics)) or 'none'}")
        wanted = {topics[k] for k in ('joint_states', 'command/joint_position',
                                      'robot_description', 'spg/markers', 'spg/status',
                                      'spg/config') if k in topics}
        for topic, _, _, data in bag.raw(wanted):
            name = topic.lstrip('/')
            if name == 'robot_description':
                urdf = messages.deserialize(messages.String, data).data
            elif name in ('spg/status', 'spg/config'):
                doc = _json_doc(messages.deserialize(messages.String, data).data)
                robot = robot or (doc.get('config') or {}).get('robot')
                if name == 'spg/status' and isinstance(doc.get('stamp'), (int, float)):
                    status.append((float(doc['stamp']), doc))
            elif name == 'spg/markers':
                item = _markers(data)
                if item is not None:
                    stamp, items, arrows = item
                    if items:
                        targets.append((stamp, items))
                    forces.append((stamp, arrows))
            elif name in ('joint_states', 'command/joint_position'):
                js = messages.deserialize(messages.JointState, data)
                (states if name == 'joint_states' else commands)[_stamp(js)] = js
    return states, commands, (targets, forces), urdf, robot, status


def load_bag(path):
    """Read a bag written by ``ifc-spg run`` or ``ifc-spg bag record`` into :class:`ViewData`.

    Raises:
        ParameterError: Not a bag, no joint states, or no way to know the robot.
    """
    states, commands, (targets, forces), urdf, robot, status = _read(path)
    if not states:
        raise ParameterError(f"bag '{path}': no joint states recorded")
    if urdf is None:
        if robot is None:
            raise ParameterError(f"bag '{path}' has neither /robot_description nor the SPG "
                                 'configuration (spg/status, spg/config) naming the robot')
        from ifc_spg.model import RobotModel
        from sim_bridge.urdf import urdf_from_robot
        urdf = urdf_from_robot(RobotModel.from_config(robot)).xml
    stamps = sorted(states)
    names = list(states[stamps[0]].name)

    def row(js):
        index = {n: i for i, n in enumerate(js.name)}
        return [float(js.position[index[n]]) if n in index else np.nan for n in names]

    q = np.array([row(states[s]) for s in stamps])
    q_v = np.array([row(commands[s]) if s in commands else [np.nan] * len(names)
                    for s in stamps])
    for items in (targets, forces, status):
        items.sort(key=lambda x: x[0])
    return ViewData(urdf, names, np.array(stamps), q, q_v, targets, status, forces)


def _attribute(element: ET.Element, name: str) -> str:
    """The attribute ``name`` of a URDF element (an error naming it where it lacks it)."""
    value = element.get(name)
    if value is None:
        raise ParameterError(f"URDF <{element.tag}> has no '{name}' attribute")
    return value


def _visuals(urdf):
    """``{link: [(kind, size, SE3 in the link, rgb)]}`` of the URDF's visual elements."""
    out = {}
    for link in ET.fromstring(urdf).iter('link'):
        items = []
        for vis in link.iter('visual'):
            origin = vis.find('origin')
            xyz = [float(v) for v in (origin.get('xyz', '0 0 0') if origin is not None
                                      else '0 0 0').split()]
            rpy = [float(v) for v in (origin.get('rpy', '0 0 0') if origin is not None
                                      else '0 0 0').split()]
            M = pin.SE3(pin.rpy.rpyToMatrix(np.array(rpy)), np.array(xyz))
            color = vis.find('material/color')
            rgba = [float(v) for v in _attribute(color, 'rgba').split()] if color is not None \
                else [0.8, 0.8, 0.8, 1.0]
            rgb = tuple(int(255 * min(max(c, 0.0), 1.0)) for c in rgba[:3])
            geom = vis.find('geometry')
            for kind in ('box', 'sphere', 'cylinder'):
                g = geom.find(kind) if geom is not None else None
                if g is None:
                    continue
                if kind == 'box':
                    size = tuple(float(v) for v in _attribute(g, 'size').split())
                elif kind == 'sphere':
                    size = (float(_attribute(g, 'radius')),)
                else:
                    size = (float(_attribute(g, 'radius')), float(_attribute(g, 'length')))
                items.append((kind, size, M, rgb))
        if items:
            out[link.get('name')] = items
    return out


def status_text(doc):
    """Markdown of an ``spg/status`` document: stack, SPG state, tank energies, PSPM."""
    if not doc:
        return 'no spg/status yet'
    stack = (doc.get('stack') or {}).get('name') or 'none'
    lines = [f"stack **{stack}**, {doc.get('state', '?')}, SPG "
             f"{(doc.get('spg') or {}).get('status', '?')}"]
    tanks = doc.get('tank_energy')
    if tanks:
        lines.append('tanks [J]: ' + ' '.join(f'{e:.2f}' for e in tanks))
    pspm = doc.get('pspm') or {}
    stall = pspm.get('stall')
    if stall:
        lines.append(f"**PSPM stall**: {', '.join(map(str, stall.get('joints', [])))}")
    elif tanks:
        lines.append('PSPM: no stall')
    return '  \n'.join(lines)


def _wxyz(R):
    x, y, z, w = pin.Quaternion(np.asarray(R, float)).coeffs()
    return np.array([w, x, y, z])


class _Scene:
    """The viser server, the robot at q (solid) and q_v (ghost), targets and a floor.

    Args:
        urdf: URDF text of the robot.
        joint_names: The order of the q vectors given to :meth:`draw`.
        host, port: Where to serve.
    """

    def __init__(self, urdf, joint_names, host, port):
        import viser

        self.model = pin.buildModelFromXML(urdf)
        self.pin_data = self.model.createData()
        self._idx = [self.model.joints[self.model.getJointId(n)].idx_q
                     if self.model.existJointName(n) else None for n in joint_names]
        visuals = _visuals(urdf)
        self.links = [link for link in visuals if self.model.existFrame(link)]
        self._frame_ids = [self.model.getFrameId(link) for link in self.links]
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.url = f'http://{host}:{self.server.get_port()}'
        scene = self.server.scene
        scene.add_grid('/floor', width=2.0, height=2.0, cell_size=0.1, section_size=0.5)
        cam = self.server.initial_camera  # looking at the robot from the front right
        cam.position, cam.look_at, cam.up = (1.6, -1.3, 1.2), (0.3, 0.0, 0.45), (0.0, 0.0, 1.0)
        self.handles: dict[str, list[Any]] = {'robot': [], 'virtual': []}  # viser handles
        for tree, opacity, tint in (('robot', None, None), ('virtual', 0.35, _GHOST)):
            for link in self.links:
                frame = scene.add_frame(f'/{tree}/{link}', show_axes=False)
                self.handles[tree].append(frame)
                for i, (kind, size, M, rgb) in enumerate(visuals[link]):
                    kw = {'color': tint or rgb, 'opacity': opacity, 'position': M.translation,
                          'wxyz': _wxyz(M.rotation)}
                    name = f'/{tree}/{link}/v{i}'
                    if kind == 'box':
                        scene.add_box(name, dimensions=size, **kw)
                    elif kind == 'sphere':
                        scene.add_icosphere(name, radius=size[0], **kw)
                    else:
                        scene.add_cylinder(name, radius=size[0], height=size[1], **kw)
        self.target_handles, self.force_handles = {}, {}
        self._stop = threading.Event()

    def fk(self, q):
        """Run pinocchio's FK of the URDF at ``q`` (joint_names order; NaN: neutral)."""
        qq = pin.neutral(self.model)
        for k, i in enumerate(self._idx):
            if i is not None and np.isfinite(q[k]):
                qq[i] = q[k]
        pin.framesForwardKinematics(self.model, self.pin_data, qq)
        return self.pin_data

    def draw(self, q, q_v):
        """Place the robot at ``q`` and the ghost at ``q_v`` (hidden if not finite)."""
        for tree, x in (('robot', q), ('virtual', q_v)):
            visible = x is not None and bool(np.all(np.isfinite(x)))
            if not visible:
                for handle in self.handles[tree]:
                    handle.visible = tree == 'robot'
                continue
            data = self.fk(x)
            for handle, f in zip(self.handles[tree], self._frame_ids):
                M = data.oMf[f]
                handle.position, handle.wxyz, handle.visible = M.translation, \
                    _wxyz(M.rotation), True

    def draw_targets(self, items):
        """Show ``[(task, position, wxyz)]`` as axes; hide the others."""
        seen = set()
        for name, p, wxyz in items:
            seen.add(name)
            handle = self.target_handles.get(name)
            if handle is None:
                handle = self.target_handles[name] = self.server.scene.add_frame(
                    f'/targets/{name}', axes_length=0.08, axes_radius=0.004)
            handle.position, handle.wxyz, handle.visible = p, wxyz, True
        for name, handle in self.target_handles.items():
            if name not in seen:
                handle.visible = False

    def draw_forces(self, items):
        """Show ``[(name, start, end, rgb)]`` as arrows; hide the others."""
        seen = set()
        for name, start, end, rgb in items:
            seen.add(name)
            points = np.array([[start, end]], dtype=float)
            colors = np.array([rgb], dtype=np.uint8)
            handle = self.force_handles.get(name)
            if handle is None:
                handle = self.force_handles[name] = self.server.scene.add_arrows(
                    f'/forces/{name}', points=points, colors=colors, shaft_radius=0.004,
                    head_radius=0.01, head_length=0.02)
            handle.points, handle.colors, handle.visible = points, colors, True
        for name, handle in self.force_handles.items():
            if name not in seen:
                handle.visible = False

    def close(self):
        """Stop the background thread and the server."""
        self._stop.set()
        self.server.stop()


def _at(series, t, default):
    """The value of ``[(stamp, value)]`` (sorted) last at or before ``t``."""
    current = default
    for stamp, value in series:
        if stamp > t + 1e-9:
            break
        current = value
    return current


class Cockpit(_Scene):
    """The cockpit of one bag: the scene and a timeline.

    Args:
        data: :class:`ViewData`.
        host: Interface to serve on (default loopback).
        port: TCP port.

    Attributes:
        server: The ``viser.ViserServer``.
        url: ``http://host:port``.
        links: Link names drawn (each a scene node ``/robot/<link>`` and ``/virtual/<link>``).
    """

    def __init__(self, data, host='127.0.0.1', port=8080):
        super().__init__(data.urdf, data.joint_names, host, port)
        self.data = data
        gui = self.server.gui
        n = len(data.t)
        self.slider = gui.add_slider('joint state', min=0, max=max(n - 1, 1), step=1,
                                     initial_value=0)
        self.playing = gui.add_checkbox('play', initial_value=False)
        self.speed = gui.add_slider('speed', min=0.1, max=4.0, step=0.1, initial_value=1.0)
        self.label = gui.add_markdown('')
        self.status = gui.add_markdown('')
        self.slider.on_update(lambda _: self.show(int(self.slider.value)))
        self.index = 0  # the sample shown (show() sets it)
        self.show(0)
        self._player = threading.Thread(target=self._play, daemon=True)
        self._player.start()

    def show(self, i):
        """Draw sample ``i``: the robot at q, the ghost at q_v, the targets then."""
        data = self.data
        i = int(np.clip(i, 0, len(data.t) - 1))
        self.index = i
        with self.server.atomic():
            self.draw(data.q[i], data.q_v[i])
            self.draw_targets(_at(data.targets, data.t[i], []))
            self.draw_forces(_at(data.forces, data.t[i], []))
        self.label.content = (f'**t = {data.t[i] - data.t[0]:.3f} s** ({i + 1}/{len(data.t)}); '
                              'solid: measured q, blue: q_v, axes: task targets, arrows: '
                              'forces (green commanded, orange measured; 1 cm/N)')
        doc = None
        for stamp, d in data.status:
            if stamp > data.t[i] + 1e-9:
                break
            doc = d
        self.status.content = status_text(doc)

    def _play(self):
        last = time.monotonic()
        while not self._stop.wait(1 / 30):  # at most 30 frames a second
            now = time.monotonic()
            if self.playing.value and len(self.data.t) > 1:
                t = self.data.t[self.index] + (now - last) * float(self.speed.value)
                i = int(np.searchsorted(self.data.t, t))
                if i >= len(self.data.t):
                    i = 0
                # viser defines the value setter apart from its getter: mypy sees it read-only
                self.slider.value = max(i, self.index + 1) % len(self.data.t)  # type: ignore[misc]
            last = now


class LiveCockpit(_Scene):
    """The cockpit of a running SPG, from its topics; a gizmo per streamed pose target.

    Subscribes to ``joint_states`` (solid robot), ``command/joint_position`` (ghost),
    ``spg/markers`` (targets) and the latched ``spg/config`` (the running stack). Each
    ``cartesian_pose`` task of that stack with ``equal: {stream: ...}`` gets a transform
    gizmo; moving it (in the page, or with :meth:`move_target`) publishes a
    geometry_msgs/PoseStamped in ``world`` on the task's stream topic. Redraws at most 30
    times a second.

    The ``spg_node`` folder holds a checkbox for ``enable`` and a control per other live
    parameter of the node (:data:`ifc_spg.node.spg_node.LIVE_PARAMETERS`); a change (in the
    page, or with :meth:`set_parameter`) goes to the node's parameter services (rclpy; on the
    built-in backend ``enable`` goes on the latched ``spg/enable`` and the rest is refused,
    :mod:`ifc_spg.tools.remote_parameters`). A refused value is shown under the controls
    and the control returns to the node's value.

    Args:
        robot: Robot configuration name (the URDF is generated from its MJCF).
        node: An ``ifc_spg.ros.Node`` to use (None: ``ros.init`` and a node ``spg_view``).
        host, port: Where to serve.
        spg_node: Name of the SPG node whose parameters the controls set.
    """

    def __init__(self, robot, node=None, host='127.0.0.1', port=8080, spg_node='spg_node'):
        from ifc_spg import ros
        from ifc_spg.model import RobotModel
        from ifc_spg.ros import msg
        from sim_bridge.urdf import urdf_from_robot

        self.robot = RobotModel.from_config(robot)
        super().__init__(urdf_from_robot(self.robot).xml, self.robot.joint_names, host, port)
        self._ros, self._msg = ros, msg
        self._own_node = node is None
        if node is None:
            ros.init(args=['ifc-spg'])
            node = ros.Node('spg_view')
        self.node = node
        self.q = self.q_v = None
        self.targets, self.forces, self.gizmos, self._pubs = [], [], {}, {}
        node.create_subscription(msg.JointState, 'joint_states',
                                 lambda m: setattr(self, 'q', self._ordered(m)), 10)
        node.create_subscription(msg.JointState, 'command/joint_position',
                                 lambda m: setattr(self, 'q_v', self._ordered(m)), 10)
        node.create_subscription(msg.String, 'spg/config', self._on_config, ros.latched(1))
        self.last_status = None
        node.create_subscription(msg.String, 'spg/status', self._on_status, 10)
        if msg.MarkerArray is not None:
            node.create_subscription(msg.MarkerArray, 'spg/markers', self._on_markers, 10)
        self.label = self.server.gui.add_markdown('waiting for joint_states ...')
        self.status = self.server.gui.add_markdown('')
        self._add_controls(spg_node)
        self._spinner = threading.Thread(target=self._spin, daemon=True)
        self._spinner.start()

    def _add_controls(self, spg_node):
        """The ``spg_node`` folder: a control per live parameter and the last reply."""
        import dataclasses

        from ifc_spg.node.config import PARAMETERS, SpgConfig
        from ifc_spg.node.spg_node import LIVE_PARAMETERS
        from ifc_spg.tools.remote_parameters import remote_parameters

        self.remote = remote_parameters(self.node, spg_node)
        defaults: dict[str, Any] = {f.name: f.default for f in dataclasses.fields(SpgConfig)}
        gui = self.server.gui
        self.controls: dict[str, Any] = {}
        self.values: dict[str, Any] = {}  # the node's value of each control (last known)
        self._syncing = False  # True while the cockpit itself sets a control
        with gui.add_folder(spg_node):
            for p in PARAMETERS:
                if p.name not in LIVE_PARAMETERS:
                    continue
                value = self.values[p.name] = defaults[p.field]
                hint = p.description + (f' [{p.range[0]:g}, {p.range[1]:g}]' if p.range else '')
                control: Any
                if isinstance(value, bool):
                    control = gui.add_checkbox(p.name, initial_value=value, hint=hint)
                else:  # no min/max here: the node checks the range and says why it refuses
                    control = gui.add_number(p.name, initial_value=value, hint=hint,
                                             step=1 if isinstance(value, int) else 0.001)
                def on_update(_: object, name: str = p.name) -> None:
                    self._on_control(name)

                control.on_update(on_update)
                self.controls[p.name] = control
            self.reply = gui.add_markdown('')
        self._synced = False  # the controls show the node's values (GetParameters)

    def _on_control(self, name):
        if not self._syncing:
            self.set_parameter(name, self.controls[name].value)

    def _show_values(self, values):
        self._syncing = True
        try:
            for name, value in values.items():
                if name in self.controls and value is not None:
                    self.values[name] = value
                    self.controls[name].value = value
        finally:
            self._syncing = False

    def set_parameter(self, name, value, timeout=5.0):
        """Set live parameter ``name`` of the SPG node (as its control in the page does).

        Returns:
            The SetParametersResult (``successful``, ``reason``); also shown in the page.
            A refused value never raises: the control returns to the node's value.
        """
        from ifc_spg.ros.parameters import SetParametersResult

        old = self.values.get(name)
        try:
            if name not in self.controls:
                raise IfcSpgError(f"'{name}' is not a live parameter of the cockpit's node; "
                                  f"live: {', '.join(self.controls)}")
            try:
                if isinstance(old, bool):
                    value = bool(value)
                elif isinstance(old, int) and float(value).is_integer():
                    value = int(value)
                elif isinstance(old, float):
                    value = float(value)
            except (TypeError, ValueError):
                raise ParameterError(f"'{name}' takes a number like {old!r}, not "
                                     f'{value!r}') from None
            result = self.remote.set(name, value, timeout)
        except Exception as exc:  # noqa: BLE001 - shown in the page, the cockpit goes on
            result = SetParametersResult(False, str(exc) if isinstance(exc, IfcSpgError)
                                         else f'{type(exc).__name__}: {exc}')
        if result.successful:
            self._show_values({name: value})
            self.reply.content = f'{name} = {value!r}: {result.reason or "set"}'
        else:
            self.reply.content = f'**{name} = {value!r} refused**: {result.reason}'
            if name in self.controls:
                self._show_values({name: old})
        return result

    def get_parameters(self, timeout=5.0):
        """``{name: value}`` of the live parameters as the SPG node has them now (rclpy)."""
        got: dict[str, Any] = {}
        answered = threading.Event()
        def done(values: dict[str, Any]) -> None:
            got.update(values)
            answered.set()

        self.remote.get(list(self.controls), done)
        answered.wait(timeout)
        return got

    def _ordered(self, m):
        index = {n: i for i, n in enumerate(m.name)}
        return np.array([float(m.position[index[n]]) if n in index else np.nan
                         for n in self.robot.joint_names])

    def _on_status(self, message):
        doc = _json_doc(message.data)
        if doc:
            self.last_status = doc

    def _on_markers(self, arr):
        self.targets, self.forces = _targets(arr.markers), _forces(arr.markers)

    def _on_config(self, message):
        import json

        from ifc_spg.node.core import parse_task_stack
        from ifc_spg.tasks.stream import default_topic

        try:
            stack = (json.loads(message.data) or {}).get('stack') or {}
            tasks = parse_task_stack(stack['text']).tasks if stack.get('text') else ()
        except (ValueError, KeyError, IfcSpgError):
            return
        for t in tasks:
            if t.type != 'cartesian_pose' or getattr(t.equal, 'kind', None) != 'stream' or \
                    t.name in self.gizmos:
                continue
            topic = t.equal.get('stream') or default_topic(t.name)
            self._pubs[t.name] = self.node.create_publisher(self._msg.PoseStamped, topic, 10)
            q = self.q_v if self.q_v is not None else self.q
            data = self.fk(q if q is not None else self.robot.q_home)
            fid = self.model.getFrameId(self.robot.frames[t.frame])
            M = data.oMf[fid]
            gizmo = self.server.scene.add_transform_controls(
                f'/gizmos/{t.name}', scale=0.2, position=M.translation, wxyz=_wxyz(M.rotation))
            def on_update(_: object, name: str = t.name) -> None:
                self._publish(name)

            gizmo.on_update(on_update)
            self.gizmos[t.name] = gizmo

    def _publish(self, name):
        gizmo = self.gizmos[name]
        out = self._msg.PoseStamped()
        out.header.frame_id = 'world'
        p, (w, x, y, z) = gizmo.position, gizmo.wxyz
        out.pose.position.x, out.pose.position.y, out.pose.position.z = (float(v) for v in p)
        o = out.pose.orientation
        o.w, o.x, o.y, o.z = float(w), float(x), float(y), float(z)
        self._pubs[name].publish(out)

    def move_target(self, name, position, wxyz=None):
        """Move the gizmo of streamed task ``name`` (as a drag in the page) and publish it."""
        gizmo = self.gizmos[name]
        gizmo.position = np.asarray(position, float)
        if wxyz is not None:
            gizmo.wxyz = np.asarray(wxyz, float)
        self._publish(name)

    def _spin(self):
        last = 0.0
        while not self._stop.is_set() and self._ros.ok():
            self._ros.spin_once(self.node, timeout_sec=0.01)
            if not self._synced and self.remote.ready():
                self._synced = True
                self.remote.get(list(self.controls), self._show_values)
            now = time.monotonic()
            if now - last >= 1 / 30 and self.q is not None:  # at most 30 frames a second
                last = now
                with self.server.atomic():
                    self.draw(self.q, self.q_v)
                    self.draw_targets(self.targets)
                    self.draw_forces(self.forces)
                self.label.content = ('solid: measured q, blue: q_v, axes: targets, green '
                                      'arrows: commanded forces (1 cm/N); drag a gizmo to '
                                      'stream a pose target')
                self.status.content = status_text(self.last_status)

    def close(self):
        """Stop spinning and serving (and the ROS node this cockpit made)."""
        self._stop.set()
        self._spinner.join(timeout=2.0)
        self.server.stop()
        if self._own_node:
            self.node.destroy_node()
            self._ros.shutdown()
