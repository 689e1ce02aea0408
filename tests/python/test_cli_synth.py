# SPDX-License-Identifier: MIT
"""`wvol synth` and `wvol demo`: outputs, determinism, and the bad inputs of docs/cli.md.

Every bad input must give exactly one line on stderr naming the problem, exit 2
for bad usage or 1 for a failure, and leave no file behind (not even a partial or
temporary one): each case runs in an empty folder whose listing is checked."""
import json
import pathlib
import os

import numpy as np
import pytest


def listing(d):
    return sorted(os.listdir(d))


def one_line_error(r, code, *needles):
    lines = r.stderr.strip().splitlines()
    assert r.returncode == code, (r.returncode, r.stderr)
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("wvol"), lines[0]
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


@pytest.mark.parametrize("kind,size", [("gaussian", "32"), ("blobs", "20x18x16"), ("skull", "40"),
                                       ("textures", "64x48x1"), ("shepp-logan", "24"), ("turbulence", "20x24x12")])
def test_synth_writes_raw_of_the_right_size(wvol, tmp_path, kind, size):
    out = tmp_path / f"{kind}.raw"
    r = wvol("synth", kind, "-o", out, "--size", size)
    assert r.returncode == 0, r.stderr
    dims = [int(x) for x in size.split("x")] if "x" in size else [int(size)] * 3
    assert out.stat().st_size == 4 * dims[0] * dims[1] * dims[2]
    assert str(out) in r.stdout and "range" in r.stdout and "bytes" in r.stdout
    assert listing(tmp_path) == [out.name]


def test_synth_json_describes_what_it_made(wvol, tmp_path):
    out = tmp_path / "s.nhdr"
    r = wvol("synth", "skull", "-o", out, "--size", "24x20x16", "--spacing", "2,2,3", "--seed", "9",
             "--noise", "5", "--labels", tmp_path / "l.nrrd", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["kind"] == "skull" and d["dims"] == [24, 20, 16] and d["spacing"] == [2, 2, 3]
    assert d["origin"] == [-23, -19, -22.5]
    assert d["seed"] == 9 and d["noise"] == 5
    assert d["files"] == [str(out), str(tmp_path / "s.raw")]
    assert d["bytes"] == out.stat().st_size + (tmp_path / "s.raw").stat().st_size
    assert d["min"] < -900 and d["max"] > 700
    assert d["labels"]["classes"] == 5 and d["labels"]["file"] == str(tmp_path / "l.nrrd")
    assert listing(tmp_path) == ["l.nrrd", "s.nhdr", "s.raw"]


def test_synth_is_deterministic(wvol, tmp_path):
    def run(name, seed):
        p = tmp_path / name
        assert wvol("synth", "textures", "-o", p, "--size", "40x40x8", "--seed", seed, "--noise", "0.1",
                    "--variant", "mixed").returncode == 0
        return p.read_bytes()
    a, b, c = run("a.raw", "5"), run("b.raw", "5"), run("c.raw", "18446744073709551615")
    assert a == b
    assert a != c


def test_skull_ct_variant_adds_only_the_table(wvol, tmp_path):
    # variant ct is the head voxel for voxel plus the patient table: a thin (2.4 mm) shell of
    # 250 HU outside the head, behind it (+y), curved (its depth changes with x)
    a, b = tmp_path / "h.raw", tmp_path / "c.raw"
    args = ["--size", "64x64x24", "--spacing", "3.75,3.75,6"]
    assert wvol("synth", "skull", "-o", a, *args).returncode == 0
    assert wvol("synth", "skull", "-o", b, "--variant", "ct", *args).returncode == 0
    h = np.fromfile(a, "<f4").reshape(24, 64, 64)
    c = np.fromfile(b, "<f4").reshape(24, 64, 64)
    diff = np.argwhere(h != c)
    assert len(diff) > 0 and np.all(h[h != c] == -1000)          # only air changed
    assert -500 < c[h != c].max() <= 250  # the table (250 HU) thinner than a 3.75 mm voxel: partial volume
    ys = diff[:, 1]
    assert ys.min() > 40                                           # behind the head (+y)
    # curved: the table's depth in y differs between its middle and its ends in x
    mid = diff[np.abs(diff[:, 2] - 32) < 3][:, 1].mean()
    end = diff[np.abs(diff[:, 2] - 32) > 20][:, 1].mean()
    assert mid > end + 1


def test_synth_nrrd_gzip_round_trips_through_info(wvol, tmp_path):
    raw, gz = tmp_path / "v.raw", tmp_path / "v.nrrd"
    assert wvol("synth", "skull", "-o", raw, "--size", "32x30x28").returncode == 0
    assert wvol("synth", "skull", "-o", gz, "--size", "32x30x28", "--gzip").returncode == 0
    assert gz.stat().st_size < raw.stat().st_size / 2
    a = json.loads(wvol("info", raw, "--dims", "32x30x28", "--json", check=True).stdout)
    b = json.loads(wvol("info", gz, "--json", check=True).stdout)
    assert a["dims"] == b["dims"] == [32, 30, 28]
    assert a["min"] == b["min"] and a["max"] == b["max"] and a["mean"] == b["mean"]


def test_synth_labels_match_the_volume(wvol, tmp_path):
    v, lab = tmp_path / "t.raw", tmp_path / "t_labels.raw"
    r = wvol("synth", "textures", "-o", v, "--labels", lab, "--size", "64x64x1", "--count", "5")
    assert r.returncode == 0, r.stderr
    labels = np.fromfile(lab, "<f4")
    assert labels.size == 64 * 64
    assert set(np.unique(labels)) == {0, 1, 2, 3, 4}
    # the labels are the volume's regions: each region is one texture, so the mean |dv/dx| over
    # neighbour pairs inside a region differs from region to region (at least 10% here: 0.001
    # to 0.43), where a label map not matching the volume would mix the textures alike
    vol = np.fromfile(v, "<f4").reshape(64, 64)
    lab2 = labels.reshape(64, 64)
    inside = lab2[:, 1:] == lab2[:, :-1]
    gx = np.abs(np.diff(vol, axis=1))
    means = sorted(float(gx[inside & (lab2[:, :-1] == k)].mean()) for k in range(5))
    assert all(b > 1.1 * a for a, b in zip(means, means[1:])), means


@pytest.mark.parametrize("kind", ["skull", "turbulence"])
def test_synth_slab_is_those_slices_of_the_whole(wvol, tmp_path, kind):
    """--slab Z0,NZ writes the same values as slices Z0.. of the whole volume (noise included:
    it is hashed from the voxel's index in the whole), with the origin at slice Z0."""
    whole, part = tmp_path / "w.raw", tmp_path / "p.nrrd"
    assert wvol("synth", kind, "-o", whole, "--size", "24x20x30", "--noise", "5").returncode == 0
    r = wvol("synth", kind, "-o", part, "--size", "24x20x30", "--noise", "5", "--slab", "11,7", "--json")
    assert r.returncode == 0, r.stderr
    rep = json.loads(r.stdout)
    full = json.loads(wvol("synth", kind, "-o", whole, "--size", "24x20x30", "--noise", "5", "--json").stdout)
    assert rep["dims"] == [24, 20, 7]
    assert rep["origin"][2] == pytest.approx(full["origin"][2] + 11 * full["spacing"][2])
    w = np.fromfile(whole, "<f4").reshape(30, 20, 24)
    raw = part.read_bytes()
    p = np.frombuffer(raw[len(raw) - 4 * 24 * 20 * 7:], "<f4").reshape(7, 20, 24)
    assert np.array_equal(w[11:18], p)


def test_synth_list_and_help(wvol):
    r = wvol("synth", "--list")
    assert r.returncode == 0
    for k in ("gaussian", "blobs", "skull", "textures", "shepp-logan", "turbulence"):
        assert k in r.stdout
    r = wvol("synth", "--help")
    assert r.returncode == 0 and "--labels" in r.stdout and "--seed" in r.stdout


# ---- bad input: one stderr line, exit 2 (usage) or 1 (failure), nothing left ----

USAGE_CASES = [
    (["synth"], "missing generator"),
    (["synth", "mandelbulb", "-o", "x.raw"], "unknown generator 'mandelbulb'"),
    (["synth", "skull", "--size", "8"], "missing output"),
    (["synth", "skull", "-o", "x.raw", "--size"], "--size needs a value"),
    (["synth", "skull", "--size", "8", "-o"], "--output needs a value"),
    (["synth", "skull", "-o", "x.raw", "--bogus"], "unknown option '--bogus'"),
    (["synth", "skull", "-o", "x.raw", "--size", "8x8"], "--size"),
    (["synth", "skull", "-o", "x.raw", "--size", "abc"], "--size"),
    (["synth", "skull", "-o", "x.raw", "--size", "0x4x4"], "--size"),
    (["synth", "skull", "-o", "x.raw", "--size", "-4"], "--size"),
    (["synth", "skull", "-o", "x.raw", "--spacing", "1,0,1"], "--spacing"),
    (["synth", "skull", "-o", "x.raw", "--spacing", "1,x,1"], "--spacing"),
    (["synth", "skull", "-o", "x.raw", "--spacing", "1,2"], "--spacing"),
    (["synth", "skull", "-o", "x.raw", "--seed", "-1"], "--seed"),
    (["synth", "skull", "-o", "x.raw", "--seed", "1.5"], "--seed"),
    (["synth", "skull", "-o", "x.raw", "--seed", "18446744073709551616"], "--seed"),
    (["synth", "skull", "-o", "x.raw", "--noise", "-1"], "--noise"),
    (["synth", "skull", "-o", "x.raw", "--noise", "nan"], "--noise"),
    (["synth", "blobs", "-o", "x.raw", "--count", "0"], "--count"),
    (["synth", "gaussian", "-o", "x.raw", "--sigma", "0"], "--sigma"),
    (["synth", "textures", "-o", "x.raw", "--variant", "plaid"], "plaid"),
    (["synth", "skull", "-o", "x.raw", "--variant", "mri"], "mri"),
    (["synth", "gaussian", "-o", "x.raw", "--labels", "l.raw"], "no label map"),
    (["synth", "skull", "-o", "x.raw", "--labels", "x.raw"], "same file"),
    (["synth", "skull", "-o", "x.xyz"], "cannot write this format"),
    (["synth", "skull", "-o", "x.raw", "--gzip"], "--gzip"),
    (["synth", "skull", "-o", "x.raw", "--slab", "3,0"], "--slab"),
    (["synth", "skull", "-o", "x.raw", "--slab", "3"], "--slab"),
    (["synth", "skull", "-o", "x.raw", "--slab", "-1,2"], "--slab"),
    (["synth", "skull", "-o", "x.raw", "--size", "16", "--slab", "10,7"], "16 slices"),
    (["synth", "skull", "-o", "x.raw", "--size", "4294967296x4294967296x4294967296"], "overflow"),
    (["synth", "skull", "-o", "x.raw", "--size", "18446744073709551615x2x1"], "overflow"),
    (["demo", "--size", "0"], "--size"),
    (["demo", "--seed", "x"], "--seed"),
    (["demo", "extra"], "unexpected argument"),
    (["nosuchcommand"], "unknown command 'nosuchcommand'"),
]


@pytest.mark.parametrize("args,needle", USAGE_CASES, ids=[" ".join(a) for a, _ in USAGE_CASES])
def test_bad_usage_exits_2_and_leaves_nothing(wvol, tmp_path, args, needle):
    r = wvol(*args, cwd=tmp_path)
    one_line_error(r, 2, needle)
    assert r.stdout == ""
    assert listing(tmp_path) == []


def test_allocation_failure_exits_1(wvol, tmp_path):
    # fits size_t, but no machine has 16 PB
    r = wvol("synth", "gaussian", "-o", "x.raw", "--size", "100000x100000x100000", cwd=tmp_path)
    one_line_error(r, 1, "out of memory")
    assert listing(tmp_path) == []


@pytest.mark.parametrize("target", ["missing/x.nrrd", "missing/x.nhdr", "file.txt/x.raw", "dir.raw", "hdr.nhdr"])
def test_unwritable_output_exits_1_and_leaves_nothing(wvol, tmp_path, target):
    # a missing folder, a file used as a folder, and folders where the output file
    # (or a detached header, after its data file was written) should go
    (tmp_path / "file.txt").write_text("not a folder")
    (tmp_path / "dir.raw").mkdir()
    (tmp_path / "hdr.nhdr").mkdir()
    before = listing(tmp_path)
    r = wvol("synth", "gaussian", "-o", tmp_path / target, "--size", "8")
    one_line_error(r, 1, os.path.basename(target))
    assert listing(tmp_path) == before
    assert listing(tmp_path / "dir.raw") == [] and listing(tmp_path / "hdr.nhdr") == []


def test_unwritable_labels_remove_the_volume_too(wvol, tmp_path):
    r = wvol("synth", "skull", "-o", tmp_path / "v.nhdr", "--labels", tmp_path / "missing" / "l.nrrd",
             "--size", "16")
    one_line_error(r, 1, "l.nrrd")
    assert listing(tmp_path) == []


@pytest.mark.parametrize("dims,why", [("8x8x9", "need"), ("8x8x7", "need"), ("4294967296x4294967296x4294967296", "overflow")])
def test_raw_file_of_the_wrong_length_is_refused(wvol, tmp_path, dims, why):
    f = tmp_path / "v.raw"
    assert wvol("synth", "blobs", "-o", f, "--size", "8").returncode == 0
    r = wvol("info", f, "--dims", dims)
    line = one_line_error(r, 1 if why == "need" else 2, why)
    assert "v.raw" in line or why == "overflow"
    assert listing(tmp_path) == ["v.raw"]


def test_demo_makes_and_writes_the_phantom(wvol, tmp_path):
    out = tmp_path / "demo"
    r = wvol("demo", "--out", out)
    assert r.returncode == 0, r.stderr
    f = out / "skull.nrrd"
    assert f.exists() and f.stat().st_size > 128 ** 3 * 4
    assert "128 x 128 x 128" in r.stdout and str(f) in r.stdout and "total" in r.stdout
    r = wvol("demo", "--out", out, "--size", "24", "--json")
    d = json.loads(r.stdout)
    assert [s["name"] for s in d["stages"]][:2] == ["phantom", "write"]
    assert d["stages"][0]["dims"] == [24, 24, 24] and d["stages"][1]["file"] == str(f)
    mesh = next(s for s in d["stages"] if s["name"] == "mesh")
    assert mesh["triangles"] > 0 and pathlib.Path(mesh["file"]).stat().st_size > 0
    sel = next(s for s in d["stages"] if s["name"] == "select")
    assert abs(sel["kept"] - 0.05 * sel["total"]) <= 1
    # 24 is a multiple of 2^3: no padding, so Parseval's prediction is the measured error
    assert abs(sel["predicted_rmse"] - sel["measured_rmse"]) <= 1e-4 * sel["measured_rmse"]


def test_demo_unwritable_folder(wvol, tmp_path):
    (tmp_path / "file").write_text("x")
    r = wvol("demo", "--out", tmp_path / "file" / "sub", "--size", "8")
    one_line_error(r, 1, "cannot create output folder")
    assert listing(tmp_path) == ["file"]


def test_synth_refuses_what_would_not_be_finite(tmp_path, wvol):
    out = tmp_path / "s.nrrd"
    r = wvol("synth", "gaussian", "--size", "8", "-o", out, "--noise", "1e39")
    assert r.returncode == 2 and "noise 1e+39: at most 3e37 (the samples are float32)" in r.stderr, r.stderr
    r = wvol("synth", "gaussian", "--size", "8", "-o", out, "--spacing", "1e308")
    assert r.returncode == 2 and "origin[0] = -inf: origin must be finite" in r.stderr, r.stderr
    assert not out.exists()
    # a spacing this large is still a place: written, and read back (the NRRD reader's vector
    # length by hypot, whose squares would overflow)
    r = wvol("synth", "gaussian", "--size", "8", "-o", out, "--spacing", "1e300")
    assert r.returncode == 0, r.stderr
    r = wvol("info", out)
    assert r.returncode == 0 and "spacing  1e+300 1e+300 1e+300" in r.stdout, r.stdout + r.stderr
