/* SPDX-License-Identifier: MIT */
/* Energy selection (libwvol/src/store/select.c, lod.c): every mode against a
 * brute-force sort, Parseval's predicted error against the measured one, the
 * PSNR target, local level of detail and its region property, bad parameters. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fixtures.h"
#include "wvol/store.h"
#include "wvol/wavelet.h"

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static double urand(void) { return fixture_urand(&rng_state); }

/* Coefficients with arbitrary values: `quant` > 0 rounds them to multiples of
 * 1/quant (small integers: exact energies, many ties), zero_share of them 0. */
static wvol_coeffs *random_coeffs(const char *fname, int levels, size_t nx, size_t ny, size_t nz, double quant,
                                  double zero_share)
{
    wvol_coeffs *c = NULL;
    if (wvol_coeffs_create(&c, fixture_filter(fname), levels, nx, ny, nz, NULL) != WVOL_OK) return NULL;
    size_t n = c->px * c->py * c->pz;
    for (size_t i = 0; i < n; i++) {
        double v = (urand() - 0.5) * 8.0 * pow(urand(), 3.0);
        if (quant > 0) v = round(v * quant) / quant;
        if (urand() < zero_share) v = 0.0;
        c->data[i] = (float)v;
    }
    c->spacing[0] = 1.0, c->spacing[1] = 0.5, c->spacing[2] = 2.0;
    c->origin[0] = -3.0, c->origin[1] = 1.0, c->origin[2] = 0.25;
    return c;
}

/* ---- brute force ---------------------------------------------------------------------- */

typedef struct item {
    float key;
    size_t idx;
    double e;
} item;

static int by_key_desc(const void *a, const void *b)
{
    const item *x = a, *y = b;
    if (x->key != y->key) return x->key > y->key ? -1 : 1;
    return x->idx < y->idx ? -1 : x->idx > y->idx;
}

/* Ranked items of c under prm (key = |c| * float(w(support centre))), the
 * low-pass mask, and energies. */
static item *ranked_items(const wvol_coeffs *c, const wvol_select_params *prm, size_t *n, unsigned char *lowpass,
                          double *total, double *fixed_drop)
{
    size_t N = c->px * c->py * c->pz, k = 0;
    item *it = malloc(N * sizeof *it);
    double s = c->filter->center;
    int L = c->filter->length;
    *total = 0, *fixed_drop = 0;
    memset(lowpass, 0, N);
    for (size_t i = 0; i < N; i++) *total += (double)c->data[i] * c->data[i];
    for (int m = 1; m <= c->levels; m++)
        for (int l = (m == c->levels ? 0 : 1); l < 8; l++) {
            size_t e[3] = {c->px == 1 ? 1 : c->px >> m, c->py == 1 ? 1 : c->py >> m, c->pz == 1 ? 1 : c->pz >> m};
            size_t P[3] = {c->px, c->py, c->pz};
            int bad = 0;
            for (int a = 0; a < 3; a++)
                if (((l >> a) & 1) && P[a] == 1) bad = 1;
            if (bad) continue;
            for (size_t r = 0; r < e[2]; r++)
                for (size_t q = 0; q < e[1]; q++)
                    for (size_t p = 0; p < e[0]; p++) {
                        size_t idx = wvol_coeffs_index(c, m, l, p, q, r), pos[3] = {p, q, r};
                        double ce = (double)c->data[idx] * c->data[idx], world[3];
                        if (l == 0) {
                            lowpass[idx] = 1;
                            continue;
                        }
                        if (m <= prm->drop_levels) {
                            *fixed_drop += ce;
                            continue;
                        }
                        for (int a = 0; a < 3; a++) {
                            double x = P[a] == 1 ? 0.0 : ldexp(pos[a] + 0.5 * (L - 1), m) - s;
                            world[a] = c->origin[a] + x * c->spacing[a];
                        }
                        float w = (float)wvol_lod_weight(prm, world);
                        float key = fabsf(c->data[idx]);
                        if (prm->n_ellipsoids > 0) key *= w;
                        it[k].key = key, it[k].idx = idx, it[k].e = ce;
                        k++;
                    }
        }
    *n = k;
    qsort(it, k, sizeof *it, by_key_desc);
    return it;
}

/* Expected kept bitmap (bytes) for prm by brute force. */
static unsigned char *brute_select(const wvol_coeffs *c, const wvol_select_params *prm, double peak)
{
    size_t N = c->px * c->py * c->pz, n, nlow = 0;
    unsigned char *kept = calloc(N, 1), *low = malloc(N);
    double total, fixed;
    item *it = ranked_items(c, prm, &n, low, &total, &fixed);
    for (size_t i = 0; i < N; i++)
        if (low[i]) kept[i] = 1, nlow++;
    size_t keep = 0;
    switch (prm->mode) {
    case WVOL_SELECT_ALL: keep = n; break;
    case WVOL_SELECT_COUNT:
    case WVOL_SELECT_FRACTION: {
        size_t K = prm->mode == WVOL_SELECT_COUNT ? prm->count : (size_t)llround(prm->fraction * (double)N);
        keep = K > nlow ? K - nlow : 0;
        if (keep > n) keep = n;
        break;
    }
    case WVOL_SELECT_THRESHOLD:
        while (keep < n && (double)it[keep].key > prm->threshold) keep++;
        break;
    case WVOL_SELECT_ENERGY:
    case WVOL_SELECT_PSNR: {
        double D, cum = fixed;
        if (prm->mode == WVOL_SELECT_ENERGY) {
            D = total - prm->energy * total;
        } else {
            double rmse = peak * pow(10.0, -prm->psnr / 20.0);
            D = (double)(c->nx * c->ny * c->nz) * rmse * rmse;
        }
        keep = n; /* drop from the bottom while the budget holds */
        while (keep > 0 && cum + it[keep - 1].e <= D) cum += it[--keep].e;
        break;
    }
    }
    for (size_t i = 0; i < keep; i++) kept[it[i].idx] = 1;
    free(it), free(low);
    return kept;
}

static int same_set(const wvol_selection *sel, const unsigned char *kept, size_t N, size_t *diff)
{
    size_t d = 0, first = (size_t)-1;
    for (size_t i = 0; i < N; i++)
        if ((wvol_selection_is_kept(sel, i) != 0) != (kept[i] != 0)) {
            if (first == (size_t)-1) first = i;
            d++;
        }
    *diff = d;
    return d == 0;
}

/* ---- tests ------------------------------------------------------------------------------- */

static void check_mode(const char *what, const wvol_coeffs *c, const wvol_select_params *prm, double peak)
{
    wvol_selection *sel = NULL;
    wvol_select_report rep;
    wvol_error err;
    size_t N = c->px * c->py * c->pz, diff = 0, cnt = 0;
    wvol_status st = wvol_select(&sel, c, prm, NULL, &rep, &err);
    CHECK(st == WVOL_OK, "%s: %s", what, err.message);
    if (st != WVOL_OK) return;
    unsigned char *kept = brute_select(c, prm, peak);
    CHECK(same_set(sel, kept, N, &diff), "%s: %zu coefficients differ from the brute-force set", what, diff);
    for (size_t i = 0; i < N; i++) cnt += kept[i];
    CHECK(rep.kept == cnt && wvol_selection_kept(sel) == cnt, "%s: kept %zu, brute force %zu", what, rep.kept, cnt);
    /* energies: totals add up and the predicted error is sqrt(dropped) */
    double tot = 0, drop = 0;
    for (size_t i = 0; i < N; i++) {
        double e = (double)c->data[i] * c->data[i];
        tot += e;
        if (!kept[i]) drop += e;
    }
    CHECK_NEAR(rep.energy_total, tot, 1e-12 * tot, "energy total");
    CHECK_NEAR(rep.energy_dropped, drop, 1e-12 * tot, "energy dropped");
    CHECK_NEAR(rep.energy_kept + rep.energy_dropped, tot, 1e-12 * tot, "kept + dropped");
    CHECK_NEAR(rep.predicted_l2, sqrt(drop), 1e-12 * sqrt(tot), "predicted l2");
    size_t lk = 0;
    for (int m = 0; m <= rep.levels; m++) lk += rep.level_kept[m];
    CHECK(lk == rep.kept, "%s: per-level kept %zu sum to %zu", what, lk, rep.kept);
    free(kept);
    wvol_selection_destroy(sel);
}

/* check_mode for a mode that takes one value (fraction, threshold, energy, psnr). */
static void check_mode_value(const char *name, wvol_select_mode mode, double value, int variant,
                             const wvol_coeffs *c, double peak)
{
    wvol_select_params prm;
    wvol_select_params_default(&prm);
    char what[128];
    prm.mode = mode;
    if (mode == WVOL_SELECT_FRACTION) prm.fraction = value;
    else if (mode == WVOL_SELECT_THRESHOLD) prm.threshold = value;
    else if (mode == WVOL_SELECT_ENERGY) prm.energy = value;
    else prm.psnr = value, prm.peak = peak;
    snprintf(what, sizeof what, "%s %g (variant %d)", name, value, variant);
    check_mode(what, c, &prm, peak);
}

static void selection_modes_match_brute_force(void)
{
    /* exact small-integer values (ties everywhere, exact energies) and plain floats */
    for (int variant = 0; variant < 4; variant++) {
        double quant = variant < 2 ? 2.0 : 0.0;
        wvol_coeffs *c = variant & 1 ? random_coeffs("db2", 2, 16, 12, 8, quant, 0.2)
                                     : random_coeffs("haar", 3, 24, 16, 16, quant, 0.1);
        size_t N = c->px * c->py * c->pz;
        wvol_select_params prm;
        wvol_select_params_default(&prm);
        char what[128];
        double peak = 7.5;
        check_mode("all", c, &prm, peak);
        for (size_t K = 0; K <= N + 10; K += N / 7 + 1) {
            wvol_select_params_default(&prm);
            prm.mode = WVOL_SELECT_COUNT, prm.count = K;
            snprintf(what, sizeof what, "count %zu (variant %d)", K, variant);
            check_mode(what, c, &prm, peak);
        }
        prm.count = N - 1;
        check_mode("count N-1", c, &prm, peak);
        prm.count = (size_t)-1;
        check_mode("count huge", c, &prm, peak);
        for (double f = 0.0; f <= 1.0; f += 0.125)
            check_mode_value("fraction", WVOL_SELECT_FRACTION, f, variant, c, peak);
        double thr[] = {0.0, 0.25, 0.5, 1.0, 3.0, 100.0};
        for (int t = 0; t < 6; t++) check_mode_value("threshold", WVOL_SELECT_THRESHOLD, thr[t], variant, c, peak);
        if (quant > 0) { /* exact energies: the brute force's sums equal the histogram's */
            double es[] = {0.0, 0.5, 0.9, 0.99, 0.999, 1.0};
            for (int e = 0; e < 6; e++) check_mode_value("energy", WVOL_SELECT_ENERGY, es[e], variant, c, peak);
            double ps[] = {10.0, 20.0, 30.0, 200.0};
            for (int e = 0; e < 4; e++) check_mode_value("psnr", WVOL_SELECT_PSNR, ps[e], variant, c, peak);
        }
        /* a global level cut and an ellipsoid weight */
        wvol_select_params_default(&prm);
        prm.mode = WVOL_SELECT_COUNT, prm.count = N / 5, prm.drop_levels = 1;
        check_mode("count with drop_levels 1", c, &prm, peak);
        prm.n_ellipsoids = 2, prm.lod_floor = 0.1;
        prm.ellipsoids[0] = (wvol_lod_ellipsoid){{2, 4, 8}, {5, 3, 6}, 1};
        prm.ellipsoids[1] = (wvol_lod_ellipsoid){{10, 6, 20}, {3, 3, 3}, 4};
        check_mode("count with ellipsoids", c, &prm, peak);
        prm.drop_levels = 0, prm.mode = WVOL_SELECT_THRESHOLD, prm.threshold = 0.3;
        check_mode("threshold with ellipsoids", c, &prm, peak);
        if (quant > 0) {
            prm.mode = WVOL_SELECT_ENERGY, prm.energy = 0.95;
            check_mode("energy with ellipsoids", c, &prm, peak);
        }
        wvol_coeffs_destroy(c);
    }
}

/* Plain floats: the energy mode keeps the smallest set by rank (dropping one
 * more of the smallest kept would fall short) and reaches the share. */
static void energy_mode_is_smallest_set(void)
{
    wvol_coeffs *c = random_coeffs("db3", 2, 20, 20, 12, 0.0, 0.0);
    double shares[] = {0.3, 0.8, 0.95, 0.9999};
    for (int e = 0; e < 4; e++) {
        wvol_select_params prm;
        wvol_select_params_default(&prm);
        wvol_select_report rep;
        wvol_selection *sel = NULL;
        prm.mode = WVOL_SELECT_ENERGY, prm.energy = shares[e];
        CHECK(wvol_select(&sel, c, &prm, NULL, &rep, NULL) == WVOL_OK, "energy select");
        CHECK(rep.energy_kept >= shares[e] * rep.energy_total * (1 - 1e-12), "share %g: kept %g of %g", shares[e],
              rep.energy_kept, rep.energy_total);
        /* the smallest kept ranked coefficient is needed */
        double emin = INFINITY;
        size_t N = c->px * c->py * c->pz;
        for (size_t i = 0; i < N; i++) {
            int m, b;
            size_t p, q, r;
            wvol_coeffs_locate(c, i, &m, &b, &p, &q, &r);
            if (b != 0 && wvol_selection_is_kept(sel, i) && fabsf(c->data[i]) == (float)rep.key_cut)
                emin = fmin(emin, (double)c->data[i] * c->data[i]);
        }
        CHECK(rep.energy_kept - emin < shares[e] * rep.energy_total * (1 + 1e-12), "share %g: not minimal", shares[e]);
        wvol_selection_destroy(sel);
    }
    wvol_coeffs_destroy(c);
}

static double blob_at(const wvol_volume *v, size_t i, size_t j, size_t k, const void *noise)
{
    size_t nx = v->nx, ny = v->ny, nz = v->nz;
    double x = (i - 0.4 * nx) / (0.2 * nx), y = (j - 0.5 * ny) / (0.25 * ny), z = (k - 0.55 * nz) / (0.3 * nz);
    double f = 100.0 * exp(-(x * x + y * y + z * z)) + 20.0 * sin(0.7 * i) * cos(0.3 * j + 0.2 * k);
    return (float)(f + *(const double *)noise * (urand() - 0.5));
}

static wvol_volume *blob_volume(size_t nx, size_t ny, size_t nz, double noise)
{
    return fixture_volume(nx, ny, nz, blob_at, &noise);
}

/* Parseval: without padding, the measured error (f64 reconstruction of the
 * dropped part) equals sqrt(dropped energy) to rounding; with padding it is at
 * most that; against the original volume it agrees to float32 rounding. */
static void predicted_error_matches_measured(void)
{
    const char *fams[] = {"haar", "db2", "coif2", "bl3"};
    for (int fi = 0; fi < 4; fi++)
        for (int pad = 0; pad < 2; pad++) {
            size_t nx = pad ? 30 : 32, ny = pad ? 27 : 32, nz = pad ? 20 : 16;
            wvol_volume *v = blob_volume(nx, ny, nz, 5.0);
            wvol_coeffs *c = NULL;
            wvol_error err;
            int levels = fi == 3 ? 2 : 3;
            CHECK(wvol_dwt3_ex(&c, v, fixture_filter(fams[fi]), levels, WVOL_PAD_EDGE, 1, &err) == WVOL_OK, "%s", err.message);
            double fr[] = {0.01, 0.05, 0.3, 1.0};
            for (int t = 0; t < 4; t++) {
                wvol_select_params prm;
                wvol_select_params_default(&prm);
                wvol_select_report rep, rep2;
                wvol_selection *sel = NULL;
                prm.mode = WVOL_SELECT_FRACTION, prm.fraction = fr[t], prm.measure = 1;
                CHECK(wvol_select(&sel, c, &prm, NULL, &rep, &err) == WVOL_OK, "%s", err.message);
                CHECK(rep.measured, "measured");
                /* bl3 is orthonormal only to its truncation defect */
                double tol = (1e-10 + 10.0 * c->filter->defect) * sqrt(rep.energy_total);
                if (!pad)
                    CHECK(fabs(rep.measured_l2 - rep.predicted_l2) <= tol, "%s %g: measured %.15g predicted %.15g",
                          fams[fi], fr[t], rep.measured_l2, rep.predicted_l2);
                else
                    CHECK(rep.measured_l2 <= rep.predicted_l2 + tol, "%s %g padded: measured %.15g > predicted %.15g",
                          fams[fi], fr[t], rep.measured_l2, rep.predicted_l2);
                CHECK(rep.measured_max <= rep.predicted_l2 + tol, "max error <= l2");
                /* against the original: float32 coefficient rounding on top */
                rep2 = rep;
                CHECK(wvol_selection_measure(sel, c, v, &rep2, &err) == WVOL_OK, "%s", err.message);
                double t32 = 1e-5 * sqrt(rep.energy_total);
                CHECK(rep2.measured_l2 <= rep.predicted_l2 + t32, "%s %g vs original: %.9g > %.9g", fams[fi], fr[t],
                      rep2.measured_l2, rep.predicted_l2);
                if (!pad)
                    CHECK(fabs(rep2.measured_l2 - rep.predicted_l2) <= t32, "%s %g vs original: %.9g vs %.9g", fams[fi],
                          fr[t], rep2.measured_l2, rep.predicted_l2);
                CHECK(rep.peak > 100.0 && rep.peak < 200.0, "peak %g", rep.peak);
                if (fr[t] == 1.0) CHECK(rep.predicted_l2 == 0.0 && isinf(rep.predicted_psnr), "nothing dropped");
                wvol_selection_destroy(sel);
            }
            wvol_coeffs_destroy(c);
            wvol_volume_destroy(v);
        }
}

/* The PSNR target: predicted PSNR >= target, measured agrees (no padding),
 * and the cut is tight (the predicted PSNR is within a coefficient's worth). */
static void psnr_target_is_met(void)
{
    wvol_volume *v = blob_volume(32, 32, 32, 2.0);
    wvol_coeffs *c = NULL;
    wvol_dwt3_ex(&c, v, fixture_filter("db2"), 3, WVOL_PAD_EDGE, 1, NULL);
    double targets[] = {25.0, 35.0, 45.0, 60.0};
    size_t last = 0;
    for (int t = 0; t < 4; t++) {
        wvol_select_params prm;
        wvol_select_params_default(&prm);
        wvol_select_report rep;
        wvol_selection *sel = NULL;
        prm.mode = WVOL_SELECT_PSNR, prm.psnr = targets[t], prm.measure = 1;
        CHECK(wvol_select(&sel, c, &prm, v, &rep, NULL) == WVOL_OK, "psnr select");
        CHECK(rep.predicted_psnr >= targets[t] - 1e-9, "target %g: predicted %g", targets[t], rep.predicted_psnr);
        CHECK(rep.measured_psnr >= targets[t] - 1e-3, "target %g: measured %g", targets[t], rep.measured_psnr);
        CHECK(rep.kept > last, "higher target keeps more (%zu after %zu)", rep.kept, last);
        last = rep.kept;
        /* tight: keeping the next coefficient by rank would not be needed, i.e. dropping it
           as well would break the target; here: the dropped budget is nearly used */
        double rmse_t = rep.peak * pow(10.0, -targets[t] / 20.0), D = rmse_t * rmse_t * 32 * 32 * 32;
        CHECK(rep.energy_dropped <= D * (1 + 1e-12), "budget %g, dropped %g", D, rep.energy_dropped);
        CHECK(rep.energy_dropped + (double)rep.key_cut * rep.key_cut > D * (1 - 1e-9),
              "cut is tight: dropped %g + next %g vs budget %g", rep.energy_dropped, rep.key_cut * rep.key_cut, D);
        wvol_selection_destroy(sel);
    }
    wvol_coeffs_destroy(c);
    wvol_volume_destroy(v);
}

/* Local level of detail (docs/store.md): inside a region R the reconstruction differs from
 * the full one by at most sqrt(sum of c^2 over dropped coefficients whose
 * support reaches into R); and the ellipsoid makes R's error much smaller than
 * the error elsewhere at the same budget. */
static void lod_region_keeps_detail(void)
{
    size_t n = 48;
    wvol_volume *v = blob_volume(n, n, n, 30.0);
    wvol_coeffs *c = NULL;
    wvol_error err;
    const wvol_filter *f = fixture_filter("db2");
    int M = 3, L = f->length;
    double s = f->center, S = L - 1;
    wvol_dwt3_ex(&c, v, f, M, WVOL_PAD_EDGE, 1, NULL);
    for (int a = 0; a < 3; a++) c->spacing[a] = 0.5, c->origin[a] = 10.0;
    wvol_select_params prm;
    wvol_select_params_default(&prm);
    prm.mode = WVOL_SELECT_FRACTION, prm.fraction = 0.1;
    prm.n_ellipsoids = 1, prm.lod_floor = 0.0;
    /* centre at voxel (24, 20, 28), radius 10 voxels, flat top: it holds the centres of
       every level-1 and level-2 function that reaches into R */
    prm.ellipsoids[0] = (wvol_lod_ellipsoid){{10 + 12.0, 10 + 10.0, 10 + 14.0}, {5.0, 5.0, 5.0}, 4};
    wvol_selection *sel = NULL, *plain = NULL;
    wvol_select_report rep;
    CHECK(wvol_select(&sel, c, &prm, NULL, &rep, &err) == WVOL_OK, "%s", err.message);
    prm.n_ellipsoids = 0;
    CHECK(wvol_select(&plain, c, &prm, NULL, NULL, &err) == WVOL_OK, "%s", err.message);
    /* dropped part, reconstructed in f64 */
    size_t N = c->px * c->py * c->pz;
    double *dr = malloc(N * sizeof *dr), *dp = malloc(N * sizeof *dp);
    for (size_t i = 0; i < N; i++) {
        dr[i] = wvol_selection_is_kept(sel, i) ? 0.0 : c->data[i];
        dp[i] = wvol_selection_is_kept(plain, i) ? 0.0 : c->data[i];
    }
    wvol_idwt3_inplace_f64(dr, c->px, c->py, c->pz, f, M, NULL);
    wvol_idwt3_inplace_f64(dp, c->px, c->py, c->pz, f, M, NULL);
    size_t lo[3] = {21, 17, 25}, hi[3] = {27, 23, 31}; /* R: voxels [lo, hi] */
    double eR = 0, eRp = 0, eOut = 0;
    size_t nR = 0, nOut = 0;
    for (size_t k = 0; k < n; k++)
        for (size_t j = 0; j < n; j++)
            for (size_t i = 0; i < n; i++) {
                size_t x = i + n * (j + n * k);
                int in = i >= lo[0] && i <= hi[0] && j >= lo[1] && j <= hi[1] && k >= lo[2] && k <= hi[2];
                if (in) eR += dr[x] * dr[x], eRp += dp[x] * dp[x], nR++;
                else eOut += dr[x] * dr[x], nOut++;
            }
    /* the bound: dropped coefficients whose (periodic) support meets R */
    double bound = 0;
    for (size_t i = 0; i < N; i++) {
        int m, b;
        size_t pos[3], P[3] = {c->px, c->py, c->pz};
        if (wvol_selection_is_kept(sel, i)) continue;
        wvol_coeffs_locate(c, i, &m, &b, pos, pos + 1, pos + 2);
        int meets = 1;
        for (int a = 0; a < 3; a++) {
            double l0 = ldexp((double)pos[a], m) - s, h0 = l0 + ldexp(S, m);
            if (floor((hi[a] - l0) / P[a]) < ceil((lo[a] - h0) / P[a])) meets = 0;
        }
        if (meets) bound += (double)c->data[i] * c->data[i];
    }
    CHECK(sqrt(eR) <= sqrt(bound) * (1 + 1e-9) + 1e-9, "region error %g > bound %g", sqrt(eR), sqrt(bound));
    double rmseR = sqrt(eR / nR), rmseO = sqrt(eOut / nOut), rmseRp = sqrt(eRp / nR);
    printf("lod: region RMSE %.4g (bound %.4g), outside %.4g, region without LOD %.4g\n", rmseR,
           sqrt(bound / nR), rmseO, rmseRp);
    CHECK(rmseR < 0.2 * rmseO, "region RMSE %g vs outside %g", rmseR, rmseO);
    CHECK(rmseR < 0.2 * rmseRp, "region RMSE %g vs no-LOD %g", rmseR, rmseRp);
    free(dr), free(dp);
    wvol_selection_destroy(sel), wvol_selection_destroy(plain);
    wvol_coeffs_destroy(c);
    wvol_volume_destroy(v);
}

static void lod_weight_shape(void)
{
    wvol_select_params prm;
    wvol_select_params_default(&prm);
    double x[3] = {1, 2, 3};
    CHECK(wvol_lod_weight(&prm, x) == 1.0, "no ellipsoid: 1");
    prm.n_ellipsoids = 1, prm.lod_floor = 0.25;
    prm.ellipsoids[0] = (wvol_lod_ellipsoid){{1, 2, 3}, {1, 2, 4}, 1};
    CHECK_NEAR(wvol_lod_weight(&prm, x), 1.0, 1e-15, "centre");
    double y[3] = {2, 2, 3};
    CHECK_NEAR(wvol_lod_weight(&prm, y), 0.25 + 0.75 * exp(-0.5), 1e-15, "one sigma");
    double z[3] = {100, 2, 3};
    CHECK_NEAR(wvol_lod_weight(&prm, z), 0.25, 1e-15, "floor far away");
    prm.ellipsoids[0].power = 8;
    double w[3] = {1.5, 2, 3};
    CHECK(wvol_lod_weight(&prm, w) > 0.999, "flat top inside d < 1: %g", wvol_lod_weight(&prm, w));
}

static void bad_params_are_refused(void)
{
    wvol_coeffs *c = random_coeffs("db2", 2, 8, 8, 8, 0, 0);
    wvol_selection *sel = (wvol_selection *)&sel;
    wvol_error err;
    wvol_select_params prm;
#define REFUSE(setup, code, what)                                                                   \
    do {                                                                                            \
        wvol_select_params_default(&prm);                                                           \
        setup;                                                                                      \
        wvol_status st_ = wvol_select(&sel, c, &prm, NULL, NULL, &err);                             \
        CHECK(st_ == (code) && sel == NULL, "%s: status %d", what, (int)st_);                       \
        CHECK(err.message[0] != 0, "%s: message", what);                                             \
    } while (0)
    REFUSE(prm.mode = WVOL_SELECT_FRACTION; prm.fraction = 1.5, WVOL_ERR_ARG, "fraction 1.5");
    REFUSE(prm.mode = WVOL_SELECT_FRACTION; prm.fraction = NAN, WVOL_ERR_ARG, "fraction NaN");
    REFUSE(prm.mode = WVOL_SELECT_ENERGY; prm.energy = -0.1, WVOL_ERR_ARG, "energy -0.1");
    REFUSE(prm.mode = WVOL_SELECT_THRESHOLD; prm.threshold = NAN, WVOL_ERR_ARG, "threshold NaN");
    REFUSE(prm.mode = WVOL_SELECT_THRESHOLD; prm.threshold = -1, WVOL_ERR_ARG, "threshold -1");
    REFUSE(prm.mode = WVOL_SELECT_PSNR; prm.psnr = INFINITY, WVOL_ERR_ARG, "psnr inf");
    REFUSE(prm.mode = (wvol_select_mode)99, WVOL_ERR_ARG, "mode 99");
    REFUSE(prm.drop_levels = 2, WVOL_ERR_ARG, "drop_levels = levels");
    REFUSE(prm.drop_levels = -1, WVOL_ERR_ARG, "drop_levels -1");
    REFUSE(prm.n_ellipsoids = 1; prm.ellipsoids[0].radii[0] = 0, WVOL_ERR_ARG, "radius 0");
    REFUSE(prm.n_ellipsoids = 17, WVOL_ERR_ARG, "17 ellipsoids");
    REFUSE(prm.lod_floor = 1.5, WVOL_ERR_ARG, "floor 1.5");
    REFUSE(prm.n_ellipsoids = 1; prm.ellipsoids[0].radii[0] = prm.ellipsoids[0].radii[1] =
               prm.ellipsoids[0].radii[2] = 1;
           prm.ellipsoids[0].power = 0.5, WVOL_ERR_ARG, "power 0.5");
    wvol_select_params_default(&prm);
    CHECK(wvol_select(&sel, NULL, &prm, NULL, NULL, &err) == WVOL_ERR_ARG && sel == NULL, "NULL coeffs");
    CHECK(wvol_select(&sel, c, NULL, NULL, NULL, &err) == WVOL_ERR_ARG, "NULL params");
    CHECK(wvol_select(NULL, c, &prm, NULL, NULL, &err) == WVOL_ERR_ARG, "NULL out");
    wvol_volume *v = NULL;
    wvol_volume_create(&v, 7, 8, 8, NULL);
    CHECK(wvol_select(&sel, c, &prm, v, NULL, &err) == WVOL_ERR_DIMS, "original of another size");
    wvol_volume_destroy(v);
    c->data[77] = NAN;
    CHECK(wvol_select(&sel, c, &prm, NULL, NULL, &err) == WVOL_ERR_NONFINITE && strstr(err.message, "77"),
          "NaN coefficient named: %s", err.message);
    wvol_coeffs_destroy(c);
}

/* Empty selections, K beyond N, the bitmap constructor and apply. */
static void edge_cases(void)
{
    wvol_coeffs *c = random_coeffs("db2", 2, 16, 16, 16, 0, 0.3);
    size_t N = c->px * c->py * c->pz, nlow = 4 * 4 * 4;
    wvol_select_params prm;
    wvol_select_params_default(&prm);
    wvol_select_report rep;
    wvol_selection *sel = NULL, *b = NULL;
    prm.mode = WVOL_SELECT_COUNT, prm.count = 0;
    CHECK(wvol_select(&sel, c, &prm, NULL, &rep, NULL) == WVOL_OK && rep.kept == nlow, "count 0 keeps the low-pass cube");
    CHECK(rep.key_cut == 0.0 && rep.kept_lowpass == nlow, "no ranked kept");
    wvol_selection_destroy(sel);
    prm.count = N * 3;
    CHECK(wvol_select(&sel, c, &prm, NULL, &rep, NULL) == WVOL_OK && rep.kept == N && rep.energy_dropped == 0.0,
          "K > N keeps all");
    wvol_selection_destroy(sel);
    prm.mode = WVOL_SELECT_THRESHOLD, prm.threshold = 0;
    CHECK(wvol_select(&sel, c, &prm, NULL, &rep, NULL) == WVOL_OK, "threshold 0");
    CHECK(rep.energy_dropped == 0.0, "threshold 0 drops only zeros");
    /* the bitmap constructor gives back the same set and report */
    wvol_select_report rb;
    CHECK(wvol_selection_from_bitmap(&b, c, wvol_selection_bits(sel), &rb, NULL) == WVOL_OK, "from bitmap");
    CHECK(wvol_selection_kept(b) == wvol_selection_kept(sel) && rb.energy_dropped == rep.energy_dropped, "same set");
    CHECK(memcmp(wvol_selection_bits(b), wvol_selection_bits(sel), (N + 63) / 64 * 8) == 0, "same bits");
    wvol_selection_destroy(b);
    /* apply zeroes exactly the dropped ones */
    wvol_selection_destroy(sel);
    prm.mode = WVOL_SELECT_FRACTION, prm.fraction = 0.1;
    wvol_select(&sel, c, &prm, NULL, &rep, NULL);
    wvol_coeffs *d = NULL;
    wvol_coeffs_clone(&d, c, NULL);
    CHECK(wvol_selection_apply(sel, d, NULL) == WVOL_OK, "apply");
    size_t bad = 0;
    double e = 0;
    for (size_t i = 0; i < N; i++) {
        if (d->data[i] != (wvol_selection_is_kept(sel, i) ? c->data[i] : 0.0f)) bad++;
        e += (double)d->data[i] * d->data[i];
    }
    CHECK(bad == 0, "%zu wrong after apply", bad);
    CHECK_NEAR(e, rep.energy_kept, 1e-12 * rep.energy_total, "kept energy");
    wvol_coeffs *other = random_coeffs("db2", 2, 16, 16, 8, 0, 0);
    CHECK(wvol_selection_apply(sel, other, NULL) == WVOL_ERR_DIMS, "apply to another layout refused");
    wvol_coeffs_destroy(other);
    wvol_coeffs_destroy(d);
    wvol_selection_destroy(sel);
    CHECK(wvol_selection_kept(NULL) == 0 && !wvol_selection_is_kept(NULL, 0), "NULL selection");
    wvol_selection_destroy(NULL);
    wvol_coeffs_destroy(c);
}

/* 2D (nz = 1): the z axis is not transformed; three bands per level. */
static void planar_volumes(void)
{
    wvol_coeffs *c = random_coeffs("db2", 3, 32, 24, 1, 2.0, 0.1);
    wvol_select_params prm;
    wvol_select_params_default(&prm);
    prm.mode = WVOL_SELECT_COUNT, prm.count = 100;
    check_mode("2D count", c, &prm, 1.0);
    prm.n_ellipsoids = 1, prm.lod_floor = 0.2;
    prm.ellipsoids[0] = (wvol_lod_ellipsoid){{5, 5, 0.25}, {4, 4, 4}, 1};
    check_mode("2D count with ellipsoid", c, &prm, 1.0);
    wvol_coeffs_destroy(c);
}

int main(void)
{
    selection_modes_match_brute_force();
    energy_mode_is_smallest_set();
    predicted_error_matches_measured();
    psnr_target_is_met();
    lod_weight_shape();
    lod_region_keeps_detail();
    bad_params_are_refused();
    edge_cases();
    planar_volumes();
    return check_summary("test_select");
}
