/* SPDX-License-Identifier: MIT */
// OpenVDB adapter: the only OpenVDB code in libwvol (C interface in io/adapters.h).
//
// Reading: a FloatGrid or DoubleGrid (by name, or the first one in the file) is
// densified over its active bounding box (united with the extent libwvol records
// when it wrote the file); every voxel of the box takes the grid's value there,
// so voxels outside the active set read as the background (or as an inactive
// tile's value). Its transform must be linear and axis-aligned with positive
// scales: spacing = the per-axis voxel size, origin = transform(bbox.min).
// The dense size is checked against the machine's memory from the file's
// metadata (file_bbox_min/max) before any tree is read, and again from the tree
// before the dense volume is allocated.
//
// Writing: a fog-volume FloatGrid named "density", background 0. Voxels that are
// exactly +0.0 are left inactive (they read back as the background 0, so nothing
// is lost); every other value is an active voxel. The full index extent
// [0, n-1] is recorded as grid metadata wvol_bbox_min/max so the dimensions come
// back exactly even when the border is zero. Uniform spacing gives a
// uniform-scale-translate map; per-axis spacing a (linear, axis-aligned)
// scale-translate map. The file is written beside the target and renamed.
//
// Every C++ exception stops at the C boundary and becomes a wvol_error.
#include "io/adapters.h"
#include "io/adapter_errors.hpp"

#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <limits>
#include <mutex>
#include <new>
#include <string>

#include "wvol/version.h"

namespace {

using openvdb::Coord;
using openvdb::CoordBBox;

using wvol_adapter::fail;

void init_once()
{
    static std::once_flag flag;
    std::call_once(flag, [] { openvdb::initialize(); });
}

const char *const META_WVOL_MIN = "wvol_bbox_min";
const char *const META_WVOL_MAX = "wvol_bbox_max";

// Text taken from a file, made safe for a one-line message (no control or non-ASCII bytes).
std::string printable(std::string s)
{
    for (char &c : s)
        if ((unsigned char)c < 0x20 || (unsigned char)c >= 0x7f) c = '?';
    return s;
}

std::string describe_grids(const openvdb::GridPtrVec &grids)
{
    if (grids.empty()) return "the file has no grids";
    std::string s = "the file has: ";
    for (size_t i = 0; i < grids.size(); i++) {
        if (i) s += ", ";
        s += "'" + printable(grids[i]->getName()) + "' (" + printable(grids[i]->valueType()) + ")";
    }
    return s;
}

bool is_scalar_float(const openvdb::GridBase &g)
{
    return g.isType<openvdb::FloatGrid>() || g.isType<openvdb::DoubleGrid>();
}

std::string fmt_bytes(double b)
{
    char buf[64];
    if (b >= 1024.0 * 1024 * 1024) std::snprintf(buf, sizeof buf, "%.1f GiB", b / (1024.0 * 1024 * 1024));
    else std::snprintf(buf, sizeof buf, "%.1f MiB", b / (1024.0 * 1024));
    return buf;
}

// Refuses a dense box that does not fit in memory (or overflows size_t).
void check_dense_size(const char *path, const std::string &grid, const Coord &lo, const Coord &hi,
                      const char *from)
{
    int64_t d[3];
    for (int a = 0; a < 3; a++) {
        d[a] = int64_t(hi[a]) - int64_t(lo[a]) + 1;
        if (d[a] < 1) fail(WVOL_ERR_FORMAT, std::string(path) + ": grid '" + grid + "': empty bounding box " + from);
    }
    size_t bytes = 0;
    long pages = sysconf(_SC_PHYS_PAGES), psize = sysconf(_SC_PAGESIZE);
    double phys = pages > 0 && psize > 0 ? double(pages) * double(psize) : 0.0;
    bool overflow = !wvol_size_mul3(size_t(d[0]), size_t(d[1]), size_t(d[2]), sizeof(float), &bytes);
    if (overflow || (phys > 0 && double(bytes) > phys)) {
        char buf[400];
        const std::string need = overflow ? std::string("more bytes than size_t can count")
                                          : fmt_bytes(double(bytes)) + " as a dense float32 volume";
        std::snprintf(buf, sizeof buf,
                      "%s: grid '%s': its active bounding box (%s) is %lld x %lld x %lld voxels, %s, "
                      "more than this machine's %s of memory; refused",
                      path, grid.c_str(), from, (long long)d[0], (long long)d[1], (long long)d[2], need.c_str(),
                      fmt_bytes(phys).c_str());
        fail(WVOL_ERR_NOMEM, buf);
    }
}

// The box libwvol recorded when it wrote the file, if any.
bool recorded_box(const openvdb::GridBase &g, CoordBBox &box)
{
    auto lo = g.getMetadata<openvdb::Vec3IMetadata>(META_WVOL_MIN);
    auto hi = g.getMetadata<openvdb::Vec3IMetadata>(META_WVOL_MAX);
    if (!lo || !hi) return false;
    Coord a(lo->value()), b(hi->value());
    if (a.x() > b.x() || a.y() > b.y() || a.z() > b.z()) return false;
    box = CoordBBox(a, b);
    return true;
}

// Spacing from an axis-aligned linear transform; refuses anything else.
void transform_spacing(const char *path, const openvdb::math::Transform &xf, const std::string &name,
                       double spacing[3])
{
    if (!xf.isLinear())
        fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": grid '" + name + "' has a non-linear (" +
                                       xf.mapType() + ") transform; only axis-aligned linear transforms are supported");
    // Scale maps give their scale directly (their AffineMap's matrix can be off in the last bit).
    openvdb::math::MapBase::ConstPtr base = xf.baseMap();
    openvdb::Vec3d scale(1.0);
    bool known = true;
    if (auto st = std::dynamic_pointer_cast<const openvdb::math::ScaleTranslateMap>(base)) scale = st->getScale();
    else if (auto sc = std::dynamic_pointer_cast<const openvdb::math::ScaleMap>(base)) scale = sc->getScale();
    else if (!std::dynamic_pointer_cast<const openvdb::math::TranslationMap>(base)) known = false;
    if (known) {
        for (int a = 0; a < 3; a++) {
            if (!(scale[a] > 0) || !std::isfinite(scale[a]))
                fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": grid '" + name +
                                               "' has a transform that flips or collapses an axis; not supported");
            spacing[a] = scale[a];
        }
        return;
    }
    openvdb::Mat4d m = base->getAffineMap()->getMat4();
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) {
            if (r == c) continue;
            if (std::fabs(m(r, c)) > 1e-12 * (std::fabs(m(r, r)) + std::fabs(m(c, c))))
                fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": grid '" + name +
                                               "' has a rotated or sheared transform (" + xf.mapType() +
                                               "); only axis-aligned scale and translation are supported");
        }
        if (!(m(r, r) > 0) || !std::isfinite(m(r, r)))
            fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": grid '" + name +
                                           "' has a transform that flips or collapses an axis; not supported");
        spacing[r] = m(r, r);
    }
}

template <typename GridT>
void densify(const GridT &grid, const CoordBBox &box, float *out)
{
    const int64_t nx = box.dim().x(), ny = box.dim().y(), nz = box.dim().z();
    const Coord lo = box.min();
    tbb::parallel_for(tbb::blocked_range<int64_t>(0, nz * ny), [&](const tbb::blocked_range<int64_t> &r) {
        auto acc = grid.getConstAccessor();
        for (int64_t row = r.begin(); row != r.end(); ++row) {
            const int64_t k = row / ny, j = row % ny;
            float *dst = out + size_t(row) * size_t(nx);
            Coord c(lo.x(), lo.y() + int(j), lo.z() + int(k));
            for (int64_t i = 0; i < nx; i++) {
                c.setX(lo.x() + int(i));
                dst[i] = float(acc.getValue(c));
            }
        }
    });
}

// OpenVDB reads lengths from the file and allocates them before reading (and after a
// short read uses an uninitialized length): a corrupt header can make it allocate
// gigabytes. So the length-prefixed parts it reads first (file header, file and grid
// metadata, grid descriptors, map type) are walked here, every length checked against
// the bytes left, before OpenVDB sees the file. Layout of file format >= 222.
class HeaderCheck {
public:
    explicit HeaderCheck(const char *path) : path_(path), in_(path, std::ios::binary)
    {
        if (!in_) fail(WVOL_ERR_IO, std::string(path) + ": cannot open: " + std::strerror(errno));
        in_.seekg(0, std::ios::end);
        size_ = uint64_t(in_.tellg());
        in_.seekg(0);
    }

    void run()
    {
        uint64_t magic = 0;
        read(&magic, 8);
        if (magic != 0x56444220u) fail(WVOL_ERR_FORMAT, std::string(path_) + ": not a readable OpenVDB file (not a VDB file)");
        const uint32_t version = u32();
        if (version < 222) return; // older layouts: left to OpenVDB
        skip(8);                   // library version
        char offsets = 0;
        read(&offsets, 1);
        skip(36); // UUID, as text
        metamap();
        const uint32_t count = u32();
        if (count > (size_ - pos_) / 36) bad("grid count");
        if (!offsets) return; // a stream without grid offsets: nothing to seek
        for (uint32_t g = 0; g < count; g++) {
            str(); // unique name
            str(); // grid type
            str(); // instance parent
            int64_t grid_pos, block_pos, end_pos;
            read(&grid_pos, 8);
            read(&block_pos, 8);
            read(&end_pos, 8);
            if (grid_pos != int64_t(pos_) || end_pos < grid_pos || uint64_t(end_pos) > size_) bad("grid offsets");
            u32(); // compression
            metamap();
            str(); // map type
            seek(uint64_t(end_pos));
        }
    }

private:
    const char *path_;
    std::ifstream in_;
    uint64_t size_ = 0, pos_ = 0;

    [[noreturn]] void bad(const char *what)
    {
        fail(WVOL_ERR_FORMAT, std::string(path_) + ": corrupt or truncated OpenVDB file (bad " + what + ")");
    }
    void read(void *dst, uint64_t n)
    {
        if (n > size_ - pos_ || !in_.read(static_cast<char *>(dst), std::streamsize(n))) bad("header");
        pos_ += n;
    }
    void seek(uint64_t p)
    {
        if (p > size_) bad("grid");
        in_.seekg(std::streamoff(p));
        pos_ = p;
    }
    void skip(uint64_t n)
    {
        if (n > size_ - pos_) bad("header");
        seek(pos_ + n);
    }
    uint32_t u32()
    {
        uint32_t v = 0;
        read(&v, 4);
        return v;
    }
    void str()
    {
        const uint32_t n = u32();
        if (n > size_ - pos_) bad("a string");
        skip(n);
    }
    void metamap()
    {
        const uint32_t count = u32();
        if (count > (size_ - pos_) / 12) bad("metadata count");
        for (uint32_t i = 0; i < count; i++) {
            str(); // name
            str(); // type name
            const uint32_t n = u32();
            if (n > size_ - pos_) bad("a metadata value");
            skip(n);
        }
    }
};

wvol_volume *read_vdb(const char *path, const char *grid_name)
{
    init_once();
    HeaderCheck(path).run();
    openvdb::io::File file(path);
    try {
        file.open(false); // no delayed loading: every read error surfaces here, not later
    } catch (const openvdb::Exception &e) {
        fail(WVOL_ERR_FORMAT, std::string(path) + ": not a readable OpenVDB file (" + e.what() + ")");
    }
    openvdb::GridPtrVecPtr metas = file.readAllGridMetadata();
    const openvdb::GridPtrVec &grids = *metas;
    size_t pick = grids.size();
    if (grid_name) {
        for (size_t i = 0; i < grids.size() && pick == grids.size(); i++)
            if (grids[i]->getName() == grid_name) pick = i;
        if (pick == grids.size())
            fail(WVOL_ERR_ARG, std::string(path) + ": no grid named '" + grid_name + "'; " + describe_grids(grids));
        if (!is_scalar_float(*grids[pick]))
            fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": grid '" + grid_name + "' holds " +
                                           printable(grids[pick]->valueType()) +
                                           " values; only float and double grids can be read (" +
                                           describe_grids(grids) + ")");
    } else {
        for (size_t i = 0; i < grids.size() && pick == grids.size(); i++)
            if (is_scalar_float(*grids[i])) pick = i;
        if (pick == grids.size())
            fail(WVOL_ERR_UNSUPPORTED,
                 std::string(path) + ": no float or double grid to read; " + describe_grids(grids));
    }
    const openvdb::GridBase &meta = *grids[pick];
    const std::string raw_name = meta.getName(), name = printable(raw_name); // name: for messages
    double spacing[3];
    transform_spacing(path, meta.transform(), name, spacing); // refuse early; the values come later

    // Before reading the tree: the dense size from the file's own statistics.
    CoordBBox box;
    bool have_box = false;
    {
        auto lo = meta.getMetadata<openvdb::Vec3IMetadata>(openvdb::GridBase::META_FILE_BBOX_MIN);
        auto hi = meta.getMetadata<openvdb::Vec3IMetadata>(openvdb::GridBase::META_FILE_BBOX_MAX);
        if (lo && hi && lo->value().x() <= hi->value().x() && lo->value().y() <= hi->value().y() &&
            lo->value().z() <= hi->value().z()) {
            box = CoordBBox(Coord(lo->value()), Coord(hi->value()));
            have_box = true;
        }
        CoordBBox rec;
        if (recorded_box(meta, rec)) {
            if (have_box) box.expand(rec);
            else box = rec;
            have_box = true;
        }
        if (have_box) check_dense_size(path, name, box.min(), box.max(), "from the file's metadata");
    }

    // Same name earlier in the file: OpenVDB addresses the n-th one as "name[n]".
    std::string unique = raw_name;
    {
        int n = 0;
        for (size_t i = 0; i < pick; i++)
            if (grids[i]->getName() == raw_name) n++;
        if (n) unique += "[" + std::to_string(n) + "]";
    }
    openvdb::GridBase::Ptr base;
    try {
        base = file.readGrid(unique);
    } catch (const std::bad_alloc &) {
        throw;
    } catch (const std::exception &e) {
        fail(WVOL_ERR_FORMAT, std::string(path) + ": grid '" + name + "' cannot be read (truncated or corrupt file?): " + e.what());
    }
    file.close();
    if (!base || !is_scalar_float(*base))
        fail(WVOL_ERR_FORMAT, std::string(path) + ": grid '" + name + "' could not be read as a float grid");

    // readAllGridMetadata hands back transforms rebuilt through an affine matrix (low
    // bits of the voxel size lost); the grid's own transform is the one in the file.
    transform_spacing(path, base->transform(), name, spacing);
    box = base->evalActiveVoxelBoundingBox();
    bool empty = box.empty();
    CoordBBox rec;
    if (recorded_box(*base, rec)) {
        if (empty) box = rec;
        else box.expand(rec);
        empty = false;
    }
    if (empty)
        fail(WVOL_ERR_FORMAT, std::string(path) + ": grid '" + name + "' has no active voxels (nothing to densify)");
    check_dense_size(path, name, box.min(), box.max(), "from the tree");

    const Coord dim = box.dim();
    wvol_volume *v = nullptr;
    wvol_error e;
    wvol_error_clear(&e);
    if (wvol_volume_create(&v, size_t(dim.x()), size_t(dim.y()), size_t(dim.z()), &e) != WVOL_OK)
        fail(e.status, std::string(path) + ": " + e.message);
    try {
        if (base->isType<openvdb::FloatGrid>())
            densify(*openvdb::gridPtrCast<openvdb::FloatGrid>(base), box, v->data);
        else
            densify(*openvdb::gridPtrCast<openvdb::DoubleGrid>(base), box, v->data);
        const openvdb::Vec3d o = base->transform().indexToWorld(box.min());
        const double origin[3] = {o.x(), o.y(), o.z()};
        if (wvol_volume_set_geometry(v, spacing, origin, &e) != WVOL_OK)
            fail(e.status, std::string(path) + ": grid '" + name + "': " + e.message);
        std::string what = std::string(path) + " (grid '" + name + "')";
        if (wvol_check_finite(v->data, v->nx, v->ny, v->nz, what.c_str(), &e) != WVOL_OK)
            fail(e.status, e.message);
    } catch (...) {
        wvol_volume_destroy(v);
        throw;
    }
    return v;
}

void write_vdb(const wvol_volume *v, const char *path)
{
    init_once();
    const size_t lim = size_t(std::numeric_limits<int32_t>::max());
    if (v->nx > lim || v->ny > lim || v->nz > lim)
        fail(WVOL_ERR_DIMS, std::string(path) + ": dimensions exceed OpenVDB's 32-bit index range");
    for (int a = 0; a < 3; a++)
        if (!(v->spacing[a] > 0) || !std::isfinite(v->spacing[a]) || !std::isfinite(v->origin[a]))
            fail(WVOL_ERR_ARG, std::string(path) + ": spacing must be positive and finite, origin finite");

    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(0.0f);
    {
        auto acc = grid->getAccessor();
        const float *src = v->data;
        for (size_t k = 0; k < v->nz; k++)
            for (size_t j = 0; j < v->ny; j++)
                for (size_t i = 0; i < v->nx; i++, src++) {
                    const float x = *src;
                    if (x == 0.0f && !std::signbit(x)) continue; // the background, left inactive
                    acc.setValueOn(Coord(int(i), int(j), int(k)), x);
                }
    }
    const openvdb::Vec3d origin(v->origin[0], v->origin[1], v->origin[2]);
    // Built by scale-then-translate on a scale map: Transform's constructor and most
    // of its operations go through an affine matrix and re-derive the voxel size
    // from differences of mapped points, which loses low bits when the origin is large.
    openvdb::math::Transform::Ptr xf;
    if (v->spacing[0] == v->spacing[1] && v->spacing[1] == v->spacing[2]) {
        xf = openvdb::math::Transform::createLinearTransform(v->spacing[0]);
    } else {
        xf = openvdb::math::Transform::createLinearTransform(1.0);
        xf->postScale(openvdb::Vec3d(v->spacing[0], v->spacing[1], v->spacing[2]));
    }
    xf->postTranslate(origin);
    {
        double check[3];
        transform_spacing(path, *xf, "density", check);
        if (check[0] != v->spacing[0] || check[1] != v->spacing[1] || check[2] != v->spacing[2])
            fail(WVOL_ERR_UNSUPPORTED, std::string(path) + ": spacing " + std::to_string(v->spacing[0]) + ", " +
                                           std::to_string(v->spacing[1]) + ", " + std::to_string(v->spacing[2]) +
                                           " is too close to uniform for OpenVDB to keep it exactly");
    }
    grid->setTransform(xf);
    grid->setName("density");
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    grid->setCreator("libwvol " WVOL_VERSION_STRING);
    grid->insertMeta("source", openvdb::StringMetadata("libwvol"));
    grid->insertMeta(META_WVOL_MIN, openvdb::Vec3IMetadata(openvdb::Vec3i(0, 0, 0)));
    grid->insertMeta(META_WVOL_MAX, openvdb::Vec3IMetadata(openvdb::Vec3i(int(v->nx) - 1, int(v->ny) - 1,
                                                                          int(v->nz) - 1)));

    wvol_atomic_file f;
    wvol_error e;
    wvol_error_clear(&e);
    if (wvol_atomic_open(&f, path, &e) != WVOL_OK) fail(e.status, e.message);
    try {
        openvdb::io::File out(f.tmp_path);
        openvdb::MetaMap file_meta;
        file_meta.insertMeta("creator", openvdb::StringMetadata("libwvol " WVOL_VERSION_STRING));
        openvdb::GridCPtrVec list{grid};
        out.write(list, file_meta);
        out.close();
        // OpenVDB's stream reports no failed write (a full disk leaves a short file): the file
        // is read back before it is renamed into place
        wvol_volume_destroy(read_vdb(f.tmp_path, nullptr));
    } catch (const wvol_adapter::Failure &fl) {
        wvol_atomic_abort(&f);
        fail(WVOL_ERR_IO, std::string(path) + ": the written file does not read back: " + fl.message +
                              " (is the disk full?)");
    } catch (const std::exception &ex) {
        wvol_atomic_abort(&f);
        fail(WVOL_ERR_IO, std::string(path) + ": writing the OpenVDB file failed (" + ex.what() + ")");
    } catch (...) {
        wvol_atomic_abort(&f);
        throw;
    }
    // f.fp was never written: committing flushes nothing and renames the file OpenVDB wrote.
    if (wvol_atomic_commit(&f, &e) != WVOL_OK) fail(e.status, e.message);
}

// Runs body, turning every exception into a wvol_error.
template <typename F>
wvol_status guarded(const char *path, wvol_error *err, F &&body)
{
    try {
        body();
        return WVOL_OK;
    } catch (const openvdb::IoError &e) {
        return wvol_error_set(err, WVOL_ERR_IO, "%s: %s", path, e.what());
    } catch (const openvdb::Exception &e) {
        return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: OpenVDB: %s", path, e.what());
    } catch (...) {
        return wvol_adapter::current_error(path, "OpenVDB", err);
    }
}

} // namespace

extern "C" wvol_status wvol__vdb_read(wvol_volume **out, const char *path, const char *grid_name,
                                      wvol_error *err)
{
    if (!out || !path) return wvol_error_set(err, WVOL_ERR_ARG, "vdb read: NULL argument");
    *out = nullptr;
    return guarded(path, err, [&] { *out = read_vdb(path, grid_name); });
}

extern "C" wvol_status wvol__vdb_write(const wvol_volume *v, const char *path, wvol_error *err)
{
    if (!v || !v->data || !path) return wvol_error_set(err, WVOL_ERR_ARG, "vdb write: NULL argument");
    return guarded(path, err, [&] { write_vdb(v, path); });
}
