"""Strict-priority cascades of QPs: one interface, three solvers."""
