/*
 * outputs.c - the I/O module's digital outputs (issue 19): [COOLANT] TYPE =
 * io with its MIST / FLOOD outlets and [IO] OUTPUT_0..7 (M64/M65 Pn) into
 * mlip_io_config, checked against the module and the inputs.
 */
#include <string.h>

#include "keys.h"
#include "mlip/text/chars.h"
#include "mlip/text/number.h"

static int tok_eq(const char *v, size_t n, const char *s)
{
	return n == strlen(s) && memcmp(v, s, n) == 0;
}

mlip_status mlip_mc_parse_output(int type, const char *v, size_t nv, uint32_t line, uint32_t col,
                                 const char *key, int64_t *val, struct mlip_config_error *err)
{
	static const char *const form =
	    " must be NODE 0x6200:SUB BIT (e.g. 10 0x6200:1 0): an output of the I/O module";
	size_t p = 0, t[4], n[4];
	int64_t node, index, sub, bit;
	int i;

	if (type == V_COOLANT) {
		*val = tok_eq(v, nv, "none")     ? MLIP_IO_NONE
		       : tok_eq(v, nv, "manual") ? MLIP_IO_MANUAL
		       : tok_eq(v, nv, "io")     ? MLIP_IO_MODULE
		                                 : -1;
		if (*val < 0) {
			return mlip_mc_value_err(
			    err, line, col, key,
			    " must be none, manual or io (the I/O module's outputs)", v, nv);
		}
		return MLIP_OK;
	}
	for (i = 0; i < 4; i++) {
		n[i] = mlip_mc_token(v, nv, &p, &t[i]);
		if (n[i] == 0 && i < 3) {
			return mlip_mc_value_err(err, line, col + (uint32_t)t[i], key, form, NULL,
			                         0);
		}
	}
	if (n[3] != 0 && !tok_eq(v + t[3], n[3], "HIGH")) {
		return mlip_mc_value_err(
		    err, line, col + (uint32_t)t[3], key,
		    tok_eq(v + t[3], n[3], "LOW")
		        ? ": outputs are active high (HIGH): an output the module switches "
		          "off by itself (power-up, the master lost) must be off"
		        : form,
		    v + t[3], n[3]);
	}
	{
		size_t s5, n5 = mlip_mc_token(v, nv, &p, &s5);
		if (n5 != 0) {
			return mlip_mc_value_err(err, line, col + (uint32_t)s5, key, form, v + s5,
			                         n5);
		}
	}
	mlip_status st = mlip_mc_node_object(v, t, n, line, col, key, &node, &index, &sub, err);
	if (st != MLIP_OK) {
		return st;
	}
	if (index != 0x6200 || sub < 1 || sub > MLIP_IO_IN_BYTES) {
		return mlip_mc_value_err(
		    err, line, col + (uint32_t)t[1], key,
		    ": the I/O module's outputs are 0x6200:1..8 (CiA 401 write output 8-bit)",
		    v + t[1], n[1]);
	}
	if (mlip_number_int(v + t[2], n[2], &bit) != 0 || bit < 0 || bit > 7) {
		return mlip_mc_value_err(err, line, col + (uint32_t)t[2], key,
		                         ": BIT must be 0..7 (a bit of the output byte)", v + t[2],
		                         n[2]);
	}
	*val = node | index << 8 | sub << 24 | bit << 32;
	return MLIP_OK;
}

/* Where output o is mapped: its section and key. */
static void key_of(uint32_t o, int *sec, int *key)
{
	if (o == MLIP_OUT_MIST || o == MLIP_OUT_FLOOD) {
		*sec = SEC_COOLANT;
		*key = o == MLIP_OUT_MIST ? QK_MIST : QK_FLOOD;
	} else {
		*sec = SEC_IO;
		*key = IK_OUT0 + (int)(o - MLIP_OUT_DOUT0);
	}
}

static void say_key(struct mlip_tb *b, uint32_t o)
{
	int sec, key;

	key_of(o, &sec, &key);
	mlip_tb_putc(b, '[');
	mlip_mc_secname(b, sec);
	mlip_tb_puts(b, "] ");
	mlip_tb_puts(b, mlip_mc_keytab[sec_kind(sec)][key].name);
}

static mlip_status place(const struct pstate *ps, struct mlip_config_error *err, uint32_t o)
{
	int sec, key;

	key_of(o, &sec, &key);
	mlip_mc_place(ps, err, sec, key, -1, 0, -1, 0);
	return MLIP_E_RANGE;
}

mlip_status mlip_mc_fill_outputs(const struct pstate *ps, struct mlip_config *c,
                                 struct mlip_config_error *err)
{
	struct mlip_io_config *io = &c->inputs;
	struct mlip_tb b;
	uint32_t o, g;
	int sec, key;

	io->out_mapped = 0;
	io->out_bytes = 0;
	memset(io->out, 0, sizeof io->out);
	for (o = 0; o < MLIP_OUT_COUNT; o++) {
		uint64_t u;
		uint8_t node;
		key_of(o, &sec, &key);
		if (!has(ps, sec, key)) {
			continue;
		}
		u = (uint64_t)ps->sec[sec].ival[key];
		node = (uint8_t)(u & 0xFF);
		io->out[o].sub = (uint8_t)((u >> 24) & 0xFF);
		io->out[o].bit = (uint8_t)((u >> 32) & 0xFF);
		io->out[o].line = ps->sec[sec].key[key].line;
		io->out_mapped |= 1u << o;
		if (node != io->node) {
			err_at(err, &b, 0, 0);
			say_key(&b, o);
			mlip_tb_puts(&b, ": node ");
			mlip_tb_uint(&b, node);
			mlip_tb_puts(&b, " is not the I/O module ([IO] NODE");
			if (io->node == 0) {
				mlip_tb_puts(&b, " not set");
			} else {
				mlip_tb_putc(&b, ' ');
				mlip_tb_uint(&b, io->node);
			}
			mlip_tb_puts(&b, "): outputs are the module's");
			return place(ps, err, o);
		}
		if (io->out[o].sub > io->out_bytes) {
			io->out_bytes = io->out[o].sub;
		}
	}
	/* one bit, one output: two functions on one wire switch each other */
	for (o = 0; o < MLIP_OUT_COUNT; o++) {
		const struct mlip_io_out *x = &io->out[o];
		if (!(io->out_mapped >> o & 1u)) {
			continue;
		}
		for (g = 0; g < o; g++) {
			const struct mlip_io_out *y = &io->out[g];
			if ((io->out_mapped >> g & 1u) && y->sub == x->sub && y->bit == x->bit) {
				uint32_t later = y->line > x->line ? g : o,
				         first = later == o ? g : o;
				err_at(err, &b, 0, 0);
				say_key(&b, later);
				mlip_tb_puts(&b, ": output 0x6200:");
				mlip_tb_uint(&b, x->sub);
				mlip_tb_puts(&b, " bit ");
				mlip_tb_uint(&b, x->bit);
				mlip_tb_puts(&b, " is already ");
				say_key(&b, first);
				mlip_tb_puts(&b, " (one output a bit)");
				return place(ps, err, later);
			}
		}
	}
	if (c->io.coolant == MLIP_IO_MODULE &&
	    !(io->out_mapped & (1u << MLIP_OUT_MIST | 1u << MLIP_OUT_FLOOD))) {
		err_at(err, &b, 0, 0);
		mlip_tb_puts(&b, "[COOLANT] TYPE = io needs MIST or FLOOD: the module's output "
		                 "that switches it (e.g. MIST = 10 0x6200:1 0)");
		mlip_mc_place(ps, err, SEC_COOLANT, QK_TYPE, -1, 0, -1, 0);
		return MLIP_E_SYNTAX;
	}
	for (o = MLIP_OUT_MIST; o <= MLIP_OUT_FLOOD; o++) {
		if ((io->out_mapped >> o & 1u) && c->io.coolant != MLIP_IO_MODULE) {
			err_at(err, &b, 0, 0);
			say_key(&b, o);
			mlip_tb_puts(&b, " switches coolant only with [COOLANT] TYPE = io");
			mlip_mc_place(ps, err, SEC_COOLANT, o == MLIP_OUT_MIST ? QK_MIST : QK_FLOOD,
			              SEC_COOLANT, QK_TYPE, -1, 0);
			return MLIP_E_RANGE;
		}
	}
	c->io.coolant_outlets = c->io.coolant == MLIP_IO_MODULE
	                            ? io->out_mapped & (MLIP_COOLANT_MIST | MLIP_COOLANT_FLOOD)
	                            : MLIP_COOLANT_MIST | MLIP_COOLANT_FLOOD;
	c->io.dout_mask = (io->out_mapped >> MLIP_OUT_DOUT0) & ((1u << MLIP_DOUT_MAX) - 1u);
	/* G38 runs with a probe input, or with the drives' touch probe (mlip-rt
	 * checks there are drives) */
	c->io.probe =
	    ((io->mapped >> MLIP_IN_PROBE) & 1u) || io->probe_source == MLIP_PROBE_SRC_DRIVE;
	return MLIP_OK;
}
