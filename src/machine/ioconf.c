/*
 * ioconf.c - the [SPINDLE], [TOOL] and [COOLANT] sections (issue 19) into the
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
	/* a drive on the bus (TYPE = cia402): defaults from the speeds */
	memset(&c->spindle, 0, sizeof c->spindle);
	c->spindle.node = has(ps, SEC_SPINDLE, SK_NODE) ? (uint8_t)sp->ival[SK_NODE] : 0;
	c->spindle.min_rpm = io->min_rpm;
	c->spindle.max_rpm = io->max_rpm;
	c->spindle.counts_per_rev = has(ps, SEC_SPINDLE, SK_CPR) ? sp->num[SK_CPR] : 0.0;
	c->spindle.accel_rpm_s = has(ps, SEC_SPINDLE, SK_ACCEL) ? sp->num[SK_ACCEL] : 0.0;
	c->spindle.band_rpm = has(ps, SEC_SPINDLE, SK_BAND) ? sp->num[SK_BAND] : 0.02 * io->max_rpm;
	c->spindle.timeout_s = has(ps, SEC_SPINDLE, SK_TIMEOUT) ? sp->num[SK_TIMEOUT]
	                       : c->spindle.accel_rpm_s > 0
	                           ? 2.0 * io->max_rpm / c->spindle.accel_rpm_s + 1.0
	                           : 0.0;
	c->spindle.band_time_s = has(ps, SEC_SPINDLE, SK_BAND_TIME) ? sp->num[SK_BAND_TIME] : 0.2;
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

/* TYPE = cia402: the drive's keys are there, its node is its own, the
 * timeout allows a reversal at full speed (a shorter one would fault a
 * spindle that does what it was told). */
static mlip_status check_spindle_drive(const struct pstate *ps, const struct mlip_config *c,
                                       struct mlip_config_error *err)
{
	static const int need[3] = {SK_NODE, SK_CPR, SK_ACCEL};
	static const char *const why[3] = {"its CANopen node id",
	                                   "0x60FF/0x606C counts per revolution",
	                                   "rpm/s, the drive's ramp 0x6083/0x6084"};
	const struct mlip_spindle_config *s = &c->spindle;
	const struct sec *io_sec = &ps->sec[SEC_IO];
	struct mlip_tb b;
	int i;

	for (i = 0; i < 3; i++) {
		if (!has(ps, SEC_SPINDLE, need[i])) {
			err_at(err, &b, ps->sec[SEC_SPINDLE].at.line, 0);
			mlip_tb_puts(&b, "missing ");
			mlip_tb_puts(&b, mlip_mc_keytab[K_SPINDLE][need[i]].name);
			mlip_tb_puts(&b, " in [SPINDLE] (TYPE = cia402: ");
			mlip_tb_puts(&b, why[i]);
			mlip_tb_puts(&b, ")");
			return MLIP_E_SYNTAX;
		}
	}
	for (i = 0; i < c->machine.n_axes; i++) {
		if (c->machine.axis[i].can_node == s->node) {
			int sec = SEC_AXIS0 + letter_index(c->machine.axis[i].letter);
			err_at(err, &b, 0, 0);
			mlip_tb_puts(&b, "NODE ");
			mlip_tb_uint(&b, s->node);
			mlip_tb_puts(&b, " is also the CAN_NODE of AXIS_");
			mlip_tb_putc(&b, c->machine.axis[i].letter);
			mlip_mc_place(ps, err, SEC_SPINDLE, SK_NODE, sec, AK_NODE, -1, 0);
			return MLIP_E_RANGE;
		}
	}
	if (s->node == c->drives.master_node) {
		err_at(err, &b, 0, 0);
		mlip_tb_puts(&b, "NODE ");
		mlip_tb_uint(&b, s->node);
		mlip_tb_puts(&b, " is also [DRIVES] MASTER_NODE (mlip's own)");
		mlip_mc_place(ps, err, SEC_SPINDLE, SK_NODE, SEC_DRIVES, DK_MASTER, -1, 0);
		return MLIP_E_RANGE;
	}
	if (has(ps, SEC_IO, IK_NODE) && io_sec->ival[IK_NODE] == s->node) {
		err_at(err, &b, 0, 0);
		mlip_tb_puts(&b, "NODE ");
		mlip_tb_uint(&b, s->node);
		mlip_tb_puts(&b, " is also [IO] NODE (the I/O module)");
		mlip_mc_place(ps, err, SEC_SPINDLE, SK_NODE, SEC_IO, IK_NODE, -1, 0);
		return MLIP_E_RANGE;
	}
	/* MAX_RPM in counts/s must fit the drive's INTEGER32 */
	if (!(c->io.max_rpm * s->counts_per_rev / 60.0 <= 2147483647.0)) {
		return io_err(ps, err, SEC_SPINDLE, SK_CPR, SK_MAX_RPM,
		              "MAX_RPM at COUNTS_PER_REV is beyond the drive's 0x60FF (INTEGER32 "
		              "counts/s)");
	}
	if (!(s->band_rpm > 0 && s->band_rpm < c->io.max_rpm)) {
		return io_err(ps, err, SEC_SPINDLE, SK_BAND, SK_MAX_RPM,
		              "AT_SPEED_BAND must be > 0 and < MAX_RPM");
	}
	if (s->timeout_s < 2.0 * c->io.max_rpm / s->accel_rpm_s) {
		err_at(err, &b, 0, 0);
		mlip_tb_puts(&b, "AT_SPEED_TIMEOUT ");
		mlip_tb_double(&b, s->timeout_s);
		mlip_tb_puts(&b, " s is shorter than a reversal at full speed (2 MAX_RPM / "
		                 "ACCELERATION = ");
		mlip_tb_double(&b, 2.0 * c->io.max_rpm / s->accel_rpm_s);
		mlip_tb_puts(&b, " s): a spindle doing as told would fault");
		mlip_mc_place(ps, err, SEC_SPINDLE, SK_TIMEOUT, SEC_SPINDLE, SK_ACCEL, SEC_SPINDLE,
		              SK_MAX_RPM);
		return MLIP_E_RANGE;
	}
	if (s->timeout_s > 3600.0 || s->band_time_s > 60.0) {
		return io_err(
		    ps, err, SEC_SPINDLE, SK_TIMEOUT, SK_BAND_TIME,
		    "AT_SPEED_TIMEOUT (at most 3600 s) or BAND_TIME (at most 60 s) too long");
	}
	return MLIP_OK;
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

	for (k = SK_MIN_RPM; k <= SK_BAND_TIME; k++) {
		if (has(ps, SEC_SPINDLE, k) && (io->spindle == MLIP_IO_NONE ||
		                                (k >= SK_NODE && io->spindle != MLIP_IO_CIA402))) {
			err_at(err, &b, 0, 0);
			mlip_tb_puts(&b, mlip_mc_keytab[K_SPINDLE][k].name);
			mlip_tb_puts(&b,
			             io->spindle == MLIP_IO_NONE
			                 ? " is for a spindle: TYPE = none has none"
			                 : " is for a spindle drive on the bus: TYPE = cia402, not "
			                   "manual");
			mlip_mc_place(ps, err, SEC_SPINDLE, k, SEC_SPINDLE, SK_TYPE, -1, 0);
			return MLIP_E_RANGE;
		}
	}
	if (io->spindle != MLIP_IO_NONE) {
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
	if (io->spindle == MLIP_IO_CIA402) {
		mlip_status st = check_spindle_drive(ps, c, err);
		if (st != MLIP_OK) {
			return st;
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
