"""``ifc-spg render``: a bag's motion in its MuJoCo scene, offscreen (EGL), GIF/WebP via Pillow.

Rendered in a child process (``MUJOCO_GL`` is read when MuJoCo is imported). Checks: the
frames are not blank, the image changes where the robot moves (a synthetic bag sweeping
joint A1 by 1 rad) and stays put where nothing moves, the ghost q_v and the force arrow
change pixels, the floor is a checker under the robot with a 10 cm scale bar, and a short
lockstep bag of ``ifc-spg run`` renders in its table scene.
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from ifc_spg.node.config import SpgConfig
from ifc_spg.offline.bag import TOPICS, BagWriter
from ifc_spg.offline.runner import CONFIG_KEY, find_config_dir, load_scenario, run_scenario
from ifc_spg.ros import messages as m

FRAMES = 20
FPS = 25.0


def _render(bag, out, *args):
    env = {**os.environ, 'MUJOCO_GL': os.environ.get('MUJOCO_GL', 'egl')}
    proc = subprocess.run([sys.executable, '-m', 'ifc_spg.cli', 'render', str(bag), '-o',
                           str(out), '--size', '320x240', '--fps', str(FPS), *args],
                          capture_output=True, text=True, env=env, timeout=300)
    if proc.returncode == 2 and 'cannot render offscreen' in proc.stderr:
        pytest.skip(proc.stderr.strip())  # no GL backend on this machine: the message says
    assert proc.returncode == 0, proc.stderr
    return proc


def _frames(path):
    from PIL import Image, ImageSequence

    with Image.open(path) as im:
        return [np.asarray(f.convert('RGB'), dtype=float) for f in ImageSequence.Iterator(im)]


def _sweep_bag(path, ghost_offset=0.0, force=0.0):
    """joint_states (and commands, contact forces) of an iiwa sweeping A1 from 0 to 1 rad."""
    from ifc_spg.model import RobotModel

    robot = RobotModel.from_config('lbr_iiwa14')
    names = list(robot.joint_names)
    q0 = np.array(robot.q_home, dtype=float)
    with BagWriter(path) as w:
        w.set_custom_data(CONFIG_KEY, json.dumps({'robot': 'lbr_iiwa14'}))
        for topic in ('joint_states', 'command/joint_position', 'sim/contact_wrench'):
            w.add_topic('/' + topic, *TOPICS[topic])
        n = int(FRAMES / FPS / 0.002)
        for i in range(n):
            t = i * 2_000_000
            q = q0.copy()
            q[0] += i / (n - 1)
            for topic, pos in (('/joint_states', q), ('/command/joint_position',
                                                      q + ghost_offset)):
                js = m.JointState(name=names, position=pos)
                js.header.stamp = m.Time(sec=t // 1_000_000_000, nanosec=t % 1_000_000_000)
                w.write_msg(topic, t, js)
            ws = m.WrenchStamped()
            ws.header.stamp = m.Time(sec=t // 1_000_000_000, nanosec=t % 1_000_000_000)
            ws.wrench.force.x = force
            w.write_msg('/sim/contact_wrench', t, ws)
    return SpgConfig(robot='lbr_iiwa14')


def test_frames_change_where_the_robot_moves(tmp_path):
    _sweep_bag(tmp_path / 'bag')
    proc = _render(tmp_path / 'bag', tmp_path / 'run.gif', '--no-ghost')
    assert f'{FRAMES}/{FRAMES} frames' in proc.stderr  # progress lines
    frames = _frames(tmp_path / 'run.gif')
    assert len(frames) == FRAMES
    first, last = frames[0], frames[-1]
    assert first.std() > 10 and last.std() > 10  # not a blank frame
    moved = np.abs(first - last).max(axis=2) > 40
    assert moved.mean() > 0.01, moved.mean()      # the arm swung through part of the image
    assert moved.mean() < 0.5, moved.mean()       # ... not the whole image (same camera)
    # consecutive frames differ a little, each
    assert all(np.abs(a - b).max() > 0 for a, b in zip(frames, frames[1:]))


def test_ghost_and_force_arrow_are_drawn(tmp_path):
    _sweep_bag(tmp_path / 'plain')
    _sweep_bag(tmp_path / 'extra', ghost_offset=0.3, force=10.0)
    _render(tmp_path / 'plain', tmp_path / 'plain.webp', '-q')
    _render(tmp_path / 'extra', tmp_path / 'extra.webp', '-q')
    plain, extra = _frames(tmp_path / 'plain.webp'), _frames(tmp_path / 'extra.webp')
    assert len(plain) == len(extra) == FRAMES
    diff = np.abs(plain[5] - extra[5]).max(axis=2) > 30
    assert diff.mean() > 0.005, diff.mean()  # q_v 0.3 rad off: a visible ghost (and arrow)

    def red(img):  # the arrow is emissive red: no robot part has that colour
        return ((img[..., 0] > 180) & (img[..., 1] < 70) & (img[..., 2] < 70)).sum()

    assert red(extra[5]) > 30 and red(plain[5]) == 0, (red(extra[5]), red(plain[5]))


def test_short_lockstep_bag_renders_in_its_scene(tmp_path):
    sc = load_scenario(find_config_dir() / 'scenarios' / 'surface_short.yaml',
                       {'duration': 0.4})
    bag = run_scenario(sc, tmp_path / 'run', quiet=True).bag
    proc = _render(bag, tmp_path / 'run.webp')
    frames = _frames(tmp_path / 'run.webp')
    assert len(frames) == int(0.4 * FPS) and frames[-1].std() > 10
    assert 'frames/s' in proc.stdout


def test_mp4_without_ffmpeg_is_a_clear_error_or_works(tmp_path):
    _sweep_bag(tmp_path / 'bag')
    env = {**os.environ, 'MUJOCO_GL': os.environ.get('MUJOCO_GL', 'egl')}
    proc = subprocess.run([sys.executable, '-m', 'ifc_spg.cli', 'render',
                           str(tmp_path / 'bag'),
                           '-o', str(tmp_path / 'run.mp4'), '--size', '320x240', '-q',
                           '--duration', '0.2'], capture_output=True, text=True, env=env,
                          timeout=300)
    if proc.returncode == 0:
        assert (tmp_path / 'run.mp4').stat().st_size > 1000
    else:
        assert proc.returncode == 2 and 'imageio-ffmpeg' in proc.stderr, proc.stderr


def test_view_turns_the_camera_and_a_bad_view_is_refused(tmp_path):
    """``--view AZIMUTH,ELEVATION``: from above (-89) the same frame is another picture; an
    elevation outside [-90, 90] or a malformed value exits 2 naming the option."""
    _sweep_bag(tmp_path / 'bag')
    _render(tmp_path / 'bag', tmp_path / 'side.gif', '-q', '--duration', '0.1')
    _render(tmp_path / 'bag', tmp_path / 'top.gif', '-q', '--duration', '0.1', '--view=180,-89')
    side, top = _frames(tmp_path / 'side.gif')[0], _frames(tmp_path / 'top.gif')[0]
    assert top.std() > 10 and (np.abs(side - top).max(axis=2) > 40).mean() > 0.02
    for bad in ('180,-100', 'left'):
        proc = subprocess.run([sys.executable, '-m', 'ifc_spg.cli', 'render',
                               str(tmp_path / 'bag'), '-o', str(tmp_path / 'x.gif'),
                               f'--view={bad}'], capture_output=True, text=True, timeout=300)
        assert proc.returncode == 2 and '--view' in proc.stderr, proc.stderr


def test_floor_is_a_checker_with_a_scale_bar(tmp_path):
    """The lower part of the frame (in front of the robot's base, seen from above at 20 deg)
    is floor: grey, not black, alternating light and dark squares along each row; the yellow
    10 cm bar is on it. ``--no-floor`` leaves the same region black."""
    _sweep_bag(tmp_path / 'bag')
    for name, extra in (('floor', ()), ('bare', ('--no-floor',))):  # WebP: no palette
        _render(tmp_path / 'bag', tmp_path / f'{name}.webp', '-q', '--duration', '0.1',
                '--no-ghost', '--size', '640x480', *extra)
    floor, bare = _frames(tmp_path / 'floor.webp')[0], _frames(tmp_path / 'bare.webp')[0]
    h, w, _ = floor.shape
    lower = floor[int(0.8 * h):, int(0.1 * w):int(0.9 * w)]  # below the base, no robot
    assert bare[int(0.8 * h):].max() < 20                   # black without the floor
    grey = lower.mean(axis=2)
    assert (grey > 60).mean() > 0.95, (grey > 60).mean()   # floor everywhere there
    assert np.ptp(lower, axis=2).max() < 40                  # grey: r, g, b alike
    for row in grey[::8]:                                    # light and dark squares
        light = row > 0.5 * (row.min() + row.max())
        assert row.max() - row.min() > 40 and np.count_nonzero(np.diff(light)) >= 4, row
    def yellow(img):
        r, g, b = img[..., 0], img[..., 1], img[..., 2]
        return (r > 160) & (g > 140) & (b < 110)

    bar = (yellow(floor) & ~yellow(bare))[h // 2:]           # the scale bar, on the floor
    assert bar.sum() > 30, bar.sum()
