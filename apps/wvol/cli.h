/* SPDX-License-Identifier: MIT */
/* Shared helpers of the wvol sub-commands: option parsing, messages, JSON, progress.
 * Exit codes: 0 ok, 1 failed, 2 bad usage. Every error is one line on stderr. */
#ifndef WVOL_CLI_H
#define WVOL_CLI_H

#include <stddef.h>
#include <stdint.h>
#include "wvol/io.h"
#include "wvol/status.h"

enum { CLI_OK = 0, CLI_FAILED = 1, CLI_USAGE = 2 };

typedef struct cli_opt {
    const char *name;   /* long name without "--" */
    char short_name;    /* 0 if none */
    int takes_value;
    const char *help;
} cli_opt;

typedef struct cli_parser {
    int argc;
    char **argv;
    int i;
    const char *cmd;
    const cli_opt *opts;  /* terminated by {NULL} */
    unsigned char given[128]; /* given[k]: opts[k] was on the command line (the first 128 options) */
    int positional_only;      /* after "--": every argument is positional (a file named "-x") */
} cli_parser;

void cli_parser_init(cli_parser *p, const char *cmd, int argc, char **argv, const cli_opt *opts);

/* Returns 1 for an option (*opt set, *value its value or NULL), 0 for a positional
 * argument (*opt NULL, *value the argument; every argument after "--" is one), -1 at
 * the end, CLI_USAGE after
 * printing an error for an unknown option or a missing value. "--help"/"-h" must
 * be listed in opts by the command if it wants them (cli_help_opt). */
int cli_next(cli_parser *p, const cli_opt **opt, const char **value);

/* Options read by some methods only: `opt` (long name) applies to the methods whose bits are set
 * in `methods` (bit m for method number m of the command); `which` names them for the message. */
typedef struct cli_method_rule {
    const char *opt;
    unsigned methods;
    const char *which;
} cli_method_rule;

/* Whether --name was given. */
int cli_given(const cli_parser *p, const char *name);
/* CLI_OK, or CLI_USAGE after "--OPT applies only to --method WHICH (not NAME)" for the first rule
 * (terminated by {NULL}) whose option was given and whose methods lack `method`: an option the
 * chosen method would not read is refused rather than ignored. */
int cli_method_rules(const cli_parser *p, const cli_method_rule *rules, int method, const char *method_name);

#define CLI_HELP_OPT {"help", 'h', 0, "show this help"}
#define CLI_JSON_OPT {"json", 0, 0, "machine-readable JSON on stdout"}
/* --threads, the same on every command that runs in parallel. */
#define CLI_THREADS_OPT {"threads", 0, 1, "threads (default: all cores, or OMP_NUM_THREADS)"}
#define CLI_MAX_THREADS 4096
/* --threads N (1..CLI_MAX_THREADS): the process's OpenMP default for every parallel region of
 * the run, also stored in *threads (for a library call's own threads field) when not NULL.
 * 1, or 0 after printing the usage error. */
int cli_threads(const char *cmd, const char *val, int *threads);
/* A .wvc input read within a memory budget (decoded chunks held at once). */
#define CLI_MEMORY_OPT {"memory", 0, 1, ".wvc input: budget for decoded chunks, e.g. 512M or 2G (default 1G)"}

/* The raw and .vdb input options of the commands that load a volume (cli_load_option):
 * a raw file's samples, byte order and place in the world, a .vdb file's grid. */
#define CLI_LOAD_OPTS                                                                    \
    {"dims", 0, 1, "raw input: NXxNYxNZ"},                                                \
    {"type", 0, 1, "raw input: sample type (float32, uint8, int16, ...)"},                 \
    {"big-endian", 0, 0, "raw input: samples are big-endian"},                           \
    {"spacing", 0, 1, "raw input: voxel spacing X,Y,Z or one number (default 1)"},        \
    {"origin", 0, 1, "raw input: world position of voxel (0,0,0), X,Y,Z (default 0)"},    \
    {"grid", 0, 1, ".vdb input: grid name (default: first float grid)"}

/* Applies o to lo when o is one of the loading options (--dims, --type, --big-endian,
 * --spacing, --origin, --grid): returns CLI_OK, or CLI_USAGE after printing an error
 * for a bad value; returns -1 when o is none of them. Only for commands whose options
 * of those names describe the input volume. */
int cli_load_option(const char *cmd, const cli_opt *o, const char *val, wvol_load_options *lo);

/* After parsing: CLI_USAGE (with a message) when a loading option given to cli_load_option does
 * not apply to the input at path (the raw-only ones to a file that carries its own geometry and
 * type, or a synth: generator; --grid to a file other than .vdb), which would otherwise be
 * ignored; CLI_OK otherwise (also for path NULL). also: a second input the same options load
 * (segment's truth), or NULL: the options fit when they fit either. */
int cli_load_options_fit(const char *cmd, const char *path, const char *also);

/* Takes val as the one positional input file of cmd: CLI_OK, or CLI_USAGE after an
 * error if *in is already set. */
int cli_one_input(const char *cmd, const char **in, const char *val);

void cli_print_help(const char *cmd, const char *usage, const char *about, const cli_opt *opts);

/* "wvol CMD: message" on stderr; return CLI_USAGE / CLI_FAILED. */
int cli_usage(const char *cmd, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
int cli_fail(const char *cmd, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
int cli_fail_err(const char *cmd, const wvol_error *err);

/* Value parsers: return 1 on success; on failure print a usage error naming the
 * option and return 0. */
int cli_parse_dims(const char *cmd, const char *opt, const char *s, size_t dims[3]);
int cli_parse_double(const char *cmd, const char *opt, const char *s, double *out);
int cli_parse_double3(const char *cmd, const char *opt, const char *s, double out[3]);
int cli_parse_long(const char *cmd, const char *opt, const char *s, long lo, long hi, long *out);
/* "5%" -> 0.05, "0.05" -> 0.05; must be in (0, 1]. */
/* A byte count: digits with an optional K, M, G or T (powers of 1024); > 0. */
int cli_parse_bytes(const char *cmd, const char *opt, const char *s, size_t *out);
/* A .wvc input opened as a file-backed store (wvol_store_open) within budget (0: the
 * default), in the shape of the pipeline's result: out->store, levels and value range
 * set, the rest zero. Prints the error and returns CLI_FAILED on failure. */
struct wvol_compressed;
int cli_open_wvc_store(const char *cmd, const char *path, size_t budget, struct wvol_compressed *out);
/* After a file-backed store was used: CLI_OK, or CLI_FAILED (printed) when a chunk could
 * not be decoded or the budget did not hold; JSON fields when json is set. */
int cli_check_wvc_store(const char *cmd, const struct wvol_compressed *c, int json);
/* The chunk cache's counters as a JSON object under key. */
struct wvol_wvc_cache_stats;
void cli_json_wvc_cache(const char *key, const struct wvol_wvc_cache_stats *cs, uint64_t file_chunks);
int cli_parse_fraction(const char *cmd, const char *opt, const char *s, double *out);
/* "WxH", sides 1..65536. */
int cli_parse_size(const char *cmd, const char *opt, const char *s, long *w, long *h);

/* A transfer function: a file (text or JSON) when `name` is one, else a preset over the data
 * range [vmin, vmax]. Returns CLI_OK, or the exit code after printing the error. */
struct wvol_tf;
int cli_load_tf(const char *cmd, const char *name, double vmin, double vmax, struct wvol_tf *tf);

/* Minimal JSON writer on stdout (one object, nested objects/arrays allowed). */
void cli_json_begin(void);
void cli_json_end(void);
void cli_json_key(const char *key);
void cli_json_str(const char *key, const char *value);
void cli_json_num(const char *key, double value);
void cli_json_int(const char *key, long long value);
void cli_json_open(const char *key, char bracket);  /* '{' or '[' ; key may be NULL in arrays */
void cli_json_close(char bracket);
/* "key":[a,b,c] of sizes; "key":[x,y,z] of numbers. */
void cli_json_size3(const char *key, size_t a, size_t b, size_t c);
void cli_json_num3(const char *key, const double v[3]);

/* Progress bar on stderr, shown only when stderr is a terminal and the work has
 * taken over a second. */
void cli_progress(const char *label, double fraction);
void cli_progress_done(void);

/* mkdir -p: 0, or the errno of the step that failed (ENOTDIR when the path is a file). The
 * folders it makes join the command's output set (output_set.h): a failure removes them again. */
int cli_make_dirs(const char *dir);
/* The first file two of the outputs outs[0..n) would both write (an .nhdr's detached data file
 * counted as its own output), or NULL: paths that differ as strings can name one file
 * ("./a.nrrd" and "a.nrrd", a link, "s.nhdr" and its "s.raw"). NULL entries are skipped. */
const char *cli_same_output(const char *const *outs, int n);
/* What to write instead of a volume path no build writes: .mhd (read only) is .mha, otherwise
 * the list 'wvol convert --help' gives. */
const char *cli_write_hint(const char *path);
/* CLI_OK, or CLI_USAGE after saying so when the detached data file an .nhdr output writes
 * (NAME.raw) is the input file itself: the volume read from it would replace it, a side effect
 * nobody asked for. */
int cli_data_file_not_input(const char *cmd, const char *in, const char *out);

/* Seconds from a monotonic clock. */
double cli_now(void);
double cli_cpu_now(void); /* the process's CPU seconds, all threads (benchmark timings on a shared machine) */

#endif
