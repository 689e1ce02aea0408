"""wvol: volume rendering and isosurfaces in wavelet space (Python interface to libwvol).

Arrays are NumPy float32 in C order indexed (z, y, x): ``a[k, j, i]`` is voxel (i, j, k)
of the library (x fastest). 2D images are (y, x). Spacing and origin are given in
(x, y, z) order, like the command line. Errors raise ValueError (bad arguments or
data), OSError (files), MemoryError or NotImplementedError (feature not built).
"""
from dataclasses import dataclass, field

import numpy as np

from . import _wvol

__version__ = _wvol.version

__all__ = ["Volume", "load", "save", "filters", "dwt3", "idwt3", "Coeffs"]


@dataclass
class Volume:
    """A volume with its geometry: ``data`` is (z, y, x) float32; spacing/origin are (x, y, z)."""
    data: np.ndarray
    spacing: tuple = (1.0, 1.0, 1.0)
    origin: tuple = (0.0, 0.0, 0.0)

    def __array__(self, dtype=None):
        return self.data if dtype is None else self.data.astype(dtype)

    @property
    def shape(self):
        return self.data.shape


def _data(vol):
    return vol.data if isinstance(vol, Volume) else vol


def load(path, dims=None, dtype="float32", grid=None, big_endian=False):
    """Reads a volume file (.raw needs ``dims=(nx, ny, nz)``; .nrrd, .vdb, .vti, ... carry theirs).

    Returns a :class:`Volume`.
    """
    data, spacing, origin = _wvol.load(path, dims=dims, dtype=dtype, grid=grid, big_endian=big_endian)
    return Volume(data, spacing, origin)


def save(vol, path, spacing=None, origin=None):
    """Writes a volume (array or :class:`Volume`); the format follows the extension."""
    if isinstance(vol, Volume):
        spacing = vol.spacing if spacing is None else spacing
        origin = vol.origin if origin is None else origin
    _wvol.save(_data(vol), str(path), spacing=spacing, origin=origin)


def filters():
    """The wavelet filters: a list of dicts (name, taps, h, vanishing_moments, defect, center)."""
    return _wvol.filters()


@dataclass
class Coeffs:
    """A multi-level 3D transform in Mallat layout on the padded grid (z, y, x)."""
    data: np.ndarray
    wavelet: str
    levels: int
    shape: tuple = field(default=())


def dwt3(vol, wavelet="db2", levels=3):
    """Forward separable 3D periodic transform; returns :class:`Coeffs`."""
    data, info = _wvol.dwt3(_data(vol), wavelet=wavelet, levels=levels)
    return Coeffs(data, info["wavelet"], info["levels"], info["shape"])


def idwt3(coeffs):
    """Inverse of :func:`dwt3`, cropped back to the original shape."""
    return _wvol.idwt3(coeffs.data, coeffs.wavelet, coeffs.levels, tuple(coeffs.shape))
