/* SPDX-License-Identifier: MIT */
/* wvol: the command-line program. Sub-commands live in cmd_<name>.c; CMake
 * generates the table below from those file names. */
#include <stdio.h>
#include <string.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

#include "cli.h"
#include "commands.h"
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
 * between a writer's chunks. docs/cli.md says the same; bench/results/speed_profile.md has the
 * thresholds measured. */
static void allocator_policy(void)
{
#if defined(__GLIBC__) && defined(M_MMAP_THRESHOLD) && defined(M_TRIM_THRESHOLD)
    (void)mallopt(M_MMAP_THRESHOLD, 4 << 20);
    (void)mallopt(M_TRIM_THRESHOLD, 128 << 20);
#endif
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
        if (!strcmp(argv[1], commands[i].name)) return commands[i].run(argc - 1, argv + 1);
    fprintf(stderr, "wvol: unknown command '%s' (run 'wvol --help' for the list)\n", argv[1]);
    return CLI_USAGE;
}
