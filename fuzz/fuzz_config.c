/*
 * fuzz_config.c - libFuzzer target for the machine configuration reader
 * (src/machine/). The checks: fuzz/invariants.h (inv_config_text,
 * inv_machine_raw). Built and run by fuzz/run.sh.
 *
 * Input: the INI text, parsed into defaults, again with err == NULL, and into
 * the parsed mill-3axis machine (all three must agree; see inv_config_text).
 * An input whose first byte is 0xFF (never valid UTF-8, so the parser would
 * stop at 1:1) is instead a raw struct mlip_machine for mlip_machine_check:
 * any doubles (NaN, inf, subnormals, -0), letters, kinds and counts; its
 * message must be well formed and a machine it passes must be sane.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "invariants.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static struct mlip_config mill;

static void violation(const char *what, const char *detail)
{
	fprintf(stderr, "fuzz_config: invariant violated: %s\n  %s\n", what, detail ? detail : "");
	abort();
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
	(void)argc;
	(void)argv;
	mlip_config_defaults(&mill);
	if (mlip_config_parse(&mill, inv_mill_ini, strlen(inv_mill_ini), NULL) != MLIP_OK) {
		violation("the built-in mill does not parse", NULL);
	}
	return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	struct inv_config_result r;
	struct mlip_machine m;
	const char *w;

	if (size >= 1 && data[0] == 0xFF) {
		memset(&m, 0, sizeof m);
		memcpy(&m, data + 1, size - 1 < sizeof m ? size - 1 : sizeof m);
		w = inv_machine_raw(&m);
		if (w) {
			violation(w, "raw machine (0xFF mode)");
		}
		return 0;
	}
	w = inv_config_text(&mill, (const char *)data, size, &r);
	if (w) {
		violation(w, r.st != MLIP_OK ? r.err.msg : NULL);
	}
	return 0;
}
