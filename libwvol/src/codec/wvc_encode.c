/* SPDX-License-Identifier: MIT
 * .wvc encoder: the dead-zone quantiser with the step chosen from an error target
 * (wvc_quant.c) and the leftover budget spent (wvc_slack.c), centroid reconstruction
 * offsets, per-section coding, header and section table; PSNR helpers.
 * Based on: Sullivan 1996 (dead-zone uniform quantiser with centroid
 * reconstruction for Laplacian sources); Parseval for orthonormal transforms
 * (the coefficient error is the volume error, DESIGN.md section 5). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <zlib.h>

#include "wvc2_internal.h"
#include "wvc_format.h"
#include "wvc_quant.h"

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void wvol_wvc_params_default(wvol_wvc_params *p)
{
    if (!p) return;
    memset(p, 0, sizeof *p);
    p->rounding = WVC_DEFAULT_ROUNDING;
    p->coder = WVOL_WVC_CODER_AUTO;
    p->zstd_level = 3;
}

static size_t band_extent(size_t pa, int level, int high)
{
    if (pa == 1) return high ? 0 : 1;
    return pa >> level;
}

void wvol__wvc_layout(wvc_layout *L, size_t px, size_t py, size_t pz, int levels)
{
    const size_t p[3] = {px, py, pz};
    int m, l, a, s = 0;
    memset(L, 0, sizeof *L);
    L->levels = levels;
    memcpy(L->p, p, sizeof p);
    /* low-pass cube */
    L->sec[s].level = levels;
    L->sec[s].band = 0;
    for (a = 0; a < 3; a++) L->sec[s].ext[a] = band_extent(p[a], levels, 0);
    s++;
    for (m = levels; m >= 1; m--)
        for (l = 1; l <= 7; l++, s++) {
            wvc_band *b = &L->sec[s];
            b->level = m;
            b->band = l;
            b->has_parent = m < levels;
            for (a = 0; a < 3; a++) {
                int high = (l >> a) & 1;
                b->ext[a] = band_extent(p[a], m, high);
                b->off[a] = (high && p[a] > 1) ? p[a] >> m : 0;
                if (b->has_parent) {
                    b->pext[a] = band_extent(p[a], m + 1, high);
                    b->poff[a] = (high && p[a] > 1) ? p[a] >> (m + 1) : 0;
                }
            }
        }
    L->nsec = s;
    for (s = 0; s < L->nsec; s++) {
        wvc_band *b = &L->sec[s];
        b->count = (uint64_t)b->ext[0] * b->ext[1] * b->ext[2];
        if (b->count == 0) b->has_parent = 0;
    }
}

void wvol__wvc_header_put(uint8_t *h, const wvc_header_fields *f)
{
    size_t n = strlen(f->filter);
    memcpy(h, WVC_MAGIC, 8);
    wvc_put_u16(h + 8, (uint16_t)f->version);
    wvc_put_u16(h + 10, 0);
    wvc_put_u32(h + 12, f->nsec);
    memcpy(h + 16, f->filter, n < 15 ? n : 15);
    h[32] = (uint8_t)f->levels;
    for (int a = 0; a < 3; a++) {
        wvc_put_u64(h + 40 + 8 * a, f->n[a]);
        wvc_put_u64(h + 64 + 8 * a, f->p[a]);
        wvc_put_f64(h + 88 + 8 * a, f->spacing[a]);
        wvc_put_f64(h + 112 + 8 * a, f->origin[a]);
    }
    wvc_put_f64(h + 136, f->value_min);
    wvc_put_f64(h + 144, f->value_max);
    wvc_put_f64(h + 152, f->step);
    wvc_put_f64(h + 160, f->rounding);
    wvc_put_f64(h + 168, f->sse);
    wvc_put_f64(h + 176, f->energy);
    wvc_put_f64(h + 184, f->dropped_energy);
    wvc_put_u64(h + 192, f->nonzero);
    wvc_put_u64(h + 200, f->payload);
}

static void header_write(uint8_t *h, const wvol_coeffs *c, const wvol_wvc_params *p, double step,
                         double sse, double energy, uint64_t nonzero, uint64_t payload,
                         const wvc_layout *L, const uint8_t coder[], const uint64_t bytes[],
                         const uint32_t crc[], const sec_stats st[], const float d1[], const float d2[],
                         const double err[])
{
    int s;
    size_t n;
    wvc_header_fields hf = {1, (uint32_t)L->nsec, c->filter->name, c->levels, {c->nx, c->ny, c->nz},
                            {c->px, c->py, c->pz}, {0}, {0}, p->value_min, p->value_max, step, p->rounding, sse,
                            energy, p->dropped_energy, nonzero, payload};
    memcpy(hf.spacing, c->spacing, sizeof hf.spacing);
    memcpy(hf.origin, c->origin, sizeof hf.origin);
    memset(h, 0, WVC_HEADER_SIZE + (size_t)L->nsec * WVC_SECTION_SIZE + 4);
    wvol__wvc_header_put(h, &hf);
    for (s = 0; s < L->nsec; s++) {
        uint8_t *e = h + WVC_HEADER_SIZE + (size_t)s * WVC_SECTION_SIZE;
        e[0] = (uint8_t)L->sec[s].level;
        e[1] = (uint8_t)L->sec[s].band;
        e[2] = coder[s];
        wvc_put_u32(e + 4, crc[s]);
        wvc_put_u64(e + 8, bytes[s]);
        wvc_put_u64(e + 16, st[s].n1 + st[s].n2);
        wvc_put_f32(e + 24, d1[s]);
        wvc_put_f32(e + 28, d2[s]);
        wvc_put_f64(e + 32, st[s].energy);
        wvc_put_f64(e + 40, err[s]);
    }
    n = WVC_HEADER_SIZE + (size_t)L->nsec * WVC_SECTION_SIZE;
    wvc_put_u32(h + n, (uint32_t)crc32(0L, h, (uInt)n));
}

/* Per detail section that the slack spending touched, the smallest |c| / step of the
 * |q| = 1 coefficients it left: the writer zeroes everything below (docs/wvc-format.md). */
static void zero_edges(double *edge, const wvc_layout *L, const float *C, const int32_t *Q, double step, double f,
                       const sec_stats *before, const sec_stats *after)
{
    const double inv = 1.0 / step;
    for (int s = 1; s < L->nsec; s++) {
        const wvc_band *b = &L->sec[s];
        double mn = INFINITY;
        long z;
        edge[s] = 0;
        if (!b->count || after[s].n1 >= before[s].n1) continue;
#pragma omp parallel for reduction(min : mn) schedule(static)
        for (z = 0; z < (long)b->ext[2]; z++)
            for (size_t y = 0; y < b->ext[1]; y++) {
                size_t base = wvc_index(L->p, b, 0, y, (size_t)z);
                for (size_t x = 0; x < b->ext[0]; x++) {
                    double a = fabs((double)C[base + x]) * inv;
                    if (Q[base + x] != 0 && a + f < 2.0 && a < mn) mn = a;
                }
            }
        /* every |q| = 1 coefficient went: zero the whole |q| = 1 cell. Not isfinite(mn): a
         * min reduction's private copies start at the type's largest value, which is +inf with
         * GCC's runtime and DBL_MAX with clang's; every |q| = 1 value is below 2 - f anyway. */
        edge[s] = mn < 2.0 - f ? mn : 2.0 - f;
    }
}

wvol_status wvol_wvc_encode(void **out, size_t *out_size, const wvol_coeffs *c,
                            const wvol_wvc_params *p, wvol_wvc_report *report, wvol_error *err)
{
    wvc_layout *L = NULL;
    sec_stats *st = NULL;
    int32_t *Q = NULL;
    uint8_t *pay[WVOL_WVC_MAX_SECTIONS] = {0}, coder[WVOL_WVC_MAX_SECTIONS] = {0};
    uint64_t bytes[WVOL_WVC_MAX_SECTIONS] = {0};
    uint32_t crc[WVOL_WVC_MAX_SECTIONS] = {0};
    size_t alt_cabac[WVOL_WVC_MAX_SECTIONS] = {0}, alt_zstd[WVOL_WVC_MAX_SECTIONS] = {0};
    float d1[WVOL_WVC_MAX_SECTIONS], d2[WVOL_WVC_MAX_SECTIONS];
    double serr[WVOL_WVC_MAX_SECTIONS];
    sec_stats n1_before[WVOL_WVC_MAX_SECTIONS];
    size_t n, hsize, total;
    double step, maxabs = 0, energy = 0, sse = 0, t0, t1, t2;
    uint64_t nonzero = 0, payload = 0;
    int s, iters = 0, failed = 0, searched = 0, bad = 0, qzero = 1;
    uint64_t *H = NULL;
    uint8_t *file;
    wvol_status status = WVOL_OK;
    wvol_wvc_report rep;

    memset(&rep, 0, sizeof rep);
    WVOL_RETURN_IF(!out || !out_size, err, WVOL_ERR_ARG, "wvc encode: output pointer is NULL");
    *out = NULL;
    *out_size = 0;
    WVOL_RETURN_IF(!c || !c->data || !c->filter || !p, err, WVOL_ERR_ARG, "wvc encode: missing input");
    WVOL_RETURN_IF(p->version < 0 || p->version > 2, err, WVOL_ERR_ARG,
                   "wvc encode: format version %d: expected 1, 2 or 0 (the default, 2)", p->version);
    WVOL_RETURN_IF(c->levels < 1 || c->levels > WVOL_WVC_MAX_LEVELS, err, WVOL_ERR_ARG,
                   "wvc encode: levels %d outside 1..%d", c->levels, WVOL_WVC_MAX_LEVELS);
    WVOL_RETURN_IF(!(p->rounding >= 0 && p->rounding <= 0.5), err, WVOL_ERR_ARG,
                   "wvc encode: rounding %g outside [0, 0.5]", p->rounding);
    WVOL_RETURN_IF(!(p->step >= 0) || !isfinite(p->step) || !(p->target_sse >= 0) ||
                       !isfinite(p->target_sse) || (p->step == 0 && p->target_sse <= 0),
                   err, WVOL_ERR_ARG, "wvc encode: give a step > 0 or an error target > 0");
    WVOL_RETURN_IF(!isfinite(p->value_min) || !isfinite(p->value_max) || p->value_min > p->value_max ||
                       !(p->dropped_energy >= 0) || !isfinite(p->dropped_energy),
                   err, WVOL_ERR_ARG, "wvc encode: bad value range or dropped energy");
    WVOL_RETURN_IF(p->coder < WVOL_WVC_CODER_AUTO || p->coder > WVOL_WVC_CODER_COMPACT, err, WVOL_ERR_ARG,
                   "wvc encode: unknown coder %d", (int)p->coder);
    WVOL_RETURN_IF((p->coder == WVOL_WVC_CODER_RANS || p->coder == WVOL_WVC_CODER_RANS4) && p->version == 1, err,
                   WVOL_ERR_ARG, "wvc encode: the rANS coders write chunks of version 2 (not --format 1)");
    for (s = 0; s < 3; s++)
        WVOL_RETURN_IF(!(isfinite(c->spacing[s]) && c->spacing[s] > 0) || !isfinite(c->origin[s]), err,
                       WVOL_ERR_ARG, "wvc encode: spacing must be > 0 and origin finite");
    WVOL_RETURN_IF(!wvol_size_mul3(c->px, c->py, c->pz, sizeof(int32_t), &n), err, WVOL_ERR_DIMS,
                   "wvc encode: padded size overflows");
    n /= sizeof(int32_t);
    L = malloc(sizeof *L);
    st = calloc(WVOL_WVC_MAX_SECTIONS, sizeof *st);
    /* zero pages until written: the quantiser writes only where a row has non-zeros */
    Q = calloc(n, sizeof *Q);
    if (!L || !st || !Q) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory");
        goto done;
    }
    wvol__wvc_layout(L, c->px, c->py, c->pz, c->levels);

    /* range and finiteness of the coefficients, and their magnitude histograms */
    t0 = now();
    H = malloc((size_t)L->nsec * WVC_HBINS * sizeof *H);
    if (!H || wvol__wvc_hist(H, L, c->data, &maxabs, &bad)) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory");
        goto done;
    }
    if (bad) {
        status = wvol_error_set(err, WVOL_ERR_NONFINITE, "wvc encode: coefficients hold NaN or Inf");
        goto done;
    }
    {
        /* |q| stays below WVC_QMAX/2 so that the quantiser never clips */
        double min_step = maxabs > 0 ? maxabs / (double)(WVC_QMAX / 2) : WVC_MIN_STEP;
        if (min_step < WVC_MIN_STEP) min_step = WVC_MIN_STEP;
        if (p->step > 0) {
            step = p->step;
            if (step > WVC_MAX_STEP) {
                status = wvol_error_set(err, WVOL_ERR_ARG, "wvc encode: step %g is above %g", step, WVC_MAX_STEP);
                goto done;
            }
            if (step < min_step) {
                status = wvol_error_set(err, WVOL_ERR_ARG,
                                        "wvc encode: step %g is below %g, the smallest this range allows",
                                        step, min_step);
                goto done;
            }
        } else if (maxabs == 0) {
            step = 1.0; /* every coefficient is zero: any step is exact */
        } else {
            step = wvol__wvc_choose_step(L, c->data, H, p->target_sse, p->rounding, maxabs, min_step, st, &iters, Q,
                                         &qzero);
            if (!isfinite(step)) {
                status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory");
                goto done;
            }
            if (step > WVC_MAX_STEP) step = WVC_MAX_STEP, searched = 0;
            else searched = 1;
        }
    }
    /* the largest value the decoder can make, (|q| + offset) step with |offset| <= 1, must be a
     * float32 (only coefficients within a few steps of FLT_MAX can fail this) */
    if ((floor(maxabs / step + 0.5) + 1.0) * step > WVC_MAX_STEP) {
        status = wvol_error_set(err, WVOL_ERR_NONFINITE,
                                "wvc encode: coefficients reach %g: with step %g a dequantised value could exceed "
                                "float32's 3.4e38; scale the volume down (or give a smaller step)",
                                maxabs, step);
        goto done;
    }
    t1 = now();
    rep.seconds_step = t1 - t0;

    /* quantise, with the exact error per section */
    if (!searched && wvol__wvc_all_stats(st, L, c->data, Q, step, p->rounding, &qzero)) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory");
        goto done;
    }
    for (s = 0; s < L->nsec; s++) {
        serr[s] = wvol__wvc_sec_error(&st[s], step, &d1[s], &d2[s]);
        sse += serr[s];
    }
    if (p->version != 1) memcpy(n1_before, st, (size_t)L->nsec * sizeof *st);
    if (p->step == 0 && sse < 0.99 * p->target_sse) {
        /* spend what the staircase left of the budget, then the exact sums again */
        if (wvol__wvc_spend_slack(L, c->data, Q, step, p->rounding, d1, p->target_sse - sse, st) > 0) {
            for (sse = 0, s = 0; s < L->nsec; s++) {
                serr[s] = wvol__wvc_sec_error(&st[s], step, &d1[s], &d2[s]);
                sse += serr[s];
            }
        }
    }
    for (s = 0; s < L->nsec; s++) {
        energy += st[s].energy;
        nonzero += st[s].n1 + st[s].n2;
    }
    t2 = now();
    rep.seconds_quantise = t2 - t1;
    if (p->version != 1) {
        /* version 2: the slab writer quantises again, with each section's dead zone widened
         * to what the slack spending zeroed (whole bins: its partial bin stays) */
        double edge[WVOL_WVC_MAX_SECTIONS] = {0};
        wvol_wvc_report r2;
        zero_edges(edge, L, c->data, Q, step, p->rounding, n1_before, st);
        status = wvol__wvc2_encode_dense(out, out_size, c, p, step, edge, &r2, err);
        if (status != WVOL_OK) goto done;
        rep.seconds_code = now() - t2;
        rep.step = step;
        rep.step_iterations = iters;
        rep.sse_quant = r2.sse_quant;
        rep.nonzero = r2.nonzero;
        rep.coefficients = n;
        rep.bytes = r2.bytes;
        rep.bytes_cabac = r2.bytes_cabac;
        rep.bytes_zstd = r2.bytes_zstd;
        rep.bytes_rans = r2.bytes_rans;
        if (report) *report = rep;
        goto done;
    }

    /* code the sections (independent given Q), largest first */
#pragma omp parallel for schedule(dynamic, 1) reduction(| : failed) if (n > 65536)
    for (s = L->nsec - 1; s >= 0; s--) {
        const wvc_band *b = &L->sec[s];
        uint8_t *a = NULL, *z = NULL;
        size_t na = 0, nz = 0;
        if (st[s].n1 + st[s].n2 == 0) {
            coder[s] = WVOL_WVC_CODER_EMPTY; /* a zero low-pass cube too: everything quantised to 0 */
            continue;
        }
        if (p->coder != WVOL_WVC_CODER_ZSTD) {
            if (wvol__wvc_cabac_encode(&a, &na, Q, L->p, b)) failed = 1;
            alt_cabac[s] = na;
        }
        /* auto: both, the smaller wins (zstd's matches beat the contexts on small
         * sections and on some regular ones, e.g. Haar levels 1-2 of smooth volumes) */
        if (p->coder != WVOL_WVC_CODER_CABAC) {
            if (wvol__wvc_zstd_encode(&z, &nz, Q, L->p, b, p->zstd_level, NULL)) failed = 1;
            alt_zstd[s] = nz;
        }
        if (a && (!z || na <= nz)) {
            pay[s] = a;
            bytes[s] = na;
            coder[s] = WVOL_WVC_CODER_CABAC;
            free(z);
        } else {
            pay[s] = z;
            bytes[s] = nz;
            coder[s] = WVOL_WVC_CODER_ZSTD;
            free(a);
        }
        if (!pay[s] || bytes[s] == 0) failed = 1;
        else crc[s] = (uint32_t)crc32(0L, pay[s], (uInt)bytes[s]);
    }
    if (failed) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory while coding");
        goto done;
    }
    for (s = 0; s < L->nsec; s++) {
        payload += bytes[s];
        rep.bytes_cabac += alt_cabac[s];
        rep.bytes_zstd += alt_zstd[s];
    }
    hsize = WVC_HEADER_SIZE + (size_t)L->nsec * WVC_SECTION_SIZE + 4;
    total = hsize + (size_t)payload;
    file = malloc(total);
    if (!file) {
        status = wvol_error_set(err, WVOL_ERR_NOMEM, "wvc encode: out of memory (%zu bytes)", total);
        goto done;
    }
    header_write(file, c, p, step, sse, energy, nonzero, payload, L, coder, bytes, crc, st, d1, d2, serr);
    {
        size_t off = hsize;
        for (s = 0; s < L->nsec; s++) {
            if (bytes[s]) memcpy(file + off, pay[s], (size_t)bytes[s]);
            off += (size_t)bytes[s];
        }
    }
    {
        /* what the reader would refuse is never handed out (its header checks, no decoding) */
        wvol_wvc_info chk;
        wvol_error perr;
        if (wvol_wvc_parse_info(&chk, file, total, &perr) != WVOL_OK) {
            status = wvol_error_set(err, WVOL_ERR_INTERNAL, "wvc encode: the file it wrote is refused by the reader: %s",
                                    perr.message);
            free(file);
            goto done;
        }
    }
    rep.seconds_code = now() - t2;
    rep.step = step;
    rep.step_iterations = iters;
    rep.sse_quant = sse;
    rep.nonzero = nonzero;
    rep.coefficients = n;
    rep.bytes = total;
    if (p->coder == WVOL_WVC_CODER_ZSTD) rep.bytes_cabac = 0;
    if (p->coder == WVOL_WVC_CODER_CABAC) rep.bytes_zstd = 0;
    *out = file;
    *out_size = total;
    if (report) *report = rep;
done:
    for (s = 0; s < WVOL_WVC_MAX_SECTIONS; s++) free(pay[s]);
    free(H);
    free(Q);
    free(st);
    free(L);
    return status;
}

double wvol_wvc_psnr(double sse, double n, double vmin, double vmax)
{
    double range = vmax - vmin;
    if (!(n > 0)) return NAN;
    if (sse <= 0) return INFINITY;
    if (!(range > 0)) return -INFINITY;
    return 20.0 * log10(range / sqrt(sse / n));
}

double wvol_wvc_sse_for_psnr(double psnr, double n, double vmin, double vmax)
{
    double range = vmax - vmin, rmse = range / pow(10.0, psnr / 20.0);
    return rmse * rmse * n;
}

wvol_status wvol_wvc_compare(double *sse, double *maxabs, const wvol_volume *a,
                             const wvol_volume *b, wvol_error *err)
{
    enum { BLOCKS = 256 };
    double s = 0, m = 0, part[BLOCKS];
    size_t n;
    WVOL_RETURN_IF(!a || !b || a->nx != b->nx || a->ny != b->ny || a->nz != b->nz, err, WVOL_ERR_DIMS,
                   "compare: volumes differ in size");
    n = wvol_volume_count(a);
    /* fixed blocks summed in order: the same error to the last bit for any thread count */
#pragma omp parallel for reduction(max : m) schedule(static)
    for (int k = 0; k < BLOCKS; k++) {
        double sk = 0;
        for (size_t i = n / BLOCKS * (size_t)k + (n % BLOCKS) * (size_t)k / BLOCKS,
                    end = n / BLOCKS * (size_t)(k + 1) + (n % BLOCKS) * (size_t)(k + 1) / BLOCKS;
             i < end; i++) {
            double d = (double)a->data[i] - (double)b->data[i];
            sk += d * d;
            if (fabs(d) > m) m = fabs(d);
        }
        part[k] = sk;
    }
    for (int k = 0; k < BLOCKS; k++) s += part[k];
    if (sse) *sse = s;
    if (maxabs) *maxabs = m;
    return WVOL_OK;
}
