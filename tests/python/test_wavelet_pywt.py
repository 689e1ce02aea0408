"""The wavelet engine against PyWavelets: filter values (through `wvol filters --json`)."""
import json

import numpy as np
import pytest

pywt = pytest.importorskip("pywt")


def _filters(wvol):
    proc = wvol("filters", "--json", check=True)
    return {f["name"]: f for f in json.loads(proc.stdout)["filters"]}


def test_filters_match_pywt_rec_lo(wvol):
    """h in our convention is PyWavelets' rec_lo; g its rec_hi. Published values are
    stored with 17 digits, so 1e-12 is a transcription check with wide margin."""
    filters = _filters(wvol)
    names = ["haar"] + [f"db{n}" for n in range(1, 11)] + [f"coif{n}" for n in range(1, 6)]
    for name in names:
        w = pywt.Wavelet(name)
        f = filters[name]
        assert f["length"] == w.dec_len, name
        np.testing.assert_allclose(f["h"], w.rec_lo, rtol=0, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(f["g"], w.rec_hi, rtol=0, atol=1e-12, err_msg=name)
        assert f["vanishing_moments"] == w.vanishing_moments_psi, name
        assert f["defect"] < 1e-12, name


def test_bl3_is_reported_with_small_defect(wvol):
    """bl3 is truncated at |h| < 1e-10, so its defect is ~ the size of the dropped
    taps times the largest ones: below 1e-8 (DESIGN.md section 3)."""
    f = _filters(wvol)["bl3"]
    h = np.array(f["h"])
    assert f["defect"] < 1e-8
    assert abs(h.sum() - np.sqrt(2)) < 1e-14
    np.testing.assert_allclose(h, h[::-1], atol=0)          # symmetric
    assert abs(f["center"] - (len(h) - 1) / 2) < 1e-9      # centred on its middle tap
    # published values of the cubic Battle-Lemarie filter (Daubechies 1992, section 5.4),
    # normalised to sum sqrt(2): centre tap and neighbours to 6 digits
    c = len(h) // 2
    np.testing.assert_allclose(h[c:c + 6], [0.766130, 0.433923, -0.050202, -0.110037, 0.032081,
                                            0.042068], atol=1e-6)
