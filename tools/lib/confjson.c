/* confjson.c - see confjson.h */
#include "confjson.h"

#include "mlip/can/canenc.h"

void mlip_json_str(FILE *f, const char *s)
{
	fputc('"', f);
	for (; *s != '\0'; s++) {
		unsigned char ch = (unsigned char)*s;
		if (ch == '"' || ch == '\\') {
			fprintf(f, "\\%c", ch);
		} else if (ch < 0x20) {
			fprintf(f, "\\u%04x", ch);
		} else {
			fputc(ch, f);
		}
	}
	fputc('"', f);
}

static void frames(FILE *f, const struct mlip_config *c)
{
	const struct mlip_can_config *can = &c->can;
	const struct mlip_machine *m = &c->machine;
	mlip_can_profile p;
	int i, nf = (m->n_axes + 1) / 2;

	fprintf(f, "[");
	if (mlip_can_profile_parse(can->profile, &p) != MLIP_OK) {
		fprintf(f, "]");
		return;
	}
	switch (p) {
	case MLIP_CAN_CIA402:
		fprintf(f, "{\"id\": %u, \"name\": \"SYNC\"}", (unsigned)can->sync_id);
		for (i = 0; i < m->n_axes; i++) {
			fprintf(f, ", {\"id\": %u, \"name\": \"RPDO %c\"}",
			        (unsigned)(can->rpdo_base + (uint32_t)m->axis[i].can_node),
			        m->axis[i].letter);
		}
		break;
	case MLIP_CAN_PACKED:
		for (i = 0; i <= nf; i++) {
			fprintf(f, "%s{\"id\": %u, \"name\": \"%s", i ? ", " : "",
			        (unsigned)(can->packed_base + (uint32_t)i),
			        i < nf ? "POS " : "COMMIT");
			if (i < nf) {
				fprintf(f, "%d", i);
			}
			fprintf(f, "\"}");
		}
		break;
	case MLIP_CAN_FD:
		fprintf(f, "{\"id\": %u, \"name\": \"FD\"}", (unsigned)can->fd_id);
		break;
	}
	fprintf(f, "]");
}

void mlip_config_print_json(FILE *f, const char *path, const struct mlip_config *c)
{
	const struct mlip_machine *m = &c->machine;
	const struct mlip_can_config *can = &c->can;
	const struct mlip_drives_config *d = &c->drives;
	int i;

	fprintf(f, "{\n  \"file\": ");
	mlip_json_str(f, path);
	fprintf(f, ",\n  \"machine\": {\n    \"coordinates\": \"");
	for (i = 0; i < m->n_axes; i++) {
		fputc(m->axis[i].letter, f);
	}
	fprintf(f,
	        "\",\n    \"max_linear_velocity\": %.17g,\n    \"max_angular_velocity\": %.17g,\n"
	        "    \"contour_tolerance\": %.17g,\n    \"period\": %.17g,\n    \"axes\": [",
	        m->max_feed_mm_s, m->max_rot_feed_deg_s, m->tolerance_mm, m->period_s);
	for (i = 0; i < m->n_axes; i++) {
		const struct mlip_axis *a = &m->axis[i];
		fprintf(f,
		        "%s\n      {\"letter\": \"%c\", \"type\": \"%s\", \"max_velocity\": %.17g, "
		        "\"max_acceleration\": %.17g, \"min_limit\": %.17g, \"max_limit\": %.17g, "
		        "\"home\": %.17g, \"can_node\": %d, \"counts_per_unit\": %.17g}",
		        i ? "," : "", a->letter, a->kind == MLIP_AXIS_ROTARY ? "ANGULAR" : "LINEAR",
		        a->max_vel, a->max_accel, a->min_limit, a->max_limit, a->home, a->can_node,
		        a->counts_per_unit);
	}
	fprintf(f, "\n    ]\n  },\n  \"lookahead\": %u,\n  \"can\": {\n    \"profile\": ",
	        (unsigned)c->lookahead);
	mlip_json_str(f, can->profile);
	fprintf(f,
	        ",\n    \"bitrate\": %u,\n    \"data_bitrate\": %u,\n    \"sync_id\": %u,\n"
	        "    \"rpdo_base\": %u,\n    \"packed_base\": %u,\n    \"fd_id\": %u,\n"
	        "    \"status_id\": %u,\n    \"frames\": ",
	        (unsigned)can->bitrate, (unsigned)can->data_bitrate, (unsigned)can->sync_id,
	        (unsigned)can->rpdo_base, (unsigned)can->packed_base, (unsigned)can->fd_id,
	        (unsigned)can->status_id);
	frames(f, c);
	fprintf(f,
	        "\n  },\n  \"drives\": {\n    \"enable\": %s,\n    \"master_node\": %u,\n"
	        "    \"heartbeat_ms\": %u,\n    \"heartbeat_timeout_ms\": %u,\n"
	        "    \"following_error\": %.17g,\n    \"sdo_timeout_ms\": %u,\n"
	        "    \"boot_timeout_ms\": %u,\n    \"state_timeout_ms\": %u\n  }\n}\n",
	        d->enable ? "true" : "false", (unsigned)d->master_node, (unsigned)d->heartbeat_ms,
	        (unsigned)d->heartbeat_timeout_ms, d->following_error, (unsigned)d->sdo_timeout_ms,
	        (unsigned)d->boot_timeout_ms, (unsigned)d->state_timeout_ms);
}
