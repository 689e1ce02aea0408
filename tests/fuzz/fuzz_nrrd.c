/* SPDX-License-Identifier: MIT
 * libFuzzer target for the text-headed volume readers: each input is written to a file of
 * its own and read as NRRD the two ways the library reads it (the whole-volume reader,
 * io/nrrd_read.c, and the slab-by-slab source, io/source_file.c, every slab read), and its
 * header read as MetaImage (io/metaimage.c). A header may name a detached data file: the
 * files it can reach are the input's own (the scratch folder holds nothing else) and the
 * system's. Build and run: scripts/fuzz.sh. */
#include "fuzz_file.h" /* first: it sets the feature macros */
#include <stdint.h>
#include <stdlib.h>

#include "io/io_internal.h"
#include "wvol/io.h"
#include "wvol/source.h"
#include "wvol/volume.h"

/* the source's slabs, read whole, when the volume is at most this many samples */
#define MAX_SAMPLES (1u << 20)

static void read_source(const char *path)
{
    wvol_source *s = NULL;
    wvol_error err;
    size_t dims[3], n;
    double sp[3], org[3];
    float *slab;
    if (wvol_source_open(&s, path, NULL, &err) != WVOL_OK) return;
    wvol_source_geometry(s, dims, sp, org);
    if (wvol_size_mul3(dims[0], dims[1], dims[2], 1, &n) && n <= MAX_SAMPLES &&
        (slab = malloc(dims[0] * dims[1] * 2 * sizeof *slab))) {
        for (size_t z = 0; z < dims[2]; z += 2) {
            const size_t nz = dims[2] - z < 2 ? dims[2] - z : 2;
            if (wvol_source_read(s, slab, z, nz, &err) != WVOL_OK) break;
        }
        free(slab);
    }
    wvol_source_destroy(s);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *nrrd = fuzz_write("in.nrrd", data, size), *mha = fuzz_write("in.mha", data, size);
    wvol_volume *v = NULL;
    wvol__meta_header mh;
    wvol_error err;
    if (wvol_nrrd_read(&v, nrrd, &err) == WVOL_OK) wvol_volume_destroy(v);
    read_source(nrrd);
    wvol__meta_read_header(&mh, mha, &err);
    return 0;
}
