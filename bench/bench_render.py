#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Run time against image error for every render method and mode (issue 5).

Volumes: the Gaussian and a skull-like phantom at --size^3; images --image^2; kept fractions
--keep. Methods: reference (dense), bricks (from the store, bricks reconstructed on demand),
axis (X-ray along an axis), spline (exact, slow: capped, see --spline-budget and --spline-keep). Every image is compared with the converged trilinear reference of the original volume
(total error, DESIGN.md section 8) as relative RMSE over all pixels and channels; the wavelet
model's own difference (spline at 100%) is listed too. In the same run: OpenVDB's vdb_render on the
same volume written as .vdb and VTK's vtkFixedPointVolumeRayCastMapper under xvfb-run, both in an
opacity-only setting matched to ours (white emission, kappa linear in the value), compared on
alpha, at each of --peer-threads; both volumes, normalised to [0, 1] for the peers. Peak memory is the
child's maximum resident set (/usr/bin/time -v, the whole process: loading and transforming the
volume included) and, for wvol, the peak resident size during the render call alone
(rss_peak_render_mib, the peak counter reset just before it) and the library's own count of what
the render allocated (render_bytes) beside the store's size (store_bytes).
Writes bench/results/render.json, render.md and render.png; `--suite ct` runs the realistic suite instead
(bench/render_ct.py: noisy anisotropic CT heads, CT ramps, VTK framed alike; render_ct.*).

Defaults are small enough for a smoke test; the issue's run is
  bench/bench_render.py --size 256 --image 512 --keep 1,5,20,100
"""
import argparse
import json
import math
import os
import pathlib
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import time
import zlib

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
WVOL = os.environ.get("WVOL_BIN", str(ROOT / "build" / "wvol"))


# ---- volumes ---------------------------------------------------------------------------------
def gaussian(n):
    x = np.arange(n) - (n - 1) / 2
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    return np.exp(-0.5 * ((X / (n / 6)) ** 2 + (Y / (n / 5)) ** 2 + (Z / (n / 7)) ** 2)).astype(np.float32)


def skull(n, tmp):
    """The project's skull phantom through `wvol synth` when it exists, else a stand-in shell."""
    out = tmp / "skull_synth.raw"
    r = subprocess.run([WVOL, "synth", "skull", "--size", str(n), "--spacing", "1", "-o", str(out)], capture_output=True)
    if r.returncode == 0 and out.exists():
        return np.fromfile(out, dtype="<f4").reshape(n, n, n).transpose(2, 1, 0)
    print("wvol synth skull failed; using a stand-in shell:", r.stderr.decode().strip())
    x = (np.arange(n) - (n - 1) / 2) / (n / 2)
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    r = np.sqrt((X / 0.8) ** 2 + (Y / 0.95) ** 2 + (Z / 0.85) ** 2)
    v = np.full((n, n, n), -1000.0, np.float32)
    v[r < 0.95] = 40.0
    shell = (r > 0.8) & (r < 0.88 + 0.03 * np.sin(6 * X))
    v[shell] = 1200.0
    v[((X + 0.3) ** 2 + (Y - 0.6) ** 2 + (Z - 0.1) ** 2) < 0.03] = -1000.0  # an eye socket
    v[((X - 0.3) ** 2 + (Y - 0.6) ** 2 + (Z - 0.1) ** 2) < 0.03] = -1000.0
    return v


def write_raw(v, path):
    v.transpose(2, 1, 0).astype("<f4").tofile(path)  # x fastest


# ---- EXR (scanline, float/half, no/zip compression) -----------------------------------------
def read_exr(path):
    data = pathlib.Path(path).read_bytes()
    assert data[:4] == b"\x76\x2f\x31\x01", "not an EXR"
    pos, attrs = 8, {}
    while data[pos] != 0:
        e = data.index(b"\0", pos); name = data[pos:e].decode(); pos = e + 1
        e = data.index(b"\0", pos); typ = data[pos:e].decode(); pos = e + 1
        size = struct.unpack_from("<i", data, pos)[0]; pos += 4
        attrs[name] = (typ, data[pos:pos + size]); pos += size
    pos += 1
    chans, b = [], attrs["channels"][1]
    i = 0
    while b[i] != 0:
        e = b.index(b"\0", i); nm = b[i:e].decode(); i = e + 1
        ptype = struct.unpack_from("<i", b, i)[0]; i += 16
        chans.append((nm, ptype))
    x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"][1])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    comp = attrs["compression"][1][0]
    lines = {0: 1, 2: 1, 3: 16}[comp]
    nchunks = (h + lines - 1) // lines
    offsets = struct.unpack_from(f"<{nchunks}Q", data, pos)
    out = {nm: np.zeros((h, w), np.float32) for nm, _ in chans}
    for off in offsets:
        y, size = struct.unpack_from("<ii", data, off)
        raw = data[off + 8: off + 8 + size]
        nl = min(lines, y1 + 1 - y)
        expect = sum(w * (2 if pt == 1 else 4) for _, pt in chans) * nl
        if comp and size < expect:
            t = bytearray(zlib.decompress(raw))
            arr = np.frombuffer(bytes(t), np.uint8).astype(np.int32)
            arr = (np.cumsum(arr - 128 * (np.arange(arr.size) > 0)) % 256).astype(np.uint8)
            half = (arr.size + 1) // 2
            inter = np.empty(arr.size, np.uint8)
            inter[0::2] = arr[:half]; inter[1::2] = arr[half:]
            raw = inter.tobytes()
        p = 0
        for li in range(nl):
            for nm, pt in chans:
                dt = "<f2" if pt == 1 else "<f4"
                n = w * (2 if pt == 1 else 4)
                out[nm][y - y0 + li] = np.frombuffer(raw[p:p + n], dt).astype(np.float32)
                p += n
    return out


def rgba(path):
    c = read_exr(path)
    return np.stack([c.get(k, np.zeros_like(c["A"])) for k in "RGBA"], -1)


def rel_rmse(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)) / max(np.abs(b).max(), 1e-30))


# ---- runs ------------------------------------------------------------------------------------
def timed(cmd, env=None, timeout=3600):
    """Runs under /usr/bin/time -v; returns (seconds, peak RSS MB, stdout, stderr, rc)."""
    t0 = time.perf_counter()
    r = subprocess.run(["/usr/bin/time", "-v", *map(str, cmd)], capture_output=True, text=True, env=env,
                       timeout=timeout)
    dt = time.perf_counter() - t0
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stderr)
    u = re.search(r"User time \(seconds\): ([0-9.]+)", r.stderr)
    sy = re.search(r"System time \(seconds\): ([0-9.]+)", r.stderr)
    timed.cpu = float(u.group(1)) + float(sy.group(1)) if u and sy else float("nan")
    return dt, (int(m.group(1)) / 1024 if m else float("nan")), r.stdout, r.stderr, r.returncode


def wvol_render(vol, n, out, args, threads):
    cmd = [WVOL, "render", vol, "--dims", f"{n}x{n}x{n}", "-o", out, "--json", "--threads", threads, *args]
    dt, mem, so, se, rc = timed(cmd)
    if rc != 0:
        return None, dt, mem, se.strip().splitlines()[-1] if se.strip() else "failed"
    info = json.loads(so)
    return info, dt, mem, None


WVOL_FIELDS = ("reconstruct_cpu_seconds", "kept", "pieces", "functions", "samples", "clamped", "bricks_built", "bricks_bound_skipped",
               "render_bytes", "store_bytes", "rss_before_render_mib", "rss_peak_render_mib", "brick", "skip_bound",
               "skipped_tolerance", "repeat", "render_cpu_seconds_max")


def vdb_write(v, path):
    import pyopenvdb as vdb
    g = vdb.FloatGrid()
    g.copyFromArray(v.astype(np.float32))  # numpy (i, j, k) -> voxel (i, j, k)
    g.name = "density"
    g.transform = vdb.createLinearTransform(voxelSize=1.0)
    vdb.write(str(path), grids=[g])


def run_vdb(vdbpath, n, img, out, kappa, threads):
    c = (n - 1) / 2 + 0.5  # vdb's voxel i covers [i, i+1): shift to our cell-centred box
    cmd = ["vdb_render", vdbpath, out, "-res", f"{img}x{img}", "-camera", "ortho", "-frame", str(n),
           "-translate", f"{c},{c},{c + 2 * n}", "-lookat", f"{c},{c},{c}", "-up", "0,1,0",
           "-absorb", f"{kappa},{kappa},{kappa}", "-scatter", "0,0,0", "-step", "0.5", "-cutoff", "1e-6",
           "-compression", "none", "-cpus", str(threads)]
    return timed(cmd)


VTK_SCRIPT = r"""
import sys, time, numpy as np, vtk
from vtk.util import numpy_support
raw, n, img, kappa, out, threads = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), sys.argv[5], int(sys.argv[6])
view = sys.argv[7] if len(sys.argv) > 7 else "+z"   # "+z", or "persp X,Y,Z": wvol's "persp dir=X,Y,Z"
repeat = int(sys.argv[8]) if len(sys.argv) > 8 else 1  # timed frames after the set-up frame: the fastest kept
vtk.vtkMultiThreader.SetGlobalMaximumNumberOfThreads(threads)
v = np.fromfile(raw, dtype='<f4')
imgd = vtk.vtkImageData(); imgd.SetDimensions(n, n, n); imgd.SetSpacing(1, 1, 1); imgd.SetOrigin(0, 0, 0)
imgd.GetPointData().SetScalars(numpy_support.numpy_to_vtk(v, deep=True))
lo, hi = float(v.min()), float(v.max())
col = vtk.vtkColorTransferFunction(); col.AddRGBPoint(lo, 1, 1, 1); col.AddRGBPoint(hi, 1, 1, 1)
op = vtk.vtkPiecewiseFunction()
for t in np.linspace(lo, hi, 64):   # alpha per unit length from kappa(value) = kappa * value
    op.AddPoint(float(t), float(1 - np.exp(-kappa * max(t, 0))))
prop = vtk.vtkVolumeProperty(); prop.SetColor(col); prop.SetScalarOpacity(op); prop.SetScalarOpacityUnitDistance(1.0)
prop.SetInterpolationTypeToLinear(); prop.ShadeOff()
mapper = vtk.vtkFixedPointVolumeRayCastMapper(); mapper.SetInputData(imgd); mapper.SetNumberOfThreads(threads)
mapper.SetSampleDistance(0.5); mapper.SetAutoAdjustSampleDistances(0)
vol = vtk.vtkVolume(); vol.SetMapper(mapper); vol.SetProperty(prop)
ren = vtk.vtkRenderer(); ren.AddVolume(vol); ren.SetBackground(0, 0, 0)
win = vtk.vtkRenderWindow(); win.SetOffScreenRendering(1); win.AddRenderer(ren); win.SetSize(img, img)
cam = ren.GetActiveCamera(); c = (n - 1) / 2
if view == "+z":
    cam.SetFocalPoint(c, c, c); cam.SetPosition(c, c, c + 2 * n); cam.SetViewUp(0, 1, 0)
    cam.ParallelProjectionOn(); cam.SetParallelScale(n / 2); cam.SetClippingRange(0.1, 10 * n)
else:
    # wvol's perspective framing (camera.c): the eye on the view direction d through the box
    # centre, at radius / sin(fov / 2) with the box [-1/2, n - 1/2]^3's half diagonal as radius,
    # up +z, vertical field of view 30 degrees
    d = np.array([float(x) for x in view.split()[1].split(",")]); d /= np.linalg.norm(d)
    radius = n * np.sqrt(3) / 2; dist = radius / np.sin(np.radians(15))
    cam.SetFocalPoint(c, c, c); cam.SetPosition(*(np.array([c, c, c]) - d * dist)); cam.SetViewUp(0, 0, 1)
    cam.ParallelProjectionOff(); cam.SetViewAngle(30); cam.SetClippingRange(dist - 2 * radius, dist + 2 * radius)
win.Render()                      # first frame: set-up (textures, min/max volume)
cpu, wall = [], []
for _ in range(repeat):
    t0 = time.process_time(); w0 = time.perf_counter(); win.Render(); t1 = time.process_time(); w1 = time.perf_counter()
    cpu.append(t1 - t0); wall.append(w1 - w0)
w2i = vtk.vtkWindowToImageFilter(); w2i.SetInput(win); w2i.SetInputBufferTypeToRGB(); w2i.ReadFrontBufferOff(); w2i.Update()
a = numpy_support.vtk_to_numpy(w2i.GetOutput().GetPointData().GetScalars()).reshape(img, img, -1)[::-1, :, 0]
np.save(out, a.astype(np.float32) / 255.0)
print(min(cpu), min(wall))
"""


def run_vtk(rawpath, n, img, out, kappa, threads, tmp, view="+z", repeat=1):
    script = tmp / "vtk_render.py"
    script.write_text(VTK_SCRIPT)
    dt, mem, so, se, rc = timed(["xvfb-run", "-a", "/usr/bin/python3", script, rawpath, n, img, kappa, out, threads,
                                 view, repeat])
    if rc != 0:
        return None, None, mem, se.strip().splitlines()[-1] if se.strip() else "failed"
    cpu, wall = map(float, so.strip().splitlines()[-1].split())
    return cpu, wall, mem, None


def equal_error_table(rows):
    """The issue's first speed goal, read off the rows: for each wvol row that is not the dense
    reference, the cheapest reference row (same volume, mode, thread count) whose error is no larger,
    and the ratio of their CPU times. Rows more accurate than every reference row are left out (no
    reference row to compare with at equal error)."""
    out = ["", "## At equal image error: each wvol path against the dense reference integrator\n",
           "For each row below, the cheapest reference row (dense volume, fixed step, same volume, mode and "
           "threads, in the same run) whose rel. RMSE is at most the row's; 'ref / row' > 1 means the row is "
           "faster than the reference at equal or lower error. When every reference row is more accurate "
           "than the row, the reference's coarsest step stands in and the cell says 'coarsest ref more "
           "accurate': the reference could take a coarser step at that error, so the ratio overstates the "
           "row's advantage; run with coarser --ref-steps to bracket every row).\n",
           "| volume | mode | method | kept % | CPU s | rel. RMSE | cheapest reference at <= that error | ref CPU s "
           "| ref / row |", "|---|---|---|---|---|---|---|---|---|"]
    def is_ref(r):
        return str(r.get("method", "")).startswith(("reference step", "wvol reference"))
    for r in rows:
        if is_ref(r) or "rel_rmse" not in r or not r.get("cpu_s") or "predicted_full_s" in r:
            continue
        if str(r.get("method", "")).startswith(("VTK", "vdb")):
            continue
        refs = [q for q in rows if is_ref(q) and "converged" not in q["method"] and q.get("volume") == r.get("volume")
                and q.get("mode") == r.get("mode") and q.get("threads") == r.get("threads") and q.get("cpu_s")
                and q.get("camera", "+z") == r.get("camera", "+z") and "rel_rmse" in q]
        if not refs:
            continue
        ok = [q for q in refs if q["rel_rmse"] <= r["rel_rmse"]]
        if not ok:
            continue
        note = ""
        best = min(ok, key=lambda q: q["cpu_s"])
        if all(q["rel_rmse"] <= r["rel_rmse"] for q in refs):
            note = " (coarsest ref more accurate)"
        out.append(f"| {r.get('volume')} | {r.get('mode')} | {r.get('method')} | {r.get('keep')} | {r['cpu_s']:.3f} | "
                   f"{r['rel_rmse']:.3g} | {best['method']}{note} | {best['cpu_s']:.3f} | "
                   f"{best['cpu_s'] / r['cpu_s']:.2f} |")
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=48)
    ap.add_argument("--image", type=int, default=64)
    ap.add_argument("--keep", default="1,5,20,100", help="kept percentages")
    ap.add_argument("--volumes", default="gaussian,skull")
    ap.add_argument("--threads", type=int, default=1, help="threads for every renderer (default 1)")
    ap.add_argument("--spline-j", default="2,4")
    ap.add_argument("--ref-step", type=float, default=0.05, help="converged reference step (voxels)")
    ap.add_argument("--spline-budget", type=float, default=600, help="skip spline runs predicted beyond (s)")
    ap.add_argument("--spline-keep", default="", help="kept percentages for the spline rows (default: all of --keep)")
    ap.add_argument("--ref-steps", default="1,0.5,0.25",
                    help="steps (voxels) of the reference rows: the curve every other method is compared with "
                         "at equal error (the equal-error table)")
    ap.add_argument("--bricks-steps", default="0.5,1", help="steps (voxels) of the bricks rows")
    ap.add_argument("--peer-steps", default="0.5,1,2", help="steps of the bricks rows beside the peers")
    ap.add_argument("--peer-threads", default="1,2", help="thread counts of the peer comparison")
    ap.add_argument("--peer-repeat", type=int, default=3,
                    help="the peer table's wvol rows and VTK each render this many frames in one process "
                         "(VTK after its set-up frame) and keep the fastest: on a shared machine one frame's "
                         "time varies by 10-25%%")
    ap.add_argument("--peer-skip", default="1e-3",
                    help="skip tolerances of extra bricks rows beside the peers (each pixel's alpha within it of "
                         "the unskipped image; '' for none)")
    ap.add_argument("--peer-cameras", default="+z;persp dir=1,0.7,0.4",
                    help="';'-separated wvol cameras of the peer comparison (+z, or persp dir=X,Y,Z: VTK matched)")
    ap.add_argument("--peers-only", action="store_true", help="only the comparison with the peers")
    ap.add_argument("--no-peers", action="store_true", help="leave the comparison with the peers out")
    ap.add_argument("--run-tag", default="", help="a tag stored in every row (tables merged from several runs "
                    "pair each row with the VTK row of its own run)")
    ap.add_argument("--no-vdb", action="store_true", help="leave vdb_render out (it can take many minutes)")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results"))
    ap.add_argument("--resume", help="a previous run's stdout: its rows are kept and their runs skipped")
    ap.add_argument("--suite", default="phantoms", choices=["phantoms", "ct"],
                    help="phantoms: the tables above (render.*); ct: the realistic suite, noisy anisotropic CT "
                         "heads with CT ramps against VTK (bench/render_ct.py, render_ct.*)")
    ap.add_argument("--ct-volumes", default="ct,skull-noisy", help="ct suite: volumes (ct, skull-noisy)")
    ap.add_argument("--ct-tfs", default="ct-bone,ct-soft", help="ct suite: transfer-function presets")
    ap.add_argument("--ct-cameras", default="+z;+y;persp dir=1,0.7,0.4", help="ct suite: ';'-separated cameras")
    ap.add_argument("--ct-steps", default="0.5,1,2,4", help="ct suite: steps (voxels of the smallest spacing); VTK "
                    "runs at the first")
    ap.add_argument("--ct-ref-step", type=float, default=0.05, help="ct suite: converged reference step")
    ap.add_argument("--ct-extra", default="--termination 0.0078;--preintegrate",
                    help="ct suite: ';'-separated extra option sets of more bricks rows (default: VTK's termination "
                         "threshold 0xff/0x7fff; pre-integration)")
    ap.add_argument("--ct-scale", type=float, default=1, help="ct suite: divide the sizes by this (smoke tests)")
    ap.add_argument("--no-vtk", action="store_true", help="ct suite: leave VTK out")
    ap.add_argument("--ct-no-shading", action="store_true",
                    help="ct suite: leave the shading figure (render_ct_shading.png) as it is")
    ap.add_argument("--ct-frames", type=int, default=4,
                    help="ct suite: frames per run through one render context (wvol) or one window (VTK): the first "
                         "(set-up included) and the later ones, the camera turned by --ct-orbit between frames")
    ap.add_argument("--ct-orbit", type=float, default=1.0,
                    help="ct suite: degrees the camera turns between frames about its up axis (the last frame is the "
                         "camera's own view)")
    ap.add_argument("--ct-baseline", default="",
                    help="ct suite: another wvol program (e.g. main's build) whose bricks rows at VTK's step, at the "
                         "default termination and at VTK's, run in the same run, labelled '(baseline)'")
    a = ap.parse_args()
    if a.ct_frames < 2:  # the later frames' timings are the point: wvol render --repeat 1 reports none
        ap.error("--ct-frames must be at least 2 (the first frame and the later ones are timed apart)")
    outdir = pathlib.Path(a.out); outdir.mkdir(parents=True, exist_ok=True)
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="bench_render_"))
    n, img, thr = a.size, a.image, str(a.threads)
    keeps = [float(k) for k in a.keep.split(",")]
    rsteps = [float(x) for x in a.ref_steps.split(",")]
    if a.suite == "ct":
        from render_ct import ct_suite
        try:
            ct_suite(a, WVOL, timed, rgba, tmp, outdir, {"cpus": os.cpu_count(), "uname": " ".join(os.uname())})
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        return 0
    rows = []
    if a.resume:
        for line in pathlib.Path(a.resume).read_text().splitlines():
            if line.startswith("{"):
                rows.append(json.loads(line))
    done = {(r.get("volume"), r.get("mode"), r.get("method"), r.get("keep")) for r in rows}

    def have(vname, mode, method, keep):
        return (vname, mode, method, keep) in done

    machine = {"cpus": os.cpu_count(), "threads": a.threads, "uname": " ".join(os.uname())}
    try:
        for vname in [x for x in a.volumes.split(",") if x]:  # --volumes "": only tabulate --resume rows
            v = gaussian(n) if vname == "gaussian" else skull(n, tmp)
            raw = tmp / f"{vname}.raw"; write_raw(v, raw)
            tf = "gaussian" if vname == "gaussian" else "ct-soft"
            diag = n * math.sqrt(3)
            for mode in [] if a.peers_only else ["xray", "absorption", "absorption-linear"]:
                # the runs of this mode; a resumed run's rows are kept and their runs skipped
                skeeps = [float(x) for x in a.spline_keep.split(",")] if a.spline_keep else keeps
                bsteps = [float(x) for x in a.bricks_steps.split(",")]
                plan = [(f"reference step={a.ref_step} (converged)", 100)] + [(f"reference step={st}", 100)
                                                                            for st in rsteps]
                for keep in keeps:
                    plan += [("axis", keep)] if mode == "xray" else []
                    plan += [(f"bricks step={st}", keep) for st in bsteps]
                    plan += [(f"spline J={J}", keep) for J in a.spline_j.split(",") if keep in skeeps]
                if all(have(vname, mode, m, k) for m, k in plan):
                    continue
                common = ["--size", f"{img}x{img}", "--camera", "+z", "--mode", mode, "--tf", tf]
                ref = tmp / f"ref_{vname}_{mode}.exr"
                info, dt, mem, e = wvol_render(raw, n, ref, common + ["--method", "reference", "--step", str(a.ref_step)], thr)
                if e: print("reference failed:", e); continue
                R = rgba(ref)
                small_ref = {}

                def ref_of(extra):
                    ps = (extra or {}).get("image", img)
                    return small_ref[ps] if ps != img else R

                def record(method, keep, out, info, dt, mem, e, extra=None):
                    row = {"volume": vname, "mode": mode, "method": method, "keep": keep, "wall_s": dt,
                           "peak_mb": mem}
                    if e:
                        row["error"] = e
                    else:
                        row["render_s"] = info.get("render_seconds") if info else dt
                        row["cpu_s"] = info.get("render_cpu_seconds") if info else timed.cpu
                        row["rel_rmse"] = rel_rmse(rgba(out), ref_of(extra))
                        for k in WVOL_FIELDS:
                            if info and k in info: row[k] = info[k]
                    row.update(extra or {})
                    rows.append(row)
                    print(json.dumps(row), flush=True)

                if not have(vname, mode, f"reference step={a.ref_step} (converged)", 100):
                    record(f"reference step={a.ref_step} (converged)", 100, ref, info, dt, mem, None, {"step": a.ref_step})
                for step in rsteps:
                    if have(vname, mode, f"reference step={step}", 100):
                        continue
                    out = tmp / "o.exr"
                    info, dt, mem, e = wvol_render(raw, n, out, common + ["--method", "reference", "--step", str(step)], thr)
                    record(f"reference step={step}", 100, out, info, dt, mem, e, {"step": step})
                for keep in keeps:
                    ka = [] if keep >= 100 else ["--keep", f"{keep}%"]
                    if mode == "xray" and not have(vname, mode, "axis", keep):
                        out = tmp / "o.exr"
                        info, dt, mem, e = wvol_render(raw, n, out, common + ["--method", "axis"] + ka, thr)
                        record("axis", keep, out, info, dt, mem, e)
                    for step in bsteps:
                        if have(vname, mode, f"bricks step={step}", keep):
                            continue
                        out = tmp / "o.exr"
                        info, dt, mem, e = wvol_render(raw, n, out, common + ["--method", "bricks", "--step", str(step)] + ka, thr)
                        record(f"bricks step={step}", keep, out, info, dt, mem, e, {"step": step})
                    if keep not in skeeps:
                        continue
                    for J in a.spline_j.split(","):
                        if have(vname, mode, f"spline J={J}", keep):
                            continue
                        # pilot at 1/8 of the pixels per side: run full size only if it fits the budget
                        ps = max(img // 8, 8)
                        pc = ["--size", f"{ps}x{ps}"] + common[2:]
                        if ps not in small_ref:
                            sref = tmp / f"sref_{ps}.exr"
                            wvol_render(raw, n, sref, pc + ["--method", "reference", "--step", str(a.ref_step)], thr)
                            small_ref[ps] = rgba(sref)
                        out = tmp / "o.exr"
                        info, dt, mem, e = wvol_render(raw, n, out, pc + ["--method", "spline", "--spline-j", J] + ka, thr)
                        pred = (info["render_cpu_seconds"] if info else dt) * (img / ps) ** 2
                        if e or pred > a.spline_budget or ps == img:
                            row_extra = {"J": int(J), "image": ps, "predicted_full_s": pred}
                            record(f"spline J={J}", keep, out, info, dt, mem, e, row_extra)
                            continue
                        info, dt, mem, e = wvol_render(raw, n, out, common + ["--method", "spline", "--spline-j", J] + ka, thr)
                        record(f"spline J={J}", keep, out, info, dt, mem, e, {"J": int(J), "image": img})
            if a.no_peers:
                continue
            # peers, opacity-only: kappa(u) = k u per voxel length, white emission, on the volume
            # normalised to u in [0, 1] (the Gaussian already is), so vdb's density and VTK's scalar
            # mean the same as ours
            k = 8.0 / diag
            lo, hi = float(v.min()), float(v.max())
            u = np.clip((v - lo) / (hi - lo), 0, 1).astype(np.float32) if (lo < 0 or hi > 1) else v
            uraw = tmp / f"{vname}_u.raw"; write_raw(u, uraw)
            tfp = tmp / "peer_tf.txt"
            tfp.write_text(f"units world\n0 1 1 1 0\n1 1 1 1 {k}\n")
            for pcam in [c for c in a.peer_cameras.split(";") if c]:
                pc = ["--size", f"{img}x{img}", "--camera", pcam, "--tf", tfp]
                cam_note = "" if pcam == "+z" else f" ({pcam})"
                ref = tmp / "ref_peer.exr"
                info, dt, mem, e = wvol_render(uraw, n, ref, pc + ["--method", "reference", "--step", str(a.ref_step)], thr)
                if e:
                    print("peer reference failed:", e)
                    continue
                RA = rgba(ref)[..., 3]
                print(f"peer reference ({vname}, {pcam}):", info["render_cpu_seconds"], "CPU s", flush=True)

                def peer_row(method, threads, keep, **kw):
                    row = {"volume": vname, "mode": "opacity-only", "method": f"{method}{cam_note} [{threads} thr]",
                           "threads": threads, "keep": keep, "camera": pcam}
                    if a.run_tag:
                        row["run"] = a.run_tag
                    row.update(kw)
                    rows.append(row)
                    print(json.dumps(row), flush=True)

                for pt in [int(x) for x in a.peer_threads.split(",")]:
                    runs = [(f"wvol reference step={st}", ["--method", "reference", "--step", str(st)], 100)
                            for st in a.peer_steps.split(",")]
                    runs += [(f"wvol bricks step={st}", ["--method", "bricks", "--step", str(st), "--keep", "5%"], 5)
                             for st in a.peer_steps.split(",")]
                    # the same with a skip tolerance: the store's near-transparent ringing skipped
                    # within a stated per-pixel bound (docs/render.md, "Skip tolerance")
                    runs += [(f"wvol bricks step={st} skip={tol}", ["--method", "bricks", "--step", str(st), "--keep",
                                                                    "5%", "--skip-tolerance", tol], 5)
                             for tol in [t for t in a.peer_skip.split(",") if t] for st in a.peer_steps.split(",")]
                    # the reference integrator on the dense reconstruction of the same 5% store: the
                    # same image as bricks up to rounding, its price the inverse transform plus the
                    # render (reconstruct_cpu_seconds is added to the row's CPU time)
                    runs += [(f"wvol reference of 5% step={st}", ["--method", "reference", "--step", str(st), "--keep", "5%"],
                              5) for st in a.peer_steps.split(",")]
                    for name, args, keep in runs:
                        if have(vname, "opacity-only", f"{name}{cam_note} [{pt} thr]", keep):
                            continue
                        out = tmp / "o.exr"
                        # each frame a separate call (--one-shot), as this table has always timed
                        info, dt, mem, e = wvol_render(uraw, n, out, pc + args + ["--repeat", str(a.peer_repeat),
                                                                                  "--one-shot"], str(pt))
                        if e:
                            peer_row(name, pt, keep, error=e)
                            continue
                        extra = {k2: info[k2] for k2 in WVOL_FIELDS if k2 in info}
                        cpu = info["render_cpu_seconds"] + info.get("reconstruct_cpu_seconds", 0)
                        if "reconstruct_cpu_seconds" in info:
                            extra["note"] = "CPU s: dense reconstruction + render"
                        peer_row(name, pt, keep, wall_s=dt, render_s=info["render_seconds"],
                                 cpu_s=cpu, peak_mb=mem, rel_rmse=rel_rmse(rgba(out)[..., 3], RA),
                                 **extra)
                    if shutil.which("vdb_render") and not a.no_vdb and pcam == "+z":
                        try:
                            vp = tmp / "g.vdb"
                            if not vp.exists(): vdb_write(u, vp)
                            out = tmp / "vdb.exr"
                            dt, mem, so, se, rc = run_vdb(vp, n, img, out, k, pt)
                            kw = {"wall_s": dt, "render_s": dt, "cpu_s": timed.cpu, "peak_mb": mem,
                                  "note": "whole process: reading the .vdb included"}
                            if rc == 0: kw["rel_rmse"] = rel_rmse(rgba(out)[..., 3], RA)
                            else: kw["error"] = se.strip().splitlines()[-1] if se.strip() else "failed"
                            peer_row("vdb_render", pt, 100, **kw)
                        except Exception as ex:  # pyopenvdb missing or failing
                            peer_row("vdb_render", pt, 100, error=repr(ex))
                    if shutil.which("xvfb-run"):
                        out = tmp / "vtk.npy"
                        vview = "+z" if pcam == "+z" else "persp " + pcam.split("dir=")[1].split()[0]
                        cpu, wall, mem, e = run_vtk(uraw, n, img, out, k, pt, tmp, vview, a.peer_repeat)
                        if e: peer_row("VTK fixed-point", pt, 100, peak_mb=mem, error=e)
                        else: peer_row("VTK fixed-point", pt, 100, render_s=wall, cpu_s=cpu, peak_mb=mem,
                                       rel_rmse=rel_rmse(np.load(out), RA), note="one Render(), set-up frame excluded")
            (tmp / "g.vdb").unlink(missing_ok=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    res = {"size": n, "image": img, "machine": machine, "rows": rows,
           "note": "rel_rmse: image against the converged trilinear reference of the original volume "
                   "(total error); opacity-only rows compare alpha only"}
    (outdir / "render.json").write_text(json.dumps(res, indent=1))
    nan = float("nan")

    def mib(r, k):
        return r.get(k, nan) / 2**20 if k in r else nan

    def render_rss(r):
        b, p = r.get("rss_before_render_mib", -1), r.get("rss_peak_render_mib", -1)
        return p - b if b is not None and p is not None and b >= 0 and p >= 0 else nan

    lines = [f"# Render benchmark: {n}^3 volumes, {img}x{img} images\n",
             f"Main table: {a.threads} thread(s). rel. RMSE: against the converged trilinear reference of the "
             f"original volume (step {a.ref_step}; total error, DESIGN.md section 8). Spline rows whose full-size "
             "run would pass the budget are pilots at a smaller image (column 'image'; error against the "
             f"converged reference at that size; 'full-size CPU s' = predicted time at {img}x{img}).\n",
             "Times are CPU seconds of the render call (wvol bricks: building the block view and bounds "
             "included); the machine is shared with other work, so absolute times are noisy: compare ratios "
             "from this one run. 'peak MB': the whole process's max RSS (loading and transforming the volume "
             "included); 'render MiB': growth of the resident peak during the render call alone; 'alloc MiB': "
             "what the render call allocated by the library's own count; 'store MiB': the store it reads.\n",
             "| volume | mode | method | kept % | image | CPU s | full-size CPU s | wall s | peak MB | render MiB "
             "| alloc MiB | store MiB | rel. RMSE |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r.get("mode") == "opacity-only":
            continue
        full = r.get("predicted_full_s", r.get("cpu_s", nan))
        lines.append(f"| {r.get('volume')} | {r.get('mode')} | {r.get('method')} | {r.get('keep')} | "
                     f"{r.get('image', img)} | {r.get('cpu_s', nan) or nan:.3f} | {full or nan:.3g} | "
                     f"{r.get('wall_s', nan):.2f} | {r.get('peak_mb', nan):.0f} | {render_rss(r):.1f} | "
                     f"{mib(r, 'render_bytes'):.1f} | {mib(r, 'store_bytes'):.1f} | "
                     + (f"{r['rel_rmse']:.3g}" if "rel_rmse" in r else r.get("error", "")) + " |")
    lines += ["", "## Against the peers (opacity only)\n",
              "kappa(u) = 8 u per box diagonal, white emission, on the volume normalised to u in [0, 1]; "
              "orthographic +z, and (rows marked with the camera) a perspective view from an oblique "
              "direction, VTK's camera placed as wvol frames it (eye at the box's bounding-sphere distance "
              "for a 30 degree field of view); alpha compared with wvol's converged reference on the same "
              "volume and view. wvol bricks render from a 5% store; 'wvol reference of 5%' is the reference "
              "integrator on the dense reconstruction of that store (CPU: the inverse transform plus the "
              f"render); the others render the dense volume. wvol and VTK: the fastest of {a.peer_repeat} frames "
              "rendered in one process (VTK's after a set-up frame; each wvol call builds all it needs "
              "again), CPU and wall each their minimum; vdb_render: the whole process (reading the .vdb "
              "included). Ratios are CPU time over VTK's CPU time at the same thread count and view, in "
              "this run.\n",
              "| volume | threads | method | kept % | CPU s | wall s | / VTK CPU | rel. RMSE (alpha) | peak MB "
              "| render MiB | alloc MiB | store MiB |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r.get("mode") != "opacity-only":
            continue
        vtk = [q for q in rows if q.get("mode") == "opacity-only" and q.get("volume") == r.get("volume")
               and q.get("threads") == r.get("threads") and str(q.get("method", "")).startswith("VTK")
               and q.get("camera", "+z") == r.get("camera", "+z") and q.get("cpu_s")]
        vtk = [q for q in vtk if q.get("run") == r.get("run")] or vtk  # rows merged from several runs
        ratio = r.get("cpu_s", nan) / vtk[0]["cpu_s"] if vtk and r.get("cpu_s") else nan
        lines.append(f"| {r.get('volume')} | {r.get('threads')} | {r.get('method')} | {r.get('keep')} | "
                     f"{r.get('cpu_s', nan) or nan:.3f} | {r.get('render_s', nan) or nan:.3f} | {ratio:.2f} | "
                     + (f"{r['rel_rmse']:.3g}" if "rel_rmse" in r else r.get("error", "")) +
                     f" | {r.get('peak_mb', nan):.0f} | {render_rss(r):.1f} | {mib(r, 'render_bytes'):.1f} | "
                     f"{mib(r, 'store_bytes'):.1f} |")
    lines += equal_error_table(rows)
    (outdir / "render.md").write_text("\n".join(lines) + "\n")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        # the peers' panels: one thread, one per view, a series per method (steps joined)
        cams = sorted({r.get("camera", "+z") for r in rows if r.get("mode") == "opacity-only"})
        fig, axes = plt.subplots(1, 2 + len(cams), figsize=(9 * (2 + len(cams)) / 2, 6))
        panels = [("gaussian", lambda r: r.get("volume") == "gaussian" and r.get("mode") != "opacity-only", None),
                  ("skull", lambda r: r.get("volume") == "skull" and r.get("mode") != "opacity-only", None)]
        for cam in cams:
            panels.append((f"peers, opacity only, {cam}, 1 thread",
                           lambda r, cam=cam: r.get("mode") == "opacity-only" and r.get("camera", "+z") == cam
                           and r.get("threads") == 1, cam))
        for ax, (title, sel, cam) in zip(axes, panels):
            groups = {}
            for r in rows:
                if sel(r) and "rel_rmse" in r and r.get("cpu_s"):
                    if cam is None:
                        label = f"{r['method']} ({r['mode']})"
                    else:  # "wvol bricks step=1 (persp ...) [1 thr]" -> "skull: wvol bricks"
                        label = f"{r['volume']}: " + re.sub(r" step=\S+| \(.*?\)| \[.*?\]", "", r["method"])
                    groups.setdefault(label, []).append((r.get("predicted_full_s", r.get("cpu_s")), r["rel_rmse"]))
            for label, pts in sorted(groups.items()):
                x, y = zip(*sorted(pts))
                style = ("s" if "bricks" in label else "o") + ("-" if cam is not None and len(pts) > 1 else "")
                ax.loglog(x, np.maximum(y, 1e-9), style, label=label)
            ax.set_title(f"{title} ({n}^3, {img}^2)", fontsize=9)
            ax.set_xlabel("render CPU time (s; spline pilots: predicted at full size)")
            ax.set_ylabel("relative RMSE")
            ax.legend(fontsize=6)
        fig.tight_layout(); fig.savefig(outdir / "render.png", dpi=90)
    except Exception as ex:
        print("plot skipped:", ex)
    print((outdir / "render.md").read_text())


if __name__ == "__main__":
    sys.exit(main())
