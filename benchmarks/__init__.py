"""Benchmarks and the soak: timing and long runs of the SPG, outside the installed package.

Run from a checkout: ``ifc-spg bench`` (and ``ifc-spg dynamics bench``) find this folder next
to the ``ifc_spg`` package; each module also runs alone, e.g. ``python -m benchmarks.soak``.
A wheel does not carry them (setup.py packages ``ifc_spg`` and ``sim_bridge`` only).
"""
