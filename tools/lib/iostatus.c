/*
 * iostatus.c - the machine's outputs and the last probe in mlip-ctl status
 * (iostatus.h).
 */
#include "iostatus.h"

#include <stdio.h>

#include "mlip/gcode/gcode.h"

/* LinuxCNC numbers the probe's parameters by axis X Y Z A B C U V W: #5061 + i. */
static int param_of(char letter)
{
	static const char order[] = "XYZABC";
	for (int i = 0; order[i] != '\0'; i++) {
		if (order[i] == letter) {
			return 5061 + i;
		}
	}
	return 0;
}

void mlip_iostatus_json(struct mlip_json *j, const struct mlip_machine *m,
                        const struct mlip_ring_status *st, const struct mlip_ring *r)
{
	struct mlip_ring_io io;
	char key[24]; /* "0x6200:" and an int: -O1 cannot see k < MLIP_IO_BYTES_SHOWN */

	mlip_json_object(j, "outputs", 1);
	for (int k = 0; k < MLIP_IO_BYTES_SHOWN; k++) {
		unsigned v = (unsigned)(st->outputs >> (8 * k)) & 0xFFu;
		if (v != 0) {
			snprintf(key, sizeof(key), "0x6200:%d", k + 1);
			mlip_json_uint(j, key, v);
		}
	}
	mlip_json_close(j);
	if (mlip_ring_io_read(r, &io) == MLIP_OK && io.coolant != MLIP_IO_MODULE &&
	    st->coolant == 0) {
		/* no outlet the controller switches ([COOLANT] TYPE none or manual):
		 * nothing it could report */
		mlip_json_string(j, "coolant", "none");
	} else {
		mlip_json_object(j, "coolant", 1);
		mlip_json_bool(j, "mist", (st->coolant & MLIP_COOLANT_MIST) != 0);
		mlip_json_bool(j, "flood", (st->coolant & MLIP_COOLANT_FLOOD) != 0);
		mlip_json_close(j);
	}
	if (st->probe_count == 0) {
		mlip_json_null(j, "probe");
		return;
	}
	mlip_json_object(j, "probe", 0);
	mlip_json_uint(j, "count", st->probe_count);
	mlip_json_bool(j, "tripped", st->probe_tripped != 0);
	mlip_json_uint(j, "line", st->probe_line);
	mlip_json_object(j, "position", 1);
	for (int k = 0; k < m->n_axes; k++) {
		char l[2] = {m->axis[k].letter, '\0'};
		mlip_json_number(j, l, "%.17g", st->probe_pos[k]);
	}
	mlip_json_close(j);
	mlip_json_object(j, "parameters", 1);
	for (int k = 0; k < m->n_axes; k++) {
		int p = param_of(m->axis[k].letter);
		if (p != 0) {
			snprintf(key, sizeof(key), "%d", p);
			mlip_json_number(j, key, "%.17g", st->probe_pos[k]);
		}
	}
	mlip_json_uint(j, "5070", st->probe_tripped != 0);
	mlip_json_close(j);
	mlip_json_close(j);
}

static void outputs_line(FILE *f, const struct mlip_ring_status *st)
{
	fprintf(f, "outputs    coolant %s",
	        st->coolant == 0                    ? "off"
	        : st->coolant == MLIP_COOLANT_MIST  ? "mist"
	        : st->coolant == MLIP_COOLANT_FLOOD ? "flood"
	                                            : "mist+flood");
	if (st->outputs == 0) {
		fprintf(f, ", module outputs all off");
	}
	for (int k = 0; k < MLIP_IO_BYTES_SHOWN; k++) {
		unsigned v = (unsigned)(st->outputs >> (8 * k)) & 0xFFu;
		if (v != 0) {
			fprintf(f, ", 0x6200:%d = 0x%02X", k + 1, v);
		}
	}
	fprintf(f, "\n");
}

void mlip_iostatus_text(FILE *f, const struct mlip_machine *m, const struct mlip_ring_status *st,
                        const struct mlip_ring *r)
{
	struct mlip_ring_io io;

	/* a machine without outputs (none in the segment's I/O area) says nothing */
	if ((mlip_ring_io_read(r, &io) == MLIP_OK &&
	     (io.coolant == MLIP_IO_MODULE || (io.outputs & 0xFF00u) != 0)) ||
	    st->outputs != 0 || st->coolant != 0) {
		outputs_line(f, st);
	}
	if (st->probe_count == 0) {
		return;
	}
	fprintf(f, "probe      line %u %s at", (unsigned)st->probe_line,
	        st->probe_tripped ? "tripped" : "did not trip, ended");
	for (int k = 0; k < m->n_axes; k++) {
		fprintf(f, " %c %.4f", m->axis[k].letter, st->probe_pos[k]);
	}
	fprintf(f, " (#5070 = %d)\n", st->probe_tripped != 0);
}
