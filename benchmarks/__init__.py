"""Benchmarks and the soak: timing and long runs of the SPG, outside the installed package.

Run from a checkout: ``ifc-spg bench`` (and ``ifc-spg dynamics bench``) find this folder next
to the ``ifc_spg`` package; each module also runs alone, e.g. ``python -m benchmarks.soak``.
A wheel does not carry them (setup.py packages ``ifc_spg`` and ``sim_bridge`` only).

They share two helpers with the tests, which live there: the closed-loop joint-impedance
plant (``test/plants.py``) and the loopback DDS set-up (``test/ros_testing.py``); importing
this package puts ``test/`` at the end of ``sys.path`` for them.
"""

from pathlib import Path
import sys

_TEST = str(Path(__file__).resolve().parent.parent / 'test')
if _TEST not in sys.path:
    sys.path.append(_TEST)
