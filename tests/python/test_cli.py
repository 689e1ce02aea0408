# SPDX-License-Identifier: MIT
"""The wvol program's contract: exit codes 0/1/2 and one clear line on stderr."""
import json

import numpy as np
import pytest

from conftest import run_wvol


def test_no_command_is_usage_error(wvol):
    r = wvol()
    assert r.returncode == 2
    assert "usage" in r.stderr


def test_unknown_command(wvol):
    r = wvol("frobnicate")
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == ["wvol: unknown command 'frobnicate' (run 'wvol --help' for the list)"]


def test_help_lists_commands(wvol):
    r = wvol("--help")
    assert r.returncode == 0
    assert "info" in r.stdout


def test_info_unknown_option(wvol):
    r = wvol("info", "--bogus", "x.raw")
    assert r.returncode == 2
    assert "--bogus" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_info_missing_file(wvol, tmp_path):
    r = wvol("info", tmp_path / "nope.raw", "--dims", "4x4x4")
    assert r.returncode == 1
    assert "nope.raw" in r.stderr


def test_info_raw_size_mismatch(wvol, tmp_path):
    p = tmp_path / "v.raw"
    p.write_bytes(b"\0" * (4 * 4 * 4 * 4 - 1))
    r = wvol("info", p, "--dims", "4x4x4")
    assert r.returncode == 1
    assert "file has 255 bytes but 4x4x4 float32 samples need 256" in r.stderr


def test_info_overflowing_dims(wvol, tmp_path):
    p = tmp_path / "v.raw"
    p.write_bytes(b"\0" * 16)
    r = wvol("info", p, "--dims", "4294967296x4294967296x4294967296")
    assert r.returncode == 2  # impossible dimensions are bad usage
    assert "dimensions 4294967296x4294967296x4294967296 overflow" in r.stderr


def test_info_malformed_dims(wvol, tmp_path):
    p = tmp_path / "v.raw"
    p.write_bytes(b"\0" * 16)
    for bad in ("4x4", "ax4x4", "0x4x4", "4x4x4x4", "-4"):
        r = wvol("info", p, "--dims", bad)
        assert r.returncode == 2, bad
        assert "--dims" in r.stderr, bad


def test_info_raw_json(wvol, tmp_path):
    import numpy as np
    a = np.arange(2 * 3 * 4, dtype="<f4").reshape(4, 3, 2)  # (z, y, x)
    p = tmp_path / "v.raw"
    a.tofile(p)
    r = wvol("info", p, "--dims", "2x3x4", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["dims"] == [2, 3, 4]
    assert d["min"] == 0 and d["max"] == 23
    assert abs(d["mean"] - 11.5) < 1e-12


def test_info_percentiles_of_a_constant_volume_are_its_value(tmp_path):
    # the 1024-bin histogram of a constant volume has width 0: its percentiles are the value
    # itself, not the value + 1 (a bin width of 1 stood in for 0)
    raw = tmp_path / "c.raw"
    np.full((4, 4, 4), 0.00248, np.float32).tofile(raw)
    r = run_wvol("info", raw, "--dims", "4x4x4", "--json")
    assert r.returncode == 0, r.stderr
    pct = json.loads(r.stdout)["percentiles"]
    assert pct and all(v == pytest.approx(0.00248, rel=1e-6) for v in pct.values()), pct


@pytest.fixture
def small(tmp_path):
    """A 16^3 float32 volume with a bright ball: the input of the option checks below."""
    z, y, x = np.mgrid[:16, :16, :16]
    raw = tmp_path / "v.raw"
    np.exp(-((x - 7.5) ** 2 + (y - 7.5) ** 2 + (z - 7.5) ** 2) / 20).astype("<f4").tofile(raw)
    return [raw, "--dims", "16x16x16"]


# docs/cli.md: 2 is bad usage, decided by the options alone (an option the chosen method does not
# read, or one that needs another; a combination no method takes; an output extension this
# build cannot write); nothing is read or written, and the line names the option
@pytest.mark.parametrize("args,words", [
    (["render", "-o", "x.exr", "--gauss", "3"], "--gauss applies only to --method spline (not auto)"),
    (["render", "-o", "x.exr", "--method", "spline", "--keep", "50%", "--step", "0.3"],
     "--step applies only to --method auto, reference, reference-fhat or bricks (not spline)"),
    (["render", "-o", "x.exr", "--method", "axis", "--keep", "50%", "--brick", "8"],
     "--brick applies only to --method auto, reference or bricks (not axis)"),
    (["render", "-o", "x.exr", "--method", "splat", "--keep", "50%"], "--method splat renders X-ray images only"),
    (["render", "-o", "x.exr", "--method", "spline", "--keep", "50%", "--preintegrate"],
     "--preintegrate applies only to --method"),
    (["render", "-o", "x.exr", "--method", "bricks", "--gradient-levels", "1"], "--gradient-levels"),
    (["render", "-o", "x.exr", "--growth", "2"], "add --progressive"),
    (["render", "-o", "x.exr", "--bound-method", "coarse"], "add --bound"),
    (["render", "-o", "x.exr", "--orbit", "10"], "add --repeat"),
    (["render", "-o", "x.exr", "--one-shot"], "add --repeat"),
    (["render", "-o", "x.exr", "--context-cache", "8M"], "add --repeat"),
    (["iso", "-o", "x.ply", "--iso", "0.5", "--tf", "grey"], "--tf applies only to --method hybrid (not mc)"),
    (["iso", "-o", "x.ply", "--iso", "0.5", "--camera", "+x"], "--camera applies only to --method cast, raytrace"),
    (["iso", "-o", "x.ply", "--iso", "0.5", "--surface", "exact"], "--surface applies only to --method hybrid"),
    (["iso", "-o", "x.exr", "--iso", "0.5", "--method", "cast", "--normals", "none"],
     "--normals applies only to --method mc (not cast)"),
    (["iso", "-o", "x.exr", "--iso", "0.5", "--method", "raytrace", "--brick", "8"],
     "--brick applies only to --method mc or cast (not raytrace)"),
    (["iso", "-o", "x.exr", "--iso", "0.5", "--method", "cast", "--chunk", "8"],
     "--chunk applies only to --method raytrace or hybrid (not cast)"),
    (["iso", "-o", "x.ply", "--iso", "0.5", "--levels", "2"], "--levels sets the levels of a store"),
    (["compress", "-o", "x.wvc", "--roi-floor", "0.2"], "--roi-floor"),
    (["compress", "-o", "x.wvc", "--format", "1", "--tile", "16"], "--tile"),
    (["compress", "-o", "x.wvc", "--format", "1", "--coder", "rans4"], "--format 1"),
    (["segment", "-o", "x.raw", "--boundary", "2"], "--boundary"),
])
def test_options_the_method_does_not_read_are_usage_errors(wvol, small, tmp_path, args, words):
    cmd, rest = args[0], [str(tmp_path / a) if a.startswith("x.") else a for a in args[1:]]
    r = wvol(cmd, *small, *rest)
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert words in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert list(tmp_path.iterdir()) == [small[0]]  # nothing written


@pytest.mark.parametrize("args,words", [
    (["-o", "x.png", "--mesh-res", "8", "--size", "16x16"], "--mesh-res sets the written mesh's cells: add --mesh"),
    (["-o", "x.ply", "--camera", "+z"], "--camera, --size and --exposure shape an image"),
    (["-o", "x.vtp", "--size", "8x8"], "--camera, --size and --exposure shape an image"),
    (["-o", "x.exr", "--exposure", "2"], "--exposure scales a PNG's values"),
])
def test_radiosity_options_for_an_output_not_written_are_usage_errors(wvol, tmp_path, args, words):
    rest = [str(tmp_path / a) if a.startswith("x.") else a for a in args]
    r = wvol("radiosity", "box", "--max-level", "2", *rest)
    assert r.returncode == 2 and words in r.stderr, (r.returncode, r.stderr)
    assert list(tmp_path.iterdir()) == []
    # the same options where their output is written are taken
    ok = {"x.png": ["--mesh", str(tmp_path / "m.ply")], "x.ply": [], "x.vtp": [], "x.exr": []}[args[1]]
    if args[1] == "x.png":
        assert wvol("radiosity", "box", "--max-level", "2", *rest, *ok).returncode == 0


def test_convert_to_an_unwritable_format_is_usage(wvol, small, tmp_path):
    r = wvol("convert", *small[:1], tmp_path / "x.mhd", *small[1:])
    assert r.returncode == 2 and "x.mhd: cannot write this format" in r.stderr, r.stderr
    r = wvol("synth", "gaussian", "-o", tmp_path / "x.mhd")  # the same refusal, the same code
    assert r.returncode == 2 and "cannot write this format" in r.stderr, r.stderr


# 1 is bad input: what only the input's contents decide, with options that are fine by themselves
@pytest.mark.parametrize("args,words", [
    (["compress", "-o", "x.wvc", "--psnr", "40"], "the volume is constant; PSNR 40 "),
    (["render", "-o", "x.exr", "--tf", "bad.tf"], "bad.tf:1"),
    (["info", "--dims", "15x16x16"], "file has 16384 bytes but 15x16x16 float32 samples need 15360"),
])
def test_bad_input_fails_with_1(wvol, tmp_path, args, words):
    raw = tmp_path / "c.raw"
    np.full((16, 16, 16), 3.0, "<f4").tofile(raw)
    (tmp_path / "bad.tf").write_text("0 1 1\n")
    rest = [str(tmp_path / a) if a.startswith(("x.", "bad.")) else a for a in args[1:]]
    dims = [] if "--dims" in rest else ["--dims", "16x16x16"]
    r = wvol(args[0], raw, *dims, *rest)
    assert r.returncode == 1, (r.returncode, r.stderr)
    assert words in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_library_message_is_not_prefixed_twice(wvol, tmp_path):
    # the library's messages name their module ("compress: ...", "camera: ..."); the program
    # prints them after its own "wvol CMD: " and puts no second label in front of them
    raw = tmp_path / "c.raw"
    np.full((8, 8, 8), 3.0, "<f4").tofile(raw)
    r = wvol("compress", raw, "--dims", "8x8x8", "-o", tmp_path / "c.wvc")
    assert r.returncode == 1
    assert r.stderr.startswith("wvol compress: the volume is constant; PSNR 50 "), r.stderr
    assert r.stderr.count("compress:") == 1, r.stderr
    r = wvol("render", raw, "--dims", "8x8x8", "-o", tmp_path / "c.exr", "--camera", "persp fov=500")
    assert r.returncode == 2
    assert r.stderr.strip() == "wvol render: camera: fov='500' (degrees in (0, 180))", r.stderr


def test_keep_alone_meshes_from_a_store(wvol, small, tmp_path):
    # --keep alone selects the coefficients (db2, the default filter): the mesh is the store's
    full = json.loads(wvol("iso", *small, "--iso", "0.5", "--json").stdout)
    kept = json.loads(wvol("iso", *small, "--iso", "0.5", "--keep", "1%", "--json").stdout)
    assert full["method"] == "mc" and kept["method"] == "mc-bricks" and kept["wavelet"] == "db2"
    assert kept["area"] != full["area"]


# docs/cli.md: --threads on every command that runs in parallel, 1..4096, the same outputs for
# any count (the commands' parallel parts sum in a fixed order)
def _outputs_with_threads(wvol, tmp_path, small, threads):
    d = tmp_path / f"t{threads}"
    d.mkdir()
    t = ("--threads", str(threads))
    runs = [
        ("synth", "skull", "--size", "24x20x17", "--noise", "20", "-o", d / "s.raw", *t),
        ("transform", *small, "-o", d / "c.raw", "--levels", "2", *t),
        ("inverse", d / "c.raw", "-o", d / "i.raw", *t),
        ("compress", *small, "-o", d / "v.wvc", "--psnr", "40", *t),
        ("decompress", d / "v.wvc", "-o", d / "d.raw", *t),
        ("segment", *small, "-o", d / "l.raw", "--som", "2x2x1", *t),
    ]
    for args in runs:
        r = wvol(*args)
        assert r.returncode == 0, (args[0], r.stderr)
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


def test_threads_option_gives_the_same_outputs(wvol, small, tmp_path):
    one = _outputs_with_threads(wvol, tmp_path, small, 1)
    two = _outputs_with_threads(wvol, tmp_path, small, 2)
    assert sorted(one) == sorted(two) and len(one) >= 6
    for name in one:
        assert one[name] == two[name], name


@pytest.mark.parametrize("cmd", ["synth", "transform", "inverse", "compress", "decompress", "render", "iso",
                                 "segment", "transport"])
@pytest.mark.parametrize("bad", ["0", "4097", "two", ""])
def test_threads_option_range_is_usage(wvol, tmp_path, cmd, bad):
    r = wvol(cmd, "--threads", bad)
    assert r.returncode == 2, r.stderr
    assert f"--threads '{bad}': expected an integer from 1 to 4096" in r.stderr


@pytest.mark.parametrize("cmd,extra", [("info", []), ("convert", ["x.vti"]), ("compress", ["-o", "x.wvc"]),
                                       ("iso", ["-o", "x.ply", "--iso", "0.5"]), ("render", ["-o", "x.png"]),
                                       ("transform", ["-o", "x.raw"]), ("segment", ["-o", "x.raw"])])
@pytest.mark.parametrize("opt", [["--dims", "16x16x16"], ["--origin", "1,2,3"], ["--spacing", "2"],
                                 ["--type", "uint8"], ["--big-endian"], ["--grid", "density"]])
def test_loading_options_the_input_does_not_take_are_usage_errors(wvol, small, tmp_path, cmd, extra, opt):
    """--dims, --type, --big-endian, --spacing and --origin describe raw input, --grid an OpenVDB
    file's: given for a file that carries its own (here NRRD), or for a generator, they are
    refused before anything is read, never ignored (docs/cli.md)."""
    src = tmp_path / "v.nrrd"
    assert wvol("convert", *small, src).returncode == 0
    rest = [str(tmp_path / a) if a.startswith("x.") else a for a in extra]
    r = wvol(cmd, src, *rest, *opt)
    assert r.returncode == 2 and opt[0] in r.stderr and "v.nrrd" in r.stderr, (r.returncode, r.stderr)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.nrrd", "v.raw"]  # nothing written
    if cmd == "compress" and opt[0] != "--grid":
        r = wvol("compress", "synth:gaussian,size=8", "-o", tmp_path / "s.wvc", *opt)
        assert r.returncode == 2 and "is a generator" in r.stderr, r.stderr


def test_a_raw_truth_takes_the_raw_options_beside_a_nrrd_input(wvol, tmp_path):
    """segment: the loading options also read the truth, so a raw truth beside a NRRD input takes them."""
    img, lab = tmp_path / "t.nrrd", tmp_path / "t_labels.raw"
    assert wvol("synth", "textures", "-o", img, "--size", "32x32x1", "--labels", lab).returncode == 0
    r = wvol("segment", img, "--truth", lab, "--dims", "32x32x1", "-o", tmp_path / "s.raw", "--levels", "2")
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("origin,words", [("1e7,0,0", "float32 vertices are 1.19209 apart"),
                                          ("1e39,0,0", "beyond float32's range")])
def test_meshes_float32_cannot_hold_are_refused(wvol, small, tmp_path, origin, words):
    """A mesh's vertices are float32 world coordinates: far from 0 they snap to whole voxels (an
    origin of 1e9 collapsed a mesh to one point), beyond FLT_MAX they are Inf. Refused, naming why."""
    for store in ([], ["--keep", "50%"]):
        r = wvol("iso", *small, "--origin", origin, "--iso", "0.5", "-o", tmp_path / "m.ply", *store)
        assert r.returncode == 2 and words in r.stderr and "origin" in r.stderr, r.stderr
        assert not (tmp_path / "m.ply").exists()
    r = wvol("iso", *small, "--origin", "1e6,0,0", "--iso", "0.5", "-o", tmp_path / "m.ply")
    assert r.returncode == 0, r.stderr  # 1/16 of a voxel apart: within the eighth allowed


def test_levels_beyond_a_small_volume_are_refused_for_images_too(wvol, tmp_path):
    v = tmp_path / "r8.nrrd"
    assert wvol("synth", "gaussian", "--size", "8", "-o", v).returncode == 0
    for method in ("raytrace", "hybrid"):
        r = wvol("iso", v, "-o", tmp_path / "o.exr", "--iso", "0.5", "--method", method, "--levels", "5",
                 "--size", "8x8")
        assert r.returncode == 2 and "--levels 5: this volume allows 1..3" in r.stderr, r.stderr
    r = wvol("iso", v, "-o", tmp_path / "o.exr", "--iso", "0.5", "--method", "raytrace", "--size", "8x8",
             "--keep", "50%", "--json")  # the default (3) fits; without --levels a larger default is capped
    assert r.returncode == 0 and json.loads(r.stdout)["levels"] == 3, r.stderr


@pytest.mark.parametrize("mode", [[], ["--in-memory"]])
def test_streamed_and_in_memory_compression_fail_alike(wvol, tmp_path, mode):
    """The same input and options: the same exit code and message, streamed or in memory (a step
    the coefficients cannot have exited 2 streamed and 1 in memory; a 1x1x1 volume was named only
    in memory)."""
    big, one = tmp_path / "c30.raw", tmp_path / "one.raw"
    np.full((8, 8, 8), 1e30, "<f4").tofile(big)
    np.ones(1, "<f4").tofile(one)
    r = wvol("compress", big, "--dims", "8x8x8", "-o", tmp_path / "x.wvc", "--step", "0.5", *mode)
    assert r.returncode == 1 and "step 0.5 is below" in r.stderr, r.stderr
    r = wvol("compress", one, "--dims", "1x1x1", "-o", tmp_path / "x.wvc", *mode)
    assert r.returncode == 1 and "one.raw: a 1x1x1 volume cannot be transformed" in r.stderr, r.stderr
    assert not (tmp_path / "x.wvc").exists()


def test_a_volume_on_a_large_offset_meets_its_psnr_or_is_refused(wvol, tmp_path):
    """1e4 + a signal of range ~1.4: float32 arithmetic lost the details (a --psnr 50 file decoded
    to 45.3 dB while the report said 50.06). The transforms now take the offset out, and the
    target accounts for float32's rounding at that magnitude: met, streamed and in memory; at 1e6
    float32 alone cannot hold 50 dB: refused (exit 1), naming what it allows."""
    n = 32
    z, y, x = np.mgrid[:n, :n, :n] / n
    s = np.exp(-((x - .5) ** 2 + (y - .5) ** 2 + (z - .5) ** 2) / 0.05) + 0.33 * np.sin(6 * x)
    for off, target in ((1e4, 50), (1e4, 60), (3e4, 50)):
        v = (np.float32(off) + s.astype(np.float32)).astype("<f4")
        src = tmp_path / "v.raw"
        v.tofile(src)
        files = []
        for mode in ([], ["--in-memory"]):
            out = tmp_path / f"x{len(files)}.wvc"
            r = wvol("compress", src, "--dims", f"{n}x{n}x{n}", "-o", out, "--psnr", str(target), "--levels", "5",
                     *mode)
            assert r.returncode == 0, r.stderr
            assert wvol("decompress", out, "-o", tmp_path / "d.raw").returncode == 0
            d = np.fromfile(tmp_path / "d.raw", "<f4").astype(np.float64)
            rng = float(v.max()) - float(v.min())
            psnr = 20 * np.log10(rng / np.sqrt(np.mean((d - v.ravel()) ** 2)))
            assert psnr >= target - 0.01, (off, target, mode, psnr)
            files.append(out)
        # with a given step (and filter) the streamed file is the in-memory one byte for byte: both
        # transforms take the same offset out the same way
        for mode in ([], ["--in-memory"]):
            assert wvol("compress", src, "--dims", f"{n}x{n}x{n}", "-o", files[len(mode)], "--step", str(off * 5e-7),
                        "--levels", "5", "--wavelet", "db2", *mode).returncode == 0
        assert files[0].read_bytes() == files[1].read_bytes(), (off, target)
    v = (np.float32(1e6) + s.astype(np.float32)).astype("<f4")
    v.tofile(tmp_path / "v.raw")
    for mode in ([], ["--in-memory"]):
        r = wvol("compress", tmp_path / "v.raw", "--dims", f"{n}x{n}x{n}", "-o", tmp_path / "y.wvc", "--psnr", "50",
                 *mode)
        assert r.returncode == 1 and "float32 alone rounds" in r.stderr and "offset" in r.stderr, r.stderr
        assert not (tmp_path / "y.wvc").exists()


def test_splat_xray_is_the_same_for_any_thread_count(wvol, tmp_path):
    # the splat summed per-thread images whose coefficients a dynamic schedule dealt out: a pixel's
    # double sum changed with the count and from run to run (one float32 step on the noisy skull
    # at 96x80); each thread now owns rows and adds in the coefficients' order
    vol, wvc = tmp_path / "s.nrrd", tmp_path / "s.wvc"
    assert wvol("synth", "skull", "--size", "96", "--noise", "20", "-o", vol).returncode == 0
    assert wvol("compress", vol, "-o", wvc, "--psnr", "50").returncode == 0
    images = set()
    for t in (1, 2, 3, 4, 7, 16, 2, 3):
        out = tmp_path / f"x{t}.exr"
        r = wvol("render", wvc, "-o", out, "--method", "splat", "--mode", "xray", "--size", "96x80", "--threads", t)
        assert r.returncode == 0, r.stderr
        images.add(out.read_bytes())
    assert len(images) == 1


def test_reported_sums_are_the_same_for_any_thread_count(wvol, tmp_path):
    # the mesh's area and volume and a compression's measured error were OpenMP reductions whose
    # order followed the thread count (the 13th digit moved); fixed blocks added in order now
    vol = tmp_path / "s.nrrd"
    assert wvol("synth", "skull", "--size", "64", "--noise", "20", "-o", vol).returncode == 0
    seen = set()
    for t in (1, 2, 3, 7):
        iso = json.loads(wvol("iso", vol, "-o", tmp_path / "m.ply", "--iso", "300", "--json", "--threads", t).stdout)
        comp = json.loads(wvol("compress", vol, "-o", tmp_path / "x.wvc", "--psnr", "50", "--verify", "--json",
                               "--threads", t).stdout)
        seen.add((iso["area"], iso["signed_volume"], comp["measured"]["sse"], comp["measured"]["psnr"]))
    assert len(seen) == 1, seen
