# SPDX-License-Identifier: MIT
"""The random-access .wvc (format 2) from the command line: regions and levels read from the
file equal the same part of a whole decode; reads stay within --memory, with the resident
peak of the process measured; every command that takes a volume takes a .wvc; a damaged
chunk fails only the regions that need it, naming it; a budget too small is refused."""
import json
import os
import re
import subprocess
import zlib

import numpy as np
import pytest

from conftest import WVOL_BIN

N = 96


@pytest.fixture(scope="module")
def wvc(tmp_path_factory):
    """A 96^3 noisy skull as format 2 with small tiles (many chunks), and its whole decode."""
    d = tmp_path_factory.mktemp("wvc2")
    vol, f, full = d / "s.nrrd", d / "s.wvc", d / "full.raw"
    for cmd in (["synth", "skull", "--size", str(N), "--noise", "20", "-o", vol],
                ["compress", vol, "-o", f, "--psnr", "50", "--levels", "3", "--tile", "16,16"],
                ["decompress", f, "-o", full]):
        r = subprocess.run([WVOL_BIN, *map(str, cmd)], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    return d, f, np.fromfile(full, dtype="<f4").reshape(N, N, N)


def peak_rss(*args):
    """Peak resident memory (bytes) of one wvol run, from the kernel's accounting of the child."""
    p = subprocess.Popen([WVOL_BIN, *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    out, err = p.stdout.read(), p.stderr.read()
    assert os.waitstatus_to_exitcode(status) == 0, err.decode()
    return ru.ru_maxrss * 1024, out.decode()


@pytest.mark.parametrize("level", [0, 1, 2])
def test_region_equals_the_whole_decode(wvc, level):
    d, f, full = wvc
    # boxes at the corner, at the far edges (the periodic basis wraps there) and inside
    for box in ([0, 0, 0, 20, 9, 33], [70, 80, 90, 96, 96, 96], [17, 40, 5, 61, 59, 77]):
        out = d / f"r{level}.raw"
        r = subprocess.run([WVOL_BIN, "decompress", str(f), "-o", str(out), "--roi", ",".join(map(str, box)),
                            "--level", str(level), "--json"], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        info = json.loads(r.stdout)
        lo = [b >> level for b in box[:3]]
        hi = [-(-b // 2 ** level) for b in box[3:]]
        got = np.fromfile(out, dtype="<f4").reshape(hi[2] - lo[2], hi[1] - lo[1], hi[0] - lo[0])
        ref = full if level == 0 else None
        if ref is None:
            lv = d / f"level{level}.raw"
            assert subprocess.run([WVOL_BIN, "decompress", str(f), "-o", str(lv), "--level", str(level)],
                                  capture_output=True).returncode == 0
            n = -(-N // 2 ** level)
            ref = np.fromfile(lv, dtype="<f4").reshape(n, n, n)
        want = ref[lo[2]:hi[2], lo[1]:hi[1], lo[0]:hi[0]]
        # float rounding of two summation orders of the same coefficients: 1e-5 of the peak
        assert np.max(np.abs(got - want)) <= 1e-5 * np.max(np.abs(ref)), box
        ch = info["chunks"]
        assert 0 < ch["decoded"] <= ch["file_chunks"]


def test_reads_stay_within_the_memory_budget(wvc):
    d, f, _ = wvc
    budget = 3 << 20
    # the process with nothing decoded: the program, its libraries, the index
    base, _ = peak_rss("info", f)
    whole, _ = peak_rss("decompress", f, "-o", d / "w.raw")
    rss, out = peak_rss("decompress", f, "-o", d / "r.raw", "--roi", "0,0,0,96,96,96", "--memory", "3M", "--json")
    ch = json.loads(out)["chunks"]
    assert ch["cache_peak_bytes"] <= budget
    # resident peak: the base, the budget, the output volume (3.4 MiB) and the brick
    # reconstruction's scratch and image (a few MiB): 16 MiB of slack
    assert rss <= base + budget + 4 * N**3 + (16 << 20), (rss, base)
    # and marching cubes from the file within the same budget
    rss_mc, _ = peak_rss("iso", f, "-o", d / "m.ply", "--iso", "300", "--memory", "3M")
    assert rss_mc <= base + budget + (48 << 20), (rss_mc, base, whole)
    # and a full-resolution frame: the chunk cache, the bricks' bounds (per chunk from the
    # index), the threads' brick caches and the image
    rss_r, out = peak_rss("render", f, "-o", d / "f.png", "--size", "64x64", "--full-resolution", "--memory", "3M",
                          "--json")
    assert json.loads(out)["method"] == "bricks"
    assert rss_r <= base + budget + (48 << 20), (rss_r, base, whole)


def test_region_output_is_streamed_in_slabs(tmp_path):
    """A whole-volume region read written slab by slab: the process never holds the output
    (192^3 floats, 27 MiB), only the chunk budget (8 MiB) and a slab, and the file equals the
    whole decode."""
    n = 192
    vol, f, full, out = tmp_path / "s.nrrd", tmp_path / "s.wvc", tmp_path / "full.raw", tmp_path / "r.nrrd"
    for cmd in (["synth", "skull", "--size", n, "--noise", "20", "-o", vol],
                ["compress", vol, "-o", f, "--psnr", "45", "--levels", "3", "--tile", "16,16"],
                ["decompress", f, "-o", full]):
        r = subprocess.run([WVOL_BIN, *map(str, cmd)], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    base, _ = peak_rss("info", f)
    rss, o = peak_rss("decompress", f, "-o", out, "--roi", f"0,0,0,{n},{n},{n}", "--memory", "8M", "--json")
    info = json.loads(o)
    assert info["slabs"] == 1 and info["chunks"]["cache_peak_bytes"] <= 8 << 20
    # the budget, a slab and its parts (8 slices: 1.2 MiB each) and the reconstruction's scratch:
    # 12 MiB of slack, less than the 27 MiB the output would add if it were held
    assert rss <= base + (8 << 20) + (12 << 20) < base + 4 * n**3, (rss, base)
    ref = np.fromfile(full, dtype="<f4")
    got = np.fromfile(out, dtype="<f4")[-n**3:]  # after the NRRD header
    assert np.max(np.abs(got - ref)) <= 1e-5 * np.max(np.abs(ref))


def test_a_region_held_whole_is_still_made_slab_by_slab(tmp_path):
    """A region whose output is held whole (a .vti, Python's wvc_region) is still made slab by
    slab: made as one box it held working buffers of about twice the box beyond the budget, and
    its gathers pinned more chunks than a small budget holds, decoded again without end (a 512^3
    file's half at 16 MiB ran past 300 s). The resident peak: the output, the budget and a slab;
    the samples equal the slab-written file's bit for bit."""
    n = 192
    vol, f = tmp_path / "s.nrrd", tmp_path / "s.wvc"
    for cmd in (["synth", "skull", "--size", n, "--noise", "20", "-o", vol],
                ["compress", vol, "-o", f, "--psnr", "45", "--levels", "3", "--tile", "32,16"]):
        r = subprocess.run([WVOL_BIN, *map(str, cmd)], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    base, _ = peak_rss("info", f)
    box = f"0,0,0,{n},{n},{n}"
    rss, _ = peak_rss("decompress", f, "-o", tmp_path / "r.vti", "--roi", box, "--memory", "8M")
    # the output (27 MiB) as a volume and again as VTK's array while it is written, the budget,
    # and a slab with its scratch: 24 MiB of slack, where one box's buffers added some 60 MiB
    assert rss <= base + 2 * 4 * n**3 + (8 << 20) + (24 << 20), (rss, base)
    assert peak_rss("decompress", f, "-o", tmp_path / "r.raw", "--roi", box, "--memory", "8M")[0] > 0
    import wvol
    arr, stats = wvol.wvc_region(f, (0, 0, 0), (n, n, n), level=0, memory=8 << 20)
    assert stats["cache_peak_bytes"] <= 8 << 20
    assert np.array_equal(arr.ravel(), np.fromfile(tmp_path / "r.raw", dtype="<f4"))


def test_whole_decode_over_the_budget_is_read_slab_by_slab(wvc):
    """A whole decode whose coefficients (96^3 floats, 3.4 MiB) exceed --memory reads the whole
    box through the chunk cache, written slab by slab: the cache within the budget, the volume
    the in-memory decode's up to float rounding. Within the budget, to a format that is not
    written by slabs, or from a version-1 file, it is decoded in memory as before."""
    d, f, full = wvc
    r = subprocess.run([WVOL_BIN, "decompress", str(f), "-o", str(d / "s.raw"), "--memory", "3M", "--json"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["slabs"] == 1 and 0 < info["chunks"]["cache_peak_bytes"] <= 3 << 20
    got = np.fromfile(d / "s.raw", dtype="<f4").reshape(N, N, N)
    # float rounding of two summation orders of the same coefficients: 1e-5 of the peak
    assert np.max(np.abs(got - full)) <= 1e-5 * np.max(np.abs(full))
    for out, budget in ((d / "m.raw", "8M"), (d / "m.bin", "3M")):
        r = subprocess.run([WVOL_BIN, "decompress", str(f), "-o", str(out), "--memory", budget, "--json"],
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        assert "slabs" not in json.loads(r.stdout), (out, budget)
    assert np.array_equal(np.fromfile(d / "m.raw", dtype="<f4").reshape(N, N, N), full)
    # a version-1 file has no chunks to read by region: decoded whole whatever the budget
    v1 = d / "v1.wvc"
    for cmd in (["compress", d / "m.raw", "--dims", f"{N}x{N}x{N}", "--psnr", "50", "--format", "1", "-o", v1],
                ["decompress", v1, "-o", d / "v1.raw", "--memory", "1M", "--json"]):
        r = subprocess.run([WVOL_BIN, *map(str, cmd)], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    assert "slabs" not in json.loads(r.stdout)


def test_iso_from_a_noisy_wvc_meshes_the_whole_decode(wvc):
    """Marching cubes from the noisy skull's .wvc: its index leaves every brick, whose rebuilding
    would cost more than the whole inverse, so with room in --memory the file is decoded whole
    and meshed densely (the report says so): the very mesh of `--brick 0`, byte for byte. A
    budget without room for the padded grid keeps to the bricks: the same triangles."""
    d, f, _ = wvc
    out = {}
    for tag, extra in (("whole", []), ("dense", ["--brick", "0"]), ("bricks", ["--memory", "2M"])):
        r = subprocess.run([WVOL_BIN, "iso", str(f), "--iso", "300", "-o", str(d / f"{tag}.ply"), "--json", *extra],
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        out[tag] = json.loads(r.stdout)
    assert out["whole"]["whole_inverse"] == 1 and out["bricks"]["whole_inverse"] == 0
    assert (d / "whole.ply").read_bytes() == (d / "dense.ply").read_bytes()
    assert out["bricks"]["triangles"] == out["whole"]["triangles"] > 1000


def test_every_command_takes_a_wvc(wvc):
    d, f, _ = wvc
    for cmd in (["render", f, "-o", d / "img.png", "--size", "48x48", "--memory", "8M"],
                ["iso", f, "-o", d / "m.ply", "--iso", "300"],
                ["convert", f, d / "c.nrrd"]):
        r = subprocess.run([WVOL_BIN, *map(str, cmd)], capture_output=True, text=True)
        assert r.returncode == 0, (cmd, r.stderr)
    assert "(wvol .wvc, decoded) ->" in r.stdout, r.stdout  # convert names the input's format
    r = subprocess.run([WVOL_BIN, "info", str(f), "--json"], capture_output=True, text=True)
    info = json.loads(r.stdout)
    assert info["version"] == 2 and info["chunks"] > 1


def test_info_counts_chunk_modes(wvc):
    """`wvol info` reports each level's chunks by coding mode, as the chunks' first payload
    bytes say (read here from the index independently), and a band's coder as "chunks"."""
    d, f, _ = wvc
    data = f.read_bytes()
    info = json.loads(subprocess.run([WVOL_BIN, "info", str(f), "--json"], capture_output=True,
                                     text=True, check=True).stdout)
    levels, nchunks = info["levels"], info["chunks"]
    idx = 224 + 48 * (1 + 7 * levels)
    names = ["bands_apart", "cabac", "cabac_blocks", "rans", "rans4"]
    want = {m: dict.fromkeys(names + ["empty"], 0) for m in range(1, levels + 1)}
    # chunks per level with 16^3 tiles: level m's bands are N / 2^m along each axis
    per_level = {m: (-(-(N >> m) // 16)) ** 3 for m in range(1, levels + 1)}
    assert sum(per_level.values()) == nchunks
    i = 0
    for m in range(levels, 0, -1):
        for _ in range(per_level[m]):
            e = idx + 32 * i
            off, size = int.from_bytes(data[e:e + 8], "little"), int.from_bytes(data[e + 8:e + 12], "little")
            want[m][names[data[off]] if size else "empty"] += 1
            i += 1
    got = {e["level"]: {k: e[k] for k in names + ["empty"]} for e in info["chunk_modes"]}
    assert got == want
    assert sum(want[1].values()) == per_level[1] and any(v for k, v in want[1].items() if k != "empty")
    for sec in info["sections"]:
        assert sec["coder"] == ("chunks" if sec["nonzero"] else "empty")
    text = subprocess.run([WVOL_BIN, "info", str(f)], capture_output=True, text=True, check=True).stdout
    assert "chunk modes" in text and f"level {levels}:" in text
    from wvol import _wvol  # the Python binding reports the same counts, level 1 first
    py = _wvol.wvc_file_chunk_modes(_wvol.wvc_file_open(str(f)))
    assert py == [want[m] for m in range(1, levels + 1)]


def test_info_refuses_an_unknown_chunk_mode(wvc, tmp_path):
    """A chunk whose mode byte no reader knows, its checksums made to match (a crafted file:
    the chunk's CRC in the index and the header's CRC over the index), makes `wvol info` fail
    naming the chunk and the mode."""
    d, f, _ = wvc
    data = bytearray(f.read_bytes())
    info = json.loads(subprocess.run([WVOL_BIN, "info", str(f), "--json"], capture_output=True,
                                     text=True, check=True).stdout)
    idx = 224 + 48 * (1 + 7 * info["levels"])
    hbytes = idx + 32 * info["chunks"] + 4
    for i in range(info["chunks"]):
        e = idx + 32 * i
        off, size = int.from_bytes(data[e:e + 8], "little"), int.from_bytes(data[e + 8:e + 12], "little")
        if size:
            data[off] = 9
            data[e + 12:e + 16] = zlib.crc32(bytes(data[off:off + size])).to_bytes(4, "little")
            break
    data[hbytes - 4:hbytes] = zlib.crc32(bytes(data[:hbytes - 4])).to_bytes(4, "little")
    bad = tmp_path / "mode.wvc"
    bad.write_bytes(bytes(data))
    r = subprocess.run([WVOL_BIN, "info", str(bad)], capture_output=True, text=True)
    assert r.returncode == 1 and "chunk" in r.stderr and "unknown chunk mode 9" in r.stderr, r.stderr


def test_damage_is_named_and_confined(wvc):
    d, f, _ = wvc
    data = bytearray(f.read_bytes())
    info = json.loads(subprocess.run([WVOL_BIN, "info", str(f), "--json"], capture_output=True,
                                     text=True).stdout)
    nsec, nchunks = 1 + 7 * info["levels"], info["chunks"]
    idx = 224 + 48 * nsec
    # the first level-1 chunk (level 1 comes last in the index) covers the origin
    first1 = nchunks - (N // 2 // 16) ** 3
    off = int.from_bytes(data[idx + 32 * first1: idx + 32 * first1 + 8], "little")
    assert off > 0
    data[off + 3] ^= 0x40
    bad = d / "bad.wvc"
    bad.write_bytes(bytes(data))
    r = subprocess.run([WVOL_BIN, "decompress", str(bad), "-o", str(d / "x.raw"), "--roi", "0,0,0,8,8,8"],
                       capture_output=True, text=True)
    assert r.returncode == 1 and "chunk" in r.stderr and "level 1" in r.stderr, r.stderr
    assert not (d / "x.raw").exists()
    r = subprocess.run([WVOL_BIN, "decompress", str(bad), "-o", str(d / "y.raw"), "--roi", "60,60,60,90,90,90"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([WVOL_BIN, "info", str(bad)], capture_output=True, text=True)
    assert r.returncode == 1 and "chunk" in r.stderr
    r = subprocess.run([WVOL_BIN, "decompress", str(f), "-o", str(d / "z.raw"), "--roi", "0,0,0,8,8,8",
                        "--memory", "1K"], capture_output=True, text=True)
    assert r.returncode == 1 and "budget" in r.stderr, r.stderr


def test_a_budget_exceeded_writes_nothing_and_names_what_would_do(wvc):
    """iso and render from a .wvc under a budget above one chain of chunks but below what one
    request pins: the run goes on to its end (a gather cannot stop it), then fails before any
    output (iso wrote its mesh first), giving the most its requests held at once as a --memory;
    on one thread that --memory then holds them (with more, the threads' timing moves it)."""
    d, f, _ = wvc
    for cmd, extra in (("iso", ["--iso", "300"]), ("render", ["--size", "64x64", "--full-resolution"])):
        out = d / ("budget." + ("ply" if cmd == "iso" else "png"))
        r = subprocess.run([WVOL_BIN, cmd, str(f), "-o", str(out), *extra, "--memory", "300K", "--threads", "1"],
                           capture_output=True, text=True)
        assert r.returncode == 1 and "exceeded" in r.stderr, r.stderr
        assert not out.exists(), cmd
        m = re.search(r"--memory (\d+K) would have held them", r.stderr)
        assert m, r.stderr
        r = subprocess.run([WVOL_BIN, cmd, str(f), "-o", str(out), *extra, "--memory", m.group(1), "--threads", "1"],
                           capture_output=True, text=True)
        assert r.returncode == 0 and out.exists(), r.stderr


def test_python_region_equals_the_whole_decode(wvc):
    import wvol
    d, f, full = wvc
    arr, stats = wvol.wvc_region(f, (5, 60, 30), (40, 96, 77), level=0, memory=4 << 20)
    assert arr.shape == (47, 36, 35)
    assert np.max(np.abs(arr - full[30:77, 60:96, 5:40])) <= 1e-5 * np.max(np.abs(full))
    assert 0 < stats["chunks_decoded"] and stats["cache_peak_bytes"] <= 4 << 20
    # at 50 dB every chunk's quantised values fit 16 bits, which the cache then holds
    assert stats["chunks_decoded_narrow"] == stats["chunks_decoded"]
    with pytest.raises(ValueError, match="box 0..97 along axis 0 is empty or outside"):
        wvol.wvc_region(f, (0, 0, 0), (97, 4, 4))
