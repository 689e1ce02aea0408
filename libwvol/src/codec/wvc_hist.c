/* SPDX-License-Identifier: MIT
 * Magnitude histograms of the sub-bands and the quantiser step they predict.
 *
 * One pass over the coefficients counts |c| per section in logarithmic bins (the
 * top 14 bits of the float32 pattern: exponent and 5 mantissa bits, 32 bins per
 * octave, each at most 2.2% wide); it also finds max |c| and refuses NaN/Inf. From
 * the counts the squared error of the dead-zone quantiser with centroid offsets
 * (docs/wvc-format.md, "Quantiser") is estimated for any step without touching the
 * data again, so the step that meets an error target is found by bisection on the
 * estimate; one exact pass then checks it (wvc_encode.c). Integer counts make the
 * result independent of the number of threads. */
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "core/alloc.h"
#include "wvc_internal.h"

#define HSHIFT 18 /* float bits >> HSHIFT = bin */

static inline uint32_t float_bits(float v)
{
    uint32_t u;
    memcpy(&u, &v, 4);
    return u;
}

static inline double bin_edge(uint32_t k)
{
    uint32_t u = k << HSHIFT;
    float v;
    if (u >= 0x7F800000u) return 3.4028234663852886e38; /* top finite bin ends at FLT_MAX */
    memcpy(&v, &u, 4);
    return v;
}

/* Eight values at a time: their magnitudes' bits, running maximum and bins in vectors, then
 * the eight counts (the counting itself cannot be vectorised: bins repeat). */
typedef uint32_t hist_v8u __attribute__((vector_size(32)));

WVOL__CLONES void wvol__wvc_slice_hist(uint64_t *restrict H, const float *restrict row0, size_t ex, size_t ey, size_t sy,
                               uint32_t *maxbits)
{
    const hist_v8u absmask = {0x7FFFFFFFu, 0x7FFFFFFFu, 0x7FFFFFFFu, 0x7FFFFFFFu,
                              0x7FFFFFFFu, 0x7FFFFFFFu, 0x7FFFFFFFu, 0x7FFFFFFFu};
    hist_v8u vmax = {0, 0, 0, 0, 0, 0, 0, 0};
    uint32_t mx = *maxbits;
    for (size_t y = 0; y < ey; y++) {
        const float *restrict row = row0 + y * sy;
        size_t x = 0;
        for (; x + 8 <= ex; x += 8) {
            hist_v8u u, gt;
            memcpy(&u, row + x, sizeof u);
            u &= absmask;
            gt = (hist_v8u)(u > vmax);
            vmax = (u & gt) | (vmax & ~gt);
            u >>= HSHIFT;
            H[u[0]]++, H[u[1]]++, H[u[2]]++, H[u[3]]++, H[u[4]]++, H[u[5]]++, H[u[6]]++, H[u[7]]++;
        }
        for (; x < ex; x++) {
            uint32_t u = float_bits(row[x]) & 0x7FFFFFFFu;
            mx = u > mx ? u : mx;
            H[u >> HSHIFT]++;
        }
    }
    for (int k = 0; k < 8; k++) mx = vmax[k] > mx ? vmax[k] : mx;
    *maxbits = mx;
}

typedef struct hist_task {
    int sec;
    size_t z;
} hist_task;

int wvol__wvc_hist(uint64_t *H, const wvc_layout *L, const float *C, double *maxabs, int *nonfinite)
{
    const size_t nb = WVC_HBINS;
    size_t ntask = 0, t;
    hist_task *task;
    /* each thread counts into its own histograms: a few threads saturate the memory */
    int nthr = omp_get_max_threads() < 4 ? omp_get_max_threads() : 4, s;
    uint64_t *part;
    uint32_t maxbits = 0;
    if (nthr < 1) nthr = 1;
    for (s = 0; s < L->nsec; s++) ntask += L->sec[s].count ? L->sec[s].ext[2] : 0;
    task = malloc((ntask ? ntask : 1) * sizeof *task);
    part = calloc((size_t)nthr * (size_t)L->nsec * nb, sizeof *part);
    if (!task || !part) {
        free(task);
        free(part);
        return -1;
    }
    for (t = 0, s = 0; s < L->nsec; s++)
        for (size_t z = 0; L->sec[s].count && z < L->sec[s].ext[2]; z++, t++) task[t].sec = s, task[t].z = z;
#pragma omp parallel num_threads(nthr) reduction(max : maxbits) if (ntask > 16)
    {
        uint64_t *mine = part + (size_t)omp_get_thread_num() * (size_t)L->nsec * nb;
        uint32_t mb = 0;
        long i;
#pragma omp for schedule(dynamic, 8)
        for (i = 0; i < (long)ntask; i++) {
            const wvc_band *b = &L->sec[task[i].sec];
            wvol__wvc_slice_hist(mine + (size_t)task[i].sec * nb, C + wvc_index(L->p, b, 0, 0, task[i].z), b->ext[0],
                       b->ext[1], L->p[0], &mb);
        }
        maxbits = mb > maxbits ? mb : maxbits;
    }
    memset(H, 0, (size_t)L->nsec * nb * sizeof *H);
    for (int th = 0; th < nthr; th++)
        for (size_t k = 0; k < (size_t)L->nsec * nb; k++) H[k] += part[(size_t)th * L->nsec * nb + k];
    free(part);
    free(task);
    *nonfinite = maxbits >= 0x7F800000u;
    *maxabs = INFINITY;
    if (!*nonfinite) {
        float m;
        memcpy(&m, &maxbits, 4);
        *maxabs = m;
    }
    return 0;
}

/* The non-empty bins of all sections, for repeated evaluation. */
typedef struct hbin {
    double lo, hi, n;
} hbin;

struct wvc_hist_est {
    hbin *bins;
    size_t start[WVOL_WVC_MAX_SECTIONS + 1];
};

wvc_hist_est *wvol__wvc_hist_prepare(const uint64_t *H, const wvc_layout *L)
{
    size_t n = 0, k;
    wvc_hist_est *hl = malloc(sizeof *hl);
    if (!hl) return NULL;
    for (k = 0; k < (size_t)L->nsec * WVC_HBINS; k++) n += H[k] != 0;
    hl->bins = wvol__reuse_get((n ? n : 1) * sizeof *hl->bins);
    if (!hl->bins) {
        free(hl);
        return NULL;
    }
    n = 0;
    for (int s = 0; s < L->nsec; s++) {
        hl->start[s] = n;
        for (k = 0; k < WVC_HBINS; k++) {
            uint64_t c = H[(size_t)s * WVC_HBINS + k];
            if (!c) continue;
            hl->bins[n].lo = bin_edge((uint32_t)k);
            hl->bins[n].hi = bin_edge((uint32_t)k + 1);
            hl->bins[n].n = (double)c;
            n++;
        }
    }
    hl->start[L->nsec] = n;
    return hl;
}

void wvol__wvc_hist_free(wvc_hist_est *hl)
{
    if (hl) wvol__reuse_put(hl->bins);
    free(hl);
}

/* Adds the share `n` of a bin whose t = |c|/d + f lies uniformly in [t0, t1), all
 * with the same q = floor(t): to the zeroed energy (q = 0) or to the sums of
 * r = t - f - q of its class (q = 1, q >= 2). */
typedef struct hsums {
    double zero, n1, s1, ss1, n2, s2, ss2;
} hsums;

static inline void hist_piece(hsums *h, double n, double t0, double t1, double q, double d, double f)
{
    if (q < 1) {
        double a0 = (t0 - f) * d, a1 = (t1 - f) * d;
        h->zero += n * (a0 * a0 + a0 * a1 + a1 * a1) / 3.0;
    } else {
        double r0 = t0 - f - q, r1 = t1 - f - q, m = 0.5 * (r0 + r1), m2 = (r0 * r0 + r0 * r1 + r1 * r1) / 3.0;
        if (q < 2) h->n1 += n, h->s1 += n * m, h->ss1 += n * m2;
        else h->n2 += n, h->s2 += n * m, h->ss2 += n * m2;
    }
}

/* Estimated squared error of the quantiser with step d on one section's counts,
 * with |c| taken as uniform within each bin: a bin that crosses a quantiser
 * boundary is split there; a bin wider than the step spreads its remainders r over
 * the whole cell (its part below the dead zone split off first). */
static double hist_section_error(const hbin *bins, size_t nbins, double d, double f)
{
    const double inv = 1.0 / d;
    hsums h = {0, 0, 0, 0, 0, 0, 0};
    const double ur = 0.5 - f, urr = ((1 - f) * (1 - f) * (1 - f) + f * f * f) / 3.0; /* r uniform on [-f, 1-f) */
    for (size_t k = 0; k < nbins; k++) {
        double n = bins[k].n, t0 = bins[k].lo * inv + f, t1 = bins[k].hi * inv + f, q = floor(t0);
        if (t1 - t0 >= 1) {
            if (t0 < 1) { /* the part in the dead zone */
                double phi = (1 - t0) / (t1 - t0);
                hist_piece(&h, n * phi, t0, 1, 0, d, f);
                n *= 1 - phi;
                t0 = 1;
            }
            if (floor(0.5 * (t0 + t1)) < 2) h.n1 += n, h.s1 += n * ur, h.ss1 += n * urr;
            else h.n2 += n, h.s2 += n * ur, h.ss2 += n * urr;
        } else if (t1 <= q + 1) {
            hist_piece(&h, n, t0, t1, q, d, f);
        } else { /* crosses q + 1 */
            double phi = (q + 1 - t0) / (t1 - t0);
            hist_piece(&h, n * phi, t0, q + 1, q, d, f);
            hist_piece(&h, n * (1 - phi), q + 1, t1, q + 1, d, f);
        }
    }
    {
        double e = h.zero;
        if (h.n1 > 0) e += d * d * (h.ss1 - h.s1 * h.s1 / h.n1);
        if (h.n2 > 0) e += d * d * (h.ss2 - h.s2 * h.s2 / h.n2);
        return e;
    }
}

double wvol__wvc_hist_error(const wvc_hist_est *hl, const wvc_layout *L, double step, double f_detail)
{
    double e = 0;
    for (int s = 0; s < L->nsec; s++)
        e += hist_section_error(hl->bins + hl->start[s], hl->start[s + 1] - hl->start[s], step,
                                L->sec[s].band ? f_detail : 0.5);
    return e;
}

double wvol__wvc_hist_step(const wvc_hist_est *hl, const wvc_layout *L, double target, double f, double lo,
                           double hi)
{
    /* the error grows with the step: bisection in log(step) to 0.1% */
    if (wvol__wvc_hist_error(hl, L, hi, f) <= target) return hi;
    if (wvol__wvc_hist_error(hl, L, lo, f) > target) return lo;
    while (hi / lo > 1.001) {
        double mid = sqrt(lo * hi);
        if (wvol__wvc_hist_error(hl, L, mid, f) <= target) lo = mid;
        else hi = mid;
    }
    return lo;
}
