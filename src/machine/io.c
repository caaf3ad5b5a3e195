/*
 * io.c - the [SPINDLE], [TOOL] and [COOLANT] sections (issue 19) into the
 * config's struct mlip_gcode_io, and against the rest of the file.
 */
#include <string.h>

#include "keys.h"

void mlip_mc_fill_io(const struct pstate *ps, struct mlip_config *c)
{
	const struct sec *sp = &ps->sec[SEC_SPINDLE], *tl = &ps->sec[SEC_TOOL];
	struct mlip_gcode_io *io = &c->io;
	int i;

	memset(io, 0, sizeof *io);
	io->spindle = has(ps, SEC_SPINDLE, SK_TYPE) ? (int)sp->ival[SK_TYPE] : MLIP_IO_NONE;
	io->min_rpm = has(ps, SEC_SPINDLE, SK_MIN_RPM) ? sp->num[SK_MIN_RPM] : 0.0;
	io->max_rpm = has(ps, SEC_SPINDLE, SK_MAX_RPM) ? sp->num[SK_MAX_RPM] : 0.0;
	io->tool_change = has(ps, SEC_TOOL, OK_CHANGE) ? (int)tl->ival[OK_CHANGE] : MLIP_IO_NONE;
	for (i = 0; i < c->machine.n_axes; i++) {
		int k = OK_POS0 + letter_index(c->machine.axis[i].letter);
		if (has(ps, SEC_TOOL, k)) {
			io->change_mask |= 1u << i;
			io->change_pos[i] = tl->num[k];
		}
	}
	io->coolant =
	    has(ps, SEC_COOLANT, QK_TYPE) ? (int)ps->sec[SEC_COOLANT].ival[QK_TYPE] : MLIP_IO_NONE;
}

static mlip_status io_err(const struct pstate *ps, struct mlip_config_error *err, int sec, int k1,
                          int k2, const char *msg)
{
	struct mlip_tb b;

	err_at(err, &b, 0, 0);
	mlip_tb_puts(&b, msg);
	mlip_mc_place(ps, err, sec, k1, sec, k2, -1, 0);
	return MLIP_E_RANGE;
}

/* A key that has no effect with the section's TYPE/CHANGE none is an
 * error (nothing in the file is silently ignored); the speeds make sense
 * together; the change position is on the machine's axes, inside their
 * soft limits. */
mlip_status mlip_mc_check_io(const struct pstate *ps, const struct mlip_config *c,
                             struct mlip_config_error *err)
{
	const struct mlip_gcode_io *io = &c->io;
	struct mlip_tb b;
	int l, k;

	if (io->spindle == MLIP_IO_NONE) {
		for (k = SK_MIN_RPM; k <= SK_MAX_RPM; k++) {
			if (has(ps, SEC_SPINDLE, k)) {
				return io_err(
				    ps, err, SEC_SPINDLE, k, SK_TYPE,
				    k == SK_MIN_RPM
				        ? "MIN_RPM is for a spindle: TYPE = none has none"
				        : "MAX_RPM is for a spindle: TYPE = none has none");
			}
		}
	} else {
		if (!has(ps, SEC_SPINDLE, SK_MAX_RPM)) {
			err_at(err, &b, ps->sec[SEC_SPINDLE].at.line, 0);
			mlip_tb_puts(&b,
			             "missing MAX_RPM in [SPINDLE] (an S beyond it is refused)");
			return MLIP_E_SYNTAX;
		}
		if (!(io->max_rpm > 0)) {
			return io_err(ps, err, SEC_SPINDLE, SK_MAX_RPM, -1, "MAX_RPM must be > 0");
		}
		if (io->min_rpm > io->max_rpm) {
			return io_err(ps, err, SEC_SPINDLE, SK_MIN_RPM, SK_MAX_RPM,
			              "MIN_RPM must be <= MAX_RPM");
		}
	}
	for (l = 0; l < MLIP_MAX_AXES; l++) {
		int i, sec_key = OK_POS0 + l;
		if (!has(ps, SEC_TOOL, sec_key)) {
			continue;
		}
		if (io->tool_change == MLIP_IO_NONE) {
			return io_err(
			    ps, err, SEC_TOOL, sec_key, OK_CHANGE,
			    "a change position is for a tool change: CHANGE = none has none");
		}
		for (i = 0; i < c->machine.n_axes && c->machine.axis[i].letter != AXIS_LETTERS[l];
		     i++) {
		}
		if (i == c->machine.n_axes) {
			err_at(err, &b, 0, 0);
			mlip_tb_puts(&b, mlip_mc_keytab[K_TOOL][sec_key].name);
			mlip_tb_puts(&b, ": axis ");
			mlip_tb_putc(&b, AXIS_LETTERS[l]);
			mlip_tb_puts(&b, " is not in COORDINATES");
			mlip_mc_place(ps, err, SEC_TOOL, sec_key, -1, 0, -1, 0);
			return MLIP_E_RANGE;
		}
		if (!(io->change_pos[i] >= c->machine.axis[i].min_limit &&
		      io->change_pos[i] <= c->machine.axis[i].max_limit)) {
			err_at(err, &b, 0, 0);
			mlip_tb_puts(&b, mlip_mc_keytab[K_TOOL][sec_key].name);
			mlip_tb_puts(&b, " ");
			mlip_tb_double(&b, io->change_pos[i]);
			mlip_tb_puts(&b, " is beyond the soft limits of AXIS_");
			mlip_tb_putc(&b, AXIS_LETTERS[l]);
			mlip_mc_place(ps, err, SEC_TOOL, sec_key, -1, 0, -1, 0);
			return MLIP_E_RANGE;
		}
	}
	return MLIP_OK;
}
