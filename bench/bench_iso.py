#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Isosurface benchmark: marching cubes on one float32 volume (default 256^3: the
paper's Gaussian and a skull-like CT phantom) by libwvol, VTK's vtkFlyingEdges3D
and vtkMarchingCubes, scikit-image's marching_cubes and OpenVDB's volumeToMesh,
with 1 and 2 threads, in the same run (time, triangles, area); then marching cubes
from kept wavelet coefficients brick by brick (bricks skipped, against a full
reconstruction followed by dense marching cubes).

Every timing is the fastest of --reps runs of the extraction alone (the volume is
already in memory; file I/O excluded). Thread counts are enforced with CPU
affinity (taskset) for every tool, and with the tool's own knob where it has one
(wvol --threads, vtkSMPTools.Initialize). Normals: wvol, vtkFlyingEdges3D,
vtkMarchingCubes and scikit-image compute vertex normals; OpenVDB does not.

Ray tracer rows: `wvol iso --method raytrace` (the implicit surface f^ = iso of the
wavelet model, db2, 3 levels, from a store of the kept coefficients; no peer draws
that surface) on both phantoms for kept fractions 1%, 5% and 100%, an image of
--rt-size pixels (default 512x512) with --rt-threads threads (default 2): trace time,
time per ray (wall clock / rays), hits, basis functions and polynomial pieces per ray. `--raytrace-only`
runs just these rows and merges them into an existing iso.json / iso.md.

Brick rows alone (`--bricks-only 256,512`): at each size, per phantom, the brick path from a
store (haar 5%, db2 5%, db2 100%, 3 levels) against wvol's dense marching cubes on the original
volume and against the full inverse transform + dense MC, the commands alternated over --rounds
processes (each the fastest of --reps extractions in one process, wall clock and process CPU
seconds; the first builds the store's block view and bounds, which the later ones reuse), with
the ratio to dense MC (goal <= 2x); `--bricks-baseline PROGRAM` runs another wvol's brick path
and dense MC (e.g. main's) alternated with this build's; merged into the existing iso.json /
iso.md (the brick-path section only); --raytrace-only its ray tracer table and baseline line.

Goal (issue 6): wvol at least as fast as vtkFlyingEdges3D at the same thread count.
Writes bench/results/iso.json and bench/results/iso.md.
Image routes (`--cast`, bench/iso_cast.py): the bricked caster (wvol iso --method cast) against
marching cubes + Embree, VTK's first offscreen frame of the same mesh, OpenVDB's level set +
vdb_render and the exact f^ tracer, same camera and iso-value; bench/results/iso_cast.{json,md,png}.

Usage: /usr/bin/python3 bench/bench_iso.py [--n 256] [--reps 5] [--build build] [--quick]
       /usr/bin/python3 bench/bench_iso.py --cast [--quick]
       /usr/bin/python3 bench/bench_iso.py --raytrace-only [--rt-size 512x512] [--rt-keep 1%,5%,100%]
       /usr/bin/python3 bench/bench_iso.py --bricks-only 256,512 --threads 1 [--reps 5] [--rounds 2]
                                           [--bricks-baseline /path/to/main/wvol]
"""
import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from benchutil import cpu_model  # noqa: E402

PEER = r'''
import sys, time, json
import numpy as np
tool, path, n, iso, threads, reps = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5]), int(sys.argv[6])
f = np.fromfile(path, dtype=np.float32).reshape(n, n, n)  # [k, j, i]
def area(v, t):
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())
best = float("inf")
if tool in ("vtkFlyingEdges3D", "vtkMarchingCubes"):
    import vtk
    from vtk.util import numpy_support as ns
    vtk.vtkSMPTools.Initialize(threads)
    img = vtk.vtkImageData(); img.SetDimensions(n, n, n)
    arr = ns.numpy_to_vtk(f.ravel(), deep=1); img.GetPointData().SetScalars(arr)
    for _ in range(reps):
        fl = getattr(vtk, tool)(); fl.SetInputData(img); fl.SetValue(0, iso); fl.ComputeNormalsOn()
        t = time.perf_counter(); fl.Update(); best = min(best, time.perf_counter() - t)
    out = fl.GetOutput()
    v = ns.vtk_to_numpy(out.GetPoints().GetData()).astype(np.float64)
    tri = ns.vtk_to_numpy(out.GetPolys().GetConnectivityArray()).reshape(-1, 3)
elif tool == "skimage":
    from skimage import measure
    g = np.ascontiguousarray(f.transpose(2, 1, 0))
    for _ in range(reps):
        t = time.perf_counter(); v, tri, nrm, val = measure.marching_cubes(g, level=iso); best = min(best, time.perf_counter() - t)
elif tool == "openvdb":
    import pyopenvdb as vdb
    g = vdb.FloatGrid(background=float(f.min()) - 1.0)
    g.copyFromArray(np.ascontiguousarray(f.transpose(2, 1, 0)))  # copyFromArray ignores strides
    for _ in range(reps):
        t = time.perf_counter(); pts, tris, quads = g.convertToPolygons(isovalue=iso, adaptivity=0.0); best = min(best, time.perf_counter() - t)
    q = np.asarray(quads).reshape(-1, 4)
    tri = np.concatenate([np.asarray(tris).reshape(-1, 3), q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    v = np.asarray(pts, dtype=np.float64)
print(json.dumps({"seconds": best, "triangles": int(len(tri)), "area": area(np.asarray(v, np.float64), np.asarray(tri))}))
'''




def cpus(threads):
    return ",".join(str(i) for i in range(threads))


def gaussian(n):
    x = (np.arange(n) - (n - 1) / 2) / (n / 2)
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    return np.exp(-(X ** 2 + Y ** 2 + Z ** 2) / (2 * 0.25 ** 2)).astype(np.float32)


def skull(n, seed=7):
    """Skull-like CT phantom in HU (array [i, j, k]): air, skin, a bone shell of
    varying thickness with a textured diploe, brain, ventricles, orbits and
    sinuses as air pockets in the bone, additive noise."""
    rng = np.random.default_rng(seed)
    u = (np.arange(n) - (n - 1) / 2) / (n / 2)
    X, Y, Z = np.meshgrid(u, u, u, indexing="ij")
    r_head = np.sqrt((X / 0.78) ** 2 + (Y / 0.9) ** 2 + (Z / 0.85) ** 2)
    f = np.full((n, n, n), -1000.0, dtype=np.float32)
    f[r_head < 1.0] = 40.0
    thick = 0.07 + 0.03 * np.sin(5 * np.arctan2(Y, X)) * np.cos(3 * Z)
    bone = (r_head < 0.94) & (r_head > 0.94 - thick)
    tex = np.cos(40 * X) * np.cos(37 * Y) * np.cos(43 * Z)
    f[bone] = (1200 + 400 * tex)[bone]
    jaw = (np.sqrt((X / 0.55) ** 2 + ((Y + 0.55) / 0.25) ** 2 + ((Z + 0.45) / 0.2) ** 2) < 1.0) & (Y < -0.4)
    f[jaw] = 1100.0
    for cx in (-0.3, 0.3):  # orbits
        f[np.sqrt((X - cx) ** 2 + (Y + 0.7) ** 2 + (Z - 0.05) ** 2) < 0.15] = -1000.0
    vent = np.sqrt((X / 0.15) ** 2 + (Y / 0.3) ** 2 + ((Z - 0.1) / 0.12) ** 2) < 1.0
    f[vent] = 8.0
    f += rng.normal(0, 20, f.shape).astype(np.float32)
    return f


def write_raw(path, f):
    np.ascontiguousarray(f.transpose(2, 1, 0)).tofile(path)


def run_peer(tool, raw, n, iso, threads, reps):
    cmd = ["taskset", "-c", cpus(threads), sys.executable, "-c", PEER, tool, str(raw), str(n), str(iso),
           str(threads), str(reps)]
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), TBB_NUM_THREADS=str(threads))
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=3600)
    if p.returncode != 0:
        return {"error": p.stderr.strip().splitlines()[-1] if p.stderr.strip() else "failed"}
    return json.loads(p.stdout.strip().splitlines()[-1])


def run_wvol(build, raw, n, iso, threads, reps, extra=(), program=None):
    """One `wvol iso` process (program, else build/wvol); "cpu": its user + system CPU seconds."""
    cmd = ["taskset", "-c", cpus(threads), program or str(pathlib.Path(build) / "wvol"), "iso", str(raw), "--dims",
           str(n), "--iso", str(iso), "--threads", str(threads), "--repeat", str(reps), "--json", *extra]
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, text=True)
        _, status, ru = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read(), err.read()
    if proc.returncode != 0:
        return {"error": stderr.strip()}
    r = json.loads(stdout)
    r["cpu"] = ru.ru_utime + ru.ru_stime
    r["seconds_first"] = r["seconds"].get("extract_first", r["seconds"]["extract"])
    if "extract_cpu" in r["seconds"]:  # this build's CLI; a baseline program may predate it
        r["cpu_extract"], r["cpu_first"] = r["seconds"]["extract_cpu"], r["seconds"]["extract_first_cpu"]
    r["seconds"] = r["seconds"]["extract"]
    return r


def full_reconstruction_seconds(raw, n, wavelet, levels, keep, iso, threads, build):
    """Peer of the brick path: the library's (vectorised) inverse transform of the
    whole volume, then dense marching cubes (wvol iso --brick 0)."""
    return run_wvol(build, raw, n, iso, threads, 1,
                    ["--wavelet", wavelet, "--levels", str(levels), "--keep", keep, "--brick", "0"])


def run_raytrace(build, raw, n, iso, keep, size, threads, out_image, program=None):
    prog = program or str(pathlib.Path(build) / "wvol")
    cmd = ["taskset", "-c", cpus(threads), prog, "iso", str(raw), "--dims", str(n),
           "--iso", str(iso), "--method", "raytrace", "--keep", keep, "--size", size, "--threads", str(threads),
           "--camera", RT_CAMERA, "-o", str(out_image), "--json"]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=7200)
    if p.returncode != 0:
        return {"error": p.stderr.strip()}
    return json.loads(p.stdout)


RT_CAMERA = "persp dir=1,0.6,-0.3"
RT_KEYS = ("trace_seconds", "trace_cpu_seconds", "cells_seconds", "us_per_ray", "prepare_seconds", "rays", "hits",
           "functions", "pieces", "refined", "intervals", "evals", "grazes", "message", "error")


def same_image(a_path, b_path):
    """Hit masks and depths (EXR Z) of two tracer images: pixels hit by one only, and the
    largest depth difference where both hit."""
    from bench_render import read_exr
    za, zb = read_exr(a_path)["Z"], read_exr(b_path)["Z"]
    ha, hb = np.isfinite(za) & (za < 1e30), np.isfinite(zb) & (zb < 1e30)
    both = ha & hb
    d = np.abs(za[both] - zb[both])
    return {"mask_diff": int((ha != hb).sum()), "depth_max_diff": float(d.max()) if d.size else 0.0}


def raytrace_rows(args, phantoms, tmp):
    """The tracer's rows; with --rt-baseline, that program traces the same image first in the
    same run (its time, the ratio, and whether the images agree)."""
    rows = []
    for name, (f, iso) in phantoms.items():
        raw = pathlib.Path(tmp) / f"{name}.raw"
        if not raw.exists():
            write_raw(raw, f)
        for keep in args.rt_keep.split(","):
            size = args.rt_size
            for entry in args.rt_size_override.split(","):
                if entry and entry.split("=")[0] == f"{name}:{keep}":
                    size = entry.split("=")[1]
            base = None
            if args.rt_baseline:
                base_img = pathlib.Path(tmp) / f"{name}_{keep.rstrip('%')}_base.exr"
                base = run_raytrace(args.build, raw, args.n, iso, keep, size, args.rt_threads, base_img,
                                    program=args.rt_baseline)
            img = pathlib.Path(tmp) / f"{name}_{keep.rstrip('%')}.exr"
            r = run_raytrace(args.build, raw, args.n, iso, keep, size, args.rt_threads, img)
            row = {"phantom": name, "iso": iso, "keep": keep, "size": size, "threads": args.rt_threads,
                   "camera": RT_CAMERA}
            row.update({k: r[k] for k in RT_KEYS if k in r})
            if base is not None:
                row["baseline"] = {k: base[k] for k in RT_KEYS if k in base}
                if "error" not in base and "error" not in r:
                    row["ratio"] = base["trace_seconds"] / r["trace_seconds"]
                    row["cpu_ratio"] = base["trace_cpu_seconds"] / r["trace_cpu_seconds"]
                    row["vs_baseline"] = same_image(img, base_img)
            rows.append(row)
            print(f"{name:8s} raytrace keep {keep:5s} {size}: {r.get('trace_seconds', float('nan')):.2f} s, "
                  f"{r.get('us_per_ray', float('nan')):.1f} us/ray, {r.get('hits')} hits, "
                  f"{(r.get('functions') or 0) / max(1, r.get('rays') or 1):.0f} functions/ray"
                  + (f"; baseline {base.get('trace_seconds', float('nan')):.2f} s, ratio {row.get('ratio', float('nan')):.2f}x"
                     f" (CPU {row.get('cpu_ratio', float('nan')):.2f}x), {row.get('vs_baseline')}" if base else ""),
                  flush=True)
    return rows


def brick_rows(args, raw, name, n, iso, t):
    """The brick path's rows for one volume: per (wavelet, keep) the brick path from a store,
    dense MC on the original and the full inverse + MC, alternated over args.rounds processes
    (each the fastest of args.reps extractions), the fastest of each kept; with
    --bricks-baseline, that program's brick path and dense MC too, alternated with ours."""
    cases = [("haar", "5%"), ("db2", "5%"), ("db2", "100%")]
    cmds = [("dense", [])] + [(f"bricks {w} {k}", ["--wavelet", w, "--levels", "3", "--keep", k]) for w, k in cases]
    progs = [("", None)] + ([("base ", args.bricks_baseline)] if args.bricks_baseline else [])
    best = {}

    def keep_best(key, r):
        """The fastest process's fields; the CPU seconds, fastest and first, the least over the rounds."""
        old = best.get(key, {})
        if key not in best or ("seconds" in r and r["seconds"] < old.get("seconds", float("inf"))):
            best[key] = dict(r)
        for k in ("cpu_extract", "cpu_first"):
            if k in r or k in old:
                best[key][k] = min(r.get(k, float("inf")), old.get(k, float("inf")))

    for _ in range(args.rounds):
        for key, extra in cmds:
            for tag, prog in progs:
                keep_best(tag + key, run_wvol(args.build, raw, n, iso, t, args.reps, extra, prog))
        for w, k in cases:
            keep_best(f"full {w} {k}", run_wvol(args.build, raw, n, iso, t, args.reps,
                                                ["--wavelet", w, "--levels", "3", "--keep", k, "--brick", "0"]))
    rows = []
    for w, k in cases:
        b, full, dense = best[f"bricks {w} {k}"], best[f"full {w} {k}"], best["dense"]
        e = {"phantom": name, "n": n, "wavelet": w, "keep": k, "threads": t,
             "dense_seconds": dense.get("seconds"), "dense_triangles": dense.get("triangles"),
             "dense_seconds_first": dense.get("seconds_first"), "dense_cpu_seconds": dense.get("cpu_extract"),
             "one_brick_seconds": full.get("seconds")}
        for key in ("seconds", "seconds_first", "triangles", "area", "bricks_total", "bricks_skipped",
                    "seconds_bounds", "seconds_reconstruct_mesh", "error"):
            if key in b:
                e[key] = b[key]
        e["cpu_seconds"], e["cpu_seconds_first"] = b.get("cpu_extract"), b.get("cpu_first")
        e["dense_cpu_seconds_first"] = dense.get("cpu_first")
        if args.bricks_baseline:
            bb, bd = best[f"base bricks {w} {k}"], best["base dense"]
            e["baseline"] = {"seconds": bb.get("seconds"), "seconds_first": bb.get("seconds_first"),
                             "triangles": bb.get("triangles"), "bricks_skipped": bb.get("bricks_skipped"),
                             "dense_seconds": bd.get("seconds"), "dense_seconds_first": bd.get("seconds_first"),
                             "cpu_seconds": bb.get("cpu_extract"), "cpu_seconds_first": bb.get("cpu_first"),
                             "dense_cpu_seconds": bd.get("cpu_extract"), "dense_cpu_seconds_first": bd.get("cpu_first"),
                             "error": bb.get("error")}
        rows.append(e)
        print(f"{name:8s} {n}^3 bricks {w} {k}: {e.get('seconds', float('nan')) * 1e3:.1f} ms vs dense MC "
              f"{(e['dense_seconds'] or float('nan')) * 1e3:.1f} ms, {e.get('bricks_skipped')} of "
              f"{e.get('bricks_total')} skipped; full inverse + MC {(e['one_brick_seconds'] or float('nan')) * 1e3:.1f} ms",
              flush=True)
    return rows


def splice_section(old, new, head, table=True):
    """old with its section starting at the line beginning with head (that line, a blank line and
    the table after it; with table=False that line alone) replaced by new's; old as it is if
    either lacks it."""
    def bounds(lines):
        s = next((i for i, l in enumerate(lines) if l.startswith(head)), None)
        if s is None:
            return None
        if not table:
            return s, s + 1
        e = s + 2
        while e < len(lines) and lines[e].startswith("|"):
            e += 1
        return s, e
    ol, nl = old.split("\n"), new.split("\n")
    ob, nb = bounds(ol), bounds(nl)
    if not ob or not nb:
        return old
    return "\n".join(ol[:ob[0]] + nl[nb[0]:nb[1]] + ol[ob[1]:])


def write_md(res, out, name, tools):
    n = res["n"]
    lines = [f"# Isosurface benchmark ({n}^3, fastest of {res['reps']}, {res['machine']['cpu']}, "
             f"{res['machine']['cores']} cores, load average {res['machine']['load_avg_start']:.1f} at start)", "",
             "| phantom | threads | tool | ms | triangles | area | wvol speed-up |", "|---|---|---|---|---|---|---|"]
    for row in res["mc"]:
        for tool in ["wvol"] + tools:
            r = row[tool]
            if "error" in r:
                lines.append(f"| {row['phantom']} | {row['threads']} | {tool} | error: {r['error']} | | | |")
                continue
            sp = (r["seconds"] / row["wvol"]["seconds"]) if row["wvol"].get("seconds") else float("nan")
            lines.append(f"| {row['phantom']} | {row['threads']} | {tool} | {r['seconds'] * 1e3:.2f} | "
                         f"{r['triangles']} | {r['area']:.1f} | {sp:.2f}x |")
    bl = res.get("bricks_run", {})
    base = bl.get("baseline")
    lines += ["", "Brick path (marching cubes from kept coefficients, 3 levels, 32^3-cell bricks"
              + (f"; {bl['threads']} thread(s), {bl['rounds']} alternated rounds of processes, load average "
                 f"{bl['load_avg_start']:.1f} at start, {bl['load_avg_end']:.1f} at end" if bl else "")
              + "). Dense MC = wvol's marching cubes on the original volume in memory, same run and threads; "
              "ratio = brick path / dense MC (the goal: <= 2x). ms: the fastest of "
              f"{bl.get('reps', '?')} extractions in a process, wall clock; after the first they read the store's "
              "block view and brick bounds as the store keeps them. CPU ms: the least process CPU seconds of an "
              "extraction (`wvol iso --json`'s extract_cpu), which the machine's other tenants disturb far less "
              "than the wall clock; both the least over the rounds. first: the process's first extraction, which "
              "makes the view and the bounds (against dense MC's first). bounds = the view and the bricks' bounds "
              "in the fastest extraction; full inverse + MC = the whole inverse transform then dense MC"
              + (f"; main = {base}, run alternated with this build in the same rounds (main CPU ms and its "
                 "ratios in CPU seconds where its CLI reports them, else wall clock; this / main = this CPU ms / "
                 "main CPU ms)"
                 if base else "") + ":", "",
              "| phantom | size | wavelet | keep | ms | dense MC ms | ratio | CPU ms | dense MC CPU ms | CPU ratio "
              "| first ms | dense first ms | first ratio | first CPU ratio | bricks skipped | bounds ms "
              "| reconstruct+mesh ms | full inverse + MC ms |"
              + (" main CPU ms | main dense MC CPU ms | main ratio | main first ratio | this / main | "
                 "same triangles as main |" if base else ""),
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|" + ("---|" * 6 if base else "")]

    def ratio(a, b):
        return f"{a / b:.2f}x" if a and b else "-"

    def ms(x):
        return f"{x * 1e3:.1f}" if x else "-"

    for e in res["bricks"]:
        if "error" in e:
            lines.append(f"| {e['phantom']} | {e.get('n', n)}^3 | {e['wavelet']} | {e['keep']} | error: {e['error']} "
                         "|" + " |" * (13 + (5 if base else 0)))
            continue
        dense, dcpu = e.get("dense_seconds"), e.get("dense_cpu_seconds")
        first, dfirst = e.get("seconds_first"), e.get("dense_seconds_first")
        row = (f"| {e['phantom']} | {e.get('n', n)}^3 | {e['wavelet']} | {e['keep']} | {ms(e['seconds'])} | "
               f"{ms(dense)} | {ratio(e['seconds'], dense)} | {ms(e.get('cpu_seconds'))} | {ms(dcpu)} | "
               f"{ratio(e.get('cpu_seconds'), dcpu)} | {ms(first)} | {ms(dfirst)} | {ratio(first, dfirst)} | "
               f"{ratio(e.get('cpu_seconds_first'), e.get('dense_cpu_seconds_first'))} | "
               f"{e['bricks_skipped']}/{e['bricks_total']} | {ms(e['seconds_bounds'])} | "
               f"{ms(e['seconds_reconstruct_mesh'])} | {ms(e['one_brick_seconds'])} |")
        if base:
            b = e.get("baseline") or {}
            cpu = b.get("cpu_seconds") is not None and e.get("cpu_seconds") is not None
            bs, bd = (b.get("cpu_seconds"), b.get("dense_cpu_seconds")) if cpu else (b.get("seconds"), b.get("dense_seconds"))
            bf, bdf = ((b.get("cpu_seconds_first"), b.get("dense_cpu_seconds_first")) if cpu
                       else (b.get("seconds_first"), b.get("dense_seconds_first")))
            mine = e.get("cpu_seconds") if cpu else e.get("seconds")
            row += (f" {ms(bs)} | {ms(bd)} | {ratio(bs, bd)} | {ratio(bf, bdf)} | "
                    f"{f'{mine / bs:.3f}' if mine and bs else '-'} | "
                    f"{'yes' if b.get('triangles') == e.get('triangles') else 'NO'} |")
        lines.append(row)
    if res.get("raytrace"):
        rt = res["raytrace"]
        lines += ["", f"Ray tracer (`wvol iso --method raytrace`, f^ = iso of db2 with 3 levels from a store, camera "
                      f"\"{rt[0]['camera']}\", {rt[0]['threads']} threads; load average "
                      f"{res.get('raytrace_load_avg', float('nan')):.1f} at start). Time is the whole trace "
                      f"including the cell grid; the no-missed-hit guarantee is docs/iso.md's, tested in "
                      f"tests/c/test_iso_trace.c:", "",
                  *([res["raytrace_note"], ""] if res.get("raytrace_note") else []),
                  "| phantom | keep | image | trace s | trace CPU s | cells thread-s | us per ray | hits | "
                  "functions per ray | pieces per ray | refined per ray | root intervals | grazes | baseline trace s "
                  "(CPU s) | ratio (CPU) | same image |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in rt:
            if "error" in r:
                lines.append(f"| {r['phantom']} | {r['keep']} | {r['size']} | error: {r['error']} |" + " |" * 12)
                continue
            rays = max(1, r["rays"])
            b, v = r.get("baseline") or {}, r.get("vs_baseline")
            base = (f"{b['trace_seconds']:.2f} ({b['trace_cpu_seconds']:.2f}) | {r['ratio']:.2f}x "
                    f"({r['cpu_ratio']:.2f}x) | {'yes' if v and v['mask_diff'] == 0 else 'no'}: "
                    f"{v['mask_diff']} pixels differ in hit, depth max diff {v['depth_max_diff']:.2g}"
                    if "ratio" in r else ("earlier run |  | " if r.get("earlier_run") else " |  | "))
            cpu = r.get("trace_cpu_seconds")
            lines.append(f"| {r['phantom']} | {r['keep']} | {r['size']} | {r['trace_seconds']:.2f} | "
                         f"{cpu if cpu is None else f'{cpu:.2f}'} | "
                         f"{r['cells_seconds']:.2f} | {r['us_per_ray']:.1f} | {r['hits']} | "
                         f"{r['functions'] / rays:.0f} | {r['pieces'] / rays:.0f} | {r['refined'] / rays:.1f} | "
                         f"{r['intervals']} | {r['grazes']} | {base} |")
        if res.get("raytrace_baseline"):
            lines += ["", f"Baseline: {res['raytrace_baseline']}, traced first on the same image in the same run; "
                          "ratio = baseline time / this time (wall clock; CPU: process CPU seconds of the trace). "
                          "Rows marked 'earlier run' were not rerun."]
    (out / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=256)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--build", default=str(ROOT / "build"))
    ap.add_argument("--out", default=str(ROOT / "bench" / "results"))
    ap.add_argument("--quick", action="store_true", help="smoke test: 48^3, 1 rep, no brick section peers")
    ap.add_argument("--raytrace-only", action="store_true",
                    help="run only the ray tracer rows and merge them into the existing results")
    ap.add_argument("--no-raytrace", action="store_true", help="skip the ray tracer rows")
    ap.add_argument("--bricks-only", default="",
                    help="only the brick path's rows at these sizes (e.g. 256,512), each against dense MC on the "
                         "original in the same run, merged into the existing results")
    ap.add_argument("--rounds", type=int, default=2, help="--bricks-only: alternated processes per command")
    ap.add_argument("--bricks-baseline", default="",
                    help="--bricks-only: another wvol program (e.g. main's) run alternated with this build")
    ap.add_argument("--bricks-baseline-note", default="", help="--bricks-baseline: what it is, for the report")
    ap.add_argument("--rt-size", default="512x512", help="ray tracer image size (default 512x512)")
    ap.add_argument("--rt-size-override", default="",
                    help="per-row sizes, e.g. 'skull:100%%=128x128,gaussian:100%%=256x256' (labelled in the table)")
    ap.add_argument("--rt-keep", default="1%,5%,100%")
    ap.add_argument("--rt-threads", type=int, default=2)
    ap.add_argument("--rt-baseline", default="",
                    help="ray tracer rows: another wvol program (e.g. main's build) traced on the same image first, "
                         "in the same run: its time, the ratio and the images compared")
    ap.add_argument("--rt-baseline-note", default="", help="what --rt-baseline is, for the report")
    ap.add_argument("--cast", action="store_true",
                    help="only the image routes (bench/iso_cast.py): the bricked caster against marching cubes + "
                         "Embree, VTK, OpenVDB and the exact tracer; --quick: 96^3, 128^2, one thread")
    ap.add_argument("--tmp", default="", help="--cast: working directory for volumes and images")
    ap.add_argument("--exact-only", action="store_true",
                    help="--cast: rerun only the exact f^ tracer's rows and merge them into iso_cast.json/.md")
    ap.add_argument("--bound-only", action="store_true",
                    help="--cast: rerun only the model bound's rows (with --baseline, before and after) and merge them")
    ap.add_argument("--baseline", default="",
                    help="--exact-only / --bound-only: another build's wvol program to time as 'before'")
    ap.add_argument("--baseline-note", default="", help="--exact-only: what the baseline is, for the report")
    ap.add_argument("--exact-large", default="256", help="--exact-only: the larger image size of the 5%% rows")
    args = ap.parse_args()
    if args.cast:
        import datetime
        import iso_cast
        if args.n == 256 and args.quick:
            args.n = 0  # iso_cast's quick default
        elif args.n == 256:
            args.n = 0
        if args.bound_only:
            out = pathlib.Path(args.out)
            rows, meta = iso_cast.bound_only(args, pathlib.Path(args.build), out)
            iso_cast.write_report(rows, {}, out, meta)
            return
        if args.exact_only:
            out = pathlib.Path(args.out)
            rows, meta = iso_cast.exact_only(args, pathlib.Path(args.build), out)
            iso_cast.write_report(rows, {}, out, meta)
            return
        rows, images = iso_cast.main(args, pathlib.Path(args.build), pathlib.Path(args.out))
        meta = {"cpu": cpu_model(), "cores": os.cpu_count(), "when": datetime.datetime.utcnow().isoformat(" ", "minutes"),
                "n": rows[0]["n"], "size": rows[0]["size"], "quick": args.quick,
                "load_avg_end": os.getloadavg()[0]}
        out = pathlib.Path(args.out)
        if args.quick:
            out = out / "iso_cast_quick"
        iso_cast.write_report(rows, images, out, meta)
        return
    if args.quick:
        args.n, args.reps = 48, 1
    n = args.n
    threads = [int(t) for t in args.threads.split(",")]
    threads = [t for t in threads if t <= os.cpu_count()]
    phantoms = {"gaussian": (gaussian(n), 0.5), "skull": (skull(n), 400.0)}
    tools = ["vtkFlyingEdges3D", "vtkMarchingCubes", "skimage", "openvdb"]
    out = pathlib.Path(args.out)
    rname = "iso_quick" if args.quick else "iso"
    if args.bricks_only:
        res = json.loads((out / f"{rname}.json").read_text())
        t = max(threads)
        res["bricks_run"] = {"threads": t, "reps": args.reps, "rounds": args.rounds,
                             "load_avg_start": os.getloadavg()[0],
                             "baseline": args.bricks_baseline_note or args.bricks_baseline or None}
        res["bricks"] = []
        for size in (int(x) for x in args.bricks_only.split(",")):
            with tempfile.TemporaryDirectory() as tmp:
                for name, gen, iso in (("gaussian", gaussian, 0.5), ("skull", skull, 400.0)):
                    raw = pathlib.Path(tmp) / f"{name}.raw"
                    write_raw(raw, gen(size))
                    res["bricks"] += brick_rows(args, raw, name, size, iso, t)
                    raw.unlink()
        res["bricks_run"]["load_avg_end"] = os.getloadavg()[0]
        (out / f"{rname}.json").write_text(json.dumps(res, indent=1) + "\n")
        md = out / f"{rname}.md"
        old = md.read_text() if md.exists() else None
        write_md(res, out, rname, tools)
        if old:  # only the brick-path section changes: notes written beside the other tables stay
            md.write_text(splice_section(old, md.read_text(), "Brick path ("))
        return
    if args.raytrace_only:
        res = json.loads((out / f"{rname}.json").read_text())
        if res["n"] != n:
            sys.exit(f"--raytrace-only: {rname}.json is for n = {res['n']}, not {n}")
        res["raytrace_load_avg"] = os.getloadavg()[0]
        with tempfile.TemporaryDirectory() as tmp:
            new_rows = raytrace_rows(args, phantoms, tmp)
        # rows of this run replace those of the same phantom and keep; the others stay, marked
        done = {(r["phantom"], r["keep"]) for r in new_rows}
        kept = [dict(r, earlier_run=True) for r in res.get("raytrace", []) if (r["phantom"], r["keep"]) not in done]
        res["raytrace"] = sorted(new_rows + kept, key=lambda r: (r["phantom"], float(r["keep"].rstrip("%"))))
        res["raytrace_baseline"] = args.rt_baseline_note or args.rt_baseline or None
        res.pop("raytrace_note", None)  # a note describes one run: add it by hand after
        (out / f"{rname}.json").write_text(json.dumps(res, indent=1) + "\n")
        md = out / f"{rname}.md"
        old = md.read_text() if md.exists() else None
        write_md(res, out, rname, tools)
        if old:  # only the ray tracer's table and its baseline line change: notes beside them stay
            new = md.read_text()
            merged = splice_section(splice_section(old, new, "Ray tracer ("), new, "Baseline: ", table=False)
            if "\nBaseline: " not in new:  # no baseline this run: the old run's line would be stale
                merged = "\n".join(l for l in merged.split("\n") if not l.startswith("Baseline: "))
            md.write_text(merged)
        return
    res = {"machine": {"cpu": cpu_model(), "cores": os.cpu_count(), "load_avg_start": os.getloadavg()[0]},
           "n": n, "reps": args.reps, "mc": [], "bricks": []}
    with tempfile.TemporaryDirectory() as tmp:
        for name, (f, iso) in phantoms.items():
            raw = pathlib.Path(tmp) / f"{name}.raw"
            write_raw(raw, f)
            for t in threads:
                row = {"phantom": name, "iso": iso, "threads": t}
                w = run_wvol(args.build, raw, n, iso, t, args.reps)
                row["wvol"] = {k: w.get(k) for k in ("seconds", "triangles", "area", "error") if k in w}
                for tool in tools:
                    row[tool] = run_peer(tool, raw, n, iso, t, args.reps)
                fe = row["vtkFlyingEdges3D"].get("seconds")
                if fe and w.get("seconds"):
                    row["speedup_vs_flying_edges"] = fe / w["seconds"]
                res["mc"].append(row)
                print(f"{name:8s} {t} thr  wvol {w.get('seconds', float('nan')) * 1e3:8.2f} ms  "
                      + "  ".join(f"{k} {row[k].get('seconds', float('nan')) * 1e3:8.2f} ms" for k in tools),
                      flush=True)
            # brick path from coefficients
            for wavelet, keep in (("haar", "5%"), ("db2", "5%"), ("db2", "100%")):
                if args.quick and wavelet != "db2":
                    continue
                b = run_wvol(args.build, raw, n, iso, max(threads), 1,
                             ["--wavelet", wavelet, "--levels", "3", "--keep", keep])
                full = full_reconstruction_seconds(raw, n, wavelet, 3, keep, iso, max(threads), args.build)
                entry = {"phantom": name, "wavelet": wavelet, "keep": keep, "threads": max(threads)}
                for k in ("seconds", "triangles", "area", "bricks_total", "bricks_skipped", "seconds_bounds",
                          "seconds_reconstruct_mesh", "error"):
                    if k in b:
                        entry[k] = b[k]
                entry["one_brick_seconds"] = full.get("seconds")
                res["bricks"].append(entry)
                print(f"{name:8s} bricks {wavelet} keep {keep}: {b.get('seconds', float('nan')) * 1e3:.1f} ms, "
                      f"{b.get('bricks_skipped')} of {b.get('bricks_total')} skipped; full inverse + MC "
                      f"{(full.get('seconds') or float('nan')) * 1e3:.1f} ms", flush=True)
        if not args.no_raytrace:
            res["raytrace_load_avg"] = os.getloadavg()[0]
            res["raytrace"] = raytrace_rows(args, phantoms, tmp)
    res["machine"]["load_avg_end"] = os.getloadavg()[0]
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{rname}.json").write_text(json.dumps(res, indent=1) + "\n")
    write_md(res, out, rname, tools)


if __name__ == "__main__":
    main()
