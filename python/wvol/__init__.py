# SPDX-License-Identifier: MIT
"""wvol: volume rendering and isosurfaces in wavelet space (Python interface to libwvol).

Arrays are NumPy float32 in C order indexed (z, y, x): ``a[k, j, i]`` is voxel (i, j, k)
of the library (x fastest). 2D images are (y, x). Spacing and origin are given in
(x, y, z) order, like the command line. Errors raise ValueError (bad arguments or
data), OSError (files), MemoryError or NotImplementedError (feature not built).
"""
import math
import numbers
import operator
import os
import zlib
from dataclasses import dataclass, field
from typing import NamedTuple, Optional

import numpy as np

from . import _wvol

__version__ = _wvol.version

__all__ = ["Volume", "load", "save", "filters", "dwt3", "idwt3", "Coeffs", "compress", "Store", "ErrorEstimate",
           "synth", "segment", "Segmentation", "features", "open", "wvc_info", "wvc_region", "render", "RenderContext",
           "render_progressive", "isosurface", "isoimage",
           "save_mesh"]


@dataclass
class Volume:
    """A volume with its geometry: ``data`` is (z, y, x) float32; spacing/origin are (x, y, z)
    world units (sample ``data[k, j, i]`` sits at ``origin + (i, j, k) * spacing``).
    ``labels`` (optional, int32, same shape) is a ground-truth label map (synthetic volumes)."""
    data: np.ndarray
    spacing: tuple = (1.0, 1.0, 1.0)
    origin: tuple = (0.0, 0.0, 0.0)
    labels: Optional[np.ndarray] = None

    def __array__(self, dtype=None, copy=None):
        """``np.asarray(volume)`` is its data (no copy unless a dtype conversion is asked)."""
        return self.data if dtype is None else self.data.astype(dtype)

    @property
    def shape(self):
        return self.data.shape


def _data(vol):
    """The samples of a volume argument; a Store or Coeffs where a volume is expected is named as
    such (NumPy would otherwise refuse it as an array of dtype object)."""
    if isinstance(vol, (Store, Coeffs)):
        raise TypeError(f"expected a volume (a NumPy array or wvol.Volume), got a wvol.{type(vol).__name__}")
    return vol.data if isinstance(vol, Volume) else vol


def _fingerprint(arr):
    """CRC-32 of an array's samples in C order (about 7 GB/s: a small share of a compression)."""
    return zlib.crc32(np.ascontiguousarray(arr))


def load(path, dims=None, dtype="float32", grid=None, big_endian=False, spacing=None, origin=None):
    """Reads a volume file (.raw needs ``dims=(nx, ny, nz)``, and takes ``spacing`` and ``origin``,
    (x, y, z) or one number, default 1 and 0; .nrrd, .vdb, .vti, ... carry theirs, and giving
    them for such a file is refused, as the command line refuses them; ``grid`` names a .vdb's).

    Returns a :class:`Volume`.
    """
    name = os.fsdecode(path) if isinstance(path, (str, bytes, os.PathLike)) else None
    if name is not None:
        raw = name.lower().endswith((".raw", ".bin"))
        given = [k for k, v in (("dims", dims is not None), ("dtype", dtype != "float32"),
                                ("big_endian", bool(big_endian)), ("spacing", spacing is not None),
                                ("origin", origin is not None)) if v]
        if given and not raw:  # they were ignored: a file's own geometry wins
            raise ValueError(f"{given[0]} describes raw input (.raw, .bin): {name} carries its own")
        if grid is not None and not name.lower().endswith(".vdb"):
            raise ValueError(f"grid names a grid of an OpenVDB file: {name} is not a .vdb")
    data, spacing, origin = _wvol.load(path, dims=dims, dtype=dtype, grid=grid, big_endian=big_endian,
                                       spacing=spacing, origin=origin)
    return Volume(data, spacing, origin)


def save(vol, path, spacing=None, origin=None):
    """Writes a volume (array or :class:`Volume`); the format follows the extension."""
    if isinstance(vol, Volume):
        spacing = vol.spacing if spacing is None else spacing
        origin = vol.origin if origin is None else origin
    _wvol.save(_data(vol), os.fsdecode(path), spacing=spacing, origin=origin)


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
    """Forward separable 3D periodic transform (float32 arithmetic, edge-replicate padding
    to multiples of ``2**levels``); returns :class:`Coeffs`. ``wavelet`` is a name of
    :func:`filters` ("haar", "db1".."db10", "coif1".."coif5", "bl3")."""
    data, info = _wvol.dwt3(_data(vol), wavelet=wavelet, levels=_int(levels, "levels"))
    return Coeffs(data, info["wavelet"], info["levels"], info["shape"])


def idwt3(coeffs):
    """Inverse of :func:`dwt3`, cropped back to the original shape (a (z, y, x) array)."""
    return _wvol.idwt3(coeffs.data, coeffs.wavelet, coeffs.levels, tuple(coeffs.shape))


# ---- compression: selection of coefficients, the store ---------------------------------

class ErrorEstimate(NamedTuple):
    """Reconstruction error: ``l2`` = ||f - f~||_2 over the voxels, ``rmse`` = l2 / sqrt(voxels),
    ``psnr`` in dB with peak = data range (inf when nothing is lost), ``max`` = max |f - f~|
    (None for predictions, which come from Parseval and carry no maximum)."""
    l2: float
    rmse: float
    psnr: float
    max: Optional[float] = None


def _real(v, name):
    """v as a float; a string, a bool or anything that is not a real number is refused (a
    string would otherwise pass as a sequence of its characters)."""
    if isinstance(v, (str, bytes, bool, np.bool_)) or not isinstance(v, (numbers.Real, np.floating, np.integer)):
        raise TypeError(f"{name}: expected a real number, got {v!r}")
    return float(v)


def _real_array(v, name, dtype=np.float64):
    """An array argument of real numbers as ``dtype``: complex, string, object and bool arrays are
    refused (np.asarray(..., float) would drop an imaginary part with a warning, or parse text)."""
    a = np.asarray(v)
    if a.dtype.kind not in "iuf":
        raise TypeError(f"{name}: expected real numbers, got an array of {a.dtype}")
    return np.ascontiguousarray(a, dtype=dtype)


def _triple(v, name, default):
    """A geometry argument: None (the default), one number for all three axes, or 3 numbers (x, y, z)."""
    if v is None:
        return default
    if isinstance(v, (numbers.Real, np.floating, np.integer)) and not isinstance(v, (bool, np.bool_)):
        return (float(v),) * 3
    if isinstance(v, (str, bytes)) or not hasattr(v, "__len__"):
        raise TypeError(f"{name}: expected a number or 3 numbers (x, y, z), got {v!r}")
    if len(v) != 3:
        raise ValueError(f"{name}: expected 3 values (x, y, z), got {len(v)}")
    return tuple(_real(x, name) for x in v)


def _ints(v, name, form):
    """A fixed-length tuple of ints, ``form`` naming it ("(width, height)", "(x, y, z)"): floats,
    strings and bools are refused, not truncated or read as characters."""
    count = form.count(",") + 1
    if isinstance(v, (str, bytes)) or not hasattr(v, "__len__"):
        raise TypeError(f"{name}: expected {form}, {count} ints, got {v!r}")
    if len(v) != count:
        raise ValueError(f"{name}: expected {form}, {count} ints, got {len(v)} values")
    out = []
    for x in v:
        if isinstance(x, (bool, np.bool_)):
            raise TypeError(f"{name}: expected ints, got {x!r}")
        try:
            out.append(operator.index(x))
        except TypeError:
            raise TypeError(f"{name}: expected ints, got {x!r}") from None
    return tuple(out)


def _int(v, name):
    """One int: floats, strings and bools are refused, not truncated or parsed (numpy ints pass)."""
    if isinstance(v, (bool, np.bool_)):
        raise TypeError(f"{name}: expected an int, got {v!r}")
    try:
        return operator.index(v)
    except TypeError:
        raise TypeError(f"{name}: expected an int, got {v!r}") from None


def _threads(v, name="threads"):
    """A thread count, 0..4096 (0: OpenMP's default), as the command line's --threads."""
    v = _int(v, name)
    if not 0 <= v <= 4096:
        raise ValueError(f"{name} must be in 0..4096 (0: all), got {v}")
    return v


def _lod_level(v):
    """render's lod_level: a level >= 0 (None, not -1, asks for the automatic choice)."""
    v = _int(v, "lod_level")
    if v < 0:
        raise ValueError(f"lod_level {v}: a level >= 0 (None: chosen from the pixel footprint)")
    return v


def _size(size, name="size"):
    """(width, height) in pixels."""
    return _ints(size, name, "(width, height)")


def _geometry(vol, spacing, origin):
    if isinstance(vol, Volume):
        spacing = vol.spacing if spacing is None else spacing
        origin = vol.origin if origin is None else origin
    return _triple(spacing, "spacing", (1.0, 1.0, 1.0)), _triple(origin, "origin", (0.0, 0.0, 0.0))


def _psnr(l2, n, peak):
    if l2 == 0:
        return math.inf
    if not peak > 0:
        return math.nan
    return 20.0 * math.log10(peak / (l2 / math.sqrt(n)))


def _box_bounds(box, shape):
    """Box as (z, y, x) slices or (start, stop) pairs -> lo, hi in (x, y, z) order."""
    if len(box) != 3:
        raise ValueError(f"box must give 3 ranges (z, y, x), got {len(box)}")
    lo, hi = [], []
    for ax, (r, n) in enumerate(zip(box, shape)):
        if isinstance(r, slice):
            if r.step not in (None, 1):
                raise ValueError("box slices must have step 1")
            start, stop, _ = r.indices(n)
        else:
            start, stop = _ints(r, "box", "(start, stop)")
        if not 0 <= start < stop <= n:
            raise ValueError(f"box: axis {'zyx'[ax]} range [{start}, {stop}) must be non-empty and inside [0, {n})")
        lo.append(start)
        hi.append(stop)
    return tuple(lo[::-1]), tuple(hi[::-1])


class Store:
    """Compressed wavelet representation of a volume: the kept coefficients of a
    ``levels``-level transform (the others are zero), made by :func:`compress` or read by
    :func:`open`. It holds the library's own objects (a ``_wvol.StoreHandle``: the
    coefficients, the kept set and the C store, built once by the compression pipeline), so
    renders, meshes, reconstructions and files read them in place.

    Attributes: ``coeffs`` (padded Mallat array, (z, y, x), dropped coefficients zero; a
    read-only view of the library's array), ``wavelet``, ``levels``, ``shape`` (original
    (z, y, x)), ``spacing`` / ``origin`` ((x, y, z) world units), ``kept`` and ``total``
    (coefficient counts, the low-pass cube included in ``kept``), ``value_range`` (min, max of
    the original samples), ``report`` (the selection's numbers, a dict).
    """

    def __init__(self, handle, report, original=None, file_info=None):
        # the handle and its report change together (the coeffs setter): one attribute, so a
        # thread reading them while another replaces the coefficients sees one pair or the other
        self._state = (handle, report)
        meta = handle.meta
        self.wavelet = meta["wavelet"]
        self.levels = int(meta["levels"])
        self.shape = tuple(int(v) for v in meta["shape"])
        self.spacing = tuple(meta["spacing"])
        self.origin = tuple(meta["origin"])
        self.value_range = tuple(meta["value_range"])
        self.file_info = file_info
        self._original = original
        self._original_crc = None if original is None else _fingerprint(original)

    def __repr__(self):
        pred = ("coefficients replaced" if self.report.get("replaced") else
                f"predicted PSNR {self.predicted_error.psnr:.2f} dB")
        return f"<wvol.Store {self.wavelet} levels={self.levels} shape={self.shape} kept={self.kept}/{self.total} {pred}>"

    @property
    def _handle(self):
        return self._state[0]

    @property
    def report(self):
        """The selection's numbers (a dict)."""
        return self._state[1]

    @property
    def coeffs(self):
        """The coefficients: padded Mallat array (z, y, x), dropped ones zero. A read-only view
        of the library's array (no copy); assign a new array to replace them."""
        return self._handle.coeffs

    @coeffs.setter
    def coeffs(self, array):
        # a new handle over a copy (checked: the padded grid's size, finite values); the
        # store, reconstructions and files then follow the new coefficients
        handle, report = self._state
        handle = handle.replace_coeffs(array)
        # the selection's numbers no longer describe the store: its count is the new array's,
        # and what it dropped from the original is unknown (predicted_error refuses)
        self._state = (handle, dict(report, kept=int(handle.info()["kept"]), replaced=True))

    @property
    def kept(self):
        """Kept coefficients, the low-pass cube included."""
        return int(self.report["kept"])

    @property
    def total(self):
        """All coefficients of the padded grid."""
        return int(self.report["total"])

    @property
    def voxels(self):
        """Samples of the original grid."""
        return int(np.prod(self.shape))

    @property
    def peak(self):
        """Data range used for PSNR."""
        return float(self.value_range[1] - self.value_range[0])

    @property
    def predicted_error(self):
        """:class:`ErrorEstimate` from Parseval: the energy of what was dropped (and, for a
        store read from a .wvc file, the quantisation error its header records), plus, for a
        volume on a large offset, what float32 rounding adds there (the selection's
        ``predicted_l2``). Over the padded grid, so an upper bound of the error over the original
        voxels. A store whose coefficients were replaced (``coeffs = ...``) has no prediction:
        ValueError."""
        if self.report.get("replaced"):
            raise ValueError("predicted_error: the coefficients were replaced, so what was dropped is unknown; "
                             "use measured_error()")
        l2 = self.report.get("predicted_l2")
        if l2 is None:
            l2 = math.sqrt(max(self.report["energy_dropped"], 0.0))
        return ErrorEstimate(l2, l2 / math.sqrt(self.voxels), _psnr(l2, self.voxels, self.peak))

    def measured_error(self, original=None):
        """:class:`ErrorEstimate` of the full reconstruction against ``original`` (array or
        :class:`Volume`; default: the volume this store was compressed from, when known)."""
        ref = self._original if original is None else _data(original)
        if ref is None:
            raise ValueError("measured_error: no original volume (pass original=...)")
        if original is None and _fingerprint(ref) != self._original_crc:
            raise ValueError("measured_error: the array this store was compressed from has changed since "
                             "(pass the original as measured_error(original=...))")
        ref = np.asarray(ref)
        if ref.dtype.kind not in "iuf":
            raise TypeError(f"measured_error: original must hold real numbers, got dtype {ref.dtype}")
        # a 2D (y, x) array for a store of shape (1, y, x): the same samples; no other reshaping
        if ref.shape != self.shape and [d for d in ref.shape if d != 1] == [d for d in self.shape if d != 1]:
            ref = ref.reshape(self.shape)
        if ref.shape != self.shape:
            raise ValueError(f"measured_error: original shape {ref.shape} differs from the store's {self.shape}")
        if not np.all(np.isfinite(ref)):
            raise ValueError("measured_error: original holds NaN or Inf")
        diff = self.reconstruct().data.astype(np.float64) - ref.astype(np.float64)
        l2 = float(np.sqrt(np.sum(diff * diff)))
        peak = float(ref.max()) - float(ref.min())
        return ErrorEstimate(l2, l2 / math.sqrt(self.voxels), _psnr(l2, self.voxels, peak),
                             float(np.abs(diff).max()))

    def info(self):
        """Numbers of the C store (sparse octree of the kept coefficients): ``kept``,
        ``nodes``, ``bytes`` (memory it holds), ``bytes_per_coeff``, ``basis_bytes``
        (spline tables), ``spline_j``..."""
        return self._handle.info()

    @property
    def bytes_per_coeff(self):
        """Memory of the C store per kept coefficient (octree, masks, values, bounds)."""
        return float(self.info()["bytes_per_coeff"])

    def evaluate(self, points):
        """The continuous model f^ (sum of the kept coefficients' spline basis functions) at
        world positions ``points`` ((n, 3), (x, y, z) order); returns ``(values (n,),
        gradients (n, 3))`` in world units."""
        return self._handle.evaluate(np.atleast_2d(np.asarray(points)))  # real dtypes only (checked there)

    def reconstruct(self, level=None, box=None):
        """Reconstructs a :class:`Volume` from the kept coefficients.

        ``level=None`` (or 0): the full-resolution volume. ``level=s`` (1..levels): the
        coarser level-s volume, ``ceil(n / 2**s)`` samples per axis, spacing ``* 2**s``,
        values comparable with the samples (docs/wavelets.md). ``box``: only that brick of
        the full-resolution volume, given as (z, y, x) slices or (start, stop) pairs, e.g.
        ``np.s_[0:8, 4:20, :]``; it equals ``reconstruct().data[box]`` to float32 rounding
        and is computed from only the coefficients that reach it.
        """
        if box is not None and level not in (None, 0):
            raise ValueError("reconstruct: give level or box, not both")
        if box is not None:
            lo, hi = _box_bounds(box, self.shape)
            data, origin = self._handle.reconstruct_box(lo, hi)
            return Volume(data, self.spacing, origin)
        if level in (None, 0):
            return Volume(self._handle.reconstruct()[0], self.spacing, self.origin)
        if not isinstance(level, (int, np.integer)):
            raise TypeError(f"level must be an integer, got {type(level).__name__}")
        data, spacing, origin = self._handle.reconstruct(_int(level, "level"))
        return Volume(data, spacing, origin)

    def save(self, path, quant_share=None, step=None):
        """Writes the kept coefficients to a .wvc file (quantised with a dead-zone step and
        entropy-coded per sub-band; docs/wvc-format.md) with the library's quantiser rule
        (wvol_compress_encode, as ``wvol compress``): the step makes quantisation add
        ``quant_share`` (in (0, 1]; None: the library's 0.02) of the squared error the
        selection dropped, never less than what 120 dB PSNR allows, unless ``step`` is given.
        Atomic: no partial file. Returns the encoder's report (step, sse_quant, nonzero, bytes)."""
        share = None if quant_share is None else _real(quant_share, "quant_share")
        return self._handle.save(os.fspath(path), quant_share=share, step=None if step is None else _real(step, "step"))


_MODES = ("keep", "keep_count", "energy", "psnr", "threshold")


def compress(vol, wavelet="db2", levels=None, *, keep=None, keep_count=None, energy=None, psnr=None,
             threshold=None, roi=None, roi_floor=0.1, drop_levels=0, spacing=None, origin=None, residual=False):
    """Transforms a volume and keeps its most important coefficients; returns a :class:`Store`.
    One call of the library's compression pipeline (wvol_compress: transform, selection, store).

    ``vol``: a (z, y, x) array or a :class:`Volume` (float32 C-order arrays are read in place).
    ``wavelet``: a filter name (default ``"db2"``, the library's and ``wvol render``'s: the store is
    what renders, and its work grows with the filter's support) or ``"auto"``: a trial on a sample
    of the volume keeps db2 unless db4, coif2 or haar is estimated to take more than 10% fewer bits
    at the target (``psnr`` if given, else 50 dB), as ``wvol compress`` does for a file
    (docs/wvc-format.md, "Choosing the filter"); ``store.wavelet`` names the filter chosen.
    ``levels``: None for the library's default (3, fewer when the volume is too small for 3).
    At most one criterion (none: keep every coefficient):

    - ``keep=0.05``: the largest 5% of all coefficients;
    - ``keep_count=K``: the K largest (the low-pass cube counts);
    - ``energy=0.999``: the fewest whose energy is 99.9% of the total;
    - ``psnr=50``: drop the most that keep the predicted PSNR (peak = data range) >= 50 dB;
    - ``threshold=t``: those with weighted magnitude > t.

    ``roi``: regions of interest, a list of ``(center, radii)`` or ``(center, radii, power)``
    with center and radii in (x, y, z) world units: coefficients are ranked by
    ``|c| * w`` with ``w = roi_floor + (1 - roi_floor) * max G(x)`` over the Gaussian
    ellipsoids G (super-Gaussian for power > 1). ``drop_levels``: the finest levels dropped
    entirely. Ranking is by magnitude; the low-pass cube is always kept.
    ``residual=True`` also keeps what the selection dropped (as |c| on the majorants of the
    basis functions), so that :func:`render` can return a per-pixel error bound (``bound=True``).
    """
    given = [(n, v) for n, v in zip(_MODES, (keep, keep_count, energy, psnr, threshold)) if v is not None]
    if len(given) > 1:
        raise ValueError("compress: give at most one of keep, keep_count, energy, psnr, threshold")
    mode, value = "all", 0.0
    if given:
        name, value = given[0]
        mode = {"keep": "fraction", "keep_count": "count"}.get(name, name)
        if name == "keep_count":
            if isinstance(value, float) and not value.is_integer():
                raise ValueError("keep_count must be an integer")
            value = value if isinstance(value, float) else _int(value, "keep_count")
            if value < 0:
                raise ValueError("keep_count must be >= 0")
            if value > 2**63:
                raise ValueError(f"keep_count {value} is beyond any volume's coefficients")
        value = _real(value, name)
    spacing, origin = _geometry(vol, spacing, origin)
    arr = _data(vol)
    if roi is not None and not isinstance(roi, (list, tuple)):
        raise TypeError("roi must be a list of (center, radii[, power]) tuples")
    # the data range of what the caller gave: the float32 samples' (the library's) unless
    # another dtype was converted
    a = np.asarray(arr)
    value_range = None
    if a.dtype != np.float32 and a.dtype.kind in "iuf" and a.size:
        value_range = (float(a.min()), float(a.max()))
    handle, report = _wvol.compress(arr, wavelet=wavelet, levels=None if levels is None else _int(levels, "levels"),
                                    mode=mode, value=value,
                                    drop_levels=drop_levels, roi=roi, roi_floor=roi_floor, spacing=spacing,
                                    origin=origin, value_range=value_range, residual=bool(residual))
    # measured_error()'s default original is the caller's array, kept by reference (a copy would
    # double the memory of a store); its fingerprint tells measured_error() if it changed since
    return Store(handle, report, original=arr)



# ---- analysis: segmentation in wavelet space ---------------------------------------------

@dataclass
class Segmentation:
    """Result of :func:`segment`: ``labels`` (z, y, x) int32 = winning neuron per voxel,
    ``colors`` (z, y, x, 3) float32 = its RGB colour from the lattice position (in [0, 1]),
    ``classes`` (z, y, x) int32 = ground-truth class each neuron was given (only when
    ``truth`` was passed), ``score`` = {"error_all", "error_interior", "interior"} (only with
    ``truth``; ``error_interior`` is NaN when no voxel lies away from the boundaries), and the sizes ``features`` (raw), ``components`` (after PCA), ``neurons``."""
    labels: np.ndarray
    colors: np.ndarray
    classes: Optional[np.ndarray]
    score: Optional[dict]
    features: int
    components: int
    neurons: int


def segment(vol, wavelet="db2", levels=3, *, smooth=1, include_lowpass=True, variance=1.0, som=(4, 4, 4),
            iterations=20000, seed=1, truth=None, train_mask=None, boundary=None):
    """Segments a volume (or 2D image) with wavelet features and a 3D Kohonen map.

    Per voxel: the magnitude of every detail band of each of ``levels`` levels (box-averaged
    over ``smooth`` coarse samples) and each level's low-pass value, interpolated to the
    voxel -> PCA keeping ``variance`` of the total -> min-max normalised -> a Kohonen map of
    ``som`` = (a, b, c) neurons trained on ``iterations`` samples (deterministic for
    ``seed``) -> winner neuron and colour per voxel. With ``truth`` (int class ids >= 0, the
    volume's shape) each neuron takes the majority class of the voxels it wins among
    ``train_mask`` (bool, default all voxels), giving ``classes`` and a ``score``
    (misclassified share overall and away from boundaries of radius ``boundary``, default
    ``2**levels``). Returns a :class:`Segmentation`.
    """
    if not hasattr(som, "__len__") or len(som) != 3:
        raise TypeError(f"som must be the lattice's three sides (a, b, c), got {som!r}")
    r = _wvol.segment(_data(vol), wavelet=wavelet, levels=levels, smooth=smooth,
                      include_lowpass=bool(include_lowpass), variance=variance, som=tuple(som),
                      iterations=iterations, seed=seed, truth=truth, train_mask=train_mask,
                      boundary=-1 if boundary is None else boundary)
    return Segmentation(**r)


def features(vol, wavelet="db2", levels=3, *, smooth=1, include_lowpass=True, pca=None):
    """The per-voxel wavelet feature planes of :func:`segment`, as a (count, z, y, x) float32
    array. ``pca=v`` (in (0, 1]) projects onto the principal components explaining share v
    of the variance and normalises each to [0, 1] (as :func:`segment` does)."""
    return _wvol.features(_data(vol), wavelet=wavelet, levels=levels, smooth=smooth,
                          include_lowpass=bool(include_lowpass), variance=pca)




# ---- rendering ------------------------------------------------------------------------------

def _bound_method(bound):
    """bound= of render and render_progressive: False, True (= "exact"), "exact" or "coarse"."""
    if bound is False or bound is None:
        return 0
    if bound is True or bound == "exact":
        return 1
    if bound == "coarse":
        return 2
    raise ValueError(f"bound must be False, True, 'exact' or 'coarse', not {bound!r}")


class RenderContext:
    """Set-up kept across frames of :func:`render` (``render(..., context=ctx)``), for a user
    turning the view of one Store: the bricked path's block view of the kept coefficients, the
    coefficient bounds, the per-brick rates (while the transfer function's opacities stay the
    same) and a cache of reconstructed bricks shared by the threads, at most ``cache_bytes`` of
    voxels (0: the library's default, the dense volume's float32 size, at least 8 MiB). Each
    frame's image is what :func:`render` gives without it, bit for bit. Another Store drops what
    was kept; a volume (array) renders as without a context. Not for two threads at once."""

    def __init__(self, cache_bytes=0):
        self._handle = _wvol.render_context_new(_int(cache_bytes, "cache_bytes"))


def render(source, camera="+z", size=(256, 256), *, mode="absorption", tf="gaussian", tf_units="world",
           method="auto", step=None, shading=False, ambient=None, gauss_nodes=None, spline_j=None, brick=None,
           termination=None, threads=0, colors=None, skip_tolerance=None, preintegrate=False, gradient_levels=0,
           bound=False, lod=True, lod_level=None, lod_wavelet="db2", return_stats=False, context=None):
    """Renders a volume (array or :class:`Volume`) or a :class:`Store`; returns the image as
    an (height, width, 4) float32 array of linear, premultiplied RGBA, row 0 at the top
    (X-ray: R = G = B = the integral of f along the ray in value x world length, A = 1 where
    the ray meets the volume). One call of the library's rendering entry point (wvol_render),
    as ``wvol render`` makes: the same method for "auto", the same defaults, the same image.

    ``camera``: the library's camera text (docs/render.md): "+z", "-x", "ortho dir=1,1,0.5",
    "persp fov=40 from=-y zoom=1.5", "persp eye=X,Y,Z center=X,Y,Z up=0,0,1 fov=35", ...
    (world (x, y, z) units). ``size``: (width, height) in pixels.
    ``mode``: "xray", "absorption" (emission-absorption, exact exponential) or
    "absorption-linear" (the paper's linearised exponential). ``tf``: a preset ("gaussian",
    "grey" over the data range, "ct-bone", "ct-soft"), a transfer-function file, or a list
    of (value, r, g, b, opacity) points (opacity = extinction per world unit, or per box
    diagonal with ``tf_units="diagonal"``).
    ``method``: "auto" (the library's choice: "reference" for a volume; for a store "axis"
    where it applies (X-ray along an axis), else "bricks"), "reference" (ray marching with
    trilinear samples, ``step`` in voxels; a store is reconstructed first), "bricks" (the
    reference's ray marching on bricks reconstructed on demand from a store, never the whole
    volume, ``brick`` voxels a side), "spline" (the spline-projected integral from a store's
    kept coefficients, exact for the spline model and slow; ``gauss_nodes`` per piece),
    "axis" (X-ray along an axis from 2D coefficients), "splat" (X-ray for any orthographic
    view by footprint splatting: the spline model up to the footprint tables' interpolation
    error, about 1e-3 relative; docs/render.md) or "reference-fhat" (ray marching over the
    spline model). ``spline_j``: 2^J spline knots per unit for a store's basis functions.
    ``colors``: a colour volume, (z, y, x, 3) linear RGB per voxel on the volume's grid (e.g.
    :func:`segment`'s ``colors``), replacing the transfer function's colour (opacity still
    comes from ``tf``; nearest voxel, so classes keep crisp edges). Absorption modes and the
    sampling methods only ("reference", "reference-fhat", "bricks"); "spline", "axis" and
    "splat" refuse it.
    ``termination``: stop a ray once its transmittance falls below this (0: never).
    ``skip_tolerance``: "reference" and "bricks": the optical depth (X-ray: integral) each ray
    may skip in nearly empty bricks (e.g. a compressed volume's ringing haze); every pixel then
    changes by at most that much in alpha (a colour channel: times the largest colour), and
    ``stats["skip_bound"]`` is the largest depth actually skipped. 0: skip only what adds
    nothing.
    ``threads``: OpenMP threads (0: the default).
    Options left None take the library's defaults (docs/render.md: step 0.5, brick 8 for the
    reference's empty-space skipping and 32 for "bricks", gauss_nodes 5, spline_j the store's
    (4), termination 1e-6, ambient 0.3, skip_tolerance 0).
    ``preintegrate``: pre-integrated transfer function (absorption mode, sampling methods): the
    value linear between samples, each segment's integral exact for the piecewise-linear TF, so
    a steep TF is not under-sampled at a large step (docs/render.md, "Pre-integration").
    ``gradient_levels``: "bricks" with ``shading``: shade with the gradient of the wavelet model's
    low-pass approximation, the details of that many finest levels dropped (noise and voxel
    terracing smoothed; the samples themselves unchanged).
    ``bound=True`` (or "exact"; "coarse": each band's largest dropped coefficient, O(1) a pixel
    for any camera, looser): also return a per-pixel bound on how far this image can be from the
    image of all the coefficients (docs/render.md, "Error bounds"): ``(image, bound)``, the bound an
    array like the image (X-ray: R = G = B, A = 0; absorption: per channel and alpha). Needs a
    Store made with ``compress(..., residual=True)`` (a volume dropped nothing: its bound is 0);
    modes "xray" and "absorption", no shading or colours; ``stats["bound_max"]`` and
    ``["bound_mean"]``.
    ``lod=True`` (the default, as ``wvol render``): level of detail by screen size
    (docs/render.md, "Level of detail"): when the image's pixels are larger than the voxels,
    the sampling methods ("auto", "reference" on a volume, "bricks" on a store) render the
    wavelet level whose voxel matches the pixel footprint (orthographic: the pixel; perspective:
    at the volume's point nearest the eye), the grid ``wvol decompress --level`` gives (a
    volume's levels through ``lod_wavelet``); ``lod=False`` renders the full grid (the same
    image as before level of detail existed, bit for bit). ``lod_level=L`` forces level L (0:
    full resolution). The stats report "lod_level", "lod_footprint", "lod_voxel", "lod_dims"
    (z, y, x), and the extra error: "lod_energy" (the dropped levels' sum c^2), "lod_rmse" and
    "lod_psnr" (peak = the data range). A bound turns level of detail off.
    ``context``: a :class:`RenderContext`: the frame goes through it (wvol_render_context_frame),
    which keeps the bricked path's set-up (block view, bounds, per-brick rates, built bricks) from
    frame to frame for the same Store; the image is the same bit for bit.
    ``return_stats=True`` returns ``(image, stats)`` (``(image, bound, stats)`` with a bound):
    "method" (the one that ran), rays, samples, seconds, cpu_seconds...; through a context also
    "context_frame", "rates_reused", "bricks_reused", "cache_bytes" and "tiles_own" (docs/render.md).
    """
    w, h = _size(size)
    opts = dict(camera=camera, width=w, height=h, mode=mode, method=method, tf=tf, tf_units=tf_units, step=step,
                shading=int(bool(shading)), ambient=ambient, gauss_nodes=gauss_nodes, spline_j=spline_j,
                brick=brick, termination=termination, threads=_threads(threads), colors=colors,
                skip_tolerance=skip_tolerance, preintegrate=int(bool(preintegrate)),
                gradient_levels=_int(gradient_levels, "gradient_levels"),
                bound=_bound_method(bound), lod=int(bool(lod)),
                lod_level=-1 if lod_level is None else _lod_level(lod_level), lod_wavelet=lod_wavelet)
    if context is not None:
        if not isinstance(context, RenderContext):
            raise TypeError("context must be a wvol.RenderContext")
        opts["context"] = context._handle
    if isinstance(tf, os.PathLike):
        opts["tf"] = os.fspath(tf)
    if isinstance(source, Store):
        img, st, bd = _wvol.render(source._handle, None, None, opts)
    else:
        spacing, origin = _geometry(source, None, None)
        img, st, bd = _wvol.render(_data(source), spacing, origin, opts)
    if bound:
        return (img, bd, st) if return_stats else (img, bd)
    return (img, st) if return_stats else img


def render_progressive(vol, camera="+z", size=(256, 256), *, mode="absorption", tf="gaussian", tf_units="world",
                       wavelet="db2", levels=None, max_error=None, seconds=None, growth=4.0, bound=True,
                       step=None, termination=None, threads=0):
    """Progressive rendering of a volume (array or :class:`Volume`): a generator of
    ``(image, bound, info)``, one per pass (docs/render.md, "Progressive rendering"). The volume
    is transformed once; pass k renders from the largest coefficients, the low-pass cube alone
    first and ``growth`` times more each pass, and returns with the image the per-pixel bound on
    how far it can be from the image of all the coefficients (``bound=False``: None, and faster;
    ``"coarse"``: the cheap bound of :func:`render`).
    Passes stop after the first whose largest bound is <= ``max_error``, before one that would
    end beyond ``seconds`` (wall clock since the call), or when everything is kept;
    ``info["last"]`` marks the last and ``info["stop"]`` says why. ``info`` also has index,
    kept, total, bound_max, bound_mean, seconds, elapsed and method. Camera, size, mode, tf and
    the sampling options are those of :func:`render` (a bound needs mode "xray" or
    "absorption", no shading). Each pass is computed when the generator is advanced.
    """
    # the arguments are checked and the volume transformed here, at the call; the generator
    # below only renders (a generator function would defer every check to the first next())
    w, h = _size(size)
    spacing, origin = _geometry(vol, None, None)
    state = _wvol.progressive_begin(_data(vol), spacing, origin, wavelet, levels,
                                    0.0 if max_error is None else _real(max_error, "max_error"),
                                    0.0 if seconds is None else _real(seconds, "seconds"), _real(growth, "growth"),
                                    _bound_method(bound))
    opts = dict(camera=camera, width=w, height=h, mode=mode, tf=os.fspath(tf) if isinstance(tf, os.PathLike) else tf,
                tf_units=tf_units, step=step, termination=termination, threads=_threads(threads))
    _wvol.progressive_check(state, opts)

    def passes():
        while True:
            img, bd, info = _wvol.progressive_next(state, opts)
            yield img, bd, info
            if info["last"]:
                return

    return passes()


# ---- isosurfaces ----------------------------------------------------------------------------

def isosurface(source, iso, *, normals="gradient", brick=None, threads=0, level=0, wavelet="db2",
               return_stats=False):
    """Marching cubes at ``iso`` on a volume (array or :class:`Volume`) or on the
    reconstruction of a :class:`Store` (brick by brick: bricks whose bound from the
    coefficients does not straddle ``iso`` are skipped without reconstruction; ``brick`` =
    cells per brick edge).

    Returns ``(vertices, faces, normals)``: vertices (n, 3) float32 in world (x, y, z)
    coordinates, faces (m, 3) uint32 indices wound so their normal points from f >= iso to
    f < iso (outward for a bright blob), normals (n, 3) float32 unit vectors along -grad f
    (None with ``normals="none"``). An iso-value the data never crosses gives empty arrays
    (``return_stats=True`` also returns the stats, whose "message" says why).

    ``level=L`` (> 0) meshes the coarser grid of wavelet level L, the one ``wvol decompress
    --level`` writes (2^L times coarser, spacing 2^L times larger, origin on the level's
    scaling-function centres): a Store's from its levels above L only, a volume's through
    ``wavelet``; stats["level"] gives its level, dims (z, y, x), spacing, origin and the dropped
    levels' energy. A level above the levels available raises.
    """
    if isinstance(source, Store):
        v, f, n, st = _wvol.isosurface(source._handle, _real(iso, "iso"), normals=normals, threads=_threads(threads), brick=brick,
                                       level=_int(level, "level"), wavelet=wavelet)
    else:
        spacing, origin = _geometry(source, None, None)
        v, f, n, st = _wvol.isosurface(_data(source), _real(iso, "iso"), spacing=spacing, origin=origin, normals=normals,
                                       threads=_threads(threads), brick=brick, level=_int(level, "level"),
                                       wavelet=wavelet)
    return (v, f, n, st) if return_stats else (v, f, n)


def isoimage(source, iso, camera="+z", size=(256, 256), *, method="cast", brick=None, tolerance=None, threads=0,
             model_bound=False, return_stats=False):
    """An image of the isosurface at ``iso``, seen by ``camera`` (the words of :func:`render`).

    ``method="cast"``: the surface of the trilinear interpolant of a volume's samples (array or
    :class:`Volume`) or of a :class:`Store`'s reconstruction, cast brick by brick (bricks of
    ``brick`` cells rebuilt on demand, exact first crossing per cell, depth within ``tolerance``
    voxels, default 1e-5). ``method="exact"``: the surface f^ = iso of the wavelet model of a
    :class:`Store` (the guaranteed tracer; tolerance default 1e-3 voxels).

    ``model_bound=True`` (cast from a Store): the stats also bound |f^ - interp| per built brick
    (``fhat_bound_max``, ``fhat_bound_mean``; docs/iso.md).

    Returns ``(rgba, depth)``: rgba (h, w, 4) float32 Lambert-shaded with alpha 1 on the
    surface, depth (h, w) float32 the ray parameter of the hit (world units, +inf on a miss).
    A ray entering the box inside the surface reports where it leaves it (docs/iso.md).
    """
    w, h = _size(size)
    kw = dict(camera=camera, width=w, height=h, method=method, threads=_threads(threads), brick=brick or 0,
              tolerance=tolerance or 0.0, model_bound=bool(model_bound))
    if isinstance(source, Store):
        rgba, depth, st = _wvol.isoimage(source._handle, iso, **kw)
    else:
        spacing, origin = _geometry(source, None, None)
        rgba, depth, st = _wvol.isoimage(_data(source), iso, spacing=spacing, origin=origin, **kw)
    return (rgba, depth, st) if return_stats else (rgba, depth)


def save_mesh(path, vertices, faces, normals=None):
    """Writes a triangle mesh (as returned by :func:`isosurface`); the format follows the
    extension: .ply (binary, with normals when given), .obj, .stl, .vtp (when built with
    VTK). Atomic: no partial file."""
    _wvol.save_mesh(os.fspath(path), vertices, faces, normals)




# ---- .wvc files -----------------------------------------------------------------------------

def open(path, level=None):  # noqa: A001  (wvol.open mirrors the built-in for .wvc files)
    """Reads a .wvc file into a :class:`Store` (through the library's pipeline, as ``wvol
    render FILE.wvc`` does: every nonzero coefficient kept). ``level=m`` decodes only the
    levels coarser than m (the finer ones stay zero): ``store.reconstruct(level=m)`` is then
    the coarser volume at a fraction of the decoding cost. The store's ``predicted_error`` is
    the header's record: selection + quantisation error of the whole file."""
    handle, info = _wvol.store_open(os.fspath(path), stop_level=0 if level is None else _int(level, "level"))
    report = {"kept": int(info["nonzero"]), "total": int(np.prod(info["padded"])),
              "energy_dropped": float(info["sse"]), "energy_total": float(info["energy"]),
              "file_bytes": int(info["file_bytes"]), "step": float(info["step"])}
    return Store(handle, report, file_info=info)


def wvc_region(path, lo, hi, level=0, memory=0):
    """The box ``[lo, hi)`` (``(x, y, z)`` indices of level ``level``'s grid: 0 the voxels,
    m the grid ``2**m`` coarser, as ``open(path, level=m)`` reconstructs it) of a .wvc file,
    decoding only the chunks of a format-2 file whose basis functions reach the box, within
    ``memory`` bytes of decoded chunks (0: 1 GiB). Returns ``(array, stats)``: a float32
    array indexed ``[z, y, x]`` and the chunk cache's counters."""
    return _wvol.wvc_region(os.fspath(path), _ints(lo, "lo", "(x, y, z)"), _ints(hi, "hi", "(x, y, z)"),
                            _int(level, "level"), memory)


def wvc_info(path):
    """Header and section table of a .wvc file (checksums verified, nothing decoded)."""
    return _wvol.wvc_info(os.fspath(path))


from . import synth  # noqa: E402  (wvol.synth.*: needs Volume defined above)
from . import radiosity  # noqa: E402  (wvol.radiosity.solve: wavelet radiosity of quads)
from . import transport  # noqa: E402  (wvol.transport.*: radiative transfer in Nusselt coordinates)
