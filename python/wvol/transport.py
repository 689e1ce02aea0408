# SPDX-License-Identifier: MIT
"""Wavelet radiative transfer in Nusselt coordinates (Lewis & Fournier 2002; docs/transport.md).

Radiance on a planar parallelogram is a 4D function of (u, v, k, l): the position in the quad's
parameter space and the direction projected onto the unit disc of its frame, k = (mu_x + 1)/2,
l = (mu_y + 1)/2. Radiance cell arrays are float32 ``(N, N, N, N, 3)`` indexed ``[l, k, v, u, rgb]``
with N = 2**levels: the mean radiance over each cell. A quad is a (4, 3) array of vertices
p0 p1 p2 p3; its normal (p1 - p0) x (p3 - p0) is the side light leaves or arrives from.
"""
import os

import numpy as np

from . import _int, _real, _real_array, _wvol

__all__ = ["QUADRATURES", "haar", "coefficients", "transport", "scene", "window", "power"]

QUADRATURES = ("trapezoid", "romberg1", "romberg2", "romberg3", "monte-carlo", "stratified", "halton", "hammersley")


def haar(cells, threshold=0.0):
    """4D Haar analysis of radiance cells into the hashed coefficient tree (coefficients of
    magnitude <= threshold dropped) and synthesis back: ``(cells, nodes, coefficients)``."""
    return _wvol.transport_haar(_real_array(cells, "cells", np.float32), _real(threshold, "threshold"))


def coefficients(src, dst, j, level, quadrature="trapezoid", samples=16, seed=1):
    """All transport coefficients T_jk from the pure smoothing source basis ``j = (level, mu, mv,
    mk, ml)`` to the destination bases of ``level`` (float64, 16**level values, k's cell index
    u fastest), by the 2D reduction and the named rule."""
    return _wvol.transport_coefficients(_real_array(src, "src"), _real_array(dst, "dst"), tuple(_int(x, "j") for x in j),
                                        _int(level, "level"), quadrature, _int(samples, "samples"),
                                        _int(seed, "seed"))


def transport(cells, src, dst, levels=3, quadrature="trapezoid", samples=16, seed=1, oracle=True):
    """Transports the source's outgoing radiance cells to the destination's incident radiance
    cells (``levels`` levels) by the oracle-driven tree propagation; ``(cells, stats)``."""
    return _wvol.transport_run(_real_array(cells, "cells", np.float32), _real_array(src, "src"), _real_array(dst, "dst"),
                               _int(levels, "levels"), quadrature, _int(samples, "samples"), _int(seed, "seed"),
                               bool(oracle))


def scene(levels=3, quadrature="trapezoid", samples=16, window=None):
    """The stained-glass experiment (§7.3): dict with the ``source``, ``incident`` and
    ``reflected`` cells, transport ``stats`` and the powers (RGB) through window and floor."""
    return _wvol.transport_scene(_int(levels, "levels"), quadrature, _int(samples, "samples"),
                                 os.fspath(window) if isinstance(window, os.PathLike) else window)


def window(path=None):
    """The window image, (H, W, 3) float32 linear RGB: the built-in one, or a PNG's."""
    return _wvol.transport_window(os.fspath(path) if isinstance(path, os.PathLike) else path)


def power(cells, quad):
    """Power through a quad (paper eq. 14): 4 * area * the mean of the cells, per channel (exact for
    radiance that vanishes outside the unit disc: transported and reflected cells)."""
    q = _real_array(quad, "quad")
    c = _real_array(cells, "cells")
    if q.shape != (4, 3):
        raise ValueError(f"quad: expected (4, 3) vertices, got shape {q.shape}")
    if c.ndim < 1 or c.shape[-1] != 3 or c.size == 0:
        raise ValueError(f"cells: expected (..., 3) RGB values, got shape {c.shape}")
    area = np.linalg.norm(np.cross(q[1] - q[0], q[3] - q[0]))
    return 4.0 * area * c.reshape(-1, 3).mean(axis=0)
