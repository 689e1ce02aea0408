/* SPDX-License-Identifier: MIT */
/* Energy selection in O(N): the cut is found with two radix-histogram passes
 * over the float bits of the ranking keys (bits of non-negative floats order
 * like the floats), then a third pass marks the kept bitmap. No sort.
 * Based on: Gross et al. (wavelet-space volume analysis), eqs 16-20 (energy
 * ranking, Parseval error); radix select as in, e.g., Alabi et al. 2012. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/alloc.h"
#include "store/store_internal.h"
#include "wavelet/wavelet_bricks.h"

#define NBIN 65536

void wvol_select_params_default(wvol_select_params *p)
{
    if (!p) return;
    memset(p, 0, sizeof *p);
    p->mode = WVOL_SELECT_ALL;
    for (int e = 0; e < WVOL_LOD_MAX_ELLIPSOIDS; e++) p->ellipsoids[e].power = 1.0;
}

/* ---- streaming over the array in index order ---------------------------------- */

typedef struct pass {
    const wvol_coeffs *c;
    const wvol__segplan *sp;
    const wvol__lodw *lw;
    int drop_levels;
} pass;

typedef void (*seg_fn)(void *arg, const wvol__seg *g, size_t base, const float *d, const float *w);

static void for_each_seg(const pass *ps, seg_fn fn, void *arg)
{
    const wvol__layout *ly = &ps->sp->ly;
    wvol__seg segs[WVOL_SELECT_MAX_LEVELS + 1];
    for (size_t k = 0; k < ly->P[2]; k++)
        for (size_t j = 0; j < ly->P[1]; j++) {
            size_t row = ly->P[0] * (j + ly->P[1] * k);
            int ns = wvol__segplan_row(ps->sp, j, k, segs);
            for (int s = 0; s < ns; s++) {
                const wvol__seg *g = segs + s;
                const float *w = NULL;
                if (g->level > 0 && ps->lw && ps->lw->w[g->level]) {
                    size_t e0 = wvol__ext(ly, 0, g->level), e1 = wvol__ext(ly, 1, g->level);
                    w = ps->lw->w[g->level] + g->p0 + e0 * (g->q + e1 * g->r);
                }
                fn(arg, g, row + g->x0, ps->c->data + row + g->x0, w);
            }
        }
}

static inline int ranked(const pass *ps, const wvol__seg *g) { return g->level > ps->drop_levels; }

static inline uint32_t key_of(float c, const float *w, size_t i)
{
    float a = fabsf(c);
    uint32_t u;
    if (w) a *= w[i];
    memcpy(&u, &a, sizeof u);
    return u;
}

/* ---- pass 1: energies, counts, finiteness, top-16-bit histogram ----------------- */

typedef struct stats {
    const pass *ps;
    uint32_t *hist;    /* NBIN counts of key >> 16 (NULL: not needed) */
    double *ehist;     /* NBIN energies (NULL: not needed) */
    size_t level_total[WVOL_SELECT_MAX_LEVELS + 1];
    double level_energy[WVOL_SELECT_MAX_LEVELS + 1];
    size_t candidates;
    size_t nonfinite;  /* index + 1 of the first non-finite coefficient */
} stats;

static void stats_seg(void *arg, const wvol__seg *g, size_t base, const float *d, const float *w)
{
    stats *st = arg;
    size_t n = g->x1 - g->x0;
    double e = 0.0;
    for (size_t i = 0; i < n; i++) {
        uint32_t u;
        memcpy(&u, d + i, sizeof u);
        if ((u & 0x7fffffffu) >= 0x7f800000u && !st->nonfinite) st->nonfinite = base + i + 1;
        e += (double)d[i] * d[i];
    }
    st->level_total[g->level] += n;
    st->level_energy[g->level] += e;
    if (!ranked(st->ps, g)) return;
    st->candidates += n;
    if (st->ehist)
        for (size_t i = 0; i < n; i++) {
            uint32_t k = key_of(d[i], w, i) >> 16;
            st->hist[k]++;
            st->ehist[k] += (double)d[i] * d[i];
        }
    else if (st->hist)
        for (size_t i = 0; i < n; i++) st->hist[key_of(d[i], w, i) >> 16]++;
}

/* ---- pass 2: low-16-bit histogram inside one top bin ------------------------------- */

typedef struct sub {
    const pass *ps;
    uint32_t bin;
    uint32_t *hist;
    double *ehist;
} sub;

static void sub_seg(void *arg, const wvol__seg *g, size_t base, const float *d, const float *w)
{
    sub *sb = arg;
    size_t n = g->x1 - g->x0;
    (void)base;
    if (!ranked(sb->ps, g)) return;
    for (size_t i = 0; i < n; i++) {
        uint32_t k = key_of(d[i], w, i);
        if ((k >> 16) != sb->bin) continue;
        sb->hist[k & 0xffffu]++;
        if (sb->ehist) sb->ehist[k & 0xffffu] += (double)d[i] * d[i];
    }
}

/* ---- pass 3: marking ------------------------------------------------------------------ */

typedef enum rule {
    RULE_ALL,        /* keep every ranked coefficient */
    RULE_NONE,       /* keep none */
    RULE_CUT,        /* key > T kept; ties at T by tie rule */
    RULE_THRESHOLD,  /* (double) key > threshold */
    RULE_NONZERO,    /* c != 0 */
    RULE_BITMAP      /* the bit of src */
} rule;

typedef enum tie { TIE_COUNT, TIE_BUDGET } tie;

typedef struct mark {
    const pass *ps;
    rule rule;
    uint32_t T;
    tie tie;
    size_t tie_need, tie_kept;    /* TIE_COUNT */
    double E_lt, E_T, D, tie_cum; /* TIE_BUDGET: keep a tie while E_lt + E_T - tie_cum > D */
    double threshold;
    const uint64_t *src;
    uint64_t *bits;
    size_t kept;
    size_t level_kept[WVOL_SELECT_MAX_LEVELS + 1];
    double level_energy_kept[WVOL_SELECT_MAX_LEVELS + 1];
    double energy_kept, energy_dropped;
    float min_key;
    int any_key;
} mark;

static void mark_seg(void *arg, const wvol__seg *g, size_t base, const float *d, const float *w)
{
    mark *mk = arg;
    size_t n = g->x1 - g->x0, kept = 0;
    double ek = 0.0, ed = 0.0;
    uint64_t *bits = mk->bits;
    if (g->level == 0 || !ranked(mk->ps, g)) {
        int keep = g->level == 0;
        for (size_t i = 0; i < n; i++) {
            double e = (double)d[i] * d[i];
            if (keep) ek += e, bits[(base + i) >> 6] |= (uint64_t)1 << ((base + i) & 63);
            else ed += e;
        }
        kept = keep ? n : 0;
    } else {
        for (size_t i = 0; i < n; i++) {
            double e = (double)d[i] * d[i];
            uint32_t k = key_of(d[i], w, i);
            int keep;
            switch (mk->rule) {
            case RULE_ALL: keep = 1; break;
            case RULE_NONE: keep = 0; break;
            case RULE_THRESHOLD: {
                float kf;
                memcpy(&kf, &k, sizeof kf);
                keep = (double)kf > mk->threshold;
                break;
            }
            case RULE_NONZERO: keep = d[i] != 0.0f; break;
            case RULE_BITMAP: keep = (int)((mk->src[(base + i) >> 6] >> ((base + i) & 63)) & 1); break;
            default:
                keep = k > mk->T;
                if (k == mk->T) {
                    if (mk->tie == TIE_COUNT) {
                        keep = mk->tie_kept < mk->tie_need;
                        mk->tie_kept += (size_t)keep;
                    } else {
                        keep = mk->E_lt + (mk->E_T - mk->tie_cum) > mk->D;
                        if (keep) mk->tie_cum += e;
                    }
                }
            }
            if (keep) {
                float kf;
                memcpy(&kf, &k, sizeof kf);
                if (!mk->any_key || kf < mk->min_key) mk->min_key = kf, mk->any_key = 1;
                bits[(base + i) >> 6] |= (uint64_t)1 << ((base + i) & 63);
                kept++;
                ek += e;
            } else {
                ed += e;
            }
        }
    }
    mk->kept += kept;
    mk->level_kept[g->level] += kept;
    mk->level_energy_kept[g->level] += ek;
    mk->energy_kept += ek;
    mk->energy_dropped += ed;
}

/* ---- report helpers -------------------------------------------------------------------- */

static double psnr_of(double peak, double rmse)
{
    if (rmse == 0.0) return INFINITY;
    if (!(peak > 0.0)) return 0.0;
    return 20.0 * log10(peak / rmse);
}

/* float32's share of a reconstruction's squared error for data on a large offset (the one the
 * transforms took out and put into the low-pass band: wavelet_bricks.h, "DC offset"); 0 for data
 * near 0, whose reconstruction float32 rounds far below anything a selection drops */
static double float_floor_sse(const wvol_coeffs *c)
{
    const size_t p[3] = {c->px, c->py, c->pz};
    const float mu = wvol__lowpass_offset(c->data, p, c->levels);
    if (mu == 0.0f) return 0.0;
    return wvol__f32_floor_sse(fabs((double)mu) / wvol__dc_gain_f32(c->filter, c->levels, p),
                               (double)c->nx * (double)c->ny * (double)c->nz, c->filter, c->levels, p);
}

static void fill_report(wvol_select_report *rep, const wvol_coeffs *c, const wvol__layout *ly, const stats *st,
                        const mark *mk, double peak)
{
    size_t nvox = c->nx * c->ny * c->nz;
    memset(rep, 0, sizeof *rep);
    rep->total = ly->N;
    rep->kept = mk->kept;
    rep->kept_lowpass = st->level_total[0];
    rep->candidates = st->candidates;
    rep->key_cut = mk->any_key ? mk->min_key : 0.0;
    for (int m = 0; m <= ly->levels; m++) rep->energy_total += st->level_energy[m];
    rep->energy_kept = mk->energy_kept;
    rep->energy_dropped = mk->energy_dropped;
    rep->predicted_l2 = sqrt(mk->energy_dropped + float_floor_sse(c));
    rep->predicted_rmse = rep->predicted_l2 / sqrt((double)nvox);
    rep->peak = peak;
    rep->predicted_psnr = psnr_of(peak, rep->predicted_rmse);
    rep->levels = ly->levels;
    for (int m = 0; m <= ly->levels; m++) {
        rep->level_total[m] = st->level_total[m];
        rep->level_kept[m] = mk->level_kept[m];
        rep->level_energy[m] = st->level_energy[m];
        rep->level_energy_kept[m] = mk->level_energy_kept[m];
    }
}

static double volume_peak(const wvol_volume *v)
{
    double lo, hi;
    wvol_volume_range(v, &lo, &hi, NULL);
    return hi - lo;
}

/* f64 reconstruction of the coefficients c restricted (keep = 1) or
 * complemented (keep = 0) by the selection bits (bits NULL: all). */
static wvol_status recon64(double **out, const wvol_coeffs *c, const wvol__layout *ly, const uint64_t *bits,
                           int keep, wvol_error *err)
{
    double *x = wvol__malloc_large(ly->N * sizeof *x);
    wvol_status s;
    *out = NULL;
    WVOL_RETURN_IF(!x, err, WVOL_ERR_NOMEM, "selection: out of memory for a reconstruction (%zu values)", ly->N);
#pragma omp parallel for schedule(static)
    for (long long ii = 0; ii < (long long)ly->N; ii++) {
        size_t i = (size_t)ii;
        int in = bits ? (int)((bits[i >> 6] >> (i & 63)) & 1) : 1;
        x[i] = (in == keep || !bits) ? (double)c->data[i] : 0.0;
    }
    s = wvol_idwt3_inplace_f64(x, ly->P[0], ly->P[1], ly->P[2], c->filter, ly->levels, err);
    if (s != WVOL_OK) {
        free(x);
        return s;
    }
    *out = x;
    return WVOL_OK;
}

static double array_peak(const double *x, const wvol_coeffs *c)
{
    double lo = INFINITY, hi = -INFINITY;
    for (size_t k = 0; k < c->nz; k++)
        for (size_t j = 0; j < c->ny; j++) {
            const double *row = x + c->px * (j + c->py * k);
            for (size_t i = 0; i < c->nx; i++) {
                if (row[i] < lo) lo = row[i];
                if (row[i] > hi) hi = row[i];
            }
        }
    return hi - lo;
}

static wvol_status check_original(const wvol_coeffs *c, const wvol_volume *v, wvol_error *err)
{
    if (!v) return WVOL_OK;
    WVOL_RETURN_IF(!v->data || v->nx != c->nx || v->ny != c->ny || v->nz != c->nz, err, WVOL_ERR_DIMS,
                   "selection: original volume %zu x %zu x %zu does not match the coefficients' %zu x %zu x %zu",
                   v->nx, v->ny, v->nz, c->nx, c->ny, c->nz);
    return WVOL_OK;
}

static wvol_status full_peak(double *peak, const wvol_coeffs *c, const wvol__layout *ly, const wvol_volume *v,
                             wvol_error *err)
{
    double *x;
    if (v) {
        *peak = volume_peak(v);
        return WVOL_OK;
    }
    WVOL_FORWARD(recon64(&x, c, ly, NULL, 1, err));
    *peak = array_peak(x, c);
    free(x);
    return WVOL_OK;
}

/* ---- public ------------------------------------------------------------------------------- */

static wvol_status check_params(const wvol_select_params *prm, const wvol_coeffs *c, wvol_error *err)
{
    WVOL_RETURN_IF(!prm, err, WVOL_ERR_ARG, "selection: params are NULL");
    WVOL_RETURN_IF((int)prm->mode < WVOL_SELECT_ALL || (int)prm->mode > WVOL_SELECT_PSNR, err, WVOL_ERR_ARG,
                   "selection: unknown mode %d", (int)prm->mode);
    WVOL_RETURN_IF(prm->mode == WVOL_SELECT_FRACTION && !(prm->fraction >= 0.0 && prm->fraction <= 1.0), err,
                   WVOL_ERR_ARG, "selection: fraction %g is not in [0, 1]", prm->fraction);
    WVOL_RETURN_IF(prm->mode == WVOL_SELECT_ENERGY && !(prm->energy >= 0.0 && prm->energy <= 1.0), err,
                   WVOL_ERR_ARG, "selection: energy share %g is not in [0, 1]", prm->energy);
    WVOL_RETURN_IF(prm->mode == WVOL_SELECT_THRESHOLD && !(prm->threshold >= 0.0 && isfinite(prm->threshold)),
                   err, WVOL_ERR_ARG, "selection: threshold %g must be finite and >= 0", prm->threshold);
    WVOL_RETURN_IF(prm->mode == WVOL_SELECT_PSNR && !isfinite(prm->psnr), err, WVOL_ERR_ARG,
                   "selection: PSNR target %g is not finite", prm->psnr);
    WVOL_RETURN_IF(!isfinite(prm->peak), err, WVOL_ERR_ARG, "selection: peak %g is not finite", prm->peak);
    WVOL_RETURN_IF(prm->drop_levels < 0 || prm->drop_levels >= c->levels, err, WVOL_ERR_ARG,
                   "selection: drop_levels = %d (0..%d for %d levels)", prm->drop_levels, c->levels - 1,
                   c->levels);
    return wvol__lod_validate(prm, err);
}

static wvol_status alloc_selection(wvol_selection **out, const wvol__layout *ly, wvol_error *err)
{
    wvol_selection *s = calloc(1, sizeof *s);
    *out = NULL;
    if (s) s->bits = wvol__calloc_large((ly->N + 63) / 64, sizeof *s->bits); /* huge pages from 1 MiB */
    if (!s || !s->bits) {
        if (s) free(s);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "selection: out of memory for %zu bits", ly->N);
    }
    s->ly = *ly;
    *out = s;
    return WVOL_OK;
}

/* Walks the top histogram from the top for the bin holding the K-th largest key
 * (K >= 1): returns the bin, *above = count in higher bins. */
static uint32_t bin_from_top(const uint32_t *h, size_t K, size_t *above)
{
    size_t cum = 0;
    for (int b = NBIN - 1; b >= 0; b--) {
        if (cum + h[b] >= K) {
            *above = cum;
            return (uint32_t)b;
        }
        cum += h[b];
    }
    *above = cum;
    return 0;
}

/* Walks an energy histogram from the bottom for the first bin whose inclusion
 * pushes the cumulative energy past D: returns it (or -1), *below = energy under it. */
static int bin_from_bottom(const double *e, const uint32_t *h, double start, double D, double *below)
{
    double cum = start;
    int last = -1;
    for (int b = 0; b < NBIN; b++) {
        if (!h[b]) continue;
        last = b;
        if (cum + e[b] > D) {
            *below = cum;
            return b;
        }
        cum += e[b];
    }
    *below = cum;
    return last < 0 ? -1 : -2 - last; /* -2 - last: nothing exceeded (rounding); last bin */
}

wvol_status wvol_select(wvol_selection **out, const wvol_coeffs *c, const wvol_select_params *prm,
                        const wvol_volume *original, wvol_select_report *rep, wvol_error *err)
{
    wvol__layout ly;
    wvol__segplan sp;
    wvol__lodw lw;
    wvol_selection *sel = NULL;
    stats st;
    mark mk;
    pass ps;
    uint32_t *hist = NULL, *h2 = NULL;
    double *ehist = NULL, *e2 = NULL, peak = prm && prm->peak > 0.0 ? prm->peak : 0.0;
    wvol_status s;
    int want_energy, want_hist;

    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_select: out is NULL");
    *out = NULL;
    WVOL_FORWARD(wvol__layout_init(&ly, c, err));
    WVOL_FORWARD(check_params(prm, c, err));
    WVOL_FORWARD(check_original(c, original, err));
    if (peak == 0.0 && (prm->mode == WVOL_SELECT_PSNR || original))
        WVOL_FORWARD(full_peak(&peak, c, &ly, original, err));
    /* a constant volume has no peak: a PSNR target would keep every rounding residue */
    WVOL_RETURN_IF(prm->mode == WVOL_SELECT_PSNR && !(peak > 0.0), err, WVOL_ERR_ARG,
                   "selection: the volume is constant; PSNR %g (peak = range) is undefined: keep a count, a "
                   "fraction or an energy share instead", prm->psnr);

    WVOL_FORWARD(wvol__segplan_init(&sp, &ly, err));
    if ((s = wvol__lod_weights(&lw, c, &ly, prm, err)) != WVOL_OK) {
        wvol__segplan_free(&sp);
        return s;
    }
    ps.c = c, ps.sp = &sp, ps.lw = &lw, ps.drop_levels = prm->drop_levels;
    want_hist = prm->mode == WVOL_SELECT_COUNT || prm->mode == WVOL_SELECT_FRACTION ||
                prm->mode == WVOL_SELECT_ENERGY || prm->mode == WVOL_SELECT_PSNR;
    want_energy = prm->mode == WVOL_SELECT_ENERGY || prm->mode == WVOL_SELECT_PSNR;
    if (want_hist) {
        hist = calloc(NBIN, sizeof *hist), h2 = calloc(NBIN, sizeof *h2);
        if (want_energy) ehist = calloc(NBIN, sizeof *ehist), e2 = calloc(NBIN, sizeof *e2);
        if (!hist || !h2 || (want_energy && (!ehist || !e2))) {
            s = wvol_error_set(err, WVOL_ERR_NOMEM, "selection: out of memory");
            goto done;
        }
    }
    memset(&st, 0, sizeof st);
    st.ps = &ps, st.hist = hist, st.ehist = ehist;
    for_each_seg(&ps, stats_seg, &st);
    if (st.nonfinite) {
        size_t i = st.nonfinite - 1;
        s = wvol_error_set(err, WVOL_ERR_NONFINITE, "selection: coefficient %zu (x %zu, y %zu, z %zu) is not finite",
                           i, i % ly.P[0], (i / ly.P[0]) % ly.P[1], i / ly.P[0] / ly.P[1]);
        goto done;
    }

    memset(&mk, 0, sizeof mk);
    mk.ps = &ps;
    mk.rule = RULE_ALL;
    if (prm->mode == WVOL_SELECT_THRESHOLD) {
        mk.rule = RULE_THRESHOLD;
        mk.threshold = prm->threshold;
    } else if (prm->mode == WVOL_SELECT_COUNT || prm->mode == WVOL_SELECT_FRACTION) {
        size_t K = prm->mode == WVOL_SELECT_COUNT ? prm->count : (size_t)llround(prm->fraction * (double)ly.N);
        size_t Kd = K > st.level_total[0] ? K - st.level_total[0] : 0, above, above2;
        if (Kd == 0) {
            mk.rule = RULE_NONE;
        } else if (Kd < st.candidates) {
            sub sb = {&ps, 0, h2, NULL};
            uint32_t B = bin_from_top(hist, Kd, &above), lo;
            sb.bin = B;
            for_each_seg(&ps, sub_seg, &sb);
            lo = bin_from_top(h2, Kd - above, &above2);
            mk.rule = RULE_CUT, mk.tie = TIE_COUNT;
            mk.T = (B << 16) | lo;
            mk.tie_need = Kd - above - above2;
        }
    } else if (want_energy) {
        double total = 0.0, D, below, below2;
        int B;
        for (int m = 0; m <= ly.levels; m++) total += st.level_energy[m];
        if (prm->mode == WVOL_SELECT_ENERGY) {
            D = total - prm->energy * total;
        } else {
            double rmse = peak * pow(10.0, -prm->psnr / 20.0), fl = float_floor_sse(c);
            D = (double)(c->nx * c->ny * c->nz) * rmse * rmse;
            if (fl > 0.5 * D) {
                s = wvol_error_set(err, WVOL_ERR_ARG,
                                   "selection: PSNR %g: the volume sits on an offset where float32 alone rounds the "
                                   "reconstruction to about %.1f dB; give a lower PSNR, or the volume less its offset",
                                   prm->psnr, psnr_of(peak, sqrt(fl / (double)(c->nx * c->ny * c->nz))));
                goto done;
            }
            D -= fl; /* the budget of what the selection drops: float32 takes its share first */
        }
        /* energy that is dropped regardless: the cut levels */
        double fixed = 0.0;
        for (int m = 1; m <= prm->drop_levels; m++) fixed += st.level_energy[m];
        B = bin_from_bottom(ehist, hist, fixed, D, &below);
        if (B == -1 || B <= -2) {
            mk.rule = RULE_NONE; /* every ranked coefficient fits in the budget */
        } else {
            sub sb = {&ps, (uint32_t)B, h2, e2};
            int lo;
            for_each_seg(&ps, sub_seg, &sb);
            lo = bin_from_bottom(e2, h2, below, D, &below2);
            if (lo <= -2) { /* rounding: the sub-bins did not exceed; cut at the bin's last key */
                lo = -2 - lo;
                below2 -= e2[lo];
            }
            mk.rule = RULE_CUT, mk.tie = TIE_BUDGET;
            mk.T = ((uint32_t)B << 16) | (uint32_t)lo;
            mk.E_lt = below2, mk.E_T = e2[lo], mk.D = D;
        }
    }
    s = alloc_selection(&sel, &ly, err);
    if (s != WVOL_OK) goto done;
    mk.bits = sel->bits;
    for_each_seg(&ps, mark_seg, &mk);
    sel->kept = mk.kept;
    if (rep) {
        fill_report(rep, c, &ly, &st, &mk, peak);
        if (prm->measure && (s = wvol_selection_measure(sel, c, original, rep, err)) != WVOL_OK) {
            wvol_selection_destroy(sel);
            sel = NULL;
            goto done;
        }
    }
    *out = sel;
done:
    free(hist), free(h2), free(ehist), free(e2);
    wvol__lod_free(&lw);
    wvol__segplan_free(&sp);
    return s;
}

/* Shared by the bitmap and nonzero constructors. */
static wvol_status select_by_rule(wvol_selection **out, const wvol_coeffs *c, rule r, const uint64_t *src,
                                  wvol_select_report *rep, wvol_error *err)
{
    wvol__layout ly;
    wvol__segplan sp;
    wvol_selection *sel = NULL;
    stats st;
    mark mk;
    pass ps;
    wvol_status s;
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "selection: out is NULL");
    *out = NULL;
    WVOL_FORWARD(wvol__layout_init(&ly, c, err));
    WVOL_FORWARD(wvol__segplan_init(&sp, &ly, err));
    ps.c = c, ps.sp = &sp, ps.lw = NULL, ps.drop_levels = 0;
    if ((s = alloc_selection(&sel, &ly, err)) != WVOL_OK) {
        wvol__segplan_free(&sp);
        return s;
    }
    memset(&mk, 0, sizeof mk);
    mk.ps = &ps, mk.rule = r, mk.src = src, mk.bits = sel->bits;
    for_each_seg(&ps, mark_seg, &mk);
    sel->kept = mk.kept;
    if (rep) {
        memset(&st, 0, sizeof st);
        st.ps = &ps;
        for_each_seg(&ps, stats_seg, &st);
        fill_report(rep, c, &ly, &st, &mk, 0.0);
    }
    wvol__segplan_free(&sp);
    *out = sel;
    return WVOL_OK;
}

wvol_status wvol_selection_from_bitmap(wvol_selection **out, const wvol_coeffs *c, const uint64_t *bits,
                                       wvol_select_report *rep, wvol_error *err)
{
    WVOL_RETURN_IF(!bits, err, WVOL_ERR_ARG, "wvol_selection_from_bitmap: bits are NULL");
    return select_by_rule(out, c, RULE_BITMAP, bits, rep, err);
}

wvol_status wvol__selection_nonzero(wvol_selection **out, const wvol_coeffs *c, wvol_error *err)
{
    return select_by_rule(out, c, RULE_NONZERO, NULL, NULL, err);
}

void wvol_selection_destroy(wvol_selection *s)
{
    if (!s) return;
    free(s->bits);
    free(s);
}

size_t wvol_selection_total(const wvol_selection *s) { return s ? s->ly.N : 0; }
size_t wvol_selection_kept(const wvol_selection *s) { return s ? s->kept : 0; }

int wvol_selection_is_kept(const wvol_selection *s, size_t i)
{
    if (!s || i >= s->ly.N) return 0;
    return (int)((s->bits[i >> 6] >> (i & 63)) & 1);
}

const uint64_t *wvol_selection_bits(const wvol_selection *s) { return s ? s->bits : NULL; }

static wvol_status check_match(const wvol_selection *s, const wvol_coeffs *c, wvol__layout *ly, wvol_error *err)
{
    WVOL_RETURN_IF(!s, err, WVOL_ERR_ARG, "selection is NULL");
    WVOL_FORWARD(wvol__layout_init(ly, c, err));
    WVOL_RETURN_IF(ly->N != s->ly.N || ly->levels != s->ly.levels || ly->P[0] != s->ly.P[0] ||
                       ly->P[1] != s->ly.P[1] || ly->P[2] != s->ly.P[2],
                   err, WVOL_ERR_DIMS, "selection was made for %zu x %zu x %zu, %d levels; coefficients are %zu x %zu x %zu, %d levels",
                   s->ly.P[0], s->ly.P[1], s->ly.P[2], s->ly.levels, ly->P[0], ly->P[1], ly->P[2], ly->levels);
    return WVOL_OK;
}

wvol_status wvol_selection_apply(const wvol_selection *s, wvol_coeffs *c, wvol_error *err)
{
    wvol__layout ly;
    WVOL_FORWARD(check_match(s, c, &ly, err));
#pragma omp parallel for schedule(static)
    for (long long ww = 0; ww < (long long)((ly.N + 63) / 64); ww++) {
        size_t w = (size_t)ww, i0 = w * 64, n = ly.N - i0 < 64 ? ly.N - i0 : 64;
        uint64_t b = s->bits[w];
        if (b == ~(uint64_t)0) continue;
        for (size_t i = 0; i < n; i++)
            if (!((b >> i) & 1)) c->data[i0 + i] = 0.0f;
    }
    return WVOL_OK;
}

wvol_status wvol_selection_measure(const wvol_selection *s, const wvol_coeffs *c, const wvol_volume *original,
                                   wvol_select_report *rep, wvol_error *err)
{
    wvol__layout ly;
    double *x, sum = 0.0, mx = 0.0;
    size_t nvox = c ? c->nx * c->ny * c->nz : 0;
    WVOL_RETURN_IF(!rep, err, WVOL_ERR_ARG, "wvol_selection_measure: report is NULL");
    WVOL_FORWARD(check_match(s, c, &ly, err));
    WVOL_FORWARD(check_original(c, original, err));
    if (!(rep->peak > 0.0)) WVOL_FORWARD(full_peak(&rep->peak, c, &ly, original, err));
    /* with the original: error = original - recon(kept); without: error = recon(dropped), in f64 */
    WVOL_FORWARD(recon64(&x, c, &ly, s->bits, original ? 1 : 0, err));
    for (size_t k = 0; k < c->nz; k++)
        for (size_t j = 0; j < c->ny; j++) {
            const double *row = x + c->px * (j + c->py * k);
            const float *orow = original ? original->data + c->nx * (j + c->ny * k) : NULL;
            for (size_t i = 0; i < c->nx; i++) {
                double e = orow ? (double)orow[i] - row[i] : row[i];
                sum += e * e;
                if (fabs(e) > mx) mx = fabs(e);
            }
        }
    free(x);
    rep->measured = 1;
    rep->measured_l2 = sqrt(sum);
    rep->measured_rmse = rep->measured_l2 / sqrt((double)nvox);
    rep->measured_max = mx;
    rep->measured_psnr = psnr_of(rep->peak, rep->measured_rmse);
    rep->predicted_psnr = psnr_of(rep->peak, rep->predicted_rmse);
    return WVOL_OK;
}
