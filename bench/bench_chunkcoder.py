#!/usr/bin/env python3
"""Runs build/bench/bench_chunkcoder on .wvc files, rounds alternating over the files, and
keeps per file and coder the bytes and the best encode and decode CPU seconds (the
benchmark times each coder with the thread's CPU clock; the machine is shared), and each
round's best (decode_s_rounds, encode_s_rounds) for the spread.

  bench_chunkcoder.py --out bench/results/chunkcoder.json [--rounds 3] [--reps 3] FILE.wvc ...

Ratios against the gate of the task (bench/results/chunkcoder.md): bytes against the file's
own choice ("auto"), decode time against chunk mode 3 and mode 2."""
import argparse
import json
import os
import platform
import subprocess
import time

HERE = os.path.dirname(os.path.abspath(__file__))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("files", nargs="+")
    ap.add_argument("--exe", default=os.path.join(HERE, "..", "build", "bench", "bench_chunkcoder"))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--coders", default="auto,mode2,mode3,mode4,mode4_scalar")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    best = {}
    load = [os.getloadavg()[0]]
    for _ in range(a.rounds):
        for f in a.files:
            env = dict(os.environ, CODERS=a.coders)
            out = subprocess.run([a.exe, f, str(a.reps)], env=env, check=True, capture_output=True, text=True).stdout
            for line in out.splitlines():
                d = json.loads(line)
                k = (os.path.basename(f), d["coder"])
                e = best.setdefault(k, dict(d, file=os.path.basename(f)))
                if d["bytes"] != e["bytes"] or not d["roundtrip"]:
                    raise SystemExit("bytes differ between rounds or round trip failed: %s" % line)
                e["encode_s"] = min(e["encode_s"], d["encode_s"])
                e["decode_s"] = min(e["decode_s"], d["decode_s"])
                e.setdefault("decode_s_rounds", []).append(d["decode_s"])  # each round's best: the spread
                e.setdefault("encode_s_rounds", []).append(d["encode_s"])
        load.append(os.getloadavg()[0])
    rows = []
    for (f, coder), e in sorted(best.items()):
        auto = best.get((f, "auto"))
        ref = best.get((f, "mode2" if "40" in f else "mode3"))
        e["bytes_vs_auto"] = round(e["bytes"] / auto["bytes"], 4) if auto else None
        e["decode_speedup_vs_ref"] = round(ref["decode_s"] / e["decode_s"], 3) if ref else None
        e["decode_ns_coef"] = round(1e9 * e["decode_s"] / e["coefficients"], 2)
        rows.append(e)
    res = {
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "machine": platform.processor() or platform.machine(),
        "load_average_1min": load,
        "rounds": a.rounds,
        "reps": a.reps,
        "timer": "thread CPU seconds, best over rounds x repetitions",
        "reference": "decode_speedup_vs_ref: against mode 2 for the 40 dB files, mode 3 otherwise",
        "rows": rows,
    }
    with open(a.out, "w") as fh:
        json.dump(res, fh, indent=1)
    for e in rows:
        print("%-8s %-20s bytes %9d x%s  enc %.4f  dec %.4f  (%.2f ns/coef)  speedup %s" % (
            e["file"], e["coder"], e["bytes"], e["bytes_vs_auto"], e["encode_s"], e["decode_s"],
            e["decode_ns_coef"], e["decode_speedup_vs_ref"]))


if __name__ == "__main__":
    main()
