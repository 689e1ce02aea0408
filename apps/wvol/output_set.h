/* SPDX-License-Identifier: MIT */
/* The outputs of one command, kept or undone together. Every writer is atomic on its own (a
 * temporary renamed over the path), but a command that writes several files (an image and its
 * bound, a volume and its labels, progressive passes) can fail after the first is in place.
 * output_set_add, called before a file is written, keeps the file at that path (a hard link
 * beside it, "PATH.old-XXXXXX"); when the command ends, main() calls output_set_undo after a
 * failure, which puts every earlier file back and removes the files that did not exist before,
 * or output_set_done after a success, which drops the kept links. A path whose file is the one
 * it held at output_set_add (the same inode) is left alone: the command failed before writing it.
 * A file system without hard links keeps nothing: an undo then removes a file that replaced an
 * earlier one, which is lost, as a half-made set of outputs would otherwise stay. */
#ifndef WVOL_APP_OUTPUT_SET_H
#define WVOL_APP_OUTPUT_SET_H

#include "wvol/status.h"

/* Before path is written. A path already in the set, or NULL, is ignored. Fails when out of
 * memory or past 16384 outputs. */
wvol_status output_set_add(const char *path, wvol_error *err);
/* A folder the command created for its outputs (cli_make_dirs): an undo removes it again if it
 * is empty then. Fails only when out of memory. */
wvol_status output_set_add_dir(const char *path, wvol_error *err);
/* After a failure: every path as it was before output_set_add, the folders made removed. */
void output_set_undo(void);
/* From a handler of a signal that ends the process: undoes the set as output_set_undo does,
 * async-signal-safe (it frees nothing). */
void output_set_undo_on_signal(void);
/* After a success: removes the kept links. */
void output_set_done(void);

#endif
