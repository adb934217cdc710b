/* cmd_render.c: placeholder until the geometry modules land (replaced in this change). */
#include "cli.h"
int cmd_render(int argc, char **argv) { (void)argc; (void)argv; return CLI_USAGE; }
void help_render(void) {}
