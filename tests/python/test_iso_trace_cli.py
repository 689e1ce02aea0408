# SPDX-License-Identifier: MIT
"""wvol iso --method raytrace | hybrid: images of f^ = theta from a store (EXR with a Z depth
channel, PNG), an empty image with a note for an iso-value outside the range, bad output refused."""
import json

import numpy as np

from test_render import N, gaussian_raw, png_size, read_exr_rgba

import pytest


@pytest.fixture
def vol(tmp_path):
    return gaussian_raw(tmp_path / "g.raw")


def exr_channels(path):
    """Channel names from the EXR header's chlist attribute (plain text in the header)."""
    data = path.read_bytes()
    assert data[:4] == b"\x76\x2f\x31\x01"  # OpenEXR magic
    i = data.index(b"channels\x00chlist\x00") + len(b"channels\x00chlist\x00") + 4
    names = []
    while data[i] != 0:
        j = data.index(b"\x00", i)
        names.append(data[i:j].decode())
        i = j + 1 + 16  # name, then pixel type, linear, reserved, x and y sampling
    return names


def depth_where_hit(path, info, w, h):
    """Per row the channels A, B, G, R, Z: a depth where a ray hit (positive: in front of the
    eye of a perspective camera), none (Inf) elsewhere, and full alpha exactly there."""
    px = read_exr_rgba(path).reshape(h, 5, w)
    z, alpha = px[:, 4, :], px[:, 0, :]
    hit = np.isfinite(z)
    assert hit.sum() == info["hits"] and (z[hit] > 0).all()
    assert (alpha[hit] == 1).all() and (alpha[~hit] == 0).all()


def test_raytrace_exr_has_depth(wvol, vol, tmp_path):
    out = tmp_path / "s.exr"
    r = wvol("iso", vol, "--dims", f"{N}x{N}x{N}", "--iso", "0.5", "--method", "raytrace", "--keep", "20%",
             "--size", "24x20", "--camera", "persp dir=1,0.5,0.3", "-o", out, "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["method"] == "raytrace" and info["rays"] == 24 * 20
    assert 0 < info["hits"] < 24 * 20 and info["grazes"] == 0 and info["empty"] == 0
    assert sorted(exr_channels(out)) == ["A", "B", "G", "R", "Z"]
    depth_where_hit(out, info, 24, 20)


def test_raytrace_png_and_text_report(wvol, vol, tmp_path):
    out = tmp_path / "s.png"
    r = wvol("iso", vol, "--dims", f"{N}x{N}x{N}", "--iso", "0.5", "--method", "raytrace", "--size", "30x16",
             "-o", out)
    assert r.returncode == 0, r.stderr
    assert png_size(out) == (30, 16)
    assert "hits" in r.stdout and "us per ray" in r.stdout


def test_raytrace_iso_outside_range_is_empty_not_an_error(wvol, vol, tmp_path):
    out = tmp_path / "e.exr"
    r = wvol("iso", vol, "--dims", f"{N}x{N}x{N}", "--iso", "7", "--method", "raytrace", "--size", "8x8",
             "-o", out, "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["hits"] == 0 and info["empty"] == 1 and "outside the range" in info["message"]
    r = wvol("iso", vol, "--dims", f"{N}x{N}x{N}", "--iso", "7", "--method", "raytrace", "--size", "8x8", "-o", out)
    assert r.returncode == 0 and "outside the range" in r.stderr


def test_hybrid_png(wvol, vol, tmp_path):
    out = tmp_path / "h.png"
    r = wvol("iso", vol, "--dims", f"{N}x{N}x{N}", "--iso", "0.6", "--method", "hybrid", "--tf", "gaussian",
             "--size", "16x16", "-o", out, "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["method"] == "hybrid" and info["hits"] > 0 and info["volume_seconds"] >= 0
    assert png_size(out) == (16, 16)


def test_image_methods_refuse_mesh_outputs(wvol, vol, tmp_path):
    r = wvol("iso", vol, "--dims", f"{N}x{N}x{N}", "--iso", "0.5", "--method", "raytrace", "-o", tmp_path / "m.ply")
    assert r.returncode == 2 and ".exr" in r.stderr
    r = wvol("iso", vol, "--dims", f"{N}x{N}x{N}", "--iso", "0.5", "--method", "nope")
    assert r.returncode == 2 and "mc, cast, raytrace or hybrid" in r.stderr
    r = wvol("iso", vol, "--dims", f"{N}x{N}x{N}", "--iso", "0.5", "--method", "raytrace", "--surface", "cast")
    assert r.returncode == 2 and "--surface applies only to --method hybrid" in r.stderr
    r = wvol("iso", vol, "--dims", f"{N}x{N}x{N}", "--iso", "0.5", "--method", "hybrid", "--surface", "mesh")
    assert r.returncode == 2 and "expected exact or cast" in r.stderr


@pytest.mark.parametrize("store", [False, True])
def test_cast_exr_has_depth(wvol, vol, tmp_path, store):
    out = tmp_path / "c.exr"
    extra = ["--keep", "20%"] if store else []
    r = wvol("iso", vol, "--dims", f"{N}x{N}x{N}", "--iso", "0.5", "--method", "cast", *extra,
             "--size", "24x20", "--camera", "persp dir=1,0.5,0.3", "--brick", "8", "-o", out, "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["method"] == "cast" and info["source"] == ("store" if store else "volume")
    assert info["rays"] == 24 * 20 and 0 < info["hits"] < 24 * 20 and info["empty"] == 0
    assert 0 < info["bricks_built"] <= info["bricks_total"] and info["brick"] == 8
    assert sorted(exr_channels(out)) == ["A", "B", "G", "R", "Z"]
    depth_where_hit(out, info, 24, 20)


def test_cast_empty_and_hybrid_cast(wvol, vol, tmp_path):
    r = wvol("iso", vol, "--dims", f"{N}x{N}x{N}", "--iso", "7", "--method", "cast", "--size", "8x8",
             "-o", tmp_path / "e.png", "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["hits"] == 0 and info["empty"] == 1 and "above every sample" in info["message"]
    out = tmp_path / "h.png"
    r = wvol("iso", vol, "--dims", f"{N}x{N}x{N}", "--iso", "0.6", "--method", "hybrid", "--surface", "cast",
             "--tf", "gaussian", "--size", "16x16", "-o", out, "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["hits"] > 0 and png_size(out) == (16, 16)
