/*
 * ctltool.h - the parts of mlip-ctl (tools/mlip-ctl.c): ctlstatus.c the
 * status report, ctljog.c jog and homing, ctlmdi.c MDI lines through the
 * feeder (feed.h); mlip-ctl.c the mailbox commands, stop, their parsing and
 * main. Not a library: only mlip-ctl links these.
 */
#ifndef MLIP_TOOLS_CTLTOOL_H
#define MLIP_TOOLS_CTLTOOL_H

#include <stdint.h>
#include <stdio.h>

#include "mlip/ipc/ring.h"
#include "rt.h"

#define PROG     "mlip-ctl"
#define WAIT_NS  1000000000LL /* post retries and answer wait: 1 s each */
#define POLL_NS  1000000L     /* poll the mailbox every 1 ms */
#define LINE_MAX 256          /* `-`: a longer command line is refused whole */

enum { EXIT_DONE = 0, EXIT_FAIL = 1, EXIT_USAGE = 2 };

/* mlip-ctl.c */
void usage(FILE *f);
void sleep_ns(long ns);
/* ctlstatus.c */
int read_status(const struct mlip_ring *r, struct mlip_ring_status *st);
int cmd_status(struct mlip_shm *s, int json);
/* ctljog.c */
int cmd_jog(struct mlip_shm *s, int argc, char **argv);
int cmd_home(struct mlip_shm *s, const char *axes);
/* ctlmdi.c */
int cmd_mdi(const char *shm, int argc, char **argv);

#endif
