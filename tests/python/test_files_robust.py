# SPDX-License-Identifier: MIT
"""What is at a path before wvol reads or writes it: a FIFO, a folder, a symbolic link.

Readers take regular files only: open() of a FIFO waits for a writer, forever when none
comes, so every reader refuses one at once (the subprocess timeout here is what a hang
would hit). Writers replace their output by renaming a temporary over it: they refuse a
path that holds a folder, FIFO or device (the rename would replace it), write through a
symbolic link to the file it names (the link stays), and commands with several outputs
leave none of them when one fails, and never remove what they did not write."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import WVOL_BIN

import wvol

TIMEOUT = 60  # a reader that waits on a FIFO runs into this


def run(*args, cwd=None):
    return subprocess.run([WVOL_BIN, *map(str, args)], capture_output=True, text=True, cwd=cwd, timeout=TIMEOUT)


@pytest.fixture
def phantom(tmp_path):
    p = tmp_path / "g.nrrd"
    assert run("synth", "gaussian", "--size", "16", "-o", p).returncode == 0
    return p


@pytest.mark.parametrize("ext, extra", [(".wvc", []), (".nrrd", []), (".mha", []), (".vti", []),
                                        (".raw", ["--dims", "2x2x2"])])
def test_cli_readers_refuse_a_fifo(tmp_path, ext, extra):
    f = tmp_path / f"f{ext}"
    os.mkfifo(f)
    r = run("info", f, *extra)
    assert r.returncode == 1, r.stderr
    assert f"{f}: not a regular file" in r.stderr


def test_cli_side_files_refuse_a_fifo(tmp_path, phantom):
    tf = tmp_path / "tf.txt"
    os.mkfifo(tf)
    r = run("render", phantom, "-o", tmp_path / "x.png", "--size", "8x8", "--tf", tf)
    assert r.returncode == 1 and f"{tf}: not a regular file" in r.stderr, r.stderr  # was "unknown preset"
    obj = tmp_path / "scene.obj"
    os.mkfifo(obj)
    r = run("radiosity", obj, "-o", tmp_path / "r.png")
    assert r.returncode == 1 and f"{obj}: not a regular file" in r.stderr, r.stderr
    png = tmp_path / "w.png"
    os.mkfifo(png)
    r = run("transport", "-o", tmp_path / "t", "--window", png)
    assert r.returncode == 1 and f"{png}: not a regular file" in r.stderr, r.stderr
    assert not (tmp_path / "t").exists()  # the input is read before the output folder is made


def test_python_readers_refuse_a_fifo(tmp_path):
    f = tmp_path / "f.wvc"
    os.mkfifo(f)
    n = tmp_path / "f.nrrd"
    os.mkfifo(n)
    # in a subprocess, so that a reader that waits shows as a timeout, not a stuck test run
    code = ("import wvol, sys\n"
            "for fn, p in ((wvol.wvc_info, sys.argv[1]), (wvol.open, sys.argv[1]), (wvol.load, sys.argv[2])):\n"
            "    try:\n"
            "        fn(p)\n"
            "        print('accepted', p)\n"
            "    except OSError as e:\n"
            "        print('refused', e)\n")
    r = subprocess.run([sys.executable, "-c", code, str(f), str(n)], capture_output=True, text=True,
                       timeout=TIMEOUT, env=os.environ)
    lines = r.stdout.splitlines()
    assert lines == [f"refused {f}: not a regular file"] * 2 + [f"refused {n}: not a regular file"], r.stdout + r.stderr


@pytest.mark.parametrize("ext", [".nrrd", ".vti"])
def test_output_through_a_link_keeps_the_link(tmp_path, ext):
    target = tmp_path / f"target{ext}"
    target.write_text("old")
    link = tmp_path / f"link{ext}"
    link.symlink_to(target.name)
    r = run("synth", "gaussian", "--size", "8", "-o", link)
    assert r.returncode == 0, r.stderr
    assert link.is_symlink() and os.readlink(link) == target.name
    assert target.read_bytes() != b"old" and wvol.load(target).data.shape == (8, 8, 8)


def test_outputs_that_are_not_regular_files_are_refused_and_kept(tmp_path):
    fifo = tmp_path / "f.nrrd"
    os.mkfifo(fifo)
    folder = tmp_path / "d.nrrd"
    folder.mkdir()
    dangling = tmp_path / "l.nrrd"
    dangling.symlink_to("nothing.nrrd")
    for p, words in ((fifo, "exists and is not a regular file"), (folder, "exists and is not a regular file"),
                     (dangling, "a symbolic link to no file")):
        r = run("synth", "gaussian", "--size", "8", "-o", p)
        assert r.returncode == 1 and f"{p}: {words}" in r.stderr, r.stderr
    assert fifo.is_fifo() and folder.is_dir() and dangling.is_symlink()
    assert sorted(x.name for x in tmp_path.iterdir()) == ["d.nrrd", "f.nrrd", "l.nrrd"]  # no temporaries
    # the library's writers, through Python
    a = np.zeros((4, 4, 4), np.float32)
    with pytest.raises(OSError, match="exists and is not a regular file"):
        wvol.save(a, fifo)
    (tmp_path / "w.wvc").mkdir()
    with pytest.raises(OSError, match="exists and is not a regular file"):
        wvol.compress(a, "haar", 1).save(tmp_path / "w.wvc")
    assert fifo.is_fifo() and folder.is_dir() and (tmp_path / "w.wvc").is_dir()


def test_demo_leaves_what_it_did_not_write(tmp_path):
    out = tmp_path / "dd"
    (out / "skull.wvc").mkdir(parents=True)  # the demo cannot write its .wvc there
    r = run("demo", "--size", "16", "--out", out)
    assert r.returncode == 1 and "skull.wvc" in r.stderr, r.stderr
    assert (out / "skull.wvc").is_dir()  # not removed by the cleanup
    assert sorted(x.name for x in out.iterdir()) == ["skull.wvc"]  # what it wrote before is gone


def test_demo_refuses_a_size_too_small_before_any_work(tmp_path):
    out = tmp_path / "d2"
    r = run("demo", "--size", "4", "--out", out)
    assert r.returncode == 2 and "too small for the demo's 3 wavelet levels (at least 8 per axis)" in r.stderr
    assert r.stdout == "" and not out.exists()


def test_render_of_a_damaged_file_writes_nothing(tmp_path, phantom):
    wvc = tmp_path / "g.wvc"
    assert run("compress", phantom, "-o", wvc, "--psnr", "60").returncode == 0
    b = bytearray(wvc.read_bytes())
    b[-3] ^= 0xFF  # inside the last chunk's payload: found when that chunk is decoded
    wvc.write_bytes(bytes(b))
    out = tmp_path / "o.png"
    r = run("render", wvc, "-o", out, "--size", "32x32", "--full-resolution")
    assert r.returncode == 1 and "checksum mismatch" in r.stderr, r.stderr
    assert not out.exists()


def test_multi_output_commands_leave_no_half(tmp_path, phantom):
    img = tmp_path / "o.png"
    r = run("render", phantom, "-o", img, "--size", "16x16", "--keep", "10%", "--bound", tmp_path / "no" / "b.exr")
    assert r.returncode == 1 and "b.exr" in r.stderr, r.stderr
    assert not img.exists()
    lab = tmp_path / "l.nrrd"
    r = run("segment", phantom, "-o", lab, "--levels", "1", "--iters", "50",
            "--colors", tmp_path / "no" / "c.raw")
    assert r.returncode == 1 and "c.raw" in r.stderr, r.stderr
    assert not lab.exists()
    mesh_img = tmp_path / "r.png"
    r = run("radiosity", "box", "-o", mesh_img, "--mesh", tmp_path / "no" / "m.ply")
    assert r.returncode == 1 and "m.ply" in r.stderr, r.stderr
    assert not mesh_img.exists()


def _outputs_kept(tmp_path, phantom, old, blocked, args, cwd=None):
    """Runs a command whose output `blocked` is a folder (refused when that output is written, after
    the others): every file in `old` must hold its earlier bytes afterwards, and nothing be added."""
    for f in old:
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_bytes(b"earlier " + f.name.encode())
    blocked.mkdir(parents=True)
    before = sorted(p for p in tmp_path.rglob("*"))
    r = run(*args, cwd=cwd)
    assert r.returncode == 1 and blocked.name in r.stderr and "not a regular file" in r.stderr, r.stderr
    for f in old:
        assert f.read_bytes() == b"earlier " + f.name.encode(), f
    assert sorted(p for p in tmp_path.rglob("*")) == before  # no kept link or temporary stays


def test_a_failed_command_puts_back_the_files_it_replaced(tmp_path, phantom):
    # each writer replaces its path atomically; a later output failing must undo the earlier ones
    # to what was there before, not remove them (the user's earlier results would be lost)
    t = tmp_path
    _outputs_kept(t, phantom, [t / "o.png"], t / "b.exr",
                  ["render", phantom, "-o", t / "o.png", "--size", "16x16", "--keep", "10%", "--bound", t / "b.exr"])
    _outputs_kept(t, phantom, [t / "p.png", t / "p.pass0.png", t / "p.pass1.png"], t / "p.pass2.png",
                  ["render", phantom, "-o", t / "p.png", "--size", "16x16", "--progressive", "--growth", "2"])
    _outputs_kept(t, phantom, [t / "l.nrrd"], t / "c.raw",
                  ["segment", phantom, "-o", t / "l.nrrd", "--levels", "1", "--iters", "50", "--colors", t / "c.raw"])
    _outputs_kept(t, phantom, [t / "r.png"], t / "m.ply", ["radiosity", "box", "-o", t / "r.png", "--mesh", t / "m.ply"])
    # synth by slabs (raw and NRRD) and whole (other formats)
    _outputs_kept(t, phantom, [t / "s.nhdr", t / "s.raw"], t / "sl.nrrd",
                  ["synth", "skull", "--size", "16", "-o", t / "s.nhdr", "--labels", t / "sl.nrrd"])
    _outputs_kept(t, phantom, [t / "s.vti"], t / "sl.raw",
                  ["synth", "skull", "--size", "16", "-o", t / "s.vti", "--labels", t / "sl.raw"])
    _outputs_kept(t, phantom, [t / "k.raw"], t / "k.json", ["transform", phantom, "-o", t / "k.raw"])
    d = t / "demo"
    _outputs_kept(t, phantom, [d / "skull.nrrd", d / "skull.png", d / "skull_xray.png", d / "skull.wvc"],
                  d / "bone.ply", ["demo", "--out", d, "--size", "32"])
    tr = t / "tr"
    _outputs_kept(t, phantom, [tr / "window.png", tr / "incident.png", tr / "incident.exr", tr / "detail.png"],
                  tr / "reflected.png",
                  ["transport", "-o", tr])


def test_a_stopped_command_puts_back_what_it_replaced(tmp_path, phantom):
    # SIGINT or SIGTERM mid-run: the temporaries go and the files already replaced come back (the
    # handler undoes the output set), then the signal ends the process as it would have
    import signal
    import time
    for sig in (signal.SIGINT, signal.SIGTERM):
        d = tmp_path / sig.name
        d.mkdir()
        old = [d / "p.png", d / "p.pass0.png", d / "p.pass1.png", d / "p.pass2.png"]
        for f in old:
            f.write_bytes(b"earlier")
        before = sorted(d.iterdir())
        first = os.stat(old[1]).st_ino
        # about 130 passes: the first ones are written long before the last
        p = subprocess.Popen([WVOL_BIN, "render", phantom, "-o", d / "p.png", "--progressive", "--growth", "1.05",
                              "--size", "96x96"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        t0 = time.monotonic()
        while (not (d / "p.pass3.png").exists() and p.poll() is None and time.monotonic() - t0 < TIMEOUT):
            time.sleep(0.001)
        assert os.stat(old[1]).st_ino != first  # pass 0 was replaced before the signal
        p.send_signal(sig)
        p.wait(timeout=TIMEOUT)
        assert p.returncode == -sig, p.stderr.read()
        assert sorted(d.iterdir()) == before
        assert all(f.read_bytes() == b"earlier" for f in old)


def _small_files_only():
    # in the child: writes beyond 4 KiB fail with EFBIG (SIGXFSZ ignored, as the C tests do)
    import resource
    import signal
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))


@pytest.mark.parametrize("cmd", [["transport"], ["demo", "--size", "32"]])
def test_a_failed_command_removes_the_folders_it_made(tmp_path, cmd):
    out = tmp_path / "new" / "sub"
    flag = "-o" if cmd[0] == "transport" else "--out"
    r = subprocess.run([WVOL_BIN, *cmd, flag, str(out)], capture_output=True, text=True, timeout=TIMEOUT,
                       preexec_fn=_small_files_only)
    assert r.returncode == 1 and "File too large" in r.stderr, r.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("header, words", [
    ("DimSize = 65536 65536 65536\nElementType = MET_FLOAT\n", "the header asks for 1125899906842624 bytes of samples"),
    ("DimSize = -1 2 2\nElementType = MET_FLOAT\n", "DimSize -1 is not a size"),
    ("DimSize = 2 2\nElementType = MET_FLOAT\n", "DimSize has 2 numbers for NDims = 3"),
    ("DimSize = 2048 2048 2048\nElementType = MET_FLOAT\nCompressedData = True\n",
     "cannot come from 4 compressed bytes"),
    ("DimSize = 1 1 1\nElementType = MET_FLOAT\nCompressedData = True\nCompressedDataSize = 99999999999\n",
     "CompressedDataSize 99999999999 but only 4 bytes"),
    ("DimSize = 1 1 1\nElementType = MET_NOPE\n", "ElementType missing or not a MetaIO type"),
])
def test_metaimage_header_must_fit_its_file(tmp_path, header, words):
    # VTK's MetaIO allocates what the header says before reading: checked first, from the file's size
    p = tmp_path / "m.mha"
    p.write_bytes(b"ObjectType = Image\nNDims = 3\n" + header.encode() + b"ElementDataFile = LOCAL\n" + bytes(4))
    r = run("info", p)
    assert r.returncode == 1 and words in r.stderr, r.stderr
    lst = tmp_path / "l.mha"
    lst.write_text("ObjectType = Image\nNDims = 3\nDimSize = 1 1 1\nElementType = MET_FLOAT\nElementDataFile = LIST\n")
    r = run("info", lst)
    assert r.returncode == 1 and "ElementDataFile LIST (a list of files) is not supported" in r.stderr


def test_two_outputs_that_are_one_file_are_refused(tmp_path):
    # different strings, one file: each would overwrite the other and both be reported written
    for args, words in ((["synth", "skull", "--size", "8", "--labels", "./s.nrrd", "-o", "s.nrrd"],
                         "--labels and -o would write the same file (./s.nrrd)"),
                        (["synth", "skull", "--size", "8", "-o", "s.nhdr", "--labels", "s.raw"],  # the .nhdr's data file
                         "--labels and -o would write the same file (s.raw)")):
        r = run(*args, cwd=tmp_path)
        assert r.returncode == 2 and words in r.stderr, r.stderr
    assert not list(tmp_path.iterdir())
    assert run("synth", "textures", "--size", "16", "-o", "t.nrrd", cwd=tmp_path).returncode == 0
    r = run("segment", "t.nrrd", "-o", "l.raw", "--colors", "./l.raw", cwd=tmp_path)
    assert r.returncode == 2 and "two outputs would write the same file (./l.raw)" in r.stderr, r.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == ["t.nrrd"]


def test_transform_writes_raw_coefficients_only_to_a_raw_name(tmp_path, phantom):
    r = run("transform", phantom, "-o", tmp_path / "c.nrrd")
    assert r.returncode == 2 and "the coefficients are written as OUT.raw (and OUT.json)" in r.stderr, r.stderr
    assert not (tmp_path / "c.nrrd").exists() and not (tmp_path / "c.nrrd.json").exists()


@pytest.mark.parametrize("text, words", [
    ('{"points": [[0,0,0,0,0],[1,1,1,1,1]]', "the object is not closed"),
    ('{"points": [[0,0,0,0,0],[1,1,1,1,1]], "points": 5}', '"points" given twice'),
    ('{"points": [[0,0,0,0,0],[1,1,1,1,1]]} trailing', "text after the closing brace"),
    ('{"points": [[0,0,0,0,0],[1,1,1,1,1]}', "brackets do not match"),
])
def test_json_transfer_functions_must_be_well_formed(tmp_path, phantom, text, words):
    tf = tmp_path / "tf.json"
    tf.write_text(text)
    r = run("render", phantom, "-o", tmp_path / "o.png", "--size", "8x8", "--tf", tf)
    assert r.returncode == 1 and f"malformed JSON transfer function: {words}" in r.stderr, r.stderr
    assert not (tmp_path / "o.png").exists()


def test_messages_quoting_a_damaged_file_stay_one_line_of_text(tmp_path):
    bad = tmp_path / "a.nrrd"
    bad.write_bytes(b"NRRD0004\ntype: float\ndimension: 3\nsizes: 2 1 1\nencoding: ascii\n\n1 5x\n")
    r = run("info", bad)
    assert r.returncode == 1 and "value 2 '5x' is not a number" in r.stderr, r.stderr
    noise = tmp_path / "r.vtk"
    noise.write_bytes(bytes(range(256)) * 2)
    r = run("info", noise)
    assert r.returncode == 1
    assert r.stderr.endswith("\n") and r.stderr.count("\n") == 1
    assert all(c >= " " and c != "\x7f" for c in r.stderr[:-1]), repr(r.stderr)


def test_what_is_wrong_inside_an_input_file_is_exit_1(tmp_path, phantom):
    # docs/cli.md: 1 for malformed input, 2 for bad usage; a file's content is input
    tf = tmp_path / "tf.txt"
    tf.write_text("0 0 0 0 0\n1 1 1 1 nan\n")
    r = run("render", phantom, "-o", tmp_path / "o.png", "--size", "8x8", "--tf", tf)
    assert r.returncode == 1 and "--tf:" in r.stderr, r.stderr
    r = run("render", phantom, "-o", tmp_path / "o.png", "--size", "8x8", "--tf", "nosuchpreset")
    assert r.returncode == 2  # neither a preset nor a file: usage
    (tmp_path / "s.mtl").write_text("newmtl w\nKd 0.5 0.5 0.5\nKe 1 1 1\n")
    obj = tmp_path / "s.obj"
    obj.write_text("mtllib s.mtl\nv 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nusemtl w\nf 1 2 3 4\n")  # degenerate
    r = run("radiosity", obj, "-o", tmp_path / "r.png")
    assert r.returncode == 1 and "degenerate quad" in r.stderr, r.stderr
    truth = tmp_path / "t.nrrd"
    assert run("synth", "gaussian", "--size", "8", "-o", truth).returncode == 0
    r = run("segment", phantom, "-o", tmp_path / "l.nrrd", "--levels", "1", "--iters", "20", "--truth", truth)
    assert r.returncode == 1 and "truth is 8x8x8 but the volume is 16x16x16" in r.stderr, r.stderr
    assert not (tmp_path / "o.png").exists() and not (tmp_path / "r.png").exists() and not (tmp_path / "l.nrrd").exists()


# A write that fails part way (a full disk, here a file-size limit: writes past it fail with
# EFBIG) is an error and leaves nothing at the path. MetaImage's, NIfTI's and OpenVDB's own
# writers report no failed write, so their file is read back before it is renamed into place.
_FULL_DISK = r'''
import resource, signal, sys
import wvol
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
v = wvol.synth.turbulence(shape=(48, 48, 48))
resource.setrlimit(resource.RLIMIT_FSIZE, (48 * 1024, 48 * 1024))
try:
    wvol.save(v, sys.argv[1])
except OSError as e:
    print("OSError:", e)
else:
    print("saved")
'''


@pytest.mark.parametrize("ext", [".mha", ".nii", ".nii.gz", ".vdb", ".vti", ".vtk", ".raw", ".nrrd"])
def test_save_on_a_full_disk_fails_and_leaves_nothing(tmp_path, ext):
    out = tmp_path / f"v{ext}"
    r = subprocess.run([sys.executable, "-c", _FULL_DISK, str(out)], capture_output=True, text=True, timeout=TIMEOUT,
                       env={**os.environ})
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("OSError:") and str(out) in r.stdout, r.stdout + r.stderr
    assert os.listdir(tmp_path) == [], os.listdir(tmp_path)


def test_a_report_that_cannot_be_written_fails_the_command(tmp_path, phantom):
    # info's result is its report: written to a full disk, it must not exit 0 as if read
    with open("/dev/full", "w") as full:
        r = subprocess.run([WVOL_BIN, "info", str(phantom), "--json"], stdout=full, stderr=subprocess.PIPE,
                           text=True, timeout=TIMEOUT)
        assert r.returncode == 1 and "cannot write to standard output: No space left on device" in r.stderr, r.stderr
        out = tmp_path / "s.nrrd"
        r = subprocess.run([WVOL_BIN, "synth", "gaussian", "--size", "8", "-o", str(out)], stdout=full,
                           stderr=subprocess.PIPE, text=True, timeout=TIMEOUT)
        assert r.returncode == 1 and "cannot write to standard output" in r.stderr, r.stderr
        assert not out.exists()  # a failed command's outputs are undone


def test_outputs_that_would_replace_another_output_or_the_input_are_refused(tmp_path, phantom):
    # -o and --bound (or --mesh) naming one file wrote the image and then the bound over it, exit 0;
    # a detached header's data file named like the input replaced the input with float32 samples
    assert run("synth", "gaussian", "--size", "8", "-o", "v.raw", cwd=tmp_path).returncode == 0
    before = (tmp_path / "v.raw").read_bytes()
    cases = [
        (["render", "v.raw", "--dims", "8x8x8", "-o", "a.exr", "--bound", "./a.exr", "--keep", "50%"],
         "--bound and -o would write the same file (./a.exr)"),
        (["radiosity", "box", "-o", "r.ply", "--mesh", "./r.ply"], "--mesh and -o would write the same file (./r.ply)"),
        (["convert", "v.raw", "v.nhdr", "--dims", "8x8x8"], "v.nhdr: its data file v.raw is the input"),
        (["segment", "v.raw", "--dims", "8x8x8", "-o", "v.nhdr"], "v.nhdr: its data file v.raw is the input"),
    ]
    for args, words in cases:
        r = run(*args, cwd=tmp_path)
        assert r.returncode == 2 and words in r.stderr, (args, r.stderr)
    assert run("transform", "v.raw", "--dims", "8x8x8", "-o", "c.raw", cwd=tmp_path).returncode == 0
    r = run("inverse", "c.raw", "-o", "c.nhdr", cwd=tmp_path)
    assert r.returncode == 2 and "c.nhdr: its data file c.raw is the input" in r.stderr, r.stderr
    r = run("inverse", "c.raw", "-o", "c.zzz", cwd=tmp_path)  # refused before the inverse transform
    assert r.returncode == 2 and "-o c.zzz: cannot write this format" in r.stderr, r.stderr
    assert (tmp_path / "v.raw").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.json", "c.raw", "g.nrrd", "v.raw"]


def test_names_up_to_the_longest_a_folder_allows_are_written(tmp_path):
    # the temporary beside the output (and the kept earlier file) took the output's name plus
    # 11 bytes: a name of 245-255 bytes could not be written or replaced
    name = "b" * 249 + ".nrrd"
    uname = "é" * 122 + ".nrrd"  # 249 bytes of two-byte characters: shortened at a character's start
    for n in (name, uname):
        for _ in range(2):  # written, then replaced (the earlier file kept beside it meanwhile)
            r = run("synth", "gaussian", "--size", "8", "-o", n, cwd=tmp_path)
            assert r.returncode == 0, r.stderr
        r = run("convert", n, n[:-5] + ".vti", cwd=tmp_path)  # VTK's writers' temporaries too
        assert r.returncode == 0, r.stderr
        r = run("compress", n, "-o", n[:-5] + ".wvc", "--psnr", "40", "--memory", "64K", cwd=tmp_path)
        assert r.returncode == 0, r.stderr  # the streamed writer's spill file beside it
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [name, name[:-5] + ".vti", name[:-5] + ".wvc", uname, uname[:-5] + ".vti", uname[:-5] + ".wvc"])


def test_a_tf_folder_or_sidecar_fifo_is_named_so(tmp_path, phantom):
    # a --tf naming a folder was reported as an unknown preset; inverse's sidecar as a FIFO said
    # "Invalid argument"
    (tmp_path / "tfd").mkdir()
    r = run("render", phantom, "-o", tmp_path / "o.png", "--size", "8x8", "--tf", tmp_path / "tfd")
    assert r.returncode == 1 and "tfd: not a regular file" in r.stderr, r.stderr
    assert run("transform", phantom, "-o", tmp_path / "c.raw").returncode == 0
    (tmp_path / "c.json").unlink()
    os.mkfifo(tmp_path / "c.json")
    r = run("inverse", tmp_path / "c.raw", "-o", tmp_path / "x.nrrd")
    assert r.returncode == 1 and "cannot open the sidecar of" in r.stderr and "not a regular file" in r.stderr, r.stderr
    assert not (tmp_path / "o.png").exists() and not (tmp_path / "x.nrrd").exists()


def test_double_dash_ends_the_options(tmp_path):
    # a file whose name starts with '-' was taken for an option ("unknown option '--'")
    assert run("synth", "gaussian", "--size", "8", "-o", "./-a.nrrd", cwd=tmp_path).returncode == 0
    r = run("convert", "--", "-a.nrrd", "-b.vti", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    r = run("info", "--json", "--", "-b.vti", cwd=tmp_path)
    assert r.returncode == 0 and json.loads(r.stdout)["dims"] == [8, 8, 8], r.stderr


def test_a_truncated_index_names_the_file_size(tmp_path):
    # the message gave the bytes read first (224), not the file's size
    assert run("synth", "skull", "--size", "64", "-o", tmp_path / "b.nrrd").returncode == 0
    assert run("compress", tmp_path / "b.nrrd", "-o", tmp_path / "b.wvc", "--psnr", "50").returncode == 0
    data = (tmp_path / "b.wvc").read_bytes()
    (tmp_path / "t.wvc").write_bytes(data[:1000])
    r = run("info", tmp_path / "t.wvc")
    assert r.returncode == 1 and ".wvc file truncated: 1000 bytes, the header alone needs" in r.stderr, r.stderr


def test_an_unwritable_format_says_what_to_write(tmp_path, phantom):
    # "cannot write this format with this build" suggested that another build would write .mhd
    r = run("convert", phantom, tmp_path / "o.mhd")
    assert r.returncode == 2 and "MetaImage is written as .mha" in r.stderr, r.stderr
    r = run("convert", phantom, tmp_path / "o.zzz")
    assert r.returncode == 2 and "see 'wvol convert --help' for the formats this build writes" in r.stderr, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.nrrd"]
