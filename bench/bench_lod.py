#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Level of detail by screen size, and marching cubes from a store or a .wvc brick by brick.

In one run, on volumes made by `wvol synth` (the noisy skull phantom, sigma 20 HU, and the
Gaussian), each command in its own process:
  * marching cubes from a store against marching cubes on a dense volume, same iso-value, same
    thread count, alternated (rounds of one each, the fastest of each kept: the machine is
    shared): (a) from a 5% store in memory (`wvol iso VOL --wavelet db2 --levels 3 --keep 5%`,
    the bricks whose coefficient bound straddles theta) against dense MC on the original (the
    issue's yardstick; the surfaces differ by the 5% compression, triangle counts given); (b)
    from the .wvc at 45 dB (`wvol iso FILE.wvc`, the file-backed store: chunks decoded on
    demand) against dense MC on the file's decode (the same surface). The ratio per row; goal
    <= 2x the dense time;
  * the LOD frame: a 512^2 perspective frame of the skull's .wvc with level of detail (the
    default) and with --full-resolution: wall time and peak resident memory of the process
    (getrusage of the child, as bench/peak_rss.py), the level chosen, the reported extra error
    (the dropped levels' energy as RMSE and PSNR), and the measured image difference against
    the full-resolution frame (RMSE and max over the RGBA channels, relative to the full
    frame's largest channel value).
Writes bench/results/lod.json, lod.md and lod.png.

  python3 bench/bench_lod.py                       # MC at 256^3 and 512^3, frames of 512^3
  python3 bench/bench_lod.py --frame-sizes 512,1024
  python3 bench/bench_lod.py --quick               # 64^3 / 128^3: a smoke test
  python3 bench/bench_lod.py --mc-only             # the marching-cubes rows alone, into lod.json
"""
import argparse
import json
import os
import pathlib
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT / "tests" / "python"))
from bench_wvc2 import run  # noqa: E402  (one process runner: wall time, peak RSS, stdout)
from benchutil import cpu_model  # noqa: E402
from test_render import read_exr_rgba  # noqa: E402  (the reader of wvol's own EXR output)

WVOL = os.environ.get("WVOL_BIN", str(ROOT / "build" / "wvol"))
CAMERA = "persp dir=1,0.7,0.4"
ISO = {"skull": 400.0, "gaussian": 0.5}


def wvol(*args):
    return [WVOL, *map(str, args)]


def alternate(rounds, cmds, threads):
    """Runs the commands in turn, `rounds` times; per command the fastest run's parsed JSON."""
    best = [None] * len(cmds)
    for _ in range(rounds):
        for i, c in enumerate(cmds):
            _, _, out = run(c, threads)
            r = json.loads(out)
            if best[i] is None or r["seconds"]["extract"] < best[i]["seconds"]["extract"]:
                best[i] = r
    return best


def mc_rows(tmp, kind, n, threads, rounds):
    vol, wvc, dec = tmp / f"{kind}{n}.nrrd", tmp / f"{kind}{n}.wvc", tmp / f"{kind}{n}_dec.nrrd"
    extra = ["--noise", "20"] if kind == "skull" else []
    run(wvol("synth", kind, "--size", n, "-o", vol, *extra))
    run(wvol("compress", vol, "-o", wvc, "--psnr", 45))
    run(wvol("decompress", wvc, "-o", dec))
    iso = ISO[kind]
    common = ["--iso", iso, "--threads", threads, "--json"]
    dense, store = alternate(rounds, [wvol("iso", vol, *common),
                                      wvol("iso", vol, *common, "--wavelet", "db2", "--levels", 3, "--keep", "5%")],
                             threads)
    dense_dec, filemc, whole = alternate(rounds, [wvol("iso", dec, *common), wvol("iso", wvc, *common),
                                                  wvol("iso", wvc, *common, "--brick", 0)], threads)
    rows = []
    for source, b, d, peer in (("5% store", store, dense, "dense MC, original"),
                               (".wvc 45 dB", filemc, dense_dec, "dense MC, the decode")):
        rows.append({"phantom": kind, "n": n, "source": source, "peer": peer, "seconds": b["seconds"]["extract"],
                     "dense_seconds": d["seconds"]["extract"],
                     "ratio": b["seconds"]["extract"] / d["seconds"]["extract"], "triangles": b["triangles"],
                     "dense_triangles": d["triangles"], "bricks_total": b["bricks_total"],
                     "bricks_skipped": b["bricks_skipped"], "seconds_bounds": b.get("seconds_bounds")})
        if source.startswith(".wvc"):
            # what a user of the file pays otherwise: decode and reconstruct it whole, then dense MC
            rows[-1]["decode_mc_seconds"] = whole["seconds"]["load"] + whole["seconds"]["extract"]
            rows[-1]["ratio_decode_mc"] = b["seconds"]["extract"] / rows[-1]["decode_mc_seconds"]
        r = rows[-1]
        print(f"MC {kind} {n}^3 {source}: {r['seconds'] * 1e3:.1f} ms vs {r['dense_seconds'] * 1e3:.1f} ms "
              f"({r['ratio']:.2f}x), {r['bricks_skipped']}/{r['bricks_total']} bricks skipped"
              + (f"; decode whole + MC {r['decode_mc_seconds'] * 1e3:.1f} ms ({r['ratio_decode_mc']:.2f}x)"
                 if "decode_mc_seconds" in r else ""), flush=True)
    for p in (vol, dec):
        p.unlink()
    return rows, wvc


def frame_rows(tmp, n, size, wvc):
    rows = {}
    for name, extra in (("lod", []), ("full", ["--full-resolution"])):
        img = tmp / f"frame{n}_{name}.exr"
        wall, rss, out = run(wvol("render", wvc, "-o", img, "--size", f"{size}x{size}", "--camera", CAMERA, "--tf",
                                  "ct-bone", "--json", *extra))
        r = json.loads(out)
        rows[name] = {"wall_seconds": wall, "peak_rss_mib": rss, "render_seconds": r["render_seconds"],
                      "method": r["method"], "lod": r["lod"], "image": read_exr_rgba(img)}
        print(f"frame {n}^3 -> {size}^2 {name}: {wall:.2f} s, {rss:.0f} MiB, level {r['lod']['level']}, "
              f"{r['method']}", flush=True)
    a, b = rows["lod"].pop("image"), rows["full"].pop("image")
    peak = float(np.abs(b).max())
    lod = rows["lod"]["lod"]
    return {"n": n, "size": size, "camera": CAMERA, "file_bytes": wvc.stat().st_size, "lod": rows["lod"],
            "full": rows["full"], "level": lod["level"], "reported_rmse": lod["rmse"], "reported_psnr": lod["psnr"],
            "image_rmse_rel": float(np.sqrt(np.mean((a - b) ** 2))) / peak,
            "image_max_rel": float(np.abs(a - b).max()) / peak,
            "time_ratio": rows["lod"]["wall_seconds"] / rows["full"]["wall_seconds"],
            "rss_ratio": rows["lod"]["peak_rss_mib"] / rows["full"]["peak_rss_mib"]}


def file_rows(path, size, iso, mesh_level, full_timeout):
    """Rows for an existing large .wvc (the 2048^3 turbulence file of bench_large.py): the LOD
    frame (tf "gaussian" over the file's range), the full-resolution frame unless it runs past
    full_timeout seconds (then its absence is said), and marching cubes of the level-`mesh_level`
    grid; wall time and peak RSS of each process, the file store's default budget (1 GiB)."""
    rows = {"file": str(path), "size": size, "camera": CAMERA, "budget_mib": 1024}
    with tempfile.TemporaryDirectory(prefix="bench_lod_file_", dir=os.environ.get("BENCH_TMP")) as td:
        tmp = pathlib.Path(td)
        wall, rss, out = run(wvol("render", path, "-o", tmp / "lod.exr", "--size", f"{size}x{size}", "--camera",
                                  CAMERA, "--json"))
        r = json.loads(out)
        rows["lod"] = {"wall_seconds": wall, "peak_rss_mib": rss, "lod": r["lod"], "method": r["method"]}
        print(f"file frame lod: {wall:.1f} s, {rss:.0f} MiB, level {r['lod']['level']}", flush=True)
        try:
            wall, rss, out = run(["timeout", str(full_timeout)] + wvol("render", path, "-o", tmp / "full.exr", "--size",
                                                                       f"{size}x{size}", "--camera", CAMERA,
                                                                       "--json", "--full-resolution"))
            rows["full"] = {"wall_seconds": wall, "peak_rss_mib": rss}
            a, b = read_exr_rgba(tmp / "lod.exr"), read_exr_rgba(tmp / "full.exr")
            peak = float(np.abs(b).max())
            rows["image_rmse_rel"] = float(np.sqrt(np.mean((a - b) ** 2))) / peak
            rows["image_max_rel"] = float(np.abs(a - b).max()) / peak
        except SystemExit as e:
            rows["full"] = {"not_done": f"stopped after {full_timeout} s ({str(e).splitlines()[0][:80]})"}
        print(f"file frame full: {rows['full']}", flush=True)
        wall, rss, out = run(wvol("iso", path, "--iso", iso, "--level", mesh_level, "--json", "-o", tmp / "m.ply"))
        r = json.loads(out)
        rows["mesh"] = {"wall_seconds": wall, "peak_rss_mib": rss, "level": mesh_level, "iso": iso,
                        "dims": r["level_dims"], "triangles": r["triangles"], "level_seconds": r["level_seconds"]}
        print(f"file mesh: {rows['mesh']}", flush=True)
    return rows


def lod_vs_rows(path, peer, size, tf, rounds):
    """The issue's yardstick for a LOD frame of a large file: the same frame (camera, size,
    TF, one thread) of the same volume made at the grid the LOD picks (its own default,
    level 0 there), alternated `rounds` times, the fastest of each kept. CPU seconds and peak RSS
    are each process's own rusage (the machine is shared: the wall time counts other jobs)."""
    rows = {}
    with tempfile.TemporaryDirectory(prefix="bench_lod_vs_", dir=os.environ.get("BENCH_TMP")) as td:
        for _ in range(rounds):
            for name, f in (("file", path), ("peer", peer)):
                t0 = time.perf_counter()
                with tempfile.TemporaryFile(mode="w+") as errf:
                    p = subprocess.Popen(wvol("render", f, "-o", pathlib.Path(td) / f"{name}.exr", "--size",
                                              f"{size}x{size}", "--camera", CAMERA, "--tf", tf, "--threads", 1,
                                              "--json"), stdout=subprocess.PIPE, stderr=errf, text=True,
                                         env=dict(os.environ, OMP_NUM_THREADS="1"))
                    stdout = p.stdout.read()
                    _, status, ru = os.wait4(p.pid, 0)  # this child's own CPU time and peak RSS
                    wall = time.perf_counter() - t0
                    if os.waitstatus_to_exitcode(status) != 0:
                        errf.seek(0)
                        sys.exit(f"bench_lod: render {f} failed:\n{errf.read()}")
                r = json.loads(stdout)
                cpu = ru.ru_utime + ru.ru_stime
                e = {"file": str(f), "wall_seconds": wall, "cpu_seconds": cpu, "peak_rss_mib": ru.ru_maxrss / 1024.0,
                     "lod": r["lod"], "method": r["method"], "render_seconds": r["render_seconds"]}
                if name not in rows or cpu < rows[name]["cpu_seconds"]:
                    rows[name] = e
                print(f"{name}: {f}: {wall:.1f} s wall, {cpu:.2f} s CPU, level {r['lod']['level']}", flush=True)
    return {"size": size, "camera": CAMERA, "tf": tf, "rounds": rounds, "file": rows["file"], "peer": rows["peer"],
            "cpu_ratio": rows["file"]["cpu_seconds"] / rows["peer"]["cpu_seconds"],
            "load_at_end": os.getloadavg()[0]}


def write_md(res, path):
    L = ["# Level of detail and marching cubes from a store (bench/bench_lod.py)", "",
         f"Machine: {res['machine']}, {res['cores']} cores shared with other jobs; wvol {res['wvol']}.", "",
         f"Marching cubes, {res['threads']} thread(s), fastest of {res['rounds']} alternated rounds "
         "(extract time as `wvol iso --json` reports it; the .wvc rows include decoding the chunks)"
         + (f", load average {res['mc_load_at_start']:.1f} at start and {res['mc_load_at_end']:.1f} at end"
            if "mc_load_at_start" in res else "") + ":", "",
         "| phantom | size | source | ms | peer | peer ms | ratio | decode whole + MC ms (ratio) | triangles (peer) | bricks skipped | bounds ms |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in res["mc"]:
        b = "-" if r["seconds_bounds"] is None else f"{r['seconds_bounds'] * 1e3:.1f}"
        dm = (f"{r['decode_mc_seconds'] * 1e3:.1f} ({r['ratio_decode_mc']:.2f}x)" if "decode_mc_seconds" in r
              else "-")
        L.append(f"| {r['phantom']} | {r['n']}^3 | {r['source']} | {r['seconds'] * 1e3:.1f} | {r['peer']} | "
                 f"{r['dense_seconds'] * 1e3:.1f} | {r['ratio']:.2f}x | {dm} | {r['triangles']} ({r['dense_triangles']}) | "
                 f"{r['bricks_skipped']}/{r['bricks_total']} | {b} |")
    L += ["", f"Frames: {res['frames'][0]['size'] if res['frames'] else '-'}^2, camera `{CAMERA}`, ct-bone, the "
          "noisy skull's .wvc at 45 dB; wall time and peak RSS of the whole `wvol render` process:", "",
          "| volume | level | LOD s | full s | time ratio | LOD MiB | full MiB | reported RMSE (PSNR) | image RMSE / max (rel.) |",
          "|---|---|---|---|---|---|---|---|---|"]
    for f in res["frames"]:
        psnr = "inf" if f["reported_psnr"] is None else f"{f['reported_psnr']:.1f}"
        L.append(f"| {f['n']}^3 | {f['level']} | {f['lod']['wall_seconds']:.2f} | {f['full']['wall_seconds']:.2f} | "
                 f"{f['time_ratio']:.2f} | {f['lod']['peak_rss_mib']:.0f} | {f['full']['peak_rss_mib']:.0f} | "
                 f"{f['reported_rmse']:.3g} ({psnr} dB) | "
                 f"{f['image_rmse_rel']:.2e} / {f['image_max_rel']:.2e} |")
    L += ["", "The reported error is the volume's (the dropped detail levels' energy, RMSE over the voxels, PSNR "
          "over the data range); the image difference is measured against the full-resolution frame.",
          "A 512^2 perspective frame framing the volume sees a 512^3 volume at about one voxel a pixel at its "
          "nearest point, so level 0 is chosen there: the LOD row is then the full frame.",
          res.get("note", "")]
    for f in res.get("files", []):
        full = f["full"]
        fs = (f"{full['wall_seconds']:.1f} s, {full['peak_rss_mib']:.0f} MiB; image RMSE / max (rel.) "
              f"{f['image_rmse_rel']:.2e} / {f['image_max_rel']:.2e}" if "wall_seconds" in full else full["not_done"])
        m, lod = f["mesh"], f["lod"]["lod"]
        L += ["", f"From `{f['file']}` (file store, budget {f['budget_mib']} MiB), {f['size']}^2 frame, camera "
              f"`{f['camera']}`, tf gaussian:", "",
              f"- LOD frame: level {lod['level']} of {lod['levels']} ({lod['dims'][0]}^3 grid), "
              f"{f['lod']['wall_seconds']:.1f} s, peak RSS {f['lod']['peak_rss_mib']:.0f} MiB, reported RMSE "
              f"{lod['rmse']:.3g} (PSNR {lod['psnr']:.1f} dB)",
              f"- full-resolution frame: {fs}",
              f"- marching cubes at level {m['level']} ({m['dims'][0]}^3 grid, iso {m['iso']}): {m['triangles']} "
              f"triangles, {m['wall_seconds']:.1f} s, peak RSS {m['peak_rss_mib']:.0f} MiB"]
        g = f.get("region_mesh")
        if g:
            L.append(f"- a full-resolution 256^3 region {g['roi']} ({g['how']}): {g['chunks_decoded']} of "
                     f"{g['file_chunks']} chunks decoded in {g['decode_seconds']:.1f} s, peak RSS "
                     f"{g['decode_peak_rss_mib']:.0f} MiB; marching cubes {g['triangles']} triangles in "
                     f"{g['mc_seconds']:.1f} s, {g['mc_peak_rss_mib']:.0f} MiB (wall times of the processes)")
        L.append(f.get("note", ""))
    for v in res.get("lod_vs", []):
        a, b = v["file"], v["peer"]
        L += ["", f"LOD frame of `{a['file']}` against the same frame of `{b['file']}` (the same volume made at "
              f"{b['lod']['dims'][0]}^3, its own default level {b['lod']['level']}): {v['size']}^2, camera "
              f"`{v['camera']}`, tf {v['tf']}, one thread, {v['rounds']} alternated rounds, the fastest of each by CPU "
              "seconds (the processes' user + system time; the machine is shared, load average "
              f"{v['load_at_end']:.1f} at the end):", "",
              "| file | level | grid | method | CPU s | wall s | peak RSS MiB |", "|---|---|---|---|---|---|---|"]
        for e in (a, b):
            L.append(f"| `{pathlib.Path(e['file']).name}` | {e['lod']['level']} | {e['lod']['dims'][0]}^3 | "
                     f"{e['method']} | {e['cpu_seconds']:.2f} | {e['wall_seconds']:.1f} | {e['peak_rss_mib']:.0f} |")
        L += ["", f"CPU time ratio (LOD frame / same-grid frame): {v['cpu_ratio']:.2f} (the issue's goal: <= 2)."]
    path.write_text("\n".join(L) + "\n")


def plot(res, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    labels = [f"{r['phantom']} {r['n']}\n{r['source']}" for r in res["mc"]]
    ax[0].bar(range(len(labels)), [r["ratio"] for r in res["mc"]], color="C0")
    ax[0].axhline(2.0, color="C3", ls="--", label="goal: 2x dense MC")
    ax[0].set_xticks(range(len(labels)), labels, fontsize=7)
    ax[0].set_ylabel("time / dense marching cubes")
    ax[0].set_title("marching cubes brick by brick")
    ax[0].legend()
    fr = res["frames"]
    x = np.arange(len(fr))
    ax[1].bar(x - 0.2, [f["lod"]["wall_seconds"] for f in fr], 0.4, label="level of detail")
    ax[1].bar(x + 0.2, [f["full"]["wall_seconds"] for f in fr], 0.4, label="--full-resolution")
    ax[1].set_xticks(x, [f"{f['n']}^3 (level {f['level']})" for f in fr])
    ax[1].set_ylabel("wall seconds, 512^2 frame from the .wvc")
    ax[1].set_title("LOD frame")
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--mc-sizes", default="256,512")
    ap.add_argument("--frame-sizes", default="512")
    ap.add_argument("--image", type=int, default=512)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results"))
    ap.add_argument("--replot", action="store_true", help="rewrite the .md and .png from the .json only")
    ap.add_argument("--mc-only", action="store_true",
                    help="only the marching-cubes rows (--mc-sizes), replacing those of the existing .json")
    ap.add_argument("--wvc", help="add rows for this existing .wvc to the .json (frames and a level mesh)")
    ap.add_argument("--lod-vs", nargs=2, metavar=("LARGE.wvc", "SAME_VOLUME_512.wvc"),
                    help="add the LOD frame of LARGE against the same frame of the volume made at the LOD's grid")
    ap.add_argument("--tf", default="ct-bone", help="--lod-vs: the transfer function")
    ap.add_argument("--iso", type=float, default=1.0, help="--wvc: the mesh's iso-value")
    ap.add_argument("--mesh-level", type=int, default=3, help="--wvc: the mesh's level")
    ap.add_argument("--full-timeout", type=int, default=900, help="--wvc: stop the full-resolution frame after this")
    args = ap.parse_args()
    if args.lod_vs:
        out, name = pathlib.Path(args.out), "lod_quick" if args.quick else "lod"
        res = json.loads((out / f"{name}.json").read_text())
        res.setdefault("lod_vs", []).append(lod_vs_rows(pathlib.Path(args.lod_vs[0]), pathlib.Path(args.lod_vs[1]),
                                                        args.image, args.tf, args.rounds))
        (out / f"{name}.json").write_text(json.dumps(res, indent=1) + "\n")
        args.replot = True
    if args.wvc:
        out, name = pathlib.Path(args.out), "lod_quick" if args.quick else "lod"
        res = json.loads((out / f"{name}.json").read_text())
        res.setdefault("files", []).append(file_rows(pathlib.Path(args.wvc), args.image, args.iso, args.mesh_level,
                                                     args.full_timeout))
        (out / f"{name}.json").write_text(json.dumps(res, indent=1) + "\n")
        args.replot = True
    if args.replot:
        out, name = pathlib.Path(args.out), "lod_quick" if args.quick else "lod"
        res = json.loads((out / f"{name}.json").read_text())
        write_md(res, out / f"{name}.md")
        plot(res, out / f"{name}.png")
        return
    if args.mc_only:
        out, name = pathlib.Path(args.out), "lod_quick" if args.quick else "lod"
        res = json.loads((out / f"{name}.json").read_text())
        res.update({"threads": args.threads, "rounds": args.rounds, "mc_load_at_start": os.getloadavg()[0],
                    "wvol": run(wvol("--version"))[2].strip(), "mc": []})
        with tempfile.TemporaryDirectory(prefix="bench_lod_", dir=os.environ.get("BENCH_TMP")) as td:
            for n in [64] if args.quick else [int(x) for x in args.mc_sizes.split(",") if x]:
                for kind in ("gaussian", "skull"):
                    rows, wvc = mc_rows(pathlib.Path(td), kind, n, args.threads, args.rounds)
                    res["mc"] += rows
                    wvc.unlink()
        res["mc_load_at_end"] = os.getloadavg()[0]
        (out / f"{name}.json").write_text(json.dumps(res, indent=1) + "\n")
        write_md(res, out / f"{name}.md")
        plot(res, out / f"{name}.png")
        return
    mc_sizes = [64] if args.quick else [int(s) for s in args.mc_sizes.split(",") if s]
    frame_sizes = [128] if args.quick else [int(s) for s in args.frame_sizes.split(",") if s]
    image = 64 if args.quick else args.image
    out = pathlib.Path(args.out)
    name = "lod_quick" if args.quick else "lod"
    res = {"machine": f"{cpu_model()} ({platform.machine()})", "cores": os.cpu_count(),
           "wvol": run(wvol("--version"))[2].strip(), "threads": args.threads, "rounds": args.rounds,
           "load_at_start": os.getloadavg()[0], "mc": [], "frames": []}
    with tempfile.TemporaryDirectory(prefix="bench_lod_", dir=os.environ.get("BENCH_TMP")) as td:
        tmp = pathlib.Path(td)
        wvcs = {}
        for n in sorted(set(mc_sizes) | set(frame_sizes)):
            for kind in ("gaussian", "skull"):
                if n not in mc_sizes and kind != "skull":
                    continue
                if n in mc_sizes:
                    rows, wvc = mc_rows(tmp, kind, n, args.threads, args.rounds)
                    res["mc"] += rows
                else:
                    vol, wvc = tmp / f"skull{n}.nrrd", tmp / f"skull{n}.wvc"
                    run(wvol("synth", "skull", "--size", n, "--noise", 20, "-o", vol))
                    run(wvol("compress", vol, "-o", wvc, "--psnr", 45))
                    vol.unlink()
                if kind == "skull":
                    wvcs[n] = wvc
            if n in frame_sizes:
                res["frames"].append(frame_rows(tmp, n, image, wvcs[n]))
    res["load_at_end"] = os.getloadavg()[0]
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(res, indent=1) + "\n")
    write_md(res, out / f"{name}.md")
    plot(res, out / f"{name}.png")
    print(f"wrote {out / name}.json, .md, .png")


if __name__ == "__main__":
    main()
