# SPDX-License-Identifier: MIT
"""ParaView plugin: the libwvol .wvc reader (wvol.vtk_wvc.WVCReader) as a ParaView reader.

Load it with ``LoadPlugin(".../wvol_wvc_plugin.py", ns=globals())`` in pvpython/pvbatch,
``--plugin-directory``/``PV_PLUGIN_PATH`` pointing at its folder, or Tools > Manage Plugins in
the GUI. It needs the wvol Python package built WITHOUT the VTK adapter (scripts/setup.sh
builds it into build-paraview/python, and installs this file as
build-paraview/paraview-plugins/wvol_wvc_plugin.py): ParaView carries its own VTK, and a
module that links Debian's VTK 9.1 would put two VTKs in one process (docs/paraview.md).
"""
import os
import sys

from paraview.util.vtkAlgorithm import smdomain, smhint, smproperty, smproxy

# The wvol package sits next to the plugin folder in a build tree (build-paraview/python);
# a PYTHONPATH given by the user comes first.
_here = os.path.dirname(os.path.abspath(__file__))
_pkg = os.path.join(os.path.dirname(_here), "python")
if os.path.isdir(os.path.join(_pkg, "wvol")) and _pkg not in sys.path:
    sys.path.append(_pkg)

from wvol import _wvol  # noqa: E402

if _wvol.built_with_vtk():
    raise ImportError(f"wvol_wvc_plugin: the wvol module at {_wvol.__file__} links Debian's VTK, which must not "
                      "meet ParaView's VTK in one process: use the build without VTK (build-paraview/python, "
                      "see docs/paraview.md)")

from wvol.vtk_wvc import WVCReader  # noqa: E402


@smproxy.reader(name="WVCReader", label="WVC Reader", extensions="wvc",
                file_description="libwvol wavelet-compressed volume")
class WVCParaViewReader(WVCReader):
    """Decodes only the chunks each rank's piece needs (CAN_PRODUCE_SUB_EXTENT)."""

    @smproperty.stringvector(name="FileName")
    @smdomain.filelist()
    @smhint.filechooser(extensions="wvc", file_description="libwvol wavelet-compressed volume")
    def SetFileName(self, name):
        WVCReader.SetFileName(self, name)

    @smproperty.intvector(name="LevelOfDetail", default_values=0)
    @smdomain.intrange(min=0, max=8)
    def SetLevelOfDetail(self, level):
        """0: full resolution; s: the grid 2^s coarser (finer levels not decoded)."""
        WVCReader.SetLevelOfDetail(self, level)

    @smproperty.intvector(name="Region", number_of_elements=6, default_values=[0, -1, 0, -1, 0, -1])
    def SetRegion(self, x0, x1, y0, y1, z0, z1):
        """Voxels of the original grid, bounds included; an upper bound < 0 is the last voxel."""
        WVCReader.SetRegion(self, x0, x1, y0, y1, z0, z1)

    @smproperty.intvector(name="MemoryBudget", default_values=0)
    def SetMemoryBudget(self, mib):
        """Decoded chunks kept per rank, in MiB (0: the library's default, 1 GiB)."""
        WVCReader.SetMemoryBudget(self, mib)

    @smproperty.intvector(name="ReleaseCache", default_values=0)
    @smdomain.xml("<BooleanDomain name='bool'/>")
    def SetReleaseCache(self, release):
        """Close the file after each execution, freeing the decoded chunks (default: keep them)."""
        WVCReader.SetReleaseCache(self, release)

    @smproperty.stringvector(name="ArrayName", default_values="values")
    def SetArrayName(self, name):
        WVCReader.SetArrayName(self, name)

    @smproperty.stringvector(name="ChunkLog", default_values="")
    def SetChunkLog(self, path):
        """A file that gets one JSON line per execution and rank (chunks decoded)."""
        WVCReader.SetChunkLog(self, path)

    @smproperty.intvector(name="Threads", default_values=0)
    @smdomain.intrange(min=0, max=256)
    def SetThreads(self, threads):
        """Threads reconstructing a rank's piece (0: this node's cores shared among its ranks)."""
        WVCReader.SetThreads(self, threads)
