# SPDX-License-Identifier: MIT
"""Run by pvpython (tests/python/test_paraview.py): loads the .wvc reader plugin, reads a file at a
level of detail (and optionally a region), saves the point array as .npy and prints the
geometry, the field data and the value range the reader handed over with its array as one JSON line. Usage:
    pvpython pv_read.py PLUGIN FILE LEVEL OUT.npy [x0 x1 y0 y1 z0 z1]
(PLUGIN is loaded with LoadPlugin unless ParaView loaded it at start-up from PV_PLUGIN_PATH.)"""
import json
import sys

import numpy as np
import paraview.simple as pvs
from paraview import servermanager
from paraview.simple import LoadPlugin
from vtkmodules.util.numpy_support import vtk_to_numpy

plugin, path, level, out = sys.argv[1:5]
autoloaded = hasattr(pvs, "WVCReader")  # loaded at start-up from PV_PLUGIN_PATH
if autoloaded:
    WVCReader = pvs.WVCReader
else:
    LoadPlugin(plugin, ns=globals())  # defines WVCReader here
reader = WVCReader(FileName=path, LevelOfDetail=int(level))  # noqa: F821
if len(sys.argv) > 5:
    reader.Region = [int(v) for v in sys.argv[5:11]]
reader.UpdatePipeline()
# the range the reader hands over with its array (vtkDataArray's cache keys), read from the
# reader's own output before Fetch copies it; None where it handed none over
own = reader.GetClientSideObject().GetOutputDataObject(0).GetPointData().GetArray("values")
known = None
if own is not None and own.GetInformation().Has(own.PER_COMPONENT()):
    finite = own.GetInformation().Has(own.PER_FINITE_COMPONENT())
    known = {"range": list(own.GetRange(0)), "finite_range": list(own.GetFiniteRange(0)) if finite else None}
data = servermanager.Fetch(reader)
ext = data.GetExtent()
shape = (ext[5] - ext[4] + 1, ext[3] - ext[2] + 1, ext[1] - ext[0] + 1)
arr = data.GetPointData().GetArray("values")
if arr is None:
    print(json.dumps({"points": data.GetNumberOfPoints()}))
    sys.exit(3)
np.save(out, vtk_to_numpy(arr).reshape(shape))
fd = data.GetFieldData()
field = {fd.GetArrayName(i): fd.GetArray(i).GetTuple1(0) for i in range(fd.GetNumberOfArrays())}
print(json.dumps({"autoloaded": autoloaded, "extent": list(ext), "spacing": list(data.GetSpacing()), "origin": list(data.GetOrigin()),
                  "field": field, "known_range": known}))
