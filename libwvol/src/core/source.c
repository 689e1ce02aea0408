/* SPDX-License-Identifier: MIT */
/* Volume sources (wvol/source.h): the checked slab read over a source's callbacks, and
 * the source over a volume in memory. The file sources are in io/source_file.c. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/finite.h"
#include "core/source_volume.h"
#include "core/status_internal.h"
#include "wvol/source.h"

struct wvol_source {
    size_t dims[3];
    double spacing[3], origin[3];
    char name[256];
    int streams;
    wvol_source_ops ops;
    void *ctx;
    wvol__source_rows_fn rows; /* NULL: no row bands (wvol__source_set_rows) */
    float seen[2]; /* wvol__source_seen_range */
};

wvol_status wvol_source_create(wvol_source **out, const size_t dims[3], const double spacing[3],
                               const double origin[3], const char *name, int streams, const wvol_source_ops *ops,
                               void *ctx, wvol_error *err)
{
    wvol_source *s;
    size_t bytes;
    if (out) *out = NULL;
    if (!out || !dims || !ops || !ops->read) {
        if (ops && ops->close) ops->close(ctx);
        return wvol_error_set(err, WVOL_ERR_ARG, "volume source: NULL argument");
    }
    if (!dims[0] || !dims[1] || !dims[2] || !wvol_size_mul3(dims[0], dims[1], dims[2], sizeof(float), &bytes)) {
        if (ops->close) ops->close(ctx);
        return wvol_error_set(err, WVOL_ERR_DIMS, "volume source %s: bad size %zu x %zu x %zu", name ? name : "",
                              dims[0], dims[1], dims[2]);
    }
    if (wvol__geometry_check(spacing, origin, err) != WVOL_OK) {
        if (ops->close) ops->close(ctx);
        return WVOL_ERR_ARG;
    }
    s = calloc(1, sizeof *s);
    if (!s) {
        if (ops->close) ops->close(ctx);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "volume source: out of memory");
    }
    for (int a = 0; a < 3; a++) {
        s->dims[a] = dims[a];
        s->spacing[a] = spacing ? spacing[a] : 1.0;
        s->origin[a] = origin ? origin[a] : 0.0;
    }
    snprintf(s->name, sizeof s->name, "%s", name ? name : "volume");
    s->streams = streams;
    s->ops = *ops;
    s->ctx = ctx;
    wvol__source_seen_reset(s);
    *out = s;
    return WVOL_OK;
}

void wvol_source_destroy(wvol_source *s)
{
    if (!s) return;
    if (s->ops.close) s->ops.close(s->ctx);
    free(s);
}

void wvol_source_geometry(const wvol_source *s, size_t dims[3], double spacing[3], double origin[3])
{
    if (!s) return;
    if (dims) memcpy(dims, s->dims, sizeof s->dims);
    if (spacing) memcpy(spacing, s->spacing, sizeof s->spacing);
    if (origin) memcpy(origin, s->origin, sizeof s->origin);
}

const char *wvol_source_name(const wvol_source *s) { return s ? s->name : ""; }

int wvol_source_streams(const wvol_source *s) { return s ? s->streams : 0; }

void wvol__source_seen_reset(wvol_source *s)
{
    if (!s) return;
    s->seen[0] = INFINITY;
    s->seen[1] = -INFINITY;
}

void wvol__source_seen_range(const wvol_source *s, float range[2])
{
    range[0] = s ? s->seen[0] : INFINITY;
    range[1] = s ? s->seen[1] : -INFINITY;
}

/* What a read returned (rows y0 .. y0 + ny - 1 of slices z0 ..): its range into the seen
 * range, or the first non-finite sample refused by its voxel. */
static wvol_status check_read(wvol_source *s, const float *dst, size_t z0, size_t nz, size_t y0, size_t ny,
                              wvol_error *err)
{
    const size_t nx = s->dims[0], band = nx * ny, n = band * nz;
    float range[2];
    /* the common case (all finite) in one branch-free pass, which takes the range too; the
     * voxel is found after */
    if (wvol__finite_range(dst, n, range)) {
        s->seen[0] = range[0] < s->seen[0] ? range[0] : s->seen[0];
        s->seen[1] = range[1] > s->seen[1] ? range[1] : s->seen[1];
        return WVOL_OK;
    }
    for (size_t i = 0; i < n; i++)
        if (!isfinite(dst[i]))
            return wvol_error_set(err, WVOL_ERR_NONFINITE,
                                  "%s: %s at voxel (i=%zu, j=%zu, k=%zu); NaN and Inf are refused", s->name,
                                  isnan(dst[i]) ? "NaN" : "Inf", i % nx, y0 + (i % band) / nx, z0 + i / band);
    return WVOL_OK;
}

wvol_status wvol_source_read(wvol_source *s, float *dst, size_t z0, size_t nz, wvol_error *err)
{
    WVOL_RETURN_IF(!s || !dst, err, WVOL_ERR_ARG, "volume source: NULL argument");
    WVOL_RETURN_IF(nz == 0 || z0 > s->dims[2] || nz > s->dims[2] - z0, err, WVOL_ERR_ARG,
                   "%s: slices %zu .. %zu outside the volume's 0 .. %zu", s->name, z0, z0 + nz, s->dims[2]);
    {
        /* a user's callback may fail without a message: cleared first, so that an empty one
         * is told from an earlier call's, then filled in naming the source and the slab */
        wvol_status st;
        wvol_error_clear(err);
        st = s->ops.read(s->ctx, dst, z0, nz, err);
        if (st != WVOL_OK) {
            if (err && !err->message[0])
                wvol_error_set(err, st, "%s: read of slices %zu..%zu failed (status %d)", s->name, z0, z0 + nz - 1,
                               (int)st);
            else if (err)
                err->status = st;
            return st;
        }
    }
    return check_read(s, dst, z0, nz, 0, s->dims[1], err);
}

void wvol__source_set_rows(wvol_source *s, wvol__source_rows_fn fn)
{
    if (s) s->rows = fn;
}

wvol_status wvol__source_read_rows(wvol_source *s, float *dst, size_t z0, size_t nz, size_t y0, size_t ny,
                                   wvol_error *err)
{
    WVOL_RETURN_IF(!s || !dst, err, WVOL_ERR_ARG, "volume source: NULL argument");
    if (!s->rows) return WVOL_ERR_UNSUPPORTED;
    WVOL_RETURN_IF(nz == 0 || z0 > s->dims[2] || nz > s->dims[2] - z0 || ny == 0 || y0 > s->dims[1] ||
                       ny > s->dims[1] - y0,
                   err, WVOL_ERR_ARG, "%s: rows %zu .. %zu of slices %zu .. %zu outside the volume's %zu x %zu",
                   s->name, y0, y0 + ny, z0, z0 + nz, s->dims[1], s->dims[2]);
    WVOL_FORWARD(s->rows(s->ctx, dst, z0, nz, y0, ny, err));
    return check_read(s, dst, z0, nz, y0, ny, err);
}

wvol_status wvol_source_read_volume(wvol_source *s, wvol_volume **out, wvol_error *err)
{
    wvol_status st;
    WVOL_RETURN_IF(!out || !s, err, WVOL_ERR_ARG, "volume source: NULL argument");
    *out = NULL;
    WVOL_FORWARD(wvol_volume_create(out, s->dims[0], s->dims[1], s->dims[2], err));
    st = wvol_volume_set_geometry(*out, s->spacing, s->origin, err);
    if (!st) st = wvol_source_read(s, (*out)->data, 0, s->dims[2], err);
    if (st) {
        wvol_volume_destroy(*out);
        *out = NULL;
    }
    return st;
}

/* ---- a volume in memory ---------------------------------------------------------- */

wvol_status wvol__source_volume_read(void *ctx, float *dst, size_t z0, size_t nz, wvol_error *err)
{
    const wvol_volume *v = ctx;
    (void)err;
    memcpy(dst, v->data + v->nx * v->ny * z0, v->nx * v->ny * nz * sizeof(float));
    return WVOL_OK;
}

wvol_status wvol__source_volume_rows(void *ctx, float *dst, size_t z0, size_t nz, size_t y0, size_t ny,
                                     wvol_error *err)
{
    const wvol_volume *v = ctx;
    const size_t band = v->nx * ny;
    (void)err;
    for (size_t k = 0; k < nz; k++)
        memcpy(dst + k * band, v->data + v->nx * (v->ny * (z0 + k) + y0), band * sizeof(float));
    return WVOL_OK;
}

wvol_status wvol_source_of_volume(wvol_source **out, const wvol_volume *v, wvol_error *err)
{
    static const wvol_source_ops ops = {wvol__source_volume_read, NULL};
    size_t dims[3];
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "volume source: NULL argument");
    *out = NULL;
    WVOL_RETURN_IF(!v || !v->data, err, WVOL_ERR_ARG, "volume source: volume is NULL");
    dims[0] = v->nx, dims[1] = v->ny, dims[2] = v->nz;
    WVOL_FORWARD(wvol_source_create(out, dims, v->spacing, v->origin, "volume", 0, &ops, (void *)v, err));
    wvol__source_set_rows(*out, wvol__source_volume_rows);
    return WVOL_OK;
}
