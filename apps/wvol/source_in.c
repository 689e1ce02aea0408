/* SPDX-License-Identifier: MIT */
/* Sub-command inputs as volume sources (source_in.h): files and "synth:" generators. */
#include "source_in.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wvol_synth.h"

#define PREFIX "synth:"

int source_in_is_synth(const char *in) { return in && !strncmp(in, PREFIX, strlen(PREFIX)); }

int source_in_streams(const char *in) { return source_in_is_synth(in) || wvol_source_format_streams(in); }

/* "N" or "NXxNYxNZ" */
static int parse_size(const char *s, size_t d[3])
{
    unsigned long long v[3];
    int n = 0;
    char *end;
    for (;;) {
        if (*s < '0' || *s > '9') return 0;
        errno = 0;
        v[n++] = strtoull(s, &end, 10);
        if (errno || v[n - 1] == 0) return 0;
        s = end;
        if (!*s || n == 3) break;
        if (*s != 'x') return 0;
        s++;
    }
    if (*s || (n != 1 && n != 3)) return 0;
    for (int a = 0; a < 3; a++) d[a] = (size_t)(n == 1 ? v[0] : v[a]);
    return 1;
}

wvol_status source_in_open(wvol_source **out, const char *in, const wvol_load_options *lo, wvol_error *err)
{
    wvol_synth_params sp;
    char spec[512], *kind, *part, *save = NULL, variant[64] = "";
    int k, have_size = 0;
    if (!source_in_is_synth(in)) return wvol_source_open(out, in, lo, err);
    *out = NULL;
    if (strlen(in) >= sizeof spec)
        return wvol_error_set(err, WVOL_ERR_ARG, "%s: generator spec too long", in);
    strcpy(spec, in + strlen(PREFIX));
    wvol_synth_params_default(&sp);
    kind = strtok_r(spec, ",", &save);
    k = wvol_synth_kind_find(kind);
    if (k < 0)
        return wvol_error_set(err, WVOL_ERR_ARG, "%s: unknown generator '%s' (wvol synth --list names them)", in,
                              kind ? kind : "");
    while ((part = strtok_r(NULL, ",", &save))) {
        char *eq = strchr(part, '='), *end;
        double x;
        if (!eq) return wvol_error_set(err, WVOL_ERR_ARG, "%s: '%s' is not key=value", in, part);
        *eq++ = '\0';
        if (!strcmp(part, "size")) {
            if (!parse_size(eq, sp.dims))
                return wvol_error_set(err, WVOL_ERR_ARG, "%s: size '%s': expected N or NXxNYxNZ", in, eq);
            have_size = 1;
            continue;
        }
        if (!strcmp(part, "variant")) {
            snprintf(variant, sizeof variant, "%s", eq);
            sp.variant = variant;
            continue;
        }
        if (!strcmp(part, "seed")) {
            errno = 0;
            sp.seed = (uint64_t)strtoull(eq, &end, 10);
            if (end == eq || *end || errno || *eq == '-')
                return wvol_error_set(err, WVOL_ERR_ARG, "%s: seed '%s': expected an integer >= 0", in, eq);
            continue;
        }
        errno = 0;
        x = strtod(eq, &end);
        if (end == eq || *end || errno || !isfinite(x) || x < 0)
            return wvol_error_set(err, WVOL_ERR_ARG, "%s: %s '%s': expected a number >= 0", in, part, eq);
        if (!strcmp(part, "noise")) sp.noise = x;
        else if (!strcmp(part, "sigma")) sp.sigma = x;
        else if (!strcmp(part, "count")) sp.count = (int)x;
        else
            return wvol_error_set(err, WVOL_ERR_ARG,
                                  "%s: unknown key '%s' (size, seed, noise, sigma, count, variant)", in, part);
    }
    if (!have_size) wvol_synth_kind_default_dims(k, sp.dims);
    return wvol_synth_source(out, wvol_synth_kind_name(k), &sp, err);
}
