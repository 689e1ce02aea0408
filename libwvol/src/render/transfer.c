/* SPDX-License-Identifier: MIT
 * Transfer functions: piecewise-linear value -> (linear colour, extinction), presets,
 * a line-oriented text form and a small JSON form (docs/render.md). */
#include "core/file_open.h"
#include "render_internal.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

wvol_status wvol_tf_check(const wvol_tf *tf, wvol_error *err)
{
    int i, c;
    WVOL_RETURN_IF(!tf, err, WVOL_ERR_ARG, "transfer function: none given");
    WVOL_RETURN_IF(tf->count < 1 || tf->count > WVOL_TF_MAX_POINTS, err, WVOL_ERR_ARG,
                   "transfer function: %d points (1..%d expected)", tf->count, WVOL_TF_MAX_POINTS);
    for (i = 0; i < tf->count; i++) {
        const wvol_tf_point *p = &tf->points[i];
        WVOL_RETURN_IF(!isfinite(p->value) || !isfinite(p->opacity) || !isfinite(p->rgb[0]) || !isfinite(p->rgb[1]) ||
                           !isfinite(p->rgb[2]),
                       err, WVOL_ERR_ARG, "transfer function: point %d has a non-finite number", i + 1);
        WVOL_RETURN_IF(p->opacity < 0, err, WVOL_ERR_ARG, "transfer function: point %d (value %g) has opacity %g < 0",
                       i + 1, p->value, p->opacity);
        for (c = 0; c < 3; c++)
            WVOL_RETURN_IF(p->rgb[c] < 0, err, WVOL_ERR_ARG,
                           "transfer function: point %d (value %g) has a negative colour component %g", i + 1, p->value,
                           p->rgb[c]);
        WVOL_RETURN_IF(i > 0 && !(p->value > tf->points[i - 1].value), err, WVOL_ERR_ARG,
                       "transfer function: values must increase (point %d: %g after %g)", i + 1, p->value,
                       tf->points[i - 1].value);
    }
    return WVOL_OK;
}

static void set_pt(wvol_tf_point *p, double v, double r, double g, double b, double k)
{
    p->value = v;
    p->rgb[0] = r;
    p->rgb[1] = g;
    p->rgb[2] = b;
    p->opacity = k;
}

wvol_status wvol_tf_preset(wvol_tf *tf, const char *name, double vmin, double vmax, wvol_error *err)
{
    WVOL_RETURN_IF(!tf || !name, err, WVOL_ERR_ARG, "transfer function: no preset name");
    WVOL_RETURN_IF(!isfinite(vmin) || !isfinite(vmax) || vmin > vmax, err, WVOL_ERR_ARG,
                   "transfer function '%s': data range [%g, %g] (must be finite, vmin <= vmax)", name, vmin, vmax);
    memset(tf, 0, sizeof *tf);
    tf->per_diagonal = 1;
    if (!strcmp(name, "gaussian") || !strcmp(name, "grey") || !strcmp(name, "gray")) {
        WVOL_RETURN_IF(!isfinite(vmin) || !isfinite(vmax), err, WVOL_ERR_ARG,
                       "transfer function '%s': the data range is not finite", name);
        if (!(vmax > vmin)) vmax = vmin + 1.0; /* constant or empty volume: any ramp will do */
        if (!(vmax > vmin)) vmax = vmin + fabs(vmin); /* |vmin| >= 2^53: 1 is below its rounding */
        tf->count = 2;
        if (name[0] == 'g' && name[1] == 'a') {
            set_pt(&tf->points[0], vmin, 0.10, 0.25, 0.90, 0.0);
            set_pt(&tf->points[1], vmax, 1.00, 0.85, 0.55, 16.0);
        } else {
            set_pt(&tf->points[0], vmin, 1, 1, 1, 0.0);
            set_pt(&tf->points[1], vmax, 1, 1, 1, 8.0);
        }
    } else if (!strcmp(name, "ct-bone")) {
        tf->count = 4;
        set_pt(&tf->points[0], 150, 0.80, 0.60, 0.45, 0.0);
        set_pt(&tf->points[1], 300, 0.95, 0.85, 0.70, 40.0);
        set_pt(&tf->points[2], 800, 1.00, 0.95, 0.85, 160.0);
        set_pt(&tf->points[3], 2000, 1.00, 1.00, 1.00, 240.0);
    } else if (!strcmp(name, "ct-soft")) {
        tf->count = 6;
        set_pt(&tf->points[0], -400, 0.55, 0.25, 0.15, 0.0);
        set_pt(&tf->points[1], -100, 0.75, 0.45, 0.35, 2.0);
        set_pt(&tf->points[2], 40, 0.90, 0.55, 0.45, 6.0);
        set_pt(&tf->points[3], 120, 0.95, 0.70, 0.60, 8.0);
        set_pt(&tf->points[4], 300, 1.00, 0.95, 0.85, 60.0);
        set_pt(&tf->points[5], 1500, 1.00, 1.00, 1.00, 160.0);
    } else {
        return wvol_error_set(err, WVOL_ERR_ARG,
                              "transfer function: unknown preset '%s' (gaussian, grey, ct-bone, ct-soft, or a file)",
                              name);
    }
    return WVOL_OK;
}

void wvol_tf_eval(const wvol_tf *tf, double v, double rgb[3], double *kappa)
{
    const wvol_tf_point *p = tf->points;
    int n = tf->count, lo = 0, hi = n - 1, c;
    double w;
    if (v <= p[0].value || n == 1 || v != v) {
        lo = hi = 0;
        w = 0;
    } else if (v >= p[n - 1].value) {
        lo = hi = n - 1;
        w = 0;
    } else {
        while (hi - lo > 1) {
            int mid = (lo + hi) / 2;
            if (p[mid].value <= v) lo = mid;
            else hi = mid;
        }
        w = (v - p[lo].value) / (p[hi].value - p[lo].value);
    }
    if (rgb)
        for (c = 0; c < 3; c++) rgb[c] = p[lo].rgb[c] + w * (p[hi].rgb[c] - p[lo].rgb[c]);
    if (kappa) *kappa = p[lo].opacity + w * (p[hi].opacity - p[lo].opacity);
}

void wvol__tf_world(wvol_tf *out, const wvol_tf *tf, const wvol_geometry *g)
{
    int i;
    *out = *tf;
    if (tf->per_diagonal) {
        double lo[3], hi[3], diag;
        wvol_geometry_bounds(g, lo, hi);
        diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                    (hi[2] - lo[2]) * (hi[2] - lo[2]));
        for (i = 0; i < out->count; i++) out->points[i].opacity /= diag;
        out->per_diagonal = 0;
    }
}

/* ---- parsing ---- */

static const char *skip_ws(const char *s)
{
    while (*s && isspace((unsigned char)*s)) s++;
    return s;
}

/* The document's shape, which the reader below does not follow: one object, brackets and
 * braces matched (outside strings), nothing after it, "points" and "units" each once. 0 or the
 * problem. */
static const char *json_shape(const char *text)
{
    char stack[64];
    int depth = 0, in_str = 0, points = 0, units = 0;
    const char *s = skip_ws(text);
    if (*s != '{') return "not a JSON object";
    for (; *s; s++) {
        char c = *s;
        if (in_str) {
            if (c == '\\' && s[1]) s++;
            else if (c == '"') in_str = 0;
            continue;
        }
        if (c == '"') {
            in_str = 1;
            if (depth == 1 && !strncmp(s, "\"points\"", 8)) points++;
            if (depth == 1 && !strncmp(s, "\"units\"", 7)) units++;
        } else if (c == '{' || c == '[') {
            if (depth == (int)sizeof stack) return "nested too deeply";
            stack[depth++] = c;
        } else if (c == '}' || c == ']') {
            if (!depth || stack[depth - 1] != (c == '}' ? '{' : '[')) return "brackets do not match";
            if (--depth == 0) {
                s = skip_ws(s + 1);
                if (*s) return "text after the closing brace";
                break;
            }
        }
    }
    if (in_str) return "a string is not closed";
    if (depth) return "the object is not closed (a missing '}' or ']')";
    if (points > 1) return "\"points\" given twice";
    if (units > 1) return "\"units\" given twice";
    return NULL;
}

static wvol_status parse_json(wvol_tf *tf, const char *text, const char *what, wvol_error *err)
{
    const char *s = text, *pts = strstr(text, "\"points\""), *units = strstr(text, "\"units\"");
    int depth = 0, n = 0;
    double vals[5];
    const char *bad = json_shape(text);
    WVOL_RETURN_IF(bad, err, WVOL_ERR_FORMAT, "%s: malformed JSON transfer function: %s", what, bad);
    WVOL_RETURN_IF(!pts, err, WVOL_ERR_FORMAT, "%s: JSON transfer function has no \"points\" array", what);
    if (units) {
        const char *u = skip_ws(units + 7);
        WVOL_RETURN_IF(*u != ':', err, WVOL_ERR_FORMAT, "%s: \"units\" without a value", what);
        u = skip_ws(u + 1);
        if (!strncmp(u, "\"diagonal\"", 10)) tf->per_diagonal = 1;
        else WVOL_RETURN_IF(strncmp(u, "\"world\"", 7), err, WVOL_ERR_FORMAT,
                            "%s: \"units\" must be \"world\" or \"diagonal\"", what);
    }
    s = skip_ws(pts + 8);
    WVOL_RETURN_IF(*s != ':', err, WVOL_ERR_FORMAT, "%s: \"points\" without a value", what);
    s = skip_ws(s + 1);
    WVOL_RETURN_IF(*s != '[', err, WVOL_ERR_FORMAT, "%s: \"points\" must be an array", what);
    s++;
    for (;;) {
        s = skip_ws(s);
        if (*s == ']') break;
        if (*s == ',' && tf->count > 0) {
            s = skip_ws(s + 1);
        }
        WVOL_RETURN_IF(*s != '[', err, WVOL_ERR_FORMAT,
                       "%s: point %d must be an array [value, r, g, b, opacity]", what, tf->count + 1);
        s++;
        for (n = 0; n < 5; n++) {
            char *end;
            s = skip_ws(s);
            vals[n] = strtod(s, &end);
            WVOL_RETURN_IF(end == s, err, WVOL_ERR_FORMAT, "%s: point %d: number %d is missing or malformed", what,
                           tf->count + 1, n + 1);
            s = skip_ws(end);
            if (n < 4) {
                WVOL_RETURN_IF(*s != ',', err, WVOL_ERR_FORMAT,
                               "%s: point %d needs 5 numbers [value, r, g, b, opacity]", what, tf->count + 1);
                s++;
            }
        }
        WVOL_RETURN_IF(*s != ']', err, WVOL_ERR_FORMAT, "%s: point %d has more than 5 numbers", what, tf->count + 1);
        s++;
        WVOL_RETURN_IF(tf->count >= WVOL_TF_MAX_POINTS, err, WVOL_ERR_FORMAT, "%s: more than %d points", what,
                       WVOL_TF_MAX_POINTS);
        set_pt(&tf->points[tf->count++], vals[0], vals[1], vals[2], vals[3], vals[4]);
        depth++;
    }
    return WVOL_OK;
}

static wvol_status parse_lines(wvol_tf *tf, const char *text, const char *what, wvol_error *err)
{
    const char *s = text;
    int line = 0;
    while (*s) {
        const char *eol = strchr(s, '\n');
        size_t len = eol ? (size_t)(eol - s) : strlen(s);
        char buf[512], *p, *end;
        double v[5];
        int n;
        line++;
        WVOL_RETURN_IF(len >= sizeof buf, err, WVOL_ERR_FORMAT, "%s:%d: line too long", what, line);
        memcpy(buf, s, len);
        buf[len] = 0;
        s = eol ? eol + 1 : s + len;
        if ((p = strchr(buf, '#'))) *p = 0;
        p = (char *)skip_ws(buf);
        if (!*p) continue;
        if (!strncmp(p, "units", 5) && isspace((unsigned char)p[5])) {
            p = (char *)skip_ws(p + 5);
            end = p + strlen(p);
            while (end > p && isspace((unsigned char)end[-1])) *--end = 0;
            if (!strcmp(p, "diagonal")) tf->per_diagonal = 1;
            else if (!strcmp(p, "world")) tf->per_diagonal = 0;
            else return wvol_error_set(err, WVOL_ERR_FORMAT, "%s:%d: units '%s' (world or diagonal)", what, line, p);
            continue;
        }
        for (n = 0; n < 5; n++) {
            v[n] = strtod(p, &end);
            WVOL_RETURN_IF(end == p, err, WVOL_ERR_FORMAT,
                           "%s:%d: expected 5 numbers 'value r g b opacity', number %d is missing or malformed", what,
                           line, n + 1);
            p = end;
        }
        WVOL_RETURN_IF(*skip_ws(p), err, WVOL_ERR_FORMAT, "%s:%d: unexpected text after 5 numbers: '%s'", what, line,
                       skip_ws(p));
        WVOL_RETURN_IF(tf->count >= WVOL_TF_MAX_POINTS, err, WVOL_ERR_FORMAT, "%s: more than %d points", what,
                       WVOL_TF_MAX_POINTS);
        set_pt(&tf->points[tf->count++], v[0], v[1], v[2], v[3], v[4]);
    }
    return WVOL_OK;
}

wvol_status wvol_tf_parse(wvol_tf *tf, const char *text, const char *what, wvol_error *err)
{
    wvol_status s;
    WVOL_RETURN_IF(!tf || !text, err, WVOL_ERR_ARG, "transfer function: no text");
    if (!what) what = "transfer function";
    memset(tf, 0, sizeof *tf);
    s = *skip_ws(text) == '{' ? parse_json(tf, text, what, err) : parse_lines(tf, text, what, err);
    if (s != WVOL_OK) return s;
    WVOL_RETURN_IF(tf->count == 0, err, WVOL_ERR_FORMAT, "%s: no points", what);
    s = wvol_tf_check(tf, err);
    if (s != WVOL_OK) wvol_error_prefix(err, "%s", what);
    return s;
}

wvol_status wvol_tf_load(wvol_tf *tf, const char *path, wvol_error *err)
{
    FILE *fp;
    char *text;
    long n;
    size_t got;
    wvol_status s;
    WVOL_RETURN_IF(!path, err, WVOL_ERR_ARG, "transfer function: no file name");
    WVOL_FORWARD(wvol__fopen_regular(&fp, path, err));
    if (fseek(fp, 0, SEEK_END) != 0 || (n = ftell(fp)) < 0 || fseek(fp, 0, SEEK_SET) != 0) {
        fclose(fp);
        return wvol_error_set(err, WVOL_ERR_IO, "%s: cannot read", path);
    }
    if (n > (1 << 20)) {
        fclose(fp);
        return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: %ld bytes is too large for a transfer function", path, n);
    }
    text = malloc((size_t)n + 1);
    if (!text) {
        fclose(fp);
        return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    }
    got = fread(text, 1, (size_t)n, fp);
    fclose(fp);
    text[got] = 0;
    if (strlen(text) != got) {
        free(text);
        return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: not a text file", path);
    }
    s = wvol_tf_parse(tf, text, path, err);
    free(text);
    return s;
}

wvol_status wvol_tf_resolve(wvol_tf *tf, const char *spec, double vmin, double vmax, wvol_error *err)
{
    struct stat st;
    wvol_status s;
    WVOL_RETURN_IF(!tf || !spec, err, WVOL_ERR_ARG, "transfer function: none given");
    if (stat(spec, &st) == 0 && S_ISREG(st.st_mode)) return wvol_tf_load(tf, spec, err);
    s = wvol_tf_preset(tf, spec, vmin, vmax, err);
    /* not a preset, but something by that name exists (a folder, a FIFO): say that, not "unknown preset" */
    if (s == WVOL_ERR_ARG && stat(spec, &st) == 0) return wvol_tf_load(tf, spec, err);
    return s;
}
