"""Task subspaces S (docs/SPEC.md §2, 3.22): orthonormal columns selecting task directions.

Cartesian subspaces are 6 x m (rows: x y z rx ry rz, or fx fy fz tx ty tz for wrenches),
given in the base frame, the end-effector frame (S_base = diag(R, R) S_ee, Table 4.4) or
with only the rotational part in the end-effector frame (diag(I, R) S_ee, 3.25).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ifc_spg.errors import IfcSpgError, did_you_mean

__all__ = ['AXES', 'WRENCH_AXES', 'SUBSPACE_FRAMES', 'axes_matrix', 'cartesian_subspace',
           'check_orthonormal', 'selected_rows', 'subspace_in_base']

AXES = ('x', 'y', 'z', 'rx', 'ry', 'rz')
WRENCH_AXES = ('fx', 'fy', 'fz', 'tx', 'ty', 'tz')
SUBSPACE_FRAMES = ('base', 'ee', 'ee_orientation')


def axes_matrix(axes: Sequence[str], wrench: bool = False) -> np.ndarray:
    """Return the 6 x m selection matrix of named axes (e.g. ``['y', 'z', 'rx']``)."""
    names = WRENCH_AXES if wrench else AXES
    alias = dict(zip(AXES, WRENCH_AXES)) if wrench else dict(zip(WRENCH_AXES, AXES))
    S = np.zeros((6, len(axes)))
    seen: set[str] = set()
    for k, a in enumerate(axes):
        a = alias.get(a, a)
        if a not in names:
            raise IfcSpgError(f"unknown axis '{a}'{did_you_mean(a, names)}; "
                              f"valid axes: {' '.join(names)}")
        if a in seen:
            raise IfcSpgError(f"axis '{a}' listed twice")
        seen.add(a)
        S[names.index(a), k] = 1.0
    return S


def check_orthonormal(S: Any, tol: float = 1e-6) -> np.ndarray:
    """Raise if the columns of S are not orthonormal (within ``tol``)."""
    S = np.asarray(S, dtype=float)
    if S.ndim != 2 or S.shape[1] == 0:
        raise IfcSpgError(f'subspace must be a non-empty matrix, got shape {S.shape}')
    err = np.abs(S.T @ S - np.eye(S.shape[1])).max()
    if not np.isfinite(err) or err > tol:
        raise IfcSpgError(f'subspace columns must be orthonormal (|S^T S - I| = {err:.3g} > '
                          f'{tol:g}); normalize the columns and make them perpendicular')
    return S


def subspace_in_base(S: np.ndarray, frame: str, R: np.ndarray) -> np.ndarray:
    """Return S expressed in the base frame.

    Args:
        S: 6 x m subspace in ``frame`` coordinates.
        frame: 'base', 'ee' or 'ee_orientation'.
        R: Rotation of the end-effector frame in the base frame (3 x 3).
    """
    if frame == 'base':
        return S
    out = np.empty_like(S)
    out[:3] = S[:3] if frame == 'ee_orientation' else R.dot(S[:3])
    out[3:] = R.dot(S[3:])
    return out


def cartesian_subspace(axes: Sequence[str] | None, subspace: Any, frame: str,
                       wrench: bool = False) -> np.ndarray:
    """Validate a Cartesian task's subspace; return S (6 x m).

    Args:
        axes: Named directions (default all six), or None when ``subspace`` is given.
        subspace: Explicit 6 x m matrix with orthonormal columns, or None.
        frame: The frame S is given in: 'base', 'ee' or 'ee_orientation'.
        wrench: Name the rows ``fx .. tz`` (wrench) instead of ``x .. rz`` (pose).
    """
    names = WRENCH_AXES if wrench else AXES
    if subspace is not None and axes is not None:
        raise IfcSpgError("give either 'axes' or an explicit 'subspace', not both")
    S = axes_matrix(axes or names, wrench=wrench) if subspace is None \
        else check_orthonormal(np.asarray(subspace, dtype=float))
    if S.shape[0] != 6:
        raise IfcSpgError(f"a {'wrench' if wrench else 'Cartesian'} subspace has 6 rows "
                          f"({' '.join(names)}), got {S.shape[0]}")
    if frame not in SUBSPACE_FRAMES:
        raise IfcSpgError(f"subspace frame '{frame}' unknown; use one of "
                          f"{', '.join(SUBSPACE_FRAMES)}")
    return S


def selected_rows(S: np.ndarray, frame: str) -> np.ndarray | None:
    """The rows S^T picks, if S is a selection of base axes; else None.

    For a base-frame S whose every column is a unit axis (what ``axes`` gives), S^T x is
    ``x[rows]`` (the same numbers, without a matrix product); None for other subspaces.
    """
    if frame != 'base':
        return None
    rows = np.argmax(S, axis=0)
    sel = np.zeros_like(S)
    sel[rows, np.arange(S.shape[1])] = 1.0
    return rows.astype(np.intp) if np.array_equal(S, sel) else None
