#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""The random-access .wvc (format 2) against format 1, and reads of a region or a level.

In one run, on volumes made by `wvol synth` (the noisy skull phantom and Shepp-Logan):
  * bits: `wvol compress --psnr P` at 40 and 60 dB in format 1 and format 2 (db2, 5 levels,
    default tiles), the ratio of their sizes (goal: format 2 within 3% of format 1); at the
    largest size the skull at 40 dB only, one run each (on a shared 2-core machine);
  * speed: compress and decompress wall time of both formats, one thread and two;
  * region reads from the largest file: `wvol decompress --roi` of a 64^3 and a 256^3 box at
    full resolution and of the whole volume at level 2, each in its own process: wall time,
    peak resident memory (getrusage of the child), chunks decoded and bytes read, against a
    whole decode of the same file (goal: cost proportional to what is read);
  * marching cubes from the 40 dB file (brick by brick within --memory) against marching
    cubes on the dense decoded volume, same iso-value, same run (goal: <= 2x the dense time).
Writes bench/results/wvc2.json and wvc2.md.

  python3 bench/bench_wvc2.py               # 256^3 and 512^3 (a few minutes)
  python3 bench/bench_wvc2.py --quick       # 64^3 and 128^3: a smoke test
"""
import argparse
import json
import os
import pathlib
import platform
import resource
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
WVOL = os.environ.get("WVOL_BIN", str(ROOT / "build" / "wvol"))


def run(cmd, threads=None):
    """Runs cmd; returns (seconds, peak RSS in MiB of that child, stdout)."""
    env = dict(os.environ)
    if threads:
        env["OMP_NUM_THREADS"] = str(threads)
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    _, status, ru = os.wait4(p.pid, 0)
    dt = time.perf_counter() - t0
    out = p.stdout.read()
    err = p.stderr.read()
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit(f"bench_wvc2: {' '.join(cmd)} failed:\n{err}{out}")
    return dt, ru.ru_maxrss / 1024.0, out


def best_of(n, cmd, threads=None):
    runs = [run(cmd, threads) for _ in range(n)]
    return min(runs, key=lambda r: r[0])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results"))
    args = ap.parse_args()
    sizes = [64, 128] if args.quick else [256, 512]
    reps = 1 if args.quick else 2
    big = sizes[-1]  # the largest size: the skull at 40 dB only, one run each (its decodes take long)
    res = {"machine": platform.platform(), "cpus": os.cpu_count(), "wvol": WVOL, "bits": [], "regions": [],
           "mc": []}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        files = {}
        for n in sizes:
            for kind, extra in (("skull", ["--noise", "20"]), ("shepp-logan", [])):
                if n == big and kind != "skull":
                    continue
                vol = tmp / f"{kind}{n}.nrrd"
                run([WVOL, "synth", kind, "--size", str(n), "-o", str(vol)] + extra)
                for psnr in ((40,) if n == big else (40, 60)):
                    r_ = 1 if n == big else reps
                    row = {"volume": kind, "size": n, "psnr": psnr, "runs": r_}
                    for fmt in (1, 2):
                        out = tmp / f"{kind}{n}_{psnr}_v{fmt}.wvc"
                        cmd = [WVOL, "compress", str(vol), "-o", str(out), "--psnr", str(psnr), "-w", "db2",
                               "--levels", "5", "--format", str(fmt), "--json"]
                        t1, rss1, js = best_of(r_, cmd, threads=1)
                        t2, _, _ = best_of(r_, cmd, threads=2)
                        info = json.loads(js)
                        dec = tmp / "dec.raw"
                        d1, _, _ = best_of(r_, [WVOL, "decompress", str(out), "-o", str(dec), "--json"], threads=1)
                        d2, _, _ = best_of(r_, [WVOL, "decompress", str(out), "-o", str(dec), "--json"], threads=2)
                        mb = 4.0 * n ** 3 / 1e6
                        row[f"v{fmt}"] = {
                            "bytes": out.stat().st_size,
                            "bits_per_voxel": 8.0 * out.stat().st_size / n ** 3,
                            "measured_psnr": info.get("measured_psnr", info.get("psnr")),
                            "compress_s_1t": t1, "compress_s_2t": t2,
                            "decompress_s_1t": d1, "decompress_s_2t": d2,
                            "compress_MBps_1t": mb / t1, "decompress_MBps_1t": mb / d1,
                        }
                        files[(kind, n, psnr, fmt)] = out
                    row["size_ratio_v2_v1"] = row["v2"]["bytes"] / row["v1"]["bytes"]
                    res["bits"].append(row)
                    print(f"{kind} {n}^3 {psnr} dB: v1 {row['v1']['bytes']} B, v2 {row['v2']['bytes']} B "
                          f"(x{row['size_ratio_v2_v1']:.4f})", flush=True)
        # region reads from the largest skull file
        n = sizes[-1]
        f = files[("skull", n, 40, 2)]
        fsize = f.stat().st_size
        whole_t, whole_rss, _ = best_of(1, [WVOL, "decompress", str(f), "-o", str(tmp / "w.raw")])
        cases = [("64^3 box, full resolution", [n // 2 - 32] * 3 + [n // 2 + 32] * 3, 0),
                 ("256^3 box, full resolution" if n >= 256 else f"{n // 2}^3 box, full resolution",
                  [n // 4] * 3 + [n // 4 + min(256, n // 2)] * 3, 0),
                 ("whole volume, level 2", [0, 0, 0, n, n, n], 2)]
        for label, box, level in cases:
            cmd = [WVOL, "decompress", str(f), "-o", str(tmp / "r.raw"), "--roi", ",".join(map(str, box)),
                   "--level", str(level), "--memory", "512M", "--json"]
            t, rss, js = best_of(1, cmd)
            info = json.loads(js)
            ch = info.get("chunks", {})
            voxels = 1
            for a in range(3):
                voxels *= box[a + 3] - box[a]
            row = {"case": label, "size": n, "box": box, "level": level, "seconds": t, "peak_rss_MiB": rss,
                   "chunks_decoded": ch.get("decoded"), "file_chunks": ch.get("file_chunks"),
                   "bytes_read": ch.get("bytes_read"), "file_bytes": fsize,
                   "share_of_file_read": (ch.get("bytes_read") or 0) / fsize,
                   "share_of_volume": voxels / n ** 3 / (8 ** level),
                   "seconds_vs_whole_decode": t / whole_t, "whole_decode_seconds": whole_t,
                   "whole_decode_rss_MiB": whole_rss}
            res["regions"].append(row)
            print(f"region {label}: {t:.3f} s ({t / whole_t:.3f} of a whole decode), {rss:.0f} MiB, "
                  f"{row['share_of_file_read']:.3f} of the file read", flush=True)
        # marching cubes: from the file, brick by brick, against dense MC on the decoded volume
        for n in sizes:
            f = files[("skull", n, 40, 2)]
            dense = tmp / "dense.nrrd"
            run([WVOL, "decompress", str(f), "-o", str(dense)])
            iso = "300"
            tf, rf, jf = best_of(1 if n == big else reps, [WVOL, "iso", str(f), "-o", str(tmp / "a.ply"), "--iso", iso, "--memory",
                                        "256M", "--json"])
            td, rd, jd = best_of(1 if n == big else reps, [WVOL, "iso", str(dense), "-o", str(tmp / "b.ply"), "--iso", iso, "--json"])
            a, b = json.loads(jf), json.loads(jd)
            row = {"size": n, "iso": float(iso), "file_seconds": tf, "file_rss_MiB": rf, "dense_seconds": td,
                   "dense_rss_MiB": rd, "ratio": tf / td, "file_triangles": a.get("triangles"),
                   "dense_triangles": b.get("triangles")}
            res["mc"].append(row)
            print(f"mc {n}^3: file {tf:.2f} s ({rf:.0f} MiB) vs dense {td:.2f} s ({rd:.0f} MiB): x{tf / td:.2f}",
                  flush=True)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    name = "wvc2_quick" if args.quick else "wvc2"
    (out / f"{name}.json").write_text(json.dumps(res, indent=1))
    lines = [f"# .wvc format 2 against format 1; region reads ({platform.node()}, {os.cpu_count()} CPUs, "
             "shared and loaded: ratios from the same run)", "",
             "Process wall times include start-up and file writing. db2, 5 levels, tiles 64x64x32.", "",
             "| volume | size | PSNR | v1 bytes | v2 bytes | v2 / v1 | compress v1 / v2 (1 thread, s) | "
             "decompress v1 / v2 (1 thread, s) | decompress v2 2 threads (s) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in res["bits"]:
        lines.append(f"| {r['volume']} | {r['size']}^3 | {r['psnr']} | {r['v1']['bytes']} | {r['v2']['bytes']} | "
                     f"{r['size_ratio_v2_v1']:.4f} | {r['v1']['compress_s_1t']:.2f} / {r['v2']['compress_s_1t']:.2f} | "
                     f"{r['v1']['decompress_s_1t']:.2f} / {r['v2']['decompress_s_1t']:.2f} | "
                     f"{r['v2']['decompress_s_2t']:.2f} |")
    lines += ["", "Region reads (`wvol decompress --roi --level`, 512M budget) of the noisy skull at 40 dB:", "",
              "| read | seconds | of a whole decode | peak RSS MiB (whole decode) | chunks decoded | share of file read | share of voxels |",
              "|---|---|---|---|---|---|---|"]
    for r in res["regions"]:
        lines.append(f"| {r['case']} ({r['size']}^3 file) | {r['seconds']:.3f} | {r['seconds_vs_whole_decode']:.3f} | "
                     f"{r['peak_rss_MiB']:.0f} ({r['whole_decode_rss_MiB']:.0f}) | {r['chunks_decoded']} of "
                     f"{r['file_chunks']} | {r['share_of_file_read']:.3f} | {r['share_of_volume']:.4f} |")
    lines += ["", "Marching cubes of the noisy skull at 40 dB, iso 300: from the file (bricks, 256M budget) "
              "against dense marching cubes on the decoded volume:", "",
              "| size | file s | dense s | ratio | file RSS MiB | dense RSS MiB | triangles file / dense |",
              "|---|---|---|---|---|---|---|"]
    for r in res["mc"]:
        lines.append(f"| {r['size']}^3 | {r['file_seconds']:.2f} | {r['dense_seconds']:.2f} | {r['ratio']:.2f} | "
                     f"{r['file_rss_MiB']:.0f} | {r['dense_rss_MiB']:.0f} | {r['file_triangles']} / "
                     f"{r['dense_triangles']} |")
    (out / f"{name}.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {out / name}.json and .md")


if __name__ == "__main__":
    main()
