"""Video of a run: the measured robot of a bag in its MuJoCo scene (``ifc-spg render``).

    ifc-spg render BAG -o run.mp4|run.gif|run.webp [--fps 25] [--size 640x480]
                   [--start S] [--duration S] [--scene NAME] [--no-ghost] [--shadows]
                   [--no-floor]

Each frame shows the recorded ``joint_states`` (positions) at its time, the environment's
joints (doors, drawers: ``sim/env_joint_states``), the contact force on the tool
(``sim/contact_wrench``) as a bright red arrow labelled with its magnitude (2 cm per N, at
the tool, shifted 5 cm towards the camera so the tool does not hide it) and the virtual robot
q_v (``command/joint_position``) as a translucent green ghost. A floor of 10 cm checker
squares (3 m x 3 m around the robot's base, at z = 0 of the world) and a yellow 10 cm scale
bar on it, labelled, let a viewer judge distances. The robot comes from the bag's
SPG configuration (``custom_data`` or ``spg/config``), the scene, its options and q0 (the
scene is anchored at the tool pose of q0) from the run's scenario record (``ifc-spg run``);
a live bag does not know the bridge's scene: pass ``--scene`` (default ``free``).

Rendering is offscreen (``MUJOCO_GL=egl`` unless set: EGL with the GPU or software Mesa,
no display needed). ``.gif`` and ``.webp`` are encoded with Pillow, which holds every frame
until it writes the file (GIF 0.3 MB, WebP 0.9 MB per 640x480 frame: keep them short or small);
``.mp4`` (H.264) is streamed and needs
an ``ffmpeg`` executable: the one ``imageio-ffmpeg`` ships, else ``ffmpeg`` on the PATH.
A progress line is printed every 10 % of the frames.
"""

import json
import math
import os
from pathlib import Path
import shutil
import subprocess
import sys
import time

import numpy as np

from ifc_spg.errors import IfcSpgError, ParameterError
from ifc_spg.offline.bag import BagReader, stamp_ns
from ifc_spg.offline.replay import read_robot_params, read_spg_config, replay_robot
from ifc_spg.offline.runner import SCENARIO_KEY

__all__ = ['RenderResult', 'ffmpeg_exe', 'render']

FORCE_SCALE = 0.02  # [m/N] arrow length per newton
FLOOR_TILE = 0.1  # [m] side of a floor checker square
FLOOR_HALF = 1.5  # [m] half side of the floor, around the robot's base
_GHOST_RGBA = (0.2, 0.9, 0.3, 0.22)
_ARROW_RGBA = (1.0, 0.1, 0.1, 1.0)
_LIGHT_RGBA = (0.62, 0.64, 0.68, 1.0)
_DARK_RGBA = (0.36, 0.38, 0.42, 1.0)
_BAR_RGBA = (1.0, 0.85, 0.1, 1.0)


class RenderResult(dict):
    """What :func:`render` wrote: path, frames, fps, size (w, h), seconds (wall), bytes."""


def _gl_error(exc):
    return IfcSpgError(
        f'cannot render offscreen with MUJOCO_GL={os.environ.get("MUJOCO_GL")!r} ({exc}); '
        'install an EGL or OSMesa backend (Debian/Ubuntu: apt install libegl1 libgl1-mesa-dri '
        'for EGL with software Mesa, or libosmesa6 and MUJOCO_GL=osmesa)')


def _nearest_before(stamps, t):
    """Index of the last stamp <= t (0 if none)."""
    i = int(np.searchsorted(stamps, t, side='right')) - 1
    return max(i, 0)


class _Series:
    """Recorded samples of one topic: stamps [ns] (sorted) and values by joint name."""

    def __init__(self, samples):
        samples.sort(key=lambda s: s[0])
        self.stamps = np.array([s[0] for s in samples], dtype=np.int64)
        self.values = [s[1] for s in samples]

    def __bool__(self):
        return bool(self.values)

    def at(self, t_ns):
        return self.values[_nearest_before(self.stamps, t_ns)]


def _read_bag(path):
    states, commands, wrenches, env, configs = [], [], [], [], []
    with BagReader(path) as bag:
        topics = {t.lstrip('/'): t for t in bag.topics}
        if 'joint_states' not in topics:
            raise ParameterError(f"bag '{path}' has no 'joint_states' topic; topics: "
                                 f"{', '.join(sorted(bag.topics)) or 'none'}")
        wanted = {topics[k] for k in ('joint_states', 'command/joint_position',
                                      'sim/contact_wrench', 'sim/env_joint_states',
                                      'spg/config') if k in topics}
        for topic, _, msg in bag.messages(wanted):
            name = topic.lstrip('/')
            if name == 'spg/config':
                try:
                    configs.append((0, json.loads(msg.data)))
                except json.JSONDecodeError:
                    pass
                continue
            t = stamp_ns(msg.header.stamp)
            if name == 'joint_states':
                states.append((t, dict(zip(msg.name, map(float, msg.position)))))
            elif name == 'command/joint_position':
                commands.append((t, dict(zip(msg.name, map(float, msg.position)))))
            elif name == 'sim/env_joint_states':
                env.append((t, dict(zip(msg.name, map(float, msg.position)))))
            else:
                f = msg.wrench.force
                wrenches.append((t, np.array([f.x, f.y, f.z], dtype=float)))
        config = read_spg_config(bag, [], None, configs)
        params = read_robot_params(bag, [], configs)
        scenario = json.loads(bag.custom_data.get(SCENARIO_KEY, 'null') or 'null')
    return config, params, scenario, _Series(states), _Series(commands), _Series(wrenches), \
        _Series(env)


def _robot_bodies(model, qpos_adr):
    """Bodies moved by the robot's joints (their ghost is drawn)."""
    robot_joints = {j for j in range(model.njnt) if model.jnt_qposadr[j] in set(qpos_adr)}
    moved = set()
    for b in range(model.nbody):
        c = b
        while c > 0:
            start, num = model.body_jntadr[c], model.body_jntnum[c]
            if num > 0 and any(j in robot_joints for j in range(start, start + num)):
                moved.add(b)
                break
            c = model.body_parentid[c]
    return moved


def ffmpeg_exe():
    """The ffmpeg executable MP4 is written with (imageio-ffmpeg's, else the PATH's), or None."""
    try:
        import imageio_ffmpeg  # optional: its wheel ships an ffmpeg

        return imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        return shutil.which('ffmpeg')


def _pillow_writer(path, fps):
    """GIF or WebP frames held by Pillow until close() writes the file."""
    from PIL import Image  # only for .gif/.webp

    gif = path.suffix.lower() == '.gif'
    frames = []

    def write(img):
        frame = Image.fromarray(img)
        if gif:  # 1 byte per pixel from here on (WebP keeps RGB frames)
            frame = frame.quantize(colors=256, method=Image.Quantize.MEDIANCUT)
        frames.append(frame)

    def close():
        if not frames:
            raise ParameterError('no frames to write')
        opts = {'save_all': True, 'append_images': frames[1:],
                'duration': round(1000 / fps), 'loop': 0}
        if gif:
            opts['optimize'] = False
        else:
            opts.update(quality=80, method=4)
        frames[0].save(path, **opts)
        return path.stat().st_size
    return write, close


def _ffmpeg_writer(path, fps, size):
    """H.264 frames streamed to an ffmpeg child process."""
    exe = ffmpeg_exe()
    if exe is None:
        raise ParameterError(f"'{path}': .mp4 needs ffmpeg (pip install imageio-ffmpeg, "
                             'whose wheel ships it, or apt install ffmpeg); .gif and '
                             '.webp need nothing more')
    w, h = size
    proc = subprocess.Popen(
        [exe, '-y', '-loglevel', 'error', '-f', 'rawvideo', '-pix_fmt', 'rgb24', '-s',
         f'{w}x{h}', '-r', f'{fps}', '-i', '-', '-an', '-vcodec', 'libx264', '-pix_fmt',
         'yuv420p', '-crf', '23', str(path)], stdin=subprocess.PIPE)

    stdin = proc.stdin
    if stdin is None:  # stdin=PIPE gives one
        raise IfcSpgError(f"ffmpeg for '{path}' has no input pipe")

    def write(img):
        stdin.write(np.ascontiguousarray(img).tobytes())

    def close():
        stdin.close()
        if proc.wait() != 0:
            raise IfcSpgError(f"ffmpeg failed writing '{path}' (exit {proc.returncode})")
        return path.stat().st_size
    return write, close


def _writer(path, fps, size):
    """A frame sink for ``path`` by suffix: (write(frame), close() -> bytes written)."""
    suffix = path.suffix.lower()
    if suffix in ('.gif', '.webp'):
        return _pillow_writer(path, fps)
    if suffix == '.mp4':
        return _ffmpeg_writer(path, fps, size)
    raise ParameterError(f"'{path}': unknown video format '{suffix}'; choose .mp4, .gif or "
                         '.webp')


class _Scene:
    """The bag's robot in its MuJoCo scene, an offscreen renderer and a camera on the tool.

    Args:
        mujoco: The ``mujoco`` module (imported once ``MUJOCO_GL`` is set).
        sim: The :class:`sim_bridge.simulation.Simulation` of the scene.
        size: (width, height) in pixels.
        view: Camera (azimuth, elevation) in degrees.
        floor: Draw the checker floor and the scale bar (:func:`_floor`).
    """

    def __init__(self, mujoco, sim, size, view=(140.0, -20.0), floor=True):
        self.mj, self.sim = mujoco, sim
        m = self.model = _render_model(mujoco, sim) if floor else sim.model
        self.names = list(sim.joint_names)
        self.qadr = np.array([m.jnt_qposadr[m.joint(j).id] for j in self.names])
        self.env_adr = {j: m.jnt_qposadr[m.joint(j).id] for j in sim.env_joint_names}
        self.data, self.ghost_data = mujoco.MjData(m), mujoco.MjData(m)
        self.ghost_data.qpos[:] = self.data.qpos[:] = sim.data.qpos
        self.moved = _robot_bodies(m, self.qadr)
        self.tool_site = sim.site_id(sim.contact_chain)
        w, h = size
        m.vis.global_.offwidth = max(m.vis.global_.offwidth, w)
        m.vis.global_.offheight = max(m.vis.global_.offheight, h)
        try:
            self.renderer = mujoco.Renderer(m, h, w)
        except Exception as exc:  # noqa: BLE001 -- MuJoCo raises plain errors for GL failures
            raise _gl_error(exc) from None
        self.cam = mujoco.MjvCamera()
        mujoco.mj_forward(m, self.data)
        p_tool = self.data.site_xpos[self.tool_site].copy()
        base = self.data.xpos[m.body_rootid[m.jnt_bodyid[m.joint(self.names[0]).id]]].copy()
        self.cam.lookat[:] = 0.5 * (p_tool + base)
        self.cam.distance = max(1.2, 2.5 * float(np.linalg.norm(p_tool - base)))
        self.cam.azimuth, self.cam.elevation = (float(v) for v in view)
        self.opt = mujoco.MjvOption()
        self.pert = mujoco.MjvPerturb()
        self.floor = _floor(mujoco, m, base, p_tool) if floor else []

    def _add_floor(self, scn):
        """The checker floor and the scale bar (:func:`_floor`), as far as the scene holds."""
        mj = self.mj
        for kind, size, pos, rgba, label, matid in self.floor:
            if scn.ngeom >= scn.maxgeom:
                return
            geom = scn.geoms[scn.ngeom]
            mj.mjv_initGeom(geom, kind, size, pos, _EYE, rgba)
            geom.label, geom.emission = label, 0.3  # readable away from the headlight
            if matid >= 0:  # mjv_initGeom leaves the texture off: take the material's
                geom.matid = matid
                geom.texid = self.model.mat_texid[matid, self.mj.mjtTextureRole.mjTEXROLE_RGB]
                geom.texrepeat[:], geom.texuniform = self.model.mat_texrepeat[matid], 1
            scn.ngeom += 1

    def frame(self, q, env_q, q_v, force, shadows):
        """One image: joints ``q`` and ``env_q`` (name -> value), the ghost, the force arrow.

        Args:
            q: Measured joint positions by name.
            env_q: Environment joint positions by name (None: none recorded).
            q_v: Virtual joint positions by name (None: no ghost).
            force: Contact force (3,) [N] (None: no arrow).
            shadows: Keep shadows and reflections.
        """
        mj, data = self.mj, self.data
        data.qpos[self.qadr] = [q.get(j, 0.0) for j in self.names]
        for j, value in (env_q or {}).items():
            if j in self.env_adr:
                data.qpos[self.env_adr[j]] = value
        mj.mj_kinematics(self.model, data)
        self.renderer.update_scene(data, self.cam)
        scn = self.renderer.scene
        if not shadows:  # software GL: shadows and reflections are half the frame time
            scn.flags[mj.mjtRndFlag.mjRND_SHADOW] = 0
            scn.flags[mj.mjtRndFlag.mjRND_REFLECTION] = 0
        self._add_floor(scn)
        if q_v is not None:
            self._add_ghost(scn, q, q_v)
        if force is not None and scn.ngeom < scn.maxgeom and np.linalg.norm(force) > 0.2:
            self._add_arrow(scn, force)
        return self.renderer.render()

    def _add_ghost(self, scn, q, q_v):
        """The virtual robot as translucent geoms (the rest of the scene hidden)."""
        mj, m, gd = self.mj, self.model, self.ghost_data
        gd.qpos[:] = self.data.qpos
        gd.qpos[self.qadr] = [q_v.get(j, q.get(j, 0.0)) for j in self.names]
        mj.mj_kinematics(m, gd)
        first = scn.ngeom
        mj.mjv_addGeoms(m, gd, self.opt, self.pert, mj.mjtCatBit.mjCAT_DYNAMIC, scn)
        for i in range(first, scn.ngeom):
            g = scn.geoms[i]
            robot_geom = g.objtype == mj.mjtObj.mjOBJ_GEOM and m.geom_bodyid[g.objid] in self.moved
            g.rgba[:] = _GHOST_RGBA if robot_geom else (0.0, 0.0, 0.0, 0.0)
            if robot_geom and g.type != mj.mjtGeom.mjGEOM_MESH:
                g.size[:] = np.asarray(g.size) * 1.03  # no z-fighting where q_v ~ q

    def _add_arrow(self, scn, force):
        """The contact force as an arrow beside the tool (5 cm towards the camera)."""
        mj = self.mj
        p = self.data.site_xpos[self.tool_site].copy()
        side = np.asarray(scn.camera[0].pos, dtype=float) - p
        side[2] = 0.0
        if np.linalg.norm(side) > 1e-6:
            p += 0.05 * side / np.linalg.norm(side)
        geom = scn.geoms[scn.ngeom]
        mj.mjv_initGeom(geom, mj.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3),
                        np.eye(3).reshape(-1), _ARROW_RGBA)
        # the arrow points along the force the environment exerts on the tool
        mj.mjv_connector(geom, mj.mjtGeom.mjGEOM_ARROW, 0.014, p, p + FORCE_SCALE * force)
        geom.emission = 0.6  # lit from inside: red on any background, shadowed or not
        geom.label = f'{np.linalg.norm(force):.1f} N'
        scn.ngeom += 1

    def close(self):
        """Free the renderer and the simulation."""
        self.renderer.close()
        self.sim.close()


_EYE = np.eye(3).reshape(-1)
_FLOOR = 'ifc_render_floor'  # the checker texture and material added for the floor


def _render_model(mujoco, sim):
    """The scene's model with a checker texture and material for the floor (nothing else).

    Compiled from a copy of the simulation's MjSpec: the bodies, joints and geoms (and their
    indices) are the simulation's; the physics model is left alone.

    Raises:
        IfcSpgError: The copy compiles to another structure (then it would not show the bag).
    """
    spec = sim.robot_spec.spec.copy()
    light, dark = (c[:3] for c in (_LIGHT_RGBA, _DARK_RGBA))
    spec.add_texture(name=_FLOOR, type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, width=64, height=64,
                     rgb1=light, rgb2=dark)
    material = spec.add_material(name=_FLOOR, texuniform=True,
                                 texrepeat=[1 / FLOOR_TILE, 1 / FLOOR_TILE])
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = _FLOOR
    model, sim_model = spec.compile(), sim.model
    for size in ('nq', 'nbody', 'njnt', 'ngeom', 'nsite'):
        if getattr(model, size) != getattr(sim_model, size):
            raise IfcSpgError(f'render: the scene with its floor material has {size} '
                              f'{getattr(model, size)}, the simulation '
                              f'{getattr(sim_model, size)}; render with --no-floor')
    return model


def _floor(mujoco, model, base, p_tool):
    """``[(mjtGeom, size, pos, rgba, label, material)]``: a checker floor at z = 0 and a bar.

    The floor is a plane :data:`FLOOR_HALF` around the robot's base, its squares
    :data:`FLOOR_TILE` wide (the material of :func:`_render_model`, -1 where the model has
    none). The bar, :data:`FLOOR_TILE` long and labelled, lies along y on a grid line two
    squares in front of the base, towards the tool.
    """
    cx, cy = (round(float(v) / FLOOR_TILE) * FLOOR_TILE for v in base[:2])
    matid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_MATERIAL, _FLOOR)
    out = [(mujoco.mjtGeom.mjGEOM_PLANE, np.array([FLOOR_HALF, FLOOR_HALF, FLOOR_TILE]),
            np.array([cx, cy, 0.0]), np.array([1.0, 1.0, 1.0, 1.0]), '', matid)]
    ahead = np.asarray(p_tool[:2], float) - np.asarray(base[:2], float)
    norm = float(np.linalg.norm(ahead))
    ahead = ahead / norm if norm > 1e-6 else np.array([1.0, 0.0])
    x0 = cx + FLOOR_TILE * round(2 * ahead[0])
    y0 = cy + FLOOR_TILE * round(2 * ahead[1])
    out.append((mujoco.mjtGeom.mjGEOM_BOX, np.array([0.012, FLOOR_TILE / 2, 0.004]),
                np.array([x0, y0 + FLOOR_TILE / 2, 0.004]), np.array(_BAR_RGBA),
                f'{FLOOR_TILE * 100:g} cm', -1))
    return out


def _frame_span(states, start, duration, fps):
    """``(stamp of the first frame [ns], number of frames)`` of the recorded states."""
    t0 = int(states.stamps[0]) + int(round(start * 1e9))
    t_end = int(states.stamps[-1])
    if duration is not None:
        t_end = min(t_end, t0 + int(round(duration * 1e9)))
    return t0, max(1, int((t_end - t0) * 1e-9 * fps) + 1)


def render(bag, output, fps=25.0, size=(640, 480), start=0.0, duration=None, scene=None,
           ghost=True, quiet=False, stream=None, shadows=False, view=(140.0, -20.0),
           floor=True):
    """Render a bag's recorded motion to ``output`` (.mp4, .gif, .webp).

    Args:
        bag: Bag directory.
        output: Video file to write.
        fps: Frames per second of recorded (stamp) time.
        size: (width, height) in pixels.
        start: Seconds after the first joint state to begin at.
        duration: Seconds to render (None: to the end).
        scene: Scene name (None: the bag's scenario record, else ``free``).
        ghost: Draw the virtual robot q_v.
        quiet: No progress lines.
        stream: Where progress goes (default stderr).
        shadows: Render shadows and reflections (slower on software GL).
        view: Camera (azimuth, elevation) in degrees (-90 elevation looks straight down).
        floor: Draw the checker floor (10 cm squares) and the 10 cm scale bar.

    Returns:
        :class:`RenderResult`.
    """
    os.environ.setdefault('MUJOCO_GL', 'egl')
    import mujoco  # after MUJOCO_GL: it picks the GL backend on import

    from sim_bridge.simulation import SimConfig, Simulation

    stream = stream or sys.stderr
    output = Path(output)
    if not fps > 0:
        raise ParameterError(f'--fps must be > 0, got {fps}')
    config, params, scenario, states, commands, wrenches, env = _read_bag(bag)
    if not states:
        raise ParameterError(f"bag '{bag}' has no joint states to render")
    scenario = scenario or {}
    robot, _, _ = replay_robot(config, params, where=f"bag '{bag}'")
    sim = Simulation(SimConfig(
        robot=robot, interface=scenario.get('interface'),
        scene=scene or scenario.get('scene') or 'free',
        scene_options=scenario.get('scene_options') or {}, q0=scenario.get('q0')))
    w, h = int(size[0]), int(size[1])
    if len(view) != 2 or not all(math.isfinite(float(v)) for v in view) or \
            not -90.0 <= float(view[1]) <= 90.0:
        raise ParameterError(f'--view must be AZIMUTH,ELEVATION in degrees with the elevation '
                             f'in [-90, 90], got {view}')
    view = _Scene(mujoco, sim, (w, h), view, floor)
    t0, n_frames = _frame_span(states, start, duration, fps)
    write, close = _writer(output, fps, (w, h))
    wall = time.monotonic()
    every = max(1, n_frames // 10)
    for k in range(n_frames):
        t = t0 + int(round(k * 1e9 / fps))
        write(view.frame(states.at(t), env.at(t) if env else None,
                         commands.at(t) if ghost and commands else None,
                         wrenches.at(t) if wrenches else None, shadows))
        if not quiet and ((k + 1) % every == 0 or k + 1 == n_frames):
            el = time.monotonic() - wall
            print(f'render: {k + 1}/{n_frames} frames ({100 * (k + 1) // n_frames}%), '
                  f'{(k + 1) / el:.1f} frames/s', file=stream, flush=True)
    view.close()
    size_b = close()
    return RenderResult(path=str(output), frames=n_frames, fps=fps, size=(w, h),
                        seconds=time.monotonic() - wall, bytes=size_b)
