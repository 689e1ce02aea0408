# SPDX-License-Identifier: MIT
"""wvol.isosurface from volumes and from stores."""
import numpy as np
import pytest

import wvol
from mesh_util import area, enclosed_volume, euler_if_watertight


@pytest.fixture(scope="module")
def gauss():
    return wvol.synth.gaussian(shape=(32, 32, 32), spacing=(0.5, 0.5, 0.5))


def test_sphere_of_the_gaussian(gauss):
    v, f, n = wvol.isosurface(gauss, 0.5)
    assert v.dtype == np.float32 and v.shape[1] == 3
    assert f.dtype == np.uint32 and f.shape[1] == 3 and f.max() < len(v)
    assert n.shape == v.shape
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1, atol=1e-5)
    # f = 0.5 on the sphere of radius 0.294 * E / 2, E = 32 * 0.5 = 16 (docs/datasets.md);
    # linear interpolation on a 2-voxel-per-unit grid: within 2% of the radius
    r = np.linalg.norm(v, axis=1)
    assert abs(r.mean() - 0.294 * 8) < 0.02 * 0.294 * 8
    # normals point outward (from f >= iso to f < iso): along +r
    assert (np.sum(n * v, axis=1) > 0).mean() > 0.99
    # triangles wound outward: positive enclosed volume, close to the sphere's
    vol = enclosed_volume(v, f)
    assert abs(vol - 4 / 3 * np.pi * (0.294 * 8) ** 3) < 0.05 * vol
    # closed and consistently wound, one sphere (Euler characteristic 2); its area within 2%
    # of the sphere's (measured 0.6% below: the chords of linear interpolation cut inside)
    assert euler_if_watertight(v, f) == 2
    assert abs(area(v, f) - 4 * np.pi * (0.294 * 8) ** 2) < 0.02 * area(v, f)


def test_store_path_matches_dense_path(gauss):
    s = wvol.compress(gauss, "db2", 3, keep=0.05)
    v1, f1, _ = wvol.isosurface(s, 0.5, brick=8)
    v2, f2, _ = wvol.isosurface(s.reconstruct(), 0.5)
    assert len(f1) == len(f2) and len(v1) == len(v2)
    # same surface up to the float rounding of the two reconstructions: vertex for vertex (rows
    # sorted by their coordinates rounded to 1e-3, so that rounding cannot reorder them), 1e-5
    def rows(v):
        return v[np.lexsort(np.round(v, 3).T[::-1])]
    np.testing.assert_allclose(rows(v1), rows(v2), rtol=0, atol=1e-5)
    # stitched by global edge ids: as closed as the dense mesh, same area (rounding: 1e-4)
    assert euler_if_watertight(v1, f1) == euler_if_watertight(v2, f2) == 2
    assert abs(area(v1, f1) - area(v2, f2)) < 1e-4 * area(v2, f2)
    *_, st = wvol.isosurface(s, 0.9, brick=8, return_stats=True)
    # 31 cells per axis in bricks of 8: 4^3 bricks, each skipped (bound) or meshed
    assert st["bricks_total"] == 64 and st["bricks_skipped"] + st["bricks_meshed"] == 64


def test_empty_and_no_normals(gauss):
    v, f, n, st = wvol.isosurface(gauss, 5.0, return_stats=True)
    assert v.shape == (0, 3) and f.shape == (0, 3) and st["empty"] and "outside" in st["message"]
    v, f, n = wvol.isosurface(gauss.data, 0.5, normals="none")
    assert n is None and len(f) > 0


@pytest.mark.parametrize("call, exc, words", [
    (lambda g: wvol.isosurface(g, float("nan")), ValueError, "finite"),
    (lambda g: wvol.isosurface(g, "half"), TypeError, ""),
    (lambda g: wvol.isosurface(g, 0.5, normals="magic"), ValueError, "normals 'magic'"),
    (lambda g: wvol.isosurface(g, 0.5, brick=4), ValueError, "brick"),
    (lambda g: wvol.isosurface(g, 0.5, threads=-1), ValueError, "threads"),
    (lambda g: wvol.isosurface(g, 0.5, threads=10 ** 6), ValueError, "threads"),
    (lambda g: wvol.isosurface(wvol.compress(g, "haar", 1), 0.5, brick=-1), ValueError, "brick"),
    (lambda g: wvol.isosurface(wvol.compress(g, "haar", 1), float("inf")), ValueError, "finite"),
    (lambda g: wvol.isosurface(g.data.astype(complex), 0.5), TypeError, ""),
    (lambda g: wvol.isosurface(np.zeros((0, 2, 2)), 0.5), ValueError, ""),
    (lambda g: wvol.isosurface(np.full((4, 4, 4), np.nan), 0.5), ValueError, "NaN"),
    (lambda g: wvol.isosurface(np.zeros(4), 0.5), ValueError, ""),
])
def test_bad_input(gauss, call, exc, words):
    with pytest.raises(exc, match=words):
        call(gauss)


def test_views_and_2d():
    """Non-contiguous and float64 views are converted; the mesh is the same as from a copy."""
    g = wvol.synth.gaussian(shape=(32, 32, 32)).data.astype(np.float64)
    view = g[::2, ::2, ::2]
    v1, f1, _ = wvol.isosurface(view, 0.5)
    v2, f2, _ = wvol.isosurface(np.ascontiguousarray(view, dtype=np.float32), 0.5)
    assert np.array_equal(v1, v2) and np.array_equal(f1, f2) and len(f1) > 0
    # a 2D array is one slice: no cells along z, an empty mesh with the reason
    v, f, n, st = wvol.isosurface(g[16], 0.5, return_stats=True)
    assert len(f) == 0 and st["empty"] and "cells" in st["message"]


def test_save_mesh_formats(gauss, tmp_path):
    v, f, n = wvol.isosurface(gauss, 0.5)
    wvol.save_mesh(tmp_path / "s.ply", v, f, n)
    head = (tmp_path / "s.ply").read_bytes()[:400].decode("latin1")
    assert f"element vertex {len(v)}" in head and f"element face {len(f)}" in head and "property float nx" in head
    wvol.save_mesh(tmp_path / "s.obj", v, f)
    lines = (tmp_path / "s.obj").read_text().splitlines()
    assert sum(ln.startswith("v ") for ln in lines) == len(v) and sum(ln.startswith("f ") for ln in lines) == len(f)
    wvol.save_mesh(tmp_path / "s.stl", v, f)
    assert (tmp_path / "s.stl").stat().st_size == 84 + 50 * len(f)     # binary STL
    for bad, exc in [((v, f[:, :2]), ValueError), ((v, f + len(v)), ValueError), ((v[:, :2], f), ValueError),
                     ((v, f, n[:-1]), ValueError), ((np.full_like(v, np.nan), f), ValueError)]:
        with pytest.raises(exc):
            wvol.save_mesh(tmp_path / "bad.ply", *bad)
    with pytest.raises(NotImplementedError, match="unknown mesh format"):
        wvol.save_mesh(tmp_path / "s.xyz", v, f)
    with pytest.raises(OSError, match="cannot create output file"):
        wvol.save_mesh(tmp_path / "no" / "s.ply", v, f)
