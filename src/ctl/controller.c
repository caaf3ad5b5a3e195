/*
 * controller.c - the controller's period, pure (mlip/ctl/controller.h): commands
 * in, records in (validated), one interpolation step, frames encoded, status
 * and events out. Here: init, the period in its order, the operator's
 * commands and the status; the parts it calls live beside it (ctl.h).
 */
#include "ctl.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

mlip_status mlip_ctl_init(struct mlip_ctl *c, struct mlip_planner *p, const struct mlip_machine *m,
                          const struct mlip_ctl_opts *o)
{
	memset(c, 0, offsetof(struct mlip_ctl, blocks));
	c->planner = p;
	c->m = *m;
	if (m->n_axes < 2 || m->n_axes > MLIP_MAX_AXES) {
		return MLIP_E_INVALID;
	}
	for (int k = 0; k < m->n_axes; k++) {
		c->pos[k] = c->prog.start[k] = m->axis[k].home;
	}
	memcpy(c->carried, c->pos, sizeof(c->carried));
	memcpy(c->sent, c->pos, sizeof(c->sent));
	c->strategy = o->strategy;
	if (mlip_planner_init(p, &c->m, o->strategy, o->lookahead, c->pos, o->smooth) != MLIP_OK) {
		return MLIP_E_INVALID;
	}
	/* the look-ahead's work a bounded amount a period (mlip_planner_work):
	 * a period's cost does not grow with the look-ahead's depth */
	mlip_planner_set_async(p, 1);
	if (o->can != NULL) {
		if (mlip_canenc_init(&c->enc, o->can, &c->m) != MLIP_OK) {
			return MLIP_E_INVALID;
		}
		c->encode = 1;
		c->enc.rpdo_controlword = o->drives ? 1 : 0;
	} else if (o->drives) {
		return MLIP_E_INVALID; /* drives without frames to send them */
	}
	if (o->io != NULL) {
		c->io.cfg = *o->io;
		/* the drives' touch probe: 0x60B8 in every RPDO */
		c->enc.rpdo_probe = o->drives && o->io->probe_source == MLIP_PROBE_SRC_DRIVE;
	}
	if (o->home != NULL) {
		c->home.cfg = *o->home;
		for (int k = 0; k < m->n_axes; k++) {
			c->home.configured |= o->home->axis[k].configured ? 1u << k : 0u;
		}
	}
	if (mlip_ctl_spindle_init(&c->spindle, o->spindle, m->period_s) != MLIP_OK ||
	    (c->spindle.on && !o->drives)) {
		return MLIP_E_INVALID; /* a spindle on the bus needs the drives' master */
	}
	c->stall_periods = o->stall_periods ? o->stall_periods : MLIP_STALL_PERIODS_DEFAULT;
	c->jog.deadman = (uint64_t)floor(MLIP_JOG_DEADMAN_S / m->period_s + 1e-9);
	c->state = MLIP_STATE_IDLE;
	c->drives = o->drives != 0;
	/* enabled by the bring-up */
	mlip_402_seq_init(&c->power.seq, c->drives ? MLIP_POWER_ENABLED : MLIP_POWER_NONE,
	                  o->drive_state_periods ? o->drive_state_periods : 1000, 0);
	return MLIP_OK;
}

int32_t mlip_ct_apply_command(struct mlip_ctl *c, struct mlip_ctl_out *out,
                              const struct mlip_ctl_in *in, const struct mlip_ring_cmd *cmd)
{
	struct mlip_planner *p = c->planner;
	int held;
	if (cmd->op == MLIP_CMD_RESET) {
		return mlip_ct_reset(c, out, in);
	}
	if (cmd->op == MLIP_CMD_JOG) {
		return mlip_ct_jog_command(c, out, cmd->arg);
	}
	if (cmd->op == MLIP_CMD_JOG_AXIS) {
		return mlip_ct_jog_axis_command(c, cmd->arg);
	}
	if (cmd->op == MLIP_CMD_HOME) {
		return mlip_ct_home_command(c, out, cmd->arg);
	}
	if (cmd->op == MLIP_CMD_HOLD && c->jog.on) {
		mlip_ct_jog_release(c, MLIP_WHY_JOG_RELEASED); /* Grbl: a hold cancels a jog */
		return MLIP_OK;
	}
	if (c->io.estop && (cmd->op == MLIP_CMD_HOLD || cmd->op == MLIP_CMD_RESUME)) {
		return MLIP_E_INVALID; /* nothing to hold or resume: a reset first */
	}
	switch (cmd->op) {
	case MLIP_CMD_OVERRIDE:
		held = mlip_planner_set_override(p, (double)cmd->arg);
		if (held == MLIP_OK) {
			mlip_ct_ext_override(c, (double)cmd->arg);
		}
		return held;
	case MLIP_CMD_SPINDLE_OVERRIDE:
		return mlip_ctl_spindle_override(&c->spindle, cmd->arg, c->period);
	case MLIP_CMD_SPINDLE_STOP:
		/* Grbl's 0x9E: in an operator's hold only (Grbl ignores it
		 * elsewhere); applied once the hold is at rest */
		if (cmd->arg != 0 && cmd->arg != 1) {
			return MLIP_E_RANGE;
		}
		if (!c->spindle.on || !c->hold.op) {
			return MLIP_E_INVALID;
		}
		c->spindle.stop_req = cmd->arg;
		return MLIP_OK;
	case MLIP_CMD_HOLD:
		mlip_planner_hold(p, 1);
		c->hold.op = 1;
		c->hold.spindle = 0;
		if (mlip_planner_moving(p) || c->ext.q != NULL) {
			mlip_ct_brake_begin(c); /* at rest: no stop on the path to count */
		}
		return MLIP_OK;
	case MLIP_CMD_RESUME:
		if (c->state == MLIP_STATE_FAULT) {
			return MLIP_E_INVALID;
		}
		if (c->hold.bus) {
			/* held by the bus: only once it has been clean for a while */
			if (c->period - c->hold.bus_bad_period < MLIP_BUS_CLEAN_PERIODS) {
				return MLIP_E_INVALID;
			}
			c->hold.bus = 0;
		}
		held = c->spindle.on && mlip_ct_spindle_held(c);
		c->hold.stall = 0;
		c->hold.op = 0;
		c->spindle.stop_req = -1;
		if (c->spindle.on && (c->spindle.stopped ||
		                      (held && (c->spindle.drive.phase == MLIP_SPINDLE_RAMPING ||
		                                c->spindle.drive.phase == MLIP_SPINDLE_BRAKING)))) {
			/* Grbl: a resume restores the spindle it stopped (wherever
			 * the program stands: lines taken in the hold move it on);
			 * the motion goes on once it is at speed (mlip_ct_spindle_period) */
			mlip_ctl_spindle_stop(&c->spindle, 0, c->period);
			c->hold.spindle = 1;
			return MLIP_OK;
		}
		mlip_planner_hold(p, 0);
		c->brake.on = 0; /* resumed before rest: no stop to measure */
		c->wait.resume = c->state == MLIP_STATE_PAUSED; /* and a pause ends */
		return MLIP_OK;
	case MLIP_CMD_STOP:
		mlip_ct_begin_stop(c, out, MLIP_WHY_STOP);
		return MLIP_OK;
	case MLIP_CMD_OPTIONAL_STOP:
		if (cmd->arg != 0 && cmd->arg != 1) {
			return MLIP_E_RANGE;
		}
		c->op.optional_stop = cmd->arg;
		return MLIP_OK;
	default:
		return MLIP_E_INVALID;
	}
}

/* The executing record, for the status. */
void mlip_ct_progress(const struct mlip_ctl *c, uint64_t *seq, uint32_t *line)
{
	const struct mlip_planner *p = c->planner;
	*seq = c->prog.exec.seq;
	*line = c->prog.exec.line;
	if (c->ext.q != NULL) {
		/* following the planned queue: the record its state lies in */
		if (c->ext.q->c.mark.seq > 0) {
			*seq = c->ext.q->c.mark.seq;
			*line = c->ext.q->c.mark.line;
		}
		return;
	}
	if (c->state == MLIP_STATE_DWELLING || c->state == MLIP_STATE_PAUSED) {
		*seq = c->wait.at.seq;
		*line = c->wait.at.line;
	} else if (c->wait.stopped) {
		return; /* stopping in a wait: the pre-read after it never moves */
	} else if (c->state != MLIP_STATE_PREREAD && mlip_planner_queued(p) > 0) {
		mlip_planner_executing(p, seq, line);
	}
}

static void publish(const struct mlip_ctl *c, struct mlip_ctl_out *out)
{
	struct mlip_ring_status *s = &out->status;
	const struct mlip_planner *p = c->planner;
	memset(s, 0, sizeof(*s));
	s->heartbeat = c->period + 1;
	mlip_ct_progress(c, &s->exec_seq, &s->exec_line);
	s->state = c->state;
	s->override_pct = (uint32_t)(mlip_planner_override_pct(p) + 0.5);
	s->overruns = c->overruns;
	s->underruns = c->counts.underruns;
	s->blocks_consumed = c->counts.blocks_consumed;
	s->stop_nm = c->brake.last_nm;
	s->stop_periods = c->brake.last_periods;
	s->stops = c->brake.count;
	s->reason = c->why.why;
	s->reason_field = c->why.field;
	s->reason_seq = c->why.seq;
	s->reason_line = c->why.line;
	s->reason_value = c->why.value;
	s->reason_node = c->why.node;
	s->optional_stop = (uint32_t)c->op.optional_stop;
	memcpy(s->pos, c->pos, sizeof(s->pos));
	s->speed_mm_s = c->ext.q != NULL ? c->ext.q->c.st.v : mlip_planner_speed(p);
	s->dwell_left = c->state == MLIP_STATE_DWELLING ? c->wait.dwell_left : 0;
	s->drive_power = c->drives && c->io.estop ? MLIP_POWER_QUICK_STOP : c->power.seq.step;
	s->drive_power_periods = (uint32_t)c->power.seq.took;
	memcpy(s->prog_start, c->prog.start, sizeof(s->prog_start));
	s->stop_seen = c->op.stop_seen;
	s->io_mapped = c->io.cfg.mapped;
	s->held_by = mlip_ct_held_by(c); /* at rest: latched for the next program */
}

/* Still moving: a stall must freeze it. */
static int moving(const struct mlip_ctl *c)
{
	if (c->ext.q != NULL) {
		return c->ext.q->c.mode == MLIP_PLANQ_PLAN || c->ext.q->c.st.v != 0.0;
	}
	return mlip_planner_moving(c->planner) && c->state != MLIP_STATE_PREREAD &&
	       c->state != MLIP_STATE_DWELLING && c->state != MLIP_STATE_PAUSED;
}

/* ---- the period ----------------------------------------------------------- */

void mlip_ctl_period(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out)
{
	struct mlip_planner *p = c->planner;
	int stalled = 0;

	out->n_events = 0;
	out->n_frames = 0;
	c->power.want = 0; /* blocks_in says again whether a program waits */
	out->cmd_result = MLIP_OK;
	out->done = 0;
	c->period = in->period;
	c->overruns += in->missed;
	c->rx.view = &in->recs;
	c->rx.taken = 0;
	if (in->recs_corrupt != 0 && c->rx.corrupt == 0) {
		c->rx.corrupt =
		    in->recs_corrupt; /* a corrupted segment: nothing more is read from it */
	}

	if (!in->unsent) {
		memcpy(c->sent, c->carried, sizeof(c->sent));
	}
	/* a stall: the drives stood at the last setpoint while the plan's clock
	 * ran on. Never jump: that setpoint becomes a point of rest, and motion
	 * continues from it only on the operator's resume. Frames of the last
	 * period withheld (a stall between its work and its send): the one
	 * before is where they stand */
	int stall = in->missed > c->stall_periods || in->unsent;
	if (stall && moving(c) && c->ext.q != NULL) {
		/* the queue's state a rest at the last setpoint sent (frames
		 * withheld: the state a period back); a stop, a fault or an
		 * E-stop's run ends there (follow.c: dropped at rest) */
		mlip_planq_rest(c->ext.q, in->unsent);
		if (c->state == MLIP_STATE_RUNNING || c->state == MLIP_STATE_HELD) {
			c->hold.stall = 1;
			c->brake.on = 0;
			struct mlip_ctl_reason r = reason(MLIP_WHY_STALL, 0, 0);
			r.value = (double)in->missed;
			go(c, out, MLIP_STATE_HELD, r);
		}
	} else if (stall && moving(c)) {
		if (in->unsent) {
			mlip_planner_rest_back(p, c->sent);
			memcpy(c->pos, c->sent, sizeof(c->pos));
		} else {
			mlip_planner_rest_here(p);
		}
		if (c->state == MLIP_STATE_FAULT || c->state == MLIP_STATE_STOPPING) {
			mlip_planner_stop(p); /* a stop in progress ends here */
		} else {
			c->hold.stall = 1;
			c->brake.on = 0;
			struct mlip_ctl_reason r = reason(MLIP_WHY_STALL, 0, 0);
			mlip_ct_progress(c, &r.seq, &r.line);
			r.value = (double)in->missed;
			go(c, out, MLIP_STATE_HELD, r);
		}
		stalled = 1;
	}
	/* the inputs first: an E-stop wins over every command of this period */
	mlip_ct_io_period(c, in, out);
	if (c->io.estop && c->drives) {
		mlip_ct_estop_rest(c, in); /* this period's TPDOs judged before a reset */
	}
	if (in->cmd != NULL) {
		out->cmd_result = mlip_ct_apply_command(c, out, in, in->cmd);
	}
	/* a stop request (the segment's counter): never behind a command */
	if (in->stop_requests != c->op.stop_seen) {
		c->op.stop_seen = in->stop_requests;
		mlip_ct_begin_stop(c, out, MLIP_WHY_STOP);
	}
	if (in->exit_request && !c->op.exiting) {
		c->op.exiting = 1; /* a controlled stop on the path, then done */
		mlip_ct_begin_stop(c, out, MLIP_WHY_EXIT);
	}
	/* frames the drives did not get, or a bus that is off: do not go on
	 * blind; hold on the path until the operator resumes on a clean bus */
	if (in->bus.tx_refused != c->hold.tx_seen || in->bus.off) {
		c->hold.bus_bad_period = c->period;
		if (!c->hold.bus) {
			c->hold.bus = 1;
			c->hold.bus_why = in->bus.off ? MLIP_WHY_BUS_ERROR : MLIP_WHY_BUS_TX;
			mlip_planner_hold(p, 1);
			mlip_ct_brake_begin(c);
		}
	}
	c->hold.tx_seen = in->bus.tx_refused;
	if (in->drives.fault.event != 0 && !c->drive_faulted) {
		mlip_ct_drive_fault(c, out, &in->drives.fault);
	}
	if (in->plan_fault != c->ext.refused) {
		/* a count, not a flag: a refusal after a fault left (an E-stop's
		 * reset) faults again. A queue running: its braking run (follow.c) */
		c->ext.refused = in->plan_fault;
		if (c->ext.q == NULL) {
			c->ext.last = in->plan_prog; /* published, not started: it never starts */
		}
		struct mlip_ctl_reason r = reason(MLIP_WHY_PLAN_REFUSED, 0, 0);
		mlip_ct_progress(c, &r.seq, &r.line); /* the block it came in */
		mlip_ct_fault(c, out, r);
	}

	mlip_ct_spindle_period(c, in, out);
	mlip_mio_period(c, in); /* the probe's trip, before the records */
	mlip_ct_jog_period(c, out);
	mlip_ct_home_period(c, in, out);
	if (!mlip_ct_ext_start(c, in, out)) {
		mlip_ct_blocks_in(c, in, out); /* no record while the queue runs */
	}
	mlip_planner_work(p); /* the look-ahead's share of the period, bounded */
	if (c->rx.corrupt && !c->prog.bad) {
		struct mlip_ctl_reason r = reason(MLIP_WHY_RING_CORRUPT, c->prog.next_seq, 0);
		r.field = MLIP_FIELD_HEAD;
		r.value = (double)c->rx.corrupt;
		mlip_ct_fault(c, out, r);
		c->prog.discard = 0; /* nothing is read from that ring again */
	}

	/* one step; a pre-read or a wait does not move, nor the stall's period */
	if (c->io.estop && c->drives) {
		mlip_ct_follow_actual(c, in); /* the drives brake by themselves */
		mlip_ct_ext_drop(c);          /* the queue's plan is left behind */
	} else if (c->ext.q != NULL) {
		mlip_ct_ext_step(c, out);
	} else if (c->state == MLIP_STATE_DWELLING) {
		c->wait.dwell_left--; /* >= 1 here: a wait of 0 ended in blocks_in */
	} else if (c->state != MLIP_STATE_PREREAD && c->state != MLIP_STATE_PAUSED && !stalled) {
		double prev[MLIP_MAX_AXES];
		memcpy(prev, c->pos, sizeof(prev));
		mlip_run_state rs = mlip_planner_step(p, c->pos);
		struct mlip_ctl_reason sw;
		if (mlip_mio_sync_step(c, &sw) != MLIP_OK) {
			mlip_ct_fault(c, out,
			              sw); /* an output the machine has not (checked before) */
		}
		if (c->brake.on) {
			mlip_ct_brake_step(c, prev, rs);
		}
		int still = memcmp(prev, c->pos, sizeof(prev)) == 0;
		c->power.still_periods = still ? c->power.still_periods + 1 : 0;
		mlip_ct_after_step(c, out, in, rs, still);
	}

	if (c->drives) {
		mlip_ct_power_period(c, in, out);
	}
	memcpy(out->pos, c->pos, sizeof(out->pos));
	if (c->encode) {
		uint32_t sat = 0;
		/* the drives' controlword, and no target to a drive faulted */
		for (int k = 0; k < MLIP_MAX_AXES && c->power.seq.cw >= 0; k++) {
			c->enc.controlword[k] = (uint16_t)c->power.seq.cw; /* -1: what was sent */
			if (c->home.on && (c->home.group & (1u << k)) && !c->io.estop &&
			    c->power.seq.step == MLIP_POWER_ENABLED && c->home.step >= HS_ARM) {
				c->enc.controlword[k] = c->home.cw; /* bit 4: homing start */
			}
		}
		c->enc.rpdo_mute = in->drives.mute;
		for (int k = 0; k < MLIP_MAX_AXES; k++) {
			c->enc.probe_fn[k] = c->mio.tp_fn;
		}
		if (mlip_canenc_encode(&c->enc, (uint32_t)c->period, c->pos, out->frames,
		                       MLIP_CAN_MAX_FRAMES, &out->n_frames, &sat) != MLIP_OK) {
			/* a position beyond the drive's int32 range: never send it */
			out->n_frames = 0;
			if (c->state != MLIP_STATE_FAULT) {
				mlip_ct_begin_stop(c, out, MLIP_WHY_POSITION_RANGE);
				struct mlip_ctl_reason r = reason(MLIP_WHY_POSITION_RANGE, 0, 0);
				mlip_ct_progress(c, &r.seq, &r.line);
				go(c, out, MLIP_STATE_FAULT, r);
			}
		}
		c->counts.frames_encoded += (uint64_t)out->n_frames;
	}
	if (!c->encode || out->n_frames > 0) {
		memcpy(c->carried, c->pos, sizeof(c->carried)); /* what this period sends */
	}
	publish(c, out);
	out->power.state = out->status.drive_power;
	out->status.io_inputs = in->io.active & c->io.cfg.mapped;
	out->status.io_known = in->io.known & c->io.cfg.mapped;
	memcpy(out->outputs, c->io.outputs, sizeof(out->outputs));
	out->sdo = c->home.req;
	mlip_ct_spindle_out(c, in, out);
	out->homing = c->home.on && c->home.step >= HS_ARM ? c->home.group : 0;
	out->status.homed = c->home.homed;
	mlip_mio_publish(c, &out->status);
	out->power.ok = c->power.seq.ok;
	out->power.late_node = c->power.seq.late >= 0 ? mlip_ct_node_of(c, c->power.seq.late) : 0;
	out->power.late_sw = c->power.seq.late_sw;
	out->power.late_step = c->power.seq.late_step;
	out->status.actual_mask = in->drives.actual_mask;
	memcpy(out->status.pos_actual, in->drives.pos_actual, sizeof(out->status.pos_actual));
	/* an exit request ends once the machine is at rest */
	if (c->home.on) {
		out->done = 0; /* the drives go back to CSP first */
	} else if (c->io.estop) {
		/* quick stopped (the drives are not enabled), or at rest without drives */
		out->done = c->op.exiting && (c->drives || !mlip_planner_moving(p));
	} else {
		out->done = c->op.exiting && !c->prog.discard &&
		            (c->state == MLIP_STATE_IDLE ||
		             (c->state == MLIP_STATE_FAULT && mlip_planner_queued(p) == 0 &&
		              c->ext.q == NULL)) &&
		            (!c->drives ||
		             c->power.seq.step == MLIP_POWER_OFF); /* and the drives disabled */
	}
	out->taken = c->rx.taken;
	out->counts = c->counts;
	c->rx.view = NULL; /* the caller's, for this period only */
}
