# SPDX-License-Identifier: MIT
"""The Python package: load/save, filters, dwt3/idwt3, errors as exceptions."""
import numpy as np
import pytest
import pywt

import wvol


def test_save_load_roundtrip_keeps_values_and_geometry(tmp_path):
    a = np.random.default_rng(0).random((5, 6, 7), dtype=np.float32)
    p = tmp_path / "a.raw"
    wvol.save(a, p)
    v = wvol.load(p, dims=(7, 6, 5))
    assert v.data.shape == (5, 6, 7)
    assert np.array_equal(v.data, a)
    assert v.spacing == (1.0, 1.0, 1.0) and v.origin == (0.0, 0.0, 0.0)


def test_load_raw_places_it_in_the_world(tmp_path):
    """A raw file's spacing, origin and byte order come from the call (the CLI's --spacing,
    --origin, --big-endian); bad ones are refused before anything is read."""
    a = (np.arange(5 * 6 * 7) % 251).astype(np.int16).reshape(5, 6, 7)
    p = tmp_path / "be.raw"
    a.astype(">i2").tofile(p)
    v = wvol.load(p, dims=(7, 6, 5), dtype="int16", big_endian=True, spacing=(0.5, 0.75, 2), origin=(-1, 2, 3))
    assert np.array_equal(v.data, a.astype(np.float32))
    assert v.spacing == (0.5, 0.75, 2.0) and v.origin == (-1.0, 2.0, 3.0)
    assert wvol.load(p, dims=(7, 6, 5), dtype="int16", big_endian=True, spacing=0.25).spacing == (0.25,) * 3
    for bad, words in (({"spacing": (1, 0, 1)}, r"spacing\[1\] = 0: spacing must be finite and positive"),
                       ({"spacing": (1, float("nan"), 1)}, r"spacing\[1\] = nan"),
                       ({"origin": (0, float("inf"), 0)}, r"origin\[1\] = inf: origin must be finite"),
                       ({"spacing": (1, 1)}, "spacing: expected 3 values")):
        with pytest.raises(ValueError, match=words):
            wvol.load(p, dims=(7, 6, 5), dtype="int16", **bad)


def test_filters_match_pywavelets():
    by_name = {f["name"]: f for f in wvol.filters()}
    for name in ("haar", "db2", "db4", "coif1", "coif3"):
        ours = np.array(by_name[name]["h"])
        ref = np.array(pywt.Wavelet(name).rec_lo)
        assert ours.shape == ref.shape
        assert np.abs(ours - ref).max() < 1e-12, name


@pytest.mark.parametrize("wavelet", ["haar", "db2", "coif1", "bl3"])
def test_dwt3_roundtrip_odd_shape(wavelet):
    a = np.random.default_rng(1).standard_normal((9, 10, 11)).astype(np.float32)
    c = wvol.dwt3(a, wavelet, 2)
    assert c.data.shape == (12, 12, 12)  # padded to multiples of 2^2
    back = wvol.idwt3(c)
    # float32 transform: rounding ~ levels * taps * eps * range
    assert np.abs(back - a).max() < 1e-4 * np.abs(a).max()


def test_dwt3_parseval_without_padding():
    a = np.random.default_rng(2).standard_normal((16, 16, 16)).astype(np.float32)
    c = wvol.dwt3(a, "db2", 3)
    e_in = np.sum(a.astype(np.float64) ** 2)
    e_out = np.sum(c.data.astype(np.float64) ** 2)
    assert abs(e_in - e_out) < 1e-5 * e_in


def test_noncontiguous_and_integer_arrays_are_accepted():
    a = np.arange(16 * 16 * 32, dtype=np.int32).reshape(16, 16, 32)[:, :, ::2]
    c = wvol.dwt3(a, "haar", 1)
    back = wvol.idwt3(c)
    assert np.abs(back - a).max() < 1e-3 * a.max()


@pytest.mark.parametrize("bad, exc, words", [
    (lambda: wvol.save(np.zeros((0, 3, 3)), "/tmp/wvol_never.raw"), ValueError, "empty"),
    (lambda: wvol.save(np.array([[1.0, np.nan]]), "/tmp/wvol_never.raw"), ValueError, r"NaN at voxel \(i=1, j=0, k=0\)"),
    (lambda: wvol.save(np.array([["a"]]), "/tmp/wvol_never.raw"), TypeError, "real numbers"),
    (lambda: wvol.load("/nonexistent/x.raw", dims=(1, 1, 1)), OSError, "/nonexistent/x.raw: No such file"),
    (lambda: wvol.load("/tmp/none.raw", dims=(0, 1, 1)), ValueError, "dims: each dimension must be a positive integer"),
    (lambda: wvol.dwt3(np.zeros((8, 8, 8)), "db99"), ValueError, "unknown wavelet 'db99'"),
    (lambda: wvol.dwt3(np.zeros((8, 8, 8)), "db2", 9), ValueError, r"levels = 9 for a 8 x 8 x 8 volume \(1..3\)"),
    (lambda: wvol.dwt3(np.zeros(5)), ValueError, "got 1 dimensions"),
    (lambda: wvol.dwt3(np.zeros((2, 2, 2, 2))), ValueError, "got 4 dimensions"),
    (lambda: wvol.dwt3(np.zeros((4, 4), dtype=complex)), TypeError, "dtype complex128"),
])
def test_bad_input_raises(bad, exc, words):
    with pytest.raises(exc, match=words):
        bad()
