/* SPDX-License-Identifier: MIT */
/* The automatic filter choice of the compression pipeline (wavelet "auto", wvol/compress.h):
 * a trial on a sample of the volume estimates each candidate filter's bits at the requested
 * target, and db2 is kept unless another filter's estimate is smaller by more than the
 * margin. docs/wvc-format.md, "Choosing the filter", states the rule, the margin and how far
 * the estimate is from real file sizes.
 *
 * The sample: a volume no larger than the sample would be is transformed whole, as the file
 * is. A larger one gives a few CUBE^3 cubes spread through it, read as the cubes' rows where
 * the source can (row bands), else over the cubes' slices in increasing z (a streamed source
 * forward). A cube is transformed periodically, but only the coefficients whose analysis
 * window lies inside the cube are counted: analysis reads forward (a[k] = sum_n h[n]
 * x[2k + n], wvol/wavelet.h), so a level-m coefficient at k reads samples 2^m k ..
 * 2^m k + (2^m - 1)(L - 1), and those are
 * the coefficients the whole volume's transform has at that place. Every candidate is
 * counted on the same positions (those valid for the longest filter), so the estimates
 * compare like with like. Along an axis the cube covers whole, the cube's wrap is the
 * file's, and every position counts.
 *
 * The estimate: for each candidate the quantiser step that meets the target on the sample
 * (its squared error per coefficient equal to the target's per voxel: the filters are
 * orthogonal, so coefficient error is voxel error), then the zeroth-order entropy of the
 * quantised magnitudes per band plus a sign bit per non-zero. The coder's contexts code
 * zeros more cheaply than a zeroth-order model says, so the estimate is an upper bound
 * whose error is largely common to the candidates; the choice needs only their ratio. */
#include "wvol/compress.h"

#include "core/alloc.h"
#include "core/clock.h"
#include "core/clones.h"
#include "core/source_volume.h"
#include "core/status_internal.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define CUBE 64          /* sample cube edge: the longest candidate (coif2, 12 taps) still has
                            valid level-2 coefficients (8 of 16 per axis) */
#define CUBES_MIN 1
#define CUBES_MAX 8
#define CUBE_SHARE 64    /* one cube per 64 cubes' worth of volume, within CUBES_MIN..MAX */
#define SUB_BITS 5
#define SUB (1 << SUB_BITS) /* log-magnitude bins per octave for the error model */
#define EXP_LO (-150)    /* frexp exponents of float32 magnitudes: subnormals to the largest */
#define EXP_HI 130
#define NBINS ((EXP_HI - EXP_LO) * SUB)
_Static_assert(NBINS <= INT16_MAX, "step_for lists the bins as int16_t");
#define QEXACT 64        /* |q| below this: one histogram bin each; above: one per octave */
#define QBINS (QEXACT + 64)
#define DEFAULT_PSNR 50.0 /* the target when the caller gives neither a PSNR nor a step */

static const char *const candidates[WVOL_WAVELET_CHOICE_CANDIDATES] = {"db2", "db4", "coif2", "haar"};

int wvol_compress_wavelet_is_auto(const char *name) { return name && !strcmp(name, WVOL_COMPRESS_WAVELET_AUTO); }

/* One sampled block */
typedef struct sample_block {
    float *data;        /* the samples, e[0] x e[1] x e[2] */
} sample_block;

typedef struct sample {
    size_t dims[3], e[3];
    int whole;          /* the block is the whole volume */
    int levels;         /* levels of the blocks' transforms */
    int nb;             /* blocks */
    sample_block b[CUBES_MAX];
    size_t valid[3][32];/* counted positions per axis and level (band extent when whole) */
    double lo, hi;      /* range of the sampled voxels */
} sample;

static size_t valid_positions(size_t e, size_t n, size_t padded, int m, int taps)
{
    size_t span, ext = padded >> m;
    if (e == 1) return 1;
    if (e == n) return ext; /* the block holds the whole axis: its wrap is the file's */
    span = (((size_t)1 << m) - 1) * (size_t)(taps - 1);
    if (span + 1 > e) return 0;
    /* 2^m k + span <= e - 1 */
    size_t k = (e - 1 - span) / ((size_t)1 << m) + 1;
    return k < ext ? k : ext;
}

/* Cube origins: z evenly spread; x and y from the R2 low-discrepancy sequence, so the cubes
 * do not sit on one diagonal. Deterministic: the same dims give the same cubes. */
static void cube_origin(const sample *s, int i, size_t o[3])
{
    static const double ax = 0.7548776662466927, ay = 0.5698402909980532;
    double fx = fmod(0.5 + (i + 1) * ax, 1.0), fy = fmod(0.5 + (i + 1) * ay, 1.0);
    o[0] = (size_t)(fx * (double)(s->dims[0] - s->e[0]));
    o[1] = (size_t)(fy * (double)(s->dims[1] - s->e[1]));
    o[2] = (s->dims[2] - s->e[2]) * (size_t)(2 * i + 1) / (size_t)(2 * s->nb);
}

/* Reads the cubes' slices in increasing z, in slabs of consecutive needed slices (a
 * generator makes a slab at a cost per call as well as per slice), each slab at most
 * SLAB_BYTES or one slice: a slab of a large volume can be far larger than the sample.
 * A source that reads row bands (a raw file, NRRD raw data, a volume in memory, a generator:
 * core/source_volume.h) gives each cube its own rows instead, a few slices at a time: a
 * 64^3 cube of a 256^3 volume then reads a quarter of the bytes of its slices, of a 2048^3
 * volume a thirty-second. */
#define SLAB_BYTES ((size_t)8 << 20)
#define BAND_BYTES ((size_t)64 << 10)

/* One slice of a cube: e[1] rows of e[0] samples from src (rows nx apart) into dst, their
 * range into s->lo, s->hi. */
static void cube_slice(sample *s, float *dst, const float *src, size_t nx)
{
    for (size_t y = 0; y < s->e[1]; y++) {
        const float *row = src + y * nx;
        memcpy(dst + y * s->e[0], row, s->e[0] * sizeof(float));
        for (size_t x = 0; x < s->e[0]; x++) {
            if (row[x] < s->lo) s->lo = row[x];
            if (row[x] > s->hi) s->hi = row[x];
        }
    }
}

/* The cubes read as row bands, a few slices at a time into one small buffer;
 * WVOL_ERR_UNSUPPORTED (nothing read, no message) when the source has no row bands. */
static wvol_status read_sample_rows(sample *s, wvol_source *src, const size_t o[][3], wvol_error *err)
{
    const size_t nx = s->dims[0], band = nx * s->e[1], slice = s->e[0] * s->e[1];
    size_t step = BAND_BYTES / (band * sizeof(float));
    wvol_status st = WVOL_OK;
    float *buf;
    if (step < 1) step = 1;
    if (step > s->e[2]) step = s->e[2];
    buf = malloc(step * band * sizeof *buf);
    WVOL_RETURN_IF(!buf, err, WVOL_ERR_NOMEM, "compress: wavelet trial: out of memory");
    for (int i = 0; i < s->nb && st == WVOL_OK; i++)
        for (size_t k = 0; k < s->e[2] && st == WVOL_OK; k += step) {
            size_t nz = s->e[2] - k < step ? s->e[2] - k : step;
            st = wvol__source_read_rows(src, buf, o[i][2] + k, nz, o[i][1], s->e[1], err);
            for (size_t j = 0; st == WVOL_OK && j < nz; j++)
                cube_slice(s, s->b[i].data + (k + j) * slice, buf + j * band + o[i][0], nx);
        }
    free(buf);
    return st;
}

static wvol_status read_sample(sample *s, wvol_source *src, wvol_error *err)
{
    size_t o[CUBES_MAX][3], nx = s->dims[0], ny = s->dims[1], z, zlo = SIZE_MAX, zhi = 0, slab_max;
    size_t cube = s->e[0] * s->e[1] * s->e[2];
    float *slab;
    int i;
    wvol_status st;
    for (i = 0; i < s->nb; i++) {
        s->b[i].data = wvol__reuse_get(cube * sizeof(float));
        WVOL_RETURN_IF(!s->b[i].data, err, WVOL_ERR_NOMEM, "compress: wavelet trial: out of memory");
        cube_origin(s, i, o[i]);
        if (o[i][2] < zlo) zlo = o[i][2];
        if (o[i][2] + s->e[2] > zhi) zhi = o[i][2] + s->e[2];
    }
    st = read_sample_rows(s, src, (const size_t(*)[3])o, err);
    if (st != WVOL_ERR_UNSUPPORTED) return st;
    slab_max = SLAB_BYTES / (nx * ny * sizeof(float));
    if (slab_max < 1) slab_max = 1;
    if (slab_max > s->e[2]) slab_max = s->e[2];
    /* in huge pages (core/alloc.h): in 4 KiB pages its reads were most of a trial's page faults */
    slab = wvol__reuse_get(slab_max * nx * ny * sizeof(float));
    WVOL_RETURN_IF(!slab, err, WVOL_ERR_NOMEM, "compress: wavelet trial: out of memory");
    for (z = zlo; z < zhi;) {
        size_t nz = 0;
        /* the run of needed slices from z, at most slab_max */
        while (z + nz < zhi && nz < slab_max) {
            int used = 0;
            for (i = 0; i < s->nb; i++) used |= z + nz >= o[i][2] && z + nz < o[i][2] + s->e[2];
            if (!used) break;
            nz++;
        }
        if (nz == 0) {
            z++;
            continue;
        }
        st = wvol_source_read(src, slab, z, nz, err);
        if (st != WVOL_OK) {
            wvol__reuse_put(slab);
            return st;
        }
        for (size_t k = 0; k < nz; k++) {
            const float *slice = slab + k * nx * ny;
            size_t zz = z + k;
            for (i = 0; i < s->nb; i++)
                if (zz >= o[i][2] && zz < o[i][2] + s->e[2])
                    cube_slice(s, s->b[i].data + (zz - o[i][2]) * s->e[1] * s->e[0],
                               slice + o[i][1] * nx + o[i][0], nx);
        }
        z += nz;
    }
    wvol__reuse_put(slab);
    return WVOL_OK;
}

/* Calls fn(ctx, level, band, row, n) for every row of counted coefficients of every block,
 * in the blocks' order, then level, band, z and y. */
typedef void (*row_fn)(void *ctx, int level, int band, const float *row, size_t n);

static void for_each_counted(const sample *s, wvol_coeffs *const *blocks, row_fn fn, void *ctx)
{
    for (int i = 0; i < s->nb; i++) {
        const wvol_coeffs *c = blocks[i];
        for (int m = 1; m <= s->levels; m++) {
            for (int band = (s->whole && m == s->levels) ? 0 : 1; band < 8; band++) {
                size_t base = wvol_coeffs_index(c, m, band, 0, 0, 0), n[3], st[3] = {1, c->px, c->px * c->py};
                if (base == (size_t)-1) continue;
                for (int a = 0; a < 3; a++) n[a] = s->valid[a][m];
                for (size_t r = 0; r < n[2]; r++)
                    for (size_t q = 0; q < n[1]; q++) {
                        fn(ctx, m, band, c->data + base + r * st[2] + q * st[1], n[0]);
                    }
            }
        }
    }
}

/* ---- the error model: magnitudes in log bins, the step that meets a target ---------- */

typedef struct err_bins {
    double count[NBINS], sumsq[NBINS];
    double n, energy;
    const double *lower; /* bin_lower(k), k = 0 .. NBINS */
} err_bins;

/* Bin (e - EXP_LO) SUB + floor((m - 1/2) 2 SUB) of a = m 2^e, m in [1/2, 1). A normal float's
 * fields give it directly: e = E - 126 for the biased exponent E, and (m - 1/2) 2 SUB is the
 * mantissa's top log2(SUB) bits (exact: m = (1 + f 2^-23) / 2); a subnormal goes to frexp. */
static int mag_bin(float a)
{
    uint32_t u;
    int k;
    memcpy(&u, &a, sizeof u);
    if ((u >> 23) != 0) {
        k = ((int)(u >> 23) - 126 - EXP_LO) * SUB + (int)((u & 0x7FFFFFu) >> (23 - SUB_BITS));
    } else {
        int e;
        double m = frexp((double)a, &e); /* a = m 2^e, m in [0.5, 1) */
        k = (e - EXP_LO) * SUB + (int)((m - 0.5) * 2.0 * SUB);
    }
    return k < 0 ? 0 : k >= NBINS ? NBINS - 1 : k;
}

static double bin_lower(int k) { return ldexp(0.5 + (double)(k % SUB) / (2.0 * SUB), k / SUB + EXP_LO); }

static void add_err(void *ctx, int level, int band, const float *row, size_t n)
{
    err_bins *b = ctx;
    double energy = b->energy; /* summed in the values' order, as one running sum */
    (void)level, (void)band;
    b->n += (double)n;
    for (size_t p = 0; p < n; p++) {
        const double a = fabs((double)row[p]), a2 = a * a;
        energy += a2;
        if (a == 0) continue;
        const int k = mag_bin((float)a);
        b->count[k] += 1, b->sumsq[k] += a2;
    }
    b->energy = energy;
}

/* Squared error of the dead-zone quantiser with this step: below the dead zone's edge
 * (1 - rounding) step a coefficient becomes 0 (error c^2); above, the error is modelled as
 * uniform over a step (step^2 / 12). The bin holding the edge is split in proportion. */
static double model_sse(const err_bins *b, const int16_t *used, int nused, double step, double rounding)
{
    double t = (1.0 - rounding) * step, sse = 0, q = step * step / 12.0;
    for (int u = 0; u < nused; u++) {
        const int k = used[u];
        double lo = b->lower[k], hi = b->lower[k + 1];
        if (hi <= t) sse += b->sumsq[k];
        else if (lo >= t) sse += b->count[k] * q;
        else {
            double f = (t - lo) / (hi - lo);
            sse += f * b->sumsq[k] + (1.0 - f) * b->count[k] * q;
        }
    }
    return sse;
}

/* The step whose modelled error is target (per coefficient) x count; +inf when zeroing
 * everything already meets it. Bisection on log(step): the error grows with the step. The
 * model's sums run over the bins that hold a count (a few hundred of the NBINS), in bin
 * order. */
static double step_for(const err_bins *b, double target, double rounding)
{
    double want = target * b->n, lo, hi;
    int16_t used[NBINS];
    int nused = 0;
    if (b->energy <= want) return INFINITY;
    for (int k = 0; k < NBINS; k++)
        if (b->count[k] != 0) used[nused++] = (int16_t)k;
    lo = sqrt(target) * 1e-3, hi = sqrt(target) * 1e3;
    while (model_sse(b, used, nused, lo, rounding) > want && lo > 1e-300) lo *= 1e-3;
    while (model_sse(b, used, nused, hi, rounding) < want && hi < 1e300) hi *= 1e3;
    for (int it = 0; it < 60; it++) {
        double mid = sqrt(lo * hi);
        if (model_sse(b, used, nused, mid, rounding) < want) lo = mid;
        else hi = mid;
    }
    return sqrt(lo * hi);
}

/* ---- the rate model: zeroth-order entropy of |q| per band, plus signs ---------------- */

typedef struct rate_bins {
    double step, rounding;
    uint32_t hist[32][8][QBINS]; /* level, band, |q| bin (a sample holds fewer than 2^32) */
    uint64_t extra;              /* mantissa bits of the octave bins, and one sign bit per non-zero */
} rate_bins;

/* Whole counts, in integers (a repeated bin's increment waits one cycle, not a floating add),
 * a run of values at a time: first their quotients, in vectors (the divisions overlap instead
 * of each waiting on a branch that the data decides); then each value's bin and extra bits
 * without a branch, kept for the non-zeros only (the zeros, most of a row at low rates, are
 * just counted); then the non-zeros' increments. q = 0 exactly when the sum before the floor
 * is below 1; an octave bin's extra bits are floor(log2 q), the exponent of the double
 * q >= 64. The same counts as a value-by-value loop. (No multiply-add here for the x86-64-v3
 * clone to contract: both clones give the same values.) */
#define RATE_RUN 64
WVOL__CLONES static void add_rate(void *ctx, int level, int band, const float *row, size_t n)
{
    rate_bins *r = ctx;
    uint32_t *h = r->hist[level][band];
    const double step = r->step, rounding = r->rounding;
    uint64_t extra = 0, zeros = 0;
    for (size_t p0 = 0; p0 < n; p0 += RATE_RUN) {
        const size_t pn = n - p0 < RATE_RUN ? n - p0 : RATE_RUN;
        double t[RATE_RUN];
        uint8_t bin[RATE_RUN];
        uint16_t ext[RATE_RUN];
        size_t m = 0;
        for (size_t i = 0; i < pn; i++) t[i] = fabs((double)row[p0 + i]) / step + rounding;
        for (size_t i = 0; i < pn; i++) {
            const double q = floor(t[i]);
            uint64_t u;
            memcpy(&u, &q, sizeof u);
            const int e1 = (int)(u >> 52) - 1023; /* floor(log2 q) for q >= 1 */
            const int small = q < QEXACT, oct = QEXACT + e1 - 6;
            const int k = small ? (int)q : oct < QBINS ? oct : QBINS - 1;
            bin[m] = (uint8_t)k;
            ext[m] = (uint16_t)(1 + (small ? 0 : e1)); /* a sign bit, and the octave's bits */
            m += !(t[i] < 1.0);
        }
        zeros += pn - m;
        for (size_t i = 0; i < m; i++) h[bin[i]]++, extra += ext[i];
    }
    h[0] += (uint32_t)zeros;
    r->extra += extra;
}

static double rate_bits(const rate_bins *r)
{
    double bits = (double)r->extra;
    for (int m = 0; m < 32; m++)
        for (int b = 0; b < 8; b++) {
            double n = 0;
            for (int k = 0; k < QBINS; k++) n += r->hist[m][b][k];
            if (n == 0) continue;
            for (int k = 0; k < QBINS; k++) {
                double h = r->hist[m][b][k];
                if (h > 0) bits -= h * log2(h / n);
            }
        }
    return bits;
}

/* ---- the trial ---------------------------------------------------------------------- */

static void sample_free(sample *s)
{
    for (int i = 0; i < s->nb; i++) {
        wvol__reuse_put(s->b[i].data);
    }
}

/* What every candidate's estimate shares. */
typedef struct trial_in {
    const sample *s;
    double target, step_given, rounding;
    const double *lower; /* the error bins' bounds, bin_lower(0 .. NBINS) */
} trial_in;

/* One candidate's estimate: its transform of every block, the step that meets the target
 * on them, and the bits that step gives. */
typedef struct trial {
    double step, bits, coefficients;
    wvol_status st;
    wvol_error err;
} trial;

/* A thread's arrays, kept from one candidate to the next: fresh memory per candidate was a
 * large share of a trial's time (its first touches). */
typedef struct workspace {
    wvol_coeffs *c[CUBES_MAX];
    err_bins *eb;
    rate_bins *rb;
} workspace;

static void workspace_free(workspace *w)
{
    for (int j = 0; j < CUBES_MAX; j++) wvol_coeffs_destroy(w->c[j]);
    free(w->eb);
    free(w->rb);
}

static wvol_status trial_candidate(trial *t, const wvol_filter *f, const trial_in *in, workspace *w)
{
    const sample *s = in->s;
    wvol_status st = WVOL_OK;
    if (!w->eb) w->eb = malloc(sizeof *w->eb);
    if (!w->rb) w->rb = malloc(sizeof *w->rb);
    if (!w->eb || !w->rb) return wvol_error_set(&t->err, WVOL_ERR_NOMEM, "compress: wavelet trial: out of memory");
    for (int j = 0; j < s->nb && st == WVOL_OK; j++) {
        wvol_coeffs *c = w->c[j];
        wvol_volume *v = NULL;
        if (c && c->px == s->e[0] && c->py == s->e[1] && c->pz == s->e[2]) {
            /* no padding: the block into the previous candidate's array, transformed there
             * (what wvol_dwt3 computes, without a fresh array per candidate) */
            memcpy(c->data, s->b[j].data, s->e[0] * s->e[1] * s->e[2] * sizeof(float));
            c->filter = f;
            st = wvol_dwt3_inplace_f32(c->data, c->px, c->py, c->pz, f, s->levels, &t->err);
            if (st == WVOL_OK)
                st = wvol_check_finite(c->data, c->px, c->py, c->pz, "wavelet trial coefficients", &t->err);
            continue;
        }
        wvol_coeffs_destroy(c);
        w->c[j] = NULL;
        st = wvol_volume_wrap(&v, s->b[j].data, s->e[0], s->e[1], s->e[2], &t->err);
        if (st == WVOL_OK) st = wvol_dwt3(&w->c[j], v, f, s->levels, &t->err);
        wvol_volume_destroy(v);
    }
    if (st == WVOL_OK) {
        err_bins *eb = w->eb;
        rate_bins *rb = w->rb;
        memset(eb, 0, sizeof *eb);
        eb->lower = in->lower;
        for_each_counted(s, w->c, add_err, eb);
        t->coefficients = eb->n;
        t->step = in->step_given > 0 ? in->step_given : step_for(eb, in->target, in->rounding);
        memset(rb, 0, sizeof *rb);
        rb->step = t->step, rb->rounding = in->rounding;
        if (isfinite(t->step)) for_each_counted(s, w->c, add_rate, rb);
        t->bits = isfinite(t->step) ? rate_bits(rb) / eb->n : 0;
    }
    return st;
}

/* The sample's geometry: blocks, their levels and counted positions. */
static wvol_status plan_sample(sample *s, const size_t dims[3], int file_levels, int taps, wvol_error *err)
{
    double voxels = (double)dims[0] * (double)dims[1] * (double)dims[2], cube;
    memset(s, 0, sizeof *s);
    memcpy(s->dims, dims, sizeof s->dims);
    for (int a = 0; a < 3; a++) s->e[a] = dims[a] < CUBE ? dims[a] : CUBE;
    cube = (double)s->e[0] * (double)s->e[1] * (double)s->e[2];
    s->whole = voxels <= cube;
    if (s->whole) {
        memcpy(s->e, dims, sizeof s->e);
        s->nb = 1;
        s->levels = file_levels;
    } else {
        double k = floor(voxels / (CUBE_SHARE * cube));
        s->nb = k < CUBES_MIN ? CUBES_MIN : k > CUBES_MAX ? CUBES_MAX : (int)k;
        s->levels = wvol_dwt_max_levels(s->e[0], s->e[1], s->e[2]);
        if (s->levels > file_levels) s->levels = file_levels;
    }
    for (int m = 1; m <= s->levels; m++) {
        int ok = 1;
        for (int a = 0; a < 3; a++) {
            size_t padded = s->e[a] == 1 ? 1 : wvol_dwt_padded_size(s->e[a], s->levels);
            s->valid[a][m] = valid_positions(s->e[a], dims[a], padded, m, taps);
            ok &= s->valid[a][m] > 0;
        }
        if (!ok) {
            s->levels = m - 1; /* no coefficient of this level lies inside a cube */
            break;
        }
    }
    WVOL_RETURN_IF(s->levels < 1, err, WVOL_ERR_DIMS, "compress: wavelet trial: a %zux%zux%zu volume cannot be sampled",
                   dims[0], dims[1], dims[2]);
    return WVOL_OK;
}

wvol_status wvol_compress_choose_wavelet(wvol_wavelet_choice *out, wvol_source *src, const wvol_compress_params *p,
                                         wvol_error *err)
{
    wvol_compress_params dp;
    sample s;
    size_t dims[3];
    const wvol_filter *f[WVOL_WAVELET_CHOICE_CANDIDATES];
    int taps = 0, file_levels, maxl, best = 0;
    double t0 = wvol__now(), rounding, target = 0, step_given;
    wvol_wvc_params wp;
    wvol_status st = WVOL_OK;
    double *lower = NULL;

    WVOL_RETURN_IF(!out || !src, err, WVOL_ERR_ARG, "compress: wavelet trial: no output or no source");
    memset(out, 0, sizeof *out);
    if (!p) wvol_compress_params_default(&dp), p = &dp;
    for (int i = 0; i < WVOL_WAVELET_CHOICE_CANDIDATES; i++) {
        WVOL_FORWARD(wvol_filter_get(&f[i], candidates[i], err));
        if (f[i]->length > taps) taps = f[i]->length;
        out->name[i] = f[i]->name;
    }
    out->candidates = WVOL_WAVELET_CHOICE_CANDIDATES;
    out->margin = WVOL_WAVELET_CHOICE_MARGIN;
    out->wavelet = f[0]->name;
    wvol_source_geometry(src, dims, NULL, NULL);
    maxl = wvol_dwt_max_levels(dims[0], dims[1], dims[2]);
    WVOL_RETURN_IF(maxl < 1, err, WVOL_ERR_DIMS, "compress: a %zux%zux%zu volume cannot be transformed", dims[0],
                   dims[1], dims[2]);
    WVOL_RETURN_IF(p->levels < 0 || p->levels > maxl, err, WVOL_ERR_ARG,
                   "compress: wavelet trial: levels %d: a %zux%zux%zu volume allows 1..%d (0: the default)",
                   p->levels, dims[0], dims[1], dims[2], maxl);
    WVOL_RETURN_IF(!(p->quant.step >= 0) || !isfinite(p->quant.step), err, WVOL_ERR_ARG,
                   "compress: wavelet trial: quantiser step %g (must be finite and >= 0)", p->quant.step);
    WVOL_RETURN_IF(!(p->quant.psnr >= 0), err, WVOL_ERR_ARG,
                   "compress: wavelet trial: PSNR %g (must be > 0, or 0 for none)", p->quant.psnr);
    file_levels = p->levels > 0 ? p->levels : p->for_file ? WVOL_COMPRESS_LEVELS_FILE : WVOL_COMPRESS_LEVELS_STORE;
    if (file_levels > maxl) file_levels = maxl;
    wvol_wvc_params_default(&wp);
    rounding = p->quant.rounding >= 0 && p->quant.rounding <= 0.5 ? p->quant.rounding : wp.rounding;
    step_given = p->quant.step > 0 ? p->quant.step : 0;
    out->psnr = step_given > 0                                              ? 0
                : p->quant.psnr > 0                                         ? p->quant.psnr
                : p->select.mode == WVOL_SELECT_PSNR && p->select.psnr > 0 ? p->select.psnr
                                                                            : DEFAULT_PSNR;

    WVOL_FORWARD(plan_sample(&s, dims, file_levels, taps, err));
    s.lo = INFINITY, s.hi = -INFINITY;
    if (s.whole) {
        s.b[0].data = wvol__reuse_get(dims[0] * dims[1] * dims[2] * sizeof(float));
        if (!s.b[0].data) st = wvol_error_set(err, WVOL_ERR_NOMEM, "compress: wavelet trial: out of memory");
        if (st == WVOL_OK) st = wvol_source_read(src, s.b[0].data, 0, dims[2], err);
        for (size_t i = 0; st == WVOL_OK && i < dims[0] * dims[1] * dims[2]; i++) {
            if (s.b[0].data[i] < s.lo) s.lo = s.b[0].data[i];
            if (s.b[0].data[i] > s.hi) s.hi = s.b[0].data[i];
        }
    } else {
        st = read_sample(&s, src, err);
    }
    out->blocks = s.nb;
    out->sample_voxels = (size_t)s.nb * s.e[0] * s.e[1] * s.e[2];
    if (st != WVOL_OK) goto done;
    if (step_given == 0) {
        double peak = s.hi - s.lo;
        if (!(peak > 0)) goto done; /* a constant sample: nothing to compare; db2 */
        target = peak * peak * pow(10.0, -out->psnr / 10.0);
    }
    lower = malloc((NBINS + 1) * sizeof *lower);
    if (!lower) {
        st = wvol_error_set(err, WVOL_ERR_NOMEM, "compress: wavelet trial: out of memory");
        goto done;
    }
    for (int k = 0; k <= NBINS; k++) lower[k] = bin_lower(k);
    {
        /* the candidates side by side, each thread in its own arrays: the same estimates
         * whatever the threads; the first candidate's failure (in their order) is reported */
        const trial_in in = {&s, target, step_given, rounding, lower};
        trial t[WVOL_WAVELET_CHOICE_CANDIDATES];
        int i;
        memset(t, 0, sizeof t);
#pragma omp parallel
        {
            workspace w;
            memset(&w, 0, sizeof w);
#pragma omp for schedule(dynamic, 1)
            for (i = 0; i < WVOL_WAVELET_CHOICE_CANDIDATES; i++) t[i].st = trial_candidate(&t[i], f[i], &in, &w);
            workspace_free(&w);
        }
        for (i = 0; i < WVOL_WAVELET_CHOICE_CANDIDATES && st == WVOL_OK; i++)
            if (t[i].st != WVOL_OK) {
                st = t[i].st;
                if (err) *err = t[i].err;
            }
        for (i = 0; i < WVOL_WAVELET_CHOICE_CANDIDATES && st == WVOL_OK; i++) {
            out->sample_coefficients = (size_t)t[i].coefficients;
            out->step[i] = t[i].step;
            out->bits[i] = t[i].bits;
            if (i > 0 && out->bits[i] < out->bits[best]) best = i;
        }
        if (st != WVOL_OK) goto done;
    }
    /* db2 unless another filter's estimate is smaller by more than the margin */
    if (best > 0 && out->bits[best] < (1.0 - WVOL_WAVELET_CHOICE_MARGIN) * out->bits[0]) out->wavelet = f[best]->name;
done:
    free(lower);
    sample_free(&s);
    out->seconds = wvol__now() - t0;
    return st;
}
