# SPDX-License-Identifier: MIT
"""Wavelet radiosity (Gortler, Schroeder, Cohen, Hanrahan 1993) of scenes of planar quads.

A scene is a built-in name (``"parallel"``, ``"perpendicular"``, ``"box"``), a Wavefront ``.obj``
path (quads, MTL ``Kd`` reflectance and ``Ke`` emission), or a tuple of arrays
``(quads (n, 4, 3), emission (n, 3), reflectance (n, 3))``. Patch ``i`` maps its parameter
square bilinearly: ``x(u, v) = p0 + u (p1 - p0) + v (p3 - p0) + u v (p0 - p1 + p2 - p3)``.
Errors raise ValueError (bad scenes name the quad and field) or OSError (files).
"""
import os
from typing import NamedTuple, Optional

import numpy as np

from . import _wvol
from . import _int, _real, _real_array, _size

__all__ = ["BASES", "Scene", "Solution", "scene", "solve", "point_form_factor", "gauss_grid", "patch_points"]

BASES = ("haar", "m2", "m3", "m4", "f2", "f3")


class Scene(NamedTuple):
    """The quads of a scene: corners (n, 4, 3), emission (n, 3), reflectance (n, 3), area (n,),
    unit front normal (n, 3)."""
    quads: np.ndarray
    emission: np.ndarray
    reflectance: np.ndarray
    area: np.ndarray
    normal: np.ndarray


class Solution(NamedTuple):
    """What :func:`solve` returns: ``stats`` (interactions, kernel_evaluations, iterations,
    emitted/absorbed power, energy_error, seconds_refine/solve, ...), ``samples`` (n, res, res, 3)
    radiosity at cell centres of each patch, row index v, column u (or None), ``values``
    (n, m, 3) at the given ``uv`` points of every patch (or None), ``image`` (h, w, 4) float32
    linear RGBA rendered from the basis functions (or None)."""
    stats: dict
    samples: Optional[np.ndarray]
    values: Optional[np.ndarray]
    image: Optional[np.ndarray]


def _scene_arg(s):
    if isinstance(s, (str, os.PathLike)):
        return os.fspath(s)
    if isinstance(s, Scene):
        return (s.quads, s.emission, s.reflectance)
    if isinstance(s, bytes) or not hasattr(s, "__len__") or len(s) != 3:
        raise TypeError(f"scene: expected a name, an .obj path or (quads, emission, reflectance), got {s!r}")
    q, e, r = s
    return (_real_array(q, "quads"), _real_array(e, "emission"), _real_array(r, "reflectance"))


def scene(s) -> Scene:
    """The validated quads of a scene (name, .obj path or arrays)."""
    return Scene(*_wvol.radiosity_scene(_scene_arg(s)))


def solve(scene, basis: str = "haar", epsilon: float = 1e-3, max_level: int = 5, brightness: bool = False,
          full_matrix: bool = False, max_iterations: int = 200, tolerance: float = 1e-7, res: int = 0,
          uv=None, camera: Optional[str] = None, size=(256, 256)) -> Solution:
    """Solves the radiosity of ``scene`` with ``basis`` (haar, m2, m3, m4, f2, f3), oracle threshold
    ``epsilon``, finest level ``max_level``; ``brightness`` weights the oracle by the transferred
    brightness; ``full_matrix`` is classical radiosity (every finest cell linked to every other).
    ``res`` > 0 samples each patch on a res x res grid; ``uv`` (m, 2) evaluates every patch at those
    parameter points; ``camera`` (a ``wvol render`` camera string) renders an image of ``size``."""
    uv_arr = None if uv is None else _real_array(uv, "uv")
    d = _wvol.radiosity_solve(_scene_arg(scene), basis, _real(epsilon, "epsilon"), _int(max_level, "max_level"),
                              bool(brightness), bool(full_matrix), _int(max_iterations, "max_iterations"),
                              _real(tolerance, "tolerance"), _int(res, "res"), uv_arr, camera,
                              _size(size))
    samples, values, image = d.pop("samples", None), d.pop("values", None), d.pop("image", None)
    return Solution(d, samples, values, image)


def point_form_factor(s, patch: int, points, normal) -> np.ndarray:
    """Closed-form (Lambert) form factor from points (m, 3) with unit ``normal`` to quad ``patch``,
    without occlusion: the analytic radiosity a unit emitter gives a receiver of reflectance 1."""
    if isinstance(normal, (str, bytes)) or not hasattr(normal, "__len__") or len(normal) != 3:
        raise TypeError(f"normal: expected 3 numbers (x, y, z), got {normal!r}")
    return _wvol.radiosity_point_form_factor(_scene_arg(s), _int(patch, "patch"), _real_array(points, "points"),
                                             tuple(_real(v, "normal") for v in normal))


def gauss_grid(cells: int = 64, n: int = 4):
    """Composite n-point Gauss-Legendre rule on a cells x cells grid of the unit parameter square:
    points (m, 2) as (u, v) and weights (m,) summing to 1 (for L1 errors on a patch)."""
    x, w = np.polynomial.legendre.leggauss(n)
    x, w = (x + 1) / 2, w / 2
    t = ((np.arange(cells)[:, None] + x[None, :]) / cells).ravel()
    wt = np.tile(w, cells) / cells
    u, v = np.meshgrid(t, t, indexing="ij")
    return np.column_stack([u.ravel(), v.ravel()]), np.outer(wt, wt).ravel()


def patch_points(quad, uv) -> np.ndarray:
    """World points (m, 3) of parameter points uv (m, 2) on a quad (4, 3) (the bilinear map)."""
    q = np.asarray(quad, dtype=np.float64)
    uv = np.asarray(uv, dtype=np.float64)
    u, v = uv[:, :1], uv[:, 1:]
    return q[0] + u * (q[1] - q[0]) + v * (q[3] - q[0]) + u * v * (q[0] - q[1] + q[2] - q[3])
