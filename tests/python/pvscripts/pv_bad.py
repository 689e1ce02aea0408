# SPDX-License-Identifier: MIT
"""Run by pvpython (tests/python/test_paraview.py): opens a file the reader must refuse, then
checks that the session goes on (the reader produced no points and a new source still
works). Prints SURVIVED and the point count on success. Usage: pvpython pv_bad.py PLUGIN FILE"""
import sys

from paraview.simple import LoadPlugin, Sphere

plugin, path = sys.argv[1:3]
LoadPlugin(plugin, ns=globals())
reader = WVCReader(FileName=path)  # noqa: F821 (defined by the plugin)
reader.UpdatePipeline()
points = reader.GetDataInformation().GetNumberOfPoints()
sphere = Sphere()
sphere.UpdatePipeline()
assert sphere.GetDataInformation().GetNumberOfPoints() > 0
print(f"SURVIVED points={points}")
