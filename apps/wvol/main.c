/* SPDX-License-Identifier: MIT */
/* wvol: the command-line program. Sub-commands live in cmd_<name>.c; CMake
 * generates the table below from those file names. */
#include <stdio.h>
#include <string.h>

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

int main(int argc, char **argv)
{
    size_t i;
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
