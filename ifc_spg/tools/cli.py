"""The ``ifc-spg`` tool: demo, run, sweep, check, bag, replay, plot, bench, dynamics, ros.

Each verb lives in its own module exposing ``main(argv) -> int``; this file only
dispatches, so ``ifc-spg VERB --help`` is answered by the module that implements VERB.
"""

import importlib
import sys

__all__ = ['main', 'VERBS']

# verb -> (module, one-line help)
VERBS = {
    'demo': ('ifc_spg.tools.demo', 'run the simulated LBR demo (bridge + SPG, lockstep)'),
    'run': ('ifc_spg.offline.runner', 'offline lockstep run of a scenario file'),
    'check': ('ifc_spg.task_stack.check', 'validate task-stack files'),
    'bag': ('ifc_spg.offline.bag', 'rosbag2 MCAP record | play | info'),
    'replay': ('ifc_spg.offline.replay', 'recompute the SPG output from a bag'),
    'plot': ('ifc_spg.tools.plot', 'figures from a bag'),
    'sweep': ('ifc_spg.tools.sweep', 'run a sweep file: every point, one table, figures'),
    'render': ('ifc_spg.tools.render', 'video of a bag: the robot in its MuJoCo scene'),
    'view': ('ifc_spg.tools.view', 'browser cockpit of a bag: robot at q and q_v, targets'),
    'bench': ('ifc_spg.tools.bench', 'benchmark the SPG tick per solver'),
    'dynamics': ('ifc_spg.tools.dynamics_cli', 'Popov-Vereshchagin solver scenarios'),
    'ros': ('ifc_spg.ros.tools', 'ROS 2 layer tools: talker, listener, topic echo'),
}


def _usage():
    lines = ['usage: ifc-spg VERB [ARGS...]   (ifc-spg VERB --help for a verb)', '', 'verbs:']
    for verb, (_, text) in VERBS.items():
        lines.append(f'  {verb:<9} {text}')
    return '\n'.join(lines)


def main(argv=None):
    """Entry point of ``ifc-spg``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ('-h', '--help', 'help'):
        print(_usage())
        return 0 if argv else 2
    verb, rest = argv[0], argv[1:]
    if verb not in VERBS:
        print(f"ifc-spg: unknown verb '{verb}'\n\n{_usage()}", file=sys.stderr)
        return 2
    mod = importlib.import_module(VERBS[verb][0])
    return int(mod.main(rest) or 0)


if __name__ == '__main__':
    sys.exit(main())
