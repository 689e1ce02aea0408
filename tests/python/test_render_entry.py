# SPDX-License-Identifier: MIT
"""`wvol render` and wvol.render call the same library entry point (wvol_render) with the same
defaults: for the same input they pick the same method and make the same image, float for
float (the CLI's EXR is float32, losslessly coded): a volume at 100% (reference), a 5% store
built from it (bricks; X-ray along an axis: axis) and a .wvc file (the same)."""
import json

import numpy as np
import pytest

import wvol
from conftest import run_wvol
from test_render import read_exr_rgba

SIZE = (40, 32)
PERSP = "persp dir=1,0.7,0.4"
CASES = [  # (camera, mode, the method auto picks for a store)
    (PERSP, "absorption", "bricks"),
    ("-y", "absorption-linear", "bricks"),
    ("+z", "xray", "axis"),
    ("ortho dir=1,0.5,0.3", "xray", "bricks"),
]


@pytest.fixture(scope="module")
def volume_file(tmp_path_factory):
    # anisotropic spacing and an origin off zero: the geometry travels through the file; every
    # axis a multiple of 2^3, so the axis fast path applies to the store
    v = wvol.synth.blobs(shape=(24, 32, 40), seed=5, spacing=(1.0, 0.5, 2.0))
    path = tmp_path_factory.mktemp("entry") / "blobs.nrrd"
    wvol.save(v, path)
    return path


def cli_render(src, out, camera, mode, *extra):
    r = run_wvol("render", src, "-o", out, "--size", f"{SIZE[0]}x{SIZE[1]}", "--camera", camera, "--mode", mode,
                 "--json", *extra)
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    rgba = read_exr_rgba(out).reshape(SIZE[1], 4, SIZE[0])          # per row: channels A, B, G, R
    return info["method"], np.ascontiguousarray(rgba[:, ::-1, :].transpose(0, 2, 1))


def py_render(source, camera, mode):
    img, st = wvol.render(source, camera=camera, size=SIZE, mode=mode, return_stats=True)
    return st["method"], img


def assert_same(cli, py, method):
    (m_cli, img_cli), (m_py, img_py) = cli, py
    assert m_cli == m_py == method
    assert img_py.shape == img_cli.shape == (SIZE[1], SIZE[0], 4)
    assert np.array_equal(img_py, img_cli), f"{method}: max |diff| {np.abs(img_py - img_cli).max()}"
    assert img_py[..., 3].max() > 0.1                                # the volume is in view


@pytest.mark.parametrize("camera, mode, _", CASES)
def test_volume_renders_alike(volume_file, tmp_path, camera, mode, _):
    cli = cli_render(volume_file, tmp_path / "v.exr", camera, mode)
    assert_same(cli, py_render(wvol.load(volume_file), camera, mode), "reference")


@pytest.mark.parametrize("camera, mode, method", CASES)
def test_store_renders_alike(volume_file, tmp_path, camera, mode, method):
    cli = cli_render(volume_file, tmp_path / "s.exr", camera, mode, "--keep", "5%")
    store = wvol.compress(wvol.load(volume_file), "db2", keep=0.05)  # the CLI's render store is db2
    assert_same(cli, py_render(store, camera, mode), method)


@pytest.mark.parametrize("camera, mode, method", CASES)
def test_wvc_renders_alike(volume_file, tmp_path, camera, mode, method):
    wvc = tmp_path / "b.wvc"
    r = run_wvol("compress", volume_file, "-o", wvc, "--keep", "5%", "--levels", "3")
    assert r.returncode == 0, r.stderr
    cli = cli_render(wvc, tmp_path / "w.exr", camera, mode)
    assert_same(cli, py_render(wvol.open(wvc), camera, mode), method)
