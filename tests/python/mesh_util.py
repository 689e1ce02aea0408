# SPDX-License-Identifier: MIT
"""Mesh measures for the Python tests (NumPy only): area, enclosed volume, closedness."""
import numpy as np


def area(v, f):
    """Surface area (float64)."""
    v = v.astype(np.float64)
    a, b, c = (v[f[:, i]] for i in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()


def enclosed_volume(v, f):
    """Signed volume by the divergence theorem (positive when wound outward)."""
    v = v.astype(np.float64)
    a, b, c = (v[f[:, i]] for i in range(3))
    return np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6


def euler_if_watertight(v, f):
    """V - E + F when every edge is shared by exactly two triangles in opposite directions,
    no triangle repeats a vertex and every vertex is used (a closed, consistently wound
    surface); None otherwise."""
    f = f.astype(np.int64)
    if len(f) == 0 or np.any((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])):
        return None
    if len(np.unique(f)) != len(v):
        return None
    n = len(v)
    src = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    dst = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    key = src * n + dst
    if len(np.unique(key)) != len(key) or not np.isin(dst * n + src, key).all():
        return None
    return len(v) - len(key) // 2 + len(f)
