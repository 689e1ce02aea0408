#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Whole-process `wvol compress` / `wvol decompress` CPU of chunk mode 4 (this tree's default
--coder auto) against main's binary (its --coder auto: modes 0, 2, 3), on one thread.

For each raw float32 volume (name=path:NXxNYxNZ) and PSNR target, both programs compress it
(bytes kept); then round by round, alternating A B A B, main compresses, this tree compresses,
main decompresses main's file, this tree decompresses its file (OMP_NUM_THREADS=1,
OMP_WAIT_POLICY=passive, --threads 1 for compress, output to /dev/shm). The CPU seconds
(user + system of the process, from wait4) of each run are kept; the best over the rounds is
reported. The two decoded volumes are compared (equal quantised values: the same bytes out).

    bench_mode4_cli.py --base MAIN_WVOL --wvol build/wvol --out bench/results/mode4_cli.json \
        [--rounds 5] [--psnr 40 50 60] skull=/dev/shm/s.raw:256x256x256 ...
"""
import argparse
import filecmp
import json
import os
import subprocess
import time


def cpu(cmd):
    env = dict(os.environ, OMP_NUM_THREADS="1", OMP_WAIT_POLICY="passive")
    p = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    err = p.stderr.read()
    p.stderr.close()
    if status != 0:
        raise SystemExit("failed: %s\n%s" % (" ".join(cmd), err.decode(errors="replace")))
    return ru.ru_utime + ru.ru_stime


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("volumes", nargs="+")
    ap.add_argument("--base", required=True)
    ap.add_argument("--wvol", required=True)
    ap.add_argument("--psnr", type=float, nargs="+", default=[40, 50, 60])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--tmp", default="/dev/shm/mode4_cli")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    os.makedirs(a.tmp, exist_ok=True)
    progs = {"main": a.base, "mode4": a.wvol}
    rows = []
    load = [os.getloadavg()[0]]
    for spec in a.volumes:
        name, rest = spec.split("=", 1)
        path, dims = rest.rsplit(":", 1)
        for q in a.psnr:
            r = {"volume": name, "dims": dims, "psnr": q}
            files = {k: os.path.join(a.tmp, "%s_%g_%s.wvc" % (name, q, k)) for k in progs}
            outs = {k: os.path.join(a.tmp, "%s_%g_%s.raw" % (name, q, k)) for k in progs}
            comp = {k: [progs[k], "compress", path, "--dims", dims, "--psnr", "%g" % q, "--threads", "1",
                        "-o", files[k]] for k in progs}
            dec = {k: [progs[k], "decompress", files[k], "-o", outs[k]] for k in progs}
            for k in progs:
                r["compress_cpu_s_rounds_" + k] = []
                r["decompress_cpu_s_rounds_" + k] = []
            for _ in range(a.rounds):
                for k in progs:
                    r["compress_cpu_s_rounds_" + k].append(round(cpu(comp[k]), 4))
                for k in progs:
                    r["decompress_cpu_s_rounds_" + k].append(round(cpu(dec[k]), 4))
            for k in progs:
                r["bytes_" + k] = os.path.getsize(files[k])
                r["compress_cpu_s_" + k] = min(r["compress_cpu_s_rounds_" + k])
                r["decompress_cpu_s_" + k] = min(r["decompress_cpu_s_rounds_" + k])
            r["same_output"] = filecmp.cmp(outs["main"], outs["mode4"], shallow=False)
            r["bytes_ratio"] = round(r["bytes_mode4"] / r["bytes_main"], 4)
            r["decompress_speedup"] = round(r["decompress_cpu_s_main"] / r["decompress_cpu_s_mode4"], 3)
            r["compress_ratio"] = round(r["compress_cpu_s_mode4"] / r["compress_cpu_s_main"], 3)
            rows.append(r)
            load.append(os.getloadavg()[0])
            print("%-10s %g dB  bytes %9d -> %9d (x%.4f)  decompress %.3f -> %.3f s (%.2fx)  compress %.3f -> %.3f s "
                  "(x%.2f)  same output %s" % (name, q, r["bytes_main"], r["bytes_mode4"], r["bytes_ratio"],
                                               r["decompress_cpu_s_main"], r["decompress_cpu_s_mode4"],
                                               r["decompress_speedup"], r["compress_cpu_s_main"],
                                               r["compress_cpu_s_mode4"], r["compress_ratio"], r["same_output"]),
                  flush=True)
            for f in list(files.values()) + list(outs.values()):
                os.remove(f)
    res = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "base": a.base, "wvol": a.wvol,
           "rounds": a.rounds, "threads": 1, "timer": "process user + system CPU seconds (wait4), best of the rounds",
           "load_average_1min": load, "rows": rows}
    with open(a.out, "w") as fh:
        json.dump(res, fh, indent=1)


if __name__ == "__main__":
    main()
