# SPDX-License-Identifier: MIT
"""wvol.isoimage(store, method="exact"): the exact f^ tracer from Python gives the CLI's image
(`wvol iso --method raytrace`) for the same store, camera and iso-value."""
import json

import numpy as np
import pytest

import wvol as wv
from test_render import gaussian_raw, read_exr_rgba


@pytest.mark.parametrize("keep", [0.2, 1.0])
def test_exact_matches_the_cli(wvol, tmp_path, keep):
    n = 24
    raw = gaussian_raw(tmp_path / "g.raw", n)
    cam, size, iso = "persp dir=1,0.6,-0.3", (20, 16), 0.5
    out = tmp_path / "x.exr"
    r = wvol("iso", raw, "--dims", f"{n}x{n}x{n}", "--iso", iso, "--method", "raytrace", "--wavelet", "db2",
             "--levels", "3", "--keep", f"{keep * 100:g}%", "--size", f"{size[0]}x{size[1]}", "--camera", cam,
             "-o", out, "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    # the EXR's channels are A, B, G, R, Z, one scanline of each after the other
    z_cli = read_exr_rgba(out).reshape(size[1], 5, size[0])[:, 4, :]

    vol = wv.Volume(np.fromfile(raw, "<f4").reshape(n, n, n))
    s = wv.compress(vol, "db2", 3, keep=keep)
    rgba, z_py, st = wv.isoimage(s, iso, cam, size, method="exact", return_stats=True)
    assert st["method"] == "exact" and st["rays"] == size[0] * size[1] and st["grazes"] == 0
    assert st["hits"] == info["hits"] > 0 and st["cells"] > 0
    # the same rays and the same traced model: identical hit masks and depths (both float32 of
    # the same double; the cell grid's classes do not depend on the thread count or ray order)
    assert np.array_equal(np.isfinite(z_py), np.isfinite(z_cli))
    hit = np.isfinite(z_py)
    assert np.array_equal(z_py[hit], z_cli[hit])
    assert np.all(rgba[..., 3][hit] == 1) and np.all(rgba[..., 3][~hit] == 0)
