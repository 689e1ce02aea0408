// VTK adapter: the only VTK code in libwvol (C interface in io/adapters.h).
//
// Reads .vti, legacy .vtk structured points, .mha/.mhd, .nii/.nii.gz and a folder
// holding one DICOM series through VTK's readers; writes .vti, .mha, .nii/.nii.gz,
// legacy .vtk and triangle meshes as .vtp. See docs/formats.md for what each keeps.
//
// Geometry: the world position of the first sample is the origin; per-axis spacing
// is kept. A direction matrix (vti Direction, NIfTI qform/sform, MetaImage
// TransformMatrix) that only flips axes is applied exactly by reversing those axes;
// any other rotation is dropped (the volume's axes are taken as the world axes).
//
// Samples: one component per voxel; integers become float32 exactly (a value that
// float32 cannot hold exactly is refused, naming it); float64 is rounded to float32;
// NaN/Inf are refused. NIfTI scl_slope/scl_inter and DICOM RescaleSlope/Intercept are
// applied (the result rounded to float32).
//
// Errors: VTK reports through ErrorEvent observers (installed on every reader and
// writer) and its global vtkOutputWindow; MetaIO and DICOMParser write to std::cerr.
// While the adapter runs VTK, a process-wide mutex is held, the output window is
// replaced by one that collects the text, and std::cerr is redirected into a buffer:
// the library prints nothing, and VTK's words end up in the wvol_error message.
#include "io/adapters.h"
#include "io/adapter_errors.hpp"

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

#include <dirent.h>
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
#include <map>
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

std::string num(double x)
{
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.10g", x);
    return buf;
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
    TempFile(const char *path, const char *ext) : final_(path)
    {
        std::string t = std::string(path) + ".tmp-XXXXXX" + ext;
        std::vector<char> buf(t.begin(), t.end());
        buf.push_back('\0');
        int fd = mkstemps(buf.data(), int(std::strlen(ext)));
        if (fd < 0)
            fail(WVOL_ERR_IO, std::string(path) + ": cannot create output file: " + std::strerror(errno));
        close(fd);
        tmp_ = buf.data();
    }
    ~TempFile()
    {
        if (!tmp_.empty()) std::remove(tmp_.c_str());
    }
    const char *name() const { return tmp_.c_str(); }
    void commit()
    {
        if (std::rename(tmp_.c_str(), final_.c_str()) != 0)
            fail(WVOL_ERR_IO, final_ + ": cannot rename the written file into place: " + std::strerror(errno));
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
                char buf[160];
                std::snprintf(buf, sizeof buf, "%s: sample %zu holds the integer %lld, which float32 cannot hold exactly "
                                               "(integers above 2^24 in magnitude lose digits); refused",
                              path, i, (long long)x);
                fail(WVOL_ERR_UNSUPPORTED, buf);
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

void flip_axis(wvol_volume *v, int axis)
{
    const size_t nx = v->nx, ny = v->ny, nz = v->nz;
    float *d = v->data;
    if (axis == 0) {
        for (size_t r = 0; r < ny * nz; r++) std::reverse(d + r * nx, d + (r + 1) * nx);
    } else if (axis == 1) {
        for (size_t k = 0; k < nz; k++)
            for (size_t j = 0; j < ny / 2; j++)
                std::swap_ranges(d + (k * ny + j) * nx, d + (k * ny + j + 1) * nx, d + (k * ny + ny - 1 - j) * nx);
    } else {
        for (size_t k = 0; k < nz / 2; k++)
            std::swap_ranges(d + k * nx * ny, d + (k + 1) * nx * ny, d + (nz - 1 - k) * nx * ny);
    }
}

// Sets v's spacing/origin from g: axes whose direction is -1 (or spacing negative)
// are reversed so that spacing is positive; a rotation is dropped.
void apply_geometry(wvol_volume *v, const Geometry &g, const char *path)
{
    const size_t n[3] = {v->nx, v->ny, v->nz};
    bool diagonal = true;
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            if (r != c && std::fabs(g.dir[r][c]) > 1e-6) diagonal = false;
    double spacing[3], origin[3];
    for (int a = 0; a < 3; a++) {
        double step = g.spacing[a] * (diagonal ? (g.dir[a][a] < 0 ? -1.0 : 1.0) : 1.0);
        origin[a] = g.origin[a];
        spacing[a] = std::fabs(step);
        if (step < 0) {
            flip_axis(v, a);
            origin[a] = g.origin[a] + double(n[a] - 1) * step;
        }
    }
    wvol_error e;
    wvol_error_clear(&e);
    if (wvol_volume_set_geometry(v, spacing, origin, &e) != WVOL_OK)
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

// ---------------------------------------------------------------- MetaImage header

// The few MetaImage header fields we check or take at full precision (VTK's MetaIO
// keeps spacing as float).
struct MetaHeader {
    int ndims = 0;
    std::vector<double> spacing, origin, matrix;
    int channels = 1;
    std::string data_file;
};

std::vector<double> parse_numbers(const std::string &s)
{
    std::vector<double> v;
    std::istringstream in(s);
    double x;
    while (in >> x) v.push_back(x);
    return v;
}

MetaHeader read_meta_header(const char *path)
{
    static const char *known[] = {"ObjectType", "ObjectSubType", "NDims", "Comment", "TransformType",
                                  "Name", "ID", "ParentID", "CompressedData", "CompressedDataSize",
                                  "BinaryData", "BinaryDataByteOrderMSB", "ElementByteOrderMSB", "Color",
                                  "Position", "Offset", "Origin", "Orientation", "Rotation",
                                  "TransformMatrix", "CenterOfRotation", "AnatomicalOrientation",
                                  "ElementSpacing", "ElementSize", "DimSize", "HeaderSize",
                                  "Modality", "SequenceID", "ElementMin", "ElementMax",
                                  "ElementNumberOfChannels", "ElementType", "ElementDataFile",
                                  "AcquisitionDate", "FileName", "HeaderSizes", nullptr};
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(WVOL_ERR_IO, std::string(path) + ": cannot open: " + std::strerror(errno));
    MetaHeader h;
    std::string line;
    int lines = 0;
    bool have_dims = false;
    while (lines < 200 && std::getline(in, line)) {
        lines++;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (line.find_first_not_of(" \t") == std::string::npos) continue;
        size_t eq = line.find('=');
        std::string key = line.substr(0, eq);
        key.erase(key.find_last_not_of(" \t") + 1);
        key.erase(0, key.find_first_not_of(" \t"));
        bool ok = eq != std::string::npos;
        if (ok) {
            ok = false;
            for (int i = 0; known[i]; i++)
                if (key == known[i]) ok = true;
            // unknown keys are allowed once the header has started
            if (!ok && lines > 1) ok = true;
        }
        if (!ok)
            fail(WVOL_ERR_FORMAT, std::string(path) + ": not a MetaImage file (line " + std::to_string(lines) +
                                      " is not a 'Key = Value' header line)");
        std::string val = line.substr(eq + 1);
        if (key == "NDims") h.ndims = std::atoi(val.c_str());
        else if (key == "ElementSpacing") h.spacing = parse_numbers(val);
        else if (key == "ElementSize" && h.spacing.empty()) h.spacing = parse_numbers(val);
        else if (key == "Offset" || key == "Origin" || key == "Position") h.origin = parse_numbers(val);
        else if (key == "TransformMatrix" || key == "Rotation" || key == "Orientation") h.matrix = parse_numbers(val);
        else if (key == "ElementNumberOfChannels") h.channels = std::atoi(val.c_str());
        else if (key == "DimSize") have_dims = true;
        else if (key == "ElementDataFile") {
            val.erase(0, val.find_first_not_of(" \t"));
            h.data_file = val;
            break;
        }
    }
    if (h.ndims < 1 || !have_dims || h.data_file.empty())
        fail(WVOL_ERR_FORMAT, std::string(path) + ": not a MetaImage file (NDims, DimSize or ElementDataFile missing)");
    if (h.ndims > 3)
        fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": " + std::to_string(h.ndims) +
                                       "-D MetaImage; only 2-D and 3-D images are supported");
    if (h.channels != 1)
        fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": " + std::to_string(h.channels) +
                                       " channels per voxel; only scalar volumes are supported");
    return h;
}

// VTK's (float) value unless the header's text gives the same number more precisely.
double precise(double vtk_value, const std::vector<double> &hdr, size_t i)
{
    if (i >= hdr.size()) return vtk_value;
    double h = hdr[i];
    return std::fabs(double(float(h)) - vtk_value) <= 1e-6 * std::fabs(h) + 1e-300 ? h : vtk_value;
}

// ---------------------------------------------------------------- DICOM headers

struct DicomInfo {
    std::string file, series, syntax;
    int rows = 0, cols = 0, bits = 0, bits_stored = 0, signed_pixels = 0, samples = 1, frames = 1, instance = 0;
    size_t pixel_offset = 0, pixel_bytes = 0;
    bool has_pixels = false, encapsulated = false, has_ipp = false, has_iop = false, has_spacing = false;
    double ipp[3] = {0, 0, 0}, iop[6] = {1, 0, 0, 0, 1, 0}, pixel_spacing[2] = {1, 1};
    double slope = 1, inter = 0, thickness = 0, between = 0;
};

class DicomParser {
public:
    DicomParser(const std::vector<unsigned char> &b, DicomInfo &info) : b_(b), info_(info) {}

    // Returns false if the bytes are not a DICOM Part 10 file; throws on a malformed one.
    bool parse()
    {
        if (b_.size() < 132 || std::memcmp(&b_[128], "DICM", 4) != 0) return false;
        size_t pos = 132;
        // file meta group (always explicit VR little endian)
        while (pos + 8 <= b_.size() && u16(pos) == 0x0002) element(pos, true, 0);
        if (info_.syntax.empty()) info_.syntax = "1.2.840.10008.1.2.1";
        const bool explicit_vr = info_.syntax != "1.2.840.10008.1.2";
        while (pos + 8 <= b_.size() && !info_.has_pixels) element(pos, explicit_vr, 0);
        return true;
    }

private:
    const std::vector<unsigned char> &b_;
    DicomInfo &info_;

    [[noreturn]] void bad(const char *why) const
    {
        fail(WVOL_ERR_FORMAT, info_.file + ": malformed DICOM file (" + why + ")");
    }
    uint16_t u16(size_t p) const
    {
        if (p + 2 > b_.size()) bad("truncated");
        return uint16_t(b_[p] | (b_[p + 1] << 8));
    }
    uint32_t u32(size_t p) const
    {
        if (p + 4 > b_.size()) bad("truncated");
        return uint32_t(b_[p]) | (uint32_t(b_[p + 1]) << 8) | (uint32_t(b_[p + 2]) << 16) | (uint32_t(b_[p + 3]) << 24);
    }
    std::string str(size_t p, uint32_t len) const
    {
        std::string s(reinterpret_cast<const char *>(&b_[p]), len);
        while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
        s.erase(0, s.find_first_not_of(' '));
        return printable(s);
    }
    std::vector<double> nums(size_t p, uint32_t len) const
    {
        std::string s = str(p, len);
        std::replace(s.begin(), s.end(), '\\', ' ');
        return parse_numbers(s);
    }

    // Skips the items of a sequence of undefined length (up to its delimiter).
    void skip_sequence(size_t &pos, bool explicit_vr, int depth)
    {
        if (depth > 32) bad("sequences nested too deep");
        for (;;) {
            uint16_t g = u16(pos), e = u16(pos + 2);
            uint32_t len = u32(pos + 4);
            pos += 8;
            if (g != 0xFFFE) bad("sequence item expected");
            if (e == 0xE0DD) return; // sequence delimiter
            if (e != 0xE000) bad("sequence item expected");
            if (len != 0xFFFFFFFFu) {
                if (len > b_.size() - pos) bad("truncated item");
                pos += len;
                continue;
            }
            for (;;) { // item of undefined length: elements up to the item delimiter
                if (u16(pos) == 0xFFFE && u16(pos + 2) == 0xE00D) {
                    pos += 8;
                    break;
                }
                element(pos, explicit_vr, depth + 1);
            }
        }
    }

    void element(size_t &pos, bool explicit_vr, int depth)
    {
        const uint16_t g = u16(pos), e = u16(pos + 2);
        uint32_t len;
        bool inner_explicit = explicit_vr;
        if (g == 0xFFFE) bad("unexpected item tag");
        if (explicit_vr) {
            if (pos + 8 > b_.size()) bad("truncated");
            const char vr[3] = {char(b_[pos + 4]), char(b_[pos + 5]), 0};
            static const char *long_vrs[] = {"OB", "OD", "OF", "OL", "OV", "OW", "SQ", "SV",
                                             "UC", "UN", "UR", "UT", "UV", nullptr};
            bool is_long = false;
            for (int i = 0; long_vrs[i]; i++)
                if (!std::strcmp(vr, long_vrs[i])) is_long = true;
            if (is_long) {
                len = u32(pos + 8);
                pos += 12;
            } else {
                len = u16(pos + 6);
                pos += 8;
            }
            if (!std::strcmp(vr, "UN")) inner_explicit = false; // UN of undefined length: implicit VR inside
        } else {
            len = u32(pos + 4);
            pos += 8;
        }
        if (len == 0xFFFFFFFFu) {
            if (g == 0x7FE0 && e == 0x0010 && depth == 0) {
                info_.has_pixels = info_.encapsulated = true;
                pos = b_.size();
                return;
            }
            skip_sequence(pos, inner_explicit, depth);
            return;
        }
        if (len > b_.size() - pos) {
            if (g == 0x7FE0 && e == 0x0010 && depth == 0) bad("pixel data truncated");
            bad("element runs past the end of the file");
        }
        if (depth == 0) take(g, e, pos, len);
        pos += len;
    }

    void take(uint16_t g, uint16_t e, size_t p, uint32_t len)
    {
        const uint32_t tag = (uint32_t(g) << 16) | e;
        auto us = [&](int &out) {
            if (len >= 2) out = u16(p);
        };
        switch (tag) {
        case 0x00020010: info_.syntax = str(p, len); break;
        case 0x0020000E: info_.series = str(p, len); break;
        case 0x00200013: info_.instance = std::atoi(str(p, len).c_str()); break;
        case 0x00280010: us(info_.rows); break;
        case 0x00280011: us(info_.cols); break;
        case 0x00280100: us(info_.bits); break;
        case 0x00280101: us(info_.bits_stored); break;
        case 0x00280103: us(info_.signed_pixels); break;
        case 0x00280002: us(info_.samples); break;
        case 0x00280008: info_.frames = std::atoi(str(p, len).c_str()); break;
        case 0x00280030: {
            auto v = nums(p, len);
            if (v.size() == 2) {
                info_.pixel_spacing[0] = v[0];
                info_.pixel_spacing[1] = v[1];
                info_.has_spacing = true;
            }
        } break;
        case 0x00200032: {
            auto v = nums(p, len);
            if (v.size() == 3) {
                std::copy(v.begin(), v.end(), info_.ipp);
                info_.has_ipp = true;
            }
        } break;
        case 0x00200037: {
            auto v = nums(p, len);
            if (v.size() == 6) {
                std::copy(v.begin(), v.end(), info_.iop);
                info_.has_iop = true;
            }
        } break;
        case 0x00281053: {
            auto v = nums(p, len);
            if (v.size() == 1) info_.slope = v[0];
        } break;
        case 0x00281052: {
            auto v = nums(p, len);
            if (v.size() == 1) info_.inter = v[0];
        } break;
        case 0x00180050: {
            auto v = nums(p, len);
            if (v.size() == 1) info_.thickness = v[0];
        } break;
        case 0x00180088: {
            auto v = nums(p, len);
            if (v.size() == 1) info_.between = v[0];
        } break;
        case 0x7FE00010:
            info_.has_pixels = true;
            info_.pixel_offset = p;
            info_.pixel_bytes = len;
            break;
        default: break;
        }
    }
};

// The pixels of one uncompressed little-endian slice, rows top to bottom, rescaled.
// (Not vtkDICOMImageReader: VTK 9.1 applies RescaleSlope/Intercept in the stored
// integer type, so 30000 * 4 wraps, a signed slice with a fractional slope is read
// as unsigned, and it stores rows bottom-up.)
void dicom_pixels(const DicomInfo &s, const std::vector<unsigned char> &b, float *dst, size_t n)
{
    const size_t bytes_per = size_t(s.bits) / 8;
    if (s.bits != 8 && s.bits != 16 && s.bits != 32)
        fail(WVOL_ERR_UNSUPPORTED, s.file + ": " + std::to_string(s.bits) + "-bit DICOM pixels are not supported (8, 16, 32)");
    if (s.pixel_offset > b.size() || s.pixel_bytes < n * bytes_per || b.size() - s.pixel_offset < n * bytes_per)
        fail(WVOL_ERR_FORMAT, s.file + ": DICOM pixel data is shorter than " + std::to_string(s.cols) + " x " +
                                  std::to_string(s.rows) + " pixels of " + std::to_string(s.bits) + " bits");
    const int stored = s.bits_stored > 0 && s.bits_stored < s.bits ? s.bits_stored : s.bits;
    const unsigned char *p = b.data() + s.pixel_offset;
    const bool plain = s.slope == 1.0 && s.inter == 0.0;
    for (size_t i = 0; i < n; i++, p += bytes_per) {
        uint32_t u = p[0];
        if (bytes_per >= 2) u |= uint32_t(p[1]) << 8;
        if (bytes_per == 4) u |= (uint32_t(p[2]) << 16) | (uint32_t(p[3]) << 24);
        if (stored < 32) u &= (uint32_t(1) << stored) - 1; // bits above BitsStored are not the pixel's
        int64_t x = int64_t(u);
        if (s.signed_pixels && ((u >> (stored - 1)) & 1u)) x -= int64_t(1) << stored;
        const float f = float(x);
        if (plain && int64_t(f) != x)
            fail(WVOL_ERR_UNSUPPORTED, s.file + ": pixel value " + std::to_string(x) +
                                           " cannot be held exactly by float32; refused");
        dst[i] = plain ? f : float(double(x) * s.slope + s.inter);
    }
}

std::string base_name(const std::string &p)
{
    size_t s = p.find_last_of('/');
    return s == std::string::npos ? p : p.substr(s + 1);
}

wvol_volume *read_dicom_folder(const char *dir)
{
    std::vector<std::string> names;
    {
        DIR *d = opendir(dir);
        if (!d) fail(WVOL_ERR_IO, std::string(dir) + ": cannot list the folder: " + std::strerror(errno));
        while (struct dirent *ent = readdir(d))
            if (ent->d_name[0] != '.') names.push_back(ent->d_name);
        closedir(d);
        std::sort(names.begin(), names.end());
    }
    std::vector<DicomInfo> slices;
    size_t looked = 0;
    for (const std::string &n : names) {
        std::string file = std::string(dir) + "/" + n;
        struct stat st;
        if (stat(file.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) continue;
        looked++;
        std::ifstream in(file, std::ios::binary);
        if (!in) fail(WVOL_ERR_IO, file + ": cannot open: " + std::strerror(errno));
        std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        DicomInfo info;
        info.file = file;
        if (!DicomParser(bytes, info).parse()) continue; // not DICOM: ignored
        if (!info.has_pixels) continue;                   // DICOMDIR, reports, ...: ignored
        slices.push_back(info);
    }
    if (slices.empty())
        fail(WVOL_ERR_FORMAT, std::string(dir) + ": no DICOM image files in this folder (" + std::to_string(looked) +
                                  " file" + (looked == 1 ? "" : "s") + " looked at; files need the DICM preamble)");

    // one series only
    std::map<std::string, int> series;
    for (const auto &s : slices) series[s.series]++;
    if (series.size() > 1) {
        std::string list;
        for (const auto &kv : series)
            list += (list.empty() ? "" : ", ") + (kv.first.empty() ? std::string("(none)") : kv.first) + " (" +
                    std::to_string(kv.second) + " files)";
        fail(WVOL_ERR_FORMAT, std::string(dir) + ": mixed DICOM series (SeriesInstanceUID " + list +
                                  "); put one series per folder");
    }
    const DicomInfo s0 = slices[0];
    for (const auto &s : slices) {
        if (s.encapsulated || (s.syntax != "1.2.840.10008.1.2" && s.syntax != "1.2.840.10008.1.2.1"))
            fail(WVOL_ERR_UNSUPPORTED, s.file + ": DICOM transfer syntax " + s.syntax +
                                           " (compressed or big-endian) is not supported; only uncompressed little-endian");
        if (s.samples != 1)
            fail(WVOL_ERR_UNSUPPORTED, s.file + ": " + std::to_string(s.samples) +
                                           " samples per pixel (color); only grayscale images are supported");
        if (s.frames > 1)
            fail(WVOL_ERR_UNSUPPORTED, s.file + ": multi-frame DICOM (" + std::to_string(s.frames) +
                                           " frames) is not supported");
        if (s.rows < 1 || s.cols < 1) fail(WVOL_ERR_FORMAT, s.file + ": DICOM image without Rows/Columns");
        if (s.rows != s0.rows || s.cols != s0.cols)
            fail(WVOL_ERR_FORMAT, std::string(dir) + ": mixed DICOM series (" + base_name(s0.file) + " is " +
                                      std::to_string(s0.cols) + " x " + std::to_string(s0.rows) + " but " +
                                      base_name(s.file) + " is " + std::to_string(s.cols) + " x " +
                                      std::to_string(s.rows) + ")");
        if (s.bits != s0.bits)
            fail(WVOL_ERR_FORMAT, std::string(dir) + ": mixed DICOM series (" + base_name(s0.file) + " has " +
                                      std::to_string(s0.bits) + "-bit pixels, " + base_name(s.file) + " " +
                                      std::to_string(s.bits) + "-bit)");
        for (int a = 0; a < 2; a++)
            if (std::fabs(s.pixel_spacing[a] - s0.pixel_spacing[a]) > 1e-6 * std::fabs(s0.pixel_spacing[a]))
                fail(WVOL_ERR_FORMAT, std::string(dir) + ": mixed DICOM series (PixelSpacing differs between " +
                                          base_name(s0.file) + " and " + base_name(s.file) + ")");
        for (int a = 0; a < 6; a++)
            if (std::fabs(s.iop[a] - s0.iop[a]) > 1e-4)
                fail(WVOL_ERR_FORMAT, std::string(dir) + ": mixed DICOM series (ImageOrientationPatient differs between " +
                                          base_name(s0.file) + " and " + base_name(s.file) + ")");
    }

    // slice order and spacing: positions along the normal, or instance numbers
    const double *rdir = s0.iop, *cdir = s0.iop + 3;
    const double normal[3] = {rdir[1] * cdir[2] - rdir[2] * cdir[1], rdir[2] * cdir[0] - rdir[0] * cdir[2],
                              rdir[0] * cdir[1] - rdir[1] * cdir[0]};
    bool all_ipp = true;
    for (const auto &s : slices) all_ipp = all_ipp && s.has_ipp;
    auto key = [&](const DicomInfo &s) { return s.ipp[0] * normal[0] + s.ipp[1] * normal[1] + s.ipp[2] * normal[2]; };
    double dz = s0.between > 0 ? s0.between : s0.thickness > 0 ? s0.thickness : 1.0;
    if (all_ipp) {
        std::stable_sort(slices.begin(), slices.end(),
                         [&](const DicomInfo &a, const DicomInfo &b) { return key(a) < key(b); });
        const size_t n = slices.size();
        if (n > 1) {
            const double span = key(slices[n - 1]) - key(slices[0]);
            dz = span / double(n - 1);
            for (size_t i = 1; i < n; i++) {
                const double gap = key(slices[i]) - key(slices[i - 1]);
                if (std::fabs(gap) <= 1e-6 * std::fabs(span))
                    fail(WVOL_ERR_FORMAT, std::string(dir) + ": mixed DICOM series (" + base_name(slices[i - 1].file) +
                                              " and " + base_name(slices[i].file) +
                                              " are at the same position; several acquisitions in one folder?)");
                if (std::fabs(gap - dz) > 1e-3 * std::fabs(dz))
                    fail(WVOL_ERR_UNSUPPORTED, std::string(dir) + ": DICOM slices are not evenly spaced (gap " +
                                                   num(gap) + " between " + base_name(slices[i - 1].file) + " and " +
                                                   base_name(slices[i].file) + ", " + num(dz) + " on average)");
            }
        }
    } else {
        std::stable_sort(slices.begin(), slices.end(),
                         [](const DicomInfo &a, const DicomInfo &b) { return a.instance < b.instance; });
    }

    const size_t nx = size_t(s0.cols), ny = size_t(s0.rows), nz = slices.size();
    wvol_volume *v = nullptr;
    wvol_error e;
    wvol_error_clear(&e);
    if (wvol_volume_create(&v, nx, ny, nz, &e) != WVOL_OK) fail(e.status, std::string(dir) + ": " + e.message);
    try {
        for (size_t k = 0; k < nz; k++) {
            const DicomInfo &s = slices[k];
            std::ifstream in(s.file, std::ios::binary);
            std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
            if (!in.good() && !in.eof()) fail(WVOL_ERR_IO, s.file + ": read error");
            dicom_pixels(s, bytes, v->data + k * nx * ny, nx * ny);
        }
        Geometry g;
        std::copy(slices[0].ipp, slices[0].ipp + 3, g.origin);
        g.spacing[0] = s0.pixel_spacing[1]; // PixelSpacing is row spacing (y) \ column spacing (x)
        g.spacing[1] = s0.pixel_spacing[0];
        g.spacing[2] = dz;
        apply_geometry(v, g, dir); // the patient orientation itself is not kept
        if (wvol_check_finite(v->data, nx, ny, nz, dir, &e) != WVOL_OK) fail(e.status, e.message);
    } catch (...) {
        wvol_volume_destroy(v);
        throw;
    }
    return v;
}

// ---------------------------------------------------------------- reading

wvol_volume *read_vtk(const char *path)
{
    Quiet quiet;
    if (is_dir(path)) return read_dicom_folder(path);
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
        MetaHeader h = read_meta_header(path);
        vtkNew<vtkMetaImageReader> r;
        r->SetFileName(path);
        vtkImageData *img = run_reader(r.Get(), path, "MetaImage", quiet);
        Geometry g = image_geometry(img);
        for (int a = 0; a < 3; a++) {
            g.spacing[a] = precise(g.spacing[a], h.spacing, size_t(a));
            g.origin[a] = precise(g.origin[a], h.origin, size_t(a));
        }
        if (h.ndims == 3 && h.matrix.size() == 9) // MetaImage matrices are column-major: axis a is column a
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
    Quiet quiet;
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
    } else {
        vtkNew<vtkNIFTIImageWriter> w;
        w->SetFileName(tmp.name());
        w->SetInputData(img);
        w->SetDescription("libwvol");
        run_writer(w.Get(), path, "NIfTI", quiet);
    }
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
