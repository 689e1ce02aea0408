/* SPDX-License-Identifier: MIT
 * .wvc reader: header and section table checks, per-section CRC-32, decoding
 * coarse to fine with an optional early stop, dequantisation, files.
 * Every field is checked before it is used; the coders check every byte they
 * read (docs/wvc-format.md lists the checks). */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zlib.h>

#include "core/file_open.h"
#include "core/alloc.h"
#include "core/clones.h"
#include "wvc2_internal.h"
#include "wvc2_read.h"
#include "wvc_dequant.h"
#include "wvc_format.h"
#include "wvc_internal.h"
#include "wvol/io.h"

void wvol_wvc_read_options_default(wvol_wvc_read_options *o)
{
    if (!o) return;
    memset(o, 0, sizeof *o);
}

static int finite_nonneg(double v) { return isfinite(v) && v >= 0; }

/* Checks header + table in buf[0..avail) for a file of file_size bytes. */
static wvol_status parse(wvol_wvc_info *I, const uint8_t *h, size_t avail, uint64_t file_size,
                         uint64_t max_voxels, wvol_error *err)
{
    uint32_t nsec;
    uint64_t hbytes, payload = 0, off, nonzero = 0, dims[6];
    int levels, a, s, maxlev;
    const wvol_filter *f;
    wvc_layout L;
    size_t nbytes;
    memset(I, 0, sizeof *I);
    WVOL_RETURN_IF(avail < 16 || file_size < 16, err, WVOL_ERR_FORMAT,
                   "not a .wvc file: %llu bytes is too short for a header", (unsigned long long)file_size);
    WVOL_RETURN_IF(memcmp(h, WVC_MAGIC, 8) != 0, err, WVOL_ERR_FORMAT,
                   "not a .wvc file (wrong magic bytes)");
    I->version = wvc_get_u16(h + 8);
    WVOL_RETURN_IF(I->version > WVOL_WVC_FORMAT_VERSION, err, WVOL_ERR_UNSUPPORTED,
                   ".wvc format version %d is newer than this reader (version %d): update libwvol",
                   I->version, WVOL_WVC_FORMAT_VERSION);
    WVOL_RETURN_IF(I->version < 1, err, WVOL_ERR_FORMAT, ".wvc format version %d is not valid", I->version);
    WVOL_RETURN_IF(wvc_get_u16(h + 10) != 0, err, WVOL_ERR_UNSUPPORTED,
                   ".wvc header flags 0x%x are not known to this reader", wvc_get_u16(h + 10));
    nsec = wvc_get_u32(h + 12);
    WVOL_RETURN_IF(nsec > WVOL_WVC_MAX_SECTIONS, err, WVOL_ERR_FORMAT,
                   ".wvc header: %u sections is more than %d levels allow", nsec, WVOL_WVC_MAX_LEVELS);
    if (I->version == 1) {
        hbytes = WVC_HEADER_SIZE + (uint64_t)nsec * WVC_SECTION_SIZE + 4;
    } else {
        WVOL_RETURN_IF(avail < WVC2_HEADER_SIZE || file_size < WVC2_HEADER_SIZE, err, WVOL_ERR_FORMAT,
                       ".wvc file truncated: %llu bytes is too short for a version-2 header",
                       (unsigned long long)(file_size < avail ? file_size : avail));
        hbytes = wvol__wvc2_prefix_bytes(h, avail);
        WVOL_RETURN_IF(hbytes == 0, err, WVOL_ERR_FORMAT, ".wvc header: section or chunk count is not valid");
    }
    WVOL_RETURN_IF(file_size < hbytes || avail < hbytes, err, WVOL_ERR_FORMAT,
                   ".wvc file truncated: %llu bytes, the header alone needs %llu",
                   /* the file's size when that is short; else what the caller read of it */
                   (unsigned long long)(file_size < hbytes ? file_size : avail), (unsigned long long)hbytes);
    WVOL_RETURN_IF(wvc_get_u32(h + hbytes - 4) != (uint32_t)crc32(0L, h, (uInt)(hbytes - 4)), err,
                   WVOL_ERR_FORMAT, I->version == 1 ? ".wvc header checksum mismatch: the file is corrupt"
                                                    : ".wvc header or index checksum mismatch: the file is corrupt");
    /* from here on the header is what a writer wrote, but still check every field:
     * a crafted file can carry a valid checksum */
    WVOL_RETURN_IF(memchr(h + 16, 0, 16) == NULL, err, WVOL_ERR_FORMAT, ".wvc header: filter name unterminated");
    memcpy(I->filter, h + 16, 16);
    {
        wvol_error e2;
        WVOL_RETURN_IF(wvol_filter_get(&f, I->filter, &e2) != WVOL_OK, err, WVOL_ERR_UNSUPPORTED,
                       ".wvc header: unknown wavelet '%s'", I->filter);
    }
    levels = h[32];
    WVOL_RETURN_IF((I->version == 1 && (h[33] || h[34])) || h[35] || wvc_get_u32(h + 36), err, WVOL_ERR_FORMAT,
                   ".wvc header: reserved bytes are not zero");
    WVOL_RETURN_IF(levels < 1 || levels > WVOL_WVC_MAX_LEVELS, err, WVOL_ERR_FORMAT,
                   ".wvc header: %d levels outside 1..%d", levels, WVOL_WVC_MAX_LEVELS);
    WVOL_RETURN_IF(nsec != (uint32_t)(1 + 7 * levels), err, WVOL_ERR_FORMAT,
                   ".wvc header: %u sections for %d levels (expected %d)", nsec, levels, 1 + 7 * levels);
    for (a = 0; a < 6; a++) dims[a] = wvc_get_u64(h + 40 + 8 * a);
    for (a = 0; a < 3; a++) {
        uint64_t n = dims[a], p = dims[3 + a];
        WVOL_RETURN_IF(n < 1 || n > ((uint64_t)1 << 40) || p < n || p > n + ((uint64_t)1 << levels), err,
                       WVOL_ERR_DIMS, ".wvc header: size %llu padded to %llu is not valid",
                       (unsigned long long)n, (unsigned long long)p);
        WVOL_RETURN_IF((n == 1) != (p == 1) || (p > 1 && (p & (((uint64_t)1 << levels) - 1))), err,
                       WVOL_ERR_DIMS, ".wvc header: padded size %llu is not a multiple of 2^%d",
                       (unsigned long long)p, levels);
    }
    WVOL_RETURN_IF(!wvol_size_mul3((size_t)dims[3], (size_t)dims[4], (size_t)dims[5], sizeof(float), &nbytes),
                   err, WVOL_ERR_DIMS, ".wvc header: %llux%llux%llu overflows",
                   (unsigned long long)dims[3], (unsigned long long)dims[4], (unsigned long long)dims[5]);
    WVOL_RETURN_IF(nbytes / sizeof(float) > (max_voxels ? max_voxels : WVC_DEFAULT_MAX_VOXELS), err,
                   WVOL_ERR_DIMS, ".wvc header: %llux%llux%llu is larger than the reader's limit",
                   (unsigned long long)dims[3], (unsigned long long)dims[4], (unsigned long long)dims[5]);
    maxlev = wvol_dwt_max_levels((size_t)dims[0], (size_t)dims[1], (size_t)dims[2]);
    WVOL_RETURN_IF(levels > maxlev, err, WVOL_ERR_DIMS,
                   ".wvc header: %d levels is more than a %llux%llux%llu volume allows (%d)", levels,
                   (unsigned long long)dims[0], (unsigned long long)dims[1], (unsigned long long)dims[2],
                   maxlev);
    I->levels = levels;
    I->nx = (size_t)dims[0];
    I->ny = (size_t)dims[1];
    I->nz = (size_t)dims[2];
    I->px = (size_t)dims[3];
    I->py = (size_t)dims[4];
    I->pz = (size_t)dims[5];
    for (a = 0; a < 3; a++) {
        I->spacing[a] = wvc_get_f64(h + 88 + 8 * a);
        I->origin[a] = wvc_get_f64(h + 112 + 8 * a);
        WVOL_RETURN_IF(!(isfinite(I->spacing[a]) && I->spacing[a] > 0) || !isfinite(I->origin[a]), err,
                       WVOL_ERR_FORMAT, ".wvc header: spacing or origin is not valid");
    }
    I->value_min = wvc_get_f64(h + 136);
    I->value_max = wvc_get_f64(h + 144);
    I->step = wvc_get_f64(h + 152);
    I->rounding = wvc_get_f64(h + 160);
    I->sse = wvc_get_f64(h + 168);
    I->energy = wvc_get_f64(h + 176);
    I->dropped_energy = wvc_get_f64(h + 184);
    I->nonzero = wvc_get_u64(h + 192);
    payload = wvc_get_u64(h + 200);
    WVOL_RETURN_IF(!isfinite(I->value_min) || !isfinite(I->value_max) || I->value_min > I->value_max, err,
                   WVOL_ERR_FORMAT, ".wvc header: value range is not valid");
    WVOL_RETURN_IF(!(I->step >= WVC_MIN_STEP && I->step <= WVC_MAX_STEP), err, WVOL_ERR_FORMAT,
                   ".wvc header: quantiser step %g is not valid", I->step);
    WVOL_RETURN_IF(!(I->rounding >= 0 && I->rounding <= 0.5) || !finite_nonneg(I->sse) ||
                       !finite_nonneg(I->energy) || !finite_nonneg(I->dropped_energy),
                   err, WVOL_ERR_FORMAT, ".wvc header: quantiser or error fields are not valid");
    if (I->version == 2) return wvol__wvc2_parse(I, NULL, h, avail, file_size, err);
    WVOL_RETURN_IF(payload > file_size || hbytes + payload != file_size, err, WVOL_ERR_FORMAT,
                   ".wvc file is %llu bytes but its header declares %llu: truncated or extended",
                   (unsigned long long)file_size, (unsigned long long)(hbytes + payload));
    wvol__wvc_layout(&L, I->px, I->py, I->pz, levels);
    off = hbytes;
    I->nsections = (int)nsec;
    for (s = 0; s < (int)nsec; s++) {
        const uint8_t *e = h + WVC_HEADER_SIZE + (size_t)s * WVC_SECTION_SIZE;
        wvol_wvc_section *S = &I->sections[s];
        S->level = e[0];
        S->band = e[1];
        S->coder = e[2];
        S->crc = wvc_get_u32(e + 4);
        S->bytes = wvc_get_u64(e + 8);
        S->nonzero = wvc_get_u64(e + 16);
        S->delta1 = wvc_get_f32(e + 24);
        S->delta2 = wvc_get_f32(e + 28);
        S->energy = wvc_get_f64(e + 32);
        S->error = wvc_get_f64(e + 40);
        S->count = L.sec[s].count;
        WVOL_RETURN_IF(S->level != L.sec[s].level || S->band != L.sec[s].band || e[3], err, WVOL_ERR_FORMAT,
                       ".wvc section table: entry %d is level %d band %d, expected level %d band %d", s,
                       S->level, S->band, L.sec[s].level, L.sec[s].band);
        WVOL_RETURN_IF(S->coder > WVOL_WVC_CODER_ZSTD, err, WVOL_ERR_UNSUPPORTED,
                       ".wvc section level %d band %d: unknown coder %d", S->level, S->band, S->coder);
        WVOL_RETURN_IF((S->coder == WVOL_WVC_CODER_EMPTY) != (S->bytes == 0) ||
                           (S->coder == WVOL_WVC_CODER_EMPTY) != (S->nonzero == 0) ||
                           S->nonzero > S->count || S->bytes > file_size - off,
                       err, WVOL_ERR_FORMAT, ".wvc section level %d band %d: sizes are not consistent",
                       S->level, S->band);
        WVOL_RETURN_IF(!(fabsf(S->delta1) <= 1.0f) || !(fabsf(S->delta2) <= 1.0f) ||
                           !finite_nonneg(S->energy) || !finite_nonneg(S->error),
                       err, WVOL_ERR_FORMAT, ".wvc section level %d band %d: fields are not valid",
                       S->level, S->band);
        S->offset = off;
        off += S->bytes;
        nonzero += S->nonzero;
    }
    WVOL_RETURN_IF(off != file_size || nonzero != I->nonzero, err, WVOL_ERR_FORMAT,
                   ".wvc section table does not add up to the header's totals");
    I->file_bytes = file_size;
    I->header_bytes = hbytes;
    return WVOL_OK;
}

wvol_status wvol__wvc_parse_prefix(wvol_wvc_info *I, const uint8_t *h, size_t avail, uint64_t file_size,
                                   wvol_error *err)
{
    return parse(I, h, avail, file_size, 0, err);
}

wvol_status wvol_wvc_parse_info(wvol_wvc_info *info, const void *buf, size_t size, wvol_error *err)
{
    WVOL_RETURN_IF(!info || (!buf && size), err, WVOL_ERR_ARG, "wvc: missing argument");
    return parse(info, buf, size, size, 0, err);
}

static wvol_status coeffs_new(wvol_coeffs **out, const wvol_wvc_info *I, wvol_error *err)
{
    const wvol_filter *f;
    WVOL_FORWARD(wvol_filter_get(&f, I->filter, err));
    WVOL_FORWARD(wvol_coeffs_create(out, f, I->levels, I->nx, I->ny, I->nz, err));
    if ((*out)->px != I->px || (*out)->py != I->py || (*out)->pz != I->pz) {
        wvol_coeffs_destroy(*out);
        *out = NULL;
        return wvol_error_set(err, WVOL_ERR_DIMS, ".wvc header: padded size does not match the transform's");
    }
    memcpy((*out)->spacing, I->spacing, sizeof I->spacing);
    memcpy((*out)->origin, I->origin, sizeof I->origin);
    return WVOL_OK;
}

/* Dequantises in place the w <= 8 int32 values the coder stored at o: sign(q) (|q| +
 * delta) step in double, rounded once to float (|q| = 1 takes o1 = (1 + delta1) step).
 * Explicit vectors (GCC left the scalar loop scalar), the same operations in the same
 * order as one value at a time, so the result is bit for bit that of the scalar form.
 * Returns how many were non-zero and counts in *over the values beyond float32 (a
 * crafted file's step), which become 0 and fail the decode. */
typedef int32_t deq_i8 __attribute__((vector_size(32)));
typedef int64_t deq_l4 __attribute__((vector_size(32)));
typedef double deq_d4 __attribute__((vector_size(32)));
typedef float deq_f4 __attribute__((vector_size(16)));
typedef int32_t deq_i4 __attribute__((vector_size(16)));

static inline __attribute__((always_inline)) deq_i4 dequant4(deq_i4 q, double o1, double d2, double step,
                                                             deq_i4 *nzc, deq_i4 *ovc)
{
    deq_i4 m = q >> 31, a = (q ^ m) - m; /* |q| (bounded by the coder, never INT32_MIN) */
    deq_d4 ad = __builtin_convertvector(a, deq_d4);
    deq_d4 d = (ad + d2) * step, o1v = {o1, o1, o1, o1};
    deq_l4 one = ad == 1.0, zero = ad == 0.0, big;
    deq_l4 bits = ((deq_l4)d & ~one) | ((deq_l4)o1v & one);
    deq_f4 f;
    big = ~((deq_d4)bits <= (double)FLT_MAX); /* NaN too */
    bits &= ~(big | zero);
    f = __builtin_convertvector((deq_d4)bits, deq_f4);
    *nzc -= __builtin_convertvector(~zero, deq_i4);
    *ovc -= __builtin_convertvector(big & ~zero, deq_i4);
    return (deq_i4)f | (q & (int32_t)0x80000000); /* f >= 0: the sign of q, -0.0f as the scalar form */
}

static inline __attribute__((always_inline)) uint64_t dequant8(float *o, size_t w, double o1, double d2, double step,
                                                               uint64_t *over)
{
    deq_i4 q0, q1, nzc = {0, 0, 0, 0}, ovc = {0, 0, 0, 0};
    int32_t q[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    memcpy(q, o, w * sizeof(float));
    memcpy(&q0, q, sizeof q0);
    memcpy(&q1, q + 4, sizeof q1);
    q0 = dequant4(q0, o1, d2, step, &nzc, &ovc);
    q1 = dequant4(q1, o1, d2, step, &nzc, &ovc);
    memcpy(q, &q0, sizeof q0);
    memcpy(q + 4, &q1, sizeof q1);
    memcpy(o, q, w * sizeof(float));
    *over += (uint64_t)(ovc[0] + ovc[1] + ovc[2] + ovc[3]);
    return (uint64_t)(nzc[0] + nzc[1] + nzc[2] + nzc[3]);
}

/* One row of n values: groups of eight zeros (0.0f already) skipped in one test. Where
 * the section's constants allow (wvc_dequant_fits, every valid file) the shared unchecked
 * form, which gives the same bits with a third of the operations; else every value is
 * checked against float32's range. */
WVOL__CLONES static uint64_t dequant_row(float *o, size_t n, double o1, double d2, double step, uint64_t *over)
{
    uint64_t nz = 0;
    size_t x = 0;
    if (wvc_dequant_fits(o1, d2, step)) {
        const float f1 = (float)o1;
        wvc_dq_i8 nzv = {0, 0, 0, 0, 0, 0, 0, 0};
        for (; x + 8 <= n; x += 8) {
            if (!wvc_zero8(o + x)) wvc_dequant8(o + x, o + x, f1, d2, step, &nzv); /* most are zero at low rates */
        }
        for (int k = 0; k < 8; k++) nz += (uint64_t)(uint32_t)nzv[k];
        for (; x < n; x++) {
            int32_t v;
            memcpy(&v, o + x, sizeof v);
            nz += v != 0;
            o[x] = wvc_dequant1(v, f1, d2, step);
        }
        return nz;
    }
    for (; x + 8 <= n; x += 8)
        if (!wvc_zero8(o + x)) nz += dequant8(o + x, 8, o1, d2, step, over);
    if (x < n) nz += dequant8(o + x, n - x, o1, d2, step, over);
    return nz;
}

/* The dequantisation constants of section s (in double, rounded once: the only error
 * left beyond the quantiser's is half an ulp). */
static void section_constants(const wvol_wvc_info *I, int s, double *step, double *o1, double *d2)
{
    *step = I->step;
    *o1 = (1.0 + (double)I->sections[s].delta1) * I->step;
    *d2 = I->sections[s].delta2;
}

/* A version-2 file's finest decoded level, dequantised chunk by chunk as the chunks are
 * decoded (wvc2_tile_done_fn): that level holds seven eighths of the coefficients, and a
 * separate pass would read and write them again from memory. Per section the non-zero
 * and out-of-range counts, which the section pass then checks as its own. */
typedef struct tile_dequant {
    const wvol_wvc_info *I;
    const wvc_layout *L;
    float *data;
    uint64_t *nz, *over; /* per section */
} tile_dequant;

static void dequant_tile(void *ctx, int level, const size_t off[3], const size_t ext[3])
{
    tile_dequant *t = ctx;
    for (int band = level == t->I->levels ? 0 : 1; band < 8; band++) {
        const int s = wvc2_section(t->I->levels, level, band);
        const wvc_band *b = &t->L->sec[s];
        double step, o1, d2;
        uint64_t nz = 0, over = 0;
        if (!b->count || t->I->sections[s].coder == WVOL_WVC_CODER_EMPTY) continue;
        section_constants(t->I, s, &step, &o1, &d2);
        for (size_t z = off[2]; z < off[2] + ext[2]; z++)
            for (size_t y = off[1]; y < off[1] + ext[1]; y++) {
                float *row = t->data + wvc_index(t->L->p, b, off[0], y, z);
                /* a tile's rows are short runs a plane's row apart, too short for the
                 * hardware's prefetch to follow: the row a few ahead is asked for now */
                const size_t ahead = y + 4 < off[1] + ext[1] ? 4 * t->L->p[0] : t->L->p[0] * t->L->p[1];
                for (size_t x = 0; x < ext[0]; x += 16) __builtin_prefetch(row + ahead + x);
                nz += dequant_row(row, ext[0], o1, d2, step, &over);
            }
#pragma omp atomic
        t->nz[s] += nz;
#pragma omp atomic
        t->over[s] += over;
    }
}

/* Decodes the sections of levels > stop_level from buf (the file's first avail bytes).
 * The quantised values are decoded into the output's own buffer (as int32, which
 * has the size of a float and whose zero is 0.0f) and dequantised in place. */
static wvol_status decode(wvol_coeffs **out, const uint8_t *buf, size_t avail, const wvol_wvc_info *I,
                          int stop_level, wvol_error *err)
{
    wvc_layout *L;
    int32_t *Q;
    wvol_coeffs *c = NULL;
    tile_dequant td = {NULL, NULL, NULL, NULL, NULL};
    int s, first, last, bad_sec = -1, fused = 0; /* fused: the level dequantised by dequant_tile */
    const char *why = NULL;
    wvol_status st;

    *out = NULL;
    WVOL_RETURN_IF(stop_level < 0 || stop_level > I->levels, err, WVOL_ERR_ARG,
                   "wvc: stop level %d outside 0..%d", stop_level, I->levels);
    WVOL_FORWARD(coeffs_new(&c, I, err));
    L = malloc(sizeof *L);
    if (!L) {
        wvol_coeffs_destroy(c);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc: out of memory");
    }
    Q = (int32_t *)(void *)c->data;
    wvol__wvc_layout(L, I->px, I->py, I->pz, I->levels);
    if (I->version == 2) {
        wvc2_index *x = NULL;
        wvol_wvc_info tmp = *I;
        td.I = I, td.L = L, td.data = c->data;
        td.nz = calloc((size_t)L->nsec, sizeof *td.nz);
        td.over = calloc((size_t)L->nsec, sizeof *td.over);
        fused = td.nz && td.over && stop_level < I->levels ? stop_level + 1 : 0;
        st = wvol__wvc2_parse(&tmp, &x, buf, avail, I->file_bytes, err);
        if (st == WVOL_OK)
            st = wvol__wvc2_decode_dense(Q, L->p, x, buf, avail, stop_level, fused ? dequant_tile : NULL, &td, err);
        wvol__wvc2_index_free(x);
        if (st != WVOL_OK) {
            free(td.nz);
            free(td.over);
            free(L);
            wvol_coeffs_destroy(c);
            return st;
        }
    }
    /* low-pass cube, then one level at a time; the bands of a level in parallel */
    for (first = 0; first < L->nsec && bad_sec < 0 && I->version == 1; first = last) {
        int lev = L->sec[first].level;
        if (first > 0 && lev <= stop_level) break;
        last = first + (first == 0 ? 1 : 7);
#pragma omp parallel for schedule(dynamic, 1) if (L->sec[last - 1].count > 32768)
        for (s = first; s < last; s++) {
            const wvol_wvc_section *S = &I->sections[s];
            const char *w = NULL;
            int r = 0;
            if (S->coder == WVOL_WVC_CODER_EMPTY) continue;
            if (S->offset + S->bytes > avail) {
                w = "section lies past the end of the data read";
                r = -1;
            } else if ((uint32_t)crc32(0L, buf + S->offset, (uInt)S->bytes) != S->crc) {
                w = "checksum mismatch: the file is corrupt";
                r = -1;
            } else if (S->coder == WVOL_WVC_CODER_CABAC) {
                r = wvol__wvc_cabac_decode(Q, L->p, &L->sec[s], buf + S->offset, (size_t)S->bytes, &w);
            } else {
                r = wvol__wvc_zstd_decode(Q, L->p, &L->sec[s], buf + S->offset, (size_t)S->bytes, &w);
            }
            if (r) {
#pragma omp critical(wvc_decode_error)
                if (bad_sec < 0 || s < bad_sec) {
                    bad_sec = s;
                    why = w;
                }
            }
        }
    }
    /* dequantise in place, sign(q) (|q| + delta) step, counting the non-zeros */
    for (s = 0; s < L->nsec && bad_sec < 0; s++) {
        const wvc_band *b = &L->sec[s];
        const wvol_wvc_section *S = &I->sections[s];
        double step, o1, d2;
        uint64_t nz = 0, over = 0;
        long z;
        if (s > 0 && b->level <= stop_level) break;
        if (S->coder == WVOL_WVC_CODER_EMPTY) continue;
        section_constants(I, s, &step, &o1, &d2);
        if (fused && b->level == fused) {
            nz = td.nz[s], over = td.over[s]; /* dequantised chunk by chunk */
        } else {
#pragma omp parallel for schedule(static) reduction(+ : nz, over) if (b->count > 65536)
            for (z = 0; z < (long)b->ext[2]; z++) {
                size_t y;
                for (y = 0; y < b->ext[1]; y++) {
                    nz += dequant_row(c->data + wvc_index(L->p, b, 0, y, (size_t)z), b->ext[0], o1, d2, step, &over);
                }
            }
        }
        if (over) {
            bad_sec = s;
            why = "dequantised values exceed float32's range (3.4e38)";
        } else if (nz != S->nonzero) {
            bad_sec = s;
            why = "decoded coefficient count does not match the section table";
        }
    }
    free(td.nz);
    free(td.over);
    free(L);
    if (bad_sec >= 0) {
        st = wvol_error_set(err, WVOL_ERR_FORMAT, ".wvc section level %d band %d: %s",
                            I->sections[bad_sec].level, I->sections[bad_sec].band, why ? why : "malformed");
        wvol_coeffs_destroy(c);
        return st;
    }
    *out = c;
    return WVOL_OK;
}

wvol_status wvol_wvc_decode(wvol_coeffs **out, const void *buf, size_t size,
                            const wvol_wvc_read_options *opt, wvol_wvc_info *info, wvol_error *err)
{
    wvol_wvc_info *I;
    wvol_status st;
    WVOL_RETURN_IF(!out || (!buf && size), err, WVOL_ERR_ARG, "wvc: missing argument");
    *out = NULL;
    I = malloc(sizeof *I);
    WVOL_RETURN_IF(!I, err, WVOL_ERR_NOMEM, "wvc: out of memory");
    st = parse(I, buf, size, size, opt ? opt->max_voxels : 0, err);
    if (st == WVOL_OK) st = decode(out, buf, size, I, opt ? opt->stop_level : 0, err);
    if (st == WVOL_OK && info) *info = *I;
    free(I);
    return st;
}

wvol_status wvol_wvc_save(const char *path, const void *buf, size_t size, wvol_error *err)
{
    wvol_atomic_file f;
    /* an empty buffer is no .wvc file: a reader would refuse what this wrote */
    WVOL_RETURN_IF(!buf || size == 0, err, WVOL_ERR_ARG, "wvc save: %s: no encoded bytes to write", path ? path : "(null)");
    WVOL_FORWARD(wvol_atomic_open(&f, path, err));
    if (fwrite(buf, 1, size, f.fp) != size) return wvol_atomic_fail(&f, err);
    return wvol_atomic_commit(&f, err);
}

/* Reads the first `want` bytes (or fewer when the file is shorter) into a new buffer (in
 * huge pages when large: a whole file's 4 KiB pages were most of a decode's page faults). */
static wvol_status read_prefix(uint8_t **buf, size_t *got, FILE *fp, size_t want, const char *path,
                               wvol_error *err)
{
    uint8_t *b = wvol__malloc_large(want ? want : 1);
    (void)path;
    WVOL_RETURN_IF(!b, err, WVOL_ERR_NOMEM, "out of memory");
    *got = fread(b, 1, want, fp);
    if (*got < want && ferror(fp)) {
        free(b);
        return wvol_error_set(err, WVOL_ERR_IO, "read error");
    }
    *buf = b;
    return WVOL_OK;
}

static wvol_status read_file(wvol_coeffs **out, wvol_wvc_info *info, const char *path,
                             const wvol_wvc_read_options *opt, wvol_error *err)
{
    FILE *fp;
    struct stat sb;
    uint8_t *buf = NULL;
    size_t got = 0, want;
    uint64_t fsize;
    wvol_wvc_info *I = NULL;
    wvol_status st;
    int stop = opt ? opt->stop_level : 0, s;

    WVOL_RETURN_IF(!path, err, WVOL_ERR_ARG, "wvc: missing path");
    WVOL_FORWARD(wvol__fopen_regular(&fp, path, err));
    if (fstat(fileno(fp), &sb) != 0) { /* a regular file (wvol__fopen_regular): its size */
        wvol_status s = wvol_error_set(err, WVOL_ERR_IO, "%s: cannot stat: %s", path, strerror(errno));
        fclose(fp);
        return s;
    }
    fsize = (uint64_t)sb.st_size;
    I = malloc(sizeof *I);
    if (!I) {
        fclose(fp);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "wvc: out of memory");
    }
    /* the fixed header says how long the table is */
    want = WVC_HEADER_SIZE + (size_t)WVOL_WVC_MAX_SECTIONS * WVC_SECTION_SIZE + 4;
    if (want > fsize) want = (size_t)fsize;
    st = read_prefix(&buf, &got, fp, want, path, err);
    if (st == WVOL_OK && got >= 10 && wvc_get_u16(buf + 8) == 2) {
        /* version 2: the band table and the chunk index follow the fixed header */
        uint64_t pre = wvol__wvc2_prefix_bytes(buf, got);
        if (pre > got && pre <= fsize && pre <= SIZE_MAX) {
            free(buf);
            buf = NULL;
            if (fseek(fp, 0, SEEK_SET) != 0) st = wvol_error_set(err, WVOL_ERR_IO, "cannot seek");
            else st = read_prefix(&buf, &got, fp, (size_t)pre, path, err);
        }
    }
    if (st == WVOL_OK) st = parse(I, buf, got, fsize, opt ? opt->max_voxels : 0, err);
    if (st == WVOL_OK && !out && I->version == 2) {
        /* info only: every chunk's checksum, one chunk in memory at a time */
        wvc2_index *x = NULL;
        wvol_wvc_info tmp = *I;
        uint8_t *cb = NULL;
        size_t cap = 0;
        st = wvol__wvc2_parse(&tmp, &x, buf, got, fsize, err);
        for (uint64_t id = 0; st == WVOL_OK && id < I->chunks; id++) {
            const wvc2_chunk *ck = &x->chunks[id];
            const char *why = NULL;
            if (!ck->bytes) continue;
            if (ck->bytes > cap) {
                uint8_t *nb = realloc(cb, ck->bytes);
                if (!nb) {
                    st = wvol_error_set(err, WVOL_ERR_NOMEM, "out of memory");
                    break;
                }
                cb = nb, cap = ck->bytes;
            }
            if (fseeko(fp, (off_t)ck->offset, SEEK_SET) != 0 || fread(cb, 1, ck->bytes, fp) != ck->bytes) {
                st = wvol_error_set(err, WVOL_ERR_IO, "read error");
            } else if (wvol__wvc2_chunk_check(x, (size_t)id, cb, &why)) {
                char d[96];
                wvol__wvc2_describe(d, sizeof d, x, (size_t)id);
                st = wvol_error_set(err, WVOL_ERR_FORMAT, ".wvc %s: %s", d, why);
            }
        }
        free(cb);
        wvol__wvc2_index_free(x);
    } else if (st == WVOL_OK && !out) {
        /* info only: check every section's checksum as well (CRC-32 runs at GB/s) */
        free(buf);
        buf = NULL;
        if (fseek(fp, 0, SEEK_SET) != 0 || I->file_bytes > SIZE_MAX) {
            st = wvol_error_set(err, WVOL_ERR_IO, "cannot read");
        } else {
            st = read_prefix(&buf, &got, fp, (size_t)I->file_bytes, "", err);
            if (st == WVOL_OK && got != I->file_bytes)
                st = wvol_error_set(err, WVOL_ERR_FORMAT, "file changed while reading");
            for (s = 0; st == WVOL_OK && s < I->nsections; s++) {
                const wvol_wvc_section *S = &I->sections[s];
                if (S->bytes && (uint32_t)crc32(0L, buf + S->offset, (uInt)S->bytes) != S->crc)
                    st = wvol_error_set(err, WVOL_ERR_FORMAT,
                                        ".wvc section level %d band %d: checksum mismatch: the file is corrupt",
                                        S->level, S->band);
            }
        }
    }
    if (st == WVOL_OK && out) {
        /* sections are stored coarse to fine: what a stop level needs is a prefix */
        uint64_t end = I->header_bytes;
        if (I->version == 1) {
            for (s = 0; s < I->nsections; s++)
                if (s == 0 || I->sections[s].level > stop) end = I->sections[s].offset + I->sections[s].bytes;
        } else {
            /* chunks are stored coarsest level first too */
            wvc2_index *x = NULL;
            wvol_wvc_info tmp = *I;
            st = wvol__wvc2_parse(&tmp, &x, buf, got, fsize, err);
            for (uint64_t id = 0; st == WVOL_OK && id < I->chunks; id++) {
                size_t t[3];
                int m = wvol__wvc2_chunk_coords(&x->g, (size_t)id, t);
                if ((m > stop || m == I->levels) && x->chunks[id].bytes)
                    end = x->chunks[id].offset + x->chunks[id].bytes;
            }
            wvol__wvc2_index_free(x);
        }
        free(buf);
        buf = NULL;
        if (st != WVOL_OK) {
        } else if (stop < 0 || stop > I->levels) {
            st = wvol_error_set(err, WVOL_ERR_ARG, "level %d outside 0..%d", stop, I->levels);
        } else if (fseek(fp, 0, SEEK_SET) != 0) {
            st = wvol_error_set(err, WVOL_ERR_IO, "cannot seek");
        } else if (end > SIZE_MAX) {
            st = wvol_error_set(err, WVOL_ERR_NOMEM, "too large");
        } else {
            st = read_prefix(&buf, &got, fp, (size_t)end, "", err);
            if (st == WVOL_OK && got != end)
                st = wvol_error_set(err, WVOL_ERR_FORMAT, "file changed while reading");
            if (st == WVOL_OK) st = decode(out, buf, got, I, stop, err);
        }
        }
    fclose(fp);
    free(buf);
    if (st == WVOL_OK && info) *info = *I;
    free(I);
    if (st != WVOL_OK) wvol_error_prefix(err, "%s", path);
    return st;
}

wvol_status wvol_wvc_read_info(wvol_wvc_info *info, const char *path, wvol_error *err)
{
    WVOL_RETURN_IF(!info, err, WVOL_ERR_ARG, "wvc: missing argument");
    return read_file(NULL, info, path, NULL, err);
}

wvol_status wvol_wvc_read(wvol_coeffs **out, const char *path, const wvol_wvc_read_options *opt,
                          wvol_wvc_info *info, wvol_error *err)
{
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvc: missing argument");
    *out = NULL;
    return read_file(out, info, path, opt, err);
}
