# SPDX-License-Identifier: MIT
"""wvol.transport and `wvol transport`: Haar round trips, form factors, energy, quadrature
convergence, degenerate geometry, refused input, the stained-glass run's outputs."""
import json
import math

import numpy as np
import pytest
from PIL import Image

import wvol
from conftest import run_wvol

T = wvol.transport
FLOOR = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]      # normal +z
CEILING = [[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]]    # z = 1, normal -z
WALL = [[0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]]       # x = 0, normal +x


def ff_parallel(a, b, c):
    """Howell C-11: directly opposed parallel rectangles a x b at distance c."""
    X, Y = a / c, b / c
    x1, y1 = math.sqrt(1 + X * X), math.sqrt(1 + Y * Y)
    return 2 / (math.pi * X * Y) * (math.log(x1 * y1 / math.sqrt(1 + X * X + Y * Y)) + X * y1 * math.atan(X / y1)
                                    + Y * x1 * math.atan(Y / x1) - X * math.atan(X) - Y * math.atan(Y))


def test_haar_round_trip_is_exact_on_piecewise_constant_cells():
    rng = np.random.default_rng(3)
    coarse = rng.random((4, 4, 4, 4, 3), dtype=np.float32)
    cells = coarse.repeat(2, 0).repeat(2, 1).repeat(2, 2).repeat(2, 3)      # constant on 2^4 blocks
    back, nodes, ncoef = T.haar(cells)
    # float32 butterflies over 3 levels: a few ulps
    assert np.max(np.abs(back - cells)) <= 1e-5
    # the finest level's details all vanish: nodes only at levels 0 and 1
    assert nodes <= 1 + 16
    assert ncoef <= 3 * (1 + 15 + 16 * 15)


@pytest.mark.parametrize("dst,ff", [(CEILING, ff_parallel(1, 1, 1)), (WALL, 0.2000438)])
def test_constant_radiance_gives_the_form_factor(dst, ff):
    cells = np.ones((2, 2, 2, 2, 3), np.float32)
    got, stats = T.transport(cells, FLOOR, dst, levels=3, quadrature="stratified", samples=256)
    p = T.power(got, dst)
    # received power = L pi A_s F; 256 jittered points per coefficient: measured errors ~1e-4
    assert p == pytest.approx([math.pi * ff] * 3, rel=1e-3)
    assert stats["evaluated"] > 0 and stats["oracle_zero"] > 0


def test_oracle_changes_only_the_work():
    cells = np.ones((2, 2, 2, 2, 3), np.float32)
    a, sa = T.transport(cells, FLOOR, CEILING, levels=3, quadrature="hammersley", samples=16, oracle=True)
    b, sb = T.transport(cells, FLOOR, CEILING, levels=3, quadrature="hammersley", samples=16, oracle=False)
    # the oracle is exact where it answers (interval bounds): the same cells up to float32 sums
    assert np.max(np.abs(a - b)) <= 1e-5 * np.max(np.abs(b))
    assert sa["evaluated"] < sb["evaluated"]


def test_energy_between_facing_surfaces_and_reflection():
    d = T.scene(levels=2, quadrature="hammersley", samples=64)
    src, inc, out = (np.array(d[k]) for k in ("power_window", "power_floor_in", "power_floor_out"))
    assert np.all(inc > 0) and np.all(inc <= src)      # what misses the floor is lost, nothing is made
    # tiles reflect at most kd + ks = 0.75 of what they receive (measured 0.68); 1% for the
    # reflection's quadrature (64 Hammersley directions over the lobe)
    assert np.all(out > 0) and np.all(out <= 0.75 * inc * 1.01)
    assert np.all(np.isfinite(d["incident"])) and np.all(np.isfinite(d["reflected"]))


def red(a, ref):
    return np.linalg.norm(a - ref) / np.linalg.norm(ref)


def test_red_falls_as_samples_grow_for_every_rule():
    win = [[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]]
    floor = [[-0.5, -1, 0], [2.5, -1, 0], [2.5, 2, 0], [-0.5, 2, 0]]
    j = (1, 0, 0, 1, 1)
    ref = T.coefficients(win, floor, j, 2, "stratified", 128 * 128)
    for q in T.QUADRATURES:
        lo = red(T.coefficients(win, floor, j, 2, q, 16), ref)
        hi = red(T.coefficients(win, floor, j, 2, q, 1100), ref)
        assert hi < 0.5 * lo, (q, lo, hi)    # 16 -> ~1000 samples: even N^-1/2 gives 8x


@pytest.mark.parametrize("dst", [
    [[0, 0, 1e-9], [1, 0, 1e-9], [1, 1, 2e-9], [0, 1, 2e-9]],                 # grazing
    [[1, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0]],                              # coplanar
    [[1, 0, 0], [1, 1, 0], [2, 1, 0], [2, 0, 0]],                              # coplanar, facing down
    [[0.5, -0.5, -0.5], [0.5, 1.5, -0.5], [0.5, 1.5, 1.5], [0.5, -0.5, 1.5]],  # crossing the source
])
def test_grazing_and_coplanar_geometry_gives_no_nan(dst):
    cells = np.ones((4, 4, 4, 4, 3), np.float32)
    for q in T.QUADRATURES:
        got, _ = T.transport(cells, FLOOR, dst, levels=2, quadrature=q, samples=16)
        assert np.all(np.isfinite(got)), q


def test_bad_input_is_refused(tmp_path):
    cells = np.ones((2, 2, 2, 2, 3), np.float32)
    with pytest.raises(ValueError, match="degenerate"):
        T.transport(cells, [[0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 0, 0]], CEILING)
    with pytest.raises(ValueError, match="non-planar"):
        T.transport(cells, [[0, 0, 0], [1, 0, 0], [1, 1, 0.5], [0, 1, 0]], CEILING)
    with pytest.raises(ValueError, match="parallelogram"):
        T.transport(cells, [[0, 0, 0], [1, 0, 0], [1.5, 1, 0], [0, 1, 0]], CEILING)
    with pytest.raises(ValueError, match="not finite"):
        T.transport(cells, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, math.nan, 0]], CEILING)
    bad = cells.copy()
    bad[1, 0, 1, 0, 2] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        T.transport(bad, FLOOR, CEILING)
    with pytest.raises(ValueError, match="quadrature"):
        T.transport(cells, FLOOR, CEILING, quadrature="simpson")
    with pytest.raises(ValueError, match="shape"):
        T.transport(np.ones((3, 3, 3, 3, 3), np.float32), FLOOR, CEILING)
    grey = tmp_path / "grey.png"
    Image.fromarray(np.zeros((8, 8), np.uint8), mode="L").save(grey)
    with pytest.raises(OSError, match="RGB"):     # a format error: OSError, like other bad files
        T.window(str(grey))
    with pytest.raises(OSError, match="nope.png"):
        T.window(str(tmp_path / "nope.png"))


def test_window_png_round_trip(tmp_path):
    rgb = np.zeros((16, 16, 3), np.uint8)
    rgb[:, 8:, 0] = 255
    p = tmp_path / "w.png"
    Image.fromarray(rgb, mode="RGB").save(p)
    w = T.window(str(p))
    assert w.shape == (16, 16, 3)
    assert w[0, 12, 0] == pytest.approx(1.0) and w[0, 3, 0] == 0 and w[5, 5, 1] == 0


def test_cli_writes_the_papers_pictures(tmp_path):
    out = tmp_path / "out"
    r = run_wvol("transport", "-o", out, "--levels", "2", "--quadrature", "halton", "--samples", "16", "--size",
                 "64x48", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["quadrature"] == "halton" and d["levels"] == 2 and d["coefficients_evaluated"] > 0
    assert d["kept_coefficients"] <= math.ceil(0.05 * d["coefficients_before"]) + 3
    for name in ("window.png", "incident.png", "incident.exr", "detail.png", "reflected.png", "incident_keep.png",
                 "floor_0.png", "floor_3.exr"):
        assert (out / name).stat().st_size > 0, name
    im = np.asarray(Image.open(out / "floor_1.png"))
    assert im.shape == (48, 64, 3) and im.max() > 0


def test_cli_refuses_bad_input(tmp_path):
    r = run_wvol("transport", "-o", tmp_path, "--quadrature", "simpson")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "simpson" in r.stderr
    grey = tmp_path / "grey.png"
    Image.fromarray(np.zeros((8, 8), np.uint8), mode="L").save(grey)
    r = run_wvol("transport", "-o", tmp_path / "o", "--window", grey, "--levels", "1")
    assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1 and "RGB" in r.stderr
    r = run_wvol("transport", "--levels", "2")
    assert r.returncode == 2 and "output" in r.stderr
    r = run_wvol("transport", "--help")
    assert r.returncode == 0 and "--window" in r.stdout


@pytest.mark.parametrize("g,words", [(1e80, r"coordinates must lie within \+-1e60"), (1e-100, "at least 1e-60 long")])
def test_scenes_beyond_the_integrals_range_are_refused(g, words):
    """The transfer integrals take fourth powers of lengths: at 1e80 they came out 0 (no error), at
    1e-100 the refusal spoke of an area of 0. Both now name the range; 1e50 still transports."""
    cells = np.ones((2, 2, 2, 2, 3), np.float32)
    scaled = lambda q, s: [[s * c for c in p] for p in q]  # noqa: E731
    with pytest.raises(ValueError, match=words):
        T.transport(cells, scaled(FLOOR, g), scaled(CEILING, g), levels=2)
    ref, _ = T.transport(cells, FLOOR, CEILING, levels=2)
    big, _ = T.transport(cells, scaled(FLOOR, 1e50), scaled(CEILING, 1e50), levels=2)
    # radiance transported between facing squares does not depend on the scale
    assert np.allclose(big, ref, rtol=1e-6) and np.abs(ref).max() > 0
