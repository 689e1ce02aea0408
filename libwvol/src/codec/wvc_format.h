/* SPDX-License-Identifier: MIT
 * Constants of the .wvc byte layout (docs/wvc-format.md). Not installed. */
#ifndef WVOL_CODEC_WVC_FORMAT_H
#define WVOL_CODEC_WVC_FORMAT_H

/* PNG-style magic: a high byte, the name, CR LF, ^Z, LF catch text-mode damage. */
#define WVC_MAGIC "\x89WVC\r\n\x1a\n"
#define WVC_HEADER_SIZE 208
#define WVC_SECTION_SIZE 48
#define WVC_DEFAULT_ROUNDING 0.38
/* Largest step a file may carry: (2^30 + 1) * step stays far inside float range. */
#define WVC_MAX_STEP 1e25
#define WVC_MIN_STEP 1e-30
#define WVC_DEFAULT_MAX_VOXELS ((uint64_t)1 << 34)

#endif
