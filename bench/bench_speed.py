#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Coding speed of `wvol compress` / `wvol decompress` against main's binary and ZFP, in one run.

Volumes: the noisy skull (`wvol synth skull --noise 20`) and the turbulence field at the given
sizes (default 256^3 and 512^3), raw float32 in /dev/shm (the disk's speed is not measured).
For each volume and PSNR target (40 and 60 dB), both programs compress it once (bits/voxel),
then on one and two threads the four timed commands run interleaved, round by round: main's
compress, this tree's compress, main's decompress of main's file, this tree's decompress of its
file. Each command is a whole process (start-up included), OMP_WAIT_POLICY=passive,
OMP_NUM_THREADS = threads; the CPU seconds (user + system, from wait4) and the wall seconds of
each run are kept, and the minimum over the rounds is reported. On a shared machine the CPU
seconds are the steadier measure (another job's load stretches the wall time, not our CPU
time); the load average at the start and the end is recorded.

ZFP (python3-zfpy, serial) runs in the same process on the same array: fixed accuracy, with
the tolerance bisected (in log scale) to the largest that meets the PSNR target; its
compress_numpy / decompress_numpy times (in-process CPU seconds, without start-up or file
I/O) are the best of the rounds.

main's binary: WVOL_BASE=path (or --base), else it is built from git's `main` into /tmp
(a worktree, Release, with the optional libraries found, as scripts/setup.sh builds it: its
start-up is part of what a user of main pays).

The region read of issue 21 (--roi-file F --roi x0,y0,z0,x1,y1,z1): `wvol decompress F --roi ...`
on one thread by both programs, alternated, best of the rounds, user and system CPU seconds of
each (a .vti reader's time is the bar it has to beat), the two outputs compared byte for byte.

Writes bench/results/speed.json and speed.md.
    python3 bench/bench_speed.py [--sizes 256 512] [--rounds 3] [--base PATH] [--wvol PATH]
                                 [--roi-file F --roi 0,0,0,1024,1024,512]
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from benchutil import cpu_model  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(cmd, threads, detail=False):
    """(cpu seconds, wall seconds) of one whole process; with detail, (user, system, wall)."""
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), OMP_WAIT_POLICY="passive")
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    err = p.stderr.read().decode(errors="replace")
    p.stderr.close()
    if status != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {err}")
    if detail:
        return ru.ru_utime, ru.ru_stime, wall
    return ru.ru_utime + ru.ru_stime, wall


def same_bytes(a, b):
    with open(a, "rb") as fa, open(b, "rb") as fb:
        while True:
            x, y = fa.read(1 << 20), fb.read(1 << 20)
            if x != y:
                return False
            if not x:
                return True


def roi_case(base, new, path, roi, rounds, tmp):
    """The issue-21 read: one thread, both programs alternated, best (by user + system) of the rounds."""
    best = {}
    outs = {w: os.path.join(tmp, f"roi_{w}.raw") for w in ("main", "new")}
    for _ in range(rounds):
        for who, exe in (("main", base), ("new", new)):
            u, s, w = run([exe, "decompress", path, "--roi", roi, "-o", outs[who]], 1, detail=True)
            if who not in best or u + s < best[who][0] + best[who][1]:
                best[who] = (u, s, w)
    row = {"file": path, "roi": roi, "identical": same_bytes(outs["main"], outs["new"]),
           "bytes_out": os.path.getsize(outs["new"])}
    for who, (u, s, w) in best.items():
        row[f"{who}_user_s"], row[f"{who}_sys_s"], row[f"{who}_wall_s"] = u, s, w
    for f in outs.values():
        os.remove(f)
    return row


def build_main():
    """main's wvol, built once into /tmp the way scripts/setup.sh builds it."""
    src = "/tmp/wvol-bench-main-src"
    bld = "/tmp/wvol-bench-main-build"
    if not os.path.isdir(src):
        subprocess.check_call(["git", "-C", ROOT, "worktree", "add", "--detach", src, "main"])
    subprocess.check_call(["cmake", "-S", src, "-B", bld, "-DCMAKE_BUILD_TYPE=Release", "-DWVOL_BUILD_TESTS=OFF",
                           "-DWVOL_BUILD_PYTHON=OFF", "-DWVOL_BUILD_BENCH=OFF"], stdout=subprocess.DEVNULL)
    subprocess.check_call(["cmake", "--build", bld, "-j2", "--target", "wvol_app"], stdout=subprocess.DEVNULL)
    return os.path.join(bld, "wvol")


def psnr(a, b, rng):
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return math.inf if mse == 0 else 20 * math.log10(rng / math.sqrt(mse))


def zfp_at(v, target, rounds):
    """ZFP fixed accuracy at the largest tolerance meeting the target (bisection in log tolerance)."""
    import zfpy
    rng = float(v.max() - v.min())
    lo, hi = math.log(rng * 1e-9), math.log(rng)  # lo meets the target, hi does not
    best = None
    for _ in range(14):
        mid = 0.5 * (lo + hi)
        c = zfpy.compress_numpy(v, tolerance=math.exp(mid))
        p = psnr(v, zfpy.decompress_numpy(c), rng)
        if p >= target:
            lo, best = mid, (math.exp(mid), c, p)
        else:
            hi = mid
        if hi - lo < 0.02:
            break
    if best is None:
        c = zfpy.compress_numpy(v, tolerance=math.exp(lo))
        best = (math.exp(lo), c, psnr(v, zfpy.decompress_numpy(c), rng))
    tol, c, p = best
    tc = td = math.inf
    for _ in range(rounds):  # process CPU seconds, as for wvol (zfpy is serial)
        t0 = time.process_time()
        c = zfpy.compress_numpy(v, tolerance=tol)
        tc = min(tc, time.process_time() - t0)
        t0 = time.process_time()
        zfpy.decompress_numpy(c)
        td = min(td, time.process_time() - t0)
    return {"tolerance": tol, "psnr": p, "bpv": 8 * len(c) / v.size, "compress_s": tc, "decompress_s": td}


def loadavg():
    with open("/proc/loadavg") as f:
        return f.read().split()[:3]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512])
    ap.add_argument("--kinds", nargs="+", default=["skull", "turbulence"])
    ap.add_argument("--targets", type=float, nargs="+", default=[40, 60])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--base", default=os.environ.get("WVOL_BASE"))
    ap.add_argument("--wvol", default=os.path.join(ROOT, "build", "wvol"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "speed"))
    ap.add_argument("--no-zfp", action="store_true")
    ap.add_argument("--from-log", help="rewrite the results from the JSON rows a run printed (a run cut short)")
    ap.add_argument("--note", default="", help="a line for the results file (e.g. what a cut run left out)")
    ap.add_argument("--roi-file", help="a .wvc for the region read of issue 21")
    ap.add_argument("--roi", default="0,0,0,1024,1024,512", help="its region x0,y0,z0,x1,y1,z1")
    a = ap.parse_args()
    if a.from_log:
        rows = [json.loads(line) for line in open(a.from_log) if line.startswith("{")]
        meta = {"machine": f"{cpu_model()}, {os.cpu_count()} cores, shared with other jobs",
                "load_start": ["?"], "load_end": loadavg(), "base": a.base, "wvol": a.wvol, "rounds": a.rounds,
                "note": a.note, "commit": subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"],
                                                         capture_output=True, text=True).stdout.strip()}
        with open(a.out + ".json", "w") as f:
            json.dump({"meta": meta, "rows": rows}, f, indent=1)
        write_md(a.out + ".md", meta, rows)
        return
    base = a.base or build_main()
    new = a.wvol
    meta = {"machine": f"{cpu_model()}, {os.cpu_count()} cores, shared with other jobs",
            "load_start": loadavg(), "base": base, "wvol": new, "rounds": a.rounds,
            "commit": subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True,
                                     text=True).stdout.strip()}
    rows = []
    tmp = tempfile.mkdtemp(dir="/dev/shm" if os.path.isdir("/dev/shm") else None)
    try:
        for n in a.sizes:
            for kind in a.kinds:
                raw = os.path.join(tmp, "v.raw")
                extra = ["--noise", "20"] if kind == "skull" else []
                run([new, "synth", kind, "--size", str(n), *extra, "-o", raw], 2)
                vol = np.fromfile(raw, dtype=np.float32)
                mb = vol.nbytes / 1e6
                dims = ["--dims", f"{n}x{n}x{n}", "--type", "float32"]
                for target in a.targets:
                    files = {}
                    for who, exe in (("main", base), ("new", new)):
                        files[who] = os.path.join(tmp, f"{who}.wvc")
                        run([exe, "compress", raw, *dims, "--psnr", str(target), "--threads", "1", "-o",
                             files[who]], 1)
                    bits = {w: 8 * os.path.getsize(f) / vol.size for w, f in files.items()}
                    identical = same_bytes(files["main"], files["new"])
                    # the decoded volume's PSNR, from this tree's file
                    dec = os.path.join(tmp, "d.raw")
                    run([new, "decompress", files["new"], "-o", dec], 1)
                    p_new = psnr(vol, np.fromfile(dec, dtype=np.float32), float(vol.max() - vol.min()))
                    zfp = None if a.no_zfp else zfp_at(vol.reshape(n, n, n), target, a.rounds)
                    for th in a.threads:
                        cmds = {}
                        for who, exe in (("main", base), ("new", new)):
                            cmds[("compress", who)] = [exe, "compress", raw, *dims, "--psnr", str(target),
                                                       "--threads", str(th), "-o", os.path.join(tmp, "x.wvc")]
                            cmds[("decompress", who)] = [exe, "decompress", files[who], "-o", dec]
                        res = {k: [] for k in cmds}
                        for _ in range(a.rounds):
                            for k, c in cmds.items():
                                res[k].append(run(c, th))
                        row = {"kind": kind, "n": n, "target": target, "threads": th, "mb": mb,
                               "bpv": bits, "identical": identical, "psnr_new": p_new}
                        for (op, who), r in res.items():
                            row[f"{op}_{who}_cpu_s"] = min(x[0] for x in r)
                            row[f"{op}_{who}_wall_s"] = min(x[1] for x in r)
                        if zfp:
                            row["zfp"] = zfp
                        rows.append(row)
                        print(json.dumps(row), flush=True)
                os.remove(raw)
        if a.roi_file:
            meta["roi"] = roi_case(base, new, a.roi_file, a.roi, a.rounds, tmp)
            print(json.dumps(meta["roi"]), flush=True)
    finally:
        for f in os.listdir(tmp):
            os.remove(os.path.join(tmp, f))
        os.rmdir(tmp)
    meta["load_end"] = loadavg()
    with open(a.out + ".json", "w") as f:
        json.dump({"meta": meta, "rows": rows}, f, indent=1)
    write_md(a.out + ".md", meta, rows)


def write_md(path, meta, rows):
    L = ["# .wvc coding speed: this tree against main's binary and ZFP, one run", "",
         f"Machine: {meta['machine']}. Load average at the start {' '.join(meta['load_start'])}, at the end "
         f"{' '.join(meta['load_end'])} (2 cores: other jobs ran throughout, so wall times are stretched; the "
         "CPU seconds, user + system of the whole process, are the measure below).", "",
         f"Programs: this tree ({meta['commit']}, `{meta['wvol']}`) and main's (`{meta['base']}`), each a whole "
         f"process per run (start-up included), interleaved round by round, best of {meta['rounds']}; compress "
         "streams from a raw float32 file in /dev/shm with `--psnr T --threads N`, decompress writes raw to "
         "/dev/shm; OMP_WAIT_POLICY=passive, OMP_NUM_THREADS=N. MB/s = raw float32 MB / CPU seconds. ZFP: "
         "python3-zfpy fixed accuracy at the largest tolerance meeting the target, serial, in-process "
         "CPU seconds (no start-up, no file I/O).", ""] + ([meta["note"], ""] if meta.get("note") else []) + [
         "| volume | size | dB | threads | bits/voxel main / new / ZFP | compress MB/s main / new (x) | "
         "decompress MB/s main / new (x) | new / ZFP compress, decompress | CPU s new compress, decompress | "
         "goal 400 MB/s (1 thread) compress, decompress |",
         "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        mb = r["mb"]
        cm, cn = mb / r["compress_main_cpu_s"], mb / r["compress_new_cpu_s"]
        dm, dn = mb / r["decompress_main_cpu_s"], mb / r["decompress_new_cpu_s"]
        z = r.get("zfp")
        zb = f"{z['bpv']:.3f}" if z else "-"
        zr = (f"{cn / (mb / z['compress_s']):.2f}, {dn / (mb / z['decompress_s']):.2f}" if z and r["threads"] == 1
              else "-")
        goal = (f"{'met' if cn >= 400 else 'not met'} ({cn / 400:.2f}), {'met' if dn >= 400 else 'not met'} "
                f"({dn / 400:.2f})" if r["threads"] == 1 else "-")
        L.append(f"| {r['kind']} | {r['n']}^3 | {r['target']:g} | {r['threads']} | {r['bpv']['main']:.4f} / "
                 f"{r['bpv']['new']:.4f} / {zb} | {cm:.0f} / {cn:.0f} ({cn / cm:.2f}x) | {dm:.0f} / {dn:.0f} "
                 f"({dn / dm:.2f}x) | {zr} | {r['compress_new_cpu_s']:.3f}, {r['decompress_new_cpu_s']:.3f} | "
                 f"{goal} |")
    L += ["", "Files byte for byte: " + ("the two programs wrote the same bytes in every case" if all(
        r.get("identical", False) for r in rows) else "DIFFER in: " + ", ".join(
        f"{r['kind']} {r['n']} {r['target']:g} dB" for r in rows if not r.get("identical", False)))]
    L += ["", "Bits: new / main per case: " + ", ".join(
        f"{r['kind']} {r['n']} {r['target']:g} dB {r['bpv']['new'] / r['bpv']['main']:.4f}"
        for r in rows if r["threads"] == rows[0]["threads"]), "",
        "Two threads against one (CPU-time MB/s cannot show a speed-up; wall seconds, best of the rounds, "
        "one thread / two threads):", ""]
    by = {}
    for r in rows:
        by.setdefault((r["kind"], r["n"], r["target"]), {})[r["threads"]] = r
    for (k, n, t), d in by.items():
        if 1 in d and 2 in d:
            L.append(f"- {k} {n}^3 {t:g} dB: compress main {d[1]['compress_main_wall_s'] / d[2]['compress_main_wall_s']:.2f}x, "
                     f"new {d[1]['compress_new_wall_s'] / d[2]['compress_new_wall_s']:.2f}x; decompress main "
                     f"{d[1]['decompress_main_wall_s'] / d[2]['decompress_main_wall_s']:.2f}x, new "
                     f"{d[1]['decompress_new_wall_s'] / d[2]['decompress_new_wall_s']:.2f}x")
    L += ["", "Wall seconds of each case (best of the rounds): in speed.json (`*_wall_s`)."]
    q = meta.get("roi")
    if q:
        tm, tn = q["main_user_s"] + q["main_sys_s"], q["new_user_s"] + q["new_sys_s"]
        tiny = 1e-9  # a tiny region's CPU seconds round to 0
        L += ["", f"Region read (issue 21): `wvol decompress {q['file']} --roi {q['roi']}`, one thread, the two "
              f"programs alternated, best of {meta['rounds']} by user + system CPU seconds; outputs "
              f"{'identical' if q['identical'] else 'DIFFERENT'} ({q['bytes_out']} bytes).", "",
              "| program | user s | system s | user + system s | wall s |", "|---|---|---|---|---|",
              f"| main | {q['main_user_s']:.2f} | {q['main_sys_s']:.2f} | {tm:.2f} | {q['main_wall_s']:.2f} |",
              f"| this tree | {q['new_user_s']:.2f} | {q['new_sys_s']:.2f} | {tn:.2f} | {q['new_wall_s']:.2f} |",
              "", f"main / this tree: {tm / max(tn, tiny):.2f}x in CPU seconds, "
              f"{q['main_user_s'] / max(q['new_user_s'], tiny):.2f}x in user seconds."]
    with open(path, "w") as f:
        f.write("\n".join(L) + "\n")


if __name__ == "__main__":
    main()
