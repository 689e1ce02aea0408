# SPDX-License-Identifier: MIT
"""A VTK reader of .wvc files that decodes only the piece the pipeline asks for.

:class:`WVCReader` is a ``VTKPythonAlgorithmBase`` (a source with one ``vtkImageData``
output) for plain VTK scripts (Debian's ``python3-vtk9``). ParaView has the same reader in C++,
``vtkWVCReader`` (``paraview/``, the plugin scripts/setup.sh builds): the same contract, no
Python in its read path (docs/paraview.md says why two). The VTK modules are whichever
``vtkmodules`` the running Python has.

Pipeline contract:

- ``RequestInformation`` reads the header and chunk index only (nothing decoded): the whole
  extent is the region in the grid of the chosen level of detail (level ``s`` is
  ``wvol_idwt3_level``'s grid: 2^s coarser, spacing 2^s times larger, its first sample shifted
  by the filter's centre), with ``CAN_PRODUCE_SUB_EXTENT`` set, so a parallel pipeline gives
  each piece its own sub-extent.
- ``RequestData`` reconstructs exactly the ``UPDATE_EXTENT``, decoding only the chunks whose
  basis functions' supports meet that box: N pieces decode about 1/N of the chunks each (plus
  the chunks near the cuts and the coarse levels that several pieces need). A piece spanning
  the grid along x and y (a z slab, the whole volume) is decoded straight into its own array
  and inverted in place (``wvol_wvc_read_piece_into``); any other box is reconstructed slab by
  slab (``wvol_wvc_read_region_into``).
- The output carries one point array (``ArrayName``, default ``"values"``) and field data:
  the file's error report (``PredictedRMSE``, ``PredictedPSNR`` from the header's recorded
  quantisation + dropped energy, ``KeptCoefficients`` of ``Coefficients``) and this
  execution's chunk work (``ChunksDecoded``, ``ChunksDecodedTotal`` over the open file,
  ``Piece``, ``NumberOfPieces``, ``LevelOfDetail``).
- With ``ChunkLog`` set to a path, every execution also appends one JSON line there
  (piece, rank, extent, chunks decoded, threads, seconds): how the MPI tests and the
  benchmark see each rank's share.
- Errors (a missing, damaged or refused file, a region outside the volume, a level out of
  range) are reported through VTK's error output with the library's message, and the
  request fails: the pipeline stops, the process does not, and the output is empty (also
  when a request fails after an earlier one succeeded).
- The open file is the one at ``FileName``: a file replaced at that path since it was opened
  (another device, inode, size or modification time) is opened again by the next
  ``RequestInformation``; ``RequestData`` refuses to read a replaced file whose information the
  pipeline has not asked for again (``ReleaseCache`` reopens by path).
"""
import json
import math
import os
import time

import numpy as np
from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import (VTK_FLOAT, vtkDataArray, vtkDoubleArray, vtkInformationVector,
                                      vtkOutputWindow, vtkTypeInt64Array)
from vtkmodules.vtkCommonDataModel import vtkDataObject, vtkImageData
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm, vtkStreamingDemandDrivenPipeline

from . import _int, _ints, _psnr, _threads, _wvol

SDDP = vtkStreamingDemandDrivenPipeline
# Samples reconstructed per region read (32 MiB of float32): bounds the working memory of a
# piece's reconstruction beyond its output array (see WVCReader._read_slabs).
SLAB_SAMPLES = 1 << 23
# Pieces that span the grid along x and y are decoded straight into their array (the piece
# read); False sends every request through the slab-by-slab region read (tests compare both).
PIECE_READS = True
# The largest MemoryBudget, MiB: the C++ reader's int property (vtkWVCReader).
MAX_BUDGET_MIB = 2**31 - 1


def _identity(path):
    """The file at path as (device, inode, size, modification time), None where there is none:
    a file replaced at the path has another."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


def _return_freed_memory():
    """Hands the pages glibc's malloc keeps after a read (the decoded chunks and the
    reconstruction buffers, freed but left in the heap) back to the system, so that the
    pipeline's next stage does not stack its own allocations on top of them. A no-op where
    the C library is not glibc."""
    try:
        import ctypes
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def _rank():
    """This process's rank in the global MPI controller (0 without one)."""
    try:
        from vtkmodules.vtkParallelCore import vtkMultiProcessController
    except ImportError:
        return 0
    c = vtkMultiProcessController.GetGlobalController()
    return c.GetLocalProcessId() if c is not None else 0


def error_report(info):
    """The file's predicted error and kept coefficients, from its header (nothing decoded):
    ``rmse``/``psnr`` over the voxels of the original grid from the recorded quantisation +
    dropped energy (Parseval: the transform is orthonormal), ``kept`` non-zero quantised
    coefficients of ``coefficients`` (the padded grid)."""
    voxels = int(np.prod(info["shape"]))
    l2 = math.sqrt(max(float(info["sse"]), 0.0))
    peak = float(info["value_range"][1] - info["value_range"][0])
    return {"rmse": l2 / math.sqrt(voxels), "psnr": _psnr(l2, voxels, peak), "kept": int(info["nonzero"]),
            "coefficients": int(np.prod(info["padded"]))}


def _hand_over_range(arr, data):
    """Puts the array's value range into vtkDataArray's range cache (PER_COMPONENT and
    PER_FINITE_COMPONENT, one COMPONENT_RANGE each), as VTK does once it has scanned an array:
    renderers and ParaView ask for both ranges of every array shown, and numpy's scan is faster
    than VTK's. Only when every value is finite (the two ranges are then equal); otherwise VTK
    computes them as usual. Called last: a Modified() on the array drops the keys."""
    lo, hi = float(data.min()), float(data.max())  # NaN propagates: refused by isfinite below
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return
    info = arr.GetInformation()
    for key in (vtkDataArray.PER_COMPONENT(), vtkDataArray.PER_FINITE_COMPONENT()):
        per = vtkInformationVector()
        per.SetNumberOfInformationObjects(1)
        per.GetInformationObject(0).Set(vtkDataArray.COMPONENT_RANGE(), (lo, hi), 2)
        info.Set(key, per)


class WVCReader(VTKPythonAlgorithmBase):
    """Reads a .wvc file into ``vtkImageData``, decoding only the requested extent (see the
    module's docstring for the pipeline contract)."""

    def __init__(self):
        VTKPythonAlgorithmBase.__init__(self, nInputPorts=0, nOutputPorts=1, outputType="vtkImageData")
        self._filename = None
        self._level = 0
        self._region = (0, -1, 0, -1, 0, -1)
        self._budget_mib = 0
        self._array_name = "values"
        self._chunk_log = ""
        self._release = False
        self._threads = 0
        self._file = None       # open handle (capsule) of self._opened
        self._opened = None     # (path, budget, identity) the handle was opened with
        self._info_identity = None  # identity of the file the last RequestInformation described
        self._info = None
        self._extent = None     # whole extent of the current level and region

    # ---- properties -----------------------------------------------------------------
    def _set(self, attr, value):
        """Sets a property; a change marks the reader modified (the pipeline re-executes)."""
        if getattr(self, attr) != value:
            setattr(self, attr, value)
            self.Modified()

    def SetFileName(self, name):
        self._set("_filename", os.fspath(name) if name else None)

    def GetFileName(self):
        return self._filename

    def SetLevelOfDetail(self, level):
        """0: full resolution; s: the grid 2^s coarser (the finest s levels not decoded)."""
        self._set("_level", _int(level, "LevelOfDetail"))

    def GetLevelOfDetail(self):
        return self._level

    def SetRegion(self, *ext):
        """Voxels (x0, x1, y0, y1, z0, z1) of the original grid, bounds included, like a VTK
        extent; an upper bound below 0 means the last voxel. The default is the whole volume.
        At a coarser level the region covers the coarse samples whose cells meet it."""
        ext = _ints(ext[0] if len(ext) == 1 else ext, "Region", "(x0, x1, y0, y1, z0, z1)")
        self._set("_region", ext)

    def GetRegion(self):
        return self._region

    def SetMemoryBudget(self, mib):
        """Decoded chunks kept per process, in MiB (0: what reading slab by slab needs,
        wvol_wvc_slab_budget, for the whole grid). A budget below that need still works, but
        decodes chunks several times (ChunksDecoded shows it)."""
        mib = _int(mib, "MemoryBudget")
        if not 0 <= mib <= MAX_BUDGET_MIB:
            raise ValueError(f"MemoryBudget must be in 0..{MAX_BUDGET_MIB} MiB (0: what slab by slab needs), got {mib}")
        self._set("_budget_mib", mib)

    def SetArrayName(self, name):
        if not isinstance(name, str) or not name:
            raise TypeError(f"ArrayName must be a non-empty string, got {name!r}")
        self._set("_array_name", name)

    def SetChunkLog(self, path):
        """A file that gets one JSON line per execution (piece, rank, extent, chunks); "" for none."""
        self._set("_chunk_log", os.fspath(path) if path else "")

    def SetReleaseCache(self, release):
        """True: close the file after each execution, freeing its decoded chunks (the memory
        then holds the output only; a later execution, such as a ghost-layer request, decodes
        its chunks again). False (default): keep them for the next request."""
        self._release = bool(release)

    def SetThreads(self, threads):
        """Threads that reconstruct a piece (slices along z at once); 0 (default): the cores
        this process may use, shared among the MPI ranks of this node."""
        self._set("_threads", _threads(threads, "Threads"))

    def GetThreads(self):
        return self._threads

    def GetFileInfo(self):
        """The open file's header (dict), or None before the first update."""
        return self._info

    def GetChunkStats(self):
        """The chunk cache's counters of the open file (dict), or None."""
        return _wvol.wvc_file_stats(self._file) if self._file is not None else None

    # ---- pipeline -------------------------------------------------------------------
    def _fail(self, message):
        """Reports message (prefixed with the file name unless the library's message has it) on
        VTK's error output and fails the request."""
        name = self._filename or "(no file)"
        text = message if name in message else f"{name}: {message}"
        vtkOutputWindow.GetInstance().DisplayErrorText(f"ERROR: WVCReader: {text}\n")
        return 0

    def _open(self):
        if not self._filename:
            raise ValueError("no file name set")
        key = (self._filename, self._budget_mib, _identity(self._filename))
        if self._opened != key:
            self._file = self._info = self._opened = None
            self._file = _wvol.wvc_file_open(self._filename, budget=self._budget_mib << 20)
            self._info = _wvol.wvc_file_info(self._file)
            self._opened = key

    def _level_extent(self):
        """The whole extent (x0, x1, y0, y1, z0, z1) in the grid of the chosen level."""
        info, s = self._info, self._level
        if not 0 <= s <= info["levels"]:
            raise ValueError(f"level of detail {s} outside 0..{info['levels']}")
        shape0 = info["shape"][::-1]            # (x, y, z)
        shape = info["level_shapes"][s][::-1]
        padded = info["padded"][::-1]
        ext = []
        for a in range(3):
            lo, hi = self._region[2 * a], self._region[2 * a + 1]
            if hi < 0:
                hi = shape0[a] - 1
            if lo < 0 or lo > hi or hi >= shape0[a]:
                raise ValueError(f"region {self._region[2 * a]}..{self._region[2 * a + 1]} along axis {'xyz'[a]} "
                                 f"is empty or outside 0..{shape0[a] - 1}")
            f = 1 << s if padded[a] > 1 else 1
            ext += [lo // f, min(-(-(hi + 1) // f), shape[a]) - 1]
        return tuple(ext)

    def RequestInformation(self, request, inInfoVec, outInfoVec):
        # a failed request leaves an empty output, not the previous file's data (the executive
        # does not call RequestData after a failed RequestInformation)
        previous = vtkImageData.GetData(outInfoVec, 0)
        if previous is not None:
            previous.Initialize()
        try:
            self._open()
            self._extent = self._level_extent()
        except (OSError, ValueError, MemoryError) as e:
            self._extent = None
            return self._fail(str(e))
        self._info_identity = self._opened[2]
        info, s = self._info, self._level
        out = outInfoVec.GetInformationObject(0)
        padded = info["padded"][::-1]
        spacing = [info["spacing"][a] * (2 ** s if padded[a] > 1 else 1) for a in range(3)]
        out.Set(SDDP.WHOLE_EXTENT(), self._extent, 6)
        out.Set(vtkDataObject.SPACING(), spacing, 3)
        out.Set(vtkDataObject.ORIGIN(), info["level_origins"][s], 3)
        out.Set(vtkAlgorithm.CAN_PRODUCE_SUB_EXTENT(), 1)
        vtkImageData.SetScalarType(VTK_FLOAT, out)
        vtkImageData.SetNumberOfScalarComponents(1, out)
        return 1

    def _thread_count(self):
        """Threads for one piece: the Threads property, or the cores this process may run on
        divided among the ranks Open MPI or MPICH started on this node."""
        if self._threads > 0:
            return self._threads
        try:
            cores = len(os.sched_getaffinity(0))
        except (AttributeError, OSError):
            cores = os.cpu_count() or 1
        local = 1
        for var in ("OMPI_COMM_WORLD_LOCAL_SIZE", "MPI_LOCALNRANKS", "MV2_COMM_WORLD_LOCAL_SIZE"):
            if os.environ.get(var, "").isdigit():
                local = max(1, int(os.environ[var]))
                break
        return max(1, cores // local)

    def _read(self, ue):
        """The samples of extent ue as a (z, y, x) array, its spacing and how it was read.

        A piece that spans the level's grid along x and y (what ParaView's extent translator
        gives each rank of a cubic volume, or the whole volume) is decoded straight into its
        own array and inverted in place (``wvc_file_piece``: each chunk decoded once, the
        cache holding one chain of chunks); any other box is reconstructed slab by slab
        (:meth:`_read_slabs`). With ``MemoryBudget`` 0 the cache's budget is set to what the
        chosen read needs (more would only raise the peak: the cache is transient, the
        output array is what stays)."""
        lo, hi = [ue[0], ue[2], ue[4]], [ue[1] + 1, ue[3] + 1, ue[5] + 1]
        threads = self._thread_count()
        need = _wvol.wvc_file_piece_budget(self._file, threads)
        if PIECE_READS and need > 0 and (self._budget_mib == 0 or self._budget_mib << 20 >= need):
            if self._budget_mib == 0:
                _wvol.wvc_file_set_budget(self._file, need)
            piece = _wvol.wvc_file_piece(self._file, lo, hi, self._level, threads)
            if piece is not None:
                return piece[0], piece[1], "piece"
        if self._budget_mib == 0:
            # what the slabs need: less would decode chunks again slab after slab
            shape = self._info["shape"][::-1]  # (x, y, z)
            slab = _wvol.wvc_file_slab_budget(self._file, [0, 0, 0], shape)
            if slab > 0:
                _wvol.wvc_file_set_budget(self._file, slab)
        data, spacing = self._read_slabs(ue)
        return data, spacing, "slabs"

    def _read_slabs(self, ue):
        """The samples of extent ue as a (z, y, x) array, reconstructed in place slab by slab
        along z (SLAB_SAMPLES at most each): a region read's working memory (the box's
        coefficients and reconstruction buffers) is then bounded by a slab, not the piece,
        and the chunks of consecutive slabs are mostly shared, so the cache (least recently
        used first out) serves them without decoding twice."""
        nx, ny, nz = ue[1] - ue[0] + 1, ue[3] - ue[2] + 1, ue[5] - ue[4] + 1
        # no thicker than a tile layer's depth: a slab and its halo then meet at most two
        # layers of every level, what the cache is sized for (wvol_wvc_slab_budget)
        planes = max(1, min(nz, SLAB_SAMPLES // (nx * ny), self._info["tile"][1] or nz))
        out = np.empty((nz, ny, nx), dtype=np.float32)
        spacing = None
        threads = self._thread_count()
        for z0 in range(0, nz, planes):
            z1 = min(nz, z0 + planes)
            _, spacing, _ = _wvol.wvc_file_region(self._file, [ue[0], ue[2], ue[4] + z0],
                                                  [ue[1] + 1, ue[3] + 1, ue[4] + z1], self._level,
                                                  out=out[z0:z1], threads=threads)
        return out, spacing

    def RequestData(self, request, inInfoVec, outInfoVec):
        output = vtkImageData.GetData(outInfoVec, 0)
        output.Initialize()
        if self._extent is None:
            return self._fail("no file information (RequestInformation failed)")
        if self._file is None:  # released after the previous execution
            try:
                self._open()
            except (OSError, ValueError, MemoryError) as e:
                return self._fail(str(e))
            if self._opened[2] != self._info_identity:
                # another file at the path: its extent, spacing and origin are not the ones the
                # pipeline was given
                self._file = self._opened = None
                return self._fail("the file was replaced since its information was read: update the pipeline "
                                  "again (Modified())")
        out_info = outInfoVec.GetInformationObject(0)
        ue = list(out_info.Get(SDDP.UPDATE_EXTENT()) or self._extent)
        piece = out_info.Get(SDDP.UPDATE_PIECE_NUMBER()) if out_info.Has(SDDP.UPDATE_PIECE_NUMBER()) else 0
        pieces = (out_info.Get(SDDP.UPDATE_NUMBER_OF_PIECES())
                  if out_info.Has(SDDP.UPDATE_NUMBER_OF_PIECES()) else 1)
        # Clip to the whole extent: an executive may pad a request with ghost layers.
        for a in range(3):
            ue[2 * a] = max(ue[2 * a], self._extent[2 * a])
            ue[2 * a + 1] = min(ue[2 * a + 1], self._extent[2 * a + 1])
        info = self._info
        started = time.perf_counter()
        spacing = out_info.Get(vtkDataObject.SPACING())
        before = _wvol.wvc_file_stats(self._file)["decoded"]
        empty = any(ue[2 * a] > ue[2 * a + 1] for a in range(3))
        how = None
        if empty:
            output.SetExtent(0, -1, 0, -1, 0, -1)
        else:
            try:
                data, spacing, how = self._read(ue)
            except (OSError, ValueError, MemoryError) as e:
                return self._fail(str(e))
            output.SetExtent(ue)
            output.SetSpacing(spacing)
            output.SetOrigin(info["level_origins"][self._level])
            arr = numpy_support.numpy_to_vtk(data.reshape(-1), deep=0)  # keeps a reference to data
            arr.SetName(self._array_name)
            output.GetPointData().SetScalars(arr)
            _hand_over_range(arr, data)
        stats = _wvol.wvc_file_stats(self._file)
        decoded = stats["decoded"] - before
        rep = error_report(info)
        fd = output.GetFieldData()
        for name, value in (("PredictedRMSE", rep["rmse"]), ("PredictedPSNR", rep["psnr"])):
            a = vtkDoubleArray()
            a.SetName(name)
            a.InsertNextValue(value)
            fd.AddArray(a)
        for name, value in (("KeptCoefficients", rep["kept"]), ("Coefficients", rep["coefficients"]),
                            ("ChunksDecoded", decoded), ("ChunksDecodedTotal", stats["decoded"]),
                            ("Piece", piece), ("NumberOfPieces", pieces), ("LevelOfDetail", self._level)):
            a = vtkTypeInt64Array()
            a.SetName(name)
            a.InsertNextValue(int(value))
            fd.AddArray(a)
        if self._chunk_log:
            line = json.dumps({"rank": _rank(), "pid": os.getpid(), "piece": piece, "pieces": pieces,
                               "level": self._level, "extent": None if empty else ue, "decoded": decoded,
                               "decoded_total": stats["decoded"], "chunks": info["chunks"],
                               "cache_peak_bytes": stats["peak"], "threads": self._thread_count(), "read": how,
                               "seconds": time.perf_counter() - started})
            try:
                with open(self._chunk_log, "a") as f:  # one short write per line: O_APPEND keeps lines whole
                    f.write(line + "\n")
            except OSError as e:  # the data is read: a log that cannot be written is a warning
                vtkOutputWindow.GetInstance().DisplayWarningText(
                    f"Warning: WVCReader: cannot append to the chunk log {self._chunk_log}: {e.strerror}\n")
        if self._release:
            self._file = self._opened = None
        _return_freed_memory()
        return 1

