/*
 * cli.h - what every host tool shares: building the machine from --config
 * and the --accel/--vmax/--eps/--period overrides, and strategy names.
 */
#ifndef MLIP_CLI_H
#define MLIP_CLI_H

#include <stdio.h>

#include "mlip/can/canenc.h"
#include "mlip/machine/config.h"
#include "mlip/motion/planner.h"
#include "program.h"

struct mlip_offsets_file;

struct mlip_cli_machine {
	const char *config;  /* INI path, or NULL: axes are those the program uses */
	const char *offsets; /* offsets file (offsets.h), or NULL: all zero, G54 */
	struct mlip_offsets_file *offsets_file; /* filled by the load when not NULL: the base
	                                           of a write-back (mlip_offsets_save) */
	int strict;                             /* mlip_gcode_set_strict */
	double default_feed; /* --default-feed: F for a program without any, or 0 */
	const char *accel;   /* "A" or "A1,A2,..." in config order, or NULL */
	double vmax_mm_s;    /* <= 0: unset */
	double eps_mm;
	double period_s;
	double jerk; /* > 0: every axis's MAX_JERK (--jerk), mm/s^3 or deg/s^3 */
	/* the machine's I/O (issue 19), with a config only */
	const char *tools; /* --tools FILE: the tool table (tooltable.h), or NULL */
	int ignore_spindle, ignore_coolant, ignore_tools; /* --ignore-*: on purpose */
};

/* Build cfg from the options; the program at program_path (may be NULL)
 * names the axes when there is no config. Prints "mlip-xxx: ..." errors to
 * err. 0 or -1. */
int mlip_cli_build_machine(const struct mlip_cli_machine *o, const char *program_path,
                           struct mlip_config *cfg, const char *prog, FILE *err);

/* Build the machine (cli_build_machine), read the offsets file (o->offsets)
 * and the tool table (o->tools), and check the program at path
 * (mlip_program_open) against the machine's I/O (cfg->io: the config's
 * [SPINDLE], [TOOL], [COOLANT], the table, the --ignore-* choices; without a
 * config the I/O words are notices: nothing reaches a machine); on failure
 * print why (every error of the program) and return -1, with *program
 * closed. cfg must outlive *program. */
int mlip_cli_open_program(const char *path, const struct mlip_cli_machine *o,
                          struct mlip_config *cfg, struct mlip_program *program, const char *prog,
                          FILE *err);

/* The G-code options every tool that reads programs takes (struct option
 * entries for getopt_long; their values are above any letter). */
#define MLIP_CLI_OPT_OFFSETS        0x100
#define MLIP_CLI_OPT_STRICT         0x101
#define MLIP_CLI_OPT_DEFAULT_FEED   0x102
#define MLIP_CLI_OPT_TOOLS          0x103
#define MLIP_CLI_OPT_IGNORE_SPINDLE 0x104
#define MLIP_CLI_OPT_IGNORE_COOLANT 0x105
#define MLIP_CLI_OPT_IGNORE_TOOLS   0x106
#define MLIP_CLI_GCODE_OPTIONS                                                                     \
	{"offsets", required_argument, 0, MLIP_CLI_OPT_OFFSETS},                                   \
	    {"strict", no_argument, 0, MLIP_CLI_OPT_STRICT},                                       \
	    {"default-feed", required_argument, 0, MLIP_CLI_OPT_DEFAULT_FEED},                     \
	    {"tools", required_argument, 0, MLIP_CLI_OPT_TOOLS},                                   \
	    {"ignore-spindle", no_argument, 0, MLIP_CLI_OPT_IGNORE_SPINDLE},                       \
	    {"ignore-coolant", no_argument, 0, MLIP_CLI_OPT_IGNORE_COOLANT},                       \
	{                                                                                          \
		"ignore-tools", no_argument, 0, MLIP_CLI_OPT_IGNORE_TOOLS                          \
	}
/* Their help lines. */
#define MLIP_CLI_IO_HELP                                                                           \
	"  --tools FILE          the tool table (LinuxCNC's T P Z D format; mlip-tools)\n"         \
	"  --ignore-spindle      run S/M3/M4/M5 as nothing, on purpose (no spindle driven)\n"      \
	"  --ignore-coolant      run M7/M8/M9 as nothing, on purpose\n"                            \
	"  --ignore-tools        run T/M6/M61/G43/G49 as nothing, on purpose (no length offset)\n"

/* The machine's I/O for a program: cfg->io completed from o (the tool
 * table loaded from o->tools into a table kept for the process, the
 * --ignore-* choices); NULL without a config (the words are notices). 0,
 * or -1 after printing why (the table's FILE:LINE:COL). */
int mlip_cli_io(const struct mlip_cli_machine *o, struct mlip_config *cfg,
                const struct mlip_gcode_io **io, const char *prog, FILE *err);
/* The machine's I/O <-> the segment's io area (mlip/ipc/ring.h). */
struct mlip_ring_io;
void mlip_cli_io_to_ring(const struct mlip_gcode_io *io, const struct mlip_machine *m,
                         struct mlip_ring_io *out);
/* 0, or -1 when the area holds what no config gives (a speed not finite or
 * out of order, a type unknown to this build, a change position beyond the
 * soft limits of m): the segment is not trusted. */
int mlip_cli_io_from_ring(const struct mlip_ring_io *in, const struct mlip_machine *m,
                          struct mlip_gcode_io *io);

/* The tool table the last mlip_cli_io loaded (NULL: none). */
const struct mlip_tooltable *mlip_cli_tooltable(void);
/* What the operator is to do at a manual pause (status reason SPINDLE, TOOL,
 * COOLANT, with its value): "start the spindle clockwise at 12000 rpm",
 * "insert tool 2 (6 mm flat)" (the comment from table, may be NULL), ... */
void mlip_cli_io_message(uint32_t why, double value, const struct mlip_tooltable *table, char *buf,
                         size_t len);

/* Take getopt_long's c (with arg) when it is one of those: 1 taken, 0 not
 * one of them, -1 a bad value (message printed). */
int mlip_cli_gcode_option(int c, const char *arg, struct mlip_cli_machine *o, const char *prog,
                          FILE *err);

/* "mpct" | "bisector" | "stop" | "smooth" -> strategy; -1 when unknown. */
int mlip_cli_strategy(const char *name);
const char *mlip_cli_strategy_name(mlip_strategy st);

/* Strict number parsing for options: whole string, finite. 0 or -1. */
int mlip_cli_number(const char *s, double *out);

/* SIGINT, SIGTERM, SIGHUP and SIGQUIT call handler; no SA_RESTART, so a
 * signal ends a sleep or a blocking call at once (the tools turn it into a
 * controlled stop). SIGPIPE is ignored. */
void mlip_cli_on_stop_signals(void (*handler)(int));
/* "SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT" (else "a signal"). */
const char *mlip_cli_signal_name(int sig);

/* The limits a trace of machine m is judged against. */
struct mlip_check_limits;
void mlip_cli_check_limits(const struct mlip_machine *m, struct mlip_check_limits *lim);

/* The polyline the planner will follow, one point at a time from a program
 * being streamed: home first, then every move's target, points closer than
 * MLIP_GCODE_MERGE_MM to the previous one dropped as the planner does. The
 * signature of a streaming check's point source (ctx = struct
 * mlip_cli_path): 1, 0 at the end, < 0 when the stream failed
 * (program->msg; also kept in rc). length_mm sums the linear axes' lengths
 * given so far. Fixed memory, whatever the program's length. */
struct mlip_cli_path {
	struct mlip_program *program;
	const struct mlip_machine *m;
	double last[MLIP_MAX_AXES];
	int started, rc;
	double length_mm;
};
void mlip_cli_path_start(struct mlip_cli_path *p, struct mlip_program *program,
                         const struct mlip_machine *m);
int mlip_cli_path_next(void *ctx, double *pt, uint32_t *line);

/* What a record field of a controller fault is called: "target X" for the
 * target of axis X of machine m, else mlip_rec_field_name(). */
void mlip_cli_field_name(const struct mlip_machine *m, uint32_t field, char *buf, size_t len);
/* A drive fault's event (mlip_drive_fault, status reason_field with reason
 * DRIVE) and value as the bus showed it: "statusword 0x0218 (fault)",
 * "EMCY 0x2310 (...)", "no heartbeat for 120 ms", ... */
void mlip_cli_drive_fault_text(uint32_t event, int64_t value, char *buf, size_t len);

/* --profile P (NULL: the file's) and --bitrate (<= 0: the file's) over the
 * [CAN] section the INI reader checked, then the same rule set
 * (mlip_can_config_check) again: they may break it. *prof is the profile in
 * force. 0, 2 for an unknown profile name, 1 when [CAN] breaks a rule;
 * "PROG: ..." messages on err. */
int mlip_cli_can_override(struct mlip_config *cfg, const char *path, const char *profile,
                          double bitrate, mlip_can_profile *prof, const char *prog, FILE *err);

#endif
