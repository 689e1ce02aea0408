# SPDX-License-Identifier: MIT
"""ParaView reading a .wvc (libwvol's reader plugin, each rank decoding the chunks of its piece)
against the same volume as a .vti read by ParaView's own XML reader: time to first image (a
volume rendering saved by pvbatch) and peak resident memory per rank, at 1 and 2 MPI ranks.

Both runs render the same noisy skull with the same camera and transfer function
(tests/python/pvscripts/pv_render.py). The .vti holds the original samples (zlib-compressed
appended data, as wvol writes it); the .wvc the compressed coefficients (--psnr). Peak memory
is each rank's maximum resident set (the kernel's accounting of that process, via wait4 in
bench/peak_rss.py); time to first image is the wall time of the whole pvbatch run (MPI and
ParaView start-up included, the same for both readers) and the part the script measures from
its start to the saved image.

    python3 bench/bench_paraview.py [--size 512] [--psnr 45] [--quick]

Needs scripts/setup.sh's build/ (the wvol CLI) and build-paraview/ (pvbatch wrapper, plugin).
Writes bench/results/paraview.json and paraview.md (paraview_quick.* with --quick).
"""
import argparse
import json
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import time

from benchutil import cpu_model

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests" / "python" / "pvscripts"))
import headless  # noqa: E402  (tests/python/pvscripts/headless.py: an Xvfb display)

ROOT = pathlib.Path(__file__).resolve().parents[1]
BUILD = pathlib.Path(os.environ.get("WVOL_BUILD_DIR", ROOT / "build"))
PV_BUILD = pathlib.Path(os.environ.get("WVOL_PARAVIEW_BUILD_DIR", ROOT / "build-paraview"))
WVOL = BUILD / "wvol"
PVBATCH = PV_BUILD / "pvbatch"
PLUGIN = PV_BUILD / "paraview-plugins" / "wvol_wvc_plugin.py"
RENDER = ROOT / "tests" / "python" / "pvscripts" / "pv_render.py"
PEAK = ROOT / "bench" / "peak_rss.py"


def sh(cmd, **kw):
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(map(str, cmd))}\n{r.stdout}\n{r.stderr}")
    return r


def run_pvbatch(path, ranks, outdir, vmin, vmax, iso, budget, level=0):
    """One pvbatch run of the volume rendering (a .wvc at its level of detail `level`): (wall
    seconds, in-script seconds, peak RSS per rank in bytes, chunk log lines, read seconds)."""
    shutil.rmtree(outdir, ignore_errors=True)  # no log lines or peaks of an earlier run
    outdir.mkdir(parents=True)
    log = outdir / "chunks.jsonl"
    rss = outdir / "rss"
    cmd = [sys.executable, PEAK, rss, PVBATCH, RENDER, PLUGIN, path, outdir, log, vmin, vmax, iso,
           "--array", "density", "--budget", budget, "--release", "--only", "volume", "--time-read",
           "--level", level]
    if ranks > 1:
        cmd = [shutil.which("mpiexec"), "-n", ranks, "--allow-run-as-root", "--oversubscribe", *cmd]
    with headless.display() as disp:
        t0 = time.perf_counter()
        r = sh(cmd, timeout=3600, env={**os.environ, "DISPLAY": disp})
        wall = time.perf_counter() - t0
    m = re.search(r"first image after ([0-9.]+) s", r.stdout + r.stderr)
    reads = [float(x) for x in re.findall(r"data read in ([0-9.]+) s", r.stdout + r.stderr)]
    peaks = sorted(int(p.read_text()) for p in outdir.glob("rss.*"))
    chunks = [json.loads(x) for x in log.read_text().splitlines()] if log.exists() else []
    return wall, float(m.group(1)) if m else None, peaks, chunks, reads


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=512, help="edge of the cubic volume (default 512)")
    ap.add_argument("--psnr", type=float, default=45.0)
    ap.add_argument("--budget", type=int, default=0,
                    help="the reader's chunk cache per rank, MiB (default 0: the reader's own choice, the library's "
                         "1 GiB or what reading its slabs needs when that is more)")
    ap.add_argument("--quick", action="store_true", help="128^3, for a check that it runs")
    ap.add_argument("--keep", help="folder for the data and images (default: a temporary one)")
    ap.add_argument("--reuse", action="store_true",
                    help="with --keep: use the skull.wvc and skull.vti already there (made by an earlier run)")
    ap.add_argument("--out", default="paraview", help="results name in bench/results/ (default paraview)")
    ap.add_argument("--lod", type=int, default=0,
                    help="also run the .wvc at this level of detail (1: half the samples along each axis), "
                         "reported beside the full-resolution rows, outside their ratios")
    a = ap.parse_args()
    n = 128 if a.quick else a.size
    for need in (WVOL, PVBATCH, PLUGIN):
        if not need.exists():
            sys.exit(f"{need} is missing: run scripts/setup.sh")
    work = pathlib.Path(a.keep) if a.keep else pathlib.Path(tempfile.mkdtemp(prefix="bench_pv_"))
    work.mkdir(parents=True, exist_ok=True)
    raw, wvc, vti = work / "skull.nrrd", work / "skull.wvc", work / "skull.vti"
    t = time.perf_counter()
    if not (a.reuse and wvc.exists() and vti.exists()):
        sh([WVOL, "synth", "skull", "--size", n, "--noise", "20", "-o", raw])
        sh([WVOL, "compress", raw, "-o", wvc, "--psnr", a.psnr])
        sh([WVOL, "convert", raw, vti])
        os.remove(raw)
    prep = time.perf_counter() - t
    info = json.loads(sh([WVOL, "info", wvc, "--json"]).stdout)
    vmin, vmax, iso = -1000.0, 2000.0, 300.0  # Hounsfield-like units of the skull phantom
    rows = []
    for ranks in (1, 2):
        for name, path in (("wvc", wvc), ("vti", vti)):
            wall, first, peaks, chunks, reads = run_pvbatch(path, ranks, work / f"{name}{ranks}", vmin, vmax, iso, a.budget)
            row = {"reader": name, "ranks": ranks, "wall_s": wall, "first_image_s": first,
                   "peak_rss_bytes_per_rank": peaks, "max_peak_rss_bytes": max(peaks), "read_s": reads}
            if chunks:
                row["chunks_decoded_per_rank"] = [c["decoded"] for c in chunks]
                row["read_s_per_rank"] = [c.get("seconds") for c in chunks]
                row["chunks_in_file"] = chunks[0]["chunks"]
            rows.append(row)
            print(json.dumps(row), flush=True)
    for ranks in ((1, 2) if a.lod else ()):
        wall, first, peaks, chunks, reads = run_pvbatch(wvc, ranks, work / f"wvc_lod{ranks}", vmin, vmax, iso, a.budget,
                                                        level=a.lod)
        row = {"reader": f"wvc level {a.lod}", "level": a.lod, "ranks": ranks, "wall_s": wall,
               "first_image_s": first, "peak_rss_bytes_per_rank": peaks, "max_peak_rss_bytes": max(peaks),
               "read_s": reads, "chunks_decoded_per_rank": [c["decoded"] for c in chunks],
               "read_s_per_rank": [c.get("seconds") for c in chunks], "chunks_in_file": chunks[0]["chunks"]}
        rows.append(row)
        print(json.dumps(row), flush=True)
    by = {(r["reader"], r["ranks"]): r for r in rows}
    ratios = {
        f"vti_over_wvc_first_image_{k}rank": by[("vti", k)]["first_image_s"] / by[("wvc", k)]["first_image_s"]
        for k in (1, 2)}
    ratios.update({
        f"vti_over_wvc_peak_rss_{k}rank": by[("vti", k)]["max_peak_rss_bytes"] / by[("wvc", k)]["max_peak_rss_bytes"]
        for k in (1, 2)})
    ratios["wvc_peak_rss_1_over_2_ranks"] = by[("wvc", 1)]["max_peak_rss_bytes"] / by[("wvc", 2)]["max_peak_rss_bytes"]
    ratios["vti_peak_rss_1_over_2_ranks"] = by[("vti", 1)]["max_peak_rss_bytes"] / by[("vti", 2)]["max_peak_rss_bytes"]
    for k in ((1, 2) if a.lod else ()):
        lod = by[(f"wvc level {a.lod}", k)]
        ratios[f"vti_over_wvc_level{a.lod}_first_image_{k}rank"] = by[("vti", k)]["first_image_s"] / lod["first_image_s"]
        ratios[f"vti_over_wvc_level{a.lod}_peak_rss_{k}rank"] = by[("vti", k)]["max_peak_rss_bytes"] / lod["max_peak_rss_bytes"]
    result = {"machine": {"cpu": cpu_model(), "cores": os.cpu_count()}, "size": [n, n, n], "psnr": a.psnr,
              "reader_budget_mib": a.budget,
              "bytes": {"wvc": wvc.stat().st_size, "vti": vti.stat().st_size, "float32": 4 * n ** 3},
              "prepare_s": prep, "runs": rows, "ratios": ratios, "wvc_info": info,
              "note": "pvbatch 5.11 (Debian) under Xvfb, software OpenGL; wall_s includes MPI and ParaView start-up"}
    out = ROOT / "bench" / "results" / ("paraview_quick" if a.quick else a.out)
    out.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    mib = 1 << 20
    lines = [f"# ParaView: .wvc reader plugin vs .vti ({n}^3 noisy skull, --psnr {a.psnr:g})", "",
             f"Machine: {cpu_model()}, {os.cpu_count()} cores (shared). Files: .wvc "
             f"{result['bytes']['wvc'] / mib:.1f} MiB, .vti {result['bytes']['vti'] / mib:.1f} MiB, float32 "
             f"{result['bytes']['float32'] / mib:.0f} MiB; the .wvc reader's chunk cache {f'{a.budget} MiB' if a.budget else 'its default (MemoryBudget 0)'} per rank. Made by `python3 bench/bench_paraview.py"
             f"{' --quick' if a.quick else f' --size {n}'}`.", "",
             "| reader | ranks | time to first image (s, in script) | pvbatch wall (s) | peak RSS per rank (MiB) |"
             " chunks decoded per rank | reading s (pipeline update; reader's own) |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['reader']} | {r['ranks']} | {r['first_image_s']:.2f} | {r['wall_s']:.2f} | "
                     f"{', '.join(f'{p / mib:.0f}' for p in r['peak_rss_bytes_per_rank'])} | "
                     f"{', '.join(map(str, r.get('chunks_decoded_per_rank', []))) or '-'}"
                     f"{' of ' + str(r['chunks_in_file']) if 'chunks_in_file' in r else ''} | "
                     f"{', '.join(f'{t:.2f}' for t in r['read_s']) or '-'}"
                     f"{'; ' + ', '.join(f'{t:.2f}' for t in r['read_s_per_rank'] if t is not None) if r.get('read_s_per_rank') else ''} |")
    lines += ["", "Ratios: " + ", ".join(f"{k} {v:.2f}" for k, v in ratios.items()), ""]
    if a.lod:
        lines += [f"The `wvc level {a.lod}` rows read the file's level of detail {a.lod} (LevelOfDetail={a.lod}: "
                  f"{n >> a.lod}^3 samples, the level's predicted error in the field data) and render it with "
                  "the same camera and transfer function: not the same data as the .vti, so they are outside the "
                  "full-resolution ratios and have their own.", ""]
    out.with_suffix(".md").write_text("\n".join(lines))
    print("\n".join(lines))
    if not a.keep:
        shutil.rmtree(work)


if __name__ == "__main__":
    main()
