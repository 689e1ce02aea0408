/* SPDX-License-Identifier: MIT */
/* Shared helpers of the wvol sub-commands (cli.h): option parsing, messages, JSON, progress. */
#define _XOPEN_SOURCE 700 /* realpath */
#include "cli.h"
#include "output_set.h"
#include "wvol/compress.h"
#include "wvol/store.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <sys/stat.h>
#include <unistd.h>
#include <omp.h>

#include "wvol/render.h"

void cli_parser_init(cli_parser *p, const char *cmd, int argc, char **argv, const cli_opt *opts)
{
    p->argc = argc;
    p->argv = argv;
    p->i = 1;
    p->cmd = cmd;
    p->opts = opts;
    p->positional_only = 0;
    memset(p->given, 0, sizeof p->given);
}

int cli_given(const cli_parser *p, const char *name)
{
    for (size_t k = 0; k < sizeof p->given && p->opts[k].name; k++)
        if (!strcmp(p->opts[k].name, name)) return p->given[k];
    return 0;
}

int cli_method_rules(const cli_parser *p, const cli_method_rule *rules, int method, const char *method_name)
{
    for (const cli_method_rule *r = rules; r->opt; r++)
        if (!(r->methods >> method & 1u) && cli_given(p, r->opt))
            return cli_usage(p->cmd, "--%s applies only to --method %s (not %s)", r->opt, r->which, method_name);
    return CLI_OK;
}

int cli_next(cli_parser *p, const cli_opt **opt, const char **value)
{
    const char *arg, *eq;
    const cli_opt *o;
    size_t len;
    *opt = NULL;
    *value = NULL;
    if (p->i >= p->argc) return -1;
    arg = p->argv[p->i++];
    if (!p->positional_only && !strcmp(arg, "--")) { /* the usual end of the options */
        p->positional_only = 1;
        if (p->i >= p->argc) return -1;
        arg = p->argv[p->i++];
    }
    if (p->positional_only || arg[0] != '-' || arg[1] == '\0' || (arg[1] >= '0' && arg[1] <= '9') || arg[1] == '.') {
        *value = arg; /* positional, including negative numbers */
        return 0;
    }
    if (arg[1] == '-') {
        const char *name = arg + 2;
        eq = strchr(name, '=');
        len = eq ? (size_t)(eq - name) : strlen(name);
        for (o = p->opts; o->name; o++)
            if (strlen(o->name) == len && strncmp(o->name, name, len) == 0) break;
    } else {
        eq = NULL;
        for (o = p->opts; o->name; o++)
            if (o->short_name && o->short_name == arg[1] && arg[2] == '\0') break;
    }
    if (!o->name) return cli_usage(p->cmd, "unknown option '%s' (see 'wvol %s --help')", arg, p->cmd);
    *opt = o;
    if ((size_t)(o - p->opts) < sizeof p->given) p->given[o - p->opts] = 1;
    if (o->takes_value) {
        if (eq) {
            *value = eq + 1;
        } else if (p->i < p->argc) {
            *value = p->argv[p->i++];
        } else {
            return cli_usage(p->cmd, "option --%s needs a value", o->name);
        }
    } else if (eq) {
        return cli_usage(p->cmd, "option --%s takes no value", o->name);
    }
    return 1;
}

void cli_print_help(const char *cmd, const char *usage, const char *about, const cli_opt *opts)
{
    const cli_opt *o;
    printf("usage: wvol %s %s\n\n%s\n\noptions:\n", cmd, usage, about);
    for (o = opts; o->name; o++) {
        char left[64];
        snprintf(left, sizeof left, "%s%c%s--%s%s", o->short_name ? "-" : "",
                 o->short_name ? o->short_name : ' ', o->short_name ? ", " : "  ", o->name,
                 o->takes_value ? " VALUE" : "");
        printf("  %-28s %s\n", o->short_name ? left : left + 2, o->help);
    }
}

static int vmessage(const char *cmd, int code, const char *fmt, va_list ap)
{
    char msg[2048];
    cli_progress_done();
    vsnprintf(msg, sizeof msg, fmt, ap);
    /* a message can quote bytes of a damaged file (a reader's own text): control bytes are
     * shown as '?', so that the line stays one line of text on any terminal */
    for (char *c = msg; *c; c++)
        if ((unsigned char)*c < 0x20 || *c == 0x7f) *c = '?';
    {
        /* a library message that names the command already ("compress: levels ...") is not
         * prefixed twice */
        size_t n = strlen(cmd);
        const char *m = strncmp(msg, cmd, n) == 0 && msg[n] == ':' && msg[n + 1] == ' ' ? msg + n + 2 : msg;
        fprintf(stderr, "wvol %s: %s\n", cmd, m);
    }
    return code;
}

int cli_usage(const char *cmd, const char *fmt, ...)
{
    va_list ap;
    int r;
    va_start(ap, fmt);
    r = vmessage(cmd, CLI_USAGE, fmt, ap);
    va_end(ap);
    return r;
}

int cli_fail(const char *cmd, const char *fmt, ...)
{
    va_list ap;
    int r;
    va_start(ap, fmt);
    r = vmessage(cmd, CLI_FAILED, fmt, ap);
    va_end(ap);
    return r;
}

int cli_fail_err(const char *cmd, const wvol_error *err)
{
    if (err->status == WVOL_ERR_ARG || err->status == WVOL_ERR_DIMS)
        return cli_usage(cmd, "%s", err->message);
    return cli_fail(cmd, "%s", err->message[0] ? err->message : wvol_status_string(err->status));
}

int cli_parse_dims(const char *cmd, const char *opt, const char *s, size_t dims[3])
{
    const char *p = s;
    int n = 0;
    while (n < 3) {
        char *end;
        unsigned long long v;
        if (*p < '0' || *p > '9') break;
        errno = 0;
        v = strtoull(p, &end, 10);
        if (errno || v == 0 || v > (unsigned long long)((size_t)-1)) {
            cli_usage(cmd, "--%s '%s': each dimension must be an integer from 1 to %zu", opt, s,
                      (size_t)-1);
            return 0;
        }
        dims[n++] = (size_t)v;
        p = end;
        if (*p == 'x' || *p == 'X' || *p == ',') p++;
        else break;
    }
    if (*p || (n != 1 && n != 3)) {
        cli_usage(cmd, "--%s '%s': expected N or NXxNYxNZ (positive integers)", opt, s);
        return 0;
    }
    if (n == 1) dims[1] = dims[2] = dims[0];
    return 1;
}

int cli_parse_double(const char *cmd, const char *opt, const char *s, double *out)
{
    char *end;
    errno = 0;
    *out = strtod(s, &end);
    if (!*s || *end || errno || !isfinite(*out)) {
        /* ERANGE: beyond double's range, or below its normal numbers (1e-320) */
        cli_usage(cmd, "--%s '%s': expected a finite number%s", opt, s,
                  errno == ERANGE ? " within double's normal range (about 2.2e-308 to 1.8e308 in magnitude)" : "");
        return 0;
    }
    return 1;
}

int cli_parse_double3(const char *cmd, const char *opt, const char *s, double out[3])
{
    char buf[256], *tok, *save = NULL;
    int n = 0;
    if (strlen(s) >= sizeof buf) return cli_usage(cmd, "--%s: value too long", opt), 0;
    strcpy(buf, s);
    for (tok = strtok_r(buf, ",x", &save); tok && n < 4; tok = strtok_r(NULL, ",x", &save)) {
        if (n == 3 || !cli_parse_double(cmd, opt, tok, &out[n])) {
            if (n == 3) cli_usage(cmd, "--%s '%s': expected X,Y,Z or one number", opt, s);
            return 0;
        }
        n++;
    }
    if (n == 1) out[1] = out[2] = out[0];
    else if (n != 3) return cli_usage(cmd, "--%s '%s': expected X,Y,Z or one number", opt, s), 0;
    return 1;
}

int cli_parse_long(const char *cmd, const char *opt, const char *s, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    *out = strtol(s, &end, 10);
    if (!*s || *end || errno || *out < lo || *out > hi) {
        cli_usage(cmd, "--%s '%s': expected an integer from %ld to %ld", opt, s, lo, hi);
        return 0;
    }
    return 1;
}

int cli_threads(const char *cmd, const char *val, int *threads)
{
    long n;
    if (!cli_parse_long(cmd, "threads", val, 1, CLI_MAX_THREADS, &n)) return 0;
    omp_set_num_threads((int)n); /* the process's default: every OpenMP region of this run */
    if (threads) *threads = (int)n;
    return 1;
}

int cli_parse_bytes(const char *cmd, const char *opt, const char *s, size_t *out)
{
    char *end;
    double v, mul = 1;
    errno = 0;
    v = strtod(s, &end);
    if (*end == 'K' || *end == 'k') mul = 1024.0, end++;
    else if (*end == 'M' || *end == 'm') mul = 1048576.0, end++;
    else if (*end == 'G' || *end == 'g') mul = 1073741824.0, end++;
    else if (*end == 'T' || *end == 't') mul = 1099511627776.0, end++;
    if (*end == 'B' || *end == 'b') end++;
    v *= mul;
    if (!*s || *end || errno || !(v >= 1 && v < 1.8e19)) {
        cli_usage(cmd, "--%s '%s': expected a size in bytes, e.g. 512M or 2G", opt, s);
        return 0;
    }
    *out = (size_t)v;
    return 1;
}

int cli_open_wvc_store(const char *cmd, const char *path, size_t budget, wvol_compressed *out)
{
    wvol_error err;
    wvol_store_info si;
    const wvol_wvc_info *wi;
    memset(out, 0, sizeof *out);
    wvol_error_clear(&err);
    if (wvol_store_open(&out->store, path, budget, NULL, &err) != WVOL_OK) return cli_fail_err(cmd, &err);
    wvol_store_get_info(out->store, &si);
    out->levels = si.levels;
    wi = wvol_store_file_info(out->store);
    out->value_min = wi->value_min;
    out->value_max = wi->value_max;
    return CLI_OK;
}

void cli_json_wvc_cache(const char *key, const wvol_wvc_cache_stats *cs, uint64_t file_chunks)
{
    cli_json_open(key, '{');
    cli_json_int("decoded", (long long)cs->decoded);
    cli_json_int("decoded_narrow", (long long)cs->decoded_narrow);
    cli_json_int("cache_hits", (long long)cs->hits);
    cli_json_int("bytes_read", (long long)cs->bytes_read);
    cli_json_int("cache_peak_bytes", (long long)cs->peak);
    cli_json_int("budget_bytes", (long long)cs->budget);
    cli_json_int("file_chunks", (long long)file_chunks);
    cli_json_close('}');
}

int cli_check_wvc_store(const char *cmd, const wvol_compressed *c, int json)
{
    wvol_wvc_cache_stats cs;
    wvol_error err;
    if (!c->store || !wvol_store_is_file(c->store)) return CLI_OK;
    wvol_error_clear(&err);
    memset(&cs, 0, sizeof cs);
    if (wvol_store_file_stats(c->store, &cs, &err) != WVOL_OK) {
        const int rc = cli_fail_err(cmd, &err);
        /* the run went on past the first excess, each chunk decoded still: its peak is what
         * the requests held at once, the budget that would have held them */
        if (err.status == WVOL_ERR_NOMEM && cs.peak > cs.budget) {
            const int mib = cs.peak >= ((size_t)16 << 20); /* K below 16 MiB, M above (rounded up) */
            const size_t unit = (size_t)1 << (mib ? 20 : 10);
            fprintf(stderr, "wvol %s: its requests held up to %zu bytes of chunks at once: --memory %zu%c would have held them\n",
                    cmd, cs.peak, (cs.peak + unit - 1) / unit, mib ? 'M' : 'K');
        }
        return rc;
    }
    if (json) {
        cli_json_wvc_cache("chunks", &cs, wvol_store_file_info(c->store)->chunks);
    } else {
        fprintf(stderr, "wvol %s: .wvc chunks: %llu decoded (%llu bytes read), cache peak %zu of %zu bytes\n", cmd,
                (unsigned long long)cs.decoded, (unsigned long long)cs.bytes_read, cs.peak, cs.budget);
    }
    return CLI_OK;
}

int cli_parse_fraction(const char *cmd, const char *opt, const char *s, double *out)
{
    char *end;
    double v;
    errno = 0;
    v = strtod(s, &end);
    if (*end == '%' && end[1] == '\0') {
        v /= 100.0;
    } else if (*end) {
        cli_usage(cmd, "--%s '%s': expected a fraction like 0.05 or 5%%", opt, s);
        return 0;
    }
    if (!*s || errno || !(v > 0.0 && v <= 1.0)) {
        cli_usage(cmd, "--%s '%s': the fraction must be in (0, 1] (or (0%%, 100%%])", opt, s);
        return 0;
    }
    *out = v;
    return 1;
}

int cli_parse_size(const char *cmd, const char *opt, const char *s, long *w, long *h)
{
    char *e1, *e2;
    long W = strtol(s, &e1, 10), H;
    if (e1 == s || (*e1 != 'x' && *e1 != 'X')) {
        cli_usage(cmd, "--%s '%s': expected WxH", opt, s);
        return 0;
    }
    H = strtol(e1 + 1, &e2, 10);
    if (e2 == e1 + 1 || *e2 || W < 1 || H < 1 || W > 65536 || H > 65536) {
        cli_usage(cmd, "--%s '%s': expected WxH with sides 1..65536", opt, s);
        return 0;
    }
    *w = W;
    *h = H;
    return 1;
}

int cli_load_tf(const char *cmd, const char *name, double vmin, double vmax, struct wvol_tf *tf)
{
    wvol_error err;
    struct stat st;
    wvol_status s = wvol_tf_resolve(tf, name, vmin, vmax, &err);
    if (s == WVOL_OK) return CLI_OK;
    /* what is wrong inside a file is bad input (1), whatever the library calls it; a name that is
     * neither a preset nor a file is bad usage (2) */
    if (stat(name, &st) == 0 && S_ISREG(st.st_mode)) return cli_fail(cmd, "--tf: %s", err.message);
    return s == WVOL_ERR_ARG ? cli_usage(cmd, "--tf: %s", err.message) : cli_fail_err(cmd, &err);
}

/* The loading options given so far, by name (this process parses one command line). */
static const char *const load_names[] = {"dims", "type", "big-endian", "spacing", "origin", "grid"};
static unsigned load_given;

static int is_raw_path(const char *p) { return p && (wvol_path_has_ext(p, ".raw") || wvol_path_has_ext(p, ".bin")); }

int cli_load_options_fit(const char *cmd, const char *path, const char *also)
{
    const int raw = is_raw_path(path) || is_raw_path(also);
    if (!path) return CLI_OK;
    for (int i = 0; i < 5; i++)
        if (!raw && ((load_given >> i) & 1))
            return cli_usage(cmd, "--%s describes raw input (.raw, .bin): %s %s", load_names[i], path,
                             strncmp(path, "synth:", 6) ? "carries its own" : "is a generator (its spec takes size=)");
    if (((load_given >> 5) & 1) && !wvol_path_has_ext(path, ".vdb") && !(also && wvol_path_has_ext(also, ".vdb")))
        return cli_usage(cmd, "--grid names a grid of an OpenVDB file: %s is not a .vdb", path);
    return CLI_OK;
}

int cli_load_option(const char *cmd, const cli_opt *o, const char *val, wvol_load_options *lo)
{
    for (int i = 0; i < 6; i++)
        if (!strcmp(o->name, load_names[i])) load_given |= 1u << i;
    if (!strcmp(o->name, "dims")) {
        if (!cli_parse_dims(cmd, "dims", val, lo->dims)) return CLI_USAGE;
    } else if (!strcmp(o->name, "type")) {
        int t = wvol_sample_type_parse(val);
        if (t < 0) return cli_usage(cmd, "--type '%s': unknown sample type", val);
        lo->raw_type = (wvol_sample_type)t;
    } else if (!strcmp(o->name, "big-endian")) {
        lo->big_endian = 1;
    } else if (!strcmp(o->name, "spacing")) {
        if (!cli_parse_double3(cmd, "spacing", val, lo->spacing)) return CLI_USAGE;
        for (int a = 0; a < 3; a++)
            if (!(lo->spacing[a] > 0)) return cli_usage(cmd, "--spacing '%s': spacing must be positive", val);
    } else if (!strcmp(o->name, "origin")) {
        if (!cli_parse_double3(cmd, "origin", val, lo->origin)) return CLI_USAGE;
    } else if (!strcmp(o->name, "grid")) {
        lo->grid_name = val;
    } else {
        return -1;
    }
    return CLI_OK;
}

int cli_one_input(const char *cmd, const char **in, const char *val)
{
    if (*in) return cli_usage(cmd, "one input file expected, got '%s' too", val);
    *in = val;
    return CLI_OK;
}

/* ---- JSON ---- */
static int json_need_comma[32];
static int json_depth;

static void json_sep(void)
{
    if (json_need_comma[json_depth]) fputc(',', stdout);
    json_need_comma[json_depth] = 1;
}

void cli_json_key(const char *key)
{
    const char *c;
    json_sep();
    if (!key) return;
    fputc('"', stdout);
    for (c = key; *c; c++) {
        if (*c == '"' || *c == '\\') fputc('\\', stdout);
        fputc(*c, stdout);
    }
    fputs("\":", stdout);
}

void cli_json_begin(void)
{
    json_depth = 0;
    json_need_comma[0] = 0;
    fputc('{', stdout);
    json_depth = 1;
    json_need_comma[1] = 0;
}

void cli_json_end(void)
{
    fputs("}\n", stdout);
    json_depth = 0;
}

void cli_json_str(const char *key, const char *value)
{
    const unsigned char *c;
    cli_json_key(key);
    fputc('"', stdout);
    for (c = (const unsigned char *)value; *c; c++) {
        if (*c == '"' || *c == '\\') fprintf(stdout, "\\%c", *c);
        else if (*c < 0x20) fprintf(stdout, "\\u%04x", *c);
        else fputc(*c, stdout);
    }
    fputc('"', stdout);
}

void cli_json_num(const char *key, double value)
{
    cli_json_key(key);
    if (isfinite(value)) fprintf(stdout, "%.17g", value);
    else fputs("null", stdout);
}

void cli_json_int(const char *key, long long value)
{
    cli_json_key(key);
    fprintf(stdout, "%lld", value);
}

void cli_json_open(const char *key, char bracket)
{
    cli_json_key(key);
    fputc(bracket, stdout);
    if (json_depth < 31) json_depth++;
    json_need_comma[json_depth] = 0;
}

void cli_json_close(char bracket)
{
    fputc(bracket, stdout);
    if (json_depth > 0) json_depth--;
}

void cli_json_size3(const char *key, size_t a, size_t b, size_t c)
{
    cli_json_open(key, '[');
    cli_json_int(NULL, (long long)a);
    cli_json_int(NULL, (long long)b);
    cli_json_int(NULL, (long long)c);
    cli_json_close(']');
}

void cli_json_num3(const char *key, const double v[3])
{
    cli_json_open(key, '[');
    for (int a = 0; a < 3; a++) cli_json_num(NULL, v[a]);
    cli_json_close(']');
}

/* ---- progress ---- */
double cli_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

double cli_cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double progress_start = -1;
static int progress_shown;

void cli_progress(const char *label, double fraction)
{
    int w = 30, k;
    double now = cli_now();
    if (progress_start < 0) progress_start = now;
    if (!isatty(2) || now - progress_start < 1.0) return;
    if (fraction < 0) fraction = 0;
    if (fraction > 1) fraction = 1;
    k = (int)(fraction * w);
    fprintf(stderr, "\r%-16s [", label);
    for (int i = 0; i < w; i++) fputc(i < k ? '#' : '.', stderr);
    fprintf(stderr, "] %3d%%", (int)(fraction * 100));
    progress_shown = 1;
}

void cli_progress_done(void)
{
    if (progress_shown) fputs("\r\033[K", stderr);
    progress_shown = 0;
    progress_start = -1;
}

/* path's canonical form: the real path of its folder (links and "." resolved) and its own name;
 * an existing file's link resolved too. 0 when the folder cannot be resolved. */
static int canonical_output(const char *path, char *buf, size_t cap)
{
    char dir[PATH_MAX], *r;
    const char *slash = strrchr(path, '/'), *name = slash ? slash + 1 : path;
    size_t d = slash ? (size_t)(slash - path) : 0;
    if ((r = realpath(path, NULL))) { /* it exists: where it really is */
        int ok = strlen(r) < cap;
        if (ok) strcpy(buf, r);
        free(r);
        return ok;
    }
    if (d >= sizeof dir) return 0;
    memcpy(dir, slash ? path : ".", slash ? (d ? d : 1) : 1);
    dir[slash ? (d ? d : 1) : 1] = '\0';
    if (!(r = realpath(dir, NULL))) return 0;
    d = (size_t)snprintf(buf, cap, "%s/%s", r, name);
    free(r);
    return d < cap;
}

const char *cli_write_hint(const char *path)
{
    if (wvol_path_has_ext(path, ".mhd")) return "MetaImage is written as .mha, header and data in one file";
    return "see 'wvol convert --help' for the formats this build writes";
}

int cli_data_file_not_input(const char *cmd, const char *in, const char *out)
{
    char data[PATH_MAX], a[PATH_MAX], b[PATH_MAX];
    if (!in || !out || !wvol_path_has_ext(out, ".nhdr") || !wvol_nrrd_data_path(data, sizeof data, out, 0) ||
        !canonical_output(in, a, sizeof a) || !canonical_output(data, b, sizeof b) || strcmp(a, b))
        return CLI_OK;
    return cli_usage(cmd, "%s: its data file %s is the input, which it would replace: give the header another name",
                     out, data);
}

const char *cli_same_output(const char *const *outs, int n)
{
    char canon[16][PATH_MAX], data[PATH_MAX];
    const char *named[16];
    int m = 0;
    for (int i = 0; i < n && m < 15; i++) {
        if (!outs[i]) continue;
        if (canonical_output(outs[i], canon[m], sizeof canon[m])) named[m++] = outs[i];
        if (wvol_path_has_ext(outs[i], ".nhdr") && wvol_nrrd_data_path(data, sizeof data, outs[i], 0) &&
            canonical_output(data, canon[m], sizeof canon[m]))
            named[m++] = outs[i];
    }
    for (int i = 0; i < m; i++)
        for (int j = i + 1; j < m; j++)
            if (!strcmp(canon[i], canon[j])) return named[j];
    return NULL;
}

int cli_make_dirs(const char *dir)
{
    char buf[4096];
    size_t n = strlen(dir), i;
    struct stat st;
    if (n == 0 || n >= sizeof buf) return ENAMETOOLONG;
    memcpy(buf, dir, n + 1);
    for (i = 1; i <= n; i++) {
        if (buf[i] != '/' && buf[i] != '\0') continue;
        buf[i] = '\0';
        if (mkdir(buf, 0777) == 0) {
            wvol_error e;
            if (output_set_add_dir(buf, &e) != WVOL_OK) return ENOMEM; /* a failure removes it again */
        } else if (errno != EEXIST) {
            return errno;
        }
        buf[i] = i < n ? '/' : '\0';
    }
    if (stat(dir, &st) != 0) return errno;
    return S_ISDIR(st.st_mode) ? 0 : ENOTDIR;
}
