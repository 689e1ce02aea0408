/* SPDX-License-Identifier: MIT
 * Constants of the .wvc byte layout (docs/wvc-format.md). Not installed. */
#ifndef WVOL_CODEC_WVC_FORMAT_H
#define WVOL_CODEC_WVC_FORMAT_H

/* PNG-style magic: a high byte, the name, CR LF, ^Z, LF catch text-mode damage. */
#define WVC_MAGIC "\x89WVC\r\n\x1a\n"
#define WVC_HEADER_SIZE 208
#define WVC_SECTION_SIZE 48
#define WVC_DEFAULT_ROUNDING 0.38
/* The step's range, scale-free (docs/conventions.md, "Supported magnitudes"): any step
 * a float32 coefficient can need. Largest: FLT_MAX (a larger one zeroes every float32 value);
 * the decoder refuses a dequantised value beyond FLT_MAX, and the encoder never writes one.
 * Smallest: far below 2^-29 of the smallest subnormal float (1.4e-45), so that no float32
 * coefficient is out of reach. Readers before this change took 1e-30 .. 1e25: they refuse
 * files of volumes beyond about 1e-27 .. 1e27. */
#define WVC_MAX_STEP 3.4028234663852886e38
#define WVC_MIN_STEP 1e-60
#define WVC_DEFAULT_MAX_VOXELS ((uint64_t)1 << 34)

#endif
