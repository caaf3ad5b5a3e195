/* confjson.c - see confjson.h */
#include "confjson.h"

#include "json.h"
#include "mlip/can/canenc.h"

#define G17 "%.17g" /* reads back to the same double */

static void frame(struct mlip_json *j, uint32_t id, const char *name)
{
	mlip_json_object(j, NULL, 1);
	mlip_json_uint(j, "id", id);
	mlip_json_string(j, "name", name);
	mlip_json_close(j);
}

static void frames(struct mlip_json *j, const struct mlip_config *c)
{
	const struct mlip_can_config *can = &c->can;
	const struct mlip_machine *m = &c->machine;
	mlip_can_profile p;
	char name[16];
	int i, nf = (m->n_axes + 1) / 2;

	mlip_json_array(j, "frames", 1);
	if (mlip_can_profile_parse(can->profile, &p) == MLIP_OK) {
		switch (p) {
		case MLIP_CAN_CIA402:
			frame(j, can->sync_id, "SYNC");
			for (i = 0; i < m->n_axes; i++) {
				snprintf(name, sizeof(name), "RPDO %c", m->axis[i].letter);
				frame(j, can->rpdo_base + (uint32_t)m->axis[i].can_node, name);
			}
			break;
		case MLIP_CAN_PACKED:
			for (i = 0; i <= nf; i++) {
				if (i < nf) {
					snprintf(name, sizeof(name), "POS %d", i);
				} else {
					snprintf(name, sizeof(name), "COMMIT");
				}
				frame(j, can->packed_base + (uint32_t)i, name);
			}
			break;
		case MLIP_CAN_FD:
			frame(j, can->fd_id, "FD");
			break;
		}
	}
	mlip_json_close(j);
}

void mlip_config_print_json(FILE *f, const char *path, const struct mlip_config *c)
{
	const struct mlip_machine *m = &c->machine;
	const struct mlip_can_config *can = &c->can;
	const struct mlip_drives_config *d = &c->drives;
	struct mlip_json j;
	char letters[MLIP_MAX_AXES + 1];
	int i;

	mlip_json_begin(&j, f);
	mlip_json_string(&j, "file", path);
	mlip_json_object(&j, "machine", 0);
	for (i = 0; i < m->n_axes; i++) {
		letters[i] = m->axis[i].letter;
	}
	letters[m->n_axes] = '\0';
	mlip_json_string(&j, "coordinates", letters);
	mlip_json_number(&j, "max_linear_velocity", G17, m->max_feed_mm_s);
	mlip_json_number(&j, "max_angular_velocity", G17, m->max_rot_feed_deg_s);
	mlip_json_number(&j, "contour_tolerance", G17, m->tolerance_mm);
	mlip_json_number(&j, "period", G17, m->period_s);
	mlip_json_array(&j, "axes", 0);
	for (i = 0; i < m->n_axes; i++) {
		const struct mlip_axis *a = &m->axis[i];
		char letter[2] = {a->letter, '\0'};
		mlip_json_object(&j, NULL, 1);
		mlip_json_string(&j, "letter", letter);
		mlip_json_string(&j, "type", a->kind == MLIP_AXIS_ROTARY ? "ANGULAR" : "LINEAR");
		mlip_json_number(&j, "max_velocity", G17, a->max_vel);
		mlip_json_number(&j, "max_acceleration", G17, a->max_accel);
		mlip_json_number(&j, "max_jerk", G17, a->max_jerk); /* 0: none */
		mlip_json_number(&j, "min_limit", G17, a->min_limit);
		mlip_json_number(&j, "max_limit", G17, a->max_limit);
		mlip_json_number(&j, "home", G17, a->home);
		mlip_json_int(&j, "can_node", a->can_node);
		mlip_json_number(&j, "counts_per_unit", G17, a->counts_per_unit);
		mlip_json_close(&j);
	}
	mlip_json_close(&j);
	mlip_json_close(&j);
	mlip_json_uint(&j, "lookahead", c->lookahead);
	mlip_json_object(&j, "can", 0);
	mlip_json_string(&j, "profile", can->profile);
	mlip_json_uint(&j, "bitrate", can->bitrate);
	mlip_json_uint(&j, "data_bitrate", can->data_bitrate);
	mlip_json_uint(&j, "sync_id", can->sync_id);
	mlip_json_uint(&j, "rpdo_base", can->rpdo_base);
	mlip_json_uint(&j, "packed_base", can->packed_base);
	mlip_json_uint(&j, "fd_id", can->fd_id);
	mlip_json_uint(&j, "status_id", can->status_id);
	frames(&j, c);
	mlip_json_close(&j);
	mlip_json_object(&j, "drives", 0);
	mlip_json_bool(&j, "enable", d->enable);
	mlip_json_uint(&j, "master_node", d->master_node);
	mlip_json_uint(&j, "heartbeat_ms", d->heartbeat_ms);
	mlip_json_uint(&j, "heartbeat_timeout_ms", d->heartbeat_timeout_ms);
	mlip_json_number(&j, "following_error", G17, d->following_error);
	mlip_json_uint(&j, "sdo_timeout_ms", d->sdo_timeout_ms);
	mlip_json_uint(&j, "boot_timeout_ms", d->boot_timeout_ms);
	mlip_json_uint(&j, "state_timeout_ms", d->state_timeout_ms);
	mlip_json_close(&j);
	/* homing (issue 18): each axis with a HOME_METHOD */
	mlip_json_object(&j, "home", 0);
	mlip_json_bool(&j, "required", c->home.required);
	mlip_json_array(&j, "axes", 0);
	for (int k = 0; k < c->machine.n_axes; k++) {
		const struct mlip_axis_home *h = &c->home.axis[k];
		char l[2] = {c->machine.axis[k].letter, '\0'};
		if (!h->configured) {
			continue;
		}
		mlip_json_object(&j, NULL, 1);
		mlip_json_string(&j, "axis", l);
		mlip_json_int(&j, "method", h->method);
		mlip_json_number(&j, "search_vel", G17, h->search_vel);
		mlip_json_number(&j, "latch_vel", G17, h->latch_vel);
		mlip_json_number(&j, "accel", G17, h->accel);
		mlip_json_number(&j, "offset", G17, h->offset);
		mlip_json_uint(&j, "sequence", (uint64_t)h->sequence);
		mlip_json_number(&j, "timeout_s", G17, h->timeout_s);
		mlip_json_close(&j);
	}
	mlip_json_close(&j);
	mlip_json_close(&j);
	/* the spindle (issue 19): none, manual, or a CiA 402 drive on the bus */
	mlip_json_object(&j, "spindle", 0);
	mlip_json_string(&j, "type",
	                 c->io.spindle == MLIP_IO_CIA402   ? "cia402"
	                 : c->io.spindle == MLIP_IO_MANUAL ? "manual"
	                                                   : "none");
	mlip_json_number(&j, "min_rpm", G17, c->io.min_rpm);
	mlip_json_number(&j, "max_rpm", G17, c->io.max_rpm);
	if (c->io.spindle == MLIP_IO_CIA402) {
		const struct mlip_spindle_config *sp = &c->spindle;
		mlip_json_uint(&j, "node", sp->node);
		mlip_json_number(&j, "counts_per_rev", G17, sp->counts_per_rev);
		mlip_json_number(&j, "acceleration", G17, sp->accel_rpm_s);
		mlip_json_number(&j, "at_speed_band", G17, sp->band_rpm);
		mlip_json_number(&j, "at_speed_timeout", G17, sp->timeout_s);
		mlip_json_number(&j, "band_time", G17, sp->band_time_s);
	}
	mlip_json_close(&j);
	/* the inputs on the bus (issue 18): the module's node, each function mapped */
	mlip_json_object(&j, "inputs", 0);
	mlip_json_uint(&j, "node", c->inputs.node);
	mlip_json_uint(&j, "in_bytes", c->inputs.in_bytes);
	mlip_json_array(&j, "functions", 0);
	for (uint32_t fn = 0; fn < MLIP_IN_COUNT; fn++) {
		const struct mlip_io_bit *b = &c->inputs.in[fn];
		char name[24];
		if (!(c->inputs.mapped & (1u << fn))) {
			continue;
		}
		mlip_json_object(&j, NULL, 1);
		mlip_json_string(&j, "function",
		                 mlip_io_function_name(fn, &c->machine, name, sizeof name));
		mlip_json_uint(&j, "index", fn);
		mlip_json_uint(&j, "node", b->node);
		mlip_json_uint(&j, "object", b->index);
		mlip_json_uint(&j, "sub", b->sub);
		mlip_json_uint(&j, "bit", b->bit);
		mlip_json_bool(&j, "active_low", b->active_low);
		mlip_json_close(&j);
	}
	mlip_json_close(&j);
	mlip_json_close(&j);
	mlip_json_end(&j);
}
