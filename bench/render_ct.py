# SPDX-License-Identifier: MIT
"""The realistic suite of bench/bench_render.py (`--suite ct`, issue 23): a head CT as a user has
it, against VTK's vtkFixedPointVolumeRayCastMapper in the same run.

Volumes: `wvol synth skull --variant ct --noise 20` (a thin curved table outside the head, noisy air
and tissue) at 256x256x108 with 0.96 x 0.96 x 1.5 mm voxels (anisotropic, non-cubic), and the noisy
isotropic 256^3 skull. Transfer functions: CT ramps (bone; soft tissue), transparent below a
threshold and nearly opaque above, the same points as the `ct-bone` and `ct-soft` presets, written
to a file both renderers read (VTK's opacity per unit length is 1 - exp(-kappa), sampled densely
between the knots because VTK interpolates opacity, not kappa). Cameras: orthographic along z and
along y (across the long slices) and an oblique perspective view; VTK's camera is placed as wvol
frames its view (orthographic: the projected box fits the image, VTK's parallel scale is half the
image height in world units; perspective: the box's bounding sphere fits the 30 degree field of
view), so both show the same visible extent. Steps: wvol's step in voxels of the smallest spacing,
VTK's sample distance the same length in world units. Errors: RGB (premultiplied, over black)
against wvol's converged reference on the original volume (step --ct-ref-step), relative RMSE.
Writes bench/results/render_ct.{json,md,png}.
"""
import json
import math
import os
import pathlib
import shlex
import shutil
import subprocess
import sys
import time

import numpy as np

# the presets of libwvol/src/render/transfer.c (units diagonal): value, r, g, b, kappa
PRESETS = {
    "ct-bone": [(150, .80, .60, .45, 0), (300, .95, .85, .70, 40), (800, 1, .95, .85, 160), (2000, 1, 1, 1, 240)],
    "ct-soft": [(-400, .55, .25, .15, 0), (-100, .75, .45, .35, 2), (40, .90, .55, .45, 6), (120, .95, .70, .60, 8),
                (300, 1, .95, .85, 60), (1500, 1, 1, 1, 160)],
}

VOLUMES = {  # name: (size, spacing, variant)
    "ct": ("256x256x108", "0.96,0.96,1.5", "ct"),
    "skull-noisy": ("256x256x256", "0.9375,0.9375,0.9375", "head"),
}

VTK_CT = r"""
import sys, json, time, numpy as np, vtk
from vtk.util import numpy_support
cfg = json.loads(open(sys.argv[1]).read())
n, sp, img, thr = cfg["dims"], cfg["spacing"], cfg["image"], cfg["threads"]
vtk.vtkMultiThreader.SetGlobalMaximumNumberOfThreads(thr)
v = np.fromfile(cfg["raw"], dtype='<f4')
imgd = vtk.vtkImageData(); imgd.SetDimensions(*n); imgd.SetSpacing(*sp); imgd.SetOrigin(0, 0, 0)
imgd.GetPointData().SetScalars(numpy_support.numpy_to_vtk(v, deep=True))
col = vtk.vtkColorTransferFunction(); op = vtk.vtkPiecewiseFunction()
pts = cfg["tf"]  # world kappa
for (x, r, g, b, k) in pts: col.AddRGBPoint(x, r, g, b)
for i in range(len(pts) - 1):  # opacity per unit length 1 - exp(-kappa), kappa linear between knots
    for t in np.linspace(0, 1, 33)[:-1]:
        x = pts[i][0] + t * (pts[i + 1][0] - pts[i][0]); k = pts[i][4] + t * (pts[i + 1][4] - pts[i][4])
        op.AddPoint(float(x), float(1 - np.exp(-k)))
op.AddPoint(float(pts[-1][0]), float(1 - np.exp(-pts[-1][4])))
prop = vtk.vtkVolumeProperty(); prop.SetColor(col); prop.SetScalarOpacity(op); prop.SetScalarOpacityUnitDistance(1.0)
prop.SetInterpolationTypeToLinear(); prop.ShadeOff()
mapper = vtk.vtkFixedPointVolumeRayCastMapper(); mapper.SetInputData(imgd); mapper.SetNumberOfThreads(thr)
mapper.SetSampleDistance(cfg["sample_distance"]); mapper.SetAutoAdjustSampleDistances(0)
vol = vtk.vtkVolume(); vol.SetMapper(mapper); vol.SetProperty(prop)
ren = vtk.vtkRenderer(); ren.AddVolume(vol); ren.SetBackground(0, 0, 0)
win = vtk.vtkRenderWindow(); win.SetOffScreenRendering(1); win.AddRenderer(ren); win.SetSize(img, img)
cam = ren.GetActiveCamera(); c = np.array([(n[a] - 1) / 2 * sp[a] for a in range(3)])
ext = np.array([n[a] * sp[a] for a in range(3)])  # wvol's box: the voxel cells
view = cfg["camera"]
if view.startswith("persp"):
    d = np.array([float(x) for x in view.split("dir=")[1].split(",")]); d /= np.linalg.norm(d)
    radius = np.linalg.norm(ext) / 2; dist = radius / np.sin(np.radians(15))
    cam.SetFocalPoint(*c); cam.SetPosition(*(c - d * dist)); cam.SetViewUp(0, 0, 1)
    cam.ParallelProjectionOff(); cam.SetViewAngle(30); cam.SetClippingRange(dist - 2 * radius, dist + 2 * radius)
else:  # "+z", "+y", "+x": camera on that side looking back, wvol's up (+y for z views, else +z)
    ax = "xyz".index(view[1]); d = np.zeros(3); d[ax] = 1.0
    up = (0, 1, 0) if ax == 2 else (0, 0, 1)
    rgt = np.cross(-d, up); h = max(abs(rgt) @ ext, np.array(up) @ ext)  # square image: fit both
    dist = 2 * ext.max()
    cam.SetFocalPoint(*c); cam.SetPosition(*(c + d * dist)); cam.SetViewUp(*up)
    cam.ParallelProjectionOn(); cam.SetParallelScale(h / 2); cam.SetClippingRange(0.1, 4 * dist)
# frames as wvol's --repeat N --orbit D: frame i turned by (N-1-i) D degrees about the view's up
# axis through the focal point, the last at the requested view; the first frame (VTK builds its
# tables there) timed apart from the later ones
N, D = cfg["frames"], cfg["orbit"]
cpu, wall = [], []
cam.Azimuth((N - 1) * D); cam.OrthogonalizeViewUp()
for i in range(N):
    if i:
        cam.Azimuth(-D); cam.OrthogonalizeViewUp()
    t0 = time.process_time(); w0 = time.perf_counter(); win.Render(); t1 = time.process_time(); w1 = time.perf_counter()
    cpu.append(t1 - t0); wall.append(w1 - w0)
w2i = vtk.vtkWindowToImageFilter(); w2i.SetInput(win); w2i.SetInputBufferTypeToRGB(); w2i.ReadFrontBufferOff(); w2i.Update()
a = numpy_support.vtk_to_numpy(w2i.GetOutput().GetPointData().GetScalars()).reshape(img, img, -1)[::-1, :, :3]
np.save(cfg["out"], a.astype(np.float32) / 255.0)
print(cpu[0], wall[0], min(cpu[1:]), min(wall[1:]))
"""


def tf_world(name, diag):
    return [(v, r, g, b, k / diag) for (v, r, g, b, k) in PRESETS[name]]


def tf_file(name, path):
    path.write_text("units diagonal\n" + "".join(f"{v} {r} {g} {b} {k}\n" for (v, r, g, b, k) in PRESETS[name]))


# Both renderers run with OpenMP's passive wait policy: an idle OpenMP thread sleeps instead of
# spinning (libgomp's active wait counts as CPU time). VTK's fixed-point mapper runs its threads
# through vtkMultiThreader, not OpenMP, so the setting changes nothing there; it is set for both
# so that both run under the same environment.
RUN_ENV = dict(os.environ, OMP_WAIT_POLICY="passive")

# VTK's fixed-point mapper ends a ray once its remaining opacity, in 15-bit fixed point, falls
# below 0xff (VTKKWRCHelper_CompositeColorAndCheckEarlyTermination: 0xff / 0x7fff = 0.0078): the
# comparison at equal termination gives wvol the same threshold.
VTK_TERMINATION = "--termination 0.0078"


def run_note():
    """The clock and the 1-minute load average now (two-thread CPU times are meaningful only on
    a machine whose other work leaves the cores free)."""
    return {"utc": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()), "load1": round(os.getloadavg()[0], 2)}


def ct_suite(a, wvol, timed, rgba, tmp, outdir, machine):
    rows = []
    machine = dict(machine, command=" ".join(shlex.quote(x) for x in sys.argv), wvol=str(wvol), start=run_note())
    img = a.image
    steps = [float(s) for s in a.ct_steps.split(",")]
    for vname in [x for x in a.ct_volumes.split(",") if x]:
        size, spacing, variant = VOLUMES[vname]
        dims = [int(x) for x in size.split("x")]
        sp = [float(x) for x in spacing.split(",")]
        if a.ct_scale != 1:
            dims = [max(8, int(round(d / a.ct_scale))) for d in dims]
            sp = [s * a.ct_scale for s in sp]
        nrrd = tmp / f"{vname}.nrrd"
        subprocess.run([wvol, "synth", "skull", "--variant", variant, "--noise", "20", "--size",
                        "x".join(map(str, dims)), "--spacing", ",".join(map(str, sp)), "-o", str(nrrd)],
                       check=True, capture_output=True)
        raw = tmp / f"{vname}.raw"
        subprocess.run([wvol, "synth", "skull", "--variant", variant, "--noise", "20", "--size",
                        "x".join(map(str, dims)), "--spacing", ",".join(map(str, sp)), "-o", str(raw)],
                       check=True, capture_output=True)
        diag = math.sqrt(sum((dims[i] * sp[i]) ** 2 for i in range(3)))
        for tfname in a.ct_tfs.split(","):
            tfp = tmp / f"{tfname}.txt"
            tf_file(tfname, tfp)
            for cam in [c for c in a.ct_cameras.split(";") if c]:
                base = ["--size", f"{img}x{img}", "--camera", cam, "--tf", str(tfp)]
                ref = tmp / "ref.exr"
                r = subprocess.run([wvol, "render", str(nrrd), "-o", str(ref), "--method", "reference", "--step",
                                    str(a.ct_ref_step), "--threads", "2", *base], capture_output=True, text=True)
                if r.returncode:
                    print("converged reference failed:", r.stderr)
                    continue
                R = rgba(ref)[..., :3]
                scale = max(float(np.abs(R).max()), 1e-30)

                def err(x):
                    return float(np.sqrt(np.mean((x - R) ** 2)) / scale)

                def row(method, threads, **kw):
                    rr = {"suite": "ct", "volume": vname, "dims": dims, "spacing": sp, "tf": tfname, "camera": cam,
                          "method": method, "threads": threads}
                    rr.update(kw)
                    rows.append(rr)
                    print(json.dumps(rr), flush=True)

                for thr in [int(t) for t in a.peer_threads.split(",")]:
                    runs = []
                    # the error-against-time curves at one thread; two threads at VTK's step
                    for st in (steps if thr == 1 else steps[:1]):
                        runs.append((f"reference step={st}", ["--method", "reference", "--step", str(st)], st))
                        if "--preintegrate" in a.ct_extra:
                            runs.append((f"reference step={st} --preintegrate",
                                         ["--method", "reference", "--step", str(st), "--preintegrate"], st))
                        runs.append((f"bricks 5% step={st}", ["--method", "bricks", "--keep", "5%", "--step", str(st)],
                                     st))
                        for extra in [e for e in a.ct_extra.split(";") if e]:
                            runs.append((f"bricks 5% step={st} {extra}",
                                         ["--method", "bricks", "--keep", "5%", "--step", str(st), *extra.split()], st))
                    if a.ct_baseline:  # the other build's bricks rows at VTK's step
                        st = steps[0]
                        for extra in ["", VTK_TERMINATION]:
                            runs.append((f"bricks 5% step={st}{' ' + extra if extra else ''} (baseline)",
                                         ["--method", "bricks", "--keep", "5%", "--step", str(st), *extra.split()], st))
                    for name, args, st in runs:
                        out = tmp / "o.exr"
                        baseline = name.endswith("(baseline)")
                        prog = a.ct_baseline if baseline else wvol
                        # this build: the frames through one render context, the camera turned
                        # between them; the baseline (main's build, no context): separate calls
                        frames = (["--repeat", str(a.peer_repeat)] if baseline else
                                  ["--repeat", str(a.ct_frames), "--orbit", str(a.ct_orbit)])
                        cmd = [prog, "render", str(nrrd), "-o", str(out), "--json", "--threads", str(thr),
                               *frames, *base, *args]
                        dt, mem, so, se, rc = timed(cmd, env=RUN_ENV)
                        if rc:
                            row(name, thr, error=se.strip().splitlines()[-1] if se.strip() else "failed")
                            continue
                        info = json.loads(so)
                        kw = dict(step=st, samples=info.get("samples"), bricks_built=info.get("bricks_built"),
                                  rel_rmse=err(rgba(out)[..., :3]))
                        if baseline:
                            kw.update(one_shot_cpu_s=info["render_cpu_seconds"], wall_s=info["render_seconds"])
                        else:
                            kw.update(first_cpu_s=info["first_cpu_seconds"], cpu_s=info["later_cpu_seconds"],
                                      wall_s=info["later_seconds"], bricks_reused=info.get("bricks_reused"),
                                      cache_bytes=info.get("cache_bytes"), context_bytes=info.get("context_bytes"))
                            if (st == steps[0] and name.startswith("bricks") and "preint" not in name
                                    and "--context-cache" not in name):
                                # the same frame as separate calls, each building everything
                                one = [wvol, "render", str(nrrd), "-o", str(tmp / "p.exr"), "--json", "--threads",
                                       str(thr), "--repeat", str(a.peer_repeat), "--one-shot", *base, *args]
                                _, _, so1, _, rc1 = timed(one, env=RUN_ENV)
                                if rc1 == 0:
                                    kw["one_shot_cpu_s"] = json.loads(so1)["render_cpu_seconds"]
                                    kw["one_shot_same_image"] = (tmp / "p.exr").read_bytes() == out.read_bytes()
                        row(name, thr, **kw)
                    if shutil.which("xvfb-run") and not a.no_vtk:
                        for st in steps[:1]:
                            out = tmp / "vtk.npy"
                            cfg = {"raw": str(raw), "dims": dims, "spacing": sp, "image": img, "threads": thr,
                                   "tf": tf_world(tfname, diag), "camera": cam, "frames": a.ct_frames,
                                   "orbit": a.ct_orbit, "sample_distance": st * min(sp), "out": str(out)}
                            (tmp / "vtk.json").write_text(json.dumps(cfg))
                            (tmp / "vtk_ct.py").write_text(VTK_CT)
                            dt, mem, so, se, rc = timed(["xvfb-run", "-a", "/usr/bin/python3", tmp / "vtk_ct.py",
                                                         tmp / "vtk.json"], env=RUN_ENV)
                            if rc:
                                row(f"VTK fixed-point step={st}", thr, error=se.strip().splitlines()[-1])
                                continue
                            fcpu, fwall, cpu, wall = map(float, so.strip().splitlines()[-1].split())
                            row(f"VTK fixed-point step={st}", thr, step=st, first_cpu_s=fcpu, cpu_s=cpu, wall_s=wall,
                                rel_rmse=err(np.load(out)), note="first frame: VTK's set-up; 8-bit read-back")
    shading_images(a, wvol, tmp, outdir, img)
    machine["end"] = run_note()
    write_results(rows, a, outdir, machine, img)
    return rows


def shading_images(a, wvol, tmp, outdir, img):
    """The ct volume from its 5% store, shaded, with the gradient of the samples and of the
    wavelet model's low-pass approximation (--gradient-levels 1 and 2), db2 and bl3: one
    figure, render_ct_shading.png."""
    if "ct" not in a.ct_volumes.split(",") or a.ct_no_shading:
        return
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.image as mi
        import matplotlib.pyplot as plt
    except Exception as ex:
        print("shading images skipped:", ex)
        return
    nrrd = tmp / "ct.nrrd"
    tfp = tmp / "ct-soft.txt"
    tf_file("ct-soft", tfp)
    panels = []
    for wv in ["db2", "bl3"]:
        for gl in [0, 1, 2]:
            out = tmp / f"shade_{wv}_{gl}.png"
            r = subprocess.run([wvol, "render", str(nrrd), "-o", str(out), "--method", "bricks", "--keep", "5%",
                                "--wavelet", wv, "--shading", "--gradient-levels", str(gl), "--tf", str(tfp),
                                "--camera", "persp dir=0.35,1,-0.3 fov=30 zoom=1.5", "--size", f"{img}x{img}"],
                               capture_output=True, text=True)
            if r.returncode == 0:
                panels.append((f"{wv}, gradient of " + ("the samples" if gl == 0 else f"low-pass (-{gl} levels)"),
                               mi.imread(out)))
    if not panels:
        return
    fig, axes = plt.subplots(2, 3, figsize=(12, 8))
    for ax, (title, im) in zip(axes.ravel(), panels):
        ax.imshow(im)
        ax.set_title(title, fontsize=9)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(outdir / "render_ct_shading.png", dpi=80)


VTK_ROW = "VTK fixed-point step=0.5"


def vtk_of(rows, r):
    """The VTK row of r's volume, TF, camera and threads, or None."""
    vt = [q for q in rows if q["volume"] == r["volume"] and q["tf"] == r["tf"] and q["camera"] == r["camera"]
          and q["threads"] == r["threads"] and q["method"].startswith("VTK") and q.get("cpu_s")]
    return vt[0] if vt else None


def equal_error(one_thr):
    """Of one case's one-thread rows (later frames), the bricks row most faster than the cheapest
    reference row of the original whose error is no larger: (that speed-up, its method), or None."""
    refs = [r for r in one_thr if r["method"].startswith("reference") and "preint" not in r["method"]]
    best = None
    for b in [r for r in one_thr if r["method"].startswith("bricks")]:
        ok = [q for q in refs if q["rel_rmse"] <= b["rel_rmse"]]
        if ok:
            x = min(ok, key=lambda q: q["cpu_s"])["cpu_s"] / b["cpu_s"]
            if best is None or x > best[0]:
                best = (x, b["method"])
    return best


def summary(rows):
    """Per volume, TF and camera (one thread unless stated): the goals read off the rows. Bricks
    against VTK at VTK's step: later frames against VTK's later frames, first frames (set-up
    included) against VTK's first, one-shot calls against VTK's later frames; at equal error,
    the cheapest bricks row against the cheapest reference row of the original whose error is
    no larger (later frames, both through the context); pre-integration (when its rows ran): the
    largest step whose error is at most the classic step 0.5's."""
    base = any(r["method"].endswith("(baseline)") for r in rows)
    preint = any("--preintegrate" in r["method"] for r in rows)
    T = "bricks 5% step=0.5 --termination 0.0078"
    # rows with a larger context cache at VTK's termination (--ct-extra "--termination 0.0078
    # --context-cache SIZE"): their own column
    big = sorted({r["method"] for r in rows if r["method"].startswith(T + " --context-cache")})
    out = ["", "## Summary per case (1 thread unless stated)\n",
           "Step 0.5 (VTK's). The stated comparison is at equal termination: VTK ends a ray at a remaining "
           "opacity of 0xff/0x7fff = 0.0078, 'at VTK's termination' gives wvol the same threshold; wvol's default "
           "(1e-6) beside it. 'later': the fastest later frame (camera turned between frames) over VTK's; 'first': "
           "the first frame, set-up included, over VTK's first; 'one-shot': each frame a separate call over VTK's "
           "later frames." + (" '(baseline)': the other build given by --ct-baseline, one-shot, in the same run."
                              if base else "") + "\n",
           "| volume | TF | camera | at VTK's termination, later / VTK (1 thr, 2 thr) |" +
           "".join(f" {m.split('--termination 0.0078 ')[1]}, later / VTK (1, 2 thr) |" for m in big) +
           " first / VTK (1, 2 thr) | one-shot / VTK (1, 2 thr) |" + (" baseline one-shot / VTK (1, 2 thr) |" if base else "") +
           " termination 1e-6, later / VTK (1, 2 thr) | at equal error: reference / bricks CPU (later frames) | "
           "classic step 0.5 error |" + (" largest pre-integrated step at <= that error (reference; bricks) |"
                                         if preint else ""),
           "|---|---|---|---|" + "---|" * len(big) + "---|---|" + ("---|" if base else "") + "---|---|---|" +
           ("---|" if preint else "")]
    keys = sorted({(r["volume"], r["tf"], r["camera"]) for r in rows})
    for key in keys:
        sel = [r for r in rows if (r["volume"], r["tf"], r["camera"]) == key and "rel_rmse" in r]

        def one(method, thr):
            q = [r for r in sel if r["method"] == method and r["threads"] == thr]
            return q[0] if q else None

        def ratio(method, thr, field, vfield="cpu_s"):
            r, v = one(method, thr), one(VTK_ROW, thr)
            return f"{r[field] / v[vfield]:.2f}" if r and v and r.get(field) and v.get(vfield) else "-"

        def pair(method, field, vfield="cpu_s"):
            return f"{ratio(method, 1, field, vfield)}, {ratio(method, 2, field, vfield)}"

        one_thr = [r for r in sel if r["threads"] == 1 and not r["method"].endswith("(baseline)") and r.get("cpu_s")]
        best = equal_error(one_thr)
        eq = f"{best[0]:.2f} ({best[1]})" if best else "-"
        classic = one("reference step=0.5", 1)
        cols = [pair(T, "cpu_s")] + [pair(m, "cpu_s") for m in big] + [pair(T, "first_cpu_s", "first_cpu_s"),
                                                                       pair(T, "one_shot_cpu_s")]
        if base:
            cols += [pair(T + " (baseline)", "one_shot_cpu_s")]
        cols += [pair("bricks 5% step=0.5", "cpu_s"), eq, f"{classic['rel_rmse']:.3g}" if classic else "-"]
        if preint:
            pre = "-"
            if classic:
                def largest(prefix):
                    ok = [r for r in one_thr if r["method"].startswith(prefix) and "--preintegrate" in r["method"]
                          and r["rel_rmse"] <= classic["rel_rmse"]]
                    return f"{max(r['step'] for r in ok):g}" if ok else "none"
                pre = f"{largest('reference')}; {largest('bricks')}"
            cols.append(pre)
        out.append(f"| {key[0]} | {key[1]} | {key[2]} | " + " | ".join(cols) + " |")
    return out


def run_lines(machine):
    """How this run was made: the command, the clock and the load at its start and end."""
    st, en = machine.get("start", {}), machine.get("end", {})
    return [f"This run: `WVOL_BIN={machine.get('wvol', '?')} {machine.get('command', '')}`, {st.get('utc', '?')} to "
            f"{en.get('utc', '?')} UTC; "
            f"1-minute load average {st.get('load1', '?')} at the start, {en.get('load1', '?')} at the end "
            f"({machine.get('cpus')} CPUs; a load above about 1 means other work shared the cores, which makes the "
            "two-thread rows, and the ratios, less reliable).\n"]


def goals(rows):
    """Issue 23's goals read off the rows, one line each."""
    T = "bricks 5% step=0.5 --termination 0.0078"
    keys = sorted({(r["volume"], r["tf"], r["camera"]) for r in rows})

    def ratios(method, thr, field, vfield):
        out = []
        for key in keys:
            b = [r for r in rows if (r["volume"], r["tf"], r["camera"]) == key and r["method"] == method
                 and r["threads"] == thr and r.get(field)]
            v = [r for r in rows if (r["volume"], r["tf"], r["camera"]) == key and r["method"] == VTK_ROW
                 and r["threads"] == thr and r.get(vfield)]
            if b and v:
                out.append((b[0][field] / v[0][vfield], key))
        return out

    def span(rs):
        return f"{min(x for x, _ in rs):.2f}-{max(x for x, _ in rs):.2f}x" if rs else "no rows"

    lines = ["Goals of issue 23 at equal termination (VTK's 0xff/0x7fff) and VTK's step 0.5, read off the rows "
             "below:"]
    for thr in (1, 2):
        rs = ratios(T, thr, "cpu_s", "cpu_s")
        met = [r for r in rs if r[0] <= 0.7]
        worst = max(rs) if rs else None
        lines.append(f"- <= 0.7x VTK's CPU time on every camera, {thr} thread{'s' if thr > 1 else ''}, later frames: "
                     f"{span(rs)}; " + ("REACHED" if rs and len(met) == len(rs) else "NOT reached") +
                     f" ({len(met)} of {len(rs)} cases" + (f"; the worst {worst[1][1]} {worst[1][2]} at {worst[0]:.3f}"
                                                         if worst else "") + ").")
    for thr in (1, 2):
        lines.append(f"- first frames (set-up included) against VTK's first, {thr} thread{'s' if thr > 1 else ''}: "
                     f"{span(ratios(T, thr, 'first_cpu_s', 'first_cpu_s'))}; one-shot calls against VTK's later "
                     f"frames: {span(ratios(T, thr, 'one_shot_cpu_s', 'cpu_s'))}.")
    eq = []
    for key in keys:
        best = equal_error([r for r in rows if (r["volume"], r["tf"], r["camera"]) == key and r["threads"] == 1
                            and r.get("cpu_s") and "rel_rmse" in r and not r["method"].endswith("(baseline)")])
        if best:
            eq.append(best[0])
    lines.append(f"- at equal image error, >= 2x faster than the dense reference on the original (later frames, one "
                 f"thread): " + (f"{min(eq):.2f}-{max(eq):.2f}x; " + ("REACHED" if min(eq) >= 2 else "NOT reached") +
                                 f" ({sum(x >= 2 for x in eq)} of {len(eq)} cases)." if eq else "no rows."))
    return lines + [""]


def write_results(rows, a, outdir, machine, img):
    (outdir / "render_ct.json").write_text(json.dumps({"image": img, "machine": machine, "rows": rows}, indent=1))
    nan = float("nan")
    lines = [f"# Render benchmark, realistic suite: noisy CT heads, CT ramps, {img}x{img} images\n",
             "`bench/bench_render.py --suite ct` (bench/render_ct.py). Volumes: `ct` = `wvol synth skull --variant "
             "ct --noise 20` at 256x256x108, 0.96 x 0.96 x 1.5 mm (a table arc outside the head, noisy air); "
             "`skull-noisy` = the 256^3 skull with the same noise (in the suite, `--ct-volumes`; a run may leave it out). TFs: the `ct-bone` and `ct-soft` presets. "
             "The camera is framed like VTK's: VTK's camera is placed where wvol frames its view, so both show "
             "the same visible extent (orthographic: the projected box fits the image; perspective: the box's "
             "bounding sphere fits a 30 degree field of view). Steps in voxels of the smallest spacing; VTK's "
             "sample distance is the same length in mm. rel. RMSE: RGB against wvol's converged reference "
             f"(step {a.ct_ref_step}) on the original volume. What is timed (CPU seconds of the process): "
             f"{a.ct_frames} frames in one process, the camera turned by {a.ct_orbit:g} degrees about its up axis "
             "between frames (frame i at (N-1-i) times that, the last at the named view: the image compared), "
             "wvol's through one render context (`wvol render --repeat N --orbit D`: the block view, the bounds, "
             "the brick rates and a cache of built bricks, the dense volume's size by default, kept from frame to "
             "frame), VTK's through one window and mapper; 'first': the first frame (wvol's set-up, VTK's "
             "tables built in its first Render) against VTK's first; 'later' (the CPU s and / VTK columns): the "
             "fastest later frame against VTK's fastest later frame; 'one-shot': wvol's bricks rows at step 0.5 "
             f"again as separate calls (`--repeat {a.peer_repeat} --one-shot`: each frame builds everything), the "
             "fastest, against VTK's later frames. Both run with OMP_WAIT_POLICY=passive (an idle OpenMP "
             "thread sleeps rather than spins; VTK's mapper threads through vtkMultiThreader, which it does not "
             "affect).\n",
             "| volume | TF | camera | threads | method | first frame CPU s | / VTK first | later CPU s | / VTK later "
             "| one-shot CPU s | / VTK later | rel. RMSE | samples |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]

    def f3(x):
        return f"{x:.3f}" if x is not None else ""

    def rat(x, y):
        return f"{x / y:.2f}" if x and y else ""

    for r in rows:
        vt = vtk_of(rows, r)
        lines.append(f"| {r['volume']} | {r['tf']} | {r['camera']} | {r['threads']} | {r['method']} | "
                     f"{f3(r.get('first_cpu_s'))} | {rat(r.get('first_cpu_s'), vt and vt.get('first_cpu_s'))} | "
                     f"{f3(r.get('cpu_s'))} | {rat(r.get('cpu_s'), vt and vt['cpu_s'])} | "
                     f"{f3(r.get('one_shot_cpu_s'))} | {rat(r.get('one_shot_cpu_s'), vt and vt['cpu_s'])} | "
                     + (f"{r['rel_rmse']:.3g}" if "rel_rmse" in r else r.get("error", "")) +
                     f" | {r.get('samples', '') or ''} |")
    lines[2:2] = run_lines(machine) + goals(rows)
    lines += summary(rows)
    (outdir / "render_ct.md").write_text("\n".join(lines) + "\n")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        keys = sorted({(r["volume"], r["tf"], r["camera"]) for r in rows})
        fig, axes = plt.subplots(1, max(len(keys), 1), figsize=(4.5 * max(len(keys), 1), 4.5), squeeze=False)
        for ax, key in zip(axes[0], keys):
            groups = {}
            for r in rows:
                if (r["volume"], r["tf"], r["camera"]) == key and r["threads"] == 1 and r.get("cpu_s") and "rel_rmse" in r:
                    label = r["method"].split(" step=")[0] + (" " + r["method"].split(" step=")[1].split(" ", 1)[1]
                                                               if " " in r["method"].split(" step=")[-1] else "")
                    groups.setdefault(label, []).append((r["cpu_s"], r["rel_rmse"]))
            for label, pts in sorted(groups.items()):
                x, y = zip(*sorted(pts))
                ax.loglog(x, np.maximum(y, 1e-9), "o-", label=label)
            ax.set_title(" ".join(key), fontsize=8)
            ax.set_xlabel("CPU s (1 thread, later frames)")
            ax.set_ylabel("rel. RMSE (RGB)")
            ax.legend(fontsize=6)
        fig.tight_layout()
        fig.savefig(outdir / "render_ct.png", dpi=80)
    except Exception as ex:
        print("plot skipped:", ex)
    print((outdir / "render_ct.md").read_text())
