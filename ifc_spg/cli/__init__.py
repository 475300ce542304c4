"""The command lines of the package: ``ifc-spg VERB`` and the ``python -m`` tools.

Each verb lives in its own module here (``ifc_spg/cli/VERB.py``) exposing
``main(argv) -> int``: its parser, its printing and its exit status, around library
functions that stay in their layers. This file only dispatches, so ``ifc-spg VERB --help``
is answered by the module that implements VERB. The benchmarks are not part of the package:
``ifc-spg bench`` runs them from the ``benchmarks/`` folder of a checkout (:mod:`.bench`).
"""

from collections.abc import Sequence
import importlib
import sys

__all__ = ['main', 'VERBS']

# verb -> (module, one-line help)
VERBS = {
    'demo': ('ifc_spg.cli.demo', 'run the simulated LBR demo (bridge + SPG, lockstep)'),
    'run': ('ifc_spg.cli.run', 'offline lockstep run of a scenario file'),
    'check': ('ifc_spg.cli.check', 'validate task-stack files'),
    'bag': ('ifc_spg.cli.bag', 'rosbag2 MCAP record | play | info'),
    'replay': ('ifc_spg.cli.replay', 'recompute the SPG output from a bag'),
    'plot': ('ifc_spg.cli.plot', 'figures from a bag'),
    'sweep': ('ifc_spg.cli.sweep', 'run a sweep file: every point, one table, figures'),
    'render': ('ifc_spg.cli.render', 'video of a bag: the robot in its MuJoCo scene'),
    'view': ('ifc_spg.cli.view', 'browser cockpit of a bag: robot at q and q_v, targets'),
    'bench': ('ifc_spg.cli.bench', 'benchmark the SPG tick per solver'),
    'dynamics': ('ifc_spg.cli.dynamics', 'Popov-Vereshchagin solver scenarios'),
    'ros': ('ifc_spg.cli.ros', 'ROS 2 layer tools: talker, listener, topic echo'),
}


def _usage() -> str:
    lines = ['usage: ifc-spg VERB [ARGS...]   (ifc-spg VERB --help for a verb)', '', 'verbs:']
    for verb, (_, text) in VERBS.items():
        lines.append(f'  {verb:<9} {text}')
    return '\n'.join(lines)


def main(argv: Sequence[str] | None = None) -> int:
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

