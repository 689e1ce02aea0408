#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Volumes larger than memory: streamed compression's time, throughput and peak resident
memory against the volume's size, and its bits/voxel at 40 and 60 dB against ZFP.

Volumes: the skull phantom with noise (sigma 20 HU) and the turbulence field, at 256^3,
512^3, 1024^3 (and 2048^3 with --big: streamed from the generator, never written).
For each size up to 1024^3, in the same run:
  * `wvol synth` writes the volume to a raw file slab by slab (its time and peak RSS);
  * `wvol compress FILE --psnr T` for T = 40 and 60 dB: streamed (two passes over the
    file, the volume never held): wall time, MB/s of float32 input, peak RSS of the
    process (/usr/bin/time's %M), bits/voxel, passes, the encoder's exact PSNR;
  * at 256^3 and 512^3 also `--in-memory` (the whole-volume pipeline) at 40 dB, and at
    256^3 the streamed compression straight from the generator (`synth:KIND,...`);
  * ZFP (python3-zfpy, fixed accuracy, one thread) on the same file, compressed slab by
    slab (64 slices, a multiple of ZFP's 4^3 blocks: in fixed-accuracy mode each block is
    coded on its own, so the bits are the whole array's plus one small header per slab),
    memory-mapped: a tolerance sweep on every 4th slab brackets each target, then full
    passes at the bracketing tolerances; bits/voxel at exactly 40 / 60 dB interpolated
    (log bits against PSNR) between them, as bench_rd.py does.
PSNR: 20 log10(range / RMSE), range = max - min of the volume, RMSE over all voxels.
Writes bench/results/large.json, large.md and large.png.

  python3 bench/bench_large.py            # 256^3 .. 1024^3 (about half an hour on 2 cores)
  python3 bench/bench_large.py --big      # and 2048^3 from the generator (long)
  python3 bench/bench_large.py --quick    # 64^3 and 128^3: a smoke test
"""
import argparse
import json
import math
import os
import pathlib
import platform
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_rd import bpv_at  # noqa: E402
from benchutil import cpu_model  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
WVOL = os.environ.get("WVOL_BIN", str(ROOT / "build" / "wvol"))
RESULTS = ROOT / "bench" / "results"
KINDS = {"skull": ["--noise", "20"], "turbulence": []}
SHORT = {"turbulence": "turb"}  # file names of the kept 2048^3 outputs
TARGETS = [40, 60]
SLAB = 64
# wvol's threads (--threads): 1 by default, the single-thread speed the goal is
# stated in; OpenMP waits passively, so that threads waiting at a barrier give the core
# back on a machine shared with other jobs (spinning there cost more than the work)
THREADS = os.environ.get("WVOL_THREADS", "1")
ENV = dict(os.environ, OMP_WAIT_POLICY=os.environ.get("OMP_WAIT_POLICY", "passive"))


def run_rss(cmd, env=None, cpu=None):
    """Runs a command under /usr/bin/time and returns (stdout, wall seconds, peak RSS in bytes
    of that process, from /usr/bin/time). (os.wait4's ru_maxrss of a child forked from this Python would count the
    parent's pages the child held before exec: a Python holding ZFP's arrays inflated it.)
    cpu: a dict that receives the process's user + system CPU seconds (on a shared machine
    the wall time includes the time other jobs held the cores; the CPU time does not)."""
    with tempfile.NamedTemporaryFile(mode="w+", suffix=".time") as tf:
        full = ["/usr/bin/time", "-f", "%M", "-o", tf.name] + [str(c) for c in cmd]
        # the CPU seconds from the children's rusage (microseconds; /usr/bin/time's %U and %S are
        # in hundredths, 6% of a 256^3 compression): the command and its small time wrapper
        u0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        r = subprocess.run(full, capture_output=True, text=True, env=env)
        wall = time.perf_counter() - t0
        u1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        if r.returncode != 0:
            raise RuntimeError(f"{' '.join(map(str, cmd))}: {r.stderr.strip()}")
        kb = open(tf.name).read().strip().splitlines()[-1].split()[0]
    if cpu is not None:
        cpu["cpu_seconds"] = (u1.ru_utime - u0.ru_utime) + (u1.ru_stime - u0.ru_stime)
    return r.stdout, wall, int(kb) * 1024


def synth_spec(kind, n):
    extra = ",noise=20" if kind == "skull" else ""
    return f"synth:{kind},size={n}{extra}"


def compress_best(src, n, target, workdir, extra=(), rounds=1):
    """compress() `rounds` times: the run of least CPU time (this VM's first touches of fresh
    memory move one run's CPU time by tens of percent), with every round's CPU and wall seconds."""
    runs = [compress(src, n, target, workdir, extra) for _ in range(max(rounds, 1))]
    best = min(runs, key=lambda c: c["cpu_seconds"])
    best["rounds_cpu_seconds"] = [c["cpu_seconds"] for c in runs]
    best["rounds_seconds"] = [c["seconds"] for c in runs]
    return best


def compress(src, n, target, workdir, extra=(), keep=None):
    out = keep or workdir / "v.wvc"
    cmd = [WVOL, "compress", src, "-o", out, "--psnr", str(target), "--json", "--threads", THREADS, *extra]
    if not str(src).startswith("synth:"):
        cmd[3:3] = ["--dims", f"{n}x{n}x{n}"]
    cpu = {}
    stdout, wall, rss = run_rss(cmd, env=ENV, cpu=cpu)
    rep = json.loads(stdout)
    if not keep:
        os.remove(out)
    return {"target": target, "seconds": wall, "cpu_seconds": cpu["cpu_seconds"], "mbs": 4 * n**3 / 1e6 / wall,
            "cpu_mbs": 4 * n**3 / 1e6 / cpu["cpu_seconds"], "peak_rss": rss,
            "bpv": rep["bits_per_voxel"], "psnr": rep["predicted"]["psnr"], "passes": rep.get("passes", 1),
            "streamed": bool(rep.get("streamed")), "window_bytes": rep.get("window_bytes"),
            "writer_bytes": rep.get("writer_bytes"), "step": rep["step"], "stage_seconds": rep["seconds"],
            "source_reads": rep.get("source_reads"), "kept_bytes": rep.get("kept_bytes")}


# ---------------------------------------------------------------- ZFP by slabs
def zfp_pass(v, tol, every=1):
    """Bits/voxel, PSNR and compress MB/s of ZFP fixed-accuracy over slabs of v (every
    `every`-th slab only for a quick bracket)."""
    import zfpy
    n = v.shape[0]
    rng = float(zfp_pass.range)
    nbytes = 0
    sse = 0.0
    count = 0
    t = 0.0
    for z0 in range(0, n, SLAB * every):
        s = np.ascontiguousarray(v[z0:z0 + SLAB])
        t0 = time.perf_counter()
        c = zfpy.compress_numpy(s, tolerance=tol)
        t += time.perf_counter() - t0
        d = zfpy.decompress_numpy(c)
        nbytes += len(c)
        for k in range(0, s.shape[0], 8):  # 8 slices at a time: float64 temporaries stay small at 2048^2
            sse += float(np.sum((d[k:k + 8].astype(np.float64) - s[k:k + 8]) ** 2))
        count += s.size
    mse = sse / count
    return {"param": tol, "bpv": 8 * nbytes / count, "psnr": math.inf if mse == 0 else 20 * math.log10(rng / math.sqrt(mse)),
            "compress_mbs": 4 * count / 1e6 / t}


def zfp_at_targets(path, n, depth=None, value_range=None):
    """ZFP's bits/voxel at the targets on the raw file (depth x n x n); value_range: the PSNR
    peak when the file is a sample of a larger volume (default: the file's own range)."""
    depth = depth or n
    v = np.memmap(path, dtype="<f4", mode="r", shape=(depth, n, n))
    if value_range is None:
        lo = hi = None
        for z0 in range(0, depth, SLAB):
            s = np.asarray(v[z0:z0 + SLAB])
            lo = float(s.min()) if lo is None else min(lo, float(s.min()))
            hi = float(s.max()) if hi is None else max(hi, float(s.max()))
        value_range = hi - lo
    zfp_pass.range = value_range
    rng = value_range
    # the tolerances bracketing each target: searched on every 4th slab from 512^3 (a
    # quarter of the volume, spread through it), then measured again on every slab (and moved
    # outwards while the whole volume's PSNRs do not bracket the target)
    every = 4 if n >= 512 and depth >= 4 * SLAB else 1
    tol = lambda k: rng * 2.0 ** (-k * 0.75)  # noqa: E731
    sub, full, result = {}, {}, {}

    def bracket(points, k, target, measure):
        for _ in range(30):
            for j in (k, k + 1):
                if j not in points:
                    points[j] = measure(j)
            if points[k]["psnr"] > target:
                k -= 1
            elif points[k + 1]["psnr"] < target:
                k += 1
            else:
                return k
        return None

    k = 6
    for target in TARGETS:
        k0 = bracket(sub, k, target, lambda j: zfp_pass(v, tol(j), every))
        k1 = bracket(full, k0, target, lambda j: zfp_pass(v, tol(j))) if k0 is not None else None
        pts = [full[k1], full[k1 + 1]] if k1 is not None else []
        result[str(target)] = {"bpv": bpv_at(pts, target) if pts else None, "points": pts,
                               "compress_mbs": min(p["compress_mbs"] for p in pts) if pts else None}
        k = k1 if k1 is not None else k
    del v
    return result


# ---------------------------------------------------------------- the run
def region_reads(path, n, depth, workdir):
    """Time, peak RSS and what is read for a 64^3 and a 256^3 region at full resolution (at the
    centre) and the whole volume at level 2 (as a region: through the file-backed store, within
    --memory's default 1 GiB), each as its own `wvol decompress` process."""
    out = []
    c, cz = n // 2, depth // 2

    def box(h):
        hz = min(h, cz)
        return ["--roi", ",".join(map(str, [c - h, c - h, cz - hz, c + h, c + h, cz + hz]))], 8 * h * h * hz

    for name, (extra, voxels) in (("64^3 region", box(32)), ("256^3 region", box(128)),
                                  ("level 2, whole", (["--level", "2", "--roi", f"0,0,0,{n},{n},{depth}"], (n // 4) ** 2 * (depth // 4)))):
        dst = workdir / "region.raw"
        cpu = {}
        stdout, wall, rss = run_rss([WVOL, "decompress", path, "-o", dst, "--json", *extra], env=ENV, cpu=cpu)
        rep = json.loads(stdout)
        os.remove(dst)
        out.append({"read": name, "voxels_out": voxels, "seconds": wall, "cpu_seconds": cpu["cpu_seconds"],
                    "peak_rss": rss, "chunks": rep.get("chunks"), "file_bytes": os.path.getsize(path)})
    return out


def zfp_sampled_slabs(kind, n, depth, slabs, value_range, workdir):
    """ZFP at 2048^3 as a user would run it, by slabs of 64 slices, on `slabs` slabs spread
    evenly through the volume (made by `wvol synth --slab`, the whole's values): in
    fixed-accuracy mode each 4^3 block is coded on its own, so the bits/voxel and the error of
    the sampled slabs estimate the whole's (PSNR with the whole volume's range)."""
    path = workdir / "zfp_slabs.raw"
    starts = [round(i * (depth - SLAB) / max(slabs - 1, 1)) // 4 * 4 for i in range(slabs)]
    with open(path, "wb") as out:
        for z0 in starts:
            one = workdir / "slab.raw"
            run_rss([WVOL, "synth", kind, "--size", f"{n}x{n}x{depth}", "--slab", f"{z0},{SLAB}", "-o", one,
                     *KINDS[kind]], env=ENV)
            with open(one, "rb") as f:
                while True:
                    b = f.read(1 << 26)
                    if not b:
                        break
                    out.write(b)
            os.remove(one)
    try:
        res = zfp_at_targets(path, n, depth=len(starts) * SLAB, value_range=value_range)
    finally:
        os.remove(path)
    res["slab_starts"] = starts
    return res


def bench_size(kind, n, workdir, depth, keep_dir=None, big_targets=(40,), zfp_slabs=0, rounds=1, two_reads=False,
               zfp=True):
    row = {"kind": kind, "n": n, "voxels": n**3}
    if n > 1024:
        # streamed from the generator only, never written: n x n x depth slices (the memory
        # does not depend on the depth, test_wavelet_stream; depth = n is the whole cube)
        row["depth"] = depth
        row["voxels"] = n * n * depth
        spec = synth_spec(kind, n).replace(f"size={n}", f"size={n}x{n}x{depth}")
        row["compress"] = []
        for t in big_targets:
            # the first target's file is kept (other tools read it); the others are removed
            keep = pathlib.Path(keep_dir) / f"{SHORT.get(kind, kind)}_{n}.wvc" if keep_dir and t == big_targets[0] else None
            c = compress(spec, n, t, workdir, keep=keep)
            c["mbs"] = 4 * n * n * depth / 1e6 / c["seconds"]
            c["cpu_mbs"] = 4 * n * n * depth / 1e6 / c["cpu_seconds"]
            if keep:
                c["file"] = str(keep)
                row["regions"] = region_reads(keep, n, depth, workdir)
            row["compress"].append(c)
            print(json.dumps(c), flush=True)
        if zfp_slabs:
            # the PSNR peak: the whole volume's range, from the kept file's header (written now
            # or by an earlier run with --big-targets none)
            kept = pathlib.Path(keep_dir or ".") / f"{SHORT.get(kind, kind)}_{n}.wvc"
            info = json.loads(subprocess.run([WVOL, "info", kept, "--json"], capture_output=True,
                                             text=True).stdout or "{}") if kept.exists() else {}
            if "value_max" in info:
                row["zfp"] = zfp_sampled_slabs(kind, n, depth, zfp_slabs, info["value_max"] - info["value_min"],
                                               workdir)
        return row
    raw = workdir / f"{kind}{n}.raw"
    _, wall, rss = run_rss([WVOL, "synth", kind, "--size", str(n), "-o", raw, *KINDS[kind]])
    row["synth"] = {"seconds": wall, "peak_rss": rss}
    row["compress"] = [compress_best(raw, n, t, workdir, rounds=rounds) for t in TARGETS]
    if two_reads:
        # the path of every size whose pyramid exceeds the budget (--memory): the source read
        # and transformed twice; where the default already took it, that run is this one
        row["two_reads"] = [c if c.get("source_reads") == 2 else
                            compress_best(raw, n, c["target"], workdir, ("--memory", "1M"), rounds)
                            for c in row["compress"]]
    if n <= 512:
        row["in_memory"] = compress(raw, n, 40, workdir, ("--in-memory",))
    if n <= 256:
        row["from_generator"] = compress(synth_spec(kind, n), n, 40, workdir)
    if zfp:
        row["zfp"] = zfp_at_targets(raw, n)
    os.remove(raw)
    return row


def write_md(res, path):
    L = ["# Streamed compression of volumes larger than memory", "",
         f"Machine: {res['machine']}; wvol threads: {res['threads']}; ZFP: python3-zfpy, one thread, by slabs of "
         f"{SLAB} slices. Date: {res['date']}.", "",
         "Peak RSS is the process's (/usr/bin/time %M); MB/s of float32 input. Streamed = two passes over the "
         "raw file (statistics, then writing); the volume is never held.", "",
         "CPU s is the process's user + system time (/usr/bin/time): on this shared machine the wall time "
         "includes the time other jobs held the cores, the CPU time does not; CPU MB/s and CPU ns/voxel "
         "follow from it. Bits are unchanged by the speed work (the same step, the same bytes).", "",
         "| volume | size | dense GiB | synth s | target dB | wvol s | CPU s | MB/s | CPU MB/s | CPU ns/voxel | "
         "peak RSS MiB | passes | wvol bits/voxel | ZFP bits/voxel | wvol / ZFP |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        n = r["n"]
        synth = f"{r['synth']['seconds']:.1f}" if "synth" in r else "(generator)"
        for c in r["compress"]:
            zb = r.get("zfp", {}).get(str(c["target"]), {}).get("bpv")
            zcol = f"{zb:.4f} | {c['bpv'] / zb:.2f}" if zb else "- | -"
            size = f"{n}^2 x {r['depth']}" if "depth" in r else f"{n}^3"
            cpu = c.get("cpu_seconds")
            cpucols = (f"{cpu:.1f} | {c['mbs']:.1f} | {4 * r['voxels'] / 1e6 / cpu:.1f} | {1e9 * cpu / r['voxels']:.1f}"
                       if cpu else f"- | {c['mbs']:.1f} | - | -")
            L.append(f"| {r['kind']} | {size} | {4 * r['voxels'] / 2**30:.2f} | {synth} | {c['target']} | {c['seconds']:.1f} | "
                     f"{cpucols} | {c['peak_rss'] / 2**20:.0f} | "
                     f"{c['passes']} | {c['bpv']:.4f} | {zcol} |")
    L += ["", "In-memory pipeline (`--in-memory`) and streamed from the generator (`synth:`), 40 dB, same run:", "",
          "| volume | size | in-memory s | in-memory peak RSS MiB | streamed-from-file peak RSS MiB | "
          "from generator s | from generator peak RSS MiB |", "|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        if "in_memory" in r:
            m, g, s = r["in_memory"], r.get("from_generator"), r["compress"][0]
            gen = f"{g['seconds']:.1f} | {g['peak_rss'] / 2**20:.0f}" if g else "- | -"
            L.append(f"| {r['kind']} | {r['n']}^3 | {m['seconds']:.1f} | {m['peak_rss'] / 2**20:.0f} | "
                     f"{s['peak_rss'] / 2**20:.0f} | {gen} |")
    regions = [r for r in res["rows"] if r.get("regions")]
    if regions:
        L += ["", "Region reads from the kept file (`wvol decompress --roi ... [--level 2]`, default --memory 1 GiB), "
              "each its own process; read = the payload bytes of the chunks decoded:", "",
              "| volume | read | output voxels | s | CPU s | peak RSS MiB | chunks decoded / in file | MB read | "
              "file MB | read / file |", "|---|---|---|---|---|---|---|---|---|---|"]
        for r in regions:
            for g in r["regions"]:
                ch = g.get("chunks") or {}
                rd = ch.get("bytes_read", 0)
                L.append(f"| {r['kind']} {r['n']}^3 | {g['read']} | {g['voxels_out']} | {g['seconds']:.2f} | "
                         f"{g['cpu_seconds']:.2f} | {g['peak_rss'] / 2**20:.0f} | {ch.get('decoded', '-')} / "
                         f"{ch.get('file_chunks', '-')} | {rd / 1e6:.2f} | {g['file_bytes'] / 1e6:.1f} | "
                         f"{rd / g['file_bytes']:.4f} |")
    for r in res["rows"]:
        if "depth" in r and r.get("compress"):
            L += ["", f"{r['kind']} {r['n']}^2 x {r['depth']}: " + "; ".join(
                f"{c['target']} dB took {c['seconds'] / 60:.1f} min in one run (not split), streamed from the "
                f"generator (made twice: one pass for the statistics, one for the writer)" for c in r["compress"]) + "."]
    zs = [r for r in res["rows"] if r.get("zfp", {}).get("slab_starts")]
    for r in zs:
        L += ["", f"ZFP at {r['n']}^3 ({r['kind']}): by slabs of {SLAB} slices as a user would, on "
              f"{len(r['zfp']['slab_starts'])} slabs spread through the volume (starting at slices "
              f"{', '.join(map(str, r['zfp']['slab_starts']))}; made by `wvol synth --slab`); fixed-accuracy "
              "ZFP codes each 4^3 block on its own, so these slabs' bits/voxel and error estimate the whole's "
              "(PSNR with the whole volume's range)."]
    L += ["", "Time against voxels (streamed from the file, 40 dB): ns/voxel relative to the smallest size:", ""]
    for kind in KINDS:
        rows = [r for r in res["rows"] if r["kind"] == kind and "synth" in r]
        if rows:
            base = rows[0]["compress"][0]["seconds"] / rows[0]["voxels"]
            L.append(f"- {kind}, wall: " + ", ".join(f"{r['n']}^3 {r['compress'][0]['seconds'] / r['voxels'] / base:.2f}"
                                                    for r in rows))
            if all("cpu_seconds" in r["compress"][0] for r in rows):
                base = rows[0]["compress"][0]["cpu_seconds"] / rows[0]["voxels"]
                L.append(f"- {kind}, CPU: " + ", ".join(
                    f"{r['n']}^3 {r['compress'][0]['cpu_seconds'] / r['voxels'] / base:.2f}" for r in rows))
    L += linearity_md(res)
    path.write_text("\n".join(L) + "\n")


def linearity_md(res):
    """CPU ns/voxel against the size, per target, for the default run (the pyramid kept when it
    fits --memory's 1 GiB: the source read once up to 512^3) and for the two-read path (every
    size as it runs once its pyramid exceeds the budget), with each path's largest / smallest."""
    rows = [r for r in res["rows"] if r.get("two_reads") and "synth" in r]
    if not rows:
        return []
    L = ["", "CPU time against voxels, per path (best of each run's rounds; `--rounds`): CPU ns/voxel, and the "
         "largest over the smallest across the sizes (the goal: within 1.2). Default: the pyramid kept when it "
         "fits the 1 GiB budget (256^3, 512^3: the source read once), read twice above it. Two reads: `--memory "
         "1M`, every size the way sizes above the budget go.", "",
         "| volume | target dB | path | " + " | ".join(f"{r['n']}^3" for r in rows if r["kind"] == rows[0]["kind"])
         + " | largest / smallest |", "|---|---|---|" + "---|" * (1 + len([r for r in rows if r["kind"] == rows[0]["kind"]]))]
    for kind in KINDS:
        kr = [r for r in rows if r["kind"] == kind]
        if not kr:
            continue
        for i, t in enumerate(TARGETS):
            for name, key in (("default", "compress"), ("two reads", "two_reads")):
                ns = [1e9 * r[key][i]["cpu_seconds"] / r["voxels"] for r in kr]
                L.append(f"| {kind} | {t} | {name} | " + " | ".join(f"{v:.1f}" for v in ns)
                         + f" | {max(ns) / min(ns):.2f} |")
    return L


def plot(res, path):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
    for kind, mk in zip(KINDS, "os"):
        rows = [r for r in res["rows"] if r["kind"] == kind and r.get("compress")]
        n = [r["n"] for r in rows]
        ax[0].plot(n, [1e9 * r["compress"][0]["seconds"] / r["voxels"] for r in rows], mk + "-", label=f"{kind} streamed")
        ax[1].plot(n, [r["compress"][0]["peak_rss"] / 2**30 for r in rows], mk + "-", label=f"{kind} streamed")
        im = [r for r in rows if "in_memory" in r]
        if im:
            ax[1].plot([r["n"] for r in im], [r["in_memory"]["peak_rss"] / 2**30 for r in im], mk + "--",
                       label=f"{kind} in memory")
        for t, ls in zip(TARGETS, ("-", ":")):
            zr = [r for r in rows if r.get("zfp", {}).get(str(t), {}).get("bpv")]
            pts = [(r["n"], c["bpv"]) for r in rows for c in r["compress"] if c["target"] == t]
            ax[2].plot([q[0] for q in pts], [q[1] for q in pts], mk + ls, label=f"{kind} wvol {t} dB")
            ax[2].plot([r["n"] for r in zr], [r["zfp"][str(t)]["bpv"] for r in zr], mk + ls, alpha=0.4,
                       label=f"{kind} ZFP {t} dB")
    ax[1].axhline(2, color="grey", lw=0.8)
    ax[1].plot([256, 512, 1024, 2048], [4 * m**3 / 2**30 for m in (256, 512, 1024, 2048)], "k:", lw=0.8,
               label="dense volume")
    for a, t in zip(ax, ("ns per voxel (40 dB)", "peak RSS GiB", "bits/voxel")):
        a.set_xscale("log", base=2)
        a.set_title(t)
        a.set_xlabel("edge (voxels)")
        a.legend(fontsize=7)
    ax[1].set_yscale("log")
    ax[2].set_yscale("log")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="64^3 and 128^3 only")
    ap.add_argument("--big", action="store_true", help="also 2048^2 slices, streamed from the generator")
    ap.add_argument("--depth", type=int, default=2048, help="slices of the 2048^2 runs (default 2048: the cube)")
    ap.add_argument("--sizes", help="comma-separated edges (overrides the defaults)")
    ap.add_argument("--kinds", default=",".join(KINDS), help="skull,turbulence")
    ap.add_argument("--out", default="large", help="results name in bench/results/")
    ap.add_argument("--workdir", help="folder for the raw files (default: a temporary one)")
    ap.add_argument("--merge", help="A.json,B.json,...: join the rows of earlier runs (the same kind and size "
                                    "merged) into --out's json, md and plot, and run nothing")
    ap.add_argument("--keep", help="2048^3: keep the first target's .wvc in this folder (KIND_2048.wvc) and "
                                   "time region reads from it")
    ap.add_argument("--big-targets", default="40",
                    help="2048^3: PSNR targets (default 40; none: only ZFP, with the range of the kept file)")
    ap.add_argument("--rounds", type=int, default=1,
                    help="up to 1024^3: each compression this many times, the least CPU time kept (default 1)")
    ap.add_argument("--two-reads", action="store_true",
                    help="up to 1024^3: also the two-read path (--memory 1M) at every size, for time against voxels")
    ap.add_argument("--no-zfp", action="store_true", help="skip ZFP (its bits from an earlier run: the bytes do "
                                                          "not depend on the speed work)")
    ap.add_argument("--zfp-slabs", type=int, default=0,
                    help="2048^3 with --keep: ZFP by slabs of 64 slices on this many slabs spread through the volume")
    a = ap.parse_args()
    if a.merge:
        runs = [json.loads((RESULTS / f).read_text()) for f in a.merge.split(",")]
        res = dict(runs[0], rows=[], merged=a.merge.split(","))
        for r in (row for run in runs for row in run["rows"]):
            same = [x for x in res["rows"] if x["kind"] == r["kind"] and x["n"] == r["n"]]
            if same:
                same[0]["compress"] = same[0].get("compress", []) + r.get("compress", [])
                same[0].update({k: v for k, v in r.items() if k != "compress"})
            else:
                res["rows"].append(r)
        (RESULTS / f"{a.out}.json").write_text(json.dumps(res, indent=1))
        write_md(res, RESULTS / f"{a.out}.md")
        plot(res, RESULTS / f"{a.out}.png")
        print(f"wrote bench/results/{a.out}.json, .md, .png")
        return
    sizes = [64, 128] if a.quick else [256, 512, 1024] + ([2048] if a.big else [])
    if a.sizes:
        sizes = [int(s) for s in a.sizes.split(",")]
    res = {"machine": f"{cpu_model()}, {os.cpu_count()} cores, {platform.system()}",
           "threads": THREADS, "omp_wait_policy": ENV["OMP_WAIT_POLICY"],
           "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "rows": []}
    t_all = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=a.workdir) as tmp:
        work = pathlib.Path(tmp)
        for n in sizes:
            for kind in a.kinds.split(","):
                t0 = time.perf_counter()
                targets = () if a.big_targets == "none" else tuple(int(t) for t in a.big_targets.split(","))
                row = bench_size(kind, n, work, a.depth, a.keep, targets, a.zfp_slabs, a.rounds, a.two_reads,
                                 not a.no_zfp)
                row["bench_seconds"] = time.perf_counter() - t0
                res["rows"].append(row)
                if not row["compress"]:
                    print(f"{kind:10s} {n:5d}^3: ZFP {row.get('zfp')}", flush=True)
                    continue
                c = row["compress"][0]
                print(f"{kind:10s} {n:5d}^3: {c['seconds']:8.1f} s, {c['mbs']:7.1f} MB/s, peak RSS "
                      f"{c['peak_rss'] / 2**20:7.0f} MiB, {c['bpv']:.4f} bits/voxel at 40 dB"
                      + (f", ZFP {row['zfp']['40']['bpv']:.4f}" if row.get("zfp", {}).get("40", {}).get("bpv") else "")
                      + f" ({row['bench_seconds']:.0f} s)", flush=True)
    res["seconds"] = time.perf_counter() - t_all
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{a.out}.json").write_text(json.dumps(res, indent=1))
    write_md(res, RESULTS / f"{a.out}.md")
    plot(res, RESULTS / f"{a.out}.png")
    print(f"wrote bench/results/{a.out}.json, .md, .png ({res['seconds']:.0f} s)")


if __name__ == "__main__":
    main()
