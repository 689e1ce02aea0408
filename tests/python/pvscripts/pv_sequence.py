# SPDX-License-Identifier: MIT
"""Run by pvpython (tests/python/test_paraview.py): the C++ reader's output across a sequence of
executions driven on the client-side algorithm, as a VTK pipeline drives it. Prints one JSON
line: the point count and extent after each step. Usage:
    pvpython pv_sequence.py PLUGIN FIRST.wvc SECOND.wvc WORKDIR
Steps: FIRST read; a level of detail the file lacks (must fail, output empty); FIRST copied to
WORKDIR/r.wvc and read; SECOND put at that path by os.replace, then Modified() (the new file
must be read); with ReleaseCache, piece 0 of 2 of FIRST, SECOND put at the path, piece 1 (must
fail: refused, not read in the old file's frame); Threads -5 (must fail)."""
import json
import os
import shutil
import sys

from paraview.simple import LoadPlugin

plugin, first, second, work = sys.argv[1:5]
LoadPlugin(plugin, ns=globals())
steps = {}


def record(name, alg):
    img = alg.GetOutputDataObject(0)
    steps[name] = {"points": img.GetNumberOfPoints(), "extent": list(img.GetExtent()),
                   "scalars": img.GetPointData().GetScalars() is not None}


def replace_with(src, path):
    shutil.copy(src, path + ".new")
    os.replace(path + ".new", path)


reader = WVCReader(FileName=first)  # noqa: F821 (from the plugin)
alg = reader.GetClientSideObject()
alg.Update()
record("first", alg)
reader.LevelOfDetail = 7
reader.UpdateVTKObjects()
alg.Update()
record("bad_level", alg)

path = os.path.join(work, "r.wvc")
shutil.copy(first, path)
reader.LevelOfDetail = 0
reader.FileName = path
reader.UpdateVTKObjects()
alg.Update()
record("copy", alg)
replace_with(second, path)
alg.Modified()
alg.Update()
record("replaced", alg)

shutil.copy(first, path)
released = WVCReader(FileName=path, ReleaseCache=1)  # noqa: F821
ralg = released.GetClientSideObject()
ralg.UpdatePiece(0, 2, 0)
record("piece0", ralg)
replace_with(second, path)
ralg.UpdatePiece(1, 2, 0)
record("piece1_replaced", ralg)

threads = WVCReader(FileName=first, Threads=-5)  # noqa: F821
talg = threads.GetClientSideObject()
talg.Update()
record("threads", talg)
print(json.dumps(steps))
