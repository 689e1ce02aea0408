# SPDX-License-Identifier: MIT
"""Run by pvpython (tests/python/test_paraview.py): opens a file the reader must refuse, then
checks that the session goes on (the reader produced no points and a new source still
works). Prints SURVIVED and the point count on success. Usage:
    pvpython pv_bad.py PLUGIN FILE [--level S] [--region x0 x1 y0 y1 z0 z1] [--array NAME]"""
import argparse

from paraview.simple import LoadPlugin, Sphere

ap = argparse.ArgumentParser()
ap.add_argument("plugin")
ap.add_argument("path")
ap.add_argument("--level", type=int, default=0)
ap.add_argument("--region", type=int, nargs=6, default=[0, -1, 0, -1, 0, -1])
ap.add_argument("--array", default="values")
a = ap.parse_args()
LoadPlugin(a.plugin, ns=globals())
reader = WVCReader(FileName=a.path, LevelOfDetail=a.level, Region=a.region,  # noqa: F821 (from the plugin)
                   ArrayName=a.array)
reader.UpdatePipeline()
points = reader.GetDataInformation().GetNumberOfPoints()
sphere = Sphere()
sphere.UpdatePipeline()
assert sphere.GetDataInformation().GetNumberOfPoints() > 0
print(f"SURVIVED points={points}")
