"""The shipped ACCREA self-collision stack (config/tasks/table_4_1_accrea_self_collision.yaml):
the two tools are sent through each other; the collision_avoidance level holds every
self pair at its margin, and without it the tools pass through each other. Kinematic
closed loop (q = q_v), distances checked with coal over all 218 self pairs, independently
of the SPG's cull."""

from pathlib import Path

from helpers import self_collision_run
import numpy as np
import pytest
import yaml

from ifc_spg import RobotModel

STACK = Path(__file__).resolve().parent.parent / 'config' / 'tasks' / \
    'table_4_1_accrea_self_collision.yaml'
DT, TICKS = 0.002, 1600  # 3.2 s: the reach takes 3 s


@pytest.fixture(scope='module')
def robot():
    return RobotModel.from_config('accrea_dual_arm')


def _run(robot, avoid):
    return self_collision_run(robot, STACK, ('l_tool', 'r_tool'), TICKS, DT, avoid=avoid)


def test_the_hands_meet_at_the_margin_and_never_closer(robot):
    margin = yaml.safe_load(STACK.read_text())['tasks'][0]['margin']
    worst, inside, (left, right), spg = _run(robot, avoid=True)
    assert inside and spg.info.status == 'ok', spg.info.message
    assert worst >= margin - 1e-3, worst
    assert worst <= margin + 2e-3, worst  # the level was engaged: it held a pair at d_s
    # the tools came together (from 0.67 m apart) instead of stopping early
    assert np.linalg.norm(left - right) <= 0.1, (left, right)


def test_without_the_level_the_tools_pass_through_each_other(robot):
    worst, inside, (left, right), _ = _run(robot, avoid=False)
    assert inside
    assert worst < 0.0, worst  # overlapping shapes
    assert left[1] < right[1]  # crossed: the left tool ends to the right of the right one
