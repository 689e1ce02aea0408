# SPDX-License-Identifier: MIT
"""wvol.compress and the Store: selection criteria, predicted vs measured error, coarser
levels and bricks, bad input."""
import math

import numpy as np
import pytest

import wvol


def _blob(shape=(20, 24, 28)):
    z, y, x = np.mgrid[:shape[0], :shape[1], :shape[2]].astype(np.float32)
    c = [(n - 1) / 2 for n in shape]
    r2 = (z - c[0]) ** 2 + (y - c[1]) ** 2 + (x - c[2]) ** 2
    return np.exp(-r2 / 40.0).astype(np.float32) + 0.01 * np.sin(x)


def test_keep_fraction_count_and_all():
    a = _blob()
    s = wvol.compress(a, keep=0.05)
    assert s.total == 24 * 24 * 32                       # padded to multiples of 2^3
    assert s.kept == round(0.05 * s.total)
    assert np.count_nonzero(s.coeffs) <= s.kept
    s2 = wvol.compress(a, "haar", 2, keep_count=500)
    assert s2.kept == 500 and s2.levels == 2 and s2.wavelet == "haar"
    full = wvol.compress(a)
    assert full.kept == full.total
    # nothing dropped: predicted error 0, reconstruction exact to float32 rounding
    assert full.predicted_error.l2 == 0 and math.isinf(full.predicted_error.psnr)
    assert full.measured_error().max < 1e-5


@pytest.mark.parametrize("wavelet", ["haar", "db2", "coif1"])
def test_predicted_error_matches_measured_without_padding(wavelet):
    """Parseval: on a grid with no padding the predicted L2 equals the measured one up to
    float32 rounding of the transform (relative 1e-3 of a ~1e-1 error is far above it)."""
    a = _blob((16, 16, 32))
    s = wvol.compress(a, wavelet, 3, keep=0.03)
    p, m = s.predicted_error, s.measured_error()
    assert p.l2 > 0
    assert abs(p.l2 - m.l2) < 1e-3 * p.l2 + 1e-5
    assert abs(p.rmse - m.rmse) < 1e-3 * p.rmse + 1e-7
    assert abs(p.psnr - m.psnr) < 0.01


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_measured_error_refuses_an_input_changed_since(dtype):
    """measured_error() compares with the array the store was compressed from, kept by
    reference (a float32 array is read in place by compress; a float64 one converted): when
    the caller has changed it since, the default is refused instead of measuring against
    other samples; an original passed in is read when called."""
    a = _blob().astype(dtype)
    s = wvol.compress(a, keep=0.05)
    before = s.measured_error()
    assert math.isfinite(before.psnr) and before.l2 > 0
    keep = a.copy()
    a *= 3
    with pytest.raises(ValueError, match="changed since"):
        s.measured_error()
    assert s.measured_error(a).l2 > 2 * before.l2
    assert s.measured_error(keep) == before
    a[...] = keep  # the same samples again: the default is accepted
    assert s.measured_error() == before


def test_energy_and_psnr_targets_are_met():
    a = _blob()
    s = wvol.compress(a, energy=0.999)
    r = s.report
    assert r["energy_kept"] >= 0.999 * r["energy_total"]
    s = wvol.compress(a, psnr=45)
    assert s.predicted_error.psnr >= 45
    # the prediction is over the padded grid: an upper bound of the measured error
    assert s.measured_error().l2 <= s.predicted_error.l2 * (1 + 1e-4) + 1e-6
    lossier = wvol.compress(a, psnr=30)
    assert lossier.kept < s.kept


def test_drop_levels_and_roi():
    a = _blob((16, 16, 16))
    s = wvol.compress(a, drop_levels=1)
    assert s.report["level_kept"][1] == 0                 # finest level gone
    assert np.all(s.coeffs[8:, :, :] == 0) and np.all(s.coeffs[:, 8:, :] == 0)
    # an ROI around one corner moves the same budget of coefficients towards that corner:
    # the error there falls and the error in the opposite corner rises (fixed seed)
    roi = [((3.0, 3.0, 3.0), (3.0, 3.0, 3.0))]
    noisy = a + 0.05 * np.random.default_rng(0).standard_normal(a.shape).astype(np.float32)

    def corner_errors(**kw):
        s = wvol.compress(noisy, keep=0.1, **kw)
        e = np.abs(s.reconstruct().data - noisy)
        return e[:6, :6, :6].mean(), e[10:, 10:, 10:].mean()

    near0, far0 = corner_errors()
    near, far = corner_errors(roi=roi, roi_floor=0.1)
    assert near < 0.9 * near0 and far > far0


def test_reconstruct_level_and_box():
    a = _blob((17, 20, 23))
    v = wvol.Volume(a, spacing=(1.0, 2.0, 0.5), origin=(10.0, 0.0, -3.0))
    s = wvol.compress(v, "db2", 3, keep=0.2)
    full = s.reconstruct()
    assert full.data.shape == a.shape and full.spacing == v.spacing and full.origin == v.origin
    coarse = s.reconstruct(level=2)
    assert coarse.data.shape == (5, 5, 6)                  # ceil(n / 4)
    assert coarse.spacing == (4.0, 8.0, 2.0)
    # the coarse cube holds local averages of the same function: its mean is near the full one's
    assert abs(coarse.data.mean() - full.data.mean()) < 0.05 * abs(full.data).max()
    box = np.s_[3:9, 0:20, 5:11]
    brick = s.reconstruct(box=box)
    assert brick.data.shape == (6, 20, 6)
    # brick synthesis runs in float64: equal to the full reconstruction to float32 rounding
    np.testing.assert_allclose(brick.data, full.data[box], atol=1e-5)
    assert brick.origin == (10.0 + 5 * 1.0, 0.0, -3.0 + 3 * 0.5)
    np.testing.assert_allclose(s.reconstruct(box=((3, 9), (0, 20), (5, 11))).data, brick.data)


def test_dwt3_hands_over_memory_and_reads_in_place():
    a = _blob((16, 16, 16))
    c = wvol.dwt3(a, "haar", 2)
    assert c.data.flags["C_CONTIGUOUS"] and c.data.dtype == np.float32
    assert c.data.base is not None                       # wraps the library's buffer, not a copy
    back = wvol.idwt3(c)
    assert np.abs(back - a).max() < 1e-5


@pytest.mark.parametrize("kwargs, exc, words", [
    (dict(keep=0.1, energy=0.9), ValueError, "at most one of keep"),
    (dict(keep=1.5), ValueError, r"fraction 1.5 is not in \[0, 1\]"),
    (dict(keep=float("nan")), ValueError, "selection value must be finite"),
    (dict(energy=-0.1), ValueError, r"energy share -0.1 is not in \[0, 1\]"),
    (dict(keep_count=-3), ValueError, "keep_count must be >= 0"),
    (dict(keep_count=2.5), ValueError, "keep_count must be an integer"),
    (dict(drop_levels=3), ValueError, "drop_levels 3: must be below the levels"),
    (dict(levels=9), ValueError, "levels 9: a 8x8x8 volume allows 1..3"),
    (dict(wavelet="nope"), ValueError, "unknown wavelet 'nope'"),
    (dict(roi=[((1, 2), (1, 1, 1))]), ValueError, "roi center: expected 3 values"),
    (dict(roi=[((1, 2, 3), (0, 1, 1))]), ValueError, "radius 0 on axis 0 must be > 0"),
    (dict(roi=5), TypeError, "roi must be a list"),
    (dict(spacing=(1, -1, 1)), ValueError, r"spacing\[1\] = -1"),
])
def test_compress_refuses_bad_arguments(kwargs, exc, words):
    with pytest.raises(exc, match=words):
        wvol.compress(_blob((8, 8, 8)), **kwargs)


@pytest.mark.parametrize("arr, exc, words", [
    (np.zeros((0, 4, 4), np.float32), ValueError, "the array is empty"),
    (np.zeros(8, np.float32), ValueError, "got 1 dimensions"),
    (np.zeros((2, 2, 2, 2), np.float32), ValueError, "got 4 dimensions"),
    (np.full((8, 8, 8), np.nan, np.float32), ValueError, r"NaN at voxel \(i=0, j=0, k=0\)"),
    (np.zeros((8, 8, 8), complex), TypeError, "real numbers"),
    (np.zeros((8, 8, 8), object), TypeError, "real numbers"),
    ("not an array", TypeError, "real numbers"),
])
def test_compress_refuses_bad_arrays(arr, exc, words):
    with pytest.raises(exc, match=words):
        wvol.compress(arr, keep=0.1)


def test_reconstruct_refuses_bad_requests():
    s = wvol.compress(_blob((8, 8, 8)), "haar", 2, keep=0.5)
    for kw in (dict(level=3), dict(level=-1), dict(box=np.s_[0:0, :, :]), dict(box=((0, 9), (0, 8), (0, 8))),
               dict(box=np.s_[::2, :, :]), dict(box=(1, 2)), dict(level=1, box=np.s_[:, :, :])):
        with pytest.raises(ValueError):
            s.reconstruct(**kw)
    with pytest.raises(TypeError):
        s.reconstruct(level=1.5)
    # a coefficient array of the wrong size put in a store is refused, not read past (the store
    # checks it when it takes it)
    with pytest.raises(ValueError):
        s.coeffs = np.zeros((4, 4, 4), np.float32)
        s.reconstruct()


def test_c_store_info_and_evaluate():
    v = wvol.synth.gaussian(shape=(16, 16, 16))
    s = wvol.compress(v, "haar", 2, keep=0.1)
    info = s.info()
    assert info["kept"] <= s.kept and info["kept_lowpass"] == 64        # 16/4 cubed low-pass
    assert info["bytes"] > 0 and s.bytes_per_coeff == pytest.approx(info["bytes"] / info["kept"])
    # Haar: f^ is piecewise constant and, at a voxel centre, equals the reconstructed sample
    k, j, i = np.mgrid[:16, :16, :16]
    pts = np.stack([i.ravel(), j.ravel(), k.ravel()], 1) * np.array(v.spacing) + np.array(v.origin)
    val, grad = s.evaluate(pts)
    assert val.shape == (4096,) and grad.shape == (4096, 3)
    np.testing.assert_allclose(val, s.reconstruct().data.ravel(), atol=1e-6)   # float32 coefficients
    with pytest.raises(ValueError):
        s.evaluate(np.zeros((3, 2)))
    with pytest.raises(ValueError):
        s.evaluate([[0.0, np.nan, 0.0]])


def test_2d_images_compress_as_one_slice():
    a = np.random.default_rng(0).random((30, 40), dtype=np.float32)
    s = wvol.compress(a, "db2", 2, keep=0.3)
    assert s.shape == (1, 30, 40) and s.coeffs.shape == (1, 32, 40)    # the 1-voxel axis is not transformed
    assert s.total == 32 * 40 and s.kept == round(0.3 * s.total)
    assert s.reconstruct().data.shape == (1, 30, 40)
    assert s.reconstruct(level=1).data.shape == (1, 15, 20)
    # measured against the 2D original; the prediction bounds it (padding 30 -> 32 rows)
    assert s.measured_error(a).l2 <= s.predicted_error.l2 * (1 + 1e-4)
