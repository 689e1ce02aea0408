/* Wavelet engine: filters, 1D and 3D periodic transforms, partial reconstruction. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "wvol/wavelet.h"

/* Every filter: sum h = sqrt2, orthonormal to < 1e-12 (bl3: its reported defect < 1e-8,
 * the price of truncating at 1e-10), g from h, the stated vanishing moments hold
 * (sum (-1)^n n^k h[n] = 0 for k < vm, relative to sum |n^k h[n]|), and the centre is
 * sum n h[n] / sqrt2. */
static void filters_are_orthonormal_qmf(void)
{
    int count = wvol_filter_count();
    CHECK(count == 17, "17 filters, got %d", count);
    for (int i = 0; i < count; i++) {
        const wvol_filter *f = wvol_filter_at(i), *g = NULL;
        double sum = 0.0, m1 = 0.0;
        int bl = f->family == WVOL_BATTLE_LEMARIE;
        for (int n = 0; n < f->length; n++) sum += f->h[n], m1 += n * f->h[n];
        CHECK_NEAR(sum, sqrt(2.0), 1e-14, f->name);
        CHECK(f->defect < (bl ? 1e-8 : 1e-12), "%s defect %g", f->name, f->defect);
        CHECK(f->defect >= 0.0, "%s defect %g", f->name, f->defect);
        CHECK_NEAR(f->center, m1 / sqrt(2.0), 1e-12, f->name);
        for (int n = 0; n < f->length; n++)
            CHECK(f->g[n] == ((n & 1) ? -1.0 : 1.0) * f->h[f->length - 1 - n], "%s g[%d]", f->name, n);
        for (int k = 0; k < f->vanishing_moments; k++) {
            double acc = 0.0, mag = 0.0;
            for (int n = 0; n < f->length; n++) {
                double t = pow(n - f->center, k) * f->g[n];
                acc += t;
                mag += fabs(t);
            }
            /* db10's 9th moment sums terms of size 1e9: relative 1e-9 (bl3: 1e-6, truncation) */
            CHECK(fabs(acc) <= (bl ? 1e-6 : 1e-9) * mag, "%s moment %d: %g of %g", f->name, k, acc, mag);
        }
        CHECK(wvol_filter_get(&g, f->name, NULL) == WVOL_OK && g == f, "lookup %s", f->name);
    }
    const wvol_filter *f = NULL;
    wvol_error err;
    CHECK(wvol_filter_get(&f, "db11", &err) == WVOL_ERR_ARG && f == NULL, "db11 refused");
    CHECK(strstr(err.message, "db11") != NULL, "message names it: %s", err.message);
    CHECK(wvol_filter_get(&f, NULL, NULL) == WVOL_ERR_ARG, "NULL name refused");
    CHECK(wvol_filter_get(NULL, "db2", NULL) == WVOL_ERR_ARG, "NULL out refused");
    CHECK(wvol_filter_at(-1) == NULL && wvol_filter_at(count) == NULL, "out of range index");
    wvol_filter_get(&f, "haar", NULL);
    CHECK_NEAR(f->center, 0.5, 1e-15, "haar centre");
}

int main(void)
{
    filters_are_orthonormal_qmf();
    return check_summary("test_wavelet");
}
