/*
 * inputs.c - the digital inputs on the bus (issue 18): a V_IOBIT value, the
 * [IO] section and the axes' LIMIT_NEG / LIMIT_POS / HOME_SWITCH into
 * mlip_io_config, and their checks against the machine.
 */
#include <string.h>

#include "keys.h"
#include "mlip/text/chars.h"
#include "mlip/text/number.h"

/* packed: node | index << 8 | sub << 24 | bit << 32 | active_low << 40 */
static struct mlip_io_bit unpack(int64_t v, uint32_t line)
{
	struct mlip_io_bit b;
	uint64_t u = (uint64_t)v;

	b.node = (uint8_t)(u & 0xFF);
	b.index = (uint16_t)((u >> 8) & 0xFFFF);
	b.sub = (uint8_t)((u >> 24) & 0xFF);
	b.bit = (uint8_t)((u >> 32) & 0xFF);
	b.active_low = (uint8_t)((u >> 40) & 1);
	b.line = line;
	return b;
}

size_t mlip_mc_token(const char *v, size_t nv, size_t *p, size_t *start)
{
	size_t q = *p;

	while (q < nv && mlip_is_blank(v[q])) {
		q++;
	}
	*start = q;
	while (q < nv && !mlip_is_blank(v[q])) {
		q++;
	}
	*p = q;
	return q - *start;
}

mlip_status mlip_mc_value_err(struct mlip_config_error *err, uint32_t line, uint32_t col,
                              const char *key, const char *what, const char *tok, size_t ntok)
{
	struct mlip_tb b;

	err_at(err, &b, line, col);
	mlip_tb_puts(&b, key);
	mlip_tb_puts(&b, what);
	if (tok != NULL) {
		mlip_tb_puts(&b, ", got '");
		mlip_tb_token(&b, tok, ntok);
		mlip_tb_putc(&b, '\'');
	}
	return MLIP_E_SYNTAX;
}

mlip_status mlip_mc_node_object(const char *v, const size_t *t, const size_t *n, uint32_t line,
                                uint32_t col, const char *key, int64_t *node, int64_t *index,
                                int64_t *sub, struct mlip_config_error *err)
{
	size_t colon;

	if (mlip_number_int(v + t[0], n[0], node) != 0 || *node < 1 || *node > 127) {
		return mlip_mc_value_err(err, line, col + (uint32_t)t[0], key,
		                         ": NODE must be a node id 1..127", v + t[0], n[0]);
	}
	for (colon = 0; colon < n[1] && v[t[1] + colon] != ':'; colon++) {
	}
	if (colon == n[1] || mlip_number_int(v + t[1], colon, index) != 0 || *index < 0 ||
	    *index > 0xFFFF || mlip_number_int(v + t[1] + colon + 1, n[1] - colon - 1, sub) != 0 ||
	    *sub < 0 || *sub > 0xFF) {
		return mlip_mc_value_err(err, line, col + (uint32_t)t[1], key,
		                         ": the object must be INDEX:SUB (e.g. 0x6000:1)", v + t[1],
		                         n[1]);
	}
	return MLIP_OK;
}

mlip_status mlip_mc_parse_iobit(const char *v, size_t nv, uint32_t line, uint32_t col,
                                const char *key, int64_t *packed, struct mlip_config_error *err)
{
	static const char *const form =
	    " must be NODE INDEX:SUB BIT HIGH|LOW (e.g. 10 0x6000:1 0 LOW)";
	size_t p = 0, t[4], n[4];
	int64_t node, index, sub, bit, low;
	mlip_status st;
	int i;

	for (i = 0; i < 4; i++) {
		n[i] = mlip_mc_token(v, nv, &p, &t[i]);
		if (n[i] == 0) {
			return mlip_mc_value_err(err, line, col + (uint32_t)t[i], key, form, NULL,
			                         0);
		}
	}
	{
		size_t s5, n5 = mlip_mc_token(v, nv, &p, &s5);
		if (n5 != 0) {
			return mlip_mc_value_err(err, line, col + (uint32_t)s5, key, form, v + s5,
			                         n5);
		}
	}
	st = mlip_mc_node_object(v, t, n, line, col, key, &node, &index, &sub, err);
	if (st != MLIP_OK) {
		return st;
	}
	if (mlip_number_int(v + t[2], n[2], &bit) != 0 || bit < 0 || bit > 31) {
		return mlip_mc_value_err(err, line, col + (uint32_t)t[2], key,
		                         ": BIT must be 0..31", v + t[2], n[2]);
	}
	if (n[3] == 4 && memcmp(v + t[3], "HIGH", 4) == 0) {
		low = 0;
	} else if (n[3] == 3 && memcmp(v + t[3], "LOW", 3) == 0) {
		low = 1;
	} else {
		return mlip_mc_value_err(
		    err, line, col + (uint32_t)t[3], key,
		    ": the polarity must be HIGH (on when the bit is 1) or LOW (on when 0)",
		    v + t[3], n[3]);
	}
	*packed = node | index << 8 | sub << 24 | bit << 32 | low << 40;
	return MLIP_OK;
}

const char *mlip_io_probe_warning(const struct mlip_io_config *io)
{
	if (io->probe_source != MLIP_PROBE_SRC_DRIVE || (io->mapped >> MLIP_IN_PROBE & 1u)) {
		return NULL;
	}
	return "[PROBE] SOURCE = drive without [IO] PROBE: the touch probe's status 0x60B9 has no "
	       "level, so a probe that is on when a G38.2/G38.3 starts (a plate touching, a "
	       "stuck switch) gives no edge and nothing stops the move toward its target; map "
	       "the probe's level, e.g. PROBE = 3 0x60FD:0 16 HIGH (the drive's digital input "
	       "bit, see its manual), and mlip refuses such a G38 before anything moves";
}

const char *mlip_io_function_name(uint32_t f, const struct mlip_machine *m, char *buf, size_t n)
{
	static const char *const fixed[MLIP_IN_AXIS0] = {"estop", "hold", "cycle start", "probe"};
	static const char *const per_axis[3] = {" limit -", " limit +", " home switch"};
	struct mlip_tb b;
	uint32_t k;

	mlip_tb_init(&b, buf, n);
	if (f < MLIP_IN_AXIS0) {
		mlip_tb_puts(&b, fixed[f]);
	} else if (f < MLIP_IN_COUNT) {
		k = (f - MLIP_IN_AXIS0) / 3;
		if (m != NULL && (int)k < m->n_axes) {
			mlip_tb_putc(&b, m->axis[k].letter);
		} else {
			mlip_tb_puts(&b, "axis ");
			mlip_tb_uint(&b, k);
		}
		mlip_tb_puts(&b, per_axis[(f - MLIP_IN_AXIS0) % 3]);
	} else {
		mlip_tb_puts(&b, "?");
	}
	return buf;
}

/* Where function f is mapped: its section and key (an axis' LIMIT_INPUTS
 * = drive when that maps it). */
static void key_of(const struct pstate *ps, const struct mlip_config *c, uint32_t f, int *sec,
                   int *key)
{
	if (f < MLIP_IN_AXIS0) {
		*sec = SEC_IO;
		*key = IK_ESTOP + (int)f;
	} else {
		uint32_t k = (f - MLIP_IN_AXIS0) / 3;
		*sec = SEC_AXIS0 + letter_index(c->machine.axis[k].letter);
		*key = AK_LIMIT_NEG + (int)((f - MLIP_IN_AXIS0) % 3);
		if (!has(ps, *sec, *key) && has(ps, *sec, AK_LIMIT_INPUTS)) {
			*key = AK_LIMIT_INPUTS;
		}
	}
}

static mlip_status io_err(const struct pstate *ps, const struct mlip_config *c, uint32_t f,
                          struct mlip_config_error *err, struct mlip_tb *b)
{
	int sec, key;

	key_of(ps, c, f, &sec, &key);
	mlip_mc_place(ps, err, sec, key, -1, 0, -1, 0);
	(void)b;
	return MLIP_E_RANGE;
}

static void say_key(const struct pstate *ps, struct mlip_tb *b, const struct mlip_config *c,
                    uint32_t f)
{
	int sec, key;

	key_of(ps, c, f, &sec, &key);
	mlip_tb_putc(b, '[');
	mlip_mc_secname(b, sec);
	mlip_tb_puts(b, "] ");
	mlip_tb_puts(b, mlip_mc_keytab[sec_kind(sec)][key].name);
}

mlip_status mlip_mc_fill_inputs(const struct pstate *ps, struct mlip_config *c,
                                struct mlip_config_error *err)
{
	struct mlip_io_config *io = &c->inputs;
	const struct mlip_machine *m = &c->machine;
	struct mlip_tb b;
	uint32_t f, g;
	int i, sec, key;

	memset(io, 0, sizeof *io);
	io->probe_source = has(ps, SEC_PROBE, PK_SOURCE)
	                       ? (uint8_t)ps->sec[SEC_PROBE].ival[PK_SOURCE]
	                       : MLIP_PROBE_SRC_IO;
	if (has(ps, SEC_IO, IK_NODE)) {
		io->node = (uint8_t)ps->sec[SEC_IO].ival[IK_NODE];
	}
	for (f = 0; f < MLIP_IN_COUNT; f++) {
		if (f >= MLIP_IN_AXIS0 && (int)((f - MLIP_IN_AXIS0) / 3) >= m->n_axes) {
			break;
		}
		key_of(ps, c, f, &sec, &key);
		if (key == AK_LIMIT_INPUTS) {
			/* the switches on the axis' drive (CAN_NODE, CiA 402 0x60FD:
			 * bit 0 negative limit, 1 positive limit, 2 home switch), on
			 * when set */
			const struct mlip_axis *a = &m->axis[(f - MLIP_IN_AXIS0) / 3];
			int fk = (int)((f - MLIP_IN_AXIS0) % 3);
			for (i = AK_LIMIT_NEG; i <= AK_HOME_SW; i++) {
				if (has(ps, sec, i)) {
					err_at(err, &b, 0, 0);
					mlip_tb_puts(&b, "AXIS_");
					mlip_tb_putc(&b, a->letter);
					mlip_tb_putc(&b, ' ');
					mlip_tb_puts(&b, mlip_mc_keytab[K_AXIS][i].name);
					mlip_tb_puts(&b, " and LIMIT_INPUTS = drive map the same "
					                 "switch: one or the other");
					mlip_mc_place(ps, err, sec, i, sec, AK_LIMIT_INPUTS, -1, 0);
					return MLIP_E_RANGE;
				}
			}
			io->in[f] = (struct mlip_io_bit){.node = a->can_node,
			                                 .index = 0x60FD,
			                                 .sub = 0,
			                                 .bit = (uint8_t)fk,
			                                 .active_low = 0,
			                                 .line = ps->sec[sec].key[key].line};
			io->mapped |= 1u << f;
		} else if (has(ps, sec, key)) {
			io->in[f] = unpack(ps->sec[sec].ival[key], ps->sec[sec].key[key].line);
			io->mapped |= 1u << f;
		}
	}
	if (io->node != 0) {
		for (i = 0; i < m->n_axes; i++) {
			if (m->axis[i].can_node == io->node) {
				err_at(err, &b, 0, 0);
				mlip_tb_puts(&b, "[IO] NODE ");
				mlip_tb_uint(&b, io->node);
				mlip_tb_puts(&b, " is also the CAN_NODE of AXIS_");
				mlip_tb_putc(&b, m->axis[i].letter);
				mlip_mc_place(ps, err, SEC_IO, IK_NODE,
				              SEC_AXIS0 + letter_index(m->axis[i].letter), AK_NODE,
				              -1, 0);
				return MLIP_E_RANGE;
			}
		}
		if (io->node == c->drives.master_node) {
			err_at(err, &b, 0, 0);
			mlip_tb_puts(&b, "[IO] NODE ");
			mlip_tb_uint(&b, io->node);
			mlip_tb_puts(&b, " is also the [DRIVES] MASTER_NODE");
			mlip_mc_place(ps, err, SEC_IO, IK_NODE, SEC_DRIVES, DK_MASTER, -1, 0);
			return MLIP_E_RANGE;
		}
	}
	for (f = 0; f < MLIP_IN_COUNT; f++) {
		const struct mlip_io_bit *x = &io->in[f];
		int drive = -1;
		if (!(io->mapped & (1u << f))) {
			continue;
		}
		for (i = 0; i < m->n_axes; i++) {
			if (m->axis[i].can_node == x->node) {
				drive = i;
			}
		}
		if (x->node != io->node && drive < 0) {
			err_at(err, &b, 0, 0);
			say_key(ps, &b, c, f);
			mlip_tb_puts(&b, ": node ");
			mlip_tb_uint(&b, x->node);
			mlip_tb_puts(&b, " is neither the I/O module ([IO] NODE");
			if (io->node == 0) {
				mlip_tb_puts(&b, " not set");
			} else {
				mlip_tb_puts(&b, " ");
				mlip_tb_uint(&b, io->node);
			}
			mlip_tb_puts(&b, ") nor a drive (an axis' CAN_NODE)");
			return io_err(ps, c, f, err, &b);
		}
		if (drive < 0 && !(x->index == 0x6000 && x->sub >= 1 &&
		                   x->sub <= MLIP_IO_IN_BYTES && x->bit <= 7)) {
			err_at(err, &b, 0, 0);
			say_key(ps, &b, c, f);
			mlip_tb_puts(&b, ": the I/O module's inputs are 0x6000:1..8, bits 0..7");
			return io_err(ps, c, f, err, &b);
		}
		if (drive >= 0 && !(x->index == 0x60FD && x->sub == 0)) {
			err_at(err, &b, 0, 0);
			say_key(ps, &b, c, f);
			mlip_tb_puts(
			    &b, ": a drive's inputs are 0x60FD:0 (digital inputs), bits 0..31");
			return io_err(ps, c, f, err, &b);
		}
		if (drive < 0 && x->sub > io->in_bytes) {
			io->in_bytes = x->sub;
		}
		for (g = 0; g < f; g++) {
			const struct mlip_io_bit *y = &io->in[g];
			if ((io->mapped & (1u << g)) && y->node == x->node &&
			    y->index == x->index && y->sub == x->sub && y->bit == x->bit) {
				/* named in the order of the file: the later one is wrong */
				uint32_t later = y->line > x->line ? g : f,
				         first = later == f ? g : f;
				err_at(err, &b, 0, 0);
				say_key(ps, &b, c, later);
				mlip_tb_puts(&b, ": node ");
				mlip_tb_uint(&b, x->node);
				mlip_tb_puts(&b, " bit ");
				mlip_tb_uint(&b, x->bit);
				mlip_tb_puts(&b, " of its inputs already carries ");
				say_key(ps, &b, c, first);
				mlip_tb_puts(&b, " (one function a bit)");
				{
					int s1, k1, s2, k2;
					key_of(ps, c, f, &s1, &k1);
					key_of(ps, c, g, &s2, &k2);
					mlip_mc_place(ps, err, s1, k1, s2, k2, -1, 0);
				}
				return MLIP_E_RANGE;
			}
		}
	}
	return MLIP_OK;
}
