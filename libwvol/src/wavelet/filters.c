/* SPDX-License-Identifier: MIT */
/* The filter catalogue: Haar, Daubechies db1..db10, Coiflets coif1..coif5 (published
 * values, filter_tables.h) and Battle-Lemarie bl3 (computed from its Fourier form).
 * Everything derived (g, defect, centre, BL taps) is computed once, under pthread_once,
 * so lookup is thread-safe and the returned filters are immutable afterwards. bl3 is the
 * catalogue's last entry. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>

#include "wavelet/filter_tables.h"
#include "wavelet/wavelet_internal.h"

enum { NFILTERS = 1 + 10 + 5 + 1 };

typedef struct filter_src {
    const char *name;
    wvol_family family;
    int order;
    const double *h;
    int length;
    int vanishing_moments;
} filter_src;

static const double h_haar[2] = {0.70710678118654757, 0.70710678118654757};

#define DB(n) {"db" #n, WVOL_FAMILY_DAUBECHIES, n, wvol__h_db##n, 2 * n, n}
#define COIF(n) {"coif" #n, WVOL_FAMILY_COIFLET, n, wvol__h_coif##n, 6 * n, 2 * n}
static const filter_src sources[NFILTERS] = {
    {"haar", WVOL_FAMILY_HAAR, 1, h_haar, 2, 1},
    DB(1), DB(2), DB(3), DB(4), DB(5), DB(6), DB(7), DB(8), DB(9), DB(10),
    COIF(1), COIF(2), COIF(3), COIF(4), COIF(5),
    /* bl3: the cubic spline space reproduces cubics, so psi has 4 vanishing moments
     * (approximately, after truncation). h is filled in at init. */
    {"bl3", WVOL_FAMILY_BATTLE_LEMARIE, 3, NULL, 0, 4},
};

static wvol_filter filters[NFILTERS];
static double gbuf[NFILTERS][WVOL__MAX_TAPS];
static double blbuf[WVOL__MAX_TAPS];
/* the published filters at once; bl3, whose Fourier construction (thousands of samples of its
 * transfer function and a cosine sum per tap) no other filter needs, only when it is asked
 * for (by name or by enumerating the catalogue) */
static pthread_once_t once = PTHREAD_ONCE_INIT, once_bl = PTHREAD_ONCE_INIT;
static int bl_ok; /* bl3 built (else dropped from the catalogue) */

double wvol__filter_defect(const double *h, int length)
{
    double worst = 0.0;
    for (int k = 0; 2 * k < length; k++) {
        double acc = 0.0;
        for (int n = 0; n + 2 * k < length; n++) acc += h[n] * h[n + 2 * k];
        acc -= (k == 0);
        if (fabs(acc) > worst) worst = fabs(acc);
    }
    return worst;
}

/* filters[i] from sources[i] with taps h[0 .. len) */
static void build_filter(int i, const double *h, int len)
{
    const filter_src *s = &sources[i];
    wvol_filter *f = &filters[i];
    double m1 = 0.0;
    int n;
    memset(f, 0, sizeof *f);
    snprintf(f->name, sizeof f->name, "%s", s->name);
    f->family = s->family;
    f->order = s->order;
    f->length = len;
    f->h = h;
    for (n = 0; n < len; n++) gbuf[i][n] = ((n & 1) ? -1.0 : 1.0) * h[len - 1 - n];
    f->g = gbuf[i];
    f->vanishing_moments = s->vanishing_moments;
    f->defect = wvol__filter_defect(h, len);
    /* Centre s = int x phi(x) dx. From phi(t) = sqrt2 sum h[n] phi(2t - n) and
     * int phi = 1: M1 = (sqrt2/4) sum h[n] (M1 + n) = M1/2 + (sqrt2/4) sum n h[n],
     * so M1 = sum n h[n] / sqrt2 (Haar: 1/2; a symmetric filter: its centre tap). */
    for (n = 0; n < len; n++) m1 += n * h[n];
    f->center = m1 / sqrt(2.0);
}

static void init_filters(void)
{
    for (int i = 0; i < NFILTERS - 1; i++) build_filter(i, sources[i].h, sources[i].length);
}

static void init_bl(void)
{
    int len = 0;
    if (wvol__bl_compute(sources[NFILTERS - 1].order, 1e-10, blbuf, WVOL__MAX_TAPS, &len) != 0) return;
    build_filter(NFILTERS - 1, blbuf, len);
    bl_ok = 1;
}

/* The catalogue's size, every filter built. */
static int catalogue(void)
{
    pthread_once(&once, init_filters);
    pthread_once(&once_bl, init_bl);
    return NFILTERS - 1 + bl_ok;
}

const char *wvol_family_name(wvol_family f)
{
    switch (f) {
    case WVOL_FAMILY_HAAR: return "haar";
    case WVOL_FAMILY_DAUBECHIES: return "daubechies";
    case WVOL_FAMILY_COIFLET: return "coiflet";
    case WVOL_FAMILY_BATTLE_LEMARIE: return "battle-lemarie";
    }
    return "?";
}

int wvol_filter_count(void) { return catalogue(); }

const wvol_filter *wvol_filter_at(int i) { return (i >= 0 && i < catalogue()) ? &filters[i] : NULL; }

wvol_status wvol_filter_get(const wvol_filter **out, const char *name, wvol_error *err)
{
    WVOL_RETURN_IF(!out, err, WVOL_ERR_ARG, "wvol_filter_get: out is NULL");
    *out = NULL;
    WVOL_RETURN_IF(!name, err, WVOL_ERR_ARG, "wvol_filter_get: name is NULL");
    pthread_once(&once, init_filters);
    for (int i = 0; i < NFILTERS - 1; i++)
        if (!strcmp(filters[i].name, name)) {
            *out = &filters[i];
            return WVOL_OK;
        }
    if (!strcmp(name, sources[NFILTERS - 1].name)) {
        pthread_once(&once_bl, init_bl);
        WVOL_RETURN_IF(!bl_ok, err, WVOL_ERR_INTERNAL, "filter 'bl3': Fourier construction failed");
        *out = &filters[NFILTERS - 1];
        return WVOL_OK;
    }
    return wvol_error_set(err, WVOL_ERR_ARG,
                          "unknown wavelet '%s' (haar, db1..db10, coif1..coif5, bl3)", name);
}
