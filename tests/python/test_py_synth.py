# SPDX-License-Identifier: MIT
"""wvol.synth.*: shapes, geometry, labels, determinism, bad arguments."""
import inspect

import numpy as np
import pytest

import wvol


def test_kinds_list_every_generator():
    names = {k[0] for k in wvol.synth.kinds()}
    assert names == {"gaussian", "blobs", "skull", "textures", "shepp-logan", "turbulence"}
    with_labels = {k[0] for k in wvol.synth.kinds() if k[2]}
    assert with_labels == {"skull", "textures"}


def test_gaussian_values_and_centred_geometry():
    v = wvol.synth.gaussian(shape=(17, 19, 21), sigma=0.25)
    assert v.data.shape == (17, 19, 21) and v.data.dtype == np.float32
    assert v.spacing == (1.0, 1.0, 1.0)
    # centred on world 0: origin = -(n - 1) / 2 * spacing per axis (x, y, z)
    assert v.origin == (-10.0, -9.0, -8.0)
    # peak 1 at the centre voxel, exp(-|u|^2 / (2 sigma^2)) with u = x / (E / 2), E = 21
    assert abs(v.data[8, 9, 10] - 1.0) < 1e-6
    u = 5.0 / 10.5
    assert abs(v.data[8, 9, 15] - np.exp(-u * u / (2 * 0.25 ** 2))) < 1e-5
    assert v.labels is None


def test_seed_noise_and_determinism():
    a = wvol.synth.blobs(shape=(16, 16, 16), seed=5)
    b = wvol.synth.blobs(shape=(16, 16, 16), seed=5)
    c = wvol.synth.blobs(shape=(16, 16, 16), seed=6)
    assert np.array_equal(a.data, b.data) and not np.array_equal(a.data, c.data)
    n = wvol.synth.gaussian(shape=(32, 32, 32), noise=0.1, seed=2)
    clean = wvol.synth.gaussian(shape=(32, 32, 32))
    resid = (n.data - clean.data).astype(np.float64)
    # 32768 Gaussian samples: the sample sigma is within 3% of 0.1 (its s.e. is 0.4%)
    assert abs(resid.std() - 0.1) < 0.003 and abs(resid.mean()) < 0.003


def test_skull_and_textures_have_labels():
    s = wvol.synth.skull(shape=(24, 32, 32), spacing=(1.5, 1.5, 2.0))
    assert s.spacing == (1.5, 1.5, 2.0)
    assert s.labels.shape == s.data.shape and s.labels.dtype == np.int32
    assert set(np.unique(s.labels)) <= {0, 1, 2, 3, 4}
    assert s.data[s.labels == 4].mean() > 500 and s.data[s.labels == 0].min() <= -900   # bone vs air HU
    t = wvol.synth.textures(shape=(1, 48, 48), count=5, variant="dots")
    assert t.data.shape == (1, 48, 48)
    assert set(np.unique(t.labels)) == set(range(5))
    assert 0 <= t.data.min() and t.data.max() <= 1


def test_shepp_logan_variants():
    a = wvol.synth.shepp_logan(shape=(32, 32, 32))
    b = wvol.synth.shepp_logan(shape=(32, 32, 32), variant="yu-ye-wang")
    assert abs(a.data.max() - 2.0) < 1e-6 and abs(b.data.max() - 1.0) < 1e-6   # outer shell densities
    assert wvol.synth.make("shepp-logan", shape=(32, 32, 32)).data.tobytes() == a.data.tobytes()


@pytest.mark.parametrize("call, exc, words", [
    (lambda: wvol.synth.gaussian(shape=(0, 4, 4)), ValueError, "every dimension must be >= 1"),
    (lambda: wvol.synth.gaussian(shape=(4, 4)), TypeError, r"shape must be \(nz, ny, nx\)"),
    (lambda: wvol.synth.gaussian(shape=(4, 4, 4), spacing=(1, 0, 1)), ValueError, "three positive values"),
    (lambda: wvol.synth.gaussian(shape=(4, 4, 4), noise=-1), ValueError, "noise must be finite and >= 0"),
    (lambda: wvol.synth.gaussian(shape=(4, 4, 4), noise=float("nan")), ValueError, "noise must be finite"),
    (lambda: wvol.synth.gaussian(shape=(4, 4, 4), seed=-1), ValueError, "seed must be an integer"),
    (lambda: wvol.synth.blobs(shape=(4, 4, 4), count=1000), ValueError, "count 1000 must be from 1 to 64"),
    (lambda: wvol.synth.textures(shape=(4, 16, 16), variant="plaid"), ValueError, "unknown variant 'plaid'"),
    (lambda: wvol.synth.make("teapot"), ValueError, "unknown synthetic volume 'teapot'"),
])
def test_bad_arguments_raise(call, exc, words):
    with pytest.raises(exc, match=words):
        call()


def test_default_sizes_are_the_generators():
    """shape=None everywhere, and the sizes docs/datasets.md gives, as the CLI and make() have them."""
    want = {"gaussian": (32, 32, 32), "blobs": (64, 64, 64), "skull": (128, 128, 128), "textures": (1, 256, 256),
            "shepp_logan": (128, 128, 128), "turbulence": (128, 128, 128)}
    for name, shape in want.items():
        fn = getattr(wvol.synth, name)
        assert inspect.signature(fn).parameters["shape"].default is None, name
        if name in ("gaussian", "blobs", "textures"):  # the small ones: made, not only declared
            assert fn().data.shape == shape, name
            assert wvol.synth.make(name.replace("_", "-")).data.shape == shape, name
