/*
 * tooltable.h - the tool table (issue 19): LinuxCNC's format, kept as a
 * state file (statefile.h: sealed by its last line, read whole and checked,
 * never written through a link) that the operator reads and edits.
 *
 *   ; mlip tool table: ... (comment lines start with ';')
 *   T1 P1 Z12.5 D6 ;6 mm flat end mill
 *   T2 P2 Z30.25 D3.175 ;1/8" ball
 *   ; end 4 lines sha256 3f2a9c5b1d7e0a42
 *
 * One tool a line (LinuxCNC's tool.tbl): T the tool number (a whole number
 * >= 1, written without leading zeros, each once), P the pocket (a whole
 * number 0..1000, each once), Z the length offset G43 applies and D the
 * diameter (machine units, mm), the comment after ';' (shown when the tool
 * is asked for). LinuxCNC's other columns (X Y A B C U V W I J Q) are
 * accepted when 0 (a mill's table written by LinuxCNC's tooledit) and
 * refused otherwise (mlip offsets tools along Z only: a value it would not
 * apply is never silently ignored). At most MLIP_TOOLS_MAX tools. A hand
 * edit (or a table copied from LinuxCNC) is accepted, checked and sealed by
 * `mlip-tools --accept FILE`. Errors: "FILE:LINE:COL: what; what to do".
 *
 * The tool in the spindle is not here: it outlives a program in the offsets
 * file (its TOOL line, offsets.h), where M6 and M61 leave it.
 */
#ifndef MLIP_TOOLS_TOOLTABLE_H
#define MLIP_TOOLS_TOOLTABLE_H

#include <stddef.h>
#include <stdio.h>

#include "mlip/gcode/gcode.h"
#include "statefile.h"

#define MLIP_TOOLS_MAX     1000 /* tools in a table (LinuxCNC: 1000 pockets) */
#define MLIP_TOOLS_ABS_MAX 1e4  /* mm: a larger Z or D is not a tool's */
#define MLIP_TOOLS_POCKETS 1000 /* P 0..this */
#define MLIP_TOOLS_COMMENT 96   /* bytes of a comment kept for messages */

struct mlip_tooltable {
	const char *path;
	struct mlip_tool *tools; /* sorted by number (the reader's struct mlip_gcode_io) */
	char (*comment)[MLIP_TOOLS_COMMENT];
	uint32_t *line; /* where each tool stands in the file */
	uint32_t n;
};

/* Read and check the table at path (flags: MLIP_SF_UNSEALED for an accept).
 * 0, or -1 after printing "prog: error: FILE:LINE:COL: ..." to err. */
int mlip_tooltable_load(struct mlip_tooltable *t, const char *path, unsigned flags,
                        const char *prog, FILE *err);
void mlip_tooltable_free(struct mlip_tooltable *t);

/* The comment of tool n ("" when none or not in the table). */
const char *mlip_tooltable_comment(const struct mlip_tooltable *t, int32_t n);

/* The state file kind of a tool table (for mlip-tools). */
void mlip_tooltable_kind(struct mlip_sf_kind *k);

#endif
