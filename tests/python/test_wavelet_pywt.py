# SPDX-License-Identifier: MIT
"""The wavelet engine against PyWavelets: filter values (through `wvol filters --json`)."""
import json

import numpy as np
import pytest

import pywt  # noqa: E402  (python3-pywt: part of the setup, a failure rather than a skip)
# periodization has no boundary effects; pywt warns about deep levels on small sizes anyway
pytestmark = pytest.mark.filterwarnings("ignore:Level value")


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
    assert len(h) % 2 == 0 and h[-1] == 0.0                 # one zero tap: even length for the QMF
    core = h[:-1]
    assert f["defect"] < 1e-8
    assert abs(h.sum() - np.sqrt(2)) < 1e-14
    np.testing.assert_array_equal(core, core[::-1])          # symmetric
    c = len(core) // 2
    assert abs(f["center"] - c) < 1e-9                        # centred on its middle tap
    assert min(abs(core[0]), abs(core[-1])) >= 1e-10          # truncated where |h| < 1e-10 ...
    assert abs(core[0]) < 3e-10                               # ... and not earlier
    # published values of the cubic Battle-Lemarie filter (Daubechies 1992, section 5.4,
    # normalised to sum sqrt2): centre tap and neighbours to 6 digits
    np.testing.assert_allclose(core[c:c + 6], [0.766130, 0.433923, -0.050202, -0.110037, 0.032081,
                                               0.042068], atol=1e-6)


# ---- the transform against pywt.wavedecn(mode='periodization') -----------------------------

def _transform(wvol, tmp_path, vol, wavelet, levels, extra=()):
    """Runs `wvol transform` on vol (numpy array indexed [z, y, x]); returns (coeffs, sidecar)."""
    src = tmp_path / "in.raw"
    out = tmp_path / "c.raw"
    np.ascontiguousarray(vol, dtype="<f4").tofile(src)
    nz, ny, nx = vol.shape
    wvol("transform", src, "--dims", f"{nx}x{ny}x{nz}", "-o", out, "--wavelet", wavelet,
         "--levels", levels, *extra, check=True)
    side = json.loads((tmp_path / "c.json").read_text())
    px, py, pz = side["padded"]
    return np.fromfile(out, dtype="<f4").reshape(pz, py, px), side


# pywt's periodization filters the input of every level shifted by s = L/2 - 1 samples
# compared with our a[k] = sum h[n] x[2k+n]. Over M levels that is equivalent to: our
# transform of x rolled by S = s (2^M - 1) along every axis, then the level-m bands rolled by
# t_m = -s (2^(M-m) - 1) positions (coarsest level: no shift). docs/wavelets.md states it.
@pytest.mark.parametrize("wavelet", ["haar", "db2", "coif1"])
@pytest.mark.parametrize("levels", [1, 2, 3])
def test_transform_matches_pywt_wavedecn_periodization(wvol, tmp_path, wavelet, levels):
    rng = np.random.default_rng(7 + levels)
    vol = rng.standard_normal((16, 32, 24)).astype(np.float32)   # [z, y, x]; multiples of 2^3
    L = pywt.Wavelet(wavelet).dec_len
    s = L // 2 - 1
    S = s * (2 ** levels - 1)
    ours, side = _transform(wvol, tmp_path, np.roll(vol, S, axis=(0, 1, 2)), wavelet, levels)
    assert side["padded"] == [24, 32, 16] and side["levels"] == levels
    ref = pywt.wavedecn(vol.astype(np.float64), wavelet, mode="periodization", level=levels)
    arr, slices = pywt.coeffs_to_array(ref)
    # coeffs_to_array uses the same pyramid layout: compare band by band with the shift
    scale = np.abs(arr).max()
    tol = 1e-5 * scale          # float32 transform vs float64 pywt: ~levels * L * eps32 * range
    np.testing.assert_allclose(ours[slices[0]], arr[slices[0]], rtol=0, atol=tol)
    for i, detail in enumerate(slices[1:]):
        m = levels - i                       # slices[1] is the coarsest detail level
        t = -s * (2 ** (levels - m) - 1)
        for key, sl in detail.items():
            band = np.roll(ours[sl], t, axis=(0, 1, 2))
            np.testing.assert_allclose(band, arr[sl], rtol=0, atol=tol, err_msg=f"level {m} band {key}")


def test_pywt_band_keys_match_our_band_bits(wvol, tmp_path):
    """Band l (bit0 = high-pass along x = numpy's last axis) sits where coeffs_to_array puts
    the key whose last letter is 'd' for x: a check of the layout on a Haar transform."""
    vol = np.zeros((8, 8, 8), np.float32)
    vol[..., 0::2] = 1.0                      # varies along x only: only x-high-pass bands
    ours, _ = _transform(wvol, tmp_path, vol, "haar", 1)
    assert np.abs(ours[:4, :4, 4:]).max() > 0.5          # band 1 (x high) at [0:4, 0:4, 4:8]
    ours[:4, :4, 4:] = 0
    ours[:4, :4, :4] = 0
    assert np.abs(ours).max() < 1e-6


# ---- command line --------------------------------------------------------------------------

def test_cli_roundtrip_odd_sizes_and_partial(wvol, tmp_path):
    rng = np.random.default_rng(3)
    vol = rng.random((7, 13, 17)).astype(np.float32)
    _, side = _transform(wvol, tmp_path, vol, "coif1", 2, ("--f64",))
    assert side["dims"] == [17, 13, 7] and side["padded"] == [20, 16, 8]
    assert side["wavelet"] == "coif1" and side["precision"] == "float64"
    wvol("inverse", tmp_path / "c.raw", "-o", tmp_path / "r.raw", check=True)
    back = np.fromfile(tmp_path / "r.raw", dtype="<f4").reshape(vol.shape)
    assert np.abs(back - vol).max() < 1e-5   # 2 levels x 6 taps x eps32 x range, with margin
    wvol("inverse", tmp_path / "c.raw", "-o", tmp_path / "b.raw", "--brick", "3,2,1,9,13,5", check=True)
    brick = np.fromfile(tmp_path / "b.raw", dtype="<f4").reshape(4, 11, 6)
    np.testing.assert_allclose(brick, back[1:5, 2:13, 3:9], atol=1e-5)
    wvol("inverse", tmp_path / "c.raw", "-o", tmp_path / "l.raw", "--level", "1", check=True)
    coarse = np.fromfile(tmp_path / "l.raw", dtype="<f4")
    assert coarse.size == 9 * 7 * 4           # ceil(n / 2) per axis


def test_cli_refuses_bad_input(wvol, tmp_path):
    vol = np.ones((4, 4, 4), np.float32)
    vol[1, 2, 3] = np.nan
    vol.tofile(tmp_path / "nan.raw")
    proc = wvol("transform", tmp_path / "nan.raw", "--dims", "4x4x4", "-o", tmp_path / "c.raw")
    assert proc.returncode == 1 and "i=3, j=2, k=1" in proc.stderr
    assert not (tmp_path / "c.raw").exists()
    np.ones((4, 4, 4), np.float32).tofile(tmp_path / "ok.raw")
    for args, words in [(("--levels", "3"), "--levels 3: a 4 x 4 x 4 volume allows 1..2"),
                        (("--levels", "0"), "--levels '0': expected an integer from 1 to 30"),
                        (("--wavelet", "db42"), "unknown wavelet 'db42'"),
                        (("--pad", "mirror"), "--pad 'mirror': expected edge, zero or periodic")]:
        proc = wvol("transform", tmp_path / "ok.raw", "--dims", "4x4x4", "-o", tmp_path / "c.raw", *args)
        assert proc.returncode == 2, (args, proc.stderr)
        assert proc.stderr.startswith("wvol transform: ") and words in proc.stderr, proc.stderr
    wvol("transform", tmp_path / "ok.raw", "--dims", "4x4x4", "-o", tmp_path / "c.raw", check=True)
    with open(tmp_path / "c.raw", "ab") as fp:       # a truncated / extended coefficient file
        fp.write(b"\0\0\0\0")
    proc = wvol("inverse", tmp_path / "c.raw", "-o", tmp_path / "r.raw")
    assert proc.returncode == 1 and "260 bytes, the sidecar says 64 float32 values" in proc.stderr
    proc = wvol("inverse", tmp_path / "missing.raw", "-o", tmp_path / "r.raw")
    assert proc.returncode == 1 and "cannot open the sidecar of" in proc.stderr
