# SPDX-License-Identifier: MIT
"""wvol render --colors: the segmentation's colour volume replaces the TF colour."""
import numpy as np
import pytest
from PIL import Image

N = 64


def srgb(v):
    v = np.clip(v, 0, 1)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)


@pytest.fixture
def segmented(wvol, tmp_path):
    img, lab, rgb = tmp_path / "t.raw", tmp_path / "lab.raw", tmp_path / "rgb.raw"
    wvol("synth", "textures", "-o", img, "--size", f"{N}x{N}x1", "--labels", lab, check=True)
    wvol("segment", img, "--dims", f"{N}x{N}x1", "--colors", rgb, check=True)
    return img, rgb


def test_each_pixel_takes_its_voxels_class_colour(wvol, segmented, tmp_path):
    img, rgb = segmented
    tf = tmp_path / "flat.tf"
    # constant kappa = 3 per world unit: every ray crosses one voxel (nz = 1), alpha = 1 - e^-3
    tf.write_text("units world\n-1e6 1 1 1 3\n1e6 1 1 1 3\n")
    out = tmp_path / "seg.png"
    r = wvol("render", img, "--dims", f"{N}x{N}x1", "--colors", rgb, "--tf", tf, "--camera", "+z",
             "--size", f"{N}x{N}", "--exposure", "1", "-o", out)
    assert r.returncode == 0, r.stderr
    got = np.asarray(Image.open(out).convert("RGB"), dtype=float)
    colours = np.fromfile(rgb, "<f4").reshape(N, N, 3)[::-1]  # image row 0 is the top (+y)
    want = np.round(255 * srgb((1 - np.exp(-3.0)) * colours))
    assert len(np.unique(colours.reshape(-1, 3), axis=0)) >= 3  # several classes are on show
    # 8-bit rounding: at most one step apart
    assert np.abs(got - want).max() <= 1.0


@pytest.mark.parametrize("extra,words", [
    (["--mode", "xray"], "absorption mode"),
    (["--method", "spline", "--keep", "50%"], "reference"),
    (["--method", "axis"], "reference"),
])
def test_colours_refused_where_they_cannot_apply(wvol, segmented, tmp_path, extra, words):
    img, rgb = segmented
    r = wvol("render", img, "--dims", f"{N}x{N}x1", "--colors", rgb, "-o", tmp_path / "x.png", *extra)
    assert r.returncode == 2 and words in r.stderr
    assert not (tmp_path / "x.png").exists()


def test_wrong_sized_colour_file_refused(wvol, segmented, tmp_path):
    img, _ = segmented
    bad = tmp_path / "short.raw"
    np.zeros(3 * N * N - 1, "<f4").tofile(bad)
    r = wvol("render", img, "--dims", f"{N}x{N}x1", "--colors", bad, "-o", tmp_path / "x.png")
    assert r.returncode == 1 and "short.raw: file has" in r.stderr and "float32 samples need" in r.stderr
    assert not (tmp_path / "x.png").exists()
    nan = tmp_path / "nan.raw"
    c = np.full(3 * N * N, 0.5, "<f4")
    c[10] = np.nan
    c.tofile(nan)
    r = wvol("render", img, "--dims", f"{N}x{N}x1", "--colors", nan, "-o", tmp_path / "x.png")
    assert r.returncode == 1 and "nan.raw: NaN at voxel (i=10, j=0, k=0)" in r.stderr
