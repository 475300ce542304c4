"""``ifc-spg view``: the viser cockpit of a lockstep bag, through its Python API and in a real
headless browser (Debian's chromium, where installed)."""

import shutil
import socket
import subprocess
import urllib.request

import numpy as np
import pinocchio as pin
import pytest

from ifc_spg.model import RobotModel
from ifc_spg.offline.runner import find_config_dir, load_scenario, run_scenario

viser = pytest.importorskip('viser', reason='viser (requirements.txt) is not installed')

from ifc_spg.tools.view import Cockpit, load_bag  # noqa: E402 - needs viser


def _free_port():
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


@pytest.fixture(scope='module')
def cockpit(tmp_path_factory):
    out = tmp_path_factory.mktemp('view')
    sc = load_scenario(find_config_dir() / 'scenarios' / 'surface_short.yaml',
                       {'duration': 1.2})
    c = Cockpit(load_bag(run_scenario(sc, out, quiet=True).bag), port=_free_port())
    yield c
    c.close()


def test_robot_ghost_and_targets_follow_the_timeline(cockpit):
    robot = RobotModel.from_config('lbr_iiwa14')  # FK of the SPG's model, not the URDF's
    data = robot.create_data()
    bag = cockpit.data
    assert {'link1', 'link7'} <= set(cockpit.links)
    for i in (0, len(bag.t) // 2, len(bag.t) - 1):
        cockpit.slider.value = i  # as the page's slider does
        assert cockpit.index == i
        for tree, q in (('robot', bag.q[i]), ('virtual', bag.q_v[i])):
            pin.framesForwardKinematics(robot.model, data, q)
            for link, handle in zip(cockpit.links, cockpit.handles[tree]):
                M = data.oMf[robot.model.getFrameId(link)]
                np.testing.assert_allclose(handle.position, M.translation, atol=1e-9)
                assert abs(abs(np.dot(handle.wxyz, _wxyz(M.rotation))) - 1) < 1e-9
        # the targets shown are the last /spg/markers at or before that time
        stamp, items = [x for x in bag.targets if x[0] <= bag.t[i] + 1e-9][-1]
        for name, p, _ in items:
            np.testing.assert_allclose(cockpit.target_handles[name].position, p)
    assert not np.allclose(bag.q[0], bag.q[-1])  # the timeline spans a motion


def _wxyz(R):
    x, y, z, w = pin.Quaternion(R).coeffs()
    return np.array([w, x, y, z])


def test_page_is_served_without_internet(cockpit):
    with urllib.request.urlopen(cockpit.url, timeout=10) as r:
        page = r.read().decode()
    assert r.status == 200 and '<html' in page.lower()


CHROMIUM = shutil.which('chromium') or shutil.which('chromium-browser')


def _screenshot(url, path):
    subprocess.run([CHROMIUM, '--headless=new', '--no-sandbox', '--disable-gpu',
                    '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
                    '--window-size=800,600', '--hide-scrollbars',
                    '--virtual-time-budget=3000', f'--screenshot={path}', url],
                   check=True, timeout=120, capture_output=True)
    from PIL import Image

    return np.asarray(Image.open(path).convert('RGB'), dtype=float)


@pytest.mark.skipif(CHROMIUM is None, reason='no chromium (apt-get install chromium)')
def test_a_real_browser_draws_the_robot_and_it_moves(cockpit, tmp_path):
    cockpit.slider.value = 0
    cockpit.playing.value = False
    robots = [_screenshot(cockpit.url, tmp_path / 'first.png')]
    cockpit.slider.value = len(cockpit.data.t) - 1
    robots.append(_screenshot(cockpit.url, tmp_path / 'last.png'))
    for img in robots:  # not a blank canvas: the scene has shaded, coloured pixels
        assert img.std() > 10, img.std()
    diff = np.abs(robots[0] - robots[1]).max(axis=2)
    assert (diff > 30).mean() > 0.001  # the robot moved between the two times
