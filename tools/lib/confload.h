/*
 * confload.h - host side of the machine configuration: read an INI file,
 * parse it with mlip_config_parse, check it with mlip_machine_check, and
 * print errors the way GCC does ("path:LINE:COL: error: MSG"), so editors
 * and CI logs jump to the offending key.
 */
#ifndef MLIP_CONFLOAD_H
#define MLIP_CONFLOAD_H

#include <stdio.h>

#include "mlip/machine/config.h"

/* Files larger than this are refused: a configuration is a page of text. */
#define MLIP_CONFIG_MAX_FILE (1u << 20)

/* Load path into *c, starting from mlip_config_defaults (so *c need not be
 * initialised). Returns 0, or -1 with one error printed to errf (NULL: none)
 * and *c unchanged. */
int mlip_config_load(const char *path, struct mlip_config *c, FILE *errf);

/* Print e as "path:LINE:COL: error: MSG\n", leaving out ":COL" when e->col
 * is 0 and ":LINE:COL" when e->line is 0 (a whole-file error, or a check
 * after command-line overrides, where path may be the program's name). */
void mlip_config_perror(FILE *f, const char *path, const struct mlip_config_error *e);

#endif
