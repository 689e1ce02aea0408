# SPDX-License-Identifier: MIT
"""wvol.isoimage: the bricked caster of the trilinear interpolant (volumes and stores) and the
exact f^ tracer (stores), their depth maps and refusals."""
import numpy as np
import pytest

import wvol


@pytest.fixture(scope="module")
def gauss():
    return wvol.synth.gaussian(shape=(32, 32, 32), spacing=(0.5, 0.5, 0.5))


def test_cast_depth_is_the_sphere(gauss):
    # orthographic along -z: the first crossing of f = 0.5 (a sphere of radius 0.294 * 8 around
    # the centre, docs/datasets.md) is at the sphere's near side; trilinear interpolation of a
    # 2-voxel-per-unit grid puts it within 2% of the radius
    rgba, depth, st = wvol.isoimage(gauss, 0.5, "ortho +z", (48, 48), return_stats=True)
    assert rgba.shape == (48, 48, 4) and depth.shape == (48, 48) and depth.dtype == np.float32
    hit = np.isfinite(depth)
    assert st["hits"] == hit.sum() > 0 and np.all(rgba[..., 3][hit] == 1) and np.all(rgba[..., 3][~hit] == 0)
    # the depth varies like a sphere's: from the pole (nearest) to the silhouette pixels, which
    # lie within a pixel of the equator (a pixel is ~0.3 world units here), about a radius
    centre = depth[hit].min()
    far = depth[hit].max()
    r = 0.294 * 8
    assert 0.75 * r < far - centre < 1.02 * r


def test_store_cast_matches_reconstruction_and_exact_is_close(gauss):
    s = wvol.compress(gauss, "db2", 3, keep=0.2)
    rec = wvol.Volume(s.reconstruct(), spacing=(0.5, 0.5, 0.5), origin=gauss.origin)
    _, z_store = wvol.isoimage(s, 0.5, "persp dir=1,0.6,-0.3", (24, 24), brick=8)
    _, z_rec = wvol.isoimage(rec, 0.5, "persp dir=1,0.6,-0.3", (24, 24), brick=8)
    both = np.isfinite(z_store) & np.isfinite(z_rec)
    # the store's bricks and the whole reconstruction round differently in float32 only
    assert (np.isfinite(z_store) != np.isfinite(z_rec)).sum() <= 2
    assert np.abs(z_store[both] - z_rec[both]).max() < 1e-3
    # f^ (db2, not interpolating) and the interpolant: the same surface within a voxel
    _, z_exact, st = wvol.isoimage(s, 0.5, "persp dir=1,0.6,-0.3", (24, 24), method="exact", return_stats=True)
    assert st["method"] == "exact" and st["grazes"] == 0
    both = np.isfinite(z_store) & np.isfinite(z_exact)
    assert both.sum() > 0.9 * np.isfinite(z_store).sum()
    assert np.abs(z_store[both] - z_exact[both]).max() < 0.5 * 2  # a voxel is 0.5 world units; 2 voxels


def test_model_bound_in_stats(gauss):
    s = wvol.compress(gauss, "db4", 3, keep=1.0)
    _, _, st = wvol.isoimage(s, 0.5, "persp dir=1,0.6,-0.3", (16, 16), brick=8, model_bound=True, return_stats=True)
    assert st["fhat_bound_bricks"] + st["fhat_bound_faces"] == st["bricks_built"] > 0
    # 8-cell bricks of a 32^3 grid: the inner ones' windows reach no face, so some are bounded
    assert st["fhat_bound_bricks"] > 0
    assert 0 < st["fhat_bound_mean"] <= st["fhat_bound_max"] < float("inf")
    _, _, st = wvol.isoimage(s, 0.5, "persp dir=1,0.6,-0.3", (16, 16), brick=8, return_stats=True)
    assert st["fhat_bound_bricks"] == 0 and st["fhat_bound_max"] == 0


def test_refusals(gauss):
    with pytest.raises(ValueError, match="Store"):
        wvol.isoimage(gauss, 0.5, method="exact")
    with pytest.raises(ValueError, match="expected 'cast' or 'exact'"):
        wvol.isoimage(gauss, 0.5, method="mesh")
    with pytest.raises(ValueError, match="finite"):
        wvol.isoimage(gauss, float("nan"))
    with pytest.raises(ValueError):
        wvol.isoimage(gauss, 0.5, brick=2)
