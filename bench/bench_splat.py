#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Run time against error of X-ray images of oblique orthographic views: footprint splatting.

Volumes: the Gaussian and the skull phantom at --size^3 (db2, 3 levels, kept fractions --keep);
cameras --cameras (wvol --camera text, ';'-separated). Per volume and camera, all through the wvol
CLI in this one run, with --threads threads:
  reference  the dense trilinear integrator on the original volume at a small step (--ref-step):
             the converged reference every image is compared with (total error);
  splat      X-ray by footprint splatting of the kept wavelet functions (the spline model up to
             the tables' interpolation error);
  bricks     X-ray by ray marching the trilinear reconstruction of the kept coefficients (bricks
             reconstructed on demand; a different model from the spline one);
  spline     the exact spline-projected X-ray of the kept functions (slow): rendered at a reduced
             image --spline-image, where splat and the reference are rendered too, so that the
             splat-vs-spline error is measured on equal images. Spline runs are done last, cheapest
             first (their cost predicted from the splat run's function-pixel count at that size),
             and skipped when the total --spline-budget (seconds) would be passed; a run that
             overruns the budget left is killed.
Peer: VTK's vtkFixedPointVolumeRayCastMapper in additive blend mode on the same dense volume
(normalised to [0, 1] where it is not; the wvol reference is then rendered on that volume too) and
the same orthographic camera (wvol's framing reproduced), under xvfb-run. VTK 9.1's fixed-point
mapper has no additive ray function: in that mode it composites front to back without the
sample-distance opacity correction (measured: alpha = 1 - prod(1 - a(u_i)) over its samples). The
opacity table is therefore a(u) = 1 - exp(-k d u) (d its sample distance), so that its alpha is
1 - exp(-k * Riemann sum of the X-ray), and the X-ray is read back as -ln(1 - alpha) / k, alpha from
the mapper's own 15-bit ray-cast image (the 8-bit framebuffer is resampled and coarse; its error is
listed in the JSON too). k is chosen so that the largest optical depth is --vtk-tau. The remaining
scale mismatch (VTK's volume ends at the outer voxel centres, ours half a voxel beyond; sample
placement) is removed by a least-squares scale factor, reported with the row.

Errors: relative RMSE over channel R divided by the largest |value| of the image compared with,
(a) against the exact spline image of the same kept fraction (reduced image; the dense rows
against spline at 100%) and (b) against the converged dense reference at the same image size.
Times: CPU seconds and wall seconds of the render call (wvol --json: render_cpu_seconds,
render_seconds; VTK: one Render() after a set-up frame, the fastest of --vtk-repeat).
Writes bench/results/splat.json, splat.md and splat.png.

Smoke run: bench/bench_splat.py; the real one:
  bench/bench_splat.py --size 256 --image 512 --keep 1,5,20,100 --spline-image 128
"""
import argparse
import json
import math
import os
import pathlib
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
import bench_render as br  # noqa: E402

br.WVOL = os.environ.get("WVOL_BIN", str(ROOT / "build" / "wvol"))  # bench_render's helpers read it
WVOL = br.WVOL
NAN = float("nan")


def wvol_render_limited(vol, n, out, args, threads, limit):
    """br.wvol_render with a wall-clock limit: the run (its own process group) is killed when it
    passes `limit` seconds. Returns (info, wall s, peak MB, error)."""
    cmd = ["/usr/bin/time", "-v", WVOL, "render", vol, "--dims", f"{n}x{n}x{n}", "-o", out, "--json",
           "--threads", threads, *args]
    t0 = time.perf_counter()
    p = subprocess.Popen([str(c) for c in cmd], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    try:
        so, se = p.communicate(timeout=max(limit, 1))
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        return None, time.perf_counter() - t0, NAN, f"killed after {limit:.0f} s (spline budget)"
    dt = time.perf_counter() - t0
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", se)
    mem = int(m.group(1)) / 1024 if m else NAN
    if p.returncode != 0:
        return None, dt, mem, se.strip().splitlines()[-1] if se.strip() else "failed"
    return json.loads(so), dt, mem, None


VTK_SCRIPT = r"""
import ctypes, re, sys, time, numpy as np, vtk
from vtk.util import numpy_support
raw, n, img, k, sd, out, threads, direction, repeat = sys.argv[1:10]
n, img, k, sd, threads, repeat = int(n), int(img), float(k), float(sd), int(threads), int(repeat)
vtk.vtkMultiThreader.SetGlobalMaximumNumberOfThreads(threads)
v = np.fromfile(raw, dtype='<f4')                       # x fastest, as VTK's point order
imgd = vtk.vtkImageData(); imgd.SetDimensions(n, n, n); imgd.SetSpacing(1, 1, 1); imgd.SetOrigin(0, 0, 0)
imgd.GetPointData().SetScalars(numpy_support.numpy_to_vtk(v, deep=True))
lo, hi = float(v.min()), float(v.max())
col = vtk.vtkColorTransferFunction(); col.AddRGBPoint(lo, 1, 1, 1); col.AddRGBPoint(hi, 1, 1, 1)
op = vtk.vtkPiecewiseFunction()
for t in np.linspace(lo, hi, 257):  # per-sample alpha (additive mode: no distance correction)
    op.AddPoint(float(t), float(1 - np.exp(-k * sd * max(t, 0.0))))
prop = vtk.vtkVolumeProperty(); prop.SetColor(col); prop.SetScalarOpacity(op); prop.SetScalarOpacityUnitDistance(1.0)
prop.SetInterpolationTypeToLinear(); prop.ShadeOff()
mapper = vtk.vtkFixedPointVolumeRayCastMapper(); mapper.SetInputData(imgd); mapper.SetNumberOfThreads(threads)
mapper.SetBlendModeToAdditive()
mapper.SetSampleDistance(sd); mapper.SetAutoAdjustSampleDistances(0); mapper.SetImageSampleDistance(1.0)
vol = vtk.vtkVolume(); vol.SetMapper(mapper); vol.SetProperty(prop)
ren = vtk.vtkRenderer(); ren.AddVolume(vol); ren.SetBackground(0, 0, 0)
win = vtk.vtkRenderWindow(); win.SetOffScreenRendering(1); win.AddRenderer(ren); win.SetSize(img, img)
# wvol's orthographic framing (camera.c, wvol_camera_frame): up +z (+y when looking along z),
# the view height fitting the projected box [-1/2, n - 1/2]^3, the eye 2 radii from the centre
d = np.array([float(x) for x in direction.split(",")]); d /= np.linalg.norm(d)
up = np.array([0.0, 1.0, 0.0]) if abs(d[2]) > 0.999999 else np.array([0.0, 0.0, 1.0])
r = np.cross(d, up); r /= np.linalg.norm(r); u = np.cross(r, d)
c = np.full(3, (n - 1) / 2)
corners = np.array([[(n - 0.5 if (i >> a) & 1 else -0.5) for a in range(3)] for i in range(8)]) - c
hu, hv = np.abs(corners @ r).max(), np.abs(corners @ u).max()
radius = np.linalg.norm(corners, axis=1).max()
cam = ren.GetActiveCamera()
cam.SetFocalPoint(*c); cam.SetPosition(*(c - d * 2 * radius)); cam.SetViewUp(*up)
cam.ParallelProjectionOn(); cam.SetParallelScale(max(hv, hu)); cam.SetClippingRange(0.01 * radius, 4 * radius)
win.Render()                      # set-up frame (tables, space leaping)
cpu, wall = [], []
for _ in range(repeat):
    t0 = time.process_time(); w0 = time.perf_counter(); win.Render(); t1 = time.process_time(); w1 = time.perf_counter()
    cpu.append(t1 - t0); wall.append(w1 - w0)
w2i = vtk.vtkWindowToImageFilter(); w2i.SetInput(win); w2i.SetInputBufferTypeToRGB(); w2i.ReadFrontBufferOff(); w2i.Update()
a8 = numpy_support.vtk_to_numpy(w2i.GetOutput().GetPointData().GetScalars()).reshape(img, img, -1)[::-1, :, 0] / 255.0
# the mapper's ray-cast image (unsigned short RGBA, 32767 = 1), bottom row first
ri = mapper.GetRayCastImage()
mx, my = ri.GetImageMemorySize(); ix, iy = ri.GetImageInUseSize(); ox, oy = ri.GetImageOrigin()
vx, vy = ri.GetImageViewportSize()
addr = int(re.search(r"_([0-9a-fA-F]+)_p_void", ri.GetImage()).group(1), 16)
buf = np.frombuffer((ctypes.c_ushort * (mx * my * 4)).from_address(addr), np.uint16).reshape(my, mx, 4)
a16 = np.zeros((vy, vx), np.float64)
a16[oy:oy + iy, ox:ox + ix] = buf[:iy, :ix, 3] / 32767.0
np.savez(out, a16=a16[::-1].astype(np.float32), a8=a8.astype(np.float32))
print(min(cpu), min(wall), vx, vy)
"""


def run_vtk(uraw, n, img, k, sd, out, threads, direction, repeat, tmp):
    script = tmp / "vtk_xray.py"
    script.write_text(VTK_SCRIPT)
    dt, mem, so, se, rc = br.timed(["xvfb-run", "-a", "/usr/bin/python3", script, uraw, n, img, k, sd, out, threads,
                                    direction, repeat])
    if rc != 0:
        return None, None, mem, se.strip().splitlines()[-1] if se.strip() else "failed"
    cpu, wall, vx, vy = so.strip().splitlines()[-1].split()
    if (int(vx), int(vy)) != (img, img):
        return None, None, mem, f"VTK ray-cast image {vx}x{vy}, expected {img}x{img}"
    return float(cpu), float(wall), mem, None


def ratio(a, b):
    return a / b if a and b and b > 0 else NAN


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--image", type=int, default=256)
    ap.add_argument("--keep", default="1,5,20,100", help="kept percentages")
    ap.add_argument("--volumes", default="gaussian,skull")
    ap.add_argument("--cameras", default="ortho dir=1,0.7,0.4;ortho dir=-0.3,1,-0.8", help="';'-separated")
    ap.add_argument("--wavelet", default="db2")
    ap.add_argument("--levels", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1, help="threads of every renderer (default 1)")
    ap.add_argument("--ref-step", type=float, default=0.125, help="converged reference step (voxels)")
    ap.add_argument("--bricks-step", type=float, default=0.5, help="bricks step (voxels)")
    ap.add_argument("--spline-image", type=int, default=128, help="image side of the spline rows")
    ap.add_argument("--spline-budget", type=float, default=300, help="total seconds for the spline rows")
    ap.add_argument("--vtk-step", type=float, default=0.5, help="VTK sample distance (voxels)")
    ap.add_argument("--vtk-tau", type=float, default=2.0, help="VTK: largest optical depth of the image")
    ap.add_argument("--vtk-repeat", type=int, default=3, help="VTK: timed frames after the set-up frame")
    ap.add_argument("--no-vtk", action="store_true")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results"))
    ap.add_argument("--from-json", help="only rewrite splat.md and splat.png from this splat.json")
    a = ap.parse_args()
    outdir = pathlib.Path(a.out); outdir.mkdir(parents=True, exist_ok=True)
    if a.from_json:
        return write_outputs(json.loads(pathlib.Path(a.from_json).read_text()), outdir)
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="bench_splat_"))
    n, img, simg, thr = a.size, a.image, a.spline_image, str(a.threads)
    keeps = [float(k) for k in a.keep.split(",")]
    cameras = [c.strip() for c in a.cameras.split(";") if c.strip()]
    rows, spline_jobs = [], []
    imgs = {}  # (volume, camera, method, keep, size) -> channel R
    t_start = time.perf_counter()
    machine = {"cpus": os.cpu_count(), "threads": a.threads, "uname": " ".join(os.uname()), "wvol": WVOL}

    def row_of(vname, cam, method, keep, size, info, dt, mem, e, **extra):
        row = {"volume": vname, "camera": cam, "method": method, "keep": keep, "image": size, "threads": a.threads,
               "process_wall_s": dt, "peak_mb": mem}
        if e:
            row["error"] = e
        elif info:
            row["cpu_s"] = info.get("render_cpu_seconds")
            row["wall_s"] = info.get("render_seconds")
            # wvol's own keys, less those that would shadow the row's (its "keep" is a fraction)
            for k, val in info.items():
                k = "keep_fraction" if k == "keep" else k
                if k not in row and k not in ("input", "output", "method", "mode"):
                    row[k] = val
        row.update(extra)
        rows.append(row)
        print(json.dumps(row), flush=True)
        return row

    def render(vname, raw, cam, method, keep, size, args):
        """One wvol render; its row, with the error against the converged reference of that size."""
        out = tmp / f"{vname}_{cameras.index(cam)}_{method}_{keep:g}_{size}.exr"
        ka = [] if keep >= 100 else ["--keep", f"{keep:g}%"]
        common = ["--size", f"{size}x{size}", "--camera", cam, "--mode", "xray", "--wavelet", a.wavelet,
                  "--levels", str(a.levels)]
        info, dt, mem, e = br.wvol_render(raw, n, out, common + ["--method", method] + args + ka, thr)
        extra = {}
        if not e:
            R = br.rgba(out)[..., 0]
            imgs[(vname, cam, method, keep, size)] = R
            ref = imgs.get((vname, cam, "reference", 100.0, size))
            if ref is not None:
                extra["rel_rmse_ref"] = br.rel_rmse(R, ref)
        return row_of(vname, cam, method, keep, size, info, dt, mem, e, **extra)

    try:
        for vname in [x for x in a.volumes.split(",") if x]:
            v = br.gaussian(n) if vname == "gaussian" else br.skull(n, tmp)
            raw = tmp / f"{vname}.raw"; br.write_raw(v, raw)
            lo, hi = float(v.min()), float(v.max())
            normalised = lo < 0 or hi > 1
            uraw = raw
            if normalised:  # the VTK peer's volume, u in [0, 1]
                uraw = tmp / f"{vname}_u.raw"
                br.write_raw(np.clip((v - lo) / (hi - lo), 0, 1).astype(np.float32), uraw)
            for cam in cameras:
                sizes = [img] + ([simg] if simg != img else [])
                for size in sizes:
                    render(vname, raw, cam, "reference", 100.0, size, ["--step", str(a.ref_step)])
                for keep in keeps:
                    render(vname, raw, cam, "splat", keep, img, [])
                    render(vname, raw, cam, "bricks", keep, img, ["--step", str(a.bricks_step)])
                    r = render(vname, raw, cam, "splat", keep, simg, []) if simg != img else \
                        next(q for q in reversed(rows) if q["method"] == "splat" and q["keep"] == keep)
                    spline_jobs.append({"volume": vname, "raw": raw, "camera": cam, "keep": keep,
                                        "cost": r.get("samples") or r.get("functions") or 1})
                if a.no_vtk or not shutil.which("xvfb-run") or "ortho" not in cam.split() or "dir=" not in cam:
                    continue
                # the VTK peer, on the dense volume (normalised: the reference rendered on it too)
                direction = cam.split("dir=")[1].split()[0]
                if normalised:
                    out = tmp / "ref_u.exr"
                    info, dt, mem, e = br.wvol_render(uraw, n, out, ["--size", f"{img}x{img}", "--camera", cam, "--mode",
                                                                     "xray", "--method", "reference", "--step",
                                                                     str(a.ref_step)], thr)
                    if e:
                        print("reference of the normalised volume failed:", e)
                        continue
                    RU = br.rgba(out)[..., 0]
                else:
                    RU = imgs[(vname, cam, "reference", 100.0, img)]
                k = a.vtk_tau / max(float(RU.max()), 1e-30)
                out = tmp / "vtk.npz"
                cpu, wall, mem, e = run_vtk(uraw, n, img, k, a.vtk_step, out, a.threads, direction, a.vtk_repeat, tmp)
                extra = {"vtk_step": a.vtk_step, "vtk_tau": a.vtk_tau, "vtk_k": k,
                         "volume_normalised": normalised, "note": "VTK fixed-point, additive blend mode (composites "
                         "without distance correction in VTK 9.1: X-ray read back as -ln(1-alpha)/k); one Render() "
                         "after a set-up frame"}
                if e:
                    row_of(vname, cam, "VTK fixed-point", 100.0, img, None, NAN, mem, e, **extra)
                    continue
                z = np.load(out)
                X = {key: -np.log(np.clip(1 - z[key].astype(np.float64), 1e-12, None)) / k for key in ("a16", "a8")}
                for key in X:
                    s = float(np.sum(X[key] * RU) / max(np.sum(X[key] * X[key]), 1e-300))
                    extra[f"lsq_scale_{key}"] = s
                    extra[f"rel_rmse_ref_unscaled_{key}"] = br.rel_rmse(X[key], RU)
                    extra[f"rel_rmse_ref_{key}"] = br.rel_rmse(s * X[key], RU)
                extra["rel_rmse_ref"] = extra["rel_rmse_ref_a16"]
                extra["lsq_scale"] = extra["lsq_scale_a16"]
                row_of(vname, cam, "VTK fixed-point", 100.0, img, None, NAN, mem, None, cpu_s=cpu, wall_s=wall, **extra)

        # the spline rows, cheapest first, within the budget
        spent, rate = 0.0, None  # rate: spline wall seconds per unit of the splat row's cost (max seen)
        for job in sorted(spline_jobs, key=lambda j: j["cost"]):
            vname, cam, keep = job["volume"], job["camera"], job["keep"]
            left = a.spline_budget - spent
            pred = rate * job["cost"] if rate else None
            if left <= 1 or (pred is not None and pred > left):
                row_of(vname, cam, "spline", keep, simg, None, NAN, NAN, None, skipped=True, predicted_s=pred,
                       note=f"skipped: predicted {pred or NAN:.0f} s, {max(left, 0):.0f} s of the "
                            f"{a.spline_budget:g} s budget left")
                continue
            out = tmp / f"spline_{vname}_{cameras.index(cam)}_{keep:g}.exr"
            ka = [] if keep >= 100 else ["--keep", f"{keep:g}%"]
            args = ["--size", f"{simg}x{simg}", "--camera", cam, "--mode", "xray", "--wavelet", a.wavelet, "--levels",
                    str(a.levels), "--method", "spline"] + ka
            info, dt, mem, e = wvol_render_limited(job["raw"], n, out, args, thr, left)
            spent += dt
            extra = {"predicted_s": pred}
            if not e:
                rate = max(rate or 0, dt / job["cost"])
                R = br.rgba(out)[..., 0]
                imgs[(vname, cam, "spline", keep, simg)] = R
                extra["rel_rmse_ref"] = br.rel_rmse(R, imgs[(vname, cam, "reference", 100.0, simg)])
            row_of(vname, cam, "spline", keep, simg, info, dt, mem, e, **extra)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    # errors against spline, ratios
    for r in rows:
        key = (r["volume"], r["camera"])
        sk = 100.0 if r["method"] in ("reference", "VTK fixed-point") else r["keep"]
        sp = imgs.get((*key, "spline", sk, r["image"]))
        own = imgs.get((*key, r["method"], r["keep"], r["image"]))
        if sp is not None and own is not None and r["method"] != "spline":
            r["rel_rmse_spline"] = br.rel_rmse(own, sp)
            if sk != r["keep"]:
                r["spline_keep"] = sk
        spl = [q for q in rows if q["method"] == "spline" and (q["volume"], q["camera"]) == key and q["keep"] == r["keep"]
               and q["image"] == r["image"] and q.get("cpu_s")]
        if spl and r["method"] == "splat":
            r["cpu_over_spline"] = ratio(r.get("cpu_s"), spl[0]["cpu_s"])
            r["wall_over_spline"] = ratio(r.get("wall_s"), spl[0]["wall_s"])
        vt = [q for q in rows if q["method"] == "VTK fixed-point" and (q["volume"], q["camera"]) == key
              and q["image"] == r["image"] and q.get("cpu_s")]
        if vt and r["method"] != "VTK fixed-point":
            r["cpu_over_vtk"] = ratio(r.get("cpu_s"), vt[0]["cpu_s"])
            r["wall_over_vtk"] = ratio(r.get("wall_s"), vt[0]["wall_s"])
    total = time.perf_counter() - t_start

    res = {"size": n, "image": img, "spline_image": simg, "keep": keeps, "cameras": cameras, "wavelet": a.wavelet,
           "levels": a.levels, "threads": a.threads, "ref_step": a.ref_step, "bricks_step": a.bricks_step,
           "spline_budget_s": a.spline_budget, "vtk_step": a.vtk_step, "vtk_tau": a.vtk_tau,
           "vtk_repeat": a.vtk_repeat, "total_s": total, "machine": machine, "rows": rows,
           "note": "rel_rmse_ref: against the converged dense reference (step ref_step) at the row's image size; "
                   "rel_rmse_spline: against the spline image of the same kept fraction (reference and VTK rows: "
                   "spline at 100%) at the same size; both RMSE over channel R / max |R| of the image compared "
                   "with. VTK rows: X-ray of the volume normalised to [0, 1] where it is not, against wvol's "
                   "reference of that volume, after a least-squares scale (lsq_scale)."}
    (outdir / "splat.json").write_text(json.dumps(res, indent=1))
    write_outputs(res, outdir)


def write_outputs(res, outdir):
    """splat.md and splat.png from the results (also from a saved splat.json: --from-json)."""
    rows, cameras, n, img, simg = res["rows"], res["cameras"], res["size"], res["image"], res["spline_image"]
    a = argparse.Namespace(vtk_step=0.5, vtk_tau=2.0, vtk_repeat=3)  # the defaults, for files without them
    for k in ("wavelet", "levels", "threads", "ref_step", "bricks_step", "vtk_step", "vtk_tau", "vtk_repeat"):
        if k in res:
            setattr(a, k, res[k])
    a.spline_budget = res["spline_budget_s"]
    total = res["total_s"]
    flagged = [r for r in rows if r["method"] == "splat" and r.get("rel_rmse_spline", 0) > 2e-3]
    skipped = [r for r in rows if r.get("skipped") or (r["method"] == "spline" and "error" in r)]


    def f(x, fmt):
        return "" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, fmt)

    lines = [f"# X-ray by footprint splatting: {n}^3 volumes, oblique orthographic views\n",
             f"wvol `{res['machine'].get('wvol', WVOL)}`, {a.wavelet}, {a.levels} levels, {a.threads} thread(s) for every renderer, on a "
             f"{res['machine']['cpus']}-core shared machine (absolute times are noisy; compare within this run). "
             f"Images {img}x{img}; the spline rows and the splat and reference rows beside them at "
             f"{simg}x{simg}. Total run time {total:.0f} s.\n",
             "CPU s / wall s: the render call (wvol `--json` render_cpu_seconds / render_seconds: the volume's "
             "reading and wavelet transform are outside; VTK: one Render() after a set-up frame, fastest of "
             f"{a.vtk_repeat}). rel. RMSE: over channel R, divided by the largest |R| of the image compared with; "
             "'vs spline': the exact spline-projected image of the same kept fraction at the same size (reference "
             f"and VTK: spline at 100%); 'vs ref': the converged dense reference (trilinear, step {a.ref_step}) "
             "of the original volume at the same size (total error). bricks: trilinear reconstruction of the "
             f"kept coefficients, step {a.bricks_step} (a different model from spline/splat). 'splat / spline', "
             "'/ VTK': CPU-time ratios in this run (splat at the spline rows' size against spline; every "
             "full-size row against VTK on the same volume and view).\n",
             "VTK: vtkFixedPointVolumeRayCastMapper with SetBlendModeToAdditive; in VTK 9.1 that mode composites "
             "(alpha = 1 - prod(1 - a_i), no distance correction) rather than summing, so the opacity table is "
             "a(u) = 1 - exp(-k d u) and the X-ray is read back as -ln(1 - alpha)/k from the mapper's 15-bit "
             f"ray-cast image (sample distance {a.vtk_step}, k so that the largest optical depth is {a.vtk_tau}), "
             "on the volume normalised to [0, 1] (skull; the Gaussian already is), compared with wvol's reference "
             "of that volume after a least-squares scale factor (column 'note').\n",
             "| volume | camera | method | kept % | image | CPU s | wall s | rel. RMSE vs spline | rel. RMSE vs ref "
             "| splat / spline CPU | / VTK CPU | note |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    order = {"reference": 0, "splat": 1, "bricks": 2, "spline": 3, "VTK fixed-point": 4}
    group = {"reference": 0, "VTK fixed-point": 2}  # the dense rows first and last, the kept fractions between
    for r in sorted(rows, key=lambda r: (r["volume"], cameras.index(r["camera"]), -r["image"],
                                         group.get(r["method"], 1), r["keep"], order.get(r["method"], 9))):
        note = r.get("error", "") or (r.get("note", "") if r.get("skipped") else "")
        if r["method"] == "VTK fixed-point" and "lsq_scale" in r:
            note = (f"lsq scale {r['lsq_scale']:.4f}; unscaled {r['rel_rmse_ref_unscaled_a16']:.3g}; 8-bit "
                    f"framebuffer {r['rel_rmse_ref_a8']:.3g}")
        if r["method"] == "splat" and r.get("rel_rmse_spline", 0) > 2e-3:
            note = (note + "; " if note else "") + "splat vs spline > 2e-3"
        cam = r["camera"].replace("ortho dir=", "")
        lines.append(f"| {r['volume']} | {cam} | {r['method']} | {r['keep']:g} | {r['image']} | {f(r.get('cpu_s'), '.3f')} "
                     f"| {f(r.get('wall_s'), '.3f')} | {f(r.get('rel_rmse_spline'), '.3g')} | "
                     f"{f(r.get('rel_rmse_ref'), '.3g')} | {f(r.get('cpu_over_spline'), '.3g')} | "
                     f"{f(r.get('cpu_over_vtk'), '.3g')} | {note} |")
    lines += ["", f"Spline runs: {sum(1 for r in rows if r['method'] == 'spline' and r.get('cpu_s'))} done, "
                  f"{len(skipped)} skipped or stopped by the {a.spline_budget:g} s budget."]
    if flagged:
        lines.append("Splat rows whose error against spline exceeds 2e-3: " + "; ".join(
            f"{r['volume']} {r['camera']} {r['keep']:g}% ({r['rel_rmse_spline']:.3g})" for r in flagged) + ".")
    (outdir / "splat.md").write_text("\n".join(lines) + "\n")

    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        markers = {"splat": "o", "bricks": "s", "spline": "D", "VTK fixed-point": "^"}
        colours = {}
        fig, axes = plt.subplots(1, 3, figsize=(18, 5.5))
        panels = [(axes[0], img, "rel_rmse_ref", f"{img}x{img}: against the converged dense reference"),
                  (axes[1], simg, "rel_rmse_ref", f"{simg}x{simg}: against the converged dense reference"),
                  (axes[2], simg, "rel_rmse_spline", f"{simg}x{simg}: against the exact spline image")]
        for ax, size, key, title in panels:
            for method, mk in markers.items():
                pts = [r for r in rows if r["method"] == method and r["image"] == size and r.get("cpu_s")
                       and r.get(key)]  # the reference against itself (0) left out
                for r in pts:
                    case = f"{r['volume']}, {r['camera'].replace('ortho dir=', '')}"
                    colours.setdefault(case, f"C{len(colours)}")
                    ax.loglog(r["cpu_s"], r[key], mk, color=colours[case], ms=7, alpha=0.85)
            if key == "rel_rmse_ref":  # the converged reference (error 0 by definition): its time, dotted
                for r in rows:
                    if r["method"] == "reference" and r["image"] == size and r.get("cpu_s"):
                        case = f"{r['volume']}, {r['camera'].replace('ortho dir=', '')}"
                        colours.setdefault(case, f"C{len(colours)}")
                        ax.axvline(r["cpu_s"], color=colours[case], ls=":", lw=1)
            ax.set_title(f"{title} ({n}^3, {res['threads']} thread(s))", fontsize=9)
            ax.set_xlabel("render CPU time (s)"); ax.set_ylabel("relative RMSE")
            ax.grid(True, which="both", alpha=0.3)
        handles = [plt.Line2D([], [], ls="", marker=mk, color="k", label=m) for m, mk in markers.items()]
        handles.append(plt.Line2D([], [], ls=":", color="k", label="converged reference's time"))
        handles += [plt.Line2D([], [], ls="", marker="s", color=c, label=case) for case, c in colours.items()]
        axes[0].legend(handles=handles, fontsize=7)
        fig.tight_layout(); fig.savefig(outdir / "splat.png", dpi=90)
    except Exception as ex:
        print("plot skipped:", ex)
    print((outdir / "splat.md").read_text())


if __name__ == "__main__":
    sys.exit(main())
