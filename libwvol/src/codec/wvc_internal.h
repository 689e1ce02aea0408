/* SPDX-License-Identifier: MIT
 * Shared between the .wvc files: the Mallat layout of sections, the band coders,
 * byte order helpers. Not installed. */
#ifndef WVOL_CODEC_WVC_INTERNAL_H
#define WVOL_CODEC_WVC_INTERNAL_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "core/clones.h"
#include "core/status_internal.h"
#include "wvol/wvc.h"

/* One section = one sub-band (or the low-pass cube) in the padded grid. */
typedef struct wvc_band {
    int level, band;
    size_t off[3], ext[3];   /* position and extent in the padded grid */
    int has_parent;          /* level < levels and band != 0 */
    size_t poff[3], pext[3]; /* the parent band (level + 1, same band) */
    uint64_t count;
    /* the parent region in a block of its own when pq is set (its origin, strides psy, psz): a
     * chunk coded where its rows lie, the parent's rows in another level's block; else at poff
     * on the band's own grid */
    const int32_t *pq;
    size_t psy, psz;
} wvc_band;

typedef struct wvc_layout {
    int levels;
    size_t p[3];
    int nsec;
    wvc_band sec[WVOL_WVC_MAX_SECTIONS];
} wvc_layout;

/* Fills the layout; sections in file order: low-pass cube, then level = levels..1,
 * bands 1..7. An axis of padded size 1 is not transformed: bands with a high-pass
 * along it are empty. */
void wvol__wvc_layout(wvc_layout *L, size_t px, size_t py, size_t pz, int levels);


/* The fixed header's fields both versions share (offsets 0..207, docs/wvc-format.md);
 * wvol__wvc_header_put writes them (version 2 adds its own after). */
typedef struct wvc_header_fields {
    int version;
    uint32_t nsec;
    const char *filter;
    int levels;
    size_t n[3], p[3];
    double spacing[3], origin[3];
    double value_min, value_max, step, rounding, sse, energy, dropped_energy;
    uint64_t nonzero, payload;
} wvc_header_fields;
void wvol__wvc_header_put(uint8_t *h, const wvc_header_fields *f);

/* Largest |q| the coders accept, so that sums and reconstructions stay finite. */
#define WVC_QMAX (1 << 30)

/* Magnitude histograms (wvc_hist.c): H holds nsec x WVC_HBINS counts of |c| per
 * logarithmic bin. wvol__wvc_hist fills them in one pass and reports max |c| and
 * whether any coefficient is NaN or Inf; returns 0 or -1 (memory). From them an
 * estimator (prepare: NULL when out of memory) predicts the quantiser's squared
 * error for any step (f: the detail bands' rounding offset), and hist_step finds the
 * largest step in [lo, hi] whose predicted error stays within target. */
#define WVC_HBINS 8192
typedef struct wvc_hist_est wvc_hist_est;
int wvol__wvc_hist(uint64_t *H, const wvc_layout *L, const float *C, double *maxabs, int *nonfinite);
/* One section's counts (H: WVC_HBINS) of ex x ey values at rows of stride sy; *maxbits:
 * the running max of |c|'s float32 bits (>= 0x7F800000: NaN or Inf seen). */
void wvol__wvc_slice_hist(uint64_t *H, const float *row0, size_t ex, size_t ey, size_t sy, uint32_t *maxbits);
wvc_hist_est *wvol__wvc_hist_prepare(const uint64_t *H, const wvc_layout *L);
double wvol__wvc_hist_error(const wvc_hist_est *e, const wvc_layout *L, double step, double f);
double wvol__wvc_hist_step(const wvc_hist_est *e, const wvc_layout *L, double target, double f, double lo,
                           double hi);
void wvol__wvc_hist_free(wvc_hist_est *e);

/* Band coders over the global quantised array Q (padded grid, x fastest).
 * encode: appends the CABAC payload to *buf (heap, caller frees); returns 0 or -1 (memory).
 * decode: writes the band into Q; returns 0, or -1 if the payload is malformed. */
int wvol__wvc_cabac_encode(uint8_t **buf, size_t *size, const int32_t *Q, const size_t p[3],
                           const wvc_band *b);
int wvol__wvc_cabac_decode(int32_t *Q, const size_t p[3], const wvc_band *b, const uint8_t *buf,
                           size_t size, const char **why);
/* n bands in one CABAC stream with one model (version-2 chunks). blocks = 1 adds a
 * flag per 4x4x4 block of a detail band before its group flags (chunk mode 2; 0: mode 1,
 * as version 1's band coder). The decoder adds nothing to Q's zeros (Q must be zero over
 * the bands) and, when nonzero is not NULL, stores there how many non-zero values it
 * wrote over all n bands. */
int wvol__wvc_cabac_encode_multi(uint8_t **buf, size_t *size, int n, int32_t *const Q[], const size_t *const p[],
                                 const wvc_band *const b[], int blocks);
int wvol__wvc_cabac_decode_multi(int n, int32_t *const Q[], const size_t *const p[], const wvc_band *const b[],
                                 const uint8_t *buf, size_t size, int blocks, uint64_t *nonzero, const char **why);
/* The zstd coder's working buffers: its compression context and symbol buffer (10 bytes
 * per coefficient), kept by a caller that codes chunk after chunk (a fresh context per call
 * allocates and clears its tables, and the trial runs beside most CABAC chunks); released
 * with wvol__wvc_zstd_scratch_free. */
typedef struct wvc_zstd_scratch {
    void *cctx;
    uint8_t *sym;
    size_t cap;
} wvc_zstd_scratch;
void wvol__wvc_zstd_scratch_free(wvc_zstd_scratch *z);
/* The rANS encoder's working buffers (symbols, contexts, streams: about 12 bytes per
 * coefficient), kept by a caller that codes chunk after chunk on one thread: a fresh
 * allocation per chunk paid its first page touches again every time, about as much as
 * the coding. Zero-initialised when new; released with wvol__wvc_rans_scratch_free. */
typedef struct wvc_rans_scratch {
    void *p[5];
    size_t cap[5];
    wvc_zstd_scratch zstd; /* the chunk coder's zstd trial, on the same thread (freed with s) */
    void *rans4;           /* mode 4's encoder (wvc_rans4_enc.c; freed with s) */
} wvc_rans_scratch;
void wvol__wvc_rans_scratch_free(wvc_rans_scratch *s);
/* Chunk mode 3 (wvc_rans.c): n detail bands in one static-model rANS stream and a raw
 * bit stream; same conventions as the _multi CABAC coder (the decoder writes only
 * non-zeros into Q, which must be zero over the bands, and counts them); s: the
 * encoder's buffers, kept for the next call (NULL: allocated and freed in the call). */
int wvol__wvc_rans_encode(uint8_t **buf, size_t *size, int n, int32_t *const Q[], const size_t *const p[],
                          const wvc_band *const b[], wvc_rans_scratch *s);
int wvol__wvc_rans_decode(int n, int32_t *const Q[], const size_t *const p[], const wvc_band *const b[],
                          const uint8_t *buf, size_t size, uint64_t *nonzero, const char **why);
/* Chunk mode 4 (wvc_rans4_enc.c, wvc_rans4_dec.c): n detail bands of one extent in one
 * stream of 24 interleaved rANS states and a raw bit stream, with contexts from the rows coded
 * before only (docs/wvc-format.md); same conventions as mode 3. The payload starts with a
 * flags byte (bit 0: signs modelled, else raw; bit 1: tables packed, else LEB128); _encode
 * chooses the signs per chunk and packs the tables (wvc_rans4_enc.c), _encode_stream codes the
 * stream after that byte as o says. */
typedef struct wvc_rans4_opts {
    int raw_signs;     /* 1: signs as raw bits; 0: binary rANS, band x sign(N) x sign(U) x sign(N(x-1)) */
    int packed_tables; /* 1: the tables packed (flags bit 1); 0: LEB128 entries, as files before it */
    int scalar;        /* 1: the scalar encoder whatever the CPU (the same bytes, for the tests) */
} wvc_rans4_opts;
/* lead: bytes left before the flags byte for the caller (its mode byte, say); s: the thread's
 * buffers, kept for the next call (NULL: allocated and freed in the call). */
int wvol__wvc_rans4_encode(uint8_t **buf, size_t *size, size_t lead, int n, int32_t *const Q[],
                           const size_t *const p[], const wvc_band *const b[], wvc_rans_scratch *s);
void wvol__wvc_rans4_scratch_free(void *p); /* wvc_rans_scratch.rans4 */
int wvol__wvc_rans4_encode_stream(uint8_t **buf, size_t *size, int n, int32_t *const Q[], const size_t *const p[],
                                  const wvc_band *const b[], const wvc_rans4_opts *o);
/* engine: WVC_RANS4_AUTO the AVX2 engine where the CPU has it (and the extent allows), else
 * the scalar decoder; WVC_RANS4_SCALAR the scalar decoder (the same result, for the tests) */
enum { WVC_RANS4_AUTO = 0, WVC_RANS4_SCALAR = 1 };
int wvol__wvc_rans4_decode(int n, int32_t *const Q[], const size_t *const p[], const wvc_band *const b[],
                           const uint8_t *buf, size_t size, int engine, uint64_t *nonzero, const char **why);
/* z: buffers kept for the next call (NULL: allocated and freed in the call); the same bytes. */
int wvol__wvc_zstd_encode(uint8_t **buf, size_t *size, const int32_t *Q, const size_t p[3],
                          const wvc_band *b, int level, wvc_zstd_scratch *z);
int wvol__wvc_zstd_decode(int32_t *Q, const size_t p[3], const wvc_band *b, const uint8_t *buf,
                          size_t size, const char **why);

/* Low-pass cube symbols: residuals of the 3D Lorenzo predictor on q. */
static inline int64_t wvc_lorenzo(const int32_t *Q, const size_t p[3], const wvc_band *b, size_t x,
                                  size_t y, size_t z)
{
    const size_t sy = p[0], sz = p[0] * p[1];
    const int32_t *c = Q + (b->off[0] + x) + sy * (b->off[1] + y) + sz * (b->off[2] + z);
    int64_t a = x ? c[-1] : 0, bb = y ? c[-(ptrdiff_t)sy] : 0, cc = z ? c[-(ptrdiff_t)sz] : 0;
    int64_t ab = (x && y) ? c[-1 - (ptrdiff_t)sy] : 0, ac = (x && z) ? c[-1 - (ptrdiff_t)sz] : 0;
    int64_t bc = (y && z) ? c[-(ptrdiff_t)sy - (ptrdiff_t)sz] : 0;
    int64_t abc = (x && y && z) ? c[-1 - (ptrdiff_t)sy - (ptrdiff_t)sz] : 0;
    return a + bb + cc - ab - ac - bc + abc;
}

static inline size_t wvc_index(const size_t p[3], const wvc_band *b, size_t x, size_t y, size_t z)
{
    return (b->off[0] + x) + p[0] * ((b->off[1] + y) + p[1] * (b->off[2] + z));
}

/* Little-endian field access. */
/* Whether the eight int32 values at q are all zero: four scalar loads (a copy into an
 * array goes through the stack, and the reloads wait on the store). */
static inline int wvc_zero8(const void *q)
{
    const unsigned char *c = q;
    uint64_t w0, w1, w2, w3;
    memcpy(&w0, c, 8);
    memcpy(&w1, c + 8, 8);
    memcpy(&w2, c + 16, 8);
    memcpy(&w3, c + 24, 8);
    return !(w0 | w1 | w2 | w3);
}

static inline void wvc_put_u16(uint8_t *d, uint16_t v) { d[0] = (uint8_t)v; d[1] = (uint8_t)(v >> 8); }
static inline void wvc_put_u32(uint8_t *d, uint32_t v)
{
    for (int i = 0; i < 4; i++) d[i] = (uint8_t)(v >> (8 * i));
}
static inline void wvc_put_u64(uint8_t *d, uint64_t v)
{
    for (int i = 0; i < 8; i++) d[i] = (uint8_t)(v >> (8 * i));
}
static inline void wvc_put_f64(uint8_t *d, double v)
{
    uint64_t u;
    memcpy(&u, &v, 8);
    wvc_put_u64(d, u);
}
static inline void wvc_put_f32(uint8_t *d, float v)
{
    uint32_t u;
    memcpy(&u, &v, 4);
    wvc_put_u32(d, u);
}
static inline uint16_t wvc_get_u16(const uint8_t *d) { return (uint16_t)(d[0] | (d[1] << 8)); }
static inline uint32_t wvc_get_u32(const uint8_t *d)
{
    uint32_t v = 0;
    for (int i = 3; i >= 0; i--) v = (v << 8) | d[i];
    return v;
}
static inline uint64_t wvc_get_u64(const uint8_t *d)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--) v = (v << 8) | d[i];
    return v;
}
static inline double wvc_get_f64(const uint8_t *d)
{
    uint64_t u = wvc_get_u64(d);
    double v;
    memcpy(&v, &u, 8);
    return v;
}
static inline float wvc_get_f32(const uint8_t *d)
{
    uint32_t u = wvc_get_u32(d);
    float v;
    memcpy(&v, &u, 4);
    return v;
}

#endif
