#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""How evenly `wvol compress` / `wvol decompress` share their work between two threads, for
main's binary and this tree's, on a machine whose other jobs make wall-clock speed-ups
unmeasurable (bench_speed.py measures those too, and says so).

Each command runs once per round under `perf record` (CPU-clock samples, which count only
while a thread runs, whatever else the machine does) with OMP_NUM_THREADS=2 and
OMP_WAIT_POLICY=passive (a waiting thread sleeps and takes no samples). The busiest
thread's share s of the samples bounds the two-thread wall time from below, s x the CPU
CPU seconds of a two-thread run (a plain one: perf's own time is not in it): on two free
cores the run cannot take less, and takes that when the busiest thread never waits for the
other. `bound` = CPU seconds on one thread / (s x CPU seconds on two): the wall-clock
speed-up two free cores would give at most. The median over
the rounds is reported. The same volumes as bench_speed.py (noisy skull, turbulence field,
raw float32 in /dev/shm), streamed compression at each PSNR target, decompression of that
file to raw.

Writes bench/results/speed_threads.json and .md.
    python3 bench/bench_threads.py --base MAIN_WVOL [--wvol build/wvol] [--sizes 256] [--rounds 3]
    python3 bench/bench_threads.py --from-json     # the .md again from the .json
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_speed import run  # noqa: E402
from benchutil import cpu_model  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def cpu_run(cmd, threads):
    """CPU seconds of one whole process (bench_speed.py's runner)."""
    return run(cmd, threads)[0]


def thread_shares(cmd, tmp):
    """Per-thread shares of the CPU-clock samples of one run on two threads, and its CPU seconds."""
    data = os.path.join(tmp, "perf.data")
    env = dict(os.environ, OMP_NUM_THREADS="2", OMP_WAIT_POLICY="passive")
    p = subprocess.Popen(["perf", "record", "-q", "-F", "4000", "-o", data, "--", *cmd], stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, env=env)
    _, status, ru = os.wait4(p.pid, 0)
    p.stderr.close()
    if status != 0:
        raise RuntimeError(f"perf record {' '.join(cmd)} failed")
    rep = subprocess.run(["perf", "report", "-i", data, "--sort", "pid", "--stdio"], capture_output=True,
                         text=True).stdout
    shares = [float(m.group(1)) / 100 for m in re.finditer(r"^\s+([0-9.]+)%\s+\d+:", rep, re.M)]
    os.remove(data)
    return sorted(shares, reverse=True), ru.ru_utime + ru.ru_stime


def median(v):
    v = sorted(v)
    return v[len(v) // 2]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[256])
    ap.add_argument("--kinds", nargs="+", default=["skull", "turbulence"])
    ap.add_argument("--targets", type=float, nargs="+", default=[40, 50, 60])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--base")
    ap.add_argument("--wvol", default=os.path.join(ROOT, "build", "wvol"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "speed_threads"))
    ap.add_argument("--from-json", action="store_true", help="rewrite the .md from the .json of a run")
    a = ap.parse_args()
    if a.from_json:
        with open(a.out + ".json") as f:
            d = json.load(f)
        write_md(a.out + ".md", d["meta"], d["rows"])
        return
    if not a.base:
        ap.error("--base (main's wvol) is needed")
    rows = []
    tmp = tempfile.mkdtemp(dir="/dev/shm" if os.path.isdir("/dev/shm") else None)
    progs = (("main", a.base), ("new", a.wvol))
    try:
        for n in a.sizes:
            for kind in a.kinds:
                raw = os.path.join(tmp, "v.raw")
                extra = ["--noise", "20"] if kind == "skull" else []
                cpu_run([a.wvol, "synth", kind, "--size", str(n), *extra, "-o", raw], 2)
                dims = ["--dims", f"{n}x{n}x{n}", "--type", "float32"]
                for target in a.targets:
                    for who, exe in progs:
                        f = os.path.join(tmp, f"{who}.wvc")
                        cpu_run([exe, "compress", raw, *dims, "--psnr", str(target), "-o", f], 1)
                    res = {}
                    for _ in range(a.rounds):
                        for who, exe in progs:
                            cmds = {"compress": [exe, "compress", raw, *dims, "--psnr", str(target), "-o",
                                                 os.path.join(tmp, "x.wvc")],
                                    "decompress": [exe, "decompress", os.path.join(tmp, f"{who}.wvc"), "-o",
                                                   os.path.join(tmp, "d.raw")]}
                            for op, c in cmds.items():
                                one = cpu_run(c, 1)
                                two = cpu_run(c, 2)
                                sh, _ = thread_shares(c, tmp)  # perf's own CPU time is in that run's
                                res.setdefault((op, who), []).append(
                                    {"cpu1_s": one, "cpu2_s": two, "busiest": sh[0], "bound": one / (sh[0] * two)})
                    for (op, who), v in res.items():
                        row = {"kind": kind, "n": n, "target": target, "op": op, "prog": who,
                               "cpu1_s": median([x["cpu1_s"] for x in v]), "cpu2_s": median([x["cpu2_s"] for x in v]),
                               "busiest": median([x["busiest"] for x in v]), "bound": median([x["bound"] for x in v])}
                        rows.append(row)
                        print(json.dumps(row), flush=True)
                os.remove(raw)
    finally:
        for f in os.listdir(tmp):
            os.remove(os.path.join(tmp, f))
        os.rmdir(tmp)
    commit = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    meta = {"machine": f"{cpu_model()}, {os.cpu_count()} cores, shared with other jobs", "base": a.base,
            "wvol": a.wvol, "commit": commit, "rounds": a.rounds}
    with open(a.out + ".json", "w") as f:
        json.dump({"meta": meta, "rows": rows}, f, indent=1)
    write_md(a.out + ".md", meta, rows)


def write_md(path, meta, rows):
    L = ["# Two threads: how evenly the work is shared (main's program and this tree's)", "",
         f"Machine: {meta['machine']}. This tree {meta['commit']} (`{meta['wvol']}`), main's `{meta['base']}`. "
         f"Median of {meta['rounds']} rounds. `busiest`: the busiest thread's share of the CPU-clock samples of a "
         "two-thread run (perf; a waiting thread sleeps and takes none), which does not depend on the other jobs "
         "of the machine. `1/busiest`: the wall-clock speed-up of two free cores over one if two threads cost "
         "the CPU time of one and the busiest thread never waits (an upper bound under that assumption). The CPU "
         "seconds (one run per round on this loaded machine, so within about 30%) and `bound` = one-thread CPU "
         "seconds / (busiest x two-thread CPU seconds) are given for completeness; bench_speed.py's wall-clock "
         "ratios on this shared machine are stretched by the other jobs.", "",
         "| volume | size | dB | op | busiest main / new | 1/busiest main / new | CPU s 1 thread main / new | "
         "CPU s 2 threads main / new | bound main / new |",
         "|---|---|---|---|---|---|---|---|---|"]
    by = {}
    for r in rows:
        by.setdefault((r["kind"], r["n"], r["target"], r["op"]), {})[r["prog"]] = r
    for (k, n, t, op), d in by.items():
        m, w = d["main"], d["new"]
        L.append(f"| {k} | {n}^3 | {t:g} | {op} | {m['busiest']:.2f} / {w['busiest']:.2f} | "
                 f"{1 / m['busiest']:.2f}x / {1 / w['busiest']:.2f}x | {m['cpu1_s']:.3f} / {w['cpu1_s']:.3f} | "
                 f"{m['cpu2_s']:.3f} / {w['cpu2_s']:.3f} | {m['bound']:.2f}x / {w['bound']:.2f}x |")
    with open(path, "w") as f:
        f.write("\n".join(L) + "\n")


if __name__ == "__main__":
    main()
