# SPDX-License-Identifier: MIT
"""wvol.render from volumes and stores."""
import numpy as np
import pytest

import wvol


@pytest.fixture(scope="module")
def gauss():
    return wvol.synth.gaussian(shape=(16, 16, 16))


def test_xray_of_a_volume_integrates_along_the_axis(gauss):
    img = wvol.render(gauss, camera="+z", size=(16, 16), mode="xray")
    assert img.shape == (16, 16, 4) and img.dtype == np.float32
    # along z, with pixel centres on voxel centres (docs/render.md): the integral of the
    # trilinear field over the volume's box (a cell per sample, the end cells clamped) is the
    # sum of the samples along the column, which the midpoint rule at half-voxel steps on the
    # knots integrates exactly: equal to float32 rounding of the sums (1e-6 relative)
    col = gauss.data.astype(np.float64).sum(axis=0)                 # (y, x)
    ref = col[::-1, :]                                               # image row 0 = top = +y
    np.testing.assert_allclose(img[..., 0], ref, rtol=1e-6, atol=1e-6 * ref.max())
    assert np.all(img[..., 3] == 1)


def test_absorption_modes_and_tf(gauss):
    a = wvol.render(gauss, size=(24, 20))
    assert a.shape == (20, 24, 4)
    assert 0 <= a[..., 3].min() and a[..., 3].max() <= 1 and a[10, 12, 3] > a[0, 0, 3]
    tf = [(0.0, 1, 0, 0, 0.0), (1.0, 1, 0, 0, 2.0)]                  # red, opacity up to 2 / unit
    r = wvol.render(gauss, size=(24, 20), tf=tf)
    assert np.all(r[..., 1] == 0) and r[..., 0].max() > 0           # only red light
    assert np.array_equal(wvol.render(gauss, size=(24, 20), tf=np.array(tf, np.float32)), r)   # (n, 5) array
    lin = wvol.render(gauss, size=(24, 20), tf=tf, mode="absorption-linear")
    assert np.isfinite(lin).all()


def test_store_methods_agree(gauss):
    s = wvol.compress(gauss, "db2", 2, keep=0.2)
    spline = wvol.render(s, size=(16, 16), mode="xray", method="spline")
    axis = wvol.render(s, size=(16, 16), mode="xray", method="axis")
    # the axis fast path equals the spline integrator to rounding (render.h): 1e-5 of the peak,
    # as in test_render_spline.c
    np.testing.assert_allclose(axis, spline, atol=1e-5 * spline.max())
    ref = wvol.render(s, size=(16, 16), mode="xray", method="reference")
    # f^ vs trilinear samples of the reconstruction: same integral to a few percent
    np.testing.assert_allclose(spline[..., 0], ref[..., 0], atol=0.05 * ref.max())
    img, st = wvol.render(s, size=(16, 16), camera="persp dir=1,1,0.5", method="spline", return_stats=True)
    assert st["rays"] == 256 and img.shape == (16, 16, 4)


def test_splat_is_the_spline_xray_for_oblique_views(gauss):
    # the splat fast path against the exact spline-projected X-ray of the same store; on this
    # smooth volume the tables' interpolation error measures 7e-5 of the peak (C tests:
    # noisy volumes, every family, 4e-4..4.4e-3), allowed 1e-3
    s = wvol.compress(gauss, "db2", 2, keep=0.2)
    for cam in ("ortho dir=1,0.7,0.4", "ortho dir=-1,0.2,-0.5 zoom=1.5"):
        spline = wvol.render(s, camera=cam, size=(20, 16), mode="xray", method="spline")
        splat, st = wvol.render(s, camera=cam, size=(20, 16), mode="xray", method="splat", return_stats=True)
        assert np.array_equal(splat[..., 3], spline[..., 3])
        assert np.sqrt(np.mean((splat - spline)[..., 0] ** 2)) < 1e-3 * spline[..., 0].max()
        assert st["rays_hit"] > 0 and st["functions"] >= s.kept


@pytest.mark.parametrize("kw, exc", [
    (dict(camera="sideways"), ValueError),
    (dict(size=(0, 16)), ValueError),
    (dict(mode="mri"), ValueError),
    (dict(tf="no-such-preset"), ValueError),
    (dict(tf=[(0.0, 1, 1)]), TypeError),
    (dict(tf=[(1.0, 1, 1, 1, 1), (0.0, 1, 1, 1, 1)]), ValueError),   # values must increase
    (dict(step=0), ValueError),
    (dict(step=float("nan")), ValueError),
    (dict(method="spline"), ValueError),                              # needs a store
    (dict(tf_units="furlongs", tf=[(0.0, 1, 1, 1, 1)]), ValueError),
    (dict(camera=3), TypeError),
    (dict(size=(8,)), ValueError),
    (dict(tf="/nonexistent/dir/tf.txt"), ValueError),                 # not a file: read as a preset name
    (dict(tf=[(float("nan"), 1, 1, 1, 1)]), ValueError),
    (dict(tf=[(0.0, 1, 1, 1, -1)]), ValueError),                      # negative opacity
    (dict(tf=[]), ValueError),
    (dict(tf=[1, 2, 3]), TypeError),
    (dict(threads=10 ** 6), ValueError),                              # refused, not an OpenMP abort
    (dict(termination=float("inf")), ValueError),
    (dict(skip_tolerance=-0.1), ValueError),
    (dict(skip_tolerance=float("nan")), ValueError),
    (dict(preintegrate=True, mode="xray"), ValueError),                # X-ray is linear already
    (dict(preintegrate=True, mode="absorption-linear"), ValueError),
    (dict(gradient_levels=-1), ValueError),
    (dict(gradient_levels=1, shading=True), NotImplementedError),     # a dense volume has no model
])
def test_bad_arguments(gauss, kw, exc):
    kw.setdefault("size", (8, 8))
    with pytest.raises(exc):
        wvol.render(gauss, **kw)


def test_store_reference_methods_and_options(gauss, tmp_path):
    s = wvol.compress(gauss, "db2", 2, keep=0.2)
    fhat = wvol.render(s, size=(12, 12), mode="xray", method="reference-fhat")
    spline = wvol.render(s, size=(12, 12), mode="xray", method="spline")
    # ray marching over f^ (step 0.5 voxel) converges to the exact spline integral: 1% of the peak
    np.testing.assert_allclose(fhat[..., 0], spline[..., 0], atol=0.01 * spline.max())
    # auto on a store in X-ray along an axis is the axis fast path (off-axis: bricks)
    np.testing.assert_allclose(wvol.render(s, size=(12, 12), mode="xray"), spline, atol=1e-5 * spline.max())
    # a transfer-function file, the per-diagonal units and shading (Lambert from the gradient)
    (tmp_path / "tf.txt").write_text("units diagonal\n0 0 1 0 0\n1 0 1 0 8\n")
    flat = wvol.render(gauss, size=(12, 12), tf=tmp_path / "tf.txt")
    shaded = wvol.render(gauss, size=(12, 12), tf=str(tmp_path / "tf.txt"), shading=True, ambient=0.2)
    assert np.all(flat[..., [0, 2]] == 0) and flat[..., 1].max() > 0     # green only
    # shading changes colour, not opacity: the unshaded one-colour frame sums kappa in single
    # precision (a relative few 1e-8 of each block's optical depth), the shaded one composites
    # sample by sample in double, so alpha agrees to float32 rounding (measured: 6e-8)
    np.testing.assert_allclose(flat[..., 3], shaded[..., 3], rtol=0, atol=4e-7)
    assert not np.array_equal(flat[..., 1], shaded[..., 1])
    # a store read back from a file renders the same as the one it was saved from, up to
    # quantisation (1% of the peak)
    s.save(tmp_path / "s.wvc")
    o = wvol.open(tmp_path / "s.wvc")
    np.testing.assert_allclose(wvol.render(o, size=(12, 12), mode="xray"), spline, atol=0.01 * spline.max())


def test_preintegrate_and_lowpass_gradient(gauss):
    # a steep TF, viewed along z with pixels on voxel centres: at step 1 the samples fall on the
    # voxel centres, between which the trilinear field along the ray is exactly linear, so the
    # pre-integrated image is the converged one (measured 3e-5; the segments' quadrature and the
    # converged image's own step error), while the classic one under-samples the ramp (0.27)
    tf = [(0.5, 1, 0.5, 0.2, 0), (0.55, 1, 1, 1, 6), (0.9, 0.3, 0.5, 1, 9)]
    conv = wvol.render(gauss, size=(16, 16), tf=tf, step=0.005)
    pre = wvol.render(gauss, size=(16, 16), tf=tf, step=1.0, preintegrate=True)
    classic = wvol.render(gauss, size=(16, 16), tf=tf, step=1.0)
    assert np.abs(pre - conv).max() < 3e-4 * conv.max()
    assert np.abs(classic - conv).max() > 0.05 * conv.max()
    # the low-pass gradient changes the shading of a store's bricks render, not its alpha
    s = wvol.compress(gauss, "db2", 2, keep=0.3)
    sh = wvol.render(s, size=(16, 16), tf=tf, method="bricks", shading=True)
    lp = wvol.render(s, size=(16, 16), tf=tf, method="bricks", shading=True, gradient_levels=2)
    assert np.array_equal(sh[..., 3], lp[..., 3]) and not np.array_equal(sh[..., :3], lp[..., :3])
    with pytest.raises(ValueError, match="levels"):
        wvol.render(s, size=(8, 8), method="bricks", shading=True, gradient_levels=3)


@pytest.mark.parametrize("kw, exc, words", [
    (dict(method="magic"), ValueError, "method"),
    (dict(method="axis", mode="xray", camera="ortho dir=1,1,0"), NotImplementedError, "axis"),
    (dict(method="axis"), ValueError, "X-ray only"),
    (dict(method="splat"), ValueError, "X-ray only"),
    (dict(method="splat", mode="xray", camera="persp dir=1,1,0"), NotImplementedError, "orthographic"),
    (dict(method="reference-fhat", spline_j=40), ValueError, "spline_j must be in 0..12"),
    (dict(method="spline", spline_j=-1), ValueError, "spline_j"),
    (dict(gauss_nodes=0), ValueError, r"gauss_nodes 0 \(1..10\)"),
    (dict(method="spline", skip_tolerance=1e-3), NotImplementedError, "skip tolerance"),
])
def test_bad_store_arguments(gauss, kw, exc, words):
    s = wvol.compress(gauss, "haar", 1, keep=0.5)
    with pytest.raises(exc, match=words):
        wvol.render(s, size=(4, 4), **kw)


def test_bad_volumes():
    for arr, exc in [(np.zeros((0, 4, 4)), ValueError), (np.full((4, 4, 4), np.inf), ValueError),
                     (np.zeros((4, 4, 4), complex), TypeError)]:
        with pytest.raises(exc):
            wvol.render(arr, size=(8, 8))


# ---- colour volumes (the segmentation's colours replace the TF colour) ----

def test_uniform_colour_volume_gives_colour_times_alpha(gauss):
    c = np.array([0.2, 0.5, 0.9], np.float32)
    colors = np.broadcast_to(c, gauss.shape + (3,))                    # a read-only, non-contiguous view
    plain = wvol.render(gauss, size=(12, 12))
    img = wvol.render(gauss, size=(12, 12), colors=colors)
    # kappa still comes from the TF: the same opacity; emission = c kappa, so RGB = c A
    # exactly up to float32 accumulation (1e-5 of A)
    assert np.array_equal(img[..., 3], plain[..., 3]) and img[..., 3].max() > 0.3
    np.testing.assert_allclose(img[..., :3], c * img[..., 3:], rtol=0, atol=1e-5)
    # a store: auto picks bricks (the spline paths have no voxels to colour)
    s = wvol.compress(gauss, "db2", 2, keep=0.2)
    simg = wvol.render(s, size=(12, 12), colors=colors)
    np.testing.assert_allclose(simg[..., :3], c * simg[..., 3:], rtol=0, atol=1e-5)
    ref = wvol.render(s, size=(12, 12), colors=colors, method="reference")
    np.testing.assert_allclose(ref[..., :3], c * ref[..., 3:], rtol=0, atol=1e-5)


def test_segmentation_colours_render():
    vol = wvol.synth.blobs(shape=(16, 16, 16), seed=2)
    seg = wvol.segment(vol, levels=2, iterations=500)
    img = wvol.render(vol, size=(16, 16), colors=seg.colors, camera="persp dir=1,1,1")
    plain = wvol.render(vol, size=(16, 16), camera="persp dir=1,1,1")
    assert np.isfinite(img).all() and np.array_equal(img[..., 3], plain[..., 3])
    # premultiplied colours from [0, 1] lattice colours: each channel within [0, A]
    assert np.all(img[..., :3] <= img[..., 3:] + 1e-6) and img[..., :3].max() > 0
    # a 2D image takes (y, x, 3) colours
    flat = wvol.render(vol.data[8], size=(16, 16), colors=seg.colors[8])
    assert flat.shape == (16, 16, 4) and np.isfinite(flat).all()


@pytest.mark.parametrize("colors, kw, exc, words", [
    (np.zeros((16, 16, 16, 4)), {}, ValueError, "colors must be"),
    (np.zeros((16, 16, 16)), {}, ValueError, "colors must be"),
    (np.zeros((8, 16, 16, 3)), {}, ValueError, r"\(16, 16, 16, 3\)"),
    (np.zeros((16, 16, 16, 3), complex), {}, TypeError, "real numbers"),
    (np.full((16, 16, 16, 3), np.nan), {}, ValueError, "finite"),
    (np.full((16, 16, 16, 3), -1.0), {}, ValueError, ">= 0"),
    (np.zeros((16, 16, 16, 3)), dict(mode="xray"), ValueError, "absorption mode"),
    ("red", {}, TypeError, ""),
])
def test_bad_colours(gauss, colors, kw, exc, words):
    with pytest.raises(exc, match=words):
        wvol.render(gauss, size=(4, 4), colors=colors, **kw)


def test_colours_refused_by_the_spline_paths(gauss):
    s = wvol.compress(gauss, "haar", 1, keep=0.5)
    ones = np.ones(gauss.shape + (3,), np.float32)
    for kw in (dict(method="spline"), dict(method="axis", mode="xray"), dict(method="splat", mode="xray")):
        with pytest.raises(NotImplementedError, match="reference"):
            wvol.render(s, size=(4, 4), colors=ones, **kw)


def test_skip_tolerance_bounds_each_pixel():
    # a compressed shell's ringing leaves a faint haze around it; kappa linear from 0 makes the
    # haze (slightly) opaque, so only the tolerance skips it, and each pixel's alpha moves by
    # at most the depth skipped (stats["skip_bound"] <= the tolerance; + float rounding)
    v = np.asarray(wvol.synth.skull(shape=(48, 48, 48)))
    u = ((v - v.min()) / (v.max() - v.min())).astype(np.float32)
    r = wvol.compress(u, "db2", 2, keep=0.05).reconstruct()
    tf = [(0.0, 1, 1, 1, 0.0), (1.0, 1, 1, 1, 8.0)]
    kw = dict(size=(32, 32), camera="persp dir=1,0.7,0.4", tf=tf, tf_units="diagonal", return_stats=True)
    a, sa = wvol.render(r, **kw)
    b, sb = wvol.render(r, skip_tolerance=0.01, **kw)
    assert sb["skipped_tolerance"] > 0 and 0 < sb["skip_bound"] <= 0.01
    assert sb["samples"] < sa["samples"]
    assert np.abs(a[..., 3] - b[..., 3]).max() <= sb["skip_bound"] + 2e-6


def test_bricks_from_a_store_is_the_reference_on_its_reconstruction():
    # method="bricks" renders the store's reconstruction brick by brick (never the whole
    # volume): the reference integrator's image of s.reconstruct() up to float rounding (the
    # bricks synthesise in double, the whole inverse in float: 1e-5 of the peak), with the
    # skip tolerance and a colour volume as for "reference"
    v = np.asarray(wvol.synth.skull(shape=(40, 36, 44)))
    u = ((v - v.min()) / (v.max() - v.min())).astype(np.float32)
    s = wvol.compress(u, "db2", 2, keep=0.05)
    tf = [(0.0, 1, 0.9, 0.8, 0.0), (1.0, 1, 0.9, 0.8, 8.0)]
    kw = dict(size=(24, 20), camera="persp dir=1,0.7,0.4", tf=tf, tf_units="diagonal", return_stats=True,
              lod=False)
    b, sb = wvol.render(s, method="bricks", **kw)
    r, _ = wvol.render(s.reconstruct(), method="reference", **kw)
    assert sb["bricks_built"] > 0 and sb["brick"] in (16, 32)
    assert np.abs(b - r).max() <= 1e-5 * np.abs(r).max()
    t, st = wvol.render(s, method="bricks", skip_tolerance=0.01, **kw)
    assert st["skip_bound"] <= 0.01 and np.abs(t[..., 3] - b[..., 3]).max() <= st["skip_bound"] + 2e-6
    colors = np.zeros(u.shape + (3,), np.float32)
    colors[..., 1] = 1.0
    g, _ = wvol.render(s, method="bricks", colors=colors, **kw)
    assert np.allclose(g[..., 0], 0) and np.allclose(g[..., 1], b[..., 3], atol=1e-6)


def test_render_context_keeps_the_set_up_and_the_image():
    """render(..., context=ctx): frames of one Store through a RenderContext equal the frames
    without it bit for bit, later frames take bricks built in earlier ones (and the two threads
    walk tiles of their own there, the one-shot calls sharing each tile), a TF with other
    opacities drops the rates, another Store drops everything, and a volume renders as usual."""
    v = wvol.synth.skull(shape=(40, 44, 36))
    s = wvol.compress(v, "db2", 2, keep=0.05)
    s2 = wvol.compress(v, "db2", 2, keep=0.2)
    ctx = wvol.RenderContext()
    kw = dict(size=(40, 32), method="bricks", brick=8, lod=False, tf="grey", return_stats=True, threads=2)
    for f, cam in enumerate(["persp dir=1,0.7,0.4", "persp dir=1,0.75,0.4", "persp dir=1,0.7,0.4"]):
        a, sa = wvol.render(s, cam, context=ctx, **kw)
        b, sb = wvol.render(s, cam, **kw)
        assert np.array_equal(a, b) and a[..., 3].max() > 0.1
        assert sa["context_frame"] == f + 1 and sb["context_frame"] == 0 and sa["samples"] == sb["samples"]
        assert sa["rates_reused"] == (f > 0)
        assert sa["tiles_own"] == (f > 0) and sb["tiles_own"] == 0
        if f:
            assert sa["bricks_reused"] > 0 and 0 < sa["cache_bytes"] <= sa["bytes"]
    tf = [(0.3, 1, 1, 1, 0.0), (1.0, 1, 0.5, 0.2, 40.0)]
    kw2 = dict(kw, tf=tf)
    a, sa = wvol.render(s, "+y", context=ctx, **kw2)
    assert np.array_equal(a, wvol.render(s, "+y", **kw2)[0]) and sa["rates_reused"] == 0
    a, sa = wvol.render(s2, "+y", context=ctx, **kw2)
    assert np.array_equal(a, wvol.render(s2, "+y", **kw2)[0]) and sa["context_frame"] == 1
    a, sa = wvol.render(v, "+y", context=ctx, size=(40, 32), return_stats=True)
    assert np.array_equal(a, wvol.render(v, "+y", size=(40, 32))) and sa["method"] == "reference"
    with pytest.raises(TypeError):
        wvol.render(s, "+y", context="not a context")
    with pytest.raises(ValueError):
        wvol.RenderContext(cache_bytes=-1)


def test_coarse_levels_sit_on_the_volume_for_every_filter(tmp_path):
    # a level-L function is centred (2^L - 1) x the filter's centre voxels in: for coif2 and bl3
    # the coarse grid started inside the volume and wrapped its end around (coif2 level 3: its
    # samples correlated 0.22 with the volume at their own positions; bl3's lay outside it).
    # Rolled by wvol_level_shift, every filter's level samples the volume where it says
    v = wvol.synth.blobs(shape=(37, 50, 29), spacing=(0.5, 0.75, 1.25))
    A, o0, sp = np.asarray(v.data), np.array(v.origin), np.array(v.spacing)
    for wavelet in ("coif2", "bl3", "db2", "haar"):
        path = tmp_path / f"{wavelet}.wvc"
        wvol.compress(v, wavelet, 3, psnr=60).save(path)
        s = wvol.open(path)
        for L in (1, 2, 3):
            c = s.reconstruct(level=L)
            a = np.asarray(c.data)
            off = (np.array(c.origin) - o0) / sp  # the first sample's centre, in voxels: in the first cell
            assert np.all((off >= 0) & (off < 2 ** L)), (wavelet, L, off)
            idx = [np.clip(np.round(off[ax] + np.arange(a.shape[2 - ax]) * 2 ** L).astype(int), 0,
                           A.shape[2 - ax] - 1) for ax in range(3)]
            ref = A[np.ix_(idx[2], idx[1], idx[0])]
            assert np.corrcoef(a.ravel(), ref.ravel())[0, 1] > 0.8, (wavelet, L)  # db2 level 3 (4x7x5): 0.89
            # the file's region read of the level is the same grid
            r = wvol.wvc_region(path, [0, 0, 0], list(a.shape[::-1]), level=L)
            r = np.asarray(r[0] if isinstance(r, tuple) else r)
            assert np.abs(r - a).max() <= 1e-5 * np.abs(a).max(), (wavelet, L)
    # and a frame drawn from a coarse level lines up with the full one (coif2 at 128^3: the
    # mean difference was 0.08, db2's 0.005)
    t = wvol.synth.turbulence(shape=(64, 64, 64))
    for wavelet in ("coif2", "db2"):
        wvol.compress(t, wavelet, psnr=50).save(tmp_path / "t.wvc")
        s = wvol.open(tmp_path / "t.wvc")
        kw = dict(mode="absorption", tf="grey")
        a, st = wvol.render(s, "persp dir=1,0.6,-0.3", (16, 16), return_stats=True, **kw)
        full = wvol.render(s, "persp dir=1,0.6,-0.3", (16, 16), lod=False, **kw)
        assert st["lod_level"] > 0 and np.abs(a - full)[..., :3].mean() < 0.05, wavelet
