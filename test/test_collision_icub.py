"""The shipped iCub self-collision stack (config/tasks/table_4_1_icub_self_collision.yaml):
the two hands are sent through each other; the collision_avoidance level holds every self
pair (the convex hulls of the URDF's collision meshes) at its margin, and without it the
hands pass through each other. Kinematic closed loop (q = q_v), distances checked with coal
over all 564 self pairs, independently of the SPG's cull."""

from pathlib import Path

import coal
from helpers import self_collision_run
import numpy as np
import pytest
import yaml

from ifc_spg import RobotModel
from ifc_spg.geometry import CollisionGeometry
from ifc_spg.pspm import PspmConfig

ROOT = Path(__file__).resolve().parent.parent
STACK = ROOT / 'config' / 'tasks' / 'table_4_1_icub_self_collision.yaml'
#: the iCub's shipped PSPM parameters (the stack asks for a power budget below max_power)
PSPM = PspmConfig(**{k: v for k, v in yaml.safe_load(
    (ROOT / 'config' / 'icub_upper_body.yaml').read_text())['/**']['ros__parameters']['pspm']
    .items() if k != 'enabled'})
DT, TICKS = 0.002, 1250  # 2.5 s: the reach takes 2 s


@pytest.fixture(scope='module')
def robot():
    return RobotModel.from_config('icub_upper_body')


def test_the_geometry_is_the_convex_hulls_of_the_urdf_meshes(robot):
    geometry = CollisionGeometry(robot)
    shapes = [o.geometry for o in geometry.model.geometryObjects]
    assert len(shapes) == 39  # 37 meshes, the two feet's boxes
    assert sum(isinstance(g, coal.ConvexBase) for g in shapes) == 37
    assert len(geometry.self_pairs()) == 564
    excluded = {(a, b) for a, b, _ in geometry.excluded}
    assert ('l_hand_0', 'r_hand_0') not in excluded and ('chest_0', 'l_hand_0') not in excluded
    assert ('l_forearm_0', 'l_hand_0') in excluded  # touching at q_home
    # the hulls are built once per process: a second geometry, also of a second model of
    # the same robot, shares them
    again = RobotModel.from_config('icub_upper_body')
    assert CollisionGeometry(again).model.geometryObjects[0].geometry is shapes[0]


def _run(robot, avoid):
    return self_collision_run(robot, STACK, ('l_hand', 'r_hand'), TICKS, DT, avoid=avoid,
                              pspm=PSPM)


def test_the_hands_meet_at_the_margin_and_never_closer(robot):
    margin = yaml.safe_load(STACK.read_text())['tasks'][0]['margin']
    worst, inside, (left, right), spg = _run(robot, avoid=True)
    assert inside and spg.info.status == 'ok', spg.info.message
    assert worst >= margin - 1e-3, worst
    assert worst <= margin + 2e-3, worst  # the level was engaged: it held a pair at d_s
    # the hands came together (from 0.39 m apart) instead of stopping early
    assert np.linalg.norm(left - right) <= 0.05, (left, right)


def test_without_the_level_the_hands_pass_through_each_other(robot):
    worst, inside, (left, right), _ = _run(robot, avoid=False)
    assert inside
    assert worst < -0.03, worst  # overlapping shapes
    assert np.linalg.norm(left - right) <= 0.01, (left, right)  # the hand frames met
