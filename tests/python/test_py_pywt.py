# SPDX-License-Identifier: MIT
"""wvol.dwt3 / wvol.idwt3 against PyWavelets through the Python API (the CLI does the same
in test_wavelet_pywt.py): pywt.wavedecn(mode='periodization') equals our transform up to
the index shift documented in docs/wavelets.md."""
import numpy as np
import pytest

import wvol

import pywt  # noqa: E402  (python3-pywt: part of the setup, a failure rather than a skip)
pytestmark = pytest.mark.filterwarnings("ignore:Level value")


@pytest.mark.parametrize("wavelet", ["haar", "db2", "coif1"])
@pytest.mark.parametrize("levels", [1, 2, 3])
def test_dwt3_matches_pywt_wavedecn_periodization(wavelet, levels):
    rng = np.random.default_rng(11 + levels)
    vol = rng.standard_normal((16, 32, 24)).astype(np.float32)     # (z, y, x), multiples of 2^3
    s = pywt.Wavelet(wavelet).dec_len // 2 - 1                     # per-level shift of pywt
    S = s * (2 ** levels - 1)
    ours = wvol.dwt3(np.roll(vol, S, axis=(0, 1, 2)), wavelet, levels)
    assert ours.data.shape == vol.shape and ours.levels == levels and ours.shape == vol.shape
    arr, slices = pywt.coeffs_to_array(pywt.wavedecn(vol.astype(np.float64), wavelet, mode="periodization",
                                                     level=levels))
    tol = 1e-5 * np.abs(arr).max()   # float32 transform vs float64 pywt: ~levels * taps * eps32 * range
    np.testing.assert_allclose(ours.data[slices[0]], arr[slices[0]], rtol=0, atol=tol)
    for i, detail in enumerate(slices[1:]):
        m = levels - i                                   # slices[1] is the coarsest detail level
        t = -s * (2 ** (levels - m) - 1)
        for key, sl in detail.items():
            np.testing.assert_allclose(np.roll(ours.data[sl], t, axis=(0, 1, 2)), arr[sl], rtol=0, atol=tol,
                                       err_msg=f"level {m} band {key}")


@pytest.mark.parametrize("wavelet", ["haar", "db2", "coif1"])
def test_idwt3_inverts_pywt_coefficients(wavelet):
    """The inverse direction: pywt's coefficients, shifted back into our convention, are
    reconstructed by wvol.idwt3 to the input rolled by S."""
    levels = 2
    vol = np.random.default_rng(5).standard_normal((8, 16, 24)).astype(np.float32)
    s = pywt.Wavelet(wavelet).dec_len // 2 - 1
    S = s * (2 ** levels - 1)
    arr, slices = pywt.coeffs_to_array(pywt.wavedecn(vol.astype(np.float64), wavelet, mode="periodization",
                                                     level=levels))
    ours = np.empty_like(arr)
    ours[slices[0]] = arr[slices[0]]
    for i, detail in enumerate(slices[1:]):
        m = levels - i
        t = -s * (2 ** (levels - m) - 1)
        for key, sl in detail.items():
            ours[sl] = np.roll(arr[sl], -t, axis=(0, 1, 2))
    back = wvol.idwt3(wvol.Coeffs(ours.astype(np.float32), wavelet, levels, vol.shape))
    np.testing.assert_allclose(back, np.roll(vol, S, axis=(0, 1, 2)), rtol=0, atol=1e-5 * np.abs(vol).max())


def test_filters_match_pywt_filter_banks():
    by_name = {f["name"]: f for f in wvol.filters()}
    for name in ["haar"] + [f"db{n}" for n in range(1, 11)] + [f"coif{n}" for n in range(1, 6)]:
        w = pywt.Wavelet(name)
        f = by_name[name]
        assert f["taps"] == w.dec_len
        # published values with 17 digits: 1e-12 is a transcription check
        np.testing.assert_allclose(f["h"], w.rec_lo, rtol=0, atol=1e-12, err_msg=name)
        assert f["vanishing_moments"] == w.vanishing_moments_psi
