#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Two builds of wvol against each other on the same volumes: file bytes and decode CPU.

For a change to the coded form (say mode 4's packed tables, docs/wvc-format.md) the yardstick
is the build before it: `--base` and `--new` are two `wvol` binaries. Each compresses the same
volumes (made once by `--new`'s `wvol synth`: the noisy skull, Shepp-Logan, the turbulence
field) at 40, 50 and 60 dB with the default options and with bench_wvc2.py's (db2, 5 levels),
one thread; per case the bytes of both files, whether the files and their decoded volumes are
identical (`cmp`), and each build decoding its own file (`wvol decompress`, one thread, process CPU
seconds, the least of --rounds alternated runs: on a shared VM the same binary's runs differ by
up to 1.5x with what ran before, so only the least is compared).

    bench/bench_ab_bytes.py --base OLD/wvol --new build/wvol --out bench/results/packed_tables
"""
import argparse
import filecmp
import json
import os
import pathlib
import subprocess
import tempfile
import time

from benchutil import cpu_model

VOLUMES = (("skull", ["--noise", "20"]), ("shepp-logan", []), ("turbulence", []))
CONFIGS = (("default", []), ("db2, 5 levels", ["-w", "db2", "--levels", "5"]))


def run_cpu(cmd):
    """Process CPU seconds (user + system) of one run, output to /dev/null, one OpenMP thread."""
    pid = os.fork()
    if pid == 0:
        fd = os.open(os.devnull, os.O_WRONLY)
        os.dup2(fd, 1)
        os.environ["OMP_NUM_THREADS"] = "1"
        try:
            os.execv(cmd[0], [str(c) for c in cmd])
        finally:
            os._exit(127)
    _, status, ru = os.wait4(pid, 0)
    if os.waitstatus_to_exitcode(status):
        raise SystemExit(f"{' '.join(map(str, cmd))} failed")
    return ru.ru_utime + ru.ru_stime


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", required=True, help="the wvol binary before the change")
    ap.add_argument("--new", required=True, help="the wvol binary with it")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--out", required=True, help="path stem of the .json and .md written")
    a = ap.parse_args()
    base, new = os.path.abspath(a.base), os.path.abspath(a.new)
    rows = []
    t0 = time.time()
    with tempfile.TemporaryDirectory(dir="/dev/shm" if os.path.isdir("/dev/shm") else None) as tmp:
        tmp = pathlib.Path(tmp)
        for vol, extra in VOLUMES:
            src = tmp / f"{vol}.nrrd"
            subprocess.run([new, "synth", vol, "--size", str(a.size), "-o", src] + extra, check=True,
                           stdout=subprocess.DEVNULL)
            for cname, copts in CONFIGS:
                for db in (40, 50, 60):
                    f = {k: tmp / f"{k}.wvc" for k in ("base", "new")}
                    d = {k: tmp / f"{k}.raw" for k in ("base", "new")}
                    for k, b in (("base", base), ("new", new)):
                        run_cpu([b, "compress", src, "-o", f[k], "--psnr", str(db), "--threads", "1"] + copts)
                        run_cpu([b, "decompress", f[k], "-o", d[k]])
                    same = filecmp.cmp(d["base"], d["new"], shallow=False)
                    dec = {"base": 1e9, "new": 1e9}
                    for r in range(a.rounds):
                        for k, b in ((("base", base), ("new", new)) if r % 2 == 0 else (("new", new), ("base", base))):
                            dec[k] = min(dec[k], run_cpu([b, "decompress", f[k], "-o", d[k]]))
                    row = {"volume": vol, "config": cname, "psnr": db, "bytes_base": f["base"].stat().st_size,
                           "bytes_new": f["new"].stat().st_size, "decoded_identical": same,
                           "files_identical": filecmp.cmp(f["base"], f["new"], shallow=False),
                           "decompress_cpu_s_base": dec["base"], "decompress_cpu_s_new": dec["new"]}
                    row["bytes_ratio"] = row["bytes_new"] / row["bytes_base"]
                    rows.append(row)
                    print(f"{vol:12s} {cname:14s} {db} dB: bytes {row['bytes_base']} -> {row['bytes_new']} "
                          f"({row['bytes_ratio']:.4f}), decoded identical {same}, decompress CPU "
                          f"{dec['base']:.3f} -> {dec['new']:.3f} s", flush=True)
    res = {"machine": cpu_model(), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "size": a.size,
           "rounds": a.rounds, "base": base, "new": new, "seconds": time.time() - t0, "rows": rows}
    out = pathlib.Path(a.out)
    out.with_suffix(".json").write_text(json.dumps(res, indent=1) + "\n")
    lines = [f"# Two builds against each other: bytes and decode CPU ({a.size}^3)", "",
             f"{res['machine']}; {res['date']}; load average {os.getloadavg()[0]:.1f} at the end. Made by "
             f"`bench/bench_ab_bytes.py` (base `{base}`, new `{new}`). Volumes from `wvol synth` (the skull with "
             "`--noise 20`); `wvol compress --psnr P --threads 1` with the default options and with bench_wvc2.py's "
             f"(`-w db2 --levels 5`); decompress: one thread, process CPU seconds, the least of {a.rounds} alternated "
             "runs, each build decoding its own file.", "",
             "| volume | options | dB | bytes base | bytes new | new / base | decoded identical | decompress CPU s base "
             "| new |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['volume']} | {r['config']} | {r['psnr']} | {r['bytes_base']} | {r['bytes_new']} | "
                     f"{r['bytes_ratio']:.4f} | {'yes' if r['decoded_identical'] else 'NO'} | "
                     f"{r['decompress_cpu_s_base']:.3f} | {r['decompress_cpu_s_new']:.3f} |")
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
