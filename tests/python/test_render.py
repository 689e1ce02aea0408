# SPDX-License-Identifier: MIT
"""wvol render: images from volumes (reference) and from stores (spline, axis, splat); bad input refused."""
import array
import json
import math
import struct
import zlib

import numpy as np

import pytest

N = 16


def gaussian_raw(path, n=N):
    vals = array.array("f")
    c = (n - 1) / 2
    for k in range(n):
        for j in range(n):
            for i in range(n):
                r2 = ((i - c) / (n / 6)) ** 2 + ((j - c) / (n / 5)) ** 2 + ((k - c) / (n / 7)) ** 2
                vals.append(math.exp(-0.5 * r2))
    path.write_bytes(vals.tobytes())
    return path


@pytest.fixture
def vol(tmp_path):
    return gaussian_raw(tmp_path / "g.raw")


def png_size(path):
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    w, h = struct.unpack(">II", data[16:24])
    return w, h


def test_reference_png_and_exr(wvol, vol, tmp_path):
    out = tmp_path / "a.png"
    r = wvol("render", vol, "--dims", f"{N}x{N}x{N}", "-o", out, "--size", "40x30", "--camera", "persp dir=1,1,0.5")
    assert r.returncode == 0, r.stderr
    assert png_size(out) == (40, 30)
    exr = tmp_path / "a.exr"
    r = wvol("render", vol, "--dims", f"{N}x{N}x{N}", "-o", exr, "--size", "16x16", "--mode", "xray", "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["method"] == "reference" and info["mode"] == "xray" and info["rays_hit"] == 256
    assert exr.read_bytes()[:4] == b"\x76\x2f\x31\x01"  # OpenEXR magic


def test_transfer_function_file(wvol, vol, tmp_path):
    """A TF file is read and applied: the same points as text and as JSON give the same image, and
    swapping its red and blue columns swaps the image's red and blue planes (alpha unchanged)."""
    files = {"tf.txt": "units diagonal\n0 0 0 1 0\n1 1 1 0 10\n",
             "swap.txt": "units diagonal\n0 1 0 0 0\n1 0 1 1 10\n",
             "tf.json": '{"units": "diagonal", "points": [[0, 0,0,1, 0], [1, 1,1,0, 10]]}'}
    img = {}
    for name, text in files.items():
        (tmp_path / name).write_text(text)
        r = wvol("render", vol, "--dims", f"{N}x{N}x{N}", "-o", tmp_path / (name + ".exr"), "--size", "8x8",
                 "--tf", tmp_path / name)
        assert r.returncode == 0, r.stderr
        img[name] = read_exr_rgba(tmp_path / (name + ".exr")).reshape(8, 4, 8)  # per row A, B, G, R
    a, s = img["tf.txt"], img["swap.txt"]
    assert a[:, 0].max() > 0.1 and a[:, 3].max() > 0  # seen, with some red
    assert np.array_equal(img["tf.json"], a)
    assert np.array_equal(s[:, 0], a[:, 0]) and np.array_equal(s[:, 1], a[:, 3]) and np.array_equal(s[:, 3], a[:, 1])


@pytest.mark.parametrize("args, code, words", [
    (["--camera", "+w"], 2, "+w"),
    (["--camera", "persp fov=200"], 2, "fov"),
    (["--camera", "eye=0,0,5 center=0,0,0 up=0,0,1"], 2, "parallel"),
    (["--tf", "nosuchpreset"], 2, "nosuchpreset"),
    (["--mode", "mip"], 2, "--mode"),
    (["--size", "0x5"], 2, "--size"),
    (["--method", "magic"], 2, "--method"),
    (["--skip-tolerance", "-1"], 2, "--skip-tolerance"),
    (["--skip-tolerance", "lots"], 2, "skip-tolerance"),
    (["--skip-tolerance", "0.01", "--method", "spline", "--keep", "50%"], 2,
     "--skip-tolerance applies only to --method auto, reference or bricks (not spline)"),
    (["--repeat", "0"], 2, "--repeat"),
    (["--repeat", "101"], 2, "--repeat"),
    (["--repeat", "two"], 2, "--repeat"),
])
def test_bad_options_refused(wvol, vol, tmp_path, args, code, words):
    out = tmp_path / "x.png"
    r = wvol("render", vol, "--dims", f"{N}x{N}x{N}", "-o", out, *args)
    assert r.returncode == code
    assert words in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_bad_tf_file_names_the_line(wvol, vol, tmp_path):
    tf = tmp_path / "bad.txt"
    tf.write_text("0 0 0 0 0\n0.5 1 1 1\n")
    r = wvol("render", vol, "--dims", f"{N}x{N}x{N}", "-o", tmp_path / "x.png", "--tf", tf)
    assert r.returncode == 1
    assert "bad.txt:2" in r.stderr


def test_bad_output_refused_without_partial_file(wvol, vol, tmp_path):
    r = wvol("render", vol, "--dims", f"{N}x{N}x{N}", "-o", tmp_path / "x.jpg")
    assert r.returncode == 2 and ".exr or .png" in r.stderr
    r = wvol("render", vol, "--dims", f"{N}x{N}x{N}", "-o", tmp_path / "nodir" / "x.exr", "--size", "8x8")
    assert r.returncode == 1 and "nodir" in r.stderr
    assert not (tmp_path / "nodir").exists()


def test_spline_and_axis_agree_along_an_axis(wvol, vol, tmp_path):
    common = [vol, "--dims", f"{N}x{N}x{N}", "--mode", "xray", "--size", "16x16", "--camera", "+z",
              "--wavelet", "db2", "--levels", "2", "--keep", "20%", "--json"]
    r1 = wvol("render", *common, "-o", tmp_path / "s.exr", "--method", "spline")
    assert r1.returncode == 0, r1.stderr
    r2 = wvol("render", *common, "-o", tmp_path / "a.exr", "--method", "axis")
    assert r2.returncode == 0, r2.stderr
    r3 = wvol("render", *common, "-o", tmp_path / "auto.exr")
    assert json.loads(r3.stdout)["method"] == "axis"
    # along an axis both integrate the same kept functions exactly (the spline analytically,
    # the axis path from 2D coefficients): equal to float rounding, 1e-5 of the peak as in
    # test_render_spline.c and test_py_roundtrip.py
    s, a = read_exr_rgba(tmp_path / "s.exr"), read_exr_rgba(tmp_path / "a.exr")
    assert abs(a).max() > 0 and abs(s - a).max() <= 1e-5 * abs(a).max()


def test_splat_from_the_cli(wvol, vol, tmp_path):
    # --method splat: X-ray of an oblique orthographic view, the spline model up to the
    # footprint tables' interpolation (C tests: 4e-4..4.4e-3 relative RMSE; here allowed 1e-2
    # of the peak on any pixel); a mode it cannot render is bad usage (exit 2, the options alone
    # decide it), a camera it cannot take fails when it is placed (exit 1, docs/cli.md)
    common = [vol, "--dims", f"{N}x{N}x{N}", "--mode", "xray", "--size", "16x12", "--camera",
              "ortho dir=1,0.7,0.4", "--wavelet", "db2", "--levels", "2", "--keep", "20%", "--json",
              "--spline-j", "3"]
    r1 = wvol("render", *common, "-o", tmp_path / "s.exr", "--method", "spline")
    r2 = wvol("render", *common, "-o", tmp_path / "p.exr", "--method", "splat")
    assert r1.returncode == 0 and r2.returncode == 0, r1.stderr + r2.stderr
    assert json.loads(r2.stdout)["method"] == "splat"
    a, b = read_exr_rgba(tmp_path / "p.exr"), read_exr_rgba(tmp_path / "s.exr")
    assert a.size == b.size == 4 * 16 * 12 and abs(a - b).max() < 1e-2 * abs(b).max()
    bad = [vol, "--dims", f"{N}x{N}x{N}", "--size", "8x8", "--keep", "20%", "--method", "splat"]
    r = wvol("render", *bad, "-o", tmp_path / "x.exr")
    assert r.returncode == 2 and "X-ray images only" in r.stderr and not (tmp_path / "x.exr").exists()
    r = wvol("render", *bad, "--mode", "xray", "--camera", "persp dir=1,1,0", "-o", tmp_path / "y.exr")
    assert r.returncode == 1 and "orthographic" in r.stderr and not (tmp_path / "y.exr").exists()


def test_spline_absorption_with_shading(wvol, vol, tmp_path):
    r = wvol("render", vol, "--dims", f"{N}x{N}x{N}", "-o", tmp_path / "s.png", "--size", "12x12",
             "--camera", "persp dir=1,0.5,0.3", "--method", "spline", "--keep", "10%", "--levels", "2",
             "--spline-j", "2", "--shading", "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["kept"] > 0 and info["functions"] > 0


def read_exr_rgba(path):
    """wvol's own EXR output (scanline, float32 channels, ZIP or none) as one flat float array."""
    import numpy as np
    data = path.read_bytes()
    pos, attrs = 8, {}
    while data[pos] != 0:
        e = data.index(b"\0", pos); name = data[pos:e].decode(); pos = e + 1
        e = data.index(b"\0", pos); pos = e + 1
        size = struct.unpack_from("<i", data, pos)[0]; pos += 4
        attrs[name] = data[pos:pos + size]; pos += size
    pos += 1
    x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    comp = attrs["compression"][0]
    lines = {0: 1, 2: 1, 3: 16}[comp]
    offsets = struct.unpack_from(f"<{(h + lines - 1) // lines}Q", data, pos)
    out = []
    for off in offsets:
        y, size = struct.unpack_from("<ii", data, off)
        raw = data[off + 8: off + 8 + size]
        if comp and size < 16 * w * min(lines, y1 + 1 - y):
            t = np.frombuffer(zlib.decompress(raw), np.uint8).astype(np.int64)
            t = (np.cumsum(t - 128 * (np.arange(t.size) > 0)) % 256).astype(np.uint8)  # undo the predictor
            half = (t.size + 1) // 2
            inter = np.empty(t.size, np.uint8)
            inter[0::2], inter[1::2] = t[:half], t[half:]  # undo the byte split
            raw = inter.tobytes()
        out.append(np.frombuffer(raw, "<f4"))
    return np.concatenate(out)


def test_bricks_from_a_store_and_from_a_wvc(wvol, tmp_path):
    n = 24
    vol = gaussian_raw(tmp_path / "g24.raw", n)
    dims = f"{n}x{n}x{n}"
    # the full grid: the methods compared here, not the level of detail (test_lod_cli.py)
    cam = ["--size", "20x16", "--camera", "persp dir=1,0.6,0.3", "--full-resolution"]
    r = wvol("render", vol, "--dims", dims, "-o", tmp_path / "b.exr", "--keep", "20%", "--json", *cam)
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["method"] == "bricks" and info["bricks_built"] > 0 and info["render_bytes"] > 0
    # a .wvc renders from its store (auto: bricks) and, on request, through its dense reconstruction:
    # the two are the same trilinear image up to float rounding (1e-5 of the largest channel leaves
    # room for the two reconstructions' rounding; a wrong brick would be off by far more)
    wvc = tmp_path / "g.wvc"
    r = wvol("compress", vol, "--dims", dims, "-o", wvc, "--keep", "20%", "--levels", "2")
    assert r.returncode == 0, r.stderr
    r = wvol("render", wvc, "-o", tmp_path / "w.exr", "--json", *cam)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["method"] == "bricks"
    r = wvol("render", wvc, "-o", tmp_path / "d.exr", "--method", "reference", *cam)
    assert r.returncode == 0, r.stderr
    a, b = read_exr_rgba(tmp_path / "w.exr"), read_exr_rgba(tmp_path / "d.exr")
    assert a.size == b.size == 4 * 20 * 16
    peak = abs(b).max()
    assert 0 < peak < 10 and abs(a - b).max() < 1e-5 * peak


def test_repeat_renders_the_same_image_and_reports_the_fastest(wvol, tmp_path):
    n = 24
    vol = gaussian_raw(tmp_path / "g24.raw", n)
    base = ["render", vol, "--dims", f"{n}x{n}x{n}", "--keep", "20%", "--json", "--size", "20x16",
            "--camera", "persp dir=1,0.6,0.3", "--full-resolution"]
    r1 = wvol(*base, "-o", tmp_path / "one.exr")
    r3 = wvol(*base, "-o", tmp_path / "three.exr", "--repeat", "3", "--one-shot")
    assert r1.returncode == 0 and r3.returncode == 0, r1.stderr + r3.stderr
    one, three = json.loads(r1.stdout), json.loads(r3.stdout)
    assert "repeat" not in one and three["repeat"] == 3 and three["context"] == 0
    # --one-shot: the fastest of three calls: its CPU time at most the slowest's; each call
    # builds the same bricks and takes the same samples, so the counts are one call's, and the
    # image is the same bit for bit (the calls share nothing)
    assert 0 <= three["render_cpu_seconds"] <= three["render_cpu_seconds_max"]
    for k in ("samples", "bricks_built", "rays_hit", "render_bytes"):
        assert three[k] == one[k], k
    assert (tmp_path / "one.exr").read_bytes() == (tmp_path / "three.exr").read_bytes()


def test_repeat_through_a_context_keeps_the_set_up_and_the_image(wvol, tmp_path):
    """--repeat renders its frames through one render context: the same samples and image as one
    call, the later frames taking bricks from the context's cache instead of building them;
    --orbit turns the camera between frames, the last (written) frame at --camera's view."""
    n = 24
    vol = gaussian_raw(tmp_path / "g24.raw", n)
    base = ["render", vol, "--dims", f"{n}x{n}x{n}", "--keep", "20%", "--json", "--size", "20x16",
            "--camera", "persp dir=1,0.6,0.3", "--full-resolution", "--brick", "8"]
    r1 = wvol(*base, "-o", tmp_path / "one.exr")
    r4 = wvol(*base, "-o", tmp_path / "four.exr", "--repeat", "4")
    ro = wvol(*base, "-o", tmp_path / "orbit.exr", "--repeat", "4", "--orbit", "10")
    rt = wvol(*base, "-o", tmp_path / "turned.exr", "--repeat", "4", "--orbit", "10", "--context-cache", "1")
    assert all(r.returncode == 0 for r in (r1, r4, ro, rt)), r1.stderr + r4.stderr + ro.stderr + rt.stderr
    one, four, orbit, tiny = (json.loads(r.stdout) for r in (r1, r4, ro, rt))
    assert four["context"] == 1 and four["context_frame"] == 4 and four["rates_reused"] == 1
    for k in ("samples", "rays_hit"):
        assert four[k] == one[k], k
    # the same camera again with every brick cached: nothing built after the first frame
    assert one["bricks_built"] > 0 and four["bricks_built_last"] == 0
    assert four["bricks_reused"] > 0 and 0 < four["cache_bytes"] <= four["context_bytes"]
    assert 0 < four["later_cpu_seconds"] and 0 < four["first_cpu_seconds"]
    # turned frames: the last is --camera's, bit for bit the one-shot image
    assert orbit["orbit"] == 10 and orbit["bricks_reused"] > 0
    for name in ("four", "orbit", "turned"):
        assert (tmp_path / "one.exr").read_bytes() == (tmp_path / f"{name}.exr").read_bytes(), name
    # a budget below one brick: nothing cached, the same image
    assert tiny["cache_bytes"] == 0 and tiny["bricks_reused"] == 0


@pytest.mark.parametrize("args,words", [
    (["--orbit", "400"], "--orbit"),
    (["--orbit", "x"], "orbit"),
    (["--context-cache", "lots"], "context-cache"),
])
def test_bad_repeat_options_refused(wvol, vol, tmp_path, args, words):
    r = wvol("render", vol, "--dims", f"{N}x{N}x{N}", "-o", tmp_path / "x.png", "--repeat", "2", *args)
    assert r.returncode == 2 and words in r.stderr


def test_reference_with_keep_renders_the_kept_reconstruction(wvol, tmp_path):
    """`--method reference --keep F` on a volume renders the dense reconstruction of the kept
    coefficients (it used to ignore --keep): the bricked image of the same store up to float
    rounding (1e-5 of the largest channel, as above), and visibly not the original's image."""
    n = 24
    vol = gaussian_raw(tmp_path / "g24.raw", n)
    common = ["--dims", f"{n}x{n}x{n}", "--size", "20x16", "--camera", "persp dir=1,0.6,0.3", "--json",
              "--full-resolution"]
    out = {}
    for name, extra in (("ref5", ["--method", "reference", "--keep", "1%"]),
                        ("bricks5", ["--method", "bricks", "--keep", "1%"]),
                        ("ref100", ["--method", "reference"])):
        r = wvol("render", vol, "-o", tmp_path / f"{name}.exr", *common, *extra)
        assert r.returncode == 0, r.stderr
        info = json.loads(r.stdout)
        out[name] = read_exr_rgba(tmp_path / f"{name}.exr")
        if name == "ref5":
            assert info["method"] == "reference" and info["kept"] > 0 and info["reconstruct_cpu_seconds"] >= 0
    peak = abs(out["ref100"]).max()
    assert abs(out["ref5"] - out["bricks5"]).max() < 1e-5 * peak
    assert abs(out["ref5"] - out["ref100"]).max() > 1e-3 * peak


def test_skip_tolerance_reports_its_bound(wvol, tmp_path):
    """`--skip-tolerance T` with bricks: the JSON reports the runs skipped and the largest depth
    skipped (<= T), and the image's alpha moves by at most that (+ float rounding)."""
    n = 32
    vol = gaussian_raw(tmp_path / "g32.raw", n)
    tf = tmp_path / "lin.txt"
    tf.write_text("units diagonal\n0 1 1 1 0\n1 1 1 1 8\n")
    common = ["--dims", f"{n}x{n}x{n}", "--size", "24x24", "--camera", "persp dir=1,0.7,0.4", "--tf", tf,
              "--method", "bricks", "--keep", "2%", "--brick", "8", "--json"]
    r0 = wvol("render", vol, "-o", tmp_path / "a.exr", *common)
    r1 = wvol("render", vol, "-o", tmp_path / "b.exr", *common, "--skip-tolerance", "0.02")
    assert r0.returncode == 0 and r1.returncode == 0, r0.stderr + r1.stderr
    info = json.loads(r1.stdout)
    assert "skip_bound" not in json.loads(r0.stdout)
    assert info["skipped_tolerance"] > 0 and 0 < info["skip_bound"] <= 0.02
    # per row the channels A, B, G, R: the alpha plane of each image
    a, b = (read_exr_rgba(tmp_path / f).reshape(24, 4, 24)[:, 0, :] for f in ("a.exr", "b.exr"))
    assert a.max() > 0.1  # the volume is seen
    assert abs(a - b).max() <= info["skip_bound"] + 2e-6


@pytest.mark.parametrize("camera, words", [
    ("ortho persp", "'persp' says again what an earlier word said (the projection)"),
    ("+x +y", "'+y' says again what an earlier word said (the direction)"),
    ("persp fov=30 fov=40", "'fov=40' says again what an earlier word said"),
    ("ortho fov=30", "fov= is for a perspective camera"),
    ("persp height=3", "height= is for an orthographic camera"),
    ("eye=1,2,3 dir=1,0,0", "eye=/center= and a direction (an axis, from= or dir=) both give the view direction"),
])
def test_camera_words_that_conflict_are_refused(wvol, vol, tmp_path, camera, words):
    # a later word would override the earlier one silently
    r = wvol("render", vol, "--dims", f"{N}x{N}x{N}", "-o", tmp_path / "x.png", "--size", "8x8", "--camera", camera)
    assert r.returncode == 2 and words in r.stderr, r.stderr
    assert not (tmp_path / "x.png").exists()
