/* SPDX-License-Identifier: MIT */
// VTK adapter: the only VTK code in libwvol (C interface in io/adapters.h).
//
// Reads .vti, legacy .vtk structured points, .mha/.mhd and .nii/.nii.gz through VTK's
// readers (a MetaImage header is checked first by io/metaimage.c; a folder, a DICOM
// series, goes to io/dicom.c, which needs no VTK); writes .vti, .mha, .nii/.nii.gz,
// legacy .vtk and triangle meshes as .vtp. See docs/formats.md for what each keeps.
//
// Geometry: the world position of the first sample is the origin; per-axis spacing
// is kept. A direction matrix (vti Direction, NIfTI qform/sform, MetaImage
// TransformMatrix) that only flips axes is applied exactly by reversing those axes;
// any other rotation is dropped (the volume's axes are taken as the world axes).
//
// Samples: one component per voxel; integers become float32 exactly (a value that
// float32 cannot hold exactly is refused, naming it); float64 is rounded to float32;
// NaN/Inf are refused. NIfTI scl_slope/scl_inter are applied (the result rounded to
// float32).
//
// Errors: VTK reports through ErrorEvent observers (installed on every reader and
// writer) and its global vtkOutputWindow; MetaIO writes to std::cerr.
// While the adapter runs VTK, a process-wide mutex is held, the output window is
// replaced by one that collects the text, and std::cerr is redirected into a buffer:
// the library prints nothing, and VTK's words end up in the wvol_error message.
#include "io/adapters.h"
#include "io/adapter_errors.hpp"
#include "core/file_open.h"
#include "io/io_internal.h"

#include <vtkCellArray.h>
#include <vtkCommand.h>
#include <vtkDataObjectTypes.h>
#include <vtkDataSetReader.h>
#include <vtkExecutive.h>
#include <vtkFloatArray.h>
#include <vtkIdTypeArray.h>
#include <vtkLogger.h>
#include <vtkImageData.h>
#include <vtkMatrix3x3.h>
#include <vtkMatrix4x4.h>
#include <vtkMetaImageReader.h>
#include <vtkMetaImageWriter.h>
#include <vtkNIFTIImageReader.h>
#include <vtkNIFTIImageHeader.h>
#include <vtkNIFTIImageWriter.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkOutputWindow.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkStructuredPointsReader.h>
#include <vtkXMLImageDataReader.h>
#include <vtkXMLImageDataWriter.h>
#include <vtkXMLPolyDataWriter.h>

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <mutex>
#include <new>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

namespace {

using wvol_adapter::fail;

// Text taken from a file, made safe for a one-line message (no control or non-ASCII bytes).
std::string printable(std::string s)
{
    for (char &c : s)
        if ((unsigned char)c < 0x20 || (unsigned char)c >= 0x7f) c = '?';
    return s;
}

// ---------------------------------------------------------------- silencing VTK

class CollectingWindow : public vtkOutputWindow {
public:
    static CollectingWindow *New();
    vtkTypeMacro(CollectingWindow, vtkOutputWindow);
    void DisplayText(const char *t) override { add(t); }
    void DisplayErrorText(const char *t) override { add(t); }
    void DisplayWarningText(const char *t) override { add(t); }
    void DisplayGenericWarningText(const char *t) override { add(t); }
    void DisplayDebugText(const char *t) override { add(t); }
    std::string text;

private:
    void add(const char *t)
    {
        if (t && text.size() < 4096) text += t;
    }
};
vtkStandardNewMacro(CollectingWindow);

std::mutex vtk_mutex;

// Held while VTK runs: serializes the adapter, collects VTK's global messages and
// whatever is written to std::cerr, and turns vtkLogger's stderr output off (VTK logs
// errors of objects without an ErrorEvent observer there before the output window).
class Quiet {
public:
    Quiet() : lock_(vtk_mutex)
    {
        prev_ = vtkOutputWindow::GetInstance();
        vtkOutputWindow::SetInstance(window_);
        old_cerr_ = std::cerr.rdbuf(cerr_text_.rdbuf());
        old_verbosity_ = vtkLogger::GetCurrentVerbosityCutoff();
        vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
    }
    ~Quiet()
    {
        vtkLogger::SetStderrVerbosity(old_verbosity_);
        std::cerr.rdbuf(old_cerr_);
        vtkOutputWindow::SetInstance(prev_);
    }
    Quiet(const Quiet &) = delete;
    Quiet &operator=(const Quiet &) = delete;
    std::string text() const { return window_->text + cerr_text_.str(); }

private:
    std::lock_guard<std::mutex> lock_;
    vtkSmartPointer<vtkOutputWindow> prev_;
    vtkNew<CollectingWindow> window_;
    std::ostringstream cerr_text_;
    std::streambuf *old_cerr_;
    vtkLogger::Verbosity old_verbosity_;
};

// ErrorEvent/WarningEvent observer: collects the messages. Readers are judged
// strictly: VTK's readers report a short or corrupt data block only as a warning
// (legacy reader) or on std::cerr (MetaIO) and hand back a half-read image, so any
// message at all during a read fails it.
class ErrorCatcher : public vtkCommand {
public:
    static ErrorCatcher *New() { return new ErrorCatcher; }
    void Execute(vtkObject *, unsigned long event, void *data) override
    {
        if (event != vtkCommand::ErrorEvent && event != vtkCommand::WarningEvent) return;
        failed = true;
        if (data && text.size() < 4096) text += std::string(static_cast<const char *>(data)) + "\n";
    }
    bool failed = false;
    std::string text;
};

// VTK's messages ("ERROR: In file.cxx, line 12\nvtkFoo (0x1234): the message\n\n")
// reduced to their distinct messages, without the pipeline's request dumps.
std::string clean(const std::string &raw)
{
    std::vector<std::string> lines;
    std::istringstream in(raw);
    std::string line, out;
    while (std::getline(in, line)) {
        if (line.empty() || line[0] == ' ' || line[0] == '\t') continue; // vtkInformation dumps
        while (!line.empty() && (line.back() == ' ' || line.back() == '\r' || line.back() == '\t'))
            line.pop_back();
        if (line.empty() || line.compare(0, 10, "ERROR: In ") == 0 || line.compare(0, 12, "Warning: In ") == 0 ||
            line.compare(0, 20, "Generic Warning: In ") == 0)
            continue;
        size_t p = line.find("): ");
        if (line.compare(0, 3, "vtk") == 0 && p != std::string::npos) line = line.substr(p + 3);
        if (line.find("returned failure for request") != std::string::npos) continue;
        if (std::find(lines.begin(), lines.end(), line) == lines.end()) lines.push_back(line);
    }
    for (size_t i = 0; i < lines.size() && i < 3; i++) out += (i ? "; " : "") + lines[i];
    return printable(out.size() > 300 ? out.substr(0, 300) + "..." : out);
}

template <typename AlgoT>
vtkSmartPointer<ErrorCatcher> watch(AlgoT *algo)
{
    auto c = vtkSmartPointer<ErrorCatcher>::New();
    for (vtkObject *o : {static_cast<vtkObject *>(algo), static_cast<vtkObject *>(algo->GetExecutive())}) {
        o->AddObserver(vtkCommand::ErrorEvent, c);
        o->AddObserver(vtkCommand::WarningEvent, c);
    }
    return c;
}

// ---------------------------------------------------------------- files

bool is_dir(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

bool has_ext(const char *path, const char *ext)
{
    return wvol_path_has_ext(path, ext) != 0;
}

// Temporary name beside the target that keeps its extension (VTK's writers look at it).
class TempFile {
public:
    TempFile(const char *path, const char *ext)
    {
        char *resolved = nullptr;
        wvol_error e;
        if (wvol__output_path(&resolved, path, &e) != WVOL_OK) fail(e.status, e.message);
        final_ = resolved;
        std::free(resolved);
        char *t = wvol__temp_template(final_.c_str(), ".tmp-", ext);
        if (!t) fail(WVOL_ERR_NOMEM, std::string(path) + ": out of memory");
        std::vector<char> buf(t, t + std::strlen(t) + 1);
        std::free(t);
        int fd = wvol__create_temp(buf.data(), std::strlen(ext));
        if (fd < 0)
            fail(WVOL_ERR_IO, std::string(path) + ": cannot create output file: " + std::strerror(errno));
        close(fd);
        tmp_ = buf.data();
    }
    ~TempFile()
    {
        if (tmp_.empty()) return;
        std::remove(tmp_.c_str());
        wvol__temp_done(tmp_.c_str());
    }
    const char *name() const { return tmp_.c_str(); }
    void commit()
    {
        if (std::rename(tmp_.c_str(), final_.c_str()) != 0)
            fail(WVOL_ERR_IO, final_ + ": cannot rename the written file into place: " + std::strerror(errno));
        wvol__temp_done(tmp_.c_str());
        tmp_.clear();
    }

private:
    std::string final_, tmp_;
};

// ---------------------------------------------------------------- samples

// Converts n samples to float32; integers must be exactly representable.
template <typename T>
void to_float(const T *src, size_t n, float *dst, const char *path)
{
    for (size_t i = 0; i < n; i++) {
        const T x = src[i];
        const float f = static_cast<float>(x);
        if (std::is_integral<T>::value && sizeof(T) > 2) {
            // long double holds every 64-bit integer exactly
            if (static_cast<long double>(f) != static_cast<long double>(x)) {
                char digits[24];
                wvol_error e;
                if (std::is_signed<T>::value)
                    std::snprintf(digits, sizeof digits, "%lld", static_cast<long long>(x));
                else
                    std::snprintf(digits, sizeof digits, "%llu", static_cast<unsigned long long>(x));
                wvol__inexact_integer(path, i, digits, &e);
                fail(e.status, e.message);
            }
        }
        dst[i] = f;
    }
}

std::string type_name(int t)
{
    const char *n = vtkImageScalarTypeNameMacro(t);
    return n ? n : "unknown";
}

// The image's one scalar point array, converted into dst (n samples).
void convert_scalars(vtkImageData *img, float *dst, size_t n, const char *path)
{
    vtkPointData *pd = img->GetPointData();
    vtkDataArray *a = pd ? pd->GetScalars() : nullptr;
    if (!a && pd) {
        for (int i = 0; i < pd->GetNumberOfArrays() && !a; i++) a = pd->GetArray(i);
    }
    if (!a) fail(WVOL_ERR_FORMAT, std::string(path) + ": no point data array (cell data is not read)");
    if (a->GetNumberOfComponents() != 1)
        fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": array '" + (a->GetName() ? a->GetName() : "") + "' has " +
                                       std::to_string(a->GetNumberOfComponents()) +
                                       " components per voxel (vector, color or time series); only scalar volumes are supported");
    if (size_t(a->GetNumberOfTuples()) != n)
        fail(WVOL_ERR_FORMAT, std::string(path) + ": array has " + std::to_string(a->GetNumberOfTuples()) +
                                  " values for " + std::to_string(n) + " voxels");
    if (!a->HasStandardMemoryLayout()) {
        for (size_t i = 0; i < n; i++) dst[i] = float(a->GetTuple1(vtkIdType(i)));
        return;
    }
    const void *p = a->GetVoidPointer(0);
    switch (a->GetDataType()) {
    case VTK_FLOAT: std::memcpy(dst, p, n * sizeof(float)); break;
    case VTK_DOUBLE: to_float(static_cast<const double *>(p), n, dst, path); break;
    case VTK_CHAR: to_float(static_cast<const char *>(p), n, dst, path); break;
    case VTK_SIGNED_CHAR: to_float(static_cast<const signed char *>(p), n, dst, path); break;
    case VTK_UNSIGNED_CHAR: to_float(static_cast<const unsigned char *>(p), n, dst, path); break;
    case VTK_SHORT: to_float(static_cast<const short *>(p), n, dst, path); break;
    case VTK_UNSIGNED_SHORT: to_float(static_cast<const unsigned short *>(p), n, dst, path); break;
    case VTK_INT: to_float(static_cast<const int *>(p), n, dst, path); break;
    case VTK_UNSIGNED_INT: to_float(static_cast<const unsigned int *>(p), n, dst, path); break;
    case VTK_LONG: to_float(static_cast<const long *>(p), n, dst, path); break;
    case VTK_UNSIGNED_LONG: to_float(static_cast<const unsigned long *>(p), n, dst, path); break;
    case VTK_LONG_LONG: to_float(static_cast<const long long *>(p), n, dst, path); break;
    case VTK_UNSIGNED_LONG_LONG: to_float(static_cast<const unsigned long long *>(p), n, dst, path); break;
    case VTK_ID_TYPE: to_float(static_cast<const vtkIdType *>(p), n, dst, path); break;
    default:
        fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": samples of type " + type_name(a->GetDataType()) +
                                       " are not supported");
    }
}

void rescale(float *d, size_t n, double slope, double inter)
{
    if (slope == 1.0 && inter == 0.0) return;
    for (size_t i = 0; i < n; i++) d[i] = float(double(d[i]) * slope + inter);
}

// ---------------------------------------------------------------- geometry

struct Geometry {
    double origin[3] = {0, 0, 0};  // world position of sample 0 as stored
    double spacing[3] = {1, 1, 1}; // may be negative (then the axis runs backwards)
    double dir[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
};

// Sets v's spacing/origin from g: axes whose direction is -1 (or spacing negative)
// are reversed so that spacing is positive; a rotation is dropped.
void apply_geometry(wvol_volume *v, const Geometry &g, const char *path)
{
    wvol_error e;
    wvol_error_clear(&e);
    if (wvol__io_apply_geometry(v, g.origin, g.spacing, g.dir, &e) != WVOL_OK)
        fail(WVOL_ERR_FORMAT, std::string(path) + ": " + e.message);
}

wvol_volume *volume_from_image(vtkImageData *img, const char *path, Geometry g, double slope = 1.0,
                               double inter = 0.0)
{
    int dims[3], ext[6];
    img->GetDimensions(dims);
    img->GetExtent(ext);
    if (dims[0] < 1 || dims[1] < 1 || dims[2] < 1)
        fail(WVOL_ERR_FORMAT, std::string(path) + ": the image is empty (" + std::to_string(dims[0]) + " x " +
                                  std::to_string(dims[1]) + " x " + std::to_string(dims[2]) + ")");
    // an extent that does not start at 0 moves the first sample
    double first[3];
    for (int r = 0; r < 3; r++) {
        first[r] = g.origin[r];
        for (int c = 0; c < 3; c++) first[r] += g.dir[r][c] * double(ext[2 * c]) * g.spacing[c];
    }
    std::memcpy(g.origin, first, sizeof first);
    wvol_volume *v = nullptr;
    wvol_error e;
    wvol_error_clear(&e);
    if (wvol_volume_create(&v, size_t(dims[0]), size_t(dims[1]), size_t(dims[2]), &e) != WVOL_OK)
        fail(e.status, std::string(path) + ": " + e.message);
    try {
        const size_t n = wvol_volume_count(v);
        convert_scalars(img, v->data, n, path);
        rescale(v->data, n, slope, inter);
        apply_geometry(v, g, path);
        if (wvol_check_finite(v->data, v->nx, v->ny, v->nz, path, &e) != WVOL_OK) fail(e.status, e.message);
    } catch (...) {
        wvol_volume_destroy(v);
        throw;
    }
    return v;
}

Geometry image_geometry(vtkImageData *img)
{
    Geometry g;
    img->GetOrigin(g.origin);
    img->GetSpacing(g.spacing);
    if (vtkMatrix3x3 *m = img->GetDirectionMatrix())
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) g.dir[r][c] = m->GetElement(r, c);
    return g;
}

// Runs a reader; any error event, error code or collected message fails with `kind`.
template <typename ReaderT>
vtkImageData *run_reader(ReaderT *reader, const char *path, const char *kind, const Quiet &quiet)
{
    auto catcher = watch(reader);
    reader->Update();
    if (catcher->failed || reader->GetErrorCode() != 0 || !quiet.text().empty()) {
        std::string why = clean(catcher->text + "\n" + quiet.text());
        fail(WVOL_ERR_FORMAT, std::string(path) + ": not a readable " + kind + " file" +
                                  (why.empty() ? std::string() : " (VTK: " + why + ")"));
    }
    vtkImageData *img = vtkImageData::SafeDownCast(reader->GetOutputDataObject(0));
    if (!img) fail(WVOL_ERR_FORMAT, std::string(path) + ": VTK produced no image from this " + kind + " file");
    return img;
}

// ---------------------------------------------------------------- reading

wvol_volume *read_vtk(const char *path)
{
    if (is_dir(path)) { // a DICOM series: read by io/dicom.c, no VTK involved
        wvol_volume *v = nullptr;
        wvol_error e;
        wvol_error_clear(&e);
        if (wvol__dicom_read(&v, path, &e) != WVOL_OK) fail(e.status, e.message);
        return v;
    }
    Quiet quiet;
    if (has_ext(path, ".vti")) {
        vtkNew<vtkXMLImageDataReader> r;
        r->SetFileName(path);
        vtkImageData *img = run_reader(r.Get(), path, "VTK XML image (.vti)", quiet);
        return volume_from_image(img, path, image_geometry(img));
    }
    if (has_ext(path, ".vtk")) {
        vtkNew<vtkDataSetReader> probe;
        probe->SetFileName(path);
        auto catcher = watch(probe.Get());
        const int type = probe->ReadOutputType();
        if (type != VTK_STRUCTURED_POINTS && type != VTK_IMAGE_DATA) {
            if (type < 0 || catcher->failed) {
                std::string why = clean(catcher->text + "\n" + quiet.text());
                fail(WVOL_ERR_FORMAT, std::string(path) + ": not a readable VTK legacy file" +
                                          (why.empty() ? std::string() : " (VTK: " + why + ")"));
            }
            fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": the VTK legacy file holds " +
                                           vtkDataObjectTypes::GetClassNameFromTypeId(type) +
                                           ", not structured points (a volume)");
        }
        vtkNew<vtkStructuredPointsReader> r;
        r->SetFileName(path);
        vtkImageData *img = run_reader(r.Get(), path, "VTK legacy structured points", quiet);
        return volume_from_image(img, path, image_geometry(img));
    }
    if (has_ext(path, ".mha") || has_ext(path, ".mhd")) {
        // the header checked and its numbers at full precision by io/metaimage.c
        wvol__meta_header h;
        wvol_error e;
        wvol_error_clear(&e);
        if (wvol__meta_read_header(&h, path, &e) != WVOL_OK) fail(e.status, e.message);
        vtkNew<vtkMetaImageReader> r;
        r->SetFileName(path);
        vtkImageData *img = run_reader(r.Get(), path, "MetaImage", quiet);
        Geometry g = image_geometry(img);
        for (int a = 0; a < 3; a++) {
            g.spacing[a] = wvol__meta_precise(g.spacing[a], h.spacing, h.nspacing, size_t(a));
            g.origin[a] = wvol__meta_precise(g.origin[a], h.origin, h.norigin, size_t(a));
        }
        if (h.ndims == 3 && h.nmatrix == 9) // MetaImage matrices are column-major: axis a is column a
            for (int r2 = 0; r2 < 3; r2++)
                for (int c = 0; c < 3; c++) g.dir[r2][c] = h.matrix[size_t(c * 3 + r2)];
        return volume_from_image(img, path, g);
    }
    if (has_ext(path, ".nii") || has_ext(path, ".nii.gz")) {
        vtkNew<vtkNIFTIImageReader> r;
        r->SetFileName(path);
        vtkImageData *img = run_reader(r.Get(), path, "NIfTI", quiet);
        Geometry g = image_geometry(img);
        vtkNIFTIImageHeader *hdr = r->GetNIFTIHeader();
        vtkMatrix4x4 *m = nullptr;
        if (hdr && hdr->GetSFormCode() > 0) m = r->GetSFormMatrix();
        if (!m && hdr && hdr->GetQFormCode() > 0) m = r->GetQFormMatrix();
        if (m) {
            double o[3];
            for (int a = 0; a < 3; a++) {
                o[a] = m->GetElement(a, 3);
                for (int c = 0; c < 3; c++) {
                    o[a] += m->GetElement(a, c) * g.origin[c];
                    g.dir[a][c] = m->GetElement(a, c);
                }
            }
            std::copy(o, o + 3, g.origin);
        }
        double slope = r->GetRescaleSlope(), inter = r->GetRescaleIntercept();
        if (slope == 0.0) { // NIfTI: scl_slope 0 means no scaling
            slope = 1.0;
            inter = 0.0;
        }
        return volume_from_image(img, path, g, slope, inter);
    }
    fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": not a format of the VTK adapter");
}

// ---------------------------------------------------------------- writing

// A vtkImageData over v's samples (no copy), named "density".
vtkSmartPointer<vtkImageData> image_of(const wvol_volume *v)
{
    const size_t lim = size_t(VTK_INT_MAX);
    if (v->nx > lim || v->ny > lim || v->nz > lim)
        fail(WVOL_ERR_DIMS, "dimensions exceed VTK's 32-bit extent range");
    auto img = vtkSmartPointer<vtkImageData>::New();
    img->SetDimensions(int(v->nx), int(v->ny), int(v->nz));
    img->SetSpacing(v->spacing[0], v->spacing[1], v->spacing[2]);
    img->SetOrigin(v->origin[0], v->origin[1], v->origin[2]);
    vtkNew<vtkFloatArray> a;
    a->SetName("density");
    a->SetNumberOfComponents(1);
    a->SetArray(v->data, vtkIdType(wvol_volume_count(v)), 1 /* VTK must not free it */);
    img->GetPointData()->SetScalars(a);
    return img;
}

template <typename WriterT>
void run_writer(WriterT *w, const char *path, const char *kind, const Quiet &quiet)
{
    auto catcher = watch(w);
    int ok = 1;
    if constexpr (std::is_void<decltype(w->Write())>::value) w->Write(); // vtkImageWriter
    else ok = w->Write();                                                 // vtkXMLWriter
    if (!ok || catcher->failed || w->GetErrorCode() != 0) {
        std::string why = clean(catcher->text + "\n" + quiet.text());
        fail(WVOL_ERR_IO, std::string(path) + ": writing the " + kind + " file failed" +
                              (why.empty() ? std::string() : " (VTK: " + why + ")"));
    }
}

// Legacy .vtk structured points, written here so that spacing and origin keep every
// digit (VTK's legacy writer prints 6).
void write_legacy(const wvol_volume *v, const char *tmp, const char *path)
{
    FILE *fp = std::fopen(tmp, "wb");
    if (!fp) fail(WVOL_ERR_IO, std::string(path) + ": cannot write: " + std::strerror(errno));
    const size_t n = wvol_volume_count(v);
    std::fprintf(fp,
                 "# vtk DataFile Version 3.0\nlibwvol volume\nBINARY\nDATASET STRUCTURED_POINTS\n"
                 "DIMENSIONS %zu %zu %zu\nSPACING %.17g %.17g %.17g\nORIGIN %.17g %.17g %.17g\n"
                 "POINT_DATA %zu\nSCALARS density float 1\nLOOKUP_TABLE default\n",
                 v->nx, v->ny, v->nz, v->spacing[0], v->spacing[1], v->spacing[2], v->origin[0], v->origin[1],
                 v->origin[2], n);
    std::vector<unsigned char> buf;
    const size_t chunk = 1 << 16;
    bool ok = true;
    for (size_t i = 0; i < n && ok; i += chunk) {
        const size_t m = std::min(chunk, n - i);
        buf.resize(m * 4);
        for (size_t k = 0; k < m; k++) { // big-endian, as the legacy format says
            uint32_t u;
            std::memcpy(&u, v->data + i + k, 4);
            buf[4 * k] = uint8_t(u >> 24);
            buf[4 * k + 1] = uint8_t(u >> 16);
            buf[4 * k + 2] = uint8_t(u >> 8);
            buf[4 * k + 3] = uint8_t(u);
        }
        ok = std::fwrite(buf.data(), 1, buf.size(), fp) == buf.size();
    }
    std::fputc('\n', fp);
    if (std::fflush(fp) != 0 || std::ferror(fp)) ok = false;
    if (std::fclose(fp) != 0) ok = false;
    if (!ok) fail(WVOL_ERR_IO, std::string(path) + ": write failed: " + std::strerror(errno));
}

// MetaImage's and NIfTI's writers report no failed write (a full disk leaves a short file and
// no error code): their file is read back before it is renamed into place, and one that does
// not read back as the volume written is refused. (The XML writer reports its errors.)
void read_back(const char *tmp, const char *path, const wvol_volume *v)
{
    wvol_volume *back = nullptr;
    std::string why;
    try {
        back = read_vtk(tmp);
    } catch (const wvol_adapter::Failure &f) {
        why = f.message;
    } catch (const std::exception &e) {
        why = e.what();
    }
    const bool same = back && back->nx == v->nx && back->ny == v->ny && back->nz == v->nz;
    wvol_volume_destroy(back);
    if (!same)
        fail(WVOL_ERR_IO, std::string(path) + ": the written file does not read back" +
                              (why.empty() ? std::string(" with the volume's size") : ": " + why) + " (is the disk full?)");
}

void write_vtk(const wvol_volume *v, const char *path)
{
    const char *ext = has_ext(path, ".vti")      ? ".vti"
                      : has_ext(path, ".mha")    ? ".mha"
                      : has_ext(path, ".nii.gz") ? ".nii.gz"
                      : has_ext(path, ".nii")    ? ".nii"
                      : has_ext(path, ".vtk")    ? ".vtk"
                                                 : nullptr;
    if (!ext)
        fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": the VTK adapter writes .vti .mha .nii .nii.gz .vtk");
    TempFile tmp(path, ext);
    if (!std::strcmp(ext, ".vtk")) {
        write_legacy(v, tmp.name(), path);
        tmp.commit();
        return;
    }
    bool verify = false;
    {
    Quiet quiet; // held until the writer is done: read_back takes it again
    vtkSmartPointer<vtkImageData> img = image_of(v);
    if (!std::strcmp(ext, ".vti")) {
        vtkNew<vtkXMLImageDataWriter> w;
        w->SetFileName(tmp.name());
        w->SetInputData(img);
        w->SetDataModeToAppended();
        w->EncodeAppendedDataOff();
        w->SetHeaderTypeToUInt64();
        w->SetCompressorTypeToZLib();
        run_writer(w.Get(), path, "VTK XML image", quiet);
    } else if (!std::strcmp(ext, ".mha")) {
        vtkNew<vtkMetaImageWriter> w;
        w->SetFileName(tmp.name());
        w->SetInputData(img);
        w->SetCompression(true);
        run_writer(w.Get(), path, "MetaImage", quiet);
        verify = true;
    } else {
        vtkNew<vtkNIFTIImageWriter> w;
        w->SetFileName(tmp.name());
        w->SetInputData(img);
        w->SetDescription("libwvol");
        run_writer(w.Get(), path, "NIfTI", quiet);
        verify = true;
    }
    }
    if (verify) read_back(tmp.name(), path, v);
    tmp.commit();
}

void write_mesh(const char *path, const float *xyz, size_t nverts, const unsigned *tris, size_t ntris,
                const float *normals)
{
    if ((nverts && !xyz) || (ntris && !tris))
        fail(WVOL_ERR_ARG, std::string(path) + ": mesh arrays are NULL");
    if (nverts > size_t(VTK_ID_MAX) / 3 || ntris > size_t(VTK_ID_MAX) / 4)
        fail(WVOL_ERR_DIMS, std::string(path) + ": mesh too large");
    for (size_t i = 0; i < 3 * nverts; i++)
        if (!std::isfinite(xyz[i]))
            fail(WVOL_ERR_NONFINITE, std::string(path) + ": vertex " + std::to_string(i / 3) + " is not finite");
    for (size_t i = 0; i < 3 * ntris; i++)
        if (size_t(tris[i]) >= nverts)
            fail(WVOL_ERR_ARG, std::string(path) + ": triangle " + std::to_string(i / 3) + " uses vertex " +
                                   std::to_string(tris[i]) + " of " + std::to_string(nverts));
    TempFile tmp(path, ".vtp");
    Quiet quiet;
    vtkNew<vtkFloatArray> coords;
    coords->SetNumberOfComponents(3);
    coords->SetArray(const_cast<float *>(xyz), vtkIdType(3 * nverts), 1);
    vtkNew<vtkPoints> points;
    points->SetData(coords);
    vtkNew<vtkIdTypeArray> offsets, conn;
    offsets->SetNumberOfValues(vtkIdType(ntris + 1));
    conn->SetNumberOfValues(vtkIdType(3 * ntris));
    for (size_t t = 0; t <= ntris; t++) offsets->SetValue(vtkIdType(t), vtkIdType(3 * t));
    for (size_t i = 0; i < 3 * ntris; i++) conn->SetValue(vtkIdType(i), vtkIdType(tris[i]));
    vtkNew<vtkCellArray> cells;
    cells->SetData(offsets, conn);
    vtkNew<vtkPolyData> mesh;
    mesh->SetPoints(points);
    mesh->SetPolys(cells);
    if (normals && nverts) {
        vtkNew<vtkFloatArray> nrm;
        nrm->SetName("Normals");
        nrm->SetNumberOfComponents(3);
        nrm->SetArray(const_cast<float *>(normals), vtkIdType(3 * nverts), 1);
        mesh->GetPointData()->SetNormals(nrm);
    }
    vtkNew<vtkXMLPolyDataWriter> w;
    w->SetFileName(tmp.name());
    w->SetInputData(mesh);
    w->SetDataModeToAppended();
    w->EncodeAppendedDataOff();
    w->SetHeaderTypeToUInt64();
    w->SetCompressorTypeToZLib();
    run_writer(w.Get(), path, "VTK XML polydata", quiet);
    tmp.commit();
}

template <typename F>
wvol_status guarded(const char *path, wvol_error *err, F &&body)
{
    try {
        body();
        return WVOL_OK;
    } catch (...) {
        return wvol_adapter::current_error(path, "VTK", err);
    }
}

} // namespace

extern "C" wvol_status wvol__vtk_read(wvol_volume **out, const char *path, wvol_error *err)
{
    if (!out || !path) return wvol_error_set(err, WVOL_ERR_ARG, "vtk read: NULL argument");
    *out = nullptr;
    return guarded(path, err, [&] { *out = read_vtk(path); });
}

extern "C" wvol_status wvol__vtk_write(const wvol_volume *v, const char *path, wvol_error *err)
{
    if (!v || !v->data || !path) return wvol_error_set(err, WVOL_ERR_ARG, "vtk write: NULL argument");
    return guarded(path, err, [&] { write_vtk(v, path); });
}

extern "C" wvol_status wvol__vtk_write_mesh(const char *path, const float *xyz, size_t nverts,
                                            const unsigned *tris, size_t ntris, const float *normals,
                                            wvol_error *err)
{
    if (!path) return wvol_error_set(err, WVOL_ERR_ARG, "mesh write: NULL path");
    return guarded(path, err, [&] { write_mesh(path, xyz, nverts, tris, ntris, normals); });
}
