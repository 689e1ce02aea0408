# SPDX-License-Identifier: MIT
"""Store.save / wvol.open / wvol.wvc_info: .wvc round trips from Python."""
import os

import numpy as np
import pytest

import wvol


@pytest.fixture(scope="module")
def vol():
    return wvol.synth.blobs(shape=(24, 32, 40), seed=3, spacing=(1.0, 0.5, 2.0))


def test_save_open_roundtrip_predicts_the_error(vol, tmp_path):
    s = wvol.compress(vol, "db2", 3, keep=0.05)
    rep = s.save(tmp_path / "b.wvc")
    assert rep["bytes"] == (tmp_path / "b.wvc").stat().st_size
    # quantisation adds quant_share = 2% of the dropped energy (the step search meets it
    # within its tolerance; 3% leaves room)
    assert rep["sse_quant"] <= 0.03 * s.report["energy_dropped"] + 1e-12
    o = wvol.open(tmp_path / "b.wvc")
    assert o.shape == s.shape and o.wavelet == "db2" and o.levels == 3
    assert o.spacing == vol.spacing and o.origin == vol.origin
    assert o.value_range == s.value_range
    # no padding on this grid: predicted (dropped + quantisation, Parseval) equals measured
    # to float32 rounding of the inverse transform
    p, m = o.predicted_error, o.measured_error(vol)
    assert abs(p.l2 - m.l2) < 1e-3 * m.l2
    assert m.l2 >= s.measured_error().l2 * (1 - 1e-6)         # quantisation only adds error
    assert m.l2 <= s.measured_error().l2 * np.sqrt(1.03)
    info = wvol.wvc_info(tmp_path / "b.wvc")
    assert info["shape"] == (24, 32, 40) and info["file_bytes"] == rep["bytes"]
    assert info["nonzero"] == o.kept <= s.kept


def test_open_coarse_level_only(vol, tmp_path):
    s = wvol.compress(vol, "haar", 3, keep=0.2)
    s.save(tmp_path / "h.wvc")
    full = wvol.open(tmp_path / "h.wvc")
    part = wvol.open(tmp_path / "h.wvc", level=2)
    np.testing.assert_allclose(part.reconstruct(level=2).data, full.reconstruct(level=2).data, atol=1e-5)
    assert np.abs(part.coeffs[:, :, 20:]).max() == 0          # finest x-detail bands not decoded


def test_explicit_step(vol, tmp_path):
    s = wvol.compress(vol, "db2", 2)
    coarse = s.save(tmp_path / "c.wvc", step=0.05)
    fine = s.save(tmp_path / "f.wvc", step=0.001)
    assert coarse["step"] == 0.05 and coarse["bytes"] < fine["bytes"]
    assert coarse["sse_quant"] > fine["sse_quant"]


def test_files_errors(vol, tmp_path):
    s = wvol.compress(vol, "db2", 2, keep=0.1)
    with pytest.raises(OSError):
        wvol.open(tmp_path / "missing.wvc")
    with pytest.raises(OSError):
        s.save(tmp_path / "no" / "dir" / "x.wvc")
    assert not list(tmp_path.glob("**/*.tmp*"))                 # nothing partial left
    p = tmp_path / "x.wvc"
    s.save(p)
    data = bytearray(p.read_bytes())
    (tmp_path / "trunc.wvc").write_bytes(data[: len(data) // 2])
    with pytest.raises(OSError, match="trunc.wvc: .wvc "):
        wvol.open(tmp_path / "trunc.wvc")
    data[-5] ^= 0xFF                                             # payload bit flip: CRC mismatch
    (tmp_path / "flip.wvc").write_bytes(data)
    with pytest.raises(OSError, match="flip.wvc: .wvc chunk .*checksum mismatch"):
        wvol.open(tmp_path / "flip.wvc")
    (tmp_path / "junk.wvc").write_bytes(b"not a wvc file at all" * 20)
    with pytest.raises(OSError, match=r"junk.wvc: not a .wvc file \(wrong magic bytes\)"):
        wvol.wvc_info(tmp_path / "junk.wvc")
    for kw, words in ((dict(step=-1.0), "step must be finite and > 0, got -1$"),
                      (dict(step=float("nan")), "step must be finite and > 0, got nan$"),
                      (dict(quant_share=0), r"quant_share must be in \(0, 1\], got 0$")):
        with pytest.raises(ValueError, match=words):
            s.save(tmp_path / "y.wvc", **kw)
    with pytest.raises(ValueError):
        wvol.open(p, level=-1)


@pytest.mark.parametrize("call, exc, words", [
    (lambda s, d: wvol.open(d / "missing.wvc"), OSError, "cannot open"),
    (lambda s, d: wvol.open(d), OSError, "not a regular file"),
    (lambda s, d: wvol.open(123), TypeError, "PathLike"),
    (lambda s, d: wvol.open(d / "x.wvc", level="fine"), TypeError, "level: expected an int"),
    (lambda s, d: wvol.wvc_info(d / "missing.wvc"), OSError, "cannot open"),
    (lambda s, d: wvol.wvc_info(None), TypeError, ""),
    (lambda s, d: s.save(d), ValueError, "must end in .wvc"),             # a directory, named so
    (lambda s, d: (os.mkdir(d / "w.wvc"), s.save(d / "w.wvc")), OSError, "not a regular file"),
    (lambda s, d: s.save(None), TypeError, ""),
    (lambda s, d: s.save(d / "y.wvc", quant_share=float("nan")), ValueError, "quant_share"),
])
def test_bad_paths_and_arguments(vol, tmp_path, call, exc, words):
    s = wvol.compress(vol, "haar", 1, keep=0.5)
    s.save(tmp_path / "x.wvc")
    with pytest.raises(exc, match=words):
        call(s, tmp_path)


def test_stores_of_odd_shapes_round_trip(tmp_path):
    """Padded grids (not multiples of 2**levels) and an axis of one sample."""
    for shape in [(5, 7, 9), (1, 12, 10)]:
        a = np.random.default_rng(7).random(shape, dtype=np.float32)
        s = wvol.compress(a, "db2", 2, keep=0.5)
        s.save(tmp_path / "o.wvc")
        o = wvol.open(tmp_path / "o.wvc")
        assert o.shape == shape and o.coeffs.shape == s.coeffs.shape
        # the reconstructions differ only by quantisation: below its reported error
        # (squared error over the padded grid >= over the voxels), 1e-6 for float32 rounding
        d = o.reconstruct().data.astype(np.float64) - s.reconstruct().data
        assert np.sum(d * d) <= o.file_info["sse_quant"] * (1 + 1e-4) + 1e-6
