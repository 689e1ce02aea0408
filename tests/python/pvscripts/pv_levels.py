# SPDX-License-Identifier: MIT
"""Run by pvpython (tests/python/test_paraview.py): the LevelOfDetail slider's range once the
reader has read a file's information. Prints RANGE min max. Usage:
    pvpython pv_levels.py PLUGIN FILE"""
import sys

from paraview.simple import LoadPlugin

LoadPlugin(sys.argv[1], ns=globals())
reader = WVCReader(FileName=sys.argv[2])  # noqa: F821 (from the plugin)
reader.UpdatePipelineInformation()
domain = reader.GetProperty("LevelOfDetail").SMProperty.GetDomain("range")
print(f"RANGE {domain.GetMinimum(0)} {domain.GetMaximum(0)}")
