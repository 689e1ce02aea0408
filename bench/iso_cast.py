# SPDX-License-Identifier: MIT
"""The iso caster's benchmark (bench_iso.py --cast): images of an isosurface at 512^2, same
camera and iso-value for every route, in one run:

  cast    wvol iso --method cast from the store (bricks rebuilt on demand, exact first crossing
          of the trilinear interpolant of the store's reconstruction);
  embree  our marching cubes from the same store (wvol iso --wavelet), then Embree's BVH and
          primary rays (bench/iso_embree.c: the same wvol camera rays);
  vtk     the same mesh drawn by VTK offscreen (first frame, xvfb-run; mesh read not timed);
  vdb     OpenVDB: the store's reconstruction padded with outside values, meshed, converted to a
          level set (createLevelSetFromPolygons), written and rendered by vdb_render;
  exact   the exact f^ tracer (wvol iso --method raytrace) at a small size (it takes ms per ray).

Volumes: the noisy skull (wvol synth skull --noise 20, bone at 400 HU) and the Gaussian (0.5),
N^3; 5% and 100% stores (db2, 3 levels); perspective and orthographic views along
(1, 0.6, -0.3); 1 and 2 threads (taskset for every tool, plus its own thread knob).

Time to first image: from a store already in memory (its build, as for every route, is
"prepare"): cast = bounds + bricks + rays; embree = marching cubes from the store + BVH + rays;
vtk = marching cubes + first frame; vdb = mesh + level set + vdb_render's wall time (which
includes reading the file). Trace rays/s per thread: the caster's rays / (thread-seconds of the
call - thread-seconds building bricks - bounds), Embree's rays / (trace seconds x threads).

Errors, per image: the depth difference (median, 99th percentile, where both hit) and hit
masks to the converged dense reference (the caster on the original volume: exact for the
trilinear interpolant of the original) and to the exact f^ tracer (at its small size)."""
import json
import os
import pathlib
import subprocess
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]

VTK_SCRIPT = r'''
import json, sys, time
from vtkmodules.vtkIOPLY import vtkPLYReader
from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper, vtkRenderer, vtkRenderWindow, vtkWindowToImageFilter
from vtkmodules.vtkIOImage import vtkPNGWriter
import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (the OpenGL backend)
ply, w, h, cam, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), json.loads(sys.argv[4]), sys.argv[5]
r = vtkPLYReader(); r.SetFileName(ply); r.Update()
t0 = time.perf_counter()
m = vtkPolyDataMapper(); m.SetInputData(r.GetOutput())
a = vtkActor(); a.SetMapper(m)
a.GetProperty().SetColor(0.93, 0.89, 0.80)
ren = vtkRenderer(); ren.AddActor(a); ren.SetBackground(0, 0, 0)
rw = vtkRenderWindow(); rw.SetOffScreenRendering(1); rw.AddRenderer(ren); rw.SetSize(w, h)
c = ren.GetActiveCamera()
c.SetPosition(*cam["eye"]); c.SetFocalPoint(*cam["center"]); c.SetViewUp(*cam["up"])
if cam["projection"] == "persp":
    c.SetViewAngle(cam["fov_y"])
else:
    c.ParallelProjectionOn(); c.SetParallelScale(cam["view_height"] / 2)
ren.ResetCameraClippingRange()
rw.Render()
t = time.perf_counter() - t0
g = vtkWindowToImageFilter(); g.SetInput(rw); g.ReadFrontBufferOff(); g.Update()
wr = vtkPNGWriter(); wr.SetFileName(out); wr.SetInputConnection(g.GetOutputPort()); wr.Write()
print(json.dumps({"first_frame_seconds": t}))
'''

VDB_SCRIPT = r'''
import json, sys, time
import numpy as np
import pyopenvdb as vdb
sys.path.insert(0, sys.argv[1])
import wvol
vol, keep, iso, out, threads = sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), sys.argv[5], int(sys.argv[6])
v = wvol.load(vol)
s = wvol.compress(v, "db2", 3, keep=keep)
rec = np.asarray(s.reconstruct(), dtype=np.float32)
sp = np.asarray(v.spacing, dtype=np.float64)
org = np.asarray(v.origin, dtype=np.float64)
t0 = time.perf_counter()
# pad with values outside the surface, so that its mesh is closed and the level set's sign right
outside = min(float(rec.min()), iso) - 1.0
pad = np.pad(rec, 2, constant_values=outside)
pv = wvol.Volume(pad, spacing=tuple(sp), origin=tuple(org - 2 * sp))
verts, faces, _ = wvol.isosurface(pv, iso, normals="none", threads=threads)
t1 = time.perf_counter()
xf = vdb.createLinearTransform(voxelSize=float(sp.min()))
g = vdb.FloatGrid.createLevelSetFromPolygons(np.asarray(verts, np.float32), triangles=np.asarray(faces, np.int32),
                                              transform=xf, halfWidth=3.0)
g.name = "surface"
t2 = time.perf_counter()
vdb.write(out, grids=[g])
t3 = time.perf_counter()
print(json.dumps({"mesh_seconds": t1 - t0, "levelset_seconds": t2 - t1, "write_seconds": t3 - t2}))
'''


def run(cmd, threads=None, env=None, timeout=1800):
    if threads:
        cmd = ["taskset", "-c", ",".join(str(i) for i in range(threads))] + [str(c) for c in cmd]
    t = time.perf_counter()
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, env=env, timeout=timeout)
    wall = time.perf_counter() - t
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))[:200]}: {r.stderr[-500:]}")
    return r.stdout, wall


def read_exr_z(path):
    sys.path.insert(0, str(ROOT / "bench"))
    from bench_render import read_exr
    c = read_exr(path)
    return c["Z"], np.stack([c["R"], c["G"], c["B"]], -1)


def depth_stats(a, b):
    """a against b: hit-mask differences and |depth difference| where both hit."""
    ha, hb = np.isfinite(a), np.isfinite(b)
    both = ha & hb
    d = np.abs(a[both] - b[both]) if both.any() else np.zeros(1)
    return {"hits": int(ha.sum()), "hits_ref": int(hb.sum()), "mask_diff": int((ha != hb).sum()),
            "depth_median": float(np.median(d)), "depth_p99": float(np.percentile(d, 99)),
            "depth_max": float(d.max())}


def silhouette(mask):
    """Pixels of a mask with a 4-neighbour of the other value."""
    m = mask.astype(bool)
    e = np.zeros_like(m)
    e[1:] |= m[1:] != m[:-1]
    e[:-1] |= m[1:] != m[:-1]
    e[:, 1:] |= m[:, 1:] != m[:, :-1]
    e[:, :-1] |= m[:, 1:] != m[:, :-1]
    return e


def main(args, build, out_dir):
    wv = build / "wvol"
    embree = build / "bench" / "iso_embree"
    tmp = pathlib.Path(args.tmp) if args.tmp else pathlib.Path(os.environ.get("TMPDIR", "/tmp")) / "wvol_iso_cast"
    tmp.mkdir(parents=True, exist_ok=True)
    quick = args.quick
    n = args.n if args.n else (96 if quick else 256)
    size = 128 if quick else 512
    exact_size = 24 if quick else 64
    threads_list = [1] if quick else [1, 2]
    cams = {"persp": "persp dir=1,0.6,-0.3", "ortho": "ortho dir=1,0.6,-0.3"}
    volumes = {"skull": (["skull", "--noise", "20"], 400.0), "gaussian": (["gaussian"], 0.5)}
    keeps = ["5%", "100%"]
    have_xvfb = subprocess.run(["which", "xvfb-run"], capture_output=True).returncode == 0
    have_vdb = subprocess.run(["which", "vdb_render"], capture_output=True).returncode == 0
    env_py = dict(os.environ, PYTHONPATH=str(build / "python"))
    rows, images = [], {}
    for vname, (synth, iso) in volumes.items():
        vol = tmp / f"{vname}_{n}.nrrd"
        run([wv, "synth", *synth, "--size", n, "-o", vol])
        # the converged dense reference: the caster on the original volume (exact for its interpolant)
        ref = {}
        for cname, cam in cams.items():
            run([wv, "iso", vol, "--method", "cast", "--iso", iso, "--camera", cam, "--size", f"{size}x{size}",
                 "--threads", "2", "-o", tmp / f"ref_{vname}_{cname}.exr", "--json"])
            ref[cname] = read_exr_z(tmp / f"ref_{vname}_{cname}.exr")[0]
            run([wv, "iso", vol, "--method", "cast", "--iso", iso, "--camera", cam, "--size",
                 f"{exact_size}x{exact_size}", "--threads", "2", "-o", tmp / f"refs_{vname}_{cname}.exr"])
        for keep in keeps:
            kf = float(keep.rstrip("%")) / 100
            mesh = tmp / f"{vname}_{keep.rstrip('%')}.ply"
            for T in threads_list:
                out, _ = run([wv, "iso", vol, "--iso", iso, "--wavelet", "db2", "--keep", keep, "--threads", T,
                              "-o", mesh, "--json"], threads=T)
                mc = json.loads(out)
                mc_s = mc["seconds"]["extract"]
                vdb_info = None
                for cname, cam in cams.items():
                    row = {"volume": vname, "n": n, "iso": iso, "keep": keep, "camera": cname, "size": size,
                           "threads": T, "triangles": mc["triangles"], "mc_seconds": mc_s}
                    key = f"{vname}_{keep.rstrip('%')}_{cname}_{T}"
                    # cast
                    out, _ = run([wv, "iso", vol, "--method", "cast", "--iso", iso, "--keep", keep, "--camera", cam,
                                  "--size", f"{size}x{size}", "--threads", T, "-o", tmp / f"cast_{key}.exr", "--json"],
                                 threads=T)
                    c = json.loads(out)
                    trace_ts = c["seconds"] * T - c["thread_seconds_build"] - c["seconds_bounds"] * T
                    zc, rgb = read_exr_z(tmp / f"cast_{key}.exr")
                    row["cast"] = {"first_image_seconds": c["seconds"], "bounds_seconds": c["seconds_bounds"],
                                   "build_thread_seconds": c["thread_seconds_build"],
                                   "bricks_built": c["bricks_built"], "bricks_total": c["bricks_total"],
                                   "bricks_bound": c["bricks_bound"], "bytes": c["bytes"],
                                   "rays_per_s_per_thread_trace": c["rays"] / max(trace_ts, 1e-9),
                                   "rays_per_s_per_thread_total": c["rays"] / (c["seconds"] * T),
                                   "prepare_seconds": c["prepare_seconds"],
                                   "vs_reference": depth_stats(zc, ref[cname])}
                    if T == threads_list[0]:
                        images.setdefault(key, {})["cast"] = rgb
                    if T == threads_list[0] and cname == "persp":  # the model bound's numbers and cost
                        out, _ = run([wv, "iso", vol, "--method", "cast", "--iso", iso, "--keep", keep, "--camera", cam,
                                      "--size", f"{size}x{size}", "--threads", T, "--model-bound", "--json"], threads=T)
                        mb = json.loads(out)
                        row["cast"]["model_bound"] = {k: mb[k] for k in ("fhat_bound_max", "fhat_bound_mean",
                                                                         "fhat_bound_bricks", "fhat_bound_faces",
                                                                         "seconds")}
                        # the same with db4 and J = 6, whose spline tables err 100x less than db2's at J = 4
                        out, _ = run([wv, "iso", vol, "--method", "cast", "--iso", iso, "--keep", keep, "--camera", cam,
                                      "--wavelet", "db4", "--spline-j", "6", "--size", f"{size}x{size}", "--threads", T,
                                      "--model-bound", "--json"], threads=T)
                        mb = json.loads(out)
                        row["cast"]["model_bound_db4_j6"] = {k: mb[k] for k in (
                            "fhat_bound_max", "fhat_bound_mean", "fhat_bound_bricks", "fhat_bound_faces", "seconds")}
                    # marching cubes + Embree
                    if embree.exists():
                        out, _ = run([embree, mesh, vol, cam, f"{size}x{size}", T, tmp / f"emb_{key}.raw"], threads=T)
                        e = json.loads(out)
                        ze = np.fromfile(tmp / f"emb_{key}.raw", np.float32).reshape(size, size)
                        row["embree"] = {"first_image_seconds": mc_s + e["build_seconds"] + e["trace_seconds"],
                                         "bvh_seconds": e["build_seconds"], "trace_seconds": e["trace_seconds"],
                                         "rays_per_s_per_thread_trace": e["rays"] / (e["trace_seconds"] * T),
                                         "vs_reference": depth_stats(ze, ref[cname]),
                                         "vs_cast": depth_stats(ze, zc)}
                        row["embree"]["vs_cast"]["mask_diff_off_silhouette"] = int(
                            ((np.isfinite(ze) != np.isfinite(zc)) & ~silhouette(np.isfinite(zc))).sum())
                        camj = e["camera"]
                        if T == threads_list[0]:
                            images[key]["embree (depth)"] = ze
                    else:
                        camj = None
                    # VTK: the same mesh, offscreen, first frame
                    if have_xvfb and camj:
                        png = tmp / f"vtk_{key}.png"
                        try:
                            env = dict(os.environ, LP_NUM_THREADS=str(T))
                            out, wall = run(["xvfb-run", "-a", sys.executable, "-c", VTK_SCRIPT, mesh, size, size,
                                             json.dumps(camj), png], threads=T, env=env)
                            vj = json.loads(out.strip().splitlines()[-1])
                            row["vtk"] = {"first_image_seconds": mc_s + vj["first_frame_seconds"],
                                          "first_frame_seconds": vj["first_frame_seconds"]}
                            if T == threads_list[0]:
                                from PIL import Image
                                images[key]["vtk"] = np.asarray(Image.open(png).convert("RGB"), np.float32) / 255
                        except Exception as ex:  # noqa: BLE001  (recorded, the run goes on)
                            row["vtk"] = {"error": str(ex)[:300]}
                    # OpenVDB: level set once per (volume, keep, threads), vdb_render per camera
                    if have_vdb and camj:
                        try:
                            vdbf = tmp / f"{vname}_{keep.rstrip('%')}.vdb"
                            if vdb_info is None:
                                out, _ = run([sys.executable, "-c", VDB_SCRIPT, build / "python", vol, kf, iso, vdbf,
                                              T], threads=T, env=env_py)
                                vdb_info = json.loads(out.strip().splitlines()[-1])
                            exr = tmp / f"vdb_{key}.exr"
                            opts = ["-res", f"{size}x{size}", "-translate", ",".join(map(str, camj["eye"])),
                                    "-lookat", ",".join(map(str, camj["center"])), "-up", ",".join(map(str, camj["up"])),
                                    "-cpus", T]
                            opts += (["-camera", "persp", "-fov", camj["fov_y"]] if cname == "persp"
                                     else ["-camera", "ortho", "-frame", camj["view_height"]])
                            _, wall = run(["vdb_render", vdbf, exr, *opts, "-shader", "diffuse"], threads=T)
                            row["vdb"] = {"first_image_seconds": vdb_info["mesh_seconds"] + vdb_info["levelset_seconds"]
                                          + vdb_info["write_seconds"] + wall, "render_wall_seconds": wall, **vdb_info}
                            # vdb_render writes no depth (its position shader is normalised to the
                            # volume's box): the hit mask against the caster's from the same store
                            sys.path.insert(0, str(ROOT / "bench"))
                            from bench_render import read_exr
                            dc = read_exr(exr)
                            rgbv = np.stack([dc["R"], dc["G"], dc["B"]], -1)
                            hv = rgbv.sum(-1) > 0
                            hc = np.isfinite(zc)
                            row["vdb"]["mask_vs_cast"] = int((hv != hc).sum())
                            row["vdb"]["mask_vs_cast_off_silhouette"] = int(((hv != hc) & ~silhouette(hc)).sum())
                            if T == threads_list[0]:
                                images[key]["vdb_render"] = rgbv
                        except Exception as ex:  # noqa: BLE001
                            row["vdb"] = {"error": str(ex)[:300]}
                    # the exact f^ tracer at a small size (persp only: ms per ray)
                    if cname == "persp" and (keep == "5%" or not quick):
                        out, _ = run([wv, "iso", vol, "--method", "raytrace", "--iso", iso, "--keep", keep, "--camera", cam,
                                      "--size", f"{exact_size}x{exact_size}", "--threads", T, "-o",
                                      tmp / f"exact_{key}.exr", "--json"], threads=T)
                        x = json.loads(out)
                        zx = read_exr_z(tmp / f"exact_{key}.exr")[0]
                        out, _ = run([wv, "iso", vol, "--method", "cast", "--iso", iso, "--keep", keep, "--camera", cam,
                                      "--size", f"{exact_size}x{exact_size}", "--threads", T, "-o",
                                      tmp / f"casts_{key}.exr"], threads=T)
                        zcs = read_exr_z(tmp / f"casts_{key}.exr")[0]
                        zrs = read_exr_z(tmp / f"refs_{vname}_{cname}.exr")[0]
                        row["exact"] = {"size": exact_size, "seconds": x["trace_seconds"],
                                        "rays_per_s_per_thread": x["rays"] / (x["trace_seconds"] * T),
                                        "grazes": x["grazes"], "vs_reference": depth_stats(zx, zrs),
                                        "cast_vs_exact": depth_stats(zcs, zx)}
                    rows.append(row)
                    print(summary_line(row), flush=True)
    return rows, images


RERUN_VOLUMES = {"skull": (["skull", "--noise", "20"], 400.0), "gaussian": (["gaussian"], 0.5)}


def rerun_setup(args, build, out_dir):
    """What a partial rerun (--exact-only, --bound-only) starts from: this build's program, the
    baseline's (or None), the working directory, and the rows and meta of iso_cast.json."""
    base = pathlib.Path(args.baseline) if args.baseline else None
    tmp = pathlib.Path(args.tmp) if args.tmp else pathlib.Path(os.environ.get("TMPDIR", "/tmp")) / "wvol_iso_cast"
    tmp.mkdir(parents=True, exist_ok=True)
    res = json.loads((out_dir / "iso_cast.json").read_text())
    return build / "wvol", base, tmp, res["rows"], res["meta"]


def exact_run(wv, vol, iso, keep, cam, size, T, out):
    """One exact-tracer image: its JSON report and depth map."""
    o, _ = run([wv, "iso", vol, "--method", "raytrace", "--iso", iso, "--keep", keep, "--camera", cam,
                "--size", f"{size}x{size}", "--threads", T, "-o", out, "--json"], threads=T)
    x = json.loads(o)
    return x, read_exr_z(out)[0]


def exact_only(args, build, out_dir):
    """--exact-only: reruns the exact f^ tracer's rows of iso_cast.json (perspective, 5% and 100%
    stores, 1 and 2 threads) at the small size of the full run, and the 5% rows at a larger one,
    with this build and (--baseline WVOL, another build's program, e.g. main's) the code before,
    interleaved in the same run; rows are replaced in iso_cast.json and the report rewritten."""
    wv, base, tmp, rows, meta = rerun_setup(args, build, out_dir)
    n, small, large = meta["n"], 64, int(args.exact_large)
    cam = "persp dir=1,0.6,-0.3"
    volumes = RERUN_VOLUMES
    load0 = os.getloadavg()[0]
    for vname, (synth, iso) in volumes.items():
        vol = tmp / f"{vname}_{n}.nrrd"
        run([wv, "synth", *synth, "--size", n, "-o", vol])
        for size in sorted({small, large}):
            ref = tmp / f"refx_{vname}_{size}.exr"
            run([wv, "iso", vol, "--method", "cast", "--iso", iso, "--camera", cam, "--size", f"{size}x{size}",
                 "--threads", "2", "-o", ref])
            zr = read_exr_z(ref)[0]
            for r in rows:
                if r["volume"] != vname or r["camera"] != "persp" or (size != small and r["keep"] != "5%"):
                    continue
                keep, T = r["keep"], r["threads"]
                key = f"{vname}_{keep.rstrip('%')}_{T}_{size}"
                x, zx = exact_run(wv, vol, iso, keep, cam, size, T, tmp / f"exact_{key}.exr")
                o, _ = run([wv, "iso", vol, "--method", "cast", "--iso", iso, "--keep", keep, "--camera", cam,
                            "--size", f"{size}x{size}", "--threads", T, "-o", tmp / f"casts_{key}.exr"], threads=T)
                zc = read_exr_z(tmp / f"casts_{key}.exr")[0]
                e = {"size": size, "seconds": x["trace_seconds"], "cpu_seconds": x["trace_cpu_seconds"],
                     "rays_per_s_per_thread": x["rays"] / (x["trace_seconds"] * T),
                     "rays_per_cpu_s": x["rays"] / x["trace_cpu_seconds"], "grazes": x["grazes"],
                     "hits": x["hits"], "functions": x["functions"], "cells": x.get("cells", 0),
                     "cells_undecided": x.get("cells_undecided", 0), "cells_thread_seconds": x["cells_seconds"],
                     "vs_reference": depth_stats(zx, zr), "cast_vs_exact": depth_stats(zc, zx)}
                if base:
                    xb, zb = exact_run(base, vol, iso, keep, cam, size, T, tmp / f"exactb_{key}.exr")
                    e["baseline"] = {"seconds": xb["trace_seconds"], "cpu_seconds": xb["trace_cpu_seconds"],
                                     "rays_per_s_per_thread": xb["rays"] / (xb["trace_seconds"] * T),
                                     "rays_per_cpu_s": xb["rays"] / xb["trace_cpu_seconds"], "hits": xb["hits"],
                                     "functions": xb["functions"], "vs_new": depth_stats(zb, zx)}
                r["exact" if size == small else "exact_large"] = e
                b = e.get("baseline")
                print(f"exact {vname} {keep} T={T} {size}^2: {e['rays_per_s_per_thread']:.3g} rays/s/thread"
                      + (f" (before {b['rays_per_s_per_thread']:.3g}: {b['seconds'] / e['seconds']:.1f}x; "
                         f"hits {b['hits']} / {e['hits']}, mask diff {b['vs_new']['mask_diff']}, "
                         f"depth max {b['vs_new']['depth_max']:.2g})" if b else ""), flush=True)
    meta["exact_when"] = __import__("datetime").datetime.utcnow().isoformat(" ", "minutes")
    meta["exact_load_avg"] = [load0, os.getloadavg()[0]]
    meta["exact_baseline"] = str(base) if base else None
    meta["exact_baseline_note"] = args.baseline_note
    return rows, meta


def bound_only(args, build, out_dir):
    """--bound-only: the model bound's rows (`--model-bound`, 512^2 perspective, one thread, db2 J4 and
    db4 J6 stores at 5% and 100%) with this build and (--baseline) the code before, interleaved, and
    the largest |f^ - interp| found by sampling f^ (Store.evaluate) and the trilinear interpolant of
    the reconstruction at random points of the bricks no face touches (db2 J4: the Python binding
    builds stores at J = 4 only); replaces meta["model_bound"] in iso_cast.json."""
    wv, base, tmp, rows, meta = rerun_setup(args, build, out_dir)
    n, size, cam = meta["n"], 512, "persp dir=1,0.6,-0.3"
    sys.path.insert(0, str(build / "python"))
    import wvol
    rng = np.random.default_rng(1)
    volumes = RERUN_VOLUMES
    out_rows = []
    for vname, (synth, iso) in volumes.items():
        vol = tmp / f"{vname}_{n}.nrrd"
        run([wv, "synth", *synth, "--size", n, "-o", vol])
        for keep in ("5%", "100%"):
            for lab, extra in (("db2 J4", []), ("db4 J6", ["--wavelet", "db4", "--spline-j", "6"])):
                r = {"volume": vname, "keep": keep, "store": lab}
                for who, prog in (("after", wv), ("before", base)):
                    if prog is None:
                        continue
                    o, _ = run([prog, "iso", vol, "--method", "cast", "--iso", iso, "--keep", keep, "--camera", cam,
                                *extra, "--size", f"{size}x{size}", "--threads", 1, "--model-bound", "--json",
                                "-o", tmp / "bound.exr"], threads=1)
                    mb = json.loads(o)
                    r[who] = {k: mb[k] for k in ("fhat_bound_max", "fhat_bound_mean", "fhat_bound_bricks",
                                                 "fhat_bound_faces", "seconds", "cpu_seconds")}
                if lab == "db2 J4":
                    v = wvol.load(str(vol))
                    st = wvol.compress(v, "db2", 3, keep=float(keep.rstrip("%")) / 100)
                    rec = np.asarray(st.reconstruct().data, dtype=np.float64)  # (z, y, x)
                    lo, hi = 32.0, n - 33.0  # bricks of 32 cells: those no face touches
                    x = rng.uniform(lo, hi, size=(20000, 3))
                    i0 = np.floor(x).astype(int)
                    f = x - i0
                    interp = np.zeros(len(x))
                    for dz in (0, 1):
                        for dy in (0, 1):
                            for dx in (0, 1):
                                w = (f[:, 0] if dx else 1 - f[:, 0]) * (f[:, 1] if dy else 1 - f[:, 1]) * \
                                    (f[:, 2] if dz else 1 - f[:, 2])
                                interp += w * rec[i0[:, 2] + dz, i0[:, 1] + dy, i0[:, 0] + dx]
                    world = np.asarray(v.origin) + x * np.asarray(v.spacing)
                    fh = st.evaluate(world)[0]
                    r["sampled_max"] = float(np.max(np.abs(fh - interp)))
                    r["sampled_points"] = len(x)
                out_rows.append(r)
                a, b = r["after"], r.get("before")
                print(f"bound {vname} {keep} {lab}: max {a['fhat_bound_max']:.4g} (before "
                      f"{b['fhat_bound_max'] if b else float('nan'):.4g}), mean {a['fhat_bound_mean']:.4g}, sampled max "
                      f"{r.get('sampled_max', float('nan')):.4g}", flush=True)
    meta["model_bound"] = {"rows": out_rows, "when": __import__("datetime").datetime.utcnow().isoformat(" ", "minutes"),
                           "baseline": str(base) if base else None, "load_avg": os.getloadavg()[0]}
    return rows, meta


def summary_line(r):
    def g(k, f="first_image_seconds"):
        return f"{r[k][f]:.3f}" if k in r and f in r[k] else "-"
    return (f"{r['volume']:8s} {r['keep']:>4s} {r['camera']:5s} T={r['threads']} cast {g('cast')} s "
            f"({r['cast']['rays_per_s_per_thread_trace']:.3g} rays/s/thread trace) | embree {g('embree')} | "
            f"vtk {g('vtk')} | vdb {g('vdb')}")


# ---- the report ----------------------------------------------------------------------------

def write_report(rows, images, out_dir, meta):
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "iso_cast.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=1))
    L = ["# Isosurface images: the bricked caster against the mesh routes, OpenVDB and the exact tracer", "",
         f"{meta['cpu']}; {meta['when']}; volumes {meta['n']}^3, images {meta['size']}^2, db2 3 levels. "
         "Machine shared with other jobs: compare within a row. Generated by `bench/bench_iso.py --cast`"
         + (" --quick" if meta["quick"] else "") + ".", "",
         "Time to first image in seconds from a store in memory (cast: bounds + bricks + rays; embree: our "
         "marching cubes from the store + BVH + rays; vtk: marching cubes + first offscreen frame; vdb: mesh of "
         "the padded reconstruction + level set + file + vdb_render). Ratios are route / cast.", "",
         "| volume | keep | camera | threads | cast s | embree s (x) | vtk s (x) | vdb s (x) | cast trace rays/s/thread "
         "| embree trace rays/s/thread | bricks built / total |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]

    def cell(r, k):
        if k not in r or "first_image_seconds" not in r[k]:
            return "-" if k not in r else "error"
        return f"{r[k]['first_image_seconds']:.3f} ({r[k]['first_image_seconds'] / r['cast']['first_image_seconds']:.1f}x)"
    for r in rows:
        c = r["cast"]
        L.append(f"| {r['volume']} | {r['keep']} | {r['camera']} | {r['threads']} | {c['first_image_seconds']:.3f} | "
                 f"{cell(r, 'embree')} | {cell(r, 'vtk')} | {cell(r, 'vdb')} | {c['rays_per_s_per_thread_trace']:.3g} | "
                 + (f"{r['embree']['rays_per_s_per_thread_trace']:.3g}" if "embree" in r else "-")
                 + f" | {c['bricks_built']} / {c['bricks_total']} |")
    L += ["", "Depth errors (world units; voxel = the volume's spacing) against the converged dense reference (the caster "
          "on the original volume: exact for its trilinear interpolant), where both hit; hit-mask differences in "
          "pixels. Embree and vdb_render against the caster: mask differences, and those off the silhouette "
          "(pixels with a 4-neighbour of the other value). vdb_render writes no depth, so it has masks only.", "",
          "| volume | keep | camera | cast: median / p99, mask | embree: median / p99, mask | embree vs cast: mask, "
          "off silhouette | vdb vs cast: mask, off silhouette |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["threads"] != rows[0]["threads"]:
            continue
        def e(k, sub="vs_reference"):
            if k not in r or sub not in r[k]:
                return "-"
            d = r[k][sub]
            return f"{d['depth_median']:.3g} / {d['depth_p99']:.3g}, {d['mask_diff']}"
        ev = (f"{r['embree']['vs_cast']['mask_diff']}, {r['embree']['vs_cast']['mask_diff_off_silhouette']}"
              if "embree" in r else "-")
        vv = (f"{r['vdb']['mask_vs_cast']}, {r['vdb']['mask_vs_cast_off_silhouette']}"
              if "vdb" in r and "mask_vs_cast" in r["vdb"] else "-")
        L.append(f"| {r['volume']} | {r['keep']} | {r['camera']} | {e('cast')} | {e('embree')} | {ev} | {vv} |")
    ex = [(r, r[k]) for k in ("exact", "exact_large") for r in rows if k in r]
    if ex:
        withb = any("baseline" in x for _, x in ex)
        L += ["", "The exact f^ tracer (perspective; rays/s per thread = rays / (wall seconds x threads), the "
              "whole call: its cells are classified by the rays that reach them): its speed, and the caster "
              "against it at the same size (f^ is db2's smoothed model, not the interpolant: the difference is the "
              "model's, not an error of either)."
              + (f" \"before\" is `{meta.get('exact_baseline')}`"
                 + (f" ({meta['exact_baseline_note']})" if meta.get("exact_baseline_note") else "")
                 + " on the same rays, interleaved in the same run "
                 f"({meta.get('exact_when', '')}, load average {meta.get('exact_load_avg', ['?'])[0]:.1f} at start: a "
                 "shared machine, so the rays per CPU-second are given too); its images have the same hits "
                 "(\"mask\": pixels differing) and depths within the tolerance (\"depth\": the largest difference, "
                 "world units)." if withb else ""), "",
              "| volume | keep | threads | size | exact rays/s/thread | rays/CPU-s | "
              + ("before rays/s/thread | before rays/CPU-s | speed-up (wall) | speed-up (CPU) | before vs after: mask, depth | "
                 if withb else "")
              + "cells classified / undecided | grazes | exact vs dense ref: median / p99, mask "
              "| cast vs exact: median / p99, mask |",
              "|---|---|---|---|---|---|" + ("---|---|---|---|---|" if withb else "") + "---|---|---|---|"]
        for r, x in ex:
            a, b = x["vs_reference"], x["cast_vs_exact"]
            bl = x.get("baseline")
            bcols = ""
            if withb:
                bcols = (f"{bl['rays_per_s_per_thread']:.3g} | {bl['rays_per_cpu_s']:.3g} | "
                         f"{bl['seconds'] / x['seconds']:.1f}x | {bl['cpu_seconds'] / x['cpu_seconds']:.1f}x | "
                         f"{bl['vs_new']['mask_diff']}, {bl['vs_new']['depth_max']:.2g} | " if bl else "- | - | - | - | - | ")
            L.append(f"| {r['volume']} | {r['keep']} | {r['threads']} | {x['size']}^2 | {x['rays_per_s_per_thread']:.3g} | "
                     f"{x.get('rays_per_cpu_s', float('nan')):.3g} | " + bcols
                     + f"{x.get('cells', '-')} / {x.get('cells_undecided', '-')} | {x['grazes']} | "
                     f"{a['depth_median']:.3g} / {a['depth_p99']:.3g}, {a['mask_diff']} | "
                     f"{b['depth_median']:.3g} / {b['depth_p99']:.3g}, {b['mask_diff']} |")
    mb = meta.get("model_bound")
    mbr = [r for r in rows if "model_bound" in r.get("cast", {})]
    if mbr and not mb:  # a full run's rows (--bound-only replaces them by its own table)
        L += ["", "The model bound (`--model-bound`): per built brick, a bound of |f^ - interp| (f^ the store's spline "
              "model, interp the trilinear interpolant of its reconstruction; docs/iso.md), max and mean over the bricks "
              "whose sample window no face clips, and the call's time with it.", "",
              "| volume | keep | store | bound max | bound mean | bricks bounded / at faces | seconds with the bound "
              "| without (db2) |", "|---|---|---|---|---|---|---|---|"]
        for r in mbr:
            for lab, k in (("db2 J4", "model_bound"), ("db4 J6", "model_bound_db4_j6")):
                m = r["cast"][k]
                L.append(f"| {r['volume']} | {r['keep']} | {lab} | {m['fhat_bound_max']:.4g} | {m['fhat_bound_mean']:.4g} | "
                         f"{m['fhat_bound_bricks']} / {m['fhat_bound_faces']} | {m['seconds']:.3f} | "
                         f"{r['cast']['first_image_seconds']:.3f} |")
    if mb:
        withb = any("before" in r for r in mb["rows"])
        L += ["", "The model bound (`--model-bound`, `bench/bench_iso.py --cast --bound-only`, " + mb["when"] + "): per "
              "built brick, per group of 4^3 cells, a bound of |f^ - interp| (f^ the store's spline model, interp the "
              "trilinear interpolant of its reconstruction; docs/iso.md); max and mean over the bricks whose sample "
              "window no face clips, 512^2 perspective, one thread"
              + (f"; 'before' is {mb['baseline']} (the bound per brick), interleaved in the same run" if withb else "")
              + ". 'sampled' is the largest |f^ - interp| found at 20000 random points of the bricks no face touches "
              "(Store.evaluate against the trilinear interpolant of the reconstruction; db2 J4 only: the Python binding "
              "builds J = 4 stores), and 'bound / sampled' the largest bound over it.", "",
              "| volume | keep | store | bound max | bound mean | " + ("before: max | before: mean | tighter (max) | " if withb else "")
              + "sampled max | bound / sampled | bricks bounded / at faces | CPU s with the bound" + (" (before)" if withb else "")
              + " |", "|---|---|---|---|---|" + ("---|---|---|" if withb else "") + "---|---|---|---|"]
        for r in mb["rows"]:
            a, b = r["after"], r.get("before")
            sm = r.get("sampled_max")
            L.append(f"| {r['volume']} | {r['keep']} | {r['store']} | {a['fhat_bound_max']:.4g} | {a['fhat_bound_mean']:.4g} | "
                     + (f"{b['fhat_bound_max']:.4g} | {b['fhat_bound_mean']:.4g} | "
                        f"{b['fhat_bound_max'] / a['fhat_bound_max']:.3g}x | " if b else ("- | - | - | " if withb else ""))
                     + (f"{sm:.4g} | {a['fhat_bound_max'] / sm:.3g} | " if sm else "- | - | ")
                     + f"{a['fhat_bound_bricks']} / {a['fhat_bound_faces']} | {a['cpu_seconds']:.3f}"
                     + (f" ({b['cpu_seconds']:.3f})" if b else "") + " |")
    (out_dir / "iso_cast.md").write_text("\n".join(L) + "\n")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        routes = ["cast", "embree", "vtk", "vdb"]
        T0 = rows[0]["threads"]
        sel = [r for r in rows if r["threads"] == T0]
        fig, ax = plt.subplots(figsize=(10, 4))
        w = 0.2
        for i, k in enumerate(routes):
            ys = [r[k]["first_image_seconds"] if k in r and "first_image_seconds" in r[k] else np.nan for r in sel]
            ax.bar(np.arange(len(sel)) + i * w, ys, w, label=k)
        ax.set_xticks(np.arange(len(sel)) + 1.5 * w)
        ax.set_xticklabels([f"{r['volume']}\n{r['keep']} {r['camera']}" for r in sel], fontsize=7)
        ax.set_yscale("log")
        ax.set_ylabel("time to first image (s)")
        ax.set_title(f"{meta['size']}^2 images, {T0} thread(s)")
        ax.legend()
        fig.tight_layout()
        fig.savefig(out_dir / "iso_cast.png", dpi=110)
        plt.close(fig)
        for key, ims in images.items():
            if not key.startswith("skull_5_") and not meta["quick"]:
                continue
            names = list(ims)
            fig, axs = plt.subplots(1, len(names), figsize=(3.2 * len(names), 3.4))
            for ax, nm in zip(np.atleast_1d(axs), names):
                im = ims[nm]
                if im.ndim == 2:
                    im = np.where(np.isfinite(im), im, np.nan)
                    ax.imshow(im, cmap="viridis")
                else:
                    ax.imshow(np.clip(im, 0, 1))
                ax.set_title(nm, fontsize=9)
                ax.axis("off")
            fig.suptitle(key.replace("_", " "))
            fig.tight_layout()
            fig.savefig(out_dir / f"iso_cast_{key}.png", dpi=80)
            plt.close(fig)
    except Exception as ex:  # noqa: BLE001  (the tables stand without the plots)
        print("plot:", ex)
