"""MuJoCo bridge: robots, scenes and emulated IFC interfaces (LBR FRI, iCub, ACCREA)."""

from sim_bridge.interface import FakeInterface, RobotInterface, State
from sim_bridge.scenes import SCENES, scene_names
from sim_bridge.simulation import INTERFACES, SimConfig, Simulation

__all__ = ['INTERFACES', 'SCENES', 'FakeInterface', 'RobotInterface', 'SimConfig', 'Simulation',
           'State', 'scene_names']
