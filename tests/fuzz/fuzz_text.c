/* SPDX-License-Identifier: MIT
 * libFuzzer target for the text a user types: the camera description (render/camera.c) and
 * the transfer function's text and JSON forms (render/transfer.c). The input's first line is
 * the camera, the rest the transfer function. Besides the sanitizers' checks, what a parser
 * accepts must be usable: an accepted camera gives finite unit rays at the image's corners
 * and centre, an accepted transfer function passes wvol_tf_check. A violation aborts, which
 * libFuzzer reports as a crash. Build and run: scripts/fuzz.sh. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "wvol/render.h"

static void camera(const char *spec)
{
    /* anisotropic spacing and an off-centre origin, so that framing is not trivially symmetric */
    const wvol_geometry g = {{17, 9, 33}, {0.5, 2.0, 1.25}, {-3.0, 40.0, 0.5}};
    const double px[5][2] = {{0, 0}, {64, 0}, {0, 48}, {64, 48}, {32.5, 24.5}};
    wvol_camera cam;
    wvol_error err;
    if (wvol_camera_parse(&cam, spec, &g, 64, 48, &err) != WVOL_OK) return;
    for (int i = 0; i < 5; i++) {
        double o[3], d[3];
        wvol_camera_ray(&cam, px[i][0], px[i][1], o, d);
        for (int a = 0; a < 3; a++)
            if (!isfinite(o[a]) || !isfinite(d[a])) abort();
        if (!(fabs(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - 1.0) < 1e-9)) abort();
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = malloc(size + 1), *nl;
    wvol_tf tf;
    wvol_error err;
    if (!text) return 0;
    memcpy(text, data, size);
    text[size] = '\0';
    nl = strchr(text, '\n');
    if (nl) *nl = '\0';
    camera(text);
    if (wvol_tf_parse(&tf, nl ? nl + 1 : "", "fuzz", &err) == WVOL_OK && wvol_tf_check(&tf, &err) != WVOL_OK) abort();
    free(text);
    return 0;
}
