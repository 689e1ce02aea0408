/* SPDX-License-Identifier: MIT
 * The reference integrator's tables: the transfer function per segment with the 2^(j/256)
 * table of its exponential (tf_fast, read per sample), and the brick contribution rate
 * that empty-space skipping decides by. */
#include "reference_internal.h"

/* Largest kappa of the TF over [lo, hi] (piecewise linear: endpoints and knots inside). */
static double tf_max_kappa(const wvol_tf *tf, double lo, double hi)
{
    double k, m;
    int i;
    wvol_tf_eval(tf, lo, NULL, &m);
    wvol_tf_eval(tf, hi, NULL, &k);
    if (k > m) m = k;
    for (i = 0; i < tf->count; i++)
        if (tf->points[i].value > lo && tf->points[i].value < hi && tf->points[i].opacity > m) m = tf->points[i].opacity;
    return m;
}

double wvol__brick_rate(const wvol_tf *tf, wvol_render_mode mode, double mn, double mx)
{
    if (mode == WVOL_RENDER_MODE_XRAY) return fmax(fabs(mn), fabs(mx));
    return fmax(tf_max_kappa(tf, mn, mx), 0.0);
}

void wvol__tf_fast_init(tf_fast *f, const wvol_tf *tf)
{
    int i, c;
    f->n = tf->count;
    f->grey = tf->count > 0;
    for (c = 0; c < 3; c++) f->rgb[c] = tf->count > 0 ? tf->points[0].rgb[c] : 0.0;
    for (i = 0; i < 256; i++) f->exp2_256[i] = exp2(i / 256.0);
    for (i = 0; i < tf->count; i++) {
        const wvol_tf_point *p = &tf->points[i], *q = i + 1 < tf->count ? p + 1 : p;
        double span = q->value - p->value;
        f->v[i] = p->value;
        f->vf[i] = (float)p->value;
        for (c = 0; c < 4; c++) {
            double a = c < 3 ? p->rgb[c] : p->opacity, b = c < 3 ? q->rgb[c] : q->opacity;
            f->c0[i][c] = a;
            f->dc[i][c] = span > 0 ? (b - a) / span : 0.0;
            if (c < 3 && a != f->rgb[c]) f->grey = 0;
        }
        f->kf0[i] = (float)f->c0[i][3];
        f->kfd[i] = (float)f->dc[i][3];
    }
    f->v_clear = -INFINITY;
    if (tf->count > 0 && f->c0[0][3] == 0.0 && isfinite(f->v[0])) {
        f->v_clear = (float)f->v[0];
        if ((double)f->v_clear > f->v[0]) f->v_clear = nextafterf(f->v_clear, -INFINITY);
    }
}
