/* SPDX-License-Identifier: MIT
 * The largest error the quantiser can leave on one coefficient of a file (wvol/wvc.h):
 * q = sign(c) floor(|c| / step + r), reconstructed at sign(q) (|q| + delta) step, so a
 * coefficient of |q| = k lies in [(k - r) step, (k + 1 - r) step) and its reconstruction's
 * error is at most max(|delta + r|, |1 - r - delta|) step; the dead zone (q = 0) leaves up
 * to (1 - r) step. r is the file's rounding, 0.5 for the low-pass cube (wvc_quant.c). In the
 * detail bands the encoder may also zero |q| = 1 coefficients to spend an unused error
 * budget (wvc_slack.c; a version-2 writer's widened dead zones are the same set), which
 * leaves up to (2 - r) step on them: the file does not say which sections it touched, so
 * every detail section is taken as possibly touched. */
#include "wvol/wvc.h"

#include <math.h>

static double worst_of(double r, double delta) { return fmax(fabs(delta + r), fabs(1.0 - r - delta)); }

double wvol_wvc_max_coeff_error(const wvol_wvc_info *info)
{
    double worst = 0;
    int i;
    /* a descriptor not made by the parser (more sections than it can hold) has no bound */
    if (!info || !(info->step > 0) || info->nsections < 0 || info->nsections > WVOL_WVC_MAX_SECTIONS) return 0;
    for (i = 0; i < info->nsections; i++) {
        const wvol_wvc_section *s = &info->sections[i];
        double r = s->band == 0 ? 0.5 : info->rounding;
        worst = fmax(worst, s->band == 0 ? 1.0 - r : 2.0 - r);
        worst = fmax(worst, worst_of(r, s->delta1));
        worst = fmax(worst, worst_of(r, s->delta2));
    }
    return worst * info->step;
}
