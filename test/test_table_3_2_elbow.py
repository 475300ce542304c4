"""Table 3.2's elbow trial (issue 27 item 5): the ball of thesis_3_2_elbow_obstacle.yaml.

Lockstep runs of the scenario (deterministic: no random input) up to the deepest point of the
elbow's path through the ball: without a collision_avoidance level (tasks 1 and 2, the SPG
not told about the ball) the elbow hits it; with the level (the 'avoid' run of
``experiments.reproduce``) q_v keeps the margin and MuJoCo reports no contact.
"""

import numpy as np
import pytest

from experiments import ch3
from experiments.harness import Run, RunSpec
from ifc_spg.errors import ParameterError
from ifc_spg.offline.runner import find_config_dir, load_scenario, run_scenario
from sim_bridge.simulation import Simulation

T_DEEPEST = 5.5  # [s] the elbow's deepest point in the ball on the unobstructed path is ~5.4 s


def _run(variant, tmp_path):
    path = find_config_dir() / 'scenarios' / ch3.ELBOW_SCENARIO
    scenario = load_scenario(path, overrides=ch3._elbow_overrides(variant))
    result = run_scenario(scenario, tmp_path / variant, duration=T_DEEPEST, quiet=True)
    run = Run(RunSpec(variant, ch3.ELBOW_SCENARIO), result)
    run.scenario = scenario
    sim = ch3._elbow_sim(run)
    try:
        return ch3._elbow_numbers(run, sim), result.metrics
    finally:
        sim.close()


@pytest.mark.slow  # two lockstep runs of 5.5 s (about 12 s of CPU)
def test_the_ball_blocks_the_elbow_and_the_avoidance_level_holds_it_off(tmp_path):
    hit, metrics = _run('no_task3', tmp_path)
    assert metrics['geom_contact']['ticks'] == round(T_DEEPEST / 0.002)
    assert hit['elbow_contacts'] > 0 and hit['peak_elbow_force_n'] > 3.0
    assert hit['min_distance_measured_m'] < 0.0
    assert hit['min_distance_virtual_m'] < -0.01  # q_v goes through the ball (not told)
    held, metrics = _run('avoid', tmp_path)
    margin = ch3.ELBOW_AVOID['margin']
    assert held['elbow_contacts'] == 0 and held['peak_elbow_force_n'] == 0.0
    assert held['min_distance_measured_m'] > 0.0
    assert margin - 0.001 <= held['min_distance_virtual_m'] < margin + 0.005  # at the margin
    assert metrics['limit_violations'] == 0
    assert held['position_error_rms_m'] < 0.02 and held['contact_lost_share'] < 0.05


def test_elbow_runs_share_table_3_2_stack():
    """'3b' is the scenario's own stack; the others differ only in task 3 (and the level)."""
    assert ch3._elbow_overrides('3b')['stacks'] == ch3._elbow_scenario()['stacks']
    names = {v: [t['name'] for t in ch3._elbow_overrides(v)['stacks'][-1]['stack']['tasks']]
             for v in ch3.ELBOW_RUNS}
    assert names == {'3b': ['contact_force', 'circle', 'min_torque'],
                     'no_task3': ['contact_force', 'circle'],
                     '3a': ['contact_force', 'circle', 'posture'],
                     'avoid': ['avoid_elbow', 'contact_force', 'circle', 'min_torque']}
    over = ch3._elbow_overrides('avoid')
    ball = ch3._elbow_scenario()['scene_options']
    assert over['stacks'][-1]['stack']['obstacles'] == [
        {'name': 'ball', 'shape': 'sphere', 'radius': ball['ball_radius'],
         'position': ball['ball']}]
    assert over['spg']['solver'] == 'daqp'


def test_ball_option_and_geom_contact_metric_refuse_bad_input():
    for bad in ({'ball': [0.1, 0.2]}, {'ball': [0.1, 0.2, np.nan]},
                {'ball': [0.1, 0.2, 0.3], 'ball_radius': 0.0}):
        with pytest.raises(ParameterError, match='ball'):
            Simulation(robot='lbr4', scene='table', scene_options=bad)
    sim = Simulation(robot='lbr4', scene='table', scene_options={'ball': [0.4, 0.0, 0.9]})
    try:
        with pytest.raises(ParameterError, match="no geom 'link9_geom'.*did you mean"):
            sim.geom_ids(['link9_geom'])
        count, force, dist = sim.geom_contact(sim.geom_ids(ch3.ELBOW_GEOMS),
                                              sim.geom_ids(['ball']))
        assert count == 0 and force == 0.0 and 0.0 < dist < 0.2
    finally:
        sim.close()
    path = find_config_dir() / 'scenarios' / ch3.ELBOW_SCENARIO
    with pytest.raises(ParameterError, match='geom_contact: with'):
        load_scenario(path, overrides={'metrics': [{'geom_contact': {'geoms': ['link3_geom'],
                                                                     'with': 'ball'}}]})
