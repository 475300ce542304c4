"""The arithmetic of the 2 ms path, chosen once at import.

The arithmetic of the 2 ms path, chosen once at import: :data:`active` is the compiled C module
``ifc_spg.kernels._native`` (built from ``_native.c`` at install time), or
:mod:`ifc_spg.kernels.reference` (numpy, the same functions and signatures) where it was not built
or ``IFC_SPG_NATIVE=0`` is set in the environment.

Each kernel replaces a handful of numpy calls on a few joints or task rows. The objects of
the tick (:class:`~ifc_spg.spg.SetPointGenerator`, the cascade, the limits, the energy
tanks) take a ``kernels`` argument (default :data:`active`), so the tests can run the C
module and the reference side by side in one process.
"""

import importlib
import os
from types import ModuleType

from ifc_spg.kernels import reference

__all__ = ['active', 'describe', 'native', 'reference', 'resolve', 'stale']


#: Kernels the reference has and a stale build of the C module lacks (empty: none).
stale: list[str] = []


def _load() -> ModuleType | None:
    try:
        module = importlib.import_module('ifc_spg.kernels._native')
    except ImportError:
        return None
    # a build from an older _native.c lacks the newer kernels: every tick would fail on the
    # first call to one (and the SPG hold), so such a module is not used at all
    stale.extend(name for name in reference.__all__ if not hasattr(module, name))
    return None if stale else module


#: The C module, or None where it was not built or is stale (whatever IFC_SPG_NATIVE says).
native: ModuleType | None = _load()
_disabled = os.environ.get('IFC_SPG_NATIVE', '1').strip() == '0'
#: The kernels new objects use by default.
active: ModuleType = reference if native is None or _disabled else native


def resolve(kernels: ModuleType | None) -> ModuleType:
    """``kernels``, or :data:`active` where it is None (a ``kernels`` argument's default)."""
    return active if kernels is None else kernels


def describe() -> str:
    """'native (C)' or 'numpy (...)': which implementation new objects use, and why."""
    if active is not reference:
        return 'native (C kernels)'
    if _disabled:
        return 'numpy (IFC_SPG_NATIVE=0)'
    if stale:
        return (f"numpy (ifc_spg.kernels._native is a stale build without {', '.join(stale)}: "
                'rebuild it with ./run setup or pip install -e .)')
    return 'numpy (ifc_spg.kernels._native was not built: reinstall with a C compiler)'
