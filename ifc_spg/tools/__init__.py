"""Above the runs: the demo, figures and videos of bags, the browser cockpit, sweep figures.

Their command lines are in :mod:`ifc_spg.cli`.
"""
