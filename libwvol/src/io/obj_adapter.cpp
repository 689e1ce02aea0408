/* SPDX-License-Identifier: MIT */
/* Wavefront OBJ + MTL through Debian's tinyobjloader (double precision build), behind the C
 * interface of adapters.h. Faces are read as written (no triangulation): the callers decide
 * which polygons they accept. */
#include "core/file_open.h"
#include "io/adapters.h"
#include "io/adapter_errors.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include <tiny_obj_loader.h>

namespace {

template <typename T> T *alloc_array(size_t n)
{
    return static_cast<T *>(std::calloc(n ? n : 1, sizeof(T)));
}

std::string first_line(const std::string &s)
{
    std::string t = s.substr(0, s.find('\n'));
    while (!t.empty() && (t.back() == '\r' || t.back() == ' ')) t.pop_back();
    return t;
}

}  // namespace

// tinyobjloader reads a coordinate it cannot parse ("nan", "1x") as 0, silently: the vertex
// lines are checked first, each coordinate a finite number. 0, or the first bad line's number.
static long bad_vertex_line(FILE *fp, std::string &what)
{
    char buf[4096];
    long line = 0;
    while (std::fgets(buf, sizeof buf, fp)) {
        const char *q = buf;
        line++;
        while (*q == ' ' || *q == '\t') q++;
        if (q[0] != 'v' || (q[1] != ' ' && q[1] != '\t')) continue;
        q += 2;
        for (int c = 0; c < 3; c++) {
            char *end;
            while (*q == ' ' || *q == '\t') q++;
            double v = std::strtod(q, &end);
            bool sep = *end == '\0' || *end == ' ' || *end == '\t' || *end == '\n' || *end == '\r';
            if (end == q || !sep || !std::isfinite(v)) {
                size_t n = std::strcspn(q, " \t\r\n");
                what.assign(q, n < 32 ? n : 32);
                return line;
            }
            q = end;
        }
    }
    return 0;
}

extern "C" wvol_status wvol__obj_read(wvol__obj *out, const char *path, wvol_error *err)
{
    if (!out || !path) return wvol_error_set(err, WVOL_ERR_ARG, "OBJ: NULL argument");
    std::memset(out, 0, sizeof *out);
    {
        // opened here first: a file that cannot be read is named with the system's reason
        // (tinyobjloader says only "Cannot open file")
        std::string what;
        FILE *fp = nullptr;
        if (wvol__fopen_regular(&fp, path, err) != WVOL_OK) return err ? err->status : WVOL_ERR_IO;
        long line = bad_vertex_line(fp, what);
        std::fclose(fp);
        if (line)
            return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: line %ld: vertex coordinate '%s' is not a finite number",
                                  path, line, what.c_str());
    }
    try {
        tinyobj::ObjReaderConfig cfg;
        cfg.triangulate = false;
        cfg.vertex_color = false;
        std::string p(path);
        size_t slash = p.rfind('/');
        cfg.mtl_search_path = slash == std::string::npos ? std::string("./") : p.substr(0, slash + 1);
        tinyobj::ObjReader reader;
        if (!reader.ParseFromFile(p, cfg)) {
            std::string why = first_line(reader.Error());
            return wvol_error_set(err, WVOL_ERR_IO, "%s: %s", path, why.empty() ? "cannot be read" : why.c_str());
        }
        if (!reader.Warning().empty())
            return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: %s", path, first_line(reader.Warning()).c_str());
        const tinyobj::attrib_t &a = reader.GetAttrib();
        const std::vector<tinyobj::material_t> &mats = reader.GetMaterials();
        size_t nfaces = 0, nidx = 0;
        for (const tinyobj::shape_t &sh : reader.GetShapes()) {
            nfaces += sh.mesh.num_face_vertices.size();
            nidx += sh.mesh.indices.size();
        }
        out->nv = a.vertices.size() / 3;
        out->nfaces = nfaces;
        out->nmtl = mats.size();
        out->v = alloc_array<double>(3 * out->nv);
        out->face_nv = alloc_array<int>(nfaces);
        out->face_mtl = alloc_array<int>(nfaces);
        out->face_first = alloc_array<size_t>(nfaces);
        out->face_v = alloc_array<long>(nidx);
        out->mtl_name = static_cast<char (*)[128]>(std::calloc(out->nmtl ? out->nmtl : 1, 128));
        out->kd = static_cast<double (*)[3]>(std::calloc(out->nmtl ? out->nmtl : 1, sizeof(double[3])));
        out->ke = static_cast<double (*)[3]>(std::calloc(out->nmtl ? out->nmtl : 1, sizeof(double[3])));
        if (!out->v || !out->face_nv || !out->face_mtl || !out->face_first || !out->face_v || !out->mtl_name ||
            !out->kd || !out->ke) {
            wvol__obj_free(out);
            return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
        }
        for (size_t i = 0; i < 3 * out->nv; i++) out->v[i] = static_cast<double>(a.vertices[i]);
        for (size_t m = 0; m < out->nmtl; m++) {
            std::snprintf(out->mtl_name[m], 128, "%s", mats[m].name.c_str());
            for (int c = 0; c < 3; c++) {
                out->kd[m][c] = static_cast<double>(mats[m].diffuse[c]);
                out->ke[m][c] = static_cast<double>(mats[m].emission[c]);
            }
        }
        size_t f = 0, k = 0;
        for (const tinyobj::shape_t &sh : reader.GetShapes()) {
            size_t base = 0;
            for (size_t j = 0; j < sh.mesh.num_face_vertices.size(); j++, f++) {
                int n = sh.mesh.num_face_vertices[j];
                out->face_nv[f] = n;
                out->face_mtl[f] = j < sh.mesh.material_ids.size() ? sh.mesh.material_ids[j] : -1;
                out->face_first[f] = k;
                for (int q = 0; q < n; q++) out->face_v[k++] = sh.mesh.indices[base + (size_t)q].vertex_index;
                base += (size_t)n;
            }
        }
        return WVOL_OK;
    } catch (...) {
        wvol__obj_free(out);
        return wvol_adapter::current_error(path, "tinyobjloader", err);
    }
}

extern "C" void wvol__obj_free(wvol__obj *o)
{
    if (!o) return;
    std::free(o->v);
    std::free(o->face_nv);
    std::free(o->face_mtl);
    std::free(o->face_first);
    std::free(o->face_v);
    std::free(o->mtl_name);
    std::free(o->kd);
    std::free(o->ke);
    std::memset(o, 0, sizeof *o);
}
