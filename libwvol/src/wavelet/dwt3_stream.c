/* SPDX-License-Identifier: MIT */
/* The forward transform streamed along z (wvol_dwt3_stream_*): slices go in in order,
 * each level's coefficient rows come out in increasing z, with memory that does not
 * depend on the number of slices.
 *
 * Per level, a window of xy-transformed slices: the first L - 2 (the periodic wrap rows
 * the last outputs need, kept from the start) and a ring of the latest L + a batch. The
 * z output k needs input rows 2k .. 2k + L - 1 (mod the level's depth): it is made as
 * soon as row 2k + L - 1 has arrived (the last ones when the last row has), by the same
 * kernels, blocks and tap order as the in-memory transform (dwt3_impl.h), so the
 * coefficients are bit-identical to wvol_dwt3's. The z-low row's low-low quadrant is
 * the next level's input row k. A level shallower than 2L keeps all its rows.
 *
 * The outputs a batch of slices allows are made together, a group per task's rows: output
 * k reads L input rows and k + 1 reads L - 2 of the same, so a task that makes the group's
 * outputs of its few plane rows one after the other finds their inputs in its cache. Made
 * one output at a time across the whole plane, each input row would be read L / 2 times
 * from wherever the window is: memory, once the L planes outgrow the cache (1024^2 slices). */
#include <omp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/alloc.h"
#include "core/finite.h"
#include "wavelet/wavelet_internal.h"
#include "wvol/source.h"

/* slices transformed in x and y together (in parallel) before the z outputs they allow,
 * which are made as a group of half as many; fewer when a slice is large (BATCH_BYTES of
 * them at most, but at least 2): each one in the batch costs a ring slot per level, a
 * slice of the reader's slab and half a group's output rows, and at 2048^2 eight slices
 * are 128 MiB three times over while two keep two threads busy. Up to 1024^2 the batch
 * stays 8: a group of 4 outputs reads 18 input planes (coif2), where one output at a
 * time would read 12 for each */
enum { BATCH = 8 };
#define BATCH_BYTES ((size_t)32 << 20)

typedef struct level_state {
    size_t cx, cy, cz, plane; /* this level's input cube (cz rows of cx x cy) */
    size_t head, ring, slots; /* wrap rows kept, ring rows; all rows when head == cz */
    float *rows;              /* slots x plane */
    size_t next;              /* next output row */
    float *out;               /* a group's output rows: low then high plane of each */
} level_state;

struct wvol_dwt3_stream {
    const wvol_filter *f;
    int levels, L, threads; /* threads: scratch slots, and the most the parallel loops use */
    size_t batch;           /* slices per take() (BATCH, fewer for large slices) */
    size_t group;           /* outputs of a level made together (batch / 2) */
    size_t n[3], p[3];
    float h[WVOL__MAX_TAPS], g[WVOL__MAX_TAPS];
    level_state lv[31];
    float *scratch;
    size_t scratch_per;
    float *last;              /* the last original slice (z padding repeats it) */
    float offset;             /* taken out of every sample (dc_offset.c; set by the first slice) */
    double dc;                /* offset x the kernels' gain: added to the coarsest low-pass band */
    size_t pushed;            /* original slices received */
    int finished, failed;
    size_t bytes;
    wvol_dwt3_rows_fn fn;
    wvol_dwt3_place_fn place; /* NULL: the rows are made in lv[m].lo / hi */
    wvol_dwt3_piece_fn piece; /* NULL: none */
    void *user;
};

static float *slot(const level_state *s, size_t i)
{
    size_t k = i < s->head || s->head == s->cz ? i : s->head + (i - s->head) % s->ring;
    return s->rows + k * s->plane;
}

void wvol_dwt3_stream_destroy(wvol_dwt3_stream *s)
{
    if (!s) return;
    for (int m = 0; m < 31; m++) {
        wvol__reuse_put(s->lv[m].rows);
        wvol__reuse_put(s->lv[m].out);
    }
    free(s->scratch);
    free(s->last);
    free(s);
}

size_t wvol_dwt3_stream_bytes(const wvol_dwt3_stream *s) { return s ? s->bytes : 0; }

wvol_status wvol_dwt3_stream_set_place(wvol_dwt3_stream *s, wvol_dwt3_place_fn place, wvol_error *err)
{
    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "streamed transform: NULL argument");
    WVOL_RETURN_IF(s->pushed, err, WVOL_ERR_ARG, "streamed transform: rows placed after the first slice");
    s->place = place;
    return WVOL_OK;
}

wvol_status wvol_dwt3_stream_set_pieces(wvol_dwt3_stream *s, wvol_dwt3_piece_fn piece, wvol_error *err)
{
    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "streamed transform: NULL argument");
    WVOL_RETURN_IF(s->pushed, err, WVOL_ERR_ARG, "streamed transform: pieces asked for after the first slice");
    s->piece = piece;
    return WVOL_OK;
}

wvol_status wvol_dwt3_stream_create(wvol_dwt3_stream **out, const wvol_filter *f, int levels, size_t nx, size_t ny,
                                    size_t nz, wvol_dwt3_rows_fn fn, void *user, wvol_error *err)
{
    wvol_dwt3_stream *s;
    dwt_plan pl;
    int maxl;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "streamed transform: out is NULL");
    *out = NULL;
    WVOL_RETURN_IF(!f || !f->h || !fn, err, WVOL_ERR_ARG, "streamed transform: no filter or no callback");
    WVOL_RETURN_IF(nx == 0 || ny == 0 || nz == 0, err, WVOL_ERR_DIMS,
                   "streamed transform: empty volume %zu x %zu x %zu", nx, ny, nz);
    maxl = wvol_dwt_max_levels(nx, ny, nz);
    WVOL_RETURN_IF(maxl == 0, err, WVOL_ERR_DIMS, "streamed transform: a 1 x 1 x 1 volume has no levels");
    WVOL_RETURN_IF(levels < 1 || levels > maxl, err, WVOL_ERR_ARG,
                   "streamed transform: levels = %d for a %zu x %zu x %zu volume (1..%d)", levels, nx, ny, nz, maxl);
    s = calloc(1, sizeof *s);
    WVOL_RETURN_IF(!s, err, WVOL_ERR_NOMEM, "streamed transform: out of memory");
    s->f = f;
    s->levels = levels;
    s->L = f->length;
    s->fn = fn;
    s->user = user;
    s->n[0] = nx, s->n[1] = ny, s->n[2] = nz;
    for (int a = 0; a < 3; a++) s->p[a] = wvol_dwt_padded_size(s->n[a], levels);
    for (int i = 0; i < f->length; i++) s->h[i] = (float)f->h[i], s->g[i] = (float)f->g[i];
    s->batch = BATCH;
    while (s->batch > 2 && s->batch * s->p[0] * s->p[1] * sizeof(float) > BATCH_BYTES) s->batch /= 2;
    s->group = s->batch / 2;
    /* scratch per thread: the in-memory plan's for the x rows and y column blocks (the z
     * pass reads the window's rows in place) */
    {
        size_t need = 0, L = (size_t)s->L;
        wvol_status st = wvol__dwt_plan(&pl, s, s->p, f, levels, sizeof(float), err);
        if (st) {
            wvol_dwt3_stream_destroy(s);
            return st;
        }
        for (int m = 0; m < levels; m++) {
            size_t cx = wvol__extent(s->p[0], m), cy = wvol__extent(s->p[1], m);
            size_t x = 4 * (cx / 2 + L), y = cy > 1 ? (cy + L) * wvol__block_width(cx, cy, s->L, sizeof(float)) : 0;
            need = x > need ? x : need;
            need = y > need ? y : need;
        }
        s->threads = pl.threads;
        s->scratch_per = (need + 15) & ~(size_t)15;
    }
    s->scratch = malloc(s->scratch_per * (size_t)s->threads * sizeof(float));
    s->bytes = s->scratch_per * (size_t)s->threads * sizeof(float);
    s->last = malloc(nx * ny * sizeof(float));
    s->bytes += nx * ny * sizeof(float);
    if (!s->scratch || !s->last) goto nomem;
    for (int m = 1; m <= levels; m++) {
        level_state *l = &s->lv[m];
        size_t L = (size_t)s->L;
        l->cx = wvol__extent(s->p[0], m - 1);
        l->cy = wvol__extent(s->p[1], m - 1);
        l->cz = wvol__extent(s->p[2], m - 1);
        l->plane = l->cx * l->cy;
        if (l->cz < 2 * L + s->batch) {
            l->head = l->cz, l->ring = 0, l->slots = l->cz;
        } else {
            l->head = L - 2, l->ring = L + s->batch, l->slots = l->head + l->ring;
        }
        l->rows = wvol__reuse_get(l->slots * l->plane * sizeof(float));
        l->out = wvol__reuse_get(2 * s->group * l->plane * sizeof(float));
        if (!l->rows || !l->out) goto nomem;
        s->bytes += (l->slots + 2 * s->group) * l->plane * sizeof(float);
    }
    *out = s;
    return WVOL_OK;
nomem:
    {
        size_t need = s->bytes;
        wvol_dwt3_stream_destroy(s);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "streamed transform: no memory for its window (%zu bytes)", need);
    }
}

/* Every value finite (`finite`: the row's test): the low-pass gains 2^1.5 per level, inputs
 * near FLT_MAX overflow. */
static wvol_status check_plane(int finite, int level, wvol_error *err)
{
    WVOL_RETURN_IF(!finite, err, WVOL_ERR_NONFINITE,
                   "streamed transform: coefficients of level %d overflow float32 (the low-pass grows by 2^1.5 per "
                   "level; input magnitudes must stay below about FLT_MAX / 2^(1.5 * levels))", level);
    return WVOL_OK;
}

static wvol_status arrive(wvol_dwt3_stream *s, int m, size_t i, wvol_error *err);

/* The offset back into rows y0 .. y1 - 1 of a z-low output plane of the coarsest level: its
 * low-low quadrant is the low-pass band (as wvol__lowpass_add does on the whole pyramid). */
static void lowpass_rows_add(const wvol_dwt3_stream *s, const level_state *l, float *low, size_t y0, size_t y1)
{
    const size_t hx = l->cx > 1 ? l->cx / 2 : 1, hy = l->cy > 1 ? l->cy / 2 : 1;
    for (size_t y = y0; y < y1 && y < hy; y++)
        for (size_t x = 0; x < hx; x++) low[x + y * l->cx] = (float)((double)low[x + y * l->cx] + s->dc);
}

/* Called from a task of a running team (a streamed compression's producer, whose team's
 * other threads code chunks: codec/wvc2_writer.h run()): the loops become task loops, so
 * that idle threads of the team share them (a nested parallel region would run on the
 * caller alone). Each thread uses its own scratch slot, so the team must not be larger
 * than the slots. The rows are computed by the same kernels either way: the same bits. */
static int team_tasks(const wvol_dwt3_stream *s)
{
    return omp_in_parallel() && omp_get_num_threads() > 1 && omp_get_num_threads() <= s->threads;
}

/* The z pass of rows y0 .. y1 - 1 of output rows k0 .. k0 + n - 1 of level m (row k0 + j
 * into lo[j], hi[j]), one output after the other while their inputs are in this thread's
 * cache, each followed by its finiteness check and the caller's piece; returns 0 when a
 * value is NaN or Inf. */
static int zrows_checked(const wvol_dwt3_stream *s, const level_state *l, int m, size_t k0, size_t n,
                         float *const *lo, float *const *hi, size_t y0, size_t y1)
{
    const size_t cnt = (y1 - y0) * l->cx;
    for (size_t j = 0; j < n; j++) {
        const size_t k = k0 + j;
        const float *rows[WVOL__MAX_TAPS];
        for (int t = 0; t < s->L; t++) rows[t] = slot(l, (2 * k + (size_t)t) % l->cz);
        wvol__dwt_zrows_f32(lo[j], hi[j], rows, l->cx, y0, y1, l->cz, s->h, s->g, s->L);
        if (m == s->levels && s->dc != 0.0) lowpass_rows_add(s, l, lo[j], y0, y1);
        if (!wvol__all_finite(lo[j] + y0 * l->cx, cnt) || !wvol__all_finite(hi[j] + y0 * l->cx, cnt)) return 0;
        if (s->piece) s->piece(s->user, m, k, y0, y1, lo[j] + y0 * l->cx, hi[j] + y0 * l->cx);
    }
    return 1;
}

/* Plane rows per z-pass task: a group's input and output rows of the task within about
 * half a core's L2 (2 + L - 2 + 2 per output, 4 bytes each), at most 8 */
static long long zpass_rows(const wvol_dwt3_stream *s, const level_state *l, size_t n)
{
    size_t per = (2 * n + (size_t)s->L - 2 + 2 * n) * l->cx * sizeof(float), r = ((size_t)512 << 10) / per;
    return r < 1 ? 1 : r > 8 ? 8 : (long long)r;
}

/* Output rows k0 .. k1 - 1 of level m (k1 - k0 <= group): the z pass of all of them, then
 * each one's callback and the next level's input row in order, then the next level's
 * outputs they allow. */
static wvol_status emit(wvol_dwt3_stream *s, int m, size_t k0, size_t k1, wvol_error *err)
{
    level_state *l = &s->lv[m];
    const size_t n = k1 - k0;
    float *lo[BATCH], *hi[BATCH];
    for (size_t j = 0; j < n; j++) {
        float *room = s->place ? s->place(s->user, m, k0 + j) : l->out + 2 * j * l->plane;
        WVOL_RETURN_IF(!room, err, WVOL_ERR_ARG, "streamed transform: no room given for row %zu of level %d", k0 + j,
                       m);
        lo[j] = room, hi[j] = room + l->plane;
    }
    if (l->cz > 1) {
        long long ny = (long long)l->cy, chunk = zpass_rows(s, l, n);
        int finite = 1;
        /* each task checks the rows it made: the check is shared as the pass is */
        if (team_tasks(s)) {
            /* unsigned: clang's taskloop compares a signed variable with its unsigned count */
            const size_t uy = (size_t)ny, uc = (size_t)chunk;
#pragma omp taskloop grainsize(1) shared(finite) if (l->plane > 32768)
            for (size_t y = 0; y < uy; y += uc)
                if (!zrows_checked(s, l, m, k0, n, lo, hi, y, y + uc < uy ? y + uc : uy)) {
#pragma omp atomic write
                    finite = 0;
                }
        } else {
#pragma omp parallel for schedule(dynamic, 1) num_threads(s->threads) if (l->plane > 32768) reduction(& : finite)
            for (long long y = 0; y < ny; y += chunk)
                finite &= zrows_checked(s, l, m, k0, n, lo, hi, (size_t)y, (size_t)(y + chunk < ny ? y + chunk : ny));
        }
        WVOL_FORWARD(check_plane(finite, m, err));
    } else {
        /* an untransformed z axis: the xy-transformed slice itself (one row, k = 0), copied
         * only into a room the caller gave */
        float *low = slot(l, 0);
        if (m == s->levels && s->dc != 0.0) lowpass_rows_add(s, l, low, 0, l->cy);
        WVOL_FORWARD(check_plane(wvol__all_finite(low, l->plane), m, err));
        lo[0] = s->place ? memcpy(lo[0], low, l->plane * sizeof(float)) : low;
        hi[0] = NULL;
        if (s->piece) s->piece(s->user, m, k0, 0, l->cy, lo[0], NULL);
    }
    for (size_t j = 0; j < n; j++) {
        const size_t k = k0 + j;
        WVOL_FORWARD(s->fn(s->user, m, k, lo[j], hi[j], err));
        if (m < s->levels) {
            level_state *nx = &s->lv[m + 1];
            float *dst = slot(nx, k);
            if (nx->cx > 1) { /* the x pass reads the low-low quadrant's rows where they are */
                wvol__dwt_slice_xy_from_f32(dst, lo[j], l->cx, nx->cy, nx->cx, nx->cy, s->h, s->g, s->L, s->scratch);
            } else {
                for (size_t y = 0; y < nx->cy; y++) memcpy(dst + y * nx->cx, lo[j] + y * l->cx, nx->cx * sizeof(float));
                wvol__dwt_slice_xy_f32(dst, nx->cx, nx->cy, s->h, s->g, s->L, s->scratch);
            }
        }
    }
    if (m < s->levels) WVOL_FORWARD(arrive(s, m + 1, k1 - 1, err));
    return WVOL_OK;
}

/* Rows up to i of level m are in their slots, xy-transformed: make the outputs they
 * complete, a group at a time. */
static wvol_status arrive(wvol_dwt3_stream *s, int m, size_t i, wvol_error *err)
{
    level_state *l = &s->lv[m];
    size_t half = l->cz > 1 ? l->cz / 2 : 1, L = (size_t)s->L, lim;
    /* output k needs rows 2k .. 2k + L - 1; the last ones wrap to the rows kept first */
    if (l->cz == 1 || i + 1 == l->cz) lim = half;
    else lim = i + 1 >= L ? (i + 1 - L) / 2 + 1 : 0;
    if (lim > half) lim = half;
    while (l->next < lim) {
        size_t k1 = l->next + s->group < lim ? l->next + s->group : lim;
        WVOL_FORWARD(emit(s, m, l->next, k1, err));
        l->next = k1;
    }
    return WVOL_OK;
}

/* Slice z0 + t of level 1, xy-transformed into its slot: straight from the source rows when
 * x needs no padding, else copied in first (edge padding). */
static void take_one(wvol_dwt3_stream *s, const float *slices, size_t z0, size_t t)
{
    level_state *l = &s->lv[1];
    size_t nx = s->n[0], ny = s->n[1];
    const float *src = slices ? slices + t * nx * ny : s->last;
    float *dst = slot(l, z0 + t);
    float *scratch = s->scratch + (size_t)omp_get_thread_num() * s->scratch_per;
    if (nx == l->cx && nx > 1 && s->offset == 0.0f) { /* no padding along x: the x pass reads the source rows */
        wvol__dwt_slice_xy_from_f32(dst, src, nx, ny, l->cx, l->cy, s->h, s->g, s->L, scratch);
        return;
    }
    for (size_t j = 0; j < l->cy; j++) {
        const float *row = src + nx * (j < ny ? j : ny - 1); /* edge padding, as wvol_dwt3 */
        float *o = dst + j * l->cx;
        memcpy(o, row, nx * sizeof(float));
        for (size_t i = nx; i < l->cx; i++) o[i] = row[nx - 1];
        if (s->offset != 0.0f) /* the offset out, as wvol_dwt3 takes it out of the padded samples */
            for (size_t i = 0; i < l->cx; i++) o[i] -= s->offset;
    }
    wvol__dwt_slice_xy_f32(dst, l->cx, l->cy, s->h, s->g, s->L, scratch);
}

/* Padded slices z0 .. z0 + cnt - 1 of level 1 (their source rows given by src(z)). */
static wvol_status take(wvol_dwt3_stream *s, const float *slices, size_t z0, size_t cnt, wvol_error *err)
{
    long long c = (long long)cnt;
    if (team_tasks(s)) {
#pragma omp taskloop grainsize(1) if (cnt > 1)
        for (size_t t = 0; t < cnt; t++) take_one(s, slices, z0, t); /* unsigned: as above */
    } else {
#pragma omp parallel for schedule(dynamic, 1) num_threads(s->threads) if (cnt > 1)
        for (long long t = 0; t < c; t++) take_one(s, slices, z0, (size_t)t);
    }
    return cnt ? arrive(s, 1, z0 + cnt - 1, err) : WVOL_OK;
}

wvol_status wvol_dwt3_stream_push(wvol_dwt3_stream *s, const float *slices, size_t count, wvol_error *err)
{
    size_t slice;
    WVOL_RETURN_IF(!s || (!slices && count), err, WVOL_ERR_ARG, "streamed transform: NULL argument");
    WVOL_RETURN_IF(s->failed, err, WVOL_ERR_ARG, "streamed transform: an earlier step failed");
    WVOL_RETURN_IF(count > s->n[2] - s->pushed, err, WVOL_ERR_ARG,
                   "streamed transform: %zu slices past the volume's %zu", s->pushed + count, s->n[2]);
    slice = s->n[0] * s->n[1];
    if (!s->pushed && count) { /* the first slice sets the offset, as wvol_dwt3's does */
        const size_t pad[3] = {s->p[0], s->p[1], s->p[2]};
        s->offset = wvol__slice_offset(slices, slice);
        s->dc = s->offset != 0.0f ? (double)s->offset * wvol__dc_gain_f32(s->f, s->levels, pad) : 0.0;
    }
    for (size_t done = 0; done < count;) {
        size_t b = count - done < s->batch ? count - done : s->batch;
        wvol_status st = take(s, slices + done * slice, s->pushed, b, err);
        if (st) {
            s->failed = 1;
            return st;
        }
        s->pushed += b;
        done += b;
    }
    if (count) memcpy(s->last, slices + (count - 1) * slice, slice * sizeof(float));
    return WVOL_OK;
}

wvol_status wvol_dwt3_stream_finish(wvol_dwt3_stream *s, wvol_error *err)
{
    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "streamed transform: NULL argument");
    WVOL_RETURN_IF(s->failed, err, WVOL_ERR_ARG, "streamed transform: an earlier step failed");
    WVOL_RETURN_IF(s->pushed != s->n[2], err, WVOL_ERR_ARG, "streamed transform: %zu of %zu slices given",
                   s->pushed, s->n[2]);
    WVOL_RETURN_IF(s->finished, err, WVOL_ERR_ARG, "streamed transform: finished twice");
    for (size_t z = s->n[2]; z < s->p[2]; z++) {
        wvol_status st = take(s, NULL, z, 1, err); /* edge padding along z: the last slice again */
        if (st) {
            s->failed = 1;
            return st;
        }
    }
    s->finished = 1;
    return WVOL_OK;
}

wvol_status wvol_dwt3_source_hooked(wvol_source *src, const wvol_filter *f, int levels, wvol_dwt3_rows_fn fn,
                                    wvol_dwt3_place_fn place, wvol_dwt3_piece_fn piece, void *user, size_t *bytes,
                                    wvol_error *err)
{
    wvol_dwt3_stream *s;
    size_t dims[3], S, slice;
    float *buf;
    wvol_status st = WVOL_OK;
    WVOL_RETURN_IF(!src, err, WVOL_ERR_ARG, "streamed transform: no source");
    wvol_source_geometry(src, dims, NULL, NULL);
    WVOL_FORWARD(wvol_dwt3_stream_create(&s, f, levels, dims[0], dims[1], dims[2], fn, user, err));
    s->place = place;
    s->piece = piece;
    slice = dims[0] * dims[1];
    /* slabs of about 4 MiB (at least a batch of slices when a slice is smaller): the slab
     * is fresh memory for each pass, and a larger one made the reads no faster */
    S = ((size_t)4 << 20) / (slice * sizeof(float));
    S = S < s->batch ? s->batch : S > dims[2] ? dims[2] : S;
    if (S > dims[2]) S = dims[2];
    buf = wvol__reuse_get(S * slice * sizeof(float));
    if (!buf) {
        wvol_dwt3_stream_destroy(s);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "streamed transform: no memory for a slab of %zu slices", S);
    }
    for (size_t z0 = 0; z0 < dims[2] && !st; z0 += S) {
        size_t nz = dims[2] - z0 < S ? dims[2] - z0 : S;
        st = wvol_source_read(src, buf, z0, nz, err);
        if (!st) st = wvol_dwt3_stream_push(s, buf, nz, err);
    }
    if (!st) st = wvol_dwt3_stream_finish(s, err);
    if (bytes) *bytes = wvol_dwt3_stream_bytes(s) + S * slice * sizeof(float);
    wvol__reuse_put(buf);
    wvol_dwt3_stream_destroy(s);
    return st;
}

wvol_status wvol_dwt3_source(wvol_source *src, const wvol_filter *f, int levels, wvol_dwt3_rows_fn fn, void *user,
                             size_t *bytes, wvol_error *err)
{
    return wvol_dwt3_source_hooked(src, f, levels, fn, NULL, NULL, user, bytes, err);
}

void wvol_coeffs_put_rows(wvol_coeffs *c, int level, size_t r, const float *low, const float *high)
{
    size_t cx, cy, cz, hx, hy, px, py;
    if (!c || !c->data || level < 1 || level > c->levels || !low) return;
    px = c->px, py = c->py;
    cx = wvol__extent(px, level - 1), cy = wvol__extent(py, level - 1), cz = wvol__extent(c->pz, level - 1);
    hx = cx > 1 ? cx / 2 : 1, hy = cy > 1 ? cy / 2 : 1;
    if (r >= (cz > 1 ? cz / 2 : 1)) return; /* no such row at this level */
    for (int half = 0; half < 2; half++) {
        const float *src = half ? high : low;
        size_t z = half ? cz / 2 + r : r;
        if (!src) continue;
        for (size_t y = 0; y < cy; y++) {
            float *dst = c->data + px * (y + py * z);
            const float *row = src + y * cx;
            /* the low-low quadrant of a z-low row below the coarsest level is the next
             * level's input, not a coefficient */
            size_t x0 = !half && level < c->levels && y < hy ? hx : 0;
            memcpy(dst + x0, row + x0, (cx - x0) * sizeof(float));
        }
    }
}
