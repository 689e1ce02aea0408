# SPDX-License-Identifier: MIT
"""Level of detail by screen size (docs/render.md, "Level of detail") through `wvol render`,
`wvol iso --level` and Python's wvol.render(lod=...) / wvol.isosurface(level=...): the
coarse frame is the frame of `wvol decompress --level`'s volume, the reported extra error is
the dropped levels' energy, --full-resolution / lod=False renders the full grid, marching
cubes at a level is marching cubes on the coarse decode, and bad levels are refused."""
import json

import numpy as np
import pytest

import wvol as wv
from test_render import read_exr_rgba

N = 64
# an explicit camera: "+z" would frame each grid's own box, and the coarse grid's box is
# shifted by its origin convention; the frame must be of the same world view
ORTHO = "ortho eye=0,0,-300 center=0,0,0 up=0,1,0 height=240"


@pytest.fixture(scope="module")
def skull(tmp_path_factory):
    """A 64^3 skull (.nrrd, spacing 3.75) and its .wvc (db2, 3 levels, 60 dB)."""
    from conftest import run_wvol
    d = tmp_path_factory.mktemp("lod")
    vol, wvc = d / "s.nrrd", d / "s.wvc"
    run_wvol("synth", "skull", "--size", N, "-o", vol, check=True)
    run_wvol("compress", vol, "-o", wvc, "--psnr", "60", "--levels", "3", check=True)
    return vol, wvc


def render_json(wvol, src, out, *extra):
    r = wvol("render", src, "-o", out, "--size", "16x16", "--camera", ORTHO, "--tf", "ct-bone", "--json", *extra)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def test_render_picks_the_level_of_the_pixel_footprint(wvol, skull, tmp_path):
    vol, wvc = skull
    # 240 world units over 16 pixels: a 15-unit footprint, 4 voxels of 3.75: level 2
    info = render_json(wvol, wvc, tmp_path / "a.exr")
    lod = info["lod"]
    assert lod["enabled"] == 1 and lod["level"] == 2 and lod["levels"] == 3
    assert lod["footprint"] == pytest.approx(15.0) and lod["voxel"] == pytest.approx(15.0)
    assert lod["dims"] == [16, 16, 16] and info["method"] == "reference"
    assert lod["energy"] > 0 and lod["rmse"] > 0 and np.isfinite(lod["psnr"])
    full = render_json(wvol, wvc, tmp_path / "b.exr", "--full-resolution")
    assert full["lod"]["enabled"] == 0 and full["lod"]["level"] == 0 and full["lod"]["energy"] == 0
    assert full["method"] == "bricks" and full["lod"]["dims"] == [N, N, N]
    # the text report names the level and the error
    r = wvol("render", wvc, "-o", tmp_path / "c.exr", "--size", "16x16", "--camera", ORTHO, "--tf", "ct-bone")
    assert r.returncode == 0 and "level of detail: level 2 of 3" in r.stdout and "PSNR" in r.stdout, r.stdout


def test_coarse_frame_is_the_frame_of_the_coarse_decode(wvol, skull, tmp_path):
    vol, wvc = skull
    render_json(wvol, wvc, tmp_path / "lod.exr")
    r = wvol("decompress", wvc, "--level", "2", "-o", tmp_path / "c2.nrrd")
    assert r.returncode == 0, r.stderr
    info = render_json(wvol, tmp_path / "c2.nrrd", tmp_path / "dec.exr", "--full-resolution", "--method",
                       "reference")
    a, b = read_exr_rgba(tmp_path / "lod.exr"), read_exr_rgba(tmp_path / "dec.exr")
    peak = abs(b).max()
    # the same reference integrator on the same coarse grid: the file store's level and the
    # whole decode's agree to float rounding (1e-5 of the range), so the images to far within
    # 1e-4 of their peak; the transfer function is the same preset (ct-bone is in Hounsfield
    # units, not the data range)
    assert info["lod"]["level"] == 0 and 0 < peak and abs(a - b).max() <= 1e-4 * peak


def test_reported_error_is_the_dropped_levels_energy(wvol, skull, tmp_path):
    """Parseval: the detail energy of levels 1..L is the full model's energy minus that of the
    level-L low-pass cube, whose samples (`decompress --level L`) are the low-pass coefficients
    times 2^{-3L/2}; 64 is a multiple of 2^3, so nothing is padded."""
    vol, wvc = skull
    lod = render_json(wvol, wvc, tmp_path / "a.exr")["lod"]
    L = lod["level"]
    for lv, name in ((0, "f.raw"), (L, "c.raw")):
        assert wvol("decompress", wvc, "--level", lv, "-o", tmp_path / name).returncode == 0
    f = np.fromfile(tmp_path / "f.raw", np.float32).astype(np.float64)
    c = np.fromfile(tmp_path / "c.raw", np.float32).astype(np.float64)
    want = (f ** 2).sum() - 2.0 ** (3 * L) * (c ** 2).sum()
    # the file's band energies are the encoder's (before quantisation), the decodes' are after:
    # at 60 dB the quantisation error changes the energy by ~1e-6 of the total
    assert lod["energy"] == pytest.approx(want, rel=1e-3)
    assert lod["rmse"] == pytest.approx(np.sqrt(lod["energy"] / N ** 3), rel=1e-9)


def test_iso_level_is_marching_cubes_on_the_coarse_decode(wvol, skull, tmp_path):
    vol, wvc = skull
    for L in (1, 2):
        r = wvol("iso", wvc, "--iso", "400", "--level", L, "--json", "-o", tmp_path / f"l{L}.ply")
        assert r.returncode == 0, r.stderr
        a = json.loads(r.stdout)
        assert wvol("decompress", wvc, "--level", L, "-o", tmp_path / f"d{L}.nrrd").returncode == 0
        r = wvol("iso", tmp_path / f"d{L}.nrrd", "--iso", "400", "--json")
        assert r.returncode == 0, r.stderr
        b = json.loads(r.stdout)
        n = N >> L
        assert a["level"] == L and a["level_dims"] == [n, n, n] and a["level_energy"] > 0
        assert a["level_spacing"] == pytest.approx([3.75 * 2 ** L] * 3)
        # the same grid to float rounding: the same cells cross 400 (the values sit far from it
        # on a smooth phantom); the area to 1e-5
        assert a["triangles"] == b["triangles"] > 0 and a["area"] == pytest.approx(b["area"], rel=1e-5)
    # from the dense volume (db2 levels, its own transform) the coarse grid is the level's too
    r = wvol("iso", vol, "--iso", "400", "--level", "1", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["level_dims"] == [32, 32, 32]


def test_bad_levels_are_refused(wvol, skull, tmp_path):
    vol, wvc = skull
    r = wvol("iso", wvc, "--iso", "400", "--level", "4", "-o", tmp_path / "x.ply")
    assert r.returncode == 2 and "level 4 outside 0..3" in r.stderr and not (tmp_path / "x.ply").exists()
    r = wvol("iso", wvc, "--iso", "400", "--level", "-1")
    assert r.returncode == 2 and "--level '-1': expected an integer from 0 to 30" in r.stderr
    r = wvol("iso", wvc, "--iso", "400", "--level", "1", "--method", "cast")
    assert r.returncode == 2 and "--level applies only to --method mc" in r.stderr


def test_python_lod(skull):
    vol, wvc = skull
    v = np.asarray(wv.synth.skull(shape=(N, N, N)), np.float32)
    s = wv.compress(v, "db2", 3)
    kw = dict(size=(16, 16), camera="+z", mode="xray", method="bricks", return_stats=True)
    img, st = wv.render(s, **kw)
    assert st["lod_level"] == 2 and st["lod_dims"] == (16, 16, 16) and st["method"] == "reference"
    assert st["lod_energy"] > 0 and st["lod_rmse"] == pytest.approx(np.sqrt(st["lod_energy"] / N ** 3))
    full, sf = wv.render(s, lod=False, **kw)
    assert sf["lod_level"] == 0 and sf["method"] == "bricks" and sf["lod_energy"] == 0
    forced, s1 = wv.render(s, lod_level=1, **kw)
    assert s1["lod_level"] == 1 and s1["lod_dims"] == (32, 32, 32)
    # the coarse X-ray integrates the same field, smoothed: on average within 2% of the image's
    # range of the full one (edges move most: 4 voxels a pixel), where a wrong grid (a shifted
    # origin, a wrong scale) would be off by tens of percent
    rng = float(full[..., 0].max() - full[..., 0].min())
    assert rng > 0 and np.abs(img[..., 0] - full[..., 0]).mean() < 0.02 * rng
    with pytest.raises(ValueError, match="level of detail 4 outside 0..3"):
        wv.render(s, lod_level=4, **kw)
    # marching cubes at a level: the store's and the dense volume's coarse grids
    verts, faces, normals, ist = wv.isosurface(s, 400.0, level=1, return_stats=True)
    assert ist["level"]["dims"] == (32, 32, 32) and len(faces) > 0
    assert ist["level"]["spacing"] == pytest.approx((2.0, 2.0, 2.0))
    with pytest.raises(ValueError, match="level 4 outside 0..3"):
        wv.isosurface(s, 400.0, level=4)
    with pytest.raises(ValueError):
        wv.isosurface(v, 400.0, level=-1)
