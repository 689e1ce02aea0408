# SPDX-License-Identifier: MIT
"""The .wvc readers: for plain VTK (python/wvol/vtk_wvc.py) and for ParaView (the C++ plugin
paraview/, vtkWVCReader; docs/paraview.md).

- Plain VTK (Debian's VTK, in this process): the whole extent, a level of detail, a region and
  a piece equal the same samples of `wvol decompress`; a piece decodes only part of the chunks,
  two pieces' chunks together are the whole read's; bad files are refused with a message.
- pvpython (ParaView's own VTK; the C++ plugin from scripts/setup.sh's build without the VTK
  adapter): the reader's array equals `wvol decompress` at full resolution and at a dropped
  level; bad files, a region outside the volume and a level out of range give a ParaView error
  message, and the session goes on; the plugin links no VTK but ParaView's.
- pvbatch alone and under `mpiexec -n 2` (on an Xvfb display): each rank decodes about half of the chunks, their
  union is every chunk, and the volume rendering and Contour screenshots equal the one-process
  ones within compositing rounding.

ParaView is part of the setup (scripts/setup.sh builds build-paraview/): these tests fail,
rather than skip, when it is missing."""
import json
import os
import pathlib
import re
import shutil
import subprocess

import numpy as np
import pytest

from conftest import ROOT, WVOL_BIN
from pvscripts import headless  # tests/python/pvscripts/headless.py

PV_BUILD = pathlib.Path(os.environ.get("WVOL_PARAVIEW_BUILD_DIR", ROOT / "build-paraview"))
PLUGIN = PV_BUILD / "paraview-plugins" / "WvolReader" / "WvolReader.so"  # the C++ reader (paraview/)
SCRIPTS = pathlib.Path(__file__).resolve().parent / "pvscripts"
SHAPE = (128, 64, 80)  # (z, y, x): unequal axes catch an axis-order mistake; z, the longest, is split
ISO = 100.0


def run(cmd, timeout=300, env=None):
    return subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout,
                          env=None if env is None else {**os.environ, **env})


@pytest.fixture(scope="module")
def wvc(tmp_path_factory):
    """A noisy skull, 80x64x128, as a format-2 .wvc with small tiles (many chunks), with its whole
    decode and its level-1 decode by the command line."""
    d = tmp_path_factory.mktemp("pv")
    vol, f = d / "s.nrrd", d / "s.wvc"
    nz, ny, nx = SHAPE
    for cmd in (["synth", "skull", "--size", f"{nx}x{ny}x{nz}", "--noise", "20", "--spacing", "0.5,0.75,1.25",
                 "-o", vol],
                ["compress", vol, "-o", f, "--psnr", "45", "--levels", "3", "--tile", "8,8"],
                ["decompress", f, "-o", d / "full.raw"],
                ["decompress", f, "-o", d / "level1.raw", "--level", "1"]):
        r = run([WVOL_BIN, *cmd])
        assert r.returncode == 0, r.stderr
    full = np.fromfile(d / "full.raw", dtype="<f4").reshape(SHAPE)
    l1 = np.fromfile(d / "level1.raw", dtype="<f4").reshape(tuple(-(-n // 2) for n in SHAPE))
    return d, f, full, l1


def wrap_layer_chunks(info):
    """Chunks in one z tile layer of every level: what a slab-by-slab read decodes twice at
    most, the periodic wrap of the first slab (the last layer) being needed again at the end
    after the cache, sized for two layers (wvol_wvc_slab_budget), has let it go."""
    nz, ny, nx = info["padded"]
    tile = info["tile"][0]
    return sum(-(-(nx >> m) // tile) * -(-(ny >> m) // tile) for m in range(1, info["levels"] + 1))


def close(got, want):
    """Two summation orders of the same coefficients (a brick reconstruction against the whole
    inverse transform): float rounding, 1e-5 of the peak."""
    assert got.shape == want.shape
    assert np.max(np.abs(got.astype(np.float64) - want)) <= 1e-5 * np.max(np.abs(want))


# ---- plain VTK ------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def vtk_reader():
    import vtkmodules  # noqa: F401  (python3-vtk9, scripts/packages.txt, is part of the setup: fail, not skip)
    from wvol.vtk_wvc import WVCReader
    return WVCReader


def image_array(img):
    from vtkmodules.util.numpy_support import vtk_to_numpy
    e = img.GetExtent()
    return vtk_to_numpy(img.GetPointData().GetScalars()).reshape(e[5] - e[4] + 1, e[3] - e[2] + 1, e[1] - e[0] + 1)


def field(img, name):
    return img.GetFieldData().GetArray(name).GetTuple1(0)


def test_vtk_reader_whole_and_dropped_level(wvc, vtk_reader):
    import wvol
    d, f, full, l1 = wvc
    info = wvol.wvc_info(f)
    r = vtk_reader()
    r.SetFileName(str(f))
    r.Update()
    img = r.GetOutputDataObject(0)
    close(image_array(img), full)
    assert img.GetSpacing() == pytest.approx((0.5, 0.75, 1.25))
    # the value range handed over with the array (VTK's range cache) is the array's own
    a, arr = image_array(img), img.GetPointData().GetScalars()
    assert arr.GetInformation().Has(arr.PER_COMPONENT()) and arr.GetInformation().Has(arr.PER_FINITE_COMPONENT())
    assert arr.GetRange(0) == (float(a.min()), float(a.max()))
    assert arr.GetFiniteRange(0) == (float(a.min()), float(a.max()))
    assert img.GetOrigin() == pytest.approx(info["origin"])
    # the error report is the header's (wvc_info reads it independently)
    n = float(np.prod(SHAPE))
    assert field(img, "PredictedRMSE") == pytest.approx(np.sqrt(info["sse"] / n), rel=1e-12)
    assert field(img, "KeptCoefficients") == info["nonzero"]
    assert 0 < field(img, "ChunksDecoded") <= r.GetFileInfo()["chunks"] + wrap_layer_chunks(r.GetFileInfo())
    # level 1: the CLI's coarse decode, spacing doubled, the first sample moved by the filter's centre
    r.SetLevelOfDetail(1)
    r.Update()
    img = r.GetOutputDataObject(0)
    close(image_array(img), l1)
    assert img.GetSpacing() == pytest.approx((1.0, 1.5, 2.5))
    assert img.GetOrigin() == pytest.approx(r.GetFileInfo()["level_origins"][1])
    assert field(img, "LevelOfDetail") == 1


def test_vtk_reader_region_and_pieces(wvc, vtk_reader):
    d, f, full, _ = wvc
    whole = vtk_reader()
    whole.SetFileName(str(f))
    whole.Update()
    all_chunks = field(whole.GetOutputDataObject(0), "ChunksDecoded")
    # a region: its voxels, and fewer chunks than the whole
    r = vtk_reader()
    r.SetFileName(str(f))
    r.SetRegion(5, 40, 0, -1, 30, 47)
    r.Update()
    img = r.GetOutputDataObject(0)
    assert img.GetExtent() == (5, 40, 0, 63, 30, 47)
    close(image_array(img), full[30:48, :, 5:41])
    assert 0 < field(img, "ChunksDecoded") < all_chunks
    # two pieces, one after the other on one reader (as two ranks would): each decodes part of
    # the chunks, both together exactly the whole read's chunks (a cache of 1 GiB holds them all;
    # the default keeps only what one read pins, so the second piece would decode the shared
    # coarse chunks again)
    p = vtk_reader()
    p.SetFileName(str(f))
    p.SetMemoryBudget(1024)
    got = []
    for piece in range(2):
        p.UpdatePiece(piece, 2, 0)
        img = p.GetOutputDataObject(0)
        e = img.GetExtent()
        close(image_array(img), full[e[4]:e[5] + 1, e[2]:e[3] + 1, e[0]:e[1] + 1])
        got.append(field(img, "ChunksDecoded"))
    # about half each: a chunk is decoded with its parent chain and the supports of db2 reach
    # across the cut, so both pieces share the coarse levels and the chunks near the cut
    assert all(0.25 * all_chunks <= g <= 0.75 * all_chunks for g in got), (got, all_chunks)
    assert field(p.GetOutputDataObject(0), "ChunksDecodedTotal") == all_chunks


def test_vtk_reader_slabs_equal_one_read(wvc, vtk_reader, monkeypatch):
    """A piece is reconstructed in z slabs of SLAB_SAMPLES (bounding the working memory): with
    slabs of 7 planes (not dividing 128) the samples are the same, and with the cache holding
    everything no chunk is decoded twice."""
    import wvol.vtk_wvc as vw
    d, f, full, _ = wvc
    whole = vtk_reader()
    whole.SetFileName(str(f))
    whole.Update()
    monkeypatch.setattr(vw, "PIECE_READS", False)
    monkeypatch.setattr(vw, "SLAB_SAMPLES", SHAPE[1] * SHAPE[2] * 7)
    r = vtk_reader()
    r.SetFileName(str(f))
    r.Update()
    img = r.GetOutputDataObject(0)
    close(image_array(img), full)
    # the piece read decodes each chunk once; slabs with the cache their reads need decode the
    # first slab's periodic wrap again at the end, nothing else
    once = field(whole.GetOutputDataObject(0), "ChunksDecoded")
    assert once == r.GetFileInfo()["chunks"]
    assert once <= field(img, "ChunksDecoded") <= once + wrap_layer_chunks(r.GetFileInfo())


def test_slab_budget_is_what_slab_reads_need(wvc, vtk_reader):
    """wvol_wvc_slab_budget: with a cache of that size, reading the volume in slabs of 7 planes
    decodes each chunk once, but for the first slab's periodic wrap (the last tile layer of each
    level, needed again at the end); with a quarter of it the slabs evict chunks the next slab
    decodes again. The reader opens with it (MemoryBudget 0)."""
    from wvol import _wvol
    d, f, full, _ = wvc
    nz, ny, nx = SHAPE
    h = _wvol.wvc_file_open(str(f))
    info = _wvol.wvc_file_info(h)
    need = _wvol.wvc_file_slab_budget(h, [0, 0, 0], [nx, ny, nz])
    # a box narrower in x and y needs fewer chunks per layer; a coarser grid fewer levels
    assert 0 < _wvol.wvc_file_slab_budget(h, [0, 0, 0], [16, 16, nz]) < need
    assert 0 < _wvol.wvc_file_slab_budget(h, [0, 0, 0], [nx // 2, ny // 2, nz // 2], level=1) < need
    for bad in (dict(level=4), dict(level=-1), dict(hi=[nx, 0, nz])):
        with pytest.raises(ValueError):
            _wvol.wvc_file_slab_budget(h, [0, 0, 0], bad.get("hi", [nx, ny, nz]), level=bad.get("level", 0))
    wrap = wrap_layer_chunks(info)

    def decodes(budget):
        h = _wvol.wvc_file_open(str(f), budget=budget)
        out = np.empty(SHAPE, np.float32)
        for z0 in range(0, nz, 7):
            _wvol.wvc_file_region(h, [0, 0, z0], [nx, ny, min(nz, z0 + 7)], 0, out=out[z0:z0 + 7])
        close(out, full)
        return _wvol.wvc_file_stats(h)["decoded"]

    assert info["chunks"] <= decodes(need) <= info["chunks"] + wrap
    assert decodes(need // 4) > info["chunks"] + wrap
    # the open file's budget set to the need (what the reader does) reads like a file opened with it
    h = _wvol.wvc_file_open(str(f))
    _wvol.wvc_file_set_budget(h, need)
    assert _wvol.wvc_file_stats(h)["budget"] == need
    for bad in (-1, 1):
        with pytest.raises((ValueError, MemoryError)):
            _wvol.wvc_file_set_budget(h, bad)
    assert _wvol.wvc_file_stats(h)["budget"] == need
    # the reader (MemoryBudget 0) sets it for a slab read, and for a piece read what that pins
    import wvol.vtk_wvc as vw
    r = vtk_reader()
    r.SetFileName(str(f))
    r.SetThreads(2)
    r.Update()
    assert r.GetChunkStats()["budget"] == _wvol.wvc_file_piece_budget(h, 2) < need
    vw.PIECE_READS = False
    try:
        r.Modified()
        r.Update()
    finally:
        vw.PIECE_READS = True
    assert r.GetChunkStats()["budget"] == need


def test_vtk_reader_threads_give_the_same_samples(wvc, vtk_reader):
    """Threads reconstruct parts of each slab at once, sharing the cache: the samples are the
    one-thread read's bit for bit, and each chunk is still decoded once (a thread needing a
    chunk another is decoding waits for it)."""
    d, f, full, _ = wvc
    out = {}
    for threads in (1, 3):
        r = vtk_reader()
        r.SetFileName(str(f))
        r.SetThreads(threads)
        r.Update()
        img = r.GetOutputDataObject(0)
        out[threads] = (image_array(img).copy(), field(img, "ChunksDecoded"))
    assert np.array_equal(out[1][0], out[3][0])
    assert out[1][1] == out[3][1] > 0
    close(out[3][0], full)
    with pytest.raises(ValueError, match="Threads"):
        vtk_reader().SetThreads(-1)


def test_piece_read_equals_region_read(wvc):
    """wvc_file_piece (a box spanning the level's grid along x and y, decoded into its own array
    and inverted in place) gives the samples of the region read of the same box (float rounding:
    two summation orders), at full resolution and dropped levels, for random z ranges and the
    edges (the periodic wrap below the first plane and above the last), on 1 and 3 threads (the
    same samples bit for bit), decoding each chunk once with the cache holding only what one
    read pins; other boxes are not pieces (None), and a budget below the pins is refused."""
    import wvol
    _wvol = wvol._wvol
    d, f, full, l1 = wvc
    rng = np.random.default_rng(21)
    h = _wvol.wvc_file_open(str(f))
    info = _wvol.wvc_file_info(h)
    for level in range(info["levels"]):
        gz, gy, gx = info["level_shapes"][level]
        ranges = [(0, gz), (0, 1), (gz - 1, gz), (0, gz // 2), (gz // 2, gz)]
        ranges += [tuple(sorted(rng.choice(gz + 1, 2, replace=False))) for _ in range(4)]
        for z0, z1 in ranges:
            lo, hi = [0, 0, int(z0)], [gx, gy, int(z1)]
            want, sp, org = _wvol.wvc_file_region(h, lo, hi, level)
            got = {}
            for threads in (1, 3):
                p = _wvol.wvc_file_open(str(f))
                _wvol.wvc_file_set_budget(p, _wvol.wvc_file_piece_budget(p, threads))
                a, sp2, org2 = _wvol.wvc_file_piece(p, lo, hi, level, threads)
                stats = _wvol.wvc_file_stats(p)
                assert stats["decoded"] <= info["chunks"] and stats["peak"] <= stats["budget"]
                assert sp2 == pytest.approx(sp) and org2 == pytest.approx(org)
                close(a, want)
                got[threads] = a
            assert np.array_equal(got[1], got[3]), (level, z0, z1)
    # the whole volume at full resolution and at level 1: the command line's decodes
    close(_wvol.wvc_file_piece(h, [0, 0, 0], list(SHAPE[::-1]), 0)[0], full)
    close(_wvol.wvc_file_piece(h, [0, 0, 0], [40, 32, 64], 1)[0], l1)
    # a box narrower than the grid along x or y is not a piece; a last level has nothing to invert
    assert _wvol.wvc_file_piece(h, [1, 0, 0], [80, 64, 10], 0) is None
    assert _wvol.wvc_file_piece(h, [0, 0, 0], [80, 63, 10], 0) is None
    assert _wvol.wvc_file_piece(h, [0, 0, 0], [10, 8, 16], info["levels"]) is None
    p = _wvol.wvc_file_open(str(f))
    _wvol.wvc_file_set_budget(p, _wvol.wvc_file_piece_budget(p, 1))
    with pytest.raises(MemoryError, match="piece read with 2 threads"):
        _wvol.wvc_file_piece(p, [0, 0, 0], [80, 64, 8], 0, 2)


def test_region_into_an_array(wvc):
    """wvc_file_region(out=...) reconstructs into the caller's array (how the reader fills its
    output slab by slab) with the same samples as a fresh array, on any thread count; an array
    of the wrong shape, type or layout is refused with a message naming what it must be."""
    import wvol
    d, f, full, _ = wvc
    h = wvol._wvol.wvc_file_open(str(f))
    lo, hi = [3, 5, 17], [70, 60, 113]
    ref, sp, org = wvol._wvol.wvc_file_region(h, lo, hi, 0)
    for threads in (0, 1, 2):
        out = np.full((hi[2] - lo[2], hi[1] - lo[1], hi[0] - lo[0]), np.nan, dtype=np.float32)
        got, sp2, org2 = wvol._wvol.wvc_file_region(h, lo, hi, 0, out=out, threads=threads)
        assert got is out and np.array_equal(out, ref) and sp2 == sp and org2 == org
    close(ref, full[17:113, 5:60, 3:70])
    good = (hi[2] - lo[2], hi[1] - lo[1], hi[0] - lo[0])
    for bad in (np.zeros(good, np.float64), np.zeros(good[::-1], np.float32),
                np.zeros((good[0], good[1], 2 * good[2]), np.float32)[:, :, ::2]):
        with pytest.raises(ValueError, match="C-contiguous float32"):
            wvol._wvol.wvc_file_region(h, lo, hi, 0, out=bad)
    with pytest.raises(TypeError, match="numpy"):
        wvol._wvol.wvc_file_region(h, lo, hi, 0, out=[0.0])
    with pytest.raises(ValueError, match="threads"):
        wvol._wvol.wvc_file_region(h, lo, hi, 0, threads=-2)


def test_vtk_reader_release_cache(wvc, vtk_reader):
    """ReleaseCache closes the file after each execution (its chunks freed): a later execution
    reopens it, decodes its chunks again and gives the same samples."""
    d, f, full, _ = wvc
    r = vtk_reader()
    r.SetFileName(str(f))
    r.SetReleaseCache(True)
    counts = []
    for piece in (0, 1, 0):
        r.UpdatePiece(piece, 2, 0)
        img = r.GetOutputDataObject(0)
        assert r.GetChunkStats() is None
        e = img.GetExtent()
        close(image_array(img), full[e[4]:e[5] + 1, e[2]:e[3] + 1, e[0]:e[1] + 1])
        counts.append(field(img, "ChunksDecoded"))
    assert counts[0] == counts[2] > 0  # piece 0 again: decoded again, as many chunks


@pytest.mark.parametrize("damage", ["missing", "garbage", "truncated", "region", "level"])
def test_vtk_reader_refuses_bad_input(wvc, vtk_reader, tmp_path, damage):
    from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkStringOutputWindow
    d, f, _, _ = wvc
    path = tmp_path / "bad.wvc"
    if damage == "garbage":
        path.write_bytes(b"not a wvc file at all" * 50)
    elif damage == "truncated":
        path.write_bytes(f.read_bytes()[:1000])
    elif damage in ("region", "level"):
        path = f
    sink = vtkStringOutputWindow()
    previous = vtkOutputWindow.GetInstance()
    vtkOutputWindow.SetInstance(sink)
    try:
        r = vtk_reader()
        r.SetFileName(str(path))
        if damage == "region":
            r.SetRegion(70, 90, 0, 10, 0, 10)
        if damage == "level":
            r.SetLevelOfDetail(7)
        r.Update()
    finally:
        vtkOutputWindow.SetInstance(previous)
    out = sink.GetOutput()
    assert "WVCReader" in out and str(path) in out, out
    # the library's own reason, beside the path (asserted above)
    words = {"missing": "cannot open", "garbage": "not a .wvc file", "truncated": "truncated",
             "region": "axis x", "level": "level of detail 7"}[damage]
    assert words in out, out
    assert r.GetOutputDataObject(0).GetNumberOfPoints() == 0


def _errors_of(fn):
    """fn() with VTK's error output caught: its text."""
    from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkStringOutputWindow
    sink = vtkStringOutputWindow()
    previous = vtkOutputWindow.GetInstance()
    vtkOutputWindow.SetInstance(sink)
    try:
        fn()
    finally:
        vtkOutputWindow.SetInstance(previous)
    return sink.GetOutput()


@pytest.fixture(scope="module")
def other_wvc(tmp_path_factory):
    """A second, smaller file (24x20x16) with its whole decode: what replaces the first."""
    d = tmp_path_factory.mktemp("pv2")
    vol, f = d / "g.nrrd", d / "g.wvc"
    for cmd in (["synth", "gaussian", "--size", "24x20x16", "-o", vol],
                ["compress", vol, "-o", f, "--psnr", "45", "--levels", "2", "--tile", "8"],
                ["decompress", f, "-o", d / "full.raw"]):
        r = run([WVOL_BIN, *cmd])
        assert r.returncode == 0, r.stderr
    return f, np.fromfile(d / "full.raw", dtype="<f4").reshape(16, 20, 24)


def test_vtk_reader_failed_update_empties_the_output(wvc, vtk_reader):
    """A request that fails after one that succeeded leaves an empty output, not the previous
    data (RequestInformation fails, and the executive does not call RequestData)."""
    d, f, full, _ = wvc
    r = vtk_reader()
    r.SetFileName(str(f))
    r.Update()
    assert r.GetOutputDataObject(0).GetNumberOfPoints() == full.size
    for change in (lambda: r.SetLevelOfDetail(7), lambda: r.SetFileName(str(d / "missing.wvc")),
                   lambda: r.SetRegion(70, 90, 0, 10, 0, 10)):
        r.SetFileName(str(f))
        r.SetLevelOfDetail(0)
        r.SetRegion(0, -1, 0, -1, 0, -1)
        r.Update()
        assert r.GetOutputDataObject(0).GetNumberOfPoints() == full.size
        change()
        out = _errors_of(r.Update)
        assert "WVCReader" in out, out
        img = r.GetOutputDataObject(0)
        assert img.GetNumberOfPoints() == 0 and img.GetPointData().GetScalars() is None


def test_vtk_reader_sees_a_file_replaced_at_its_path(wvc, other_wvc, vtk_reader, tmp_path):
    """The open handle is the file at FileName: replaced there (os.replace, as an atomic writer
    does), the next update reads the new file with its own extent; with ReleaseCache a piece
    requested without new information is refused rather than read in the old file's frame."""
    d, f, full, _ = wvc
    g, gfull = other_wvc
    path = tmp_path / "r.wvc"
    shutil.copy(f, path)
    r = vtk_reader()
    r.SetFileName(str(path))
    r.Update()
    assert r.GetOutputDataObject(0).GetExtent() == (0, 79, 0, 63, 0, 127)
    shutil.copy(g, tmp_path / "new.wvc")
    os.replace(tmp_path / "new.wvc", path)
    r.Modified()
    r.Update()
    img = r.GetOutputDataObject(0)
    assert img.GetExtent() == (0, 23, 0, 19, 0, 15)
    close(image_array(img), gfull)

    shutil.copy(f, path)
    r2 = vtk_reader()
    r2.SetFileName(str(path))
    r2.SetReleaseCache(True)
    r2.UpdatePiece(0, 2, 0)
    assert r2.GetOutputDataObject(0).GetNumberOfPoints() > 0
    shutil.copy(g, tmp_path / "new.wvc")
    os.replace(tmp_path / "new.wvc", path)
    out = _errors_of(lambda: r2.UpdatePiece(1, 2, 0))
    assert "replaced since its information was read" in out, out
    assert r2.GetOutputDataObject(0).GetNumberOfPoints() == 0


def test_vtk_reader_refuses_a_budget_beyond_the_cpp_readers(vtk_reader):
    r = vtk_reader()
    with pytest.raises(ValueError, match="MemoryBudget must be in 0..2147483647"):
        r.SetMemoryBudget(2**44)
    r.SetMemoryBudget(2**31 - 1)


def test_vtk_reader_unwritable_chunk_log_is_a_warning(wvc, vtk_reader, tmp_path):
    """The data is read; a chunk log that cannot be appended to is reported, the request does
    not fail, and ReleaseCache still closes the file."""
    d, f, full, _ = wvc
    r = vtk_reader()
    r.SetFileName(str(f))
    r.SetChunkLog(str(tmp_path / "no" / "such" / "log.jsonl"))
    r.SetReleaseCache(True)
    out = _errors_of(r.Update)
    assert "cannot append to the chunk log" in out, out
    assert r.GetOutputDataObject(0).GetNumberOfPoints() == full.size
    assert r.GetChunkStats() is None


# ---- ParaView -------------------------------------------------------------------------------

def pv_tool(name):
    exe = PV_BUILD / name
    assert exe.exists() and PLUGIN.exists(), (
        f"{exe} or {PLUGIN} is missing: scripts/setup.sh installs ParaView and builds {PV_BUILD}")
    return exe


@pytest.mark.parametrize("level", [0, 1])
def test_pvpython_reader_equals_decompress(wvc, tmp_path, level):
    """Level 0 loads the plugin with LoadPlugin, level 1 from PV_PLUGIN_PATH at start-up."""
    d, f, full, l1 = wvc
    out = tmp_path / "a.npy"
    env = {"PV_PLUGIN_PATH": str(PLUGIN.parent)} if level == 1 else None
    r = run([pv_tool("pvpython"), SCRIPTS / "pv_read.py", PLUGIN, f, level, out], env=env)
    assert r.returncode == 0, r.stdout + r.stderr
    meta = json.loads(r.stdout.strip().splitlines()[-1])
    assert meta["autoloaded"] == (level == 1)
    close(np.load(out), full if level == 0 else l1)
    assert meta["spacing"] == pytest.approx([s * 2 ** level for s in (0.5, 0.75, 1.25)])
    assert meta["field"]["LevelOfDetail"] == level
    assert meta["field"]["ChunksDecoded"] > 0
    assert np.isfinite(meta["field"]["PredictedPSNR"]) and meta["field"]["PredictedPSNR"] > 30
    # the range handed over with the array (so that VTK does not scan it again) is the array's own,
    # exactly: float32 extremes converted to double
    a = np.load(out)
    assert meta["known_range"] is not None
    assert meta["known_range"]["range"] == [float(a.min()), float(a.max())]
    assert meta["known_range"]["finite_range"] == [float(a.min()), float(a.max())]


def test_pvpython_level_slider_follows_the_file(wvc):
    # the LevelOfDetail slider was fixed at 0..8: levels a 3-level file lacks, and not the 30 a
    # file can have; its range now comes from the file (LevelRangeInfo)
    d, f, _, _ = wvc
    r = run([pv_tool("pvpython"), SCRIPTS / "pv_levels.py", PLUGIN, f])
    assert r.returncode == 0, r.stdout + r.stderr
    assert "RANGE 0 3" in r.stdout, r.stdout


def test_pvpython_region(wvc, tmp_path):
    d, f, full, _ = wvc
    out = tmp_path / "a.npy"
    r = run([pv_tool("pvpython"), SCRIPTS / "pv_read.py", PLUGIN, f, 0, out, 10, 20, 3, 50, 0, 12])
    assert r.returncode == 0, r.stdout + r.stderr
    close(np.load(out), full[0:13, 3:51, 10:21])


@pytest.mark.parametrize("damage", ["garbage", "truncated", "header", "missing", "region", "level", "array"])
def test_pvpython_bad_file_is_an_error_not_a_crash(wvc, tmp_path, damage):
    d, f, _, _ = wvc
    path = tmp_path / "bad.wvc"
    extra = []
    if damage == "garbage":
        path.write_bytes(b"\x00\x01garbage" * 300)
    elif damage == "truncated":
        path.write_bytes(f.read_bytes()[: f.stat().st_size // 2])
    elif damage == "header":  # the header alone: the chunk index cut short
        path.write_bytes(f.read_bytes()[:200])
    elif damage == "region":
        path, extra = f, ["--region", "70", "90", "0", "10", "0", "10"]  # x0 beyond the last voxel (79)
    elif damage == "level":
        path, extra = f, ["--level", "7"]  # the file has 3 levels
    elif damage == "array":
        path, extra = f, ["--array="]  # no name to colour by (was an unnamed array); pvpython dies on an empty argv item
    r = run([pv_tool("pvpython"), SCRIPTS / "pv_bad.py", PLUGIN, path, *extra])
    assert r.returncode == 0, r.stdout + r.stderr
    assert "SURVIVED points=0" in r.stdout, r.stdout + r.stderr
    assert "WVCReader" in r.stderr and str(path) in r.stderr, r.stderr
    # the library's own reason (half a file: its index or a chunk named as damaged)
    words = {"missing": "cannot open", "garbage": "not a .wvc file", "truncated": "chunk",
             "header": "truncated", "region": "axis x", "level": "level of detail 7",
             "array": "ArrayName is empty"}[damage]
    assert words in r.stderr, r.stderr
    # ParaView calls RequestData after a failed RequestInformation: no second message from it
    assert "no file information" not in r.stderr, r.stderr


def test_pvpython_reader_sequence(wvc, other_wvc, tmp_path):
    """The C++ reader driven as a VTK pipeline drives it (tests/python/pvscripts/pv_sequence.py):
    a failed execution empties the output; a file replaced at the path is read anew after
    Modified(); with ReleaseCache a replaced file is refused, not read in the old frame;
    Threads out of range is refused. The messages name the file once."""
    d, f, full, _ = wvc
    g, _ = other_wvc
    r = run([pv_tool("pvpython"), SCRIPTS / "pv_sequence.py", PLUGIN, f, g, tmp_path])
    assert r.returncode == 0, r.stdout + r.stderr
    steps = json.loads(r.stdout.strip().splitlines()[-1])
    assert steps["first"]["points"] == full.size
    assert steps["bad_level"]["points"] == 0 and not steps["bad_level"]["scalars"]
    assert steps["copy"]["extent"] == [0, 79, 0, 63, 0, 127]
    assert steps["replaced"]["extent"] == [0, 23, 0, 19, 0, 15] and steps["replaced"]["points"] == 24 * 20 * 16
    assert steps["piece0"]["points"] > 0
    assert steps["piece1_replaced"]["points"] == 0
    assert steps["threads"]["points"] == 0
    err = r.stderr
    assert "level of detail 7" in err and "replaced since its information was read" in err, err
    assert "Threads must be in 0..4096" in err, err
    assert f"{f}: {f}" not in err, err


def test_plugin_links_paraviews_vtk_only():
    """Two VTKs must not meet in one process: the plugin and its module link ParaView's VTK
    libraries (libvtk*-pv5.11) and libwvol statically, never Debian's VTK 9.1 (the VTK adapter)
    nor a shared libwvol."""
    pv_tool("pvpython")
    libs = [PLUGIN, *PLUGIN.parent.glob("libwvolWVCReader.so*")]
    assert len(libs) == 2, libs
    for lib in libs:
        needed = re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]",
                            run(["readelf", "-d", lib]).stdout)
        vtk = [n for n in needed if n.startswith("libvtk")]
        assert vtk and all("-pv5." in n for n in vtk), (lib, needed)
        assert not any(n.startswith("libwvol.") or n.startswith("libwvol_adapters") for n in needed), (lib, needed)


def chunk_lines(log):
    return [json.loads(line) for line in pathlib.Path(log).read_text().splitlines()]


def pvbatch_render(wvc, outdir, ranks):
    d, f, full, _ = wvc
    outdir.mkdir()
    log = outdir / "chunks.jsonl"
    cmd = [pv_tool("pvbatch"), SCRIPTS / "pv_render.py", PLUGIN, f, outdir, log, float(full.min()),
           float(full.max()), ISO]
    if ranks > 1:
        cmd = [shutil.which("mpiexec"), "-n", ranks, "--allow-run-as-root", "--oversubscribe", *cmd]
    with headless.display() as disp:
        r = run(cmd, timeout=600, env={"DISPLAY": disp})
    assert r.returncode == 0, r.stdout + r.stderr
    return chunk_lines(log)


def png(path):
    from PIL import Image
    return np.asarray(Image.open(path).convert("RGB")).astype(np.int32)


def test_mpi_two_ranks_split_the_chunks_and_match_one_rank(wvc, tmp_path):
    import wvol
    d, f, full, _ = wvc
    one = pvbatch_render(wvc, tmp_path / "one", 1)
    two = pvbatch_render(wvc, tmp_path / "two", 2)
    # the chunks a whole read decodes (one handle, nothing evicted)
    h = wvol._wvol.wvc_file_open(str(f))
    wvol._wvol.wvc_file_region(h, [0, 0, 0], [SHAPE[2], SHAPE[1], SHAPE[0]], 0)
    all_chunks = wvol._wvol.wvc_file_stats(h)["decoded"]
    # one rank reads slab by slab with the cache its slabs need: every chunk, a layer twice at most
    info = wvol._wvol.wvc_file_info(h)
    assert all_chunks <= sum(e["decoded"] for e in one if e["pieces"] == 1) <= all_chunks + wrap_layer_chunks(info)
    # two ranks, each its own piece (the first execution of each rank)
    first = {}
    for e in two:
        first.setdefault(e["rank"], e)
    assert sorted(first) == [0, 1], two
    assert sorted(e["piece"] for e in first.values()) == [0, 1]
    assert all(e["pieces"] == 2 for e in first.values())
    # a z slab spanning x and y: decoded straight into the output array (the piece read)
    assert all(e["read"] == "piece" for e in first.values()), first
    for e in first.values():
        # about half each (as test_vtk_reader_region_and_pieces: the coarse levels and the chunks
        # whose supports reach across the cut are decoded by both)
        assert 0.25 * all_chunks <= e["decoded"] <= 0.75 * all_chunks, (e, all_chunks)
    # their union is every chunk: one handle reading both ranks' extents decodes the whole set
    u = wvol._wvol.wvc_file_open(str(f))
    for e in first.values():
        x = e["extent"]
        wvol._wvol.wvc_file_region(u, [x[0], x[2], x[4]], [x[1] + 1, x[3] + 1, x[5] + 1], 0)
    assert wvol._wvol.wvc_file_stats(u)["decoded"] == all_chunks
    # screenshots: equal within compositing rounding (IceT blends the ranks' 8-bit images, the
    # volume's rays restart at the cut): a few grey levels on a few pixels, no structure moved
    for name in ("volume.png", "contour.png"):
        a, b = png(tmp_path / "one" / name), png(tmp_path / "two" / name)
        assert a.shape == b.shape
        assert a.max() > 40, f"{name}: the one-rank image is empty"
        diff = np.abs(a - b)
        assert np.mean(diff) <= 1.0, (name, float(np.mean(diff)))
        assert np.mean(diff > 8) <= 0.01, (name, float(np.mean(diff > 8)))
    docs = os.environ.get("WVOL_DOC_IMAGES")
    if docs:  # docs/paraview.md's screenshots come from this test (WVOL_DOC_IMAGES=docs/img)
        pathlib.Path(docs).mkdir(parents=True, exist_ok=True)
        for name in ("volume.png", "contour.png"):
            shutil.copy(tmp_path / "two" / name, pathlib.Path(docs) / f"paraview-mpi2-{name}")
