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
import statistics
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
PLUGIN = PV_BUILD / "paraview-plugins" / "WvolReader" / "WvolReader.so"  # vtkWVCReader (paraview/)
RENDER = ROOT / "tests" / "python" / "pvscripts" / "pv_render.py"
PEAK = ROOT / "bench" / "peak_rss.py"


def sh(cmd, **kw):
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(map(str, cmd))}\n{r.stdout}\n{r.stderr}")
    return r


def rank_peaks(outdir):
    """Each rank's peak RSS in bytes, in rank order (bench/peak_rss.py's files rss.<rank>)."""
    return [int(p.read_text()) for p in sorted(outdir.glob("rss.*"), key=lambda p: int(p.suffix[1:]))]


def run_dir(work, row):
    """The folder of a run's images, logs and peaks."""
    if "level" in row:
        return work / f"wvc_lod{row['ranks']}"
    return work / f"{row['reader']}{row['ranks']}_{row.get('repetition', 0)}"


def lit_fraction(png):
    """The fraction of the image's pixels that are not the black background."""
    from PIL import Image
    import numpy as np
    a = np.asarray(Image.open(png).convert("RGB"))
    return float((a.max(axis=2) > 0).mean())


def run_pvbatch(path, ranks, outdir, vmin, vmax, iso, budget, level=0, volume_mode="smart"):
    """One pvbatch run of the volume rendering (a .wvc at its level of detail `level`): a dict of
    the wall seconds, the in-script seconds to the first image, the reading and rendering
    seconds apart (the reader updated alone, then the image), the peak RSS per rank in bytes,
    the chunk log's lines (per rank: chunks, the read's seconds, resident memory before and
    after it) and rank 0's memory at each stage (pv_render.py's "memory" line)."""
    shutil.rmtree(outdir, ignore_errors=True)  # no log lines or peaks of an earlier run
    outdir.mkdir(parents=True)
    log = outdir / "chunks.jsonl"
    rss = outdir / "rss"
    cmd = [sys.executable, PEAK, rss, PVBATCH, RENDER, PLUGIN, path, outdir, log, vmin, vmax, iso,
           "--array", "density", "--budget", budget, "--release", "--only", "volume", "--time-read",
           "--level", level, "--volume-mode", volume_mode]
    if ranks > 1:
        cmd = [shutil.which("mpiexec"), "-n", ranks, "--allow-run-as-root", "--oversubscribe", *cmd]
    with headless.display() as disp:
        t0 = time.perf_counter()
        # the plugin loaded at start-up, as installed (for both readers): LoadPlugin in the script would
        # also rebuild paraview.simple's proxy classes on rank 0, a few MiB a built-in reader does not cost
        r = sh(cmd, timeout=3600, env={**os.environ, "DISPLAY": disp, "PV_PLUGIN_PATH": str(PLUGIN.parent)})
        wall = time.perf_counter() - t0
    text = r.stdout + r.stderr
    m = re.search(r"first image after ([0-9.]+) s", text)
    reads = [float(x) for x in re.findall(r"data read in ([0-9.]+) s", text)]
    read_cpu = [float(x) for x in re.findall(r"data read in [0-9.]+ s \(([0-9.]+) CPU s\)", text)]
    renders = [float(x) for x in re.findall(r"rendered in ([0-9.]+) s", text)]
    mem = [json.loads(x) for x in re.findall(r"^memory (\{.*\})$", text, re.M)]
    peaks = rank_peaks(outdir)
    chunks = [json.loads(x) for x in log.read_text().splitlines()] if log.exists() else []
    # a renderer that could not draw the volume (llvmpipe's GPU mapper with a piece over its texture
    # size limit) leaves a black image: its time is not a time to first image
    lit = lit_fraction(outdir / "volume.png")
    if lit == 0.0:
        sys.exit(f"{path}, {ranks} rank(s), volume mode {volume_mode}: the saved image is blank (the volume "
                 "was not drawn); use --volume-mode raycast")
    return {"image_lit_fraction": lit, "wall_s": wall, "first_image_s": float(m.group(1)) if m else None, "read_s": reads, "read_cpu_s": read_cpu,
            "render_s": renders, "peak_rss_bytes_per_rank": peaks, "max_peak_rss_bytes": max(peaks),
            "stage_memory_rank0": mem[0] if mem else None, "chunk_log": chunks}


def report(result, out):
    """Writes result (with its ratios, the memory breakdown and the goals) to out.json and out.md."""
    rows = result["runs"]
    n = result["size"][0]
    lod = result.get("lod") or next((r["level"] for r in rows if "level" in r), 0)
    mib = 1 << 20

    def med(reader, ranks, key):
        """The median over the runs of (reader, ranks) of a row's value (a list: its largest)."""
        vals = []
        for r in rows:
            if r["reader"] == reader and r["ranks"] == ranks:
                v = r[key]
                vals.append(max(v) if isinstance(v, list) else v)
        return statistics.median(vals)

    ratios = {}
    for k in (1, 2):
        for key, name in (("first_image_s", "first_image"), ("read_s", "read"), ("read_cpu_s", "read_cpu"),
                          ("render_s", "render"), ("max_peak_rss_bytes", "peak_rss")):
            if all(r.get(key) for r in rows if r["reader"] in ("wvc", "vti")):
                ratios[f"vti_over_wvc_{name}_{k}rank"] = med("vti", k, key) / med("wvc", k, key)
    for reader in ("wvc", "vti"):
        ratios[f"{reader}_peak_rss_1_over_2_ranks"] = (med(reader, 1, "max_peak_rss_bytes")
                                                       / med(reader, 2, "max_peak_rss_bytes"))
    # the data part of the peak (the peak less the rank's ParaView before any data)
    data = {}
    for r in rows:
        log = r.get("chunk_log") or []
        if r["reader"] == "wvc" and log:
            first = {}
            for c in log:
                first.setdefault(c["rank"], c)
            data.setdefault(r["ranks"], []).append(
                max(r["peak_rss_bytes_per_rank"][k] / mib - first[k]["peak_rss_mib_before"] for k in first))
    if 1 in data and 2 in data:
        ratios["wvc_data_part_1_over_2_ranks"] = statistics.median(data[1]) / statistics.median(data[2])
    for k in ((1, 2) if lod else ()):
        name = f"wvc level {lod}"
        ratios[f"vti_over_wvc_level{lod}_first_image_{k}rank"] = med("vti", k, "first_image_s") / med(name, k, "first_image_s")
        ratios[f"vti_over_wvc_level{lod}_peak_rss_{k}rank"] = (med("vti", k, "max_peak_rss_bytes")
                                                              / med(name, k, "max_peak_rss_bytes"))
    result["ratios"] = ratios

    # where each rank's peak comes from: ParaView before any data (its peak before the read), what
    # the read adds (the output array, the margins, the decoded chunks, scratch), what rendering
    # adds after it (the renderer's copies)
    breakdown = []
    for r in rows:
        log = r.get("chunk_log") or []
        first = {}
        for c in log:
            first.setdefault(c["rank"], c)
        peaks = r["peak_rss_bytes_per_rank"]
        if first:
            for k in sorted(first):
                c = first[k]
                e = c["extent"]
                samples = (e[1] - e[0] + 1) * (e[3] - e[2] + 1) * (e[5] - e[4] + 1) if e else 0
                breakdown.append({"reader": r["reader"], "ranks": r["ranks"], "rank": k,
                                  "repetition": r.get("repetition", 0), "base_mib": c.get("peak_rss_mib_before"),
                                  "after_read_mib": c.get("peak_rss_mib_after"), "array_mib": 4 * samples / mib,
                                  "cache_peak_mib": c["cache_peak_bytes"] / mib,
                                  "peak_mib": peaks[k] / mib if k < len(peaks) else None})
        elif r.get("stage_memory_rank0"):
            st = r["stage_memory_rank0"]
            breakdown.append({"reader": r["reader"], "ranks": r["ranks"], "rank": 0,
                              "repetition": r.get("repetition", 0), "base_mib": st["base"]["peak_mib"],
                              "after_read_mib": st["read"]["peak_mib"], "array_mib": None, "cache_peak_mib": None,
                              "peak_mib": peaks[0] / mib})
    result["memory_breakdown"] = breakdown

    def better(ratio, margin=0.01):
        """'met' when the .wvc is better by more than margin, 'tie' within it, else 'NOT met'."""
        return "met" if ratio > 1 + margin else ("tie (within 1%)" if ratio >= 1 - margin else "NOT met")

    goals = {f"less peak memory per rank, {k} rank(s)": better(ratios[f"vti_over_wvc_peak_rss_{k}rank"]) for k in (1, 2)}
    goals.update({f"less time to first image, {k} rank(s)": better(ratios[f"vti_over_wvc_first_image_{k}rank"])
                  for k in (1, 2)})
    goals.update({f"reading faster (wall), {k} rank(s)": better(ratios[f"vti_over_wvc_read_{k}rank"]) for k in (1, 2)})
    goals.update({f"reading in fewer CPU seconds, {k} rank(s)": better(ratios[f"vti_over_wvc_read_cpu_{k}rank"])
                  for k in (1, 2) if f"vti_over_wvc_read_cpu_{k}rank" in ratios})
    # halving: 2 ranks' largest peak at most 52.5% of 1 rank's (1.9x)
    goals["peak memory per rank halves from 1 to 2 ranks (>= 1.9x)"] = (
        "met" if ratios["wvc_peak_rss_1_over_2_ranks"] >= 1.9 else "NOT met")
    if "wvc_data_part_1_over_2_ranks" in ratios:
        goals["the data part (peak - base) halves from 1 to 2 ranks (>= 1.9x)"] = (
            "met" if ratios["wvc_data_part_1_over_2_ranks"] >= 1.9 else "NOT met")
    result["goals"] = goals
    out.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")

    budget = result.get("reader_budget_mib", 0)
    load = result.get("load_avg_1min", [float("nan")] * 2)
    lines = [f"# ParaView: the .wvc reader plugin (C++, vtkWVCReader) vs .vti ({n}^3 noisy skull, --psnr {result['psnr']:g})",
             "", *([result["title_note"], ""] if result.get("title_note") else []),
             f"Machine: {result['machine']['cpu']}, {result['machine']['cores']} cores (shared). Files: .wvc "
             f"{result['bytes']['wvc'] / mib:.1f} MiB, .vti {result['bytes']['vti'] / mib:.1f} MiB, float32 "
             f"{result['bytes']['float32'] / mib:.0f} MiB; the .wvc reader's chunk cache "
             f"{f'{budget} MiB' if budget else 'its default (MemoryBudget 0)'} per rank. Made by "
             f"`python3 bench/bench_paraview.py{' --quick' if result.get('quick') else f' --size {n}'}"
             f"{f' --lod {lod}' if lod else ''}`; load average (1 min) {load[0]:.1f} at the start, {load[1]:.1f} at "
             "the end. Reading: the reader updated alone (`UpdatePipeline`); rendering: from there to the saved "
             "volume rendering; time to first image: from the script's start (imports and the plugin included). "
             + {"smart": "Volume mapper: ParaView's default (Smart: the GPU mapper, here Mesa's llvmpipe).",
                "raycast": "Volume mapper: ParaView's CPU ray caster ('Ray Cast Only'): the default GPU mapper draws "
                           "nothing under Mesa's llvmpipe when a rank's piece is over its texture size limit (a 2 GiB piece is, a 512 MiB one is not).",
                None: "Volume mapper: ParaView's default."}[result.get("volume_mode")]
             + (f" Every saved image has the volume drawn ({min(r['image_lit_fraction'] for r in rows):.0%}-"
                f"{max(r['image_lit_fraction'] for r in rows):.0%} of its pixels lit)."
                if all("image_lit_fraction" in r for r in rows) else ""), "",
             "| reader | ranks | time to first image (s, in script) | reading (s) | reading, CPU s (rank 0) | rendering (s) | pvbatch wall (s) |"
             " peak RSS per rank (MiB) | peak RSS before / after reading, per rank (MiB) | chunks decoded per rank |"
             " reader's own read per rank (s) |", "|---|---|---|---|---|---|---|---|---|---|---|"]

    def nums(v, fmt):
        return ", ".join(fmt.format(x) for x in v if x is not None) if v else "-"

    for r in rows:
        mem = "-"
        if r.get("peak_rss_mib_before_read_per_rank"):
            mem = ", ".join(f"{b:.0f} / {c:.0f}" for b, c in zip(r["peak_rss_mib_before_read_per_rank"],
                                                                 r["peak_rss_mib_after_read_per_rank"]))
        elif r.get("stage_memory_rank0"):
            st = r["stage_memory_rank0"]
            mem = f"{st['base']['peak_mib']:.0f} / {st['read']['peak_mib']:.0f} (rank 0)"
        chunks = nums(r.get("chunks_decoded_per_rank"), "{}")
        if "chunks_in_file" in r:
            chunks += f" of {r['chunks_in_file']}"
        lines.append(f"| {r['reader']} | {r['ranks']} | {r['first_image_s']:.2f} | {nums(r['read_s'], '{:.2f}')} | "
                     f"{nums(r.get('read_cpu_s'), '{:.2f}')} | "
                     f"{nums(r['render_s'], '{:.2f}')} | {r['wall_s']:.2f} | "
                     f"{nums([p / mib for p in r['peak_rss_bytes_per_rank']], '{:.0f}')} | {mem} | {chunks} | "
                     f"{nums(r.get('read_s_per_rank'), '{:.2f}')} |")
    lines += ["", "Ratios (medians over the repeats): " + ", ".join(f"{k} {v:.2f}" for k, v in ratios.items()), ""]
    lines += ["## Where each rank's peak comes from (MiB)", "",
              "peak = base (ParaView before any data: its libraries, Python on rank 0, the plugin) + what the read "
              "adds (the output array, for the .wvc also the margins' planes, the decoded chunks and scratch) + what "
              "rendering adds beyond that (the renderer's copies).", "",
              "| reader | ranks | rank | base | read adds | output array | decoded chunks (cache peak) | rendering adds | peak |",
              "|---|---|---|---|---|---|---|---|---|"]

    def f0(v):
        return "-" if v is None else f"{v:.0f}"

    for b in breakdown:
        adds = None if b["after_read_mib"] is None or b["base_mib"] is None else b["after_read_mib"] - b["base_mib"]
        render = None if b["peak_mib"] is None or b["after_read_mib"] is None else b["peak_mib"] - b["after_read_mib"]
        lines.append(f"| {b['reader']} | {b['ranks']} | {b['rank']} | {f0(b['base_mib'])} | {f0(adds)} | "
                     f"{f0(b['array_mib'])} | {f0(b['cache_peak_mib'])} | {f0(render)} | {f0(b['peak_mib'])} |")
    lines += ["", "## Goals", ""]
    lines += [f"- {k}: {v}" for k, v in goals.items()]
    lines += [""]
    if lod:
        lines += [f"The `wvc level {lod}` rows read the file's level of detail {lod} (LevelOfDetail={lod}: "
                  f"{n >> lod}^3 samples, the level's predicted error in the field data) and render it with "
                  "the same camera and transfer function: not the same data as the .vti, so they are outside the "
                  "full-resolution ratios and the goals, and have their own ratios.", ""]
    out.with_suffix(".md").write_text("\n".join(lines))
    print("\n".join(lines))


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
    ap.add_argument("--repeat", type=int, default=1,
                    help="runs of each 1-rank pair, interleaved (wvc, vti, wvc, vti...); the ratios take the medians")
    ap.add_argument("--repeat2", type=int, default=1,
                    help="runs of each 2-rank pair, interleaved (default 1)")
    ap.add_argument("--report", action="store_true",
                    help="rewrite the .md from the results' .json (with --keep: each rank's peak from the runs' files)")
    ap.add_argument("--volume-mode", choices=("auto", "smart", "raycast"), default="auto",
                    help="ParaView's volume mapper: smart (its default, the GPU mapper: under Mesa's llvmpipe the "
                         "volume is one 3D texture, which draws nothing over llvmpipe's texture size limit) or raycast "
                         "(its CPU ray caster, 'Ray Cast Only'); auto (default): smart when the whole float32 "
                         "volume is at most 1 GiB (512^3 renders, a 2 GiB piece does not), else raycast, the same "
                         "for every row")
    ap.add_argument("--lod", type=int, default=0,
                    help="also run the .wvc at this level of detail (1: half the samples along each axis), "
                         "reported beside the full-resolution rows, outside their ratios")
    a = ap.parse_args()
    n = 128 if a.quick else a.size
    out = ROOT / "bench" / "results" / ("paraview_quick" if a.quick else a.out)
    if a.report:  # the tables again from the JSON (and the runs' rank peaks, with --keep)
        result = json.loads(out.with_suffix(".json").read_text())
        if a.keep:
            for row in result["runs"]:
                peaks = rank_peaks(run_dir(pathlib.Path(a.keep), row))
                if peaks:
                    row["peak_rss_bytes_per_rank"] = peaks
        report(result, out)
        return
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
    load_start = os.getloadavg()
    rows = []

    def record(reader, ranks, run, **extra):
        row = {"reader": reader, "ranks": ranks, **extra, **run}
        chunks = run["chunk_log"]
        if chunks:
            first = {}
            for c in chunks:  # each rank's first execution: its piece
                first.setdefault(c["rank"], c)
            row["chunks_decoded_per_rank"] = [first[k]["decoded"] for k in sorted(first)]
            row["read_s_per_rank"] = [first[k]["seconds"] for k in sorted(first)]
            row["read_cpu_s_per_rank"] = [first[k].get("cpu_seconds") for k in sorted(first)]
            row["executions"] = len(chunks)
            row["chunks_in_file"] = chunks[0]["chunks"]
            row["peak_rss_mib_before_read_per_rank"] = [first[k].get("peak_rss_mib_before") for k in sorted(first)]
            row["peak_rss_mib_after_read_per_rank"] = [first[k].get("peak_rss_mib_after") for k in sorted(first)]
            row["cache_peak_bytes_per_rank"] = [first[k]["cache_peak_bytes"] for k in sorted(first)]
        rows.append(row)
        print(json.dumps({k: v for k, v in row.items() if k != "chunk_log"}), flush=True)

    # both files in the page cache before the first timed run, so that neither reader is the one
    # that pays for the disk (the .vti's 3.5 GB at 1024^3 would otherwise)
    for path in (wvc, vti):
        with open(path, "rb") as f:
            while f.read(1 << 24):
                pass
    mode = a.volume_mode if a.volume_mode != "auto" else ("smart" if 4 * n ** 3 <= 1 << 30 else "raycast")
    for ranks in (1, 2):
        for rep in range(a.repeat if ranks == 1 else a.repeat2):  # interleaved: the load changes slowly
            for name, path in (("wvc", wvc), ("vti", vti)):
                record(name, ranks, run_pvbatch(path, ranks, run_dir(work, {"reader": name, "ranks": ranks,
                                                                            "repetition": rep}),
                                                 vmin, vmax, iso, a.budget, volume_mode=mode), repetition=rep)
    for ranks in ((1, 2) if a.lod else ()):
        record(f"wvc level {a.lod}", ranks, run_pvbatch(wvc, ranks, run_dir(work, {"ranks": ranks, "level": a.lod}),
                                                         vmin, vmax, iso, a.budget,
                                                         level=a.lod, volume_mode=mode), level=a.lod)
    result = {"machine": {"cpu": cpu_model(), "cores": os.cpu_count()}, "size": [n, n, n], "psnr": a.psnr,
              "reader_budget_mib": a.budget, "lod": a.lod, "quick": a.quick, "volume_mode": mode,
              "bytes": {"wvc": wvc.stat().st_size, "vti": vti.stat().st_size, "float32": 4 * n ** 3},
              "prepare_s": prep, "load_avg_1min": [load_start[0], os.getloadavg()[0]], "runs": rows,
              "wvc_info": info,
              "note": "pvbatch 5.11 (Debian) under Xvfb, software OpenGL; wall_s includes MPI and ParaView start-up"}
    report(result, out)
    if not a.keep:
        shutil.rmtree(work)


if __name__ == "__main__":
    main()
