#include "cli.h"
#include "info_wvc.h"

int wvol_cli_info_wvc(const char *path, int json)
{
    (void)json;
    return cli_fail("info", "%s: .wvc stores are not supported by this build yet", path);
}
