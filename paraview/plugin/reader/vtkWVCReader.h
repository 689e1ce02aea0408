// SPDX-License-Identifier: MIT
// vtkWVCReader: a libwvol .wvc file as vtkImageData, decoding only the piece the pipeline asks
// for (docs/paraview.md).
//
// Pipeline contract:
// - RequestInformation opens the file (header and chunk index only, nothing decoded) and sets
//   WHOLE_EXTENT (the Region on the grid of LevelOfDetail s: ceil(n / 2^s) samples per
//   transformed axis), SPACING (x 2^s), ORIGIN (the level grid's first sample, wvol_idwt3_level's
//   convention) and CAN_PRODUCE_SUB_EXTENT, so a parallel pipeline gives each rank its own box.
// - RequestData reconstructs exactly the UPDATE_EXTENT (clipped to the whole extent), decoding
//   only the chunks whose basis functions' supports meet it, straight into the output's
//   vtkFloatArray: a box spanning the level's grid along x and y (a z slab, the whole volume)
//   with wvol_wvc_read_piece_into (in place, each chunk decoded once), any other box slab by
//   slab with wvol_wvc_read_region_into.
// - Field data: PredictedRMSE, PredictedPSNR (the header's quantisation + dropped energy,
//   nothing decoded), KeptCoefficients of Coefficients, and this execution's ChunksDecoded,
//   ChunksDecodedTotal (since the file was opened), Piece, NumberOfPieces, LevelOfDetail.
// - Errors (missing, damaged, truncated or refused file, region outside the volume, level out
//   of range, memory) go through vtkErrorMacro with the library's message and fail the
//   request: the output is empty (also when RequestInformation fails after an earlier
//   success), the process goes on.
// - The open file is the one at FileName: a file replaced at that path since it was opened
//   (another device, inode, size or modification time) is opened again by the next
//   RequestInformation; RequestData refuses to read a replaced file whose information the
//   pipeline has not asked for again (ReleaseCache reopens by path).
#ifndef vtkWVCReader_h
#define vtkWVCReader_h

#include "vtkImageAlgorithm.h"
#include "wvolWVCReaderModule.h" // export macro

#include <string>

struct wvol_wvc_file;

class WVOLWVCREADER_EXPORT vtkWVCReader : public vtkImageAlgorithm
{
public:
  static vtkWVCReader* New();
  vtkTypeMacro(vtkWVCReader, vtkImageAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  // The .wvc file.
  vtkSetStringMacro(FileName);
  vtkGetStringMacro(FileName);
  // 0: full resolution; s: the grid 2^s coarser (the finest s levels are not decoded).
  vtkSetMacro(LevelOfDetail, int);
  vtkGetMacro(LevelOfDetail, int);
  // 0 and the file's number of levels, the LevelOfDetail it offers (ParaView's slider range),
  // once RequestInformation has opened it; 0 and 8 before.
  vtkGetVector2Macro(LevelRange, int);
  // Voxels (x0, x1, y0, y1, z0, z1) of the full grid, bounds included; an upper bound < 0 is
  // the last voxel. At a coarser level: the coarse samples whose cells meet it.
  vtkSetVector6Macro(Region, int);
  vtkGetVector6Macro(Region, int);
  // Decoded chunks kept per process, MiB (0: what the chosen read needs). A budget below a
  // piece read's pins sends the read slab by slab; below one chain of chunks it is refused.
  vtkSetMacro(MemoryBudget, int);
  vtkGetMacro(MemoryBudget, int);
  // 1: close the file after each execution (its decoded chunks freed); 0: keep them.
  vtkSetMacro(ReleaseCache, int);
  vtkGetMacro(ReleaseCache, int);
  // Threads decoding a piece (0: the cores this process may use over the ranks on this node).
  vtkSetMacro(Threads, int);
  vtkGetMacro(Threads, int);
  vtkSetStringMacro(ArrayName);
  vtkGetStringMacro(ArrayName);
  // A file that gets one JSON line per execution (rank, piece, extent, chunks, seconds); "" none.
  vtkSetStringMacro(ChunkLog);
  vtkGetStringMacro(ChunkLog);

protected:
  vtkWVCReader();
  ~vtkWVCReader() override;

  int RequestInformation(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;
  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;

private:
  vtkWVCReader(const vtkWVCReader&) = delete;
  void operator=(const vtkWVCReader&) = delete;

  // The identity of the file at a path (device, inode, size, modification time), so that a
  // file replaced at FileName is noticed.
  struct Identity
  {
    unsigned long long dev = 0, ino = 0, size = 0;
    long long mtime_sec = 0, mtime_nsec = 0;
    bool operator==(const Identity& o) const
    {
      return dev == o.dev && ino == o.ino && size == o.size && mtime_sec == o.mtime_sec && mtime_nsec == o.mtime_nsec;
    }
  };
  static Identity IdentityOf(const char* path);

  bool Open(std::string& message);
  void Close();
  int ThreadCount() const;
  // "FileName: message", the file name left out where the library's message already has it.
  std::string Describe(const std::string& message) const;

  char* FileName = nullptr;
  int LevelOfDetail = 0;
  int LevelRange[2] = { 0, 8 };
  int Region[6] = { 0, -1, 0, -1, 0, -1 };
  int MemoryBudget = 0;
  int ReleaseCache = 0;
  int Threads = 0;
  char* ArrayName = nullptr;
  char* ChunkLog = nullptr;

  wvol_wvc_file* File = nullptr; // open handle of OpenedPath with OpenedBudget
  std::string OpenedPath;
  int OpenedBudget = -1;
  Identity OpenedIdentity;      // of the file File reads
  Identity InformationIdentity; // of the file the last RequestInformation described
  int WholeExtent[6] = { 0, -1, 0, -1, 0, -1 };
  bool HaveInformation = false;
};

#endif
