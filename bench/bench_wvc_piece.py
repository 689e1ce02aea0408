# SPDX-License-Identifier: MIT
"""How fast the ParaView reader's two read paths make a rank's piece of a .wvc, against
`wvol decompress` of the whole file, in one process per measurement (each opens the file
afresh, as a pvbatch rank does):

- piece: wvc_file_piece (the piece decoded into its own array and inverted in place; what
  the reader does for a piece spanning the grid along x and y);
- slabs: wvc_file_region slab by slab with the cache the slabs need (the reader's path for
  any other box);
- decompress: `wvol decompress FILE -o OUT.raw` (whole file, its own threads), CPU seconds
  and the seconds it reports for decoding and the inverse transform (not the write).

Pieces: the whole volume (1 rank, 2 threads) and the lower half along z (one of 2 ranks,
1 thread). Runs are interleaved and repeated; the table gives each one's median CPU seconds
(the machine is shared: CPU time is steadier than wall time), wall seconds, MB/s of float32
output per CPU second, peak RSS and chunks decoded.

    python3 bench/bench_wvc_piece.py FILE.wvc [--repeat 2] [--out wvc_piece_512]

Needs build/ (the wvol CLI and the Python module). Writes bench/results/OUT.json and .md."""
import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

from benchutil import cpu_model

ROOT = pathlib.Path(__file__).resolve().parents[1]
BUILD = pathlib.Path(os.environ.get("WVOL_BUILD_DIR", ROOT / "build"))

CHILD = r"""
import json, resource, sys, time
import numpy as np
from wvol import _wvol
path, how, z1f, threads = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
t, c = time.perf_counter(), time.process_time()
f = _wvol.wvc_file_open(path)
g = _wvol.wvc_file_info(f)["shape"][::-1]
lo, hi = [0, 0, 0], [g[0], g[1], int(round(g[2] * z1f))]
if how == "piece":
    _wvol.wvc_file_set_budget(f, _wvol.wvc_file_piece_budget(f, threads))
    got = _wvol.wvc_file_piece(f, lo, hi, 0, threads)
    if got is None:  # not a piece: a padded x-y grid, or a level the piece reader declines
        sys.exit(f"{path}: the whole volume is not a piece (x and y must be the padded grid): use another file")
    a = got[0]
else:
    _wvol.wvc_file_set_budget(f, _wvol.wvc_file_slab_budget(f, [0, 0, 0], g))
    nz, ny, nx = hi[2], hi[1], hi[0]
    planes = max(1, min(nz, (1 << 23) // (nx * ny), _wvol.wvc_file_info(f)["tile"][1]))
    a = np.empty((nz, ny, nx), np.float32)
    for k in range(0, nz, planes):
        _wvol.wvc_file_region(f, [0, 0, k], [nx, ny, min(nz, k + planes)], 0, out=a[k:k + planes], threads=threads)
print(json.dumps({"wall_s": time.perf_counter() - t, "cpu_s": time.process_time() - c, "bytes": a.nbytes,
                  "decoded": _wvol.wvc_file_stats(f)["decoded"],
                  "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def run_child(path, how, z1f, threads):
    env = {**os.environ, "PYTHONPATH": str(BUILD / "python")}
    r = subprocess.run(["/usr/bin/python3", "-c", CHILD, str(path), how, str(z1f), str(threads)], env=env,
                       capture_output=True, text=True, check=True)
    return json.loads(r.stdout.strip().splitlines()[-1])


def run_decompress(path, tmp):
    out = pathlib.Path(tmp) / "whole.raw"
    t = time.perf_counter()
    p = subprocess.Popen([str(BUILD / "wvol"), "decompress", str(path), "-o", str(out), "--json"],
                         stdout=subprocess.PIPE, text=True)
    stdout = p.stdout.read()
    _, status, ru = os.wait4(p.pid, 0)  # this child's own CPU time and peak, not all children's
    wall = time.perf_counter() - t
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit(f"wvol decompress {path} failed")
    rep = json.loads(stdout)
    nbytes = out.stat().st_size
    out.unlink()
    return {"wall_s": wall, "cpu_s": ru.ru_utime + ru.ru_stime, "decode_s": rep["seconds"]["read_decode"],
            "inverse_s": rep["seconds"]["inverse_transform"], "bytes": nbytes, "peak_rss_mib": ru.ru_maxrss / 1024}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("file")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--out", default="wvc_piece")
    a = ap.parse_args()
    cases = [("piece", 1.0, 2), ("slabs", 1.0, 2), ("piece", 0.5, 1), ("slabs", 0.5, 1)]
    runs = {f"{h} {'whole' if z == 1.0 else 'half'} {t}t": [] for h, z, t in cases}
    runs["decompress whole"] = []
    with tempfile.TemporaryDirectory(prefix="bench_piece_") as tmp:
        for _ in range(a.repeat):
            for h, z, t in cases:
                r = run_child(a.file, h, z, t)
                runs[f"{h} {'whole' if z == 1.0 else 'half'} {t}t"].append(r)
                print(h, z, t, json.dumps(r), flush=True)
            r = run_decompress(a.file, tmp)
            runs["decompress whole"].append(r)
            print("decompress", json.dumps(r), flush=True)
    rows = []
    for name, rs in runs.items():
        med = {k: statistics.median(r[k] for r in rs) for k in rs[0]}
        med["mb_per_cpu_s"] = med["bytes"] / 1e6 / med["cpu_s"]
        rows.append({"case": name, **med, "runs": rs})
    by = {r["case"]: r for r in rows}
    ratios = {"slabs_over_piece_cpu_whole": by["slabs whole 2t"]["cpu_s"] / by["piece whole 2t"]["cpu_s"],
              "slabs_over_piece_cpu_half": by["slabs half 1t"]["cpu_s"] / by["piece half 1t"]["cpu_s"],
              "piece_over_decompress_cpu_whole": by["piece whole 2t"]["cpu_s"] / by["decompress whole"]["cpu_s"],
              "slabs_over_piece_rss_half": by["slabs half 1t"]["peak_rss_mib"] / by["piece half 1t"]["peak_rss_mib"]}
    result = {"machine": {"cpu": cpu_model(), "cores": os.cpu_count()}, "file": str(a.file),
              "file_bytes": pathlib.Path(a.file).stat().st_size, "repeat": a.repeat, "rows": rows, "ratios": ratios}
    out = ROOT / "bench" / "results" / a.out
    out.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    lines = [f"# The ParaView reader's piece read against its slab read and `wvol decompress` ({pathlib.Path(a.file).name})",
             "", f"Machine: {cpu_model()}, {os.cpu_count()} cores (shared with other jobs: CPU seconds are the "
             f"steadier measure). Medians of {a.repeat} interleaved runs, each a fresh process. Made by "
             f"`python3 bench/bench_wvc_piece.py FILE --out {a.out}`.", "",
             "| case | CPU s | wall s | MB/s of output per CPU s | peak RSS MiB | chunks decoded |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['case']} | {r['cpu_s']:.2f} | {r['wall_s']:.2f} | {r['mb_per_cpu_s']:.0f} | "
                     f"{r['peak_rss_mib']:.0f} | {int(r['decoded']) if 'decoded' in r else '-'} |")
    lines += ["", "`Nt`: threads. whole: the volume (one rank); half: the lower half along z (one of two ranks). "
              "decompress: its CPU seconds include writing the .raw file.", "",
              "Ratios: " + ", ".join(f"{k} {v:.2f}" for k, v in ratios.items()), ""]
    out.with_suffix(".md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())
