// SPDX-License-Identifier: MIT
// vtkWVCReader (the contract is in the header; the choices in docs/paraview.md).
#include "vtkWVCReader.h"

#include "vtkDataObject.h"
#include "vtkDoubleArray.h"
#include "vtkFieldData.h"
#include "vtkFloatArray.h"
#include "vtkImageData.h"
#include "vtkInformation.h"
#include "vtkInformationDoubleVectorKey.h"
#include "vtkInformationInformationVectorKey.h"
#include "vtkInformationVector.h"
#include "vtkMultiProcessController.h"
#include "vtkObjectFactory.h"
#include "vtkPointData.h"
#include "vtkStreamingDemandDrivenPipeline.h"
#include "vtkTypeInt64Array.h"

#include "wvol/wvc.h"

#include <algorithm>
#include <cstdint>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <thread>

#ifdef __GLIBC__
#include <malloc.h> // malloc_trim
#endif
#include <sched.h>
#include <sys/mman.h> // madvise
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

vtkStandardNewMacro(vtkWVCReader);

namespace
{
using SDDP = vtkStreamingDemandDrivenPipeline;

// Samples reconstructed per region read (32 MiB of float32): bounds a slab read's working memory
// (the box's coefficients and reconstruction buffers) beyond the output array.
constexpr size_t SlabSamples = size_t(1) << 23;

bool Transformed(const wvol_wvc_info* in, int a)
{
  const size_t p[3] = { in->px, in->py, in->pz };
  return p[a] > 1;
}

// Hands the pages glibc keeps after a read (decoded chunks, reconstruction buffers: freed but
// left in the heap) back to the system, so that the renderer's allocations do not stack on them.
void ReturnFreedMemory()
{
#ifdef __GLIBC__
  malloc_trim(0);
#endif
}

// This process's resident and peak resident set in MiB (VmRSS, VmHWM of /proc/self/status; -1
// where there is no such file): the chunk log's record of what a read adds on each rank.
void ProcessMemory(double& rss, double& peak)
{
  rss = peak = -1.0;
  if (FILE* f = std::fopen("/proc/self/status", "r"))
  {
    char line[256];
    while (std::fgets(line, sizeof line, f))
    {
      long kib;
      if (std::sscanf(line, "VmRSS: %ld kB", &kib) == 1)
      {
        rss = kib / 1024.0;
      }
      else if (std::sscanf(line, "VmHWM: %ld kB", &kib) == 1)
      {
        peak = kib / 1024.0;
      }
    }
    std::fclose(f);
  }
}

// CPU seconds of this process, all threads (the chunk log's load-independent measure of a read).
double ProcessCPUSeconds()
{
  timespec t;
  return clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t) == 0 ? t.tv_sec + 1e-9 * t.tv_nsec : -1.0;
}

// Asks for transparent huge pages on a large buffer where the kernel leaves them to madvise: the
// piece read's z pass steps a plane (MiBs) at a time through it, and 2 MiB pages take most of
// the page faults and TLB misses out of filling it. Advice only: nothing changes if refused.
void AdviseHugePages(void* p, size_t bytes)
{
#ifdef MADV_HUGEPAGE
  const uintptr_t page = 4096, a = (reinterpret_cast<uintptr_t>(p) + page - 1) & ~(page - 1);
  const uintptr_t end = reinterpret_cast<uintptr_t>(p) + bytes;
  if (bytes >= (size_t(64) << 20) && end > a)
  {
    madvise(reinterpret_cast<void*>(a), size_t(end - a) & ~(page - 1), MADV_HUGEPAGE);
  }
#else
  (void)p;
  (void)bytes;
#endif
}

// Hands the array's value range to VTK with the array, as vtkDataArray caches a range it has
// computed (PER_COMPONENT and PER_FINITE_COMPONENT, one COMPONENT_RANGE each): ParaView asks for
// both ranges of every array it is shown, and VTK's scan (sequential in Debian's build, through
// double) costs more than the decode of the piece. One pass here, eight lanes the compiler can
// keep in vector registers. Set only when every value is finite (then the two ranges are equal);
// otherwise VTK computes them as usual. Set last: any Modified() on the array drops the keys.
void SetKnownRange(vtkFloatArray* values)
{
  const float* v = values->GetPointer(0);
  const size_t n = size_t(values->GetNumberOfValues());
  if (n == 0)
  {
    return;
  }
  constexpr size_t L = 8;
  float lo[L], hi[L];
  bool nan[L];
  for (size_t l = 0; l < L; l++)
  {
    lo[l] = hi[l] = v[0];
    nan[l] = false;
  }
  size_t i = 0;
  for (; i + L <= n; i += L)
  {
    for (size_t l = 0; l < L; l++)
    {
      const float x = v[i + l];
      lo[l] = x < lo[l] ? x : lo[l];
      hi[l] = x > hi[l] ? x : hi[l];
      nan[l] |= x != x;
    }
  }
  for (; i < n; i++)
  {
    lo[0] = v[i] < lo[0] ? v[i] : lo[0];
    hi[0] = v[i] > hi[0] ? v[i] : hi[0];
    nan[0] |= v[i] != v[i];
  }
  double range[2] = { lo[0], hi[0] };
  bool any_nan = nan[0];
  for (size_t l = 1; l < L; l++)
  {
    range[0] = std::min(range[0], double(lo[l]));
    range[1] = std::max(range[1], double(hi[l]));
    any_nan |= nan[l];
  }
  if (any_nan || !std::isfinite(range[0]) || !std::isfinite(range[1]))
  {
    return;
  }
  vtkInformation* info = values->GetInformation();
  for (vtkInformationInformationVectorKey* key :
    { vtkAbstractArray::PER_COMPONENT(), vtkAbstractArray::PER_FINITE_COMPONENT() })
  {
    vtkNew<vtkInformationVector> per;
    per->SetNumberOfInformationObjects(1);
    per->GetInformationObject(0)->Set(vtkDataArray::COMPONENT_RANGE(), range, 2);
    info->Set(key, per);
  }
}

template <typename A, typename V>
void AddField(vtkFieldData* fd, const char* name, V value)
{
  vtkNew<A> a;
  a->SetName(name);
  a->InsertNextValue(value);
  fd->AddArray(a);
}
}

vtkWVCReader::vtkWVCReader()
{
  this->SetNumberOfInputPorts(0);
  this->SetArrayName("values");
  this->SetChunkLog("");
}

vtkWVCReader::~vtkWVCReader()
{
  this->Close();
  this->SetFileName(nullptr);
  this->SetArrayName(nullptr);
  this->SetChunkLog(nullptr);
}

void vtkWVCReader::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "FileName: " << (this->FileName ? this->FileName : "(none)") << "\n";
  os << indent << "LevelOfDetail: " << this->LevelOfDetail << "\n";
  os << indent << "Region: " << this->Region[0] << " " << this->Region[1] << " " << this->Region[2] << " "
     << this->Region[3] << " " << this->Region[4] << " " << this->Region[5] << "\n";
  os << indent << "MemoryBudget: " << this->MemoryBudget << " MiB\n";
  os << indent << "ReleaseCache: " << this->ReleaseCache << "\n";
  os << indent << "Threads: " << this->Threads << "\n";
}

vtkWVCReader::Identity vtkWVCReader::IdentityOf(const char* path)
{
  Identity id;
  struct stat st;
  if (path && stat(path, &st) == 0)
  {
    id.dev = st.st_dev;
    id.ino = st.st_ino;
    id.size = (unsigned long long)st.st_size;
    id.mtime_sec = st.st_mtim.tv_sec;
    id.mtime_nsec = st.st_mtim.tv_nsec;
  }
  return id;
}

std::string vtkWVCReader::Describe(const std::string& message) const
{
  const std::string name = this->FileName && *this->FileName ? this->FileName : "(no file)";
  return message.find(name) != std::string::npos ? message : name + ": " + message;
}

void vtkWVCReader::Close()
{
  wvol_wvc_close(this->File);
  this->File = nullptr;
  this->OpenedPath.clear();
  this->OpenedBudget = -1;
}

bool vtkWVCReader::Open(std::string& message)
{
  if (!this->FileName || !*this->FileName)
  {
    message = "no file name set";
    return false;
  }
  if (this->MemoryBudget < 0)
  {
    message = "MemoryBudget must be >= 0 MiB (0: what the read needs)";
    return false;
  }
  if (this->Threads < 0 || this->Threads > 4096)
  {
    message = "Threads must be in 0..4096 (0: this node's cores shared among its ranks), got " +
      std::to_string(this->Threads);
    return false;
  }
  const Identity id = IdentityOf(this->FileName);
  if (this->File && this->OpenedPath == this->FileName && this->OpenedBudget == this->MemoryBudget &&
    this->OpenedIdentity == id)
  {
    return true;
  }
  this->Close();
  wvol_error err;
  if (wvol_wvc_open(&this->File, this->FileName, size_t(this->MemoryBudget) << 20, &err) != WVOL_OK)
  {
    this->File = nullptr;
    message = err.message;
    return false;
  }
  this->OpenedPath = this->FileName;
  this->OpenedBudget = this->MemoryBudget;
  this->OpenedIdentity = id;
  return true;
}

int vtkWVCReader::ThreadCount() const
{
  if (this->Threads > 0)
  {
    return this->Threads;
  }
  int cores = 0;
#ifdef CPU_COUNT
  cpu_set_t set;
  if (sched_getaffinity(0, sizeof set, &set) == 0)
  {
    cores = CPU_COUNT(&set);
  }
#endif
  if (cores <= 0)
  {
    cores = std::max(1, int(std::thread::hardware_concurrency()));
  }
  // the ranks Open MPI, MPICH or MVAPICH started on this node share its cores
  int local = 1;
  for (const char* var : { "OMPI_COMM_WORLD_LOCAL_SIZE", "MPI_LOCALNRANKS", "MV2_COMM_WORLD_LOCAL_SIZE" })
  {
    const char* v = std::getenv(var);
    if (v && *v && std::strspn(v, "0123456789") == std::strlen(v))
    {
      local = std::max(1, std::atoi(v));
      break;
    }
  }
  return std::max(1, cores / local);
}

int vtkWVCReader::RequestInformation(vtkInformation*, vtkInformationVector**, vtkInformationVector* outputVector)
{
  this->HaveInformation = false;
  // a failed request leaves an empty output, not the previous file's data (the executive does
  // not call RequestData after a failed RequestInformation)
  if (vtkImageData* previous = vtkImageData::GetData(outputVector, 0))
  {
    previous->Initialize();
  }
  std::string message;
  if (!this->Open(message))
  {
    vtkErrorMacro(<< this->Describe(message));
    return 0;
  }
  const wvol_wvc_info* in = wvol_wvc_file_info(this->File);
  const int s = this->LevelOfDetail;
  this->LevelRange[0] = 0;
  this->LevelRange[1] = in->levels;
  if (s < 0 || s > in->levels)
  {
    vtkErrorMacro(<< this->FileName << ": level of detail " << s << " outside 0.." << in->levels);
    return 0;
  }
  const size_t n0[3] = { in->nx, in->ny, in->nz };
  size_t g[3];
  double spacing[3], origin[3];
  wvol_error err;
  if (wvol_wvc_level_geometry(in, s, g, spacing, origin, &err) != WVOL_OK)
  {
    vtkErrorMacro(<< this->Describe(err.message));
    return 0;
  }
  for (int a = 0; a < 3; a++)
  {
    long long lo = this->Region[2 * a], hi = this->Region[2 * a + 1];
    if (hi < 0)
    {
      hi = (long long)n0[a] - 1;
    }
    if (lo < 0 || lo > hi || hi >= (long long)n0[a])
    {
      vtkErrorMacro(<< this->FileName << ": region " << this->Region[2 * a] << ".." << this->Region[2 * a + 1]
                    << " along axis " << "xyz"[a] << " is empty or outside 0.." << n0[a] - 1);
      return 0;
    }
    const long long f = Transformed(in, a) ? (1LL << s) : 1;
    this->WholeExtent[2 * a] = int(lo / f);
    this->WholeExtent[2 * a + 1] = int(std::min((hi + f) / f, (long long)g[a]) - 1);
  }
  vtkInformation* out = outputVector->GetInformationObject(0);
  out->Set(SDDP::WHOLE_EXTENT(), this->WholeExtent, 6);
  out->Set(vtkDataObject::SPACING(), spacing, 3);
  out->Set(vtkDataObject::ORIGIN(), origin, 3);
  out->Set(vtkAlgorithm::CAN_PRODUCE_SUB_EXTENT(), 1);
  vtkDataObject::SetPointDataActiveScalarInfo(out, VTK_FLOAT, 1);
  this->InformationIdentity = this->OpenedIdentity;
  this->HaveInformation = true;
  return 1;
}

int vtkWVCReader::RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector* outputVector)
{
  const auto started = std::chrono::steady_clock::now();
  const double cpu_started = ProcessCPUSeconds();
  double rss_before, peak_before;
  ProcessMemory(rss_before, peak_before);
  vtkInformation* outInfo = outputVector->GetInformationObject(0);
  vtkImageData* output = vtkImageData::GetData(outInfo);
  if (!output)
  {
    vtkErrorMacro(<< "no image data output");
    return 0;
  }
  output->Initialize();
  const char* name = this->FileName ? this->FileName : "(no file)";
  if (!this->HaveInformation)
  {
    // RequestInformation failed and said why; ParaView's executive still calls RequestData (up
    // to three times an update), which fails again without repeating a message of its own
    return 0;
  }
  if (this->ArrayName && !*this->ArrayName)
  {
    // no name to colour by; the Python reader refuses it as well
    vtkErrorMacro(<< name << ": ArrayName is empty: name the point array (default values)");
    return 0;
  }
  std::string message;
  if (!this->Open(message)) // closed after the previous execution (ReleaseCache)
  {
    vtkErrorMacro(<< this->Describe(message));
    return 0;
  }
  if (!(this->OpenedIdentity == this->InformationIdentity))
  {
    // reopened by path (ReleaseCache) and another file is there now: its extent, spacing and
    // origin are not the ones the pipeline was given
    vtkErrorMacro(<< name << ": the file was replaced since its information was read: update the pipeline "
                  << "again (Modified(), or ParaView's Reload Files)");
    this->Close();
    return 0;
  }
  int ue[6];
  std::copy(this->WholeExtent, this->WholeExtent + 6, ue);
  if (outInfo->Has(SDDP::UPDATE_EXTENT()))
  {
    outInfo->Get(SDDP::UPDATE_EXTENT(), ue);
  }
  // an executive may pad a request with ghost layers beyond the whole extent
  for (int a = 0; a < 3; a++)
  {
    ue[2 * a] = std::max(ue[2 * a], this->WholeExtent[2 * a]);
    ue[2 * a + 1] = std::min(ue[2 * a + 1], this->WholeExtent[2 * a + 1]);
  }
  const int piece =
    outInfo->Has(SDDP::UPDATE_PIECE_NUMBER()) ? outInfo->Get(SDDP::UPDATE_PIECE_NUMBER()) : 0;
  const int pieces =
    outInfo->Has(SDDP::UPDATE_NUMBER_OF_PIECES()) ? outInfo->Get(SDDP::UPDATE_NUMBER_OF_PIECES()) : 1;
  const wvol_wvc_info* in = wvol_wvc_file_info(this->File);
  const int level = this->LevelOfDetail;
  const int threads = this->ThreadCount();
  wvol_wvc_cache_stats before, after;
  wvol_wvc_file_stats(this->File, &before);
  const bool empty = ue[0] > ue[1] || ue[2] > ue[3] || ue[4] > ue[5];
  const char* how = "none";
  if (!empty)
  {
    const size_t lo[3] = { size_t(ue[0]), size_t(ue[2]), size_t(ue[4]) };
    const size_t hi[3] = { size_t(ue[1]) + 1, size_t(ue[3]) + 1, size_t(ue[5]) + 1 };
    const size_t nx = hi[0] - lo[0], ny = hi[1] - lo[1], nz = hi[2] - lo[2], box = nx * ny * nz;
    double spacing[3], origin[3];
    wvol_error err;
    wvol_status st = WVOL_OK;
    vtkNew<vtkFloatArray> values;
    values->SetName(this->ArrayName ? this->ArrayName : "values");
    // The piece read: a box spanning the level's grid along x and y, decoded into its own array
    // (the margins' planes handed back after) when the cache may hold its pins. With
    // MemoryBudget 0 the cache's budget becomes what the read needs: more would only raise the
    // peak (the cache is transient; the output array is what stays).
    const size_t need = wvol_wvc_piece_budget(this->File, threads);
    const size_t cap = wvol_wvc_piece_samples(this->File, level, lo, hi);
    const size_t budget = size_t(this->MemoryBudget) << 20;
    if (need > 0 && cap > 0 && (budget == 0 || budget >= need))
    {
      if (budget == 0)
      {
        st = wvol_wvc_set_budget(this->File, need, &err);
      }
      float* work = st == WVOL_OK ? static_cast<float*>(std::malloc(cap * sizeof(float))) : nullptr;
      if (st == WVOL_OK && !work)
      {
        vtkErrorMacro(<< name << ": out of memory for a piece of " << cap << " samples");
        return 0;
      }
      if (st == WVOL_OK)
      {
        AdviseHugePages(work, cap * sizeof(float));
        st = wvol_wvc_read_piece_into(work, cap, this->File, lo, hi, level, threads, spacing, origin, &err);
      }
      if (st == WVOL_OK)
      {
        if (float* shrunk = static_cast<float*>(std::realloc(work, box * sizeof(float))))
        {
          work = shrunk;
        }
        // the array takes the buffer (freed with free()): no copy
        values->SetArray(work, vtkIdType(box), 0, vtkAbstractArray::VTK_DATA_ARRAY_FREE);
        how = "piece";
      }
      else
      {
        std::free(work);
      }
    }
    else
    {
      if (budget == 0)
      {
        // what slabs of the whole grid need: less decodes chunks again slab after slab
        const size_t z[3] = { 0, 0, 0 }, n[3] = { in->nx, in->ny, in->nz };
        const size_t slab = wvol_wvc_slab_budget(this->File, 0, z, n);
        if (slab > 0)
        {
          st = wvol_wvc_set_budget(this->File, slab, &err);
        }
      }
      if (st == WVOL_OK && !values->Allocate(vtkIdType(box)))
      {
        vtkErrorMacro(<< name << ": out of memory for " << box << " samples");
        return 0;
      }
      values->SetNumberOfTuples(vtkIdType(box));
      // z slabs no thicker than a tile layer: a slab and its halo meet at most two layers of
      // every level, what the cache is sized for (wvol_wvc_slab_budget)
      size_t planes = std::max<size_t>(1, std::min(nz, SlabSamples / (nx * ny)));
      if (in->tile_z > 0)
      {
        planes = std::min(planes, size_t(in->tile_z));
      }
      for (size_t z0 = 0; st == WVOL_OK && z0 < nz; z0 += planes)
      {
        const size_t z1 = std::min(nz, z0 + planes);
        const size_t slo[3] = { lo[0], lo[1], lo[2] + z0 }, shi[3] = { hi[0], hi[1], lo[2] + z1 };
        st = wvol_wvc_read_region_into(values->GetPointer(0) + z0 * nx * ny, this->File, slo, shi, level,
                                       threads, spacing, origin, &err);
      }
      how = "slabs";
    }
    if (st != WVOL_OK)
    {
      vtkErrorMacro(<< this->Describe(err.message));
      output->Initialize();
      ReturnFreedMemory();
      return 0;
    }
    output->SetExtent(ue);
    output->SetSpacing(outInfo->Get(vtkDataObject::SPACING()));
    output->SetOrigin(outInfo->Get(vtkDataObject::ORIGIN()));
    output->GetPointData()->SetScalars(values);
    SetKnownRange(values);
  }
  else
  {
    output->SetExtent(0, -1, 0, -1, 0, -1);
  }
  wvol_wvc_file_stats(this->File, &after);
  const uint64_t decoded = after.decoded - before.decoded;

  // the file's error report: quantisation + dropped energy over the voxels (Parseval)
  const double voxels = double(in->nx) * double(in->ny) * double(in->nz);
  const double sse = std::max(in->sse + in->dropped_energy, 0.0);
  vtkFieldData* fd = output->GetFieldData();
  AddField<vtkDoubleArray>(fd, "PredictedRMSE", std::sqrt(sse / voxels));
  AddField<vtkDoubleArray>(fd, "PredictedPSNR", wvol_wvc_psnr(sse, voxels, in->value_min, in->value_max));
  AddField<vtkTypeInt64Array>(fd, "KeptCoefficients", vtkTypeInt64(in->nonzero));
  AddField<vtkTypeInt64Array>(fd, "Coefficients", vtkTypeInt64(in->px * in->py * in->pz));
  AddField<vtkTypeInt64Array>(fd, "ChunksDecoded", vtkTypeInt64(decoded));
  AddField<vtkTypeInt64Array>(fd, "ChunksDecodedTotal", vtkTypeInt64(after.decoded));
  AddField<vtkTypeInt64Array>(fd, "Piece", vtkTypeInt64(piece));
  AddField<vtkTypeInt64Array>(fd, "NumberOfPieces", vtkTypeInt64(pieces));
  AddField<vtkTypeInt64Array>(fd, "LevelOfDetail", vtkTypeInt64(level));

  if (this->ChunkLog && *this->ChunkLog)
  {
    vtkMultiProcessController* c = vtkMultiProcessController::GetGlobalController();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    double rss_after, peak_after;
    ProcessMemory(rss_after, peak_after);
    std::ostringstream line;
    line.precision(17);
    line << "{\"rank\": " << (c ? c->GetLocalProcessId() : 0) << ", \"pid\": " << getpid() << ", \"piece\": " << piece
         << ", \"pieces\": " << pieces << ", \"level\": " << level << ", \"extent\": ";
    if (empty)
    {
      line << "null";
    }
    else
    {
      line << "[" << ue[0] << ", " << ue[1] << ", " << ue[2] << ", " << ue[3] << ", " << ue[4] << ", " << ue[5] << "]";
    }
    line << ", \"decoded\": " << decoded << ", \"decoded_total\": " << after.decoded << ", \"chunks\": " << in->chunks
         << ", \"cache_peak_bytes\": " << after.peak << ", \"threads\": " << threads << ", \"read\": \"" << how
         << "\", \"seconds\": " << seconds << ", \"cpu_seconds\": " << ProcessCPUSeconds() - cpu_started
         << ", \"rss_mib_before\": " << rss_before
         << ", \"peak_rss_mib_before\": " << peak_before << ", \"rss_mib_after\": " << rss_after
         << ", \"peak_rss_mib_after\": " << peak_after << "}\n";
    // one short write in append mode per line: concurrent ranks' lines stay whole
    if (FILE* f = std::fopen(this->ChunkLog, "a"))
    {
      const std::string s = line.str();
      std::fwrite(s.data(), 1, s.size(), f);
      std::fclose(f);
    }
    else
    {
      vtkWarningMacro(<< "cannot append to the chunk log " << this->ChunkLog);
    }
  }
  if (this->ReleaseCache)
  {
    this->Close();
  }
  ReturnFreedMemory();
  return 1;
}
