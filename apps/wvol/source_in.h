/* SPDX-License-Identifier: MIT */
/* Inputs that a sub-command can read slab by slab: a file (raw, NRRD stream; the other
 * formats are read whole) or a generator named "synth:KIND[,size=N|NXxNYxNZ][,seed=S]
 * [,noise=SIGMA][,sigma=S][,count=N][,variant=NAME]" (docs/cli.md). */
#ifndef WVOL_APP_SOURCE_IN_H
#define WVOL_APP_SOURCE_IN_H

#include "wvol/io.h"
#include "wvol/source.h"

/* 1 if `in` names a generator ("synth:..."). */
int source_in_is_synth(const char *in);
/* 1 if `in` is read slab by slab (a generator, raw or NRRD). */
int source_in_streams(const char *in);
/* Opens `in` as a source (lo: the raw options, may be NULL). A bad generator spec is
 * refused with WVOL_ERR_ARG and a message naming the part. */
wvol_status source_in_open(wvol_source **out, const char *in, const wvol_load_options *lo, wvol_error *err);

#endif
