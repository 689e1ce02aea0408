/* SPDX-License-Identifier: MIT */
/* `wvol info` on a .wvc store (implemented with the store module). */
#ifndef WVOL_INFO_WVC_H
#define WVOL_INFO_WVC_H
int wvol_cli_info_wvc(const char *path, int json);
#endif
