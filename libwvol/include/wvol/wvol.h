/* SPDX-License-Identifier: MIT
 * libwvol umbrella header: includes only.
 * Threading: handles are not shared between threads while one of them mutates;
 * read-only functions on const handles are safe to run concurrently. */
#ifndef WVOL_WVOL_H
#define WVOL_WVOL_H
#include "wvol/version.h"
#include "wvol/status.h"
#include "wvol/volume.h"
#include "wvol/io.h"
#include "wvol/source.h"
#include "wvol/image.h"
#include "wvol/wavelet.h"
#include "wvol/store.h"
#include "wvol/wvc.h"
#include "wvol/compress.h"
#include "wvol/render.h"
#include "wvol/progressive.h"
#include "wvol/lod.h"
#include "wvol/iso.h"
#include "wvol/analysis.h"
#include "wvol/rng.h"
#include "wvol/radiosity.h"
#include "wvol/transport.h"
#endif
