/*
 * confload.c - read, parse and check a machine configuration file; errors
 * printed GCC style. See confload.h.
 */
#include "confload.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

void mlip_config_perror(FILE *f, const char *path, const struct mlip_config_error *e)
{
	if (f == NULL) {
		return;
	}
	if (e->line == 0) {
		fprintf(f, "%s: error: %s\n", path, e->msg);
	} else if (e->col == 0) {
		fprintf(f, "%s:%lu: error: %s\n", path, (unsigned long)e->line, e->msg);
	} else {
		fprintf(f, "%s:%lu:%lu: error: %s\n", path, (unsigned long)e->line,
		        (unsigned long)e->col, e->msg);
	}
}

int mlip_config_load(const char *path, struct mlip_config *c, FILE *errf)
{
	struct mlip_config tmp;
	struct mlip_config_error e;
	char *buf = NULL;
	size_t n;
	int rc = -1;
	FILE *f = fopen(path, "rb");

	if (f == NULL) {
		if (errf != NULL) {
			fprintf(errf, "%s: error: cannot open: %s\n", path, strerror(errno));
		}
		return -1;
	}
	/* one byte more than allowed tells a too large file from a full one */
	buf = malloc(MLIP_CONFIG_MAX_FILE + 1);
	if (buf == NULL) {
		if (errf != NULL) {
			fprintf(errf, "%s: error: out of memory\n", path);
		}
		goto out;
	}
	n = fread(buf, 1, MLIP_CONFIG_MAX_FILE + 1, f);
	if (ferror(f)) {
		if (errf != NULL) {
			fprintf(errf, "%s: error: cannot read: %s\n", path, strerror(errno));
		}
		goto out;
	}
	if (n > MLIP_CONFIG_MAX_FILE) {
		if (errf != NULL) {
			fprintf(errf,
			        "%s: error: larger than %u bytes: not a machine configuration\n",
			        path, MLIP_CONFIG_MAX_FILE);
		}
		goto out;
	}
	mlip_config_defaults(&tmp);
	if (mlip_config_parse(&tmp, buf, n, &e) != MLIP_OK ||
	    mlip_machine_check(&tmp.machine, &e) != MLIP_OK) {
		mlip_config_perror(errf, path, &e);
		goto out;
	}
	*c = tmp;
	rc = 0;
out:
	free(buf);
	fclose(f);
	return rc;
}
