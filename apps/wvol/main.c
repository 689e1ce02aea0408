/* SPDX-License-Identifier: MIT */
/* wvol: the command-line program. Sub-commands live in cmd_<name>.c; CMake
 * generates the table below from those file names. */
#define _DEFAULT_SOURCE /* sbrk */
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#ifdef __GLIBC__
#include <malloc.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <unistd.h>
#endif

#include "cli.h"
#include "output_set.h"
#include "commands.h"
#include "wvol/io.h"
#include "wvol/version.h"

typedef struct command {
    const char *name;
    int (*run)(int argc, char **argv);
    const char *summary;
} command;

static const command commands[] = {WVOL_COMMAND_TABLE};

static void usage(FILE *out)
{
    size_t i;
    fprintf(out, "usage: wvol <command> [options]   (wvol <command> --help for details)\n\ncommands:\n");
    for (i = 0; i < sizeof commands / sizeof commands[0]; i++)
        fprintf(out, "  %-12s %s\n", commands[i].name, commands[i].summary);
    fprintf(out, "\nwvol %s\n", wvol_version_string());
}

/* The program's allocator policy (the library leaves malloc's settings to the program that
 * links it): a fixed mmap threshold of 4 MiB and a trim threshold of 128 MiB. glibc's own
 * threshold moves with every large block freed, so whether the brick path's scratch (blocks of
 * some hundred KiB to a few MiB, made and freed per brick) stayed in the heap or went to fresh
 * mappings, faulted in again at every extraction, depended on what had been freed before.
 * Blocks from 4 MiB on (the library's large buffers, asked for huge pages) get mappings of their
 * own, where huge pages work; the heap keeps what it has grown to instead of giving its top back
 * between a writer's chunks.
 *
 * And the heap in huge pages: its first HEAP_RESERVE bytes above what start-up used are asked
 * for transparent huge pages (glibc's own switch for that, the glibc.malloc.hugetlb tunable,
 * is read from the environment at start only). The heap serves every block below 4 MiB (mesh
 * pieces, payloads, row buffers, the coders' tables), and in 4 KiB pages each first touch was a
 * fault of its own: most of a compression's page faults and of a store's first marching cubes'.
 * The heap is grown once by the reserve (address space only: pages become resident as they are
 * touched, 2 MiB at a time) and the advice given to its whole 2 MiB pages; growth past the
 * reserve gets 4 KiB pages as before. Where the advice is refused, nothing changes.
 * docs/cli.md says the same; bench/results/speed_profile.md has the thresholds and the
 * faults measured. */
#define HEAP_RESERVE ((size_t)64 << 20)

static void allocator_policy(void)
{
#if defined(__GLIBC__) && defined(M_MMAP_THRESHOLD) && defined(M_TRIM_THRESHOLD)
    (void)mallopt(M_MMAP_THRESHOLD, 4 << 20);
    (void)mallopt(M_TRIM_THRESHOLD, 128 << 20);
#if defined(M_TOP_PAD) && defined(MADV_HUGEPAGE)
    {
        const uintptr_t huge = (uintptr_t)2 << 20;
        void *p;
        char *top;
        /* the next growth of the heap takes the reserve with it; the block is freed at once
         * into the top of the heap, which the trim threshold keeps */
        (void)mallopt(M_TOP_PAD, (int)HEAP_RESERVE);
        p = malloc((size_t)1 << 20);
        top = sbrk(0);
        (void)mallopt(M_TOP_PAD, 128 << 10); /* glibc's default */
        if (p && top != (char *)-1 && (char *)p < top) {
            uintptr_t a = ((uintptr_t)p + huge - 1) & ~(huge - 1), b = (uintptr_t)top & ~(huge - 1);
            if (b > a) (void)madvise((void *)a, (size_t)(b - a), MADV_HUGEPAGE);
        }
        free(p);
    }
#endif
#endif
}

/* SIGINT, SIGTERM, SIGHUP: a command stopped is a command failed, which leaves the folder as it
 * found it: the library's open temporaries are removed and the outputs already replaced are put
 * back; then the signal, its default action restored (SA_RESETHAND), ends the process as it
 * would have (status 128 + the signal), once the handler returns. */
static void on_stop_signal(int sig)
{
    const int saved = errno;
    wvol_atomic_remove_pending();
    output_set_undo_on_signal();
    raise(sig); /* blocked while the handler runs: delivered, with the default action, on return */
    errno = saved;
}

static void catch_stop_signals(void)
{
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop_signal;
    sa.sa_flags = SA_RESETHAND;
    sigfillset(&sa.sa_mask); /* one handler at a time */
    for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        struct sigaction old;
        /* a signal the caller set to be ignored (nohup, a shell's background job) stays ignored */
        if (sigaction(sigs[i], NULL, &old) == 0 && old.sa_handler != SIG_IGN) sigaction(sigs[i], &sa, NULL);
    }
}

/* The command's report, and for `info` its whole result, went to stdout: a write that failed
 * there (a full disk, a closed pipe with SIGPIPE ignored) fails the command. */
static int check_stdout(const char *cmd, int rc)
{
    errno = 0;
    if (fflush(stdout) == 0 && !ferror(stdout)) return rc;
    fprintf(stderr, "wvol %s: cannot write to standard output: %s\n", cmd, errno ? strerror(errno) : "stream error");
    return rc == CLI_OK ? CLI_FAILED : rc;
}

int main(int argc, char **argv)
{
    size_t i;
    allocator_policy();
    if (argc < 2) {
        usage(stderr);
        return CLI_USAGE;
    }
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
        usage(stdout);
        return CLI_OK;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("wvol %s\n", wvol_version_string());
        return CLI_OK;
    }
    for (i = 0; i < sizeof commands / sizeof commands[0]; i++)
        if (!strcmp(argv[1], commands[i].name)) {
            int rc;
            catch_stop_signals();
            rc = check_stdout(argv[1], commands[i].run(argc - 1, argv + 1));
            if (rc != CLI_OK) output_set_undo(); /* a failed command leaves the files it was to write as they were */
            else output_set_done();
            return rc;
        }
    fprintf(stderr, "wvol: unknown command '%s' (run 'wvol --help' for the list)\n", argv[1]);
    return CLI_USAGE;
}
