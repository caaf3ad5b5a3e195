/*
 * mlip-config - read a machine configuration the way every mlip tool does
 * (src/machine/config.c) and print it as parsed: the check of a file before a run,
 * and the one INI reader for tools in other languages (--json), so the
 * listener and the tests never parse the file a second way.
 */
#include <getopt.h>
#include <stdio.h>
#include <string.h>

#include "confjson.h"
#include "confload.h"
#include "cli.h"
#include "mlip/can/canenc.h"

#define PROG "mlip-config"

static void usage(FILE *f)
{
	fprintf(f, "usage: " PROG " [--json] [--profile P] FILE.ini\n"
	           "Check a machine configuration and print it as the mlip tools read it.\n\n"
	           "  --json        one JSON object on stdout (machine, axes, [CAN], the CAN\n"
	           "                frames of the profile, [DRIVES])\n"
	           "  --profile P   the [CAN] profile mlip-rt --profile P would use (checked\n"
	           "                with the same id rules)\n"
	           "  -h, --help\n\n"
	           "exit status: 0 valid; 1 an error (file:line:col: error: ...); 2 usage\n");
}

int main(int argc, char **argv)
{
	static const struct option opts[] = {{"json", no_argument, 0, 'j'},
	                                     {"print-config", no_argument, 0, 'p'},
	                                     {"profile", required_argument, 0, 'P'},
	                                     {"help", no_argument, 0, 'h'},
	                                     {0, 0, 0, 0}};
	static struct mlip_config cfg;
	const char *profile = NULL;
	int c, json = 0;

	while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
		switch (c) {
		case 'j':
			json = 1;
			break;
		case 'p':
			break; /* the default action, accepted for symmetry with other tools */
		case 'P':
			profile = optarg;
			break;
		case 'h':
			usage(stdout);
			return 0;
		default:
			usage(stderr);
			return 2;
		}
	}
	if (optind != argc - 1) {
		usage(stderr);
		return 2;
	}
	if (mlip_config_load(argv[optind], &cfg, stderr) != 0) {
		return 1;
	}
	const char *warn = mlip_io_probe_warning(&cfg.inputs);
	if (warn != NULL) {
		fprintf(stderr, "%s: warning: %s\n", argv[optind], warn);
	}
	if (profile != NULL) {
		mlip_can_profile p;
		int rc = mlip_cli_can_override(&cfg, argv[optind], profile, 0.0, &p, PROG, stderr);
		if (rc != 0) {
			return rc;
		}
	}
	if (json) {
		mlip_config_print_json(stdout, argv[optind], &cfg);
		return 0;
	}
	const struct mlip_machine *m = &cfg.machine;
	printf("%s: %d axes, v_m %g mm/s, eps %g mm, T %g s, look-ahead %u, CAN %s\n", argv[optind],
	       m->n_axes, m->max_feed_mm_s, m->tolerance_mm, m->period_s, (unsigned)cfg.lookahead,
	       cfg.can.profile);
	for (int i = 0; i < m->n_axes; i++) {
		const struct mlip_axis *a = &m->axis[i];
		printf(
		    "  %c %s: V %g, A %g, J %g, limits %g..%g, home %g, node %d, %g counts/unit\n",
		    a->letter, a->kind == MLIP_AXIS_ROTARY ? "angular" : "linear", a->max_vel,
		    a->max_accel, a->max_jerk, a->min_limit, a->max_limit, a->home, a->can_node,
		    a->counts_per_unit);
	}
	/* the machine's I/O: what a program's S, M3, M6, M8 meet */
	const struct mlip_gcode_io *io = &cfg.io;
	if (io->spindle == MLIP_IO_NONE) {
		printf("  spindle: none (M3/M4/S refused)\n");
	} else if (io->spindle == MLIP_IO_MANUAL) {
		printf("  spindle: manual, %g..%g rpm\n", io->min_rpm, io->max_rpm);
	} else {
		const struct mlip_spindle_config *sp = &cfg.spindle;
		printf("  spindle: CiA 402 drive, node %u, profile velocity, %g..%g rpm, %g "
		       "counts/rev, "
		       "%g rpm/s, at speed within %g rpm (timeout %g s, out of band %g s)\n",
		       (unsigned)sp->node, io->min_rpm, io->max_rpm, sp->counts_per_rev,
		       sp->accel_rpm_s, sp->band_rpm, sp->timeout_s, sp->band_time_s);
	}
	if (io->tool_change == MLIP_IO_NONE) {
		printf("  tool change: none (M6 refused)\n");
	} else {
		printf("  tool change: manual");
		for (int i = 0; i < m->n_axes; i++) {
			if (io->change_mask >> i & 1u) {
				printf(" %c%g", m->axis[i].letter, io->change_pos[i]);
			}
		}
		printf("%s\n", io->change_mask ? " (change position, machine coordinates)" : "");
	}
	const struct mlip_io_config *in = &cfg.inputs;
	if (in->probe_source == MLIP_PROBE_SRC_DRIVE) {
		const struct mlip_io_bit *p = &in->in[MLIP_IN_PROBE];
		printf("  probe: the axis drives' touch probe 1 (0x60B8..0x60BB)");
		if (in->mapped >> MLIP_IN_PROBE & 1u) {
			printf(", level node %u 0x%04X:%u bit %u%s\n", (unsigned)p->node,
			       (unsigned)p->index, (unsigned)p->sub, (unsigned)p->bit,
			       p->active_low ? " LOW" : "");
		} else {
			printf(", no level mapped\n");
		}
	} else if (in->mapped >> MLIP_IN_PROBE & 1u) {
		const struct mlip_io_bit *p = &in->in[MLIP_IN_PROBE];
		printf("  probe: input node %u 0x%04X:%u bit %u%s\n", (unsigned)p->node,
		       (unsigned)p->index, (unsigned)p->sub, (unsigned)p->bit,
		       p->active_low ? " LOW" : "");
	} else {
		printf("  probe: none (G38 refused)\n");
	}
	printf("  coolant: %s\n", io->coolant == MLIP_IO_NONE     ? "none (M7/M8 refused)"
	                          : io->coolant == MLIP_IO_MODULE ? "io (the I/O module's outputs)"
	                                                          : "manual");
	for (uint32_t o = 0; o < MLIP_OUT_COUNT; o++) {
		const struct mlip_io_out *x = &cfg.inputs.out[o];
		if (cfg.inputs.out_mapped >> o & 1u) {
			char name[16];
			snprintf(name, sizeof(name), "%s",
			         o == MLIP_OUT_MIST ? "mist (M7)" : "flood (M8)");
			if (o >= MLIP_OUT_DOUT0) {
				snprintf(name, sizeof(name), "M64 P%u", o - MLIP_OUT_DOUT0);
			}
			printf("  output %-10s node %u 0x6200:%u bit %u\n", name, cfg.inputs.node,
			       x->sub, x->bit);
		}
	}
	return 0;
}
