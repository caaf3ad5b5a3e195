/* cli.c - see cli.h */
#include "cli.h"

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "mlip/canopen/drive.h"
#include "mlip/ipc/ring.h"
#include "confload.h"
#include "mlip/gcode/gcode.h"
#include "mlip/ctl/state.h"
#include "offsetfile.h"
#include "program.h"
#include "tooltable.h"

int mlip_cli_number(const char *s, double *out)
{
	char *end;
	if (s == NULL || *s == '\0') {
		return -1;
	}
	errno = 0;
	double v = strtod(s, &end);
	if (*end != '\0' || errno != 0 || !isfinite(v)) {
		return -1;
	}
	*out = v;
	return 0;
}

int mlip_cli_gcode_option(int c, const char *arg, struct mlip_cli_machine *o, const char *prog,
                          FILE *err)
{
	switch (c) {
	case MLIP_CLI_OPT_OFFSETS:
		o->offsets = arg;
		return 1;
	case MLIP_CLI_OPT_STRICT:
		o->strict = 1;
		return 1;
	case MLIP_CLI_OPT_DEFAULT_FEED:
		if (mlip_cli_number(arg, &o->default_feed) != 0 || !(o->default_feed > 0.0)) {
			fprintf(err, "%s: --default-feed: '%s' is not a positive number\n", prog,
			        arg);
			return -1;
		}
		return 1;
	case MLIP_CLI_OPT_TOOLS:
		o->tools = arg;
		return 1;
	case MLIP_CLI_OPT_IGNORE_SPINDLE:
		o->ignore_spindle = 1;
		return 1;
	case MLIP_CLI_OPT_IGNORE_COOLANT:
		o->ignore_coolant = 1;
		return 1;
	case MLIP_CLI_OPT_IGNORE_TOOLS:
		o->ignore_tools = 1;
		return 1;
	default:
		return 0;
	}
}

int mlip_cli_strategy(const char *name)
{
	return mlip_strategy_from_name(name); /* the table's names (mlip/motion/planner.h) */
}

const char *mlip_cli_strategy_name(mlip_strategy st)
{
	const char *name = mlip_strategy_name(st);
	return name != NULL ? name : "?";
}

static int apply_accel(struct mlip_machine *m, const char *list, const char *prog, FILE *err)
{
	double v[MLIP_MAX_AXES];
	int count = 0;
	char buf[256];
	if (strlen(list) >= sizeof(buf)) {
		fprintf(err, "%s: --accel: list too long\n", prog);
		return -1;
	}
	strcpy(buf, list);
	for (char *tok = strtok(buf, ","); tok != NULL; tok = strtok(NULL, ",")) {
		if (count == MLIP_MAX_AXES || mlip_cli_number(tok, &v[count]) != 0 ||
		    !(v[count] > 0.0)) {
			fprintf(err, "%s: --accel: '%s' is not a positive number (mm/s^2)\n", prog,
			        tok);
			return -1;
		}
		count++;
	}
	if (count != 1 && count != m->n_axes) {
		fprintf(err,
		        "%s: --accel: %d values for %d axes (give one for all, or one per axis)\n",
		        prog, count, m->n_axes);
		return -1;
	}
	for (int k = 0; k < m->n_axes; k++) {
		m->axis[k].max_accel = v[count == 1 ? 0 : k];
	}
	return 0;
}

int mlip_cli_build_machine(const struct mlip_cli_machine *o, const char *program_path,
                           struct mlip_config *cfg, const char *prog, FILE *err)
{
	mlip_config_defaults(cfg);
	struct mlip_machine *m = &cfg->machine;
	if (o->config != NULL) {
		if (mlip_config_load(o->config, cfg, err) != 0) {
			return -1;
		}
	} else {
		char letters[MLIP_MAX_AXES + 1] = "";
		char why[256];
		int n = program_path
		            ? mlip_program_scan_axes(program_path, letters, why, sizeof(why))
		            : 0;
		if (n < 0) {
			fprintf(err, "%s: %s: %s\n", prog, program_path, why);
			return -1;
		}
		if (n < 2) {
			/* a program using one axis still runs on a 2-axis machine */
			const char *fill = "XYZ";
			for (int i = 0; n < 2 && fill[i]; i++) {
				if (strchr(letters, fill[i]) == NULL) {
					letters[n++] = fill[i];
					letters[n] = '\0';
				}
			}
			/* keep canonical order XYZABC */
			char sorted[MLIP_MAX_AXES + 1];
			int j = 0;
			for (const char *c = "XYZABC"; *c; c++) {
				if (strchr(letters, *c)) {
					sorted[j++] = *c;
				}
			}
			sorted[j] = '\0';
			strcpy(letters, sorted);
		}
		double vmax = o->vmax_mm_s > 0.0 ? o->vmax_mm_s : 200.0;
		m->n_axes = n;
		m->max_feed_mm_s = vmax;
		m->max_rot_feed_deg_s = 360.0;
		m->tolerance_mm = 0.01;
		m->period_s = 0.001;
		for (int k = 0; k < n; k++) {
			struct mlip_axis *ax = &m->axis[k];
			ax->letter = letters[k];
			ax->kind = MLIP_AXIS_LINEAR; /* no config: every axis linear */
			ax->max_accel = 1000.0;
			ax->max_vel = vmax;
			ax->min_limit = -1e9;
			ax->max_limit = 1e9;
			ax->home = 0.0;
			ax->can_node = k + 1;
			ax->counts_per_unit = 1000.0;
		}
	}
	if (o->accel != NULL && apply_accel(m, o->accel, prog, err) != 0) {
		return -1;
	}
	if (o->vmax_mm_s > 0.0) {
		m->max_feed_mm_s = o->vmax_mm_s;
	}
	if (o->eps_mm > 0.0) {
		m->tolerance_mm = o->eps_mm;
	}
	if (o->period_s > 0.0) {
		m->period_s = o->period_s;
	}
	if (o->jerk > 0.0) {
		for (int k = 0; k < m->n_axes; k++) {
			m->axis[k].max_jerk = o->jerk;
		}
	}
	struct mlip_config_error e;
	if (mlip_machine_check(m, &e) != MLIP_OK) {
		fprintf(err, "%s: machine: %s\n", prog, e.msg);
		return -1;
	}
	return 0;
}

void mlip_cli_path_start(struct mlip_cli_path *p, struct mlip_program *program,
                         const struct mlip_machine *m)
{
	memset(p, 0, sizeof(*p));
	p->program = program;
	p->m = m;
}

int mlip_cli_path_next(void *ctx, double *pt, uint32_t *line)
{
	struct mlip_cli_path *p = ctx;
	int n = p->m->n_axes;
	struct mlip_block b;
	if (!p->started) {
		for (int k = 0; k < n; k++) {
			p->last[k] = p->m->axis[k].home;
		}
		p->started = 1;
		memcpy(pt, p->last, sizeof(double) * (size_t)n);
		*line = 0;
		return 1;
	}
	while ((p->rc = mlip_program_next(p->program, &b)) > 0) {
		double d2 = 0.0, lin = 0.0;
		if (b.kind != MLIP_BLOCK_MOVE && b.kind != MLIP_BLOCK_PROBE) {
			continue; /* a probe's path: to its target (it trips nothing here) */
		}
		for (int k = 0; k < n; k++) {
			double d = b.target[k] - p->last[k];
			d2 += d * d;
			lin += p->m->axis[k].kind == MLIP_AXIS_LINEAR ? d * d : 0.0;
		}
		if (sqrt(d2) < MLIP_GCODE_MERGE_MM) {
			continue;
		}
		p->length_mm += sqrt(lin);
		memcpy(p->last, b.target, sizeof(double) * (size_t)n);
		memcpy(pt, b.target, sizeof(double) * (size_t)n);
		*line = b.line;
		return 1;
	}
	return p->rc; /* 0 at the end, < 0 when the stream failed */
}

void mlip_cli_check_limits(const struct mlip_machine *m, struct mlip_check_limits *lim)
{
	memset(lim, 0, sizeof(*lim));
	lim->n = m->n_axes;
	lim->vmax_mm_s = m->max_feed_mm_s;
	lim->vmax_rot_deg_s = m->max_rot_feed_deg_s;
	lim->eps_mm = m->tolerance_mm;
	lim->period_s = m->period_s;
	for (int k = 0; k < m->n_axes; k++) {
		lim->accel[k] = m->axis[k].max_accel;
		lim->jerk[k] = m->axis[k].max_jerk;
		lim->vel[k] = m->axis[k].max_vel;
		lim->rotary[k] = m->axis[k].kind == MLIP_AXIS_ROTARY;
	}
}

int mlip_cli_open_program(const char *path, const struct mlip_cli_machine *o,
                          struct mlip_config *cfg, struct mlip_program *program, const char *prog,
                          FILE *err)
{
	struct mlip_gcode_offsets off;
	struct mlip_program_options opt = {o->strict, &off, o->default_feed, NULL, NULL, 0};
	if (mlip_cli_build_machine(o, path, cfg, prog, err) != 0 ||
	    mlip_cli_io(o, cfg, &opt.io, prog, err) != 0) {
		return -1;
	}
	if (o->offsets != NULL) {
		if (mlip_offsets_load(o->offsets_file, o->offsets, &cfg->machine, &off, prog,
		                      err) != 0) {
			return -1;
		}
	} else {
		mlip_gcode_offsets_init(&off, &cfg->machine);
	}
	int rc = mlip_program_open(program, path, &cfg->machine, &opt);
	if (rc < 0) {
		fprintf(err, "%s: %s: %s\n", prog, path, program->msg);
	} else if (rc > 0) {
		mlip_program_print_errors(program, path, err);
	}
	if (rc != 0) {
		mlip_program_close(program);
		return -1;
	}
	return 0;
}

static struct mlip_tooltable cli_table;
static int cli_table_loaded;

int mlip_cli_io(const struct mlip_cli_machine *o, struct mlip_config *cfg,
                const struct mlip_gcode_io **io, const char *prog, FILE *err)
{
	*io = NULL;
	if (o->config == NULL) {
		if (o->tools != NULL || o->ignore_spindle || o->ignore_coolant || o->ignore_tools) {
			fprintf(err,
			        "%s: --tools and --ignore-* describe a machine's I/O: give its "
			        "--config\n",
			        prog);
			return -1;
		}
		return 0; /* a motion check: the I/O words are notices */
	}
	if (o->tools != NULL) {
		if (cli_table_loaded) {
			mlip_tooltable_free(&cli_table);
			cli_table_loaded = 0;
		}
		if (mlip_tooltable_load(&cli_table, o->tools, 0, prog, err) != 0) {
			return -1;
		}
		cli_table_loaded = 1;
		cfg->io.tools = cli_table.tools;
		cfg->io.n_tools = cli_table.n;
	}
	cfg->io.ignore_spindle = o->ignore_spindle;
	cfg->io.ignore_coolant = o->ignore_coolant;
	cfg->io.ignore_tools = o->ignore_tools;
	*io = &cfg->io;
	return 0;
}

void mlip_cli_io_to_ring(const struct mlip_gcode_io *io, const struct mlip_machine *m,
                         struct mlip_ring_io *out)
{
	memset(out, 0, sizeof(*out));
	out->spindle = (uint32_t)io->spindle;
	out->tool_change = (uint32_t)io->tool_change;
	out->coolant = (uint32_t)io->coolant;
	out->change_mask = io->change_mask;
	out->outputs =
	    (io->coolant_outlets & 3u) | (io->dout_mask & 0xFFu) << 8 | (io->probe ? 1u << 16 : 0u);
	out->min_rpm = io->min_rpm;
	out->max_rpm = io->max_rpm;
	for (int i = 0; i < m->n_axes && i < MLIP_MAX_AXES; i++) {
		out->change_pos[i] = io->change_pos[i];
	}
}

int mlip_cli_io_from_ring(const struct mlip_ring_io *in, const struct mlip_machine *m,
                          struct mlip_gcode_io *io)
{
	memset(io, 0, sizeof(*io));
	if ((in->spindle > MLIP_IO_MANUAL && in->spindle != MLIP_IO_CIA402) ||
	    in->tool_change > MLIP_IO_MANUAL ||
	    (in->coolant > MLIP_IO_MANUAL && in->coolant != MLIP_IO_MODULE) ||
	    (in->change_mask >> m->n_axes) != 0 || (in->outputs & ~0x1FF03u) != 0) {
		return -1;
	}
	if (in->spindle != MLIP_IO_NONE && !(in->min_rpm >= 0 && in->max_rpm > 0 &&
	                                     in->min_rpm <= in->max_rpm && in->max_rpm <= 1e6)) {
		return -1;
	}
	io->spindle = (int)in->spindle;
	io->tool_change = (int)in->tool_change;
	io->coolant = (int)in->coolant;
	io->change_mask = in->change_mask;
	io->coolant_outlets = in->outputs & 3u;
	io->dout_mask = (in->outputs >> 8) & 0xFFu;
	io->probe = (in->outputs >> 16) & 1u;
	io->min_rpm = in->min_rpm;
	io->max_rpm = in->max_rpm;
	for (int i = 0; i < m->n_axes; i++) {
		if ((in->change_mask >> i & 1u) && !(in->change_pos[i] >= m->axis[i].min_limit &&
		                                     in->change_pos[i] <= m->axis[i].max_limit)) {
			return -1;
		}
		io->change_pos[i] = in->change_pos[i];
	}
	return 0;
}

const struct mlip_tooltable *mlip_cli_tooltable(void)
{
	return cli_table_loaded ? &cli_table : NULL;
}

void mlip_cli_io_message(uint32_t why, double value, const struct mlip_tooltable *table, char *buf,
                         size_t len)
{
	if (why == MLIP_WHY_SPINDLE) {
		if (value == 0) {
			snprintf(buf, len, "stop the spindle, then resume");
		} else {
			snprintf(buf, len, "start the spindle %s at %g rpm, then resume",
			         value > 0 ? "clockwise" : "counter-clockwise", fabs(value));
		}
	} else if (why == MLIP_WHY_TOOL) {
		const char *c = table ? mlip_tooltable_comment(table, (int32_t)value) : "";
		if (value == 0) {
			snprintf(buf, len, "take the tool out of the spindle, then resume");
		} else {
			snprintf(buf, len, "insert tool %.0f%s%s%s, then resume", value,
			         *c ? " (" : "", c, *c ? ")" : "");
		}
	} else if (why == MLIP_WHY_COOLANT) {
		unsigned b = (unsigned)value;
		snprintf(buf, len, "%s, then resume",
		         b == 0 ? "turn the coolant off"
		         : b == (MLIP_COOLANT_MIST | MLIP_COOLANT_FLOOD)
		             ? "turn mist and flood coolant on"
		         : b == MLIP_COOLANT_MIST ? "turn the mist coolant on (flood off)"
		                                  : "turn the flood coolant on (mist off)");
	} else {
		snprintf(buf, len, "resume");
	}
}

/* SIGHUP too: a lost terminal or ssh session must never drop a moving
 * machine; SIGQUIT (Ctrl-\\) too: its default kills without a stop. The
 * handler runs with the others blocked, so two at once cannot interleave. */
static const int stop_signals[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT};

void mlip_cli_on_stop_signals(void (*handler)(int))
{
	struct sigaction sa;
	size_t i;

	memset(&sa, 0, sizeof(sa));
	sa.sa_handler = handler;
	sigemptyset(&sa.sa_mask);
	for (i = 0; i < sizeof(stop_signals) / sizeof(stop_signals[0]); i++) {
		sigaddset(&sa.sa_mask, stop_signals[i]);
	}
	for (i = 0; i < sizeof(stop_signals) / sizeof(stop_signals[0]); i++) {
		sigaction(stop_signals[i], &sa, NULL);
	}
	/* a log reader that went away (mlip-rt | tee, the terminal closed) makes
	 * a write fail with EPIPE instead of killing the process mid-stop */
	signal(SIGPIPE, SIG_IGN);
}

const char *mlip_cli_signal_name(int sig)
{
	switch (sig) {
	case SIGINT:
		return "SIGINT";
	case SIGTERM:
		return "SIGTERM";
	case SIGHUP:
		return "SIGHUP";
	case SIGQUIT:
		return "SIGQUIT";
	}
	return "a signal";
}

void mlip_cli_field_name(const struct mlip_machine *m, uint32_t field, char *buf, size_t len)
{
	if (field >= MLIP_FIELD_TARGET && field < MLIP_FIELD_TARGET + (uint32_t)m->n_axes) {
		snprintf(buf, len, "target %c", m->axis[field - MLIP_FIELD_TARGET].letter);
	} else {
		snprintf(buf, len, "%s", mlip_rec_field_name(field));
	}
}

void mlip_cli_drive_fault_text(uint32_t event, int64_t v, char *buf, size_t len)
{
	switch (event) {
	case MLIP_DRIVE_NOT_SWITCHED_ON:
	case MLIP_DRIVE_NOT_ENABLED:
		snprintf(
		    buf, len,
		    "%s (controlword 0x%04X) not confirmed within STATE_TIMEOUT_MS: statusword "
		    "0x%04llX (%s); nothing moves",
		    event == MLIP_DRIVE_NOT_ENABLED ? "enable operation" : "switch on",
		    event == MLIP_DRIVE_NOT_ENABLED ? MLIP_402_CW_ENABLE_OPERATION
		                                    : MLIP_402_CW_SWITCH_ON,
		    (unsigned long long)(v & 0xFFFF),
		    mlip_402_state_name(mlip_402_state_of((uint16_t)v)));
		break;
	case MLIP_DRIVE_POWER_STEP: {
		uint32_t step = (uint32_t)((v >> 16) & 0xFF);
		uint16_t sw = (uint16_t)(v & 0xFFFF);
		snprintf(
		    buf, len,
		    "%s (controlword 0x%04X) not confirmed within STATE_TIMEOUT_MS: statusword "
		    "0x%04X (%s), expected \"%s\"; nothing moves",
		    *mlip_402_step_command(step) ? mlip_402_step_command(step)
		                                 : "waiting for the drive",
		    (unsigned)(mlip_402_step_cw(step) & 0xFFFF), (unsigned)sw,
		    mlip_402_state_name(mlip_402_state_of(sw)),
		    step == MLIP_POWER_WAITING ? "a state the master can leave"
		                               : mlip_402_state_name(mlip_402_step_expects(step)));
		break;
	}
	case MLIP_DRIVE_BEYOND_LIMIT:
		snprintf(
		    buf, len,
		    "position actual %lld counts is beyond a soft limit (moved while disabled?): "
		    "bring it back within the limits by hand; nothing moves",
		    (long long)v);
		break;
	case MLIP_DRIVE_SPINDLE_TIMEOUT:
		snprintf(buf, len,
		         "at %lld rpm when AT_SPEED_TIMEOUT ran out (a slow or stalled spindle)",
		         (long long)v);
		break;
	case MLIP_DRIVE_SPINDLE_OUT_OF_BAND:
		snprintf(
		    buf, len,
		    "at %lld rpm, out of AT_SPEED_BAND for longer than BAND_TIME while cutting",
		    (long long)v);
		break;
	case MLIP_DRIVE_FAULT_BIT:
	case MLIP_DRIVE_LEFT_ENABLED:
		snprintf(buf, len, "statusword 0x%04llX (%s%s)", (unsigned long long)(v & 0xFFFF),
		         mlip_402_state_name(mlip_402_state_of((uint16_t)v)),
		         (v & MLIP_402_SW_FOLLOWING_ERROR) ? ", following error" : "");
		break;
	case MLIP_DRIVE_EMCY:
		snprintf(buf, len, "EMCY 0x%04llX (%s)", (unsigned long long)(v & 0xFFFF),
		         mlip_emcy_text((uint16_t)v));
		break;
	case MLIP_DRIVE_HEARTBEAT_LOST:
		snprintf(buf, len, "no heartbeat for %lld ms", (long long)v);
		break;
	case MLIP_DRIVE_NOT_OPERATIONAL:
		snprintf(buf, len, "its heartbeat says NMT %s", mlip_nmt_state_name((uint8_t)v));
		break;
	case MLIP_DRIVE_FOLLOWING_ERROR:
		snprintf(buf, len, "%lld counts between target sent and position actual",
		         (long long)v);
		break;
	case MLIP_DRIVE_TPDO_LOST:
		snprintf(buf, len, "no TPDO for %lld periods", (long long)v);
		break;
	case MLIP_DRIVE_INPUTS_LOST:
		snprintf(buf, len,
		         "no digital inputs 0x60FD (TPDO3) for %lld ms: its limit switches cannot "
		         "be read",
		         (long long)v);
		break;
	case MLIP_DRIVE_WRONG_DEVICE:
		snprintf(
		    buf, len,
		    "its 0x%04llX:%02llX (%s) differs from what it read at bring-up: another "
		    "device on that node, never configured nor trusted; fit the right one, then "
		    "restart mlip-rt",
		    (unsigned long long)((v >> 8) & 0xFFFF), (unsigned long long)(v & 0xFF),
		    (v >> 8) == 0x1000 ? "device type"
		    : (v & 0xFF) == 1  ? "vendor-ID"
		                       : "product code");
		break;
	default:
		snprintf(buf, len, "event %u, value %lld", (unsigned)event, (long long)v);
	}
}

int mlip_cli_can_override(struct mlip_config *cfg, const char *path, const char *profile,
                          double bitrate, mlip_can_profile *prof, const char *prog, FILE *err)
{
	struct mlip_config_error e;
	if (profile != NULL) {
		if (mlip_can_profile_parse(profile, prof) != MLIP_OK) {
			fprintf(err, "%s: --profile: '%s' is not cia402, packed or fd\n", prog,
			        profile);
			return 2;
		}
		snprintf(cfg->can.profile, sizeof(cfg->can.profile), "%s", profile);
	} else if (mlip_can_profile_parse(cfg->can.profile, prof) != MLIP_OK) {
		*prof = MLIP_CAN_CIA402;
	}
	if (bitrate > 0) {
		cfg->can.bitrate = (uint32_t)bitrate;
	}
	if (mlip_can_config_check(&cfg->can, &cfg->machine, &e) != MLIP_OK) {
		fprintf(err, "%s: %s: [CAN] with --profile %s: %s\n", prog, path,
		        mlip_can_profile_name(*prof), e.msg);
		return 1;
	}
	return 0;
}
