/* SPDX-License-Identifier: MIT
 * libFuzzer target for the DICOM file parser (io/dicom_file.c) and the number syntax
 * of text headers it uses (io/io_common.c). Build and run: scripts/fuzz.sh. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "io/dicom_internal.h"
#include "io/io_internal.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    dicom_info info;
    wvol_error err;
    double v[8];
    char *text = malloc(size + 1);
    wvol__dicom_info_init(&info);
    info.file = strdup("fuzz.dcm");
    if (info.file) wvol__dicom_parse_file(&info, data, size, &err);
    wvol__dicom_info_free(&info);
    if (text) {
        memcpy(text, data, size);
        text[size] = '\0';
        wvol__io_parse_numbers(text, v, 8);
        free(text);
    }
    return 0;
}
