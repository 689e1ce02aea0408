# SPDX-License-Identifier: MIT
"""The Python-level round trip of issue 8: synth -> compress -> save -> open -> reconstruct ->
render -> isosurface, with each stage checked against the one before."""
import numpy as np

import wvol
from mesh_util import area, euler_if_watertight


def test_synth_compress_save_open_reconstruct_render_isosurface(tmp_path):
    vol = wvol.synth.gaussian(shape=(32, 32, 32), noise=0.01, seed=4)
    store = wvol.compress(vol, "db2", 3, keep=0.05)
    assert store.kept == round(0.05 * 32 ** 3)
    # 32^3 is not padded: Parseval makes the prediction the measured error (float32 rounding)
    assert abs(store.predicted_error.l2 - store.measured_error().l2) < 1e-3 * store.predicted_error.l2

    # ---- save / open ----
    rep = store.save(tmp_path / "g.wvc")
    assert rep["bytes"] == (tmp_path / "g.wvc").stat().st_size
    opened = wvol.open(tmp_path / "g.wvc")
    assert (opened.shape, opened.wavelet, opened.levels) == (store.shape, store.wavelet, store.levels)
    assert opened.file_info["sse_quant"] == rep["sse_quant"] > 0

    # ---- reconstruct ----
    rec = opened.reconstruct()
    assert rec.data.shape == vol.data.shape and rec.spacing == vol.spacing and rec.origin == vol.origin
    # the orthonormal transform (Parseval, no padding): the squared difference between the
    # reconstructions of the opened and the in-memory store is the quantisation error the
    # file reports; the two float32 inverse transforms add ~1e-7 per voxel (measured
    # agreement 1e-6 relative), 1e-3 leaves room
    diff = rec.data.astype(np.float64) - store.reconstruct().data
    assert abs(np.sum(diff * diff) - opened.file_info["sse_quant"]) < 1e-3 * opened.file_info["sse_quant"]
    err = opened.measured_error(vol)
    assert abs(opened.predicted_error.l2 - err.l2) < 1e-3 * err.l2        # dropped + quantisation
    assert err.psnr > 35                                                # noise sigma 0.01 of peak 1: ~40 dB

    # ---- render: X-ray along z three ways ----
    axis = wvol.render(opened, camera="+z", size=(32, 32), mode="xray", method="axis")
    spline = wvol.render(opened, camera="+z", size=(32, 32), mode="xray", method="spline")
    ref = wvol.render(rec, camera="+z", size=(32, 32), mode="xray", method="reference")
    for img in (axis, spline, ref):
        assert img.shape == (32, 32, 4) and img.dtype == np.float32 and np.isfinite(img).all()
    # the axis fast path equals the spline integrator to rounding (render.h): float32 pixels
    # of magnitude ~10, 1e-5 of the peak
    np.testing.assert_allclose(axis, spline, rtol=0, atol=1e-5 * spline.max())
    # spline model f^ vs trilinear samples of the reconstruction: the same function up to
    # the model difference (largest at the peak, a few % there), so compare the total and
    # the mean per-pixel difference (measured: 1e-7 relative and 0.4% of the peak pixel)
    a, b = spline[..., 0].astype(np.float64), ref[..., 0].astype(np.float64)
    assert abs(a.sum() - b.sum()) < 1e-5 * b.sum()  # measured 1e-7: float32 sums of ~256 pixels
    assert np.abs(a - b).mean() < 0.01 * b.max()
    # emission-absorption from the store (spline integrator; tiny image, it is the slow one)
    colour = wvol.render(opened, camera="persp dir=1,1,0.5", size=(9, 9), method="spline")
    assert np.isfinite(colour).all() and 0 <= colour[..., 3].min() and colour[..., 3].max() <= 1
    assert colour[4, 4, 3] > 0.5 and colour[0, 0, 3] < colour[4, 4, 3]

    # ---- isosurface: brick by brick from the store vs marching cubes on the reconstruction ----
    v, f, n = wvol.isosurface(opened, 0.5)
    v2, f2, _ = wvol.isosurface(rec, 0.5)
    assert len(f) == len(f2) > 100
    assert euler_if_watertight(v, f) == 2                               # one closed sphere-like surface
    # same surface up to the float rounding of the two reconstructions (measured 1e-7)
    assert abs(area(v, f) - area(v2, f2)) < 1e-4 * area(v2, f2)
    r = np.linalg.norm(v.astype(np.float64), axis=1)
    assert abs(r.mean() - 0.294 * 16) < 0.03 * 0.294 * 16                # the f = 0.5 sphere
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1, atol=1e-5)
