"""The compiled kernels of the 2 ms path (``ifc_spg.kernels._native``, built from ``_native.c`` at
install time), or None where they were not built.

Each kernel replaces a handful of numpy calls on a few joints or task rows; the numpy code
next to each use is the reference the tests compare it with, and runs wherever the module
is missing. ``IFC_SPG_NATIVE=0`` in the environment selects the numpy code. Objects pick
the implementation when they are created.
"""

import os

__all__ = ['module', 'describe']


def _load():
    if os.environ.get('IFC_SPG_NATIVE', '1').strip() == '0':
        return None
    try:
        from ifc_spg.kernels import _native
    except ImportError:
        return None
    return _native


module = _load()


def describe():
    """'native (C)' or 'numpy (...)': which implementation new objects use, and why."""
    if module is not None:
        return 'native (C kernels)'
    if os.environ.get('IFC_SPG_NATIVE', '1').strip() == '0':
        return 'numpy (IFC_SPG_NATIVE=0)'
    return 'numpy (ifc_spg.kernels._native was not built: reinstall with a C compiler)'
