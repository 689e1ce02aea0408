# SPDX-License-Identifier: MIT
"""Run by pvbatch, alone or under mpiexec (tests/python/test_paraview.py, docs/paraview.md,
bench/bench_paraview.py): reads a volume (a .wvc with the reader plugin: each rank decodes the
chunks of its piece and appends a line to the chunk log; a .vti with ParaView's own reader),
saves a volume rendering and a Contour of it as PNG screenshots with a fixed camera and transfer
function (no data-dependent choices, so runs with different rank counts are comparable), and
prints the seconds from the script's start to the first image (the plugin is loaded with LoadPlugin
unless ParaView loaded it at start-up from PV_PLUGIN_PATH); with --time-read also the reading
and the rendering apart, and this process's memory at each stage (one "memory" JSON line per
rank: resident and peak resident MiB after start-up and the plugin, after reading, after the
first image). Usage:
    pvbatch pv_render.py PLUGIN FILE OUTDIR CHUNKLOG VMIN VMAX ISO
            [--level S] [--array NAME] [--budget MIB] [--release] [--only volume|contour] [--time-read]
            [--volume-mode smart|raycast]
--volume-mode raycast renders the volume with ParaView's CPU ray caster ("Ray Cast Only") instead
of the default (Smart: the GPU mapper, which under Mesa's llvmpipe holds the volume as one 3D
texture and draws nothing where a rank's piece exceeds llvmpipe's texture size limit (a 2 GiB piece does, a 512 MiB one does not))."""
import argparse
import json
import time

import paraview.simple as pvs
from paraview.simple import (ColorBy, Contour, CreateView, GetColorTransferFunction, GetOpacityTransferFunction,
                             LoadPlugin, SaveScreenshot, Show, XMLImageDataReader)

t0 = time.perf_counter()
ap = argparse.ArgumentParser()
for name in ("plugin", "path", "outdir", "log"):
    ap.add_argument(name)
for name in ("vmin", "vmax", "iso"):
    ap.add_argument(name, type=float)
ap.add_argument("--level", type=int, default=0)
ap.add_argument("--array", default="values")
ap.add_argument("--budget", type=int, default=0, help="the reader's MemoryBudget (MiB of decoded chunks)")
ap.add_argument("--release", action="store_true", help="the reader's ReleaseCache (free chunks after reading)")
ap.add_argument("--only", choices=("volume", "contour"))
ap.add_argument("--volume-mode", choices=("smart", "raycast"), default="smart")
ap.add_argument("--time-read", action="store_true",
                help="update the reader alone first and print the seconds it took (the benchmark's split of the time)")
a = ap.parse_args()
vmin, vmax, iso, only = a.vmin, a.vmax, a.iso, a.only
if a.path.endswith(".vti"):
    reader = XMLImageDataReader(FileName=[a.path])
else:
    if hasattr(pvs, "WVCReader"):  # loaded at start-up from PV_PLUGIN_PATH
        WVCReader = pvs.WVCReader
    else:
        LoadPlugin(a.plugin, ns=globals())  # defines WVCReader here
    reader = WVCReader(FileName=a.path, LevelOfDetail=a.level, ChunkLog=a.log,  # noqa: F821
                       ArrayName=a.array, MemoryBudget=a.budget, ReleaseCache=int(a.release))




def memory_mib():
    """This process's resident and peak resident set (VmRSS, VmHWM) in MiB, from /proc."""
    got = {}
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(("VmRSS:", "VmHWM:")):
                got[line.split(":")[0]] = int(line.split()[1]) / 1024.0
    return got.get("VmRSS"), got.get("VmHWM")


def rank():
    from paraview.modules.vtkRemotingCore import vtkProcessModule
    c = vtkProcessModule.GetProcessModule().GetGlobalController()
    return c.GetLocalProcessId() if c is not None else 0


stages = {}
if a.time_read:
    stages["base"] = memory_mib()  # ParaView, its Python, the plugin: before any data
    t_read, cpu_read = time.perf_counter(), time.process_time()  # process_time: all this process's threads
    reader.UpdatePipeline()
    read_s, read_cpu = time.perf_counter() - t_read, time.process_time() - cpu_read
    stages["read"] = memory_mib()
    print(f"data read in {read_s:.3f} s ({read_cpu:.3f} CPU s)", flush=True)
t_render = time.perf_counter()


def view_of(size=(480, 400)):
    view = CreateView("RenderView")
    view.ViewSize = list(size)
    view.OrientationAxesVisibility = 0
    view.Background = [0.0, 0.0, 0.0]
    try:
        view.UseColorPaletteForBackground = 0
    except AttributeError:
        pass
    return view


def place_camera(view):
    info = reader.GetDataInformation().DataInformation
    b = info.GetBounds()
    c = [(b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2]
    r = max(b[1] - b[0], b[3] - b[2], b[5] - b[4])
    view.CameraPosition = [c[0] + 1.6 * r, c[1] - 1.2 * r, c[2] + 1.0 * r]
    view.CameraFocalPoint = c
    view.CameraViewUp = [0, 0, 1]
    view.CameraParallelProjection = 0
    view.CameraViewAngle = 30


if only in (None, "volume"):
    view = view_of()
    disp = Show(reader, view)
    disp.SetRepresentationType("Volume")
    if a.volume_mode == "raycast":
        disp.VolumeRenderingMode = "Ray Cast Only"
    ColorBy(disp, ("POINTS", a.array))
    ctf = GetColorTransferFunction(a.array)
    ctf.RGBPoints = [vmin, 0.0, 0.0, 0.0, iso, 0.9, 0.5, 0.2, vmax, 1.0, 1.0, 0.9]
    otf = GetOpacityTransferFunction(a.array)
    otf.Points = [vmin, 0.0, 0.5, 0.0, iso, 0.02, 0.5, 0.0, vmax, 0.3, 0.5, 0.0]
    place_camera(view)
    SaveScreenshot(f"{a.outdir}/volume.png", view, ImageResolution=list(view.ViewSize))
    print(f"first image after {time.perf_counter() - t0:.3f} s", flush=True)
    if a.time_read:
        print(f"rendered in {time.perf_counter() - t_render:.3f} s", flush=True)
        stages["render"] = memory_mib()
        print("memory " + json.dumps({"rank": rank(), **{k: {"rss_mib": v[0], "peak_mib": v[1]}
                                                         for k, v in stages.items()}}), flush=True)

if only in (None, "contour"):
    contour = Contour(Input=reader, ContourBy=["POINTS", a.array], Isosurfaces=[iso], ComputeScalars=0)
    view = view_of()
    disp = Show(contour, view)
    disp.DiffuseColor = [0.9, 0.8, 0.6]
    try:
        ColorBy(disp, None)
    except Exception:  # noqa: BLE001  (no scalars to unset)
        pass
    place_camera(view)
    SaveScreenshot(f"{a.outdir}/contour.png", view, ImageResolution=list(view.ViewSize))
