# SPDX-License-Identifier: MIT
"""Deterministic synthetic volumes (the C generators of datasets-synth; docs/datasets.md).

Every function takes ``shape=(nz, ny, nx)`` (None: the generator's default size; nz = 1
makes a 2D image), ``spacing=(sx, sy, sz)`` (None: the generator's default), ``seed`` and
``noise`` (sigma of additive Gaussian noise, in the volume's units) and returns a
:class:`wvol.Volume` centred on world (0, 0, 0). The same arguments give the same bytes.
"""
import numpy as np

from . import _wvol
from . import Volume

__all__ = ["gaussian", "blobs", "skull", "textures", "shepp_logan", "turbulence", "kinds", "make"]


def _make(kind, shape, spacing, seed, noise, sigma=0.0, count=0, variant=None):
    data, labels, sp, org = _wvol.synth(kind, shape=None if shape is None else tuple(shape), spacing=spacing,
                                        seed=seed, noise=noise, sigma=sigma, count=count, variant=variant)
    if labels is not None:
        labels = labels.astype(np.int32)   # the library stores class ids as exact small floats
    return Volume(data, sp, org, labels=labels)


def gaussian(shape=None, spacing=None, seed=1, noise=0.0, sigma=0.25):
    """Centred isotropic Gaussian ``exp(-|u|^2 / (2 sigma^2))``, peak 1, ``u`` normalised to
    [-1, 1] across the largest extent (the paper's Fig. 15 density)."""
    return _make("gaussian", shape, spacing, seed, noise, sigma=sigma)


def blobs(shape=None, spacing=None, seed=1, noise=0.0, count=5):
    """Sum of ``count`` (1..64) rotated anisotropic Gaussians drawn from ``seed``."""
    return _make("blobs", shape, spacing, seed, noise, count=count)


def skull(shape=None, spacing=None, seed=1, noise=0.0):
    """Skull-like CT phantom in Hounsfield-like units (air -1000, bone 700..1800).
    ``.labels`` holds the tissue classes (0 air, 1 soft, 2 brain, 3 CSF, 4 bone) as int32."""
    return _make("skull", shape, spacing, seed, noise)


def textures(shape=None, spacing=None, seed=1, noise=0.0, count=4, variant="gratings"):
    """Texture mosaic of ``count`` (2..16) regions, values in [0, 1]; ``variant`` one of
    "gratings", "frequencies", "dots", "mixed". ``.labels`` holds the region ids (int32)."""
    return _make("textures", shape, spacing, seed, noise, count=count, variant=variant)


def shepp_logan(shape=None, spacing=None, seed=1, noise=0.0, variant="kak-slaney"):
    """3D Shepp-Logan phantom (Kak & Slaney's ellipsoids); ``variant`` "kak-slaney" or
    "yu-ye-wang" (higher contrast)."""
    return _make("shepp-logan", shape, spacing, seed, noise, variant=variant)


def turbulence(shape=None, spacing=None, seed=1, noise=0.0):
    """Turbulence-like field: random-phase Fourier modes with a k^(-5/3) energy spectrum from
    the box scale down to 4 voxels, unit variance (docs/datasets.md)."""
    return _make("turbulence", shape, spacing, seed, noise)


def kinds():
    """The generators: a list of (name, one-line description, has_labels)."""
    return _wvol.synth_kinds()


def make(kind, shape=None, spacing=None, seed=1, noise=0.0, **kw):
    """Any generator by its library name ("gaussian", "blobs", "skull", "textures",
    "shepp-logan"); keyword arguments ``sigma``, ``count``, ``variant`` as above."""
    return _make(kind, shape, spacing, seed, noise, **kw)
