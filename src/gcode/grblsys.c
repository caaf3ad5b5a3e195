/*
 * grblsys.c - Grbl's system lines ('$' first): not G-code. A jog "$J=" runs as
 * a G1 move (skipping it would change the path); the others are notices
 * naming what mlip does instead, or errors in strict mode (Grbl 1.1's
 * interface: "$" commands, "$J=" jogging).
 */
#include <string.h>

#include "gc.h"

/* Grbl's jog "$J=" + words at t[j..len): a G1 move at its own F, with G20/
 * G21, G90/G91 and G53 for that move only; the modal state stays as it was
 * (Grbl 1.1). Errors name columns of the original line. */
static mlip_status jog_line(struct mlip_gcode *g, const char *t, size_t len, size_t j,
                            uint32_t line, mlip_block_sink sink, void *ctx,
                            struct mlip_gcode_error *e)
{
	struct lexed lx;
	struct mlip_gcode saved;
	char buf[MLIP_GCODE_MAX_LINE + 4];
	mlip_status st;
	int k, c, has_f = 0, g53 = 0, g91 = 0;

	st = mlip_gc_lex_line(NULL, t + j, len - j, 0, &lx, e);
	if (st != MLIP_OK) {
		e->col += e->col ? (uint32_t)j : 0;
		e->line = line;
		return st;
	}
	for (k = 0; k < lx.n; k++) {
		c = mlip_gc_code_of(lx.w[k].value);
		has_f |= lx.w[k].letter == 'F';
		g53 |= lx.w[k].letter == 'G' && c == 530;
		g91 |= lx.w[k].letter == 'G' && c == 910;
		/* N (a line number) is valid in a jog: Grbl 1.1 jogging.md */
		if (!(mlip_gc_axis_slot(lx.w[k].letter) >= 0 || lx.w[k].letter == 'F' ||
		      lx.w[k].letter == 'N' ||
		      (lx.w[k].letter == 'G' &&
		       (c == 200 || c == 210 || c == 900 || c == 910 || c == 530)))) {
			return mlip_gc_fail(
			    e, line, lx.w[k].col + (uint32_t)j, MLIP_E_UNSUPPORTED,
			    "Grbl jog: only G20, G21, G90, G91, G53, axis words, F and N");
		}
	}
	if (!has_f) {
		return mlip_gc_fail(
		    e, line, (uint32_t)j - 2, MLIP_E_SYNTAX,
		    "Grbl jog without F: a jog gives its own feed, e.g. $J=G91 X10 F600");
	}
	memcpy(buf, "G1 ", 3);
	memcpy(buf + 3, t + j, len - j);
	saved = *g;
	g->motion = 1;
	g->inverse_time = 0;
	if (g53 && !g91) {
		g->absolute = 1; /* a G53 jog is in machine coordinates, whatever
		                    the program's G90/G91 (Grbl 1.1's jogging) */
	}
	st = mlip_gcode_line(g, buf, len - j + 3, line, sink, ctx, e);
	if (st != MLIP_OK && e->col) {
		e->col = e->col > 3 ? e->col - 3 + (uint32_t)j : (uint32_t)j - 2;
	}
	g->motion = saved.motion;
	g->absolute = saved.absolute;
	g->inches = saved.inches;
	g->inverse_time = saved.inverse_time;
	g->feed_mm_s = saved.feed_mm_s;
	g->feed_word = saved.feed_word;
	g->feed_reset = saved.feed_reset;
	if (st == MLIP_OK) {
		mlip_gc_notice(g, "$J", line);
	}
	return st;
}

/* Grbl system lines ('$' first): not G-code. Each kind is a notice naming
 * what mlip does instead, or an error in strict mode; a jog runs as a G1
 * move (skipping it would change the path). */
mlip_status mlip_gc_system_line(struct mlip_gcode *g, const char *t, size_t len, size_t i0,
                                uint32_t line, mlip_block_sink sink, void *ctx,
                                struct mlip_gcode_error *e)
{
	static const char *const cmds[] = {"$H", "$X", "$C",   "$G",   "$I", "$N",
	                                   "$$", "$#", "$SLP", "$RST", "$"};
	char word[8];
	size_t i, n, k;

	for (i = i0; i < len; i++) {
		unsigned char c = (unsigned char)t[i];

		if ((c < 0x20 && c != '\t') || c >= 0x7f) {
			return mlip_gc_fail(e, line, (uint32_t)i + 1, MLIP_E_SYNTAX,
			                    "unexpected character %b in a Grbl system line", c);
		}
	}
	while (len > i0 && mlip_is_blank(t[len - 1])) {
		len--;
	}
	n = len - i0;
	if (n >= 3 && mlip_upper(t[i0 + 1]) == 'J' && t[i0 + 2] == '=') {
		if (g->strict) {
			return mlip_gc_fail(
			    e, line, (uint32_t)i0 + 1, MLIP_E_UNSUPPORTED,
			    "Grbl jog '%t' is not G-code (strict mode): write it as G1", t + i0, n);
		}
		return jog_line(g, t, len, i0 + 3, line, sink, ctx, e);
	}
	/* the command: '$', then digits up to '=' (a setting), or letters/$/# */
	word[0] = '$';
	k = 1;
	i = i0 + 1;
	if (i < len && mlip_is_digit(t[i])) {
		while (i < len && mlip_is_digit(t[i]) && k < 5) {
			word[k++] = t[i++];
		}
		if (i < len && t[i] == '=') {
			word[k++] = '=';
			i = len;
		}
	} else if (i < len && (t[i] == '$' || t[i] == '#')) {
		word[k++] = t[i++];
	} else {
		while (i < len && mlip_is_alpha(t[i]) && k < 5) {
			word[k++] = mlip_upper(t[i++]);
		}
		while (k == 2 && word[1] == 'N' && i < len && mlip_is_digit(t[i])) {
			i++; /* $N0=..., $N1=...: startup blocks */
		}
		if (i < len && t[i] == '=') {
			i = len; /* $N0=..., $RST=..., $I=...: the value is Grbl's */
		}
	}
	word[k] = '\0';
	for (k = 0; k < sizeof cmds / sizeof cmds[0]; k++) {
		if (strcmp(word, cmds[k]) == 0 ||
		    (k == 10 && word[1] && word[strlen(word) - 1] == '=')) {
			break;
		}
	}
	if (i != len || k == sizeof cmds / sizeof cmds[0]) {
		return mlip_gc_fail(e, line, (uint32_t)i0 + 1, MLIP_E_SYNTAX,
		                    "unknown Grbl system command '%t'", t + i0, n);
	}
	if (g->strict) {
		return mlip_gc_fail(e, line, (uint32_t)i0 + 1, MLIP_E_UNSUPPORTED,
		                    "Grbl system line '%t' is not G-code (strict mode): delete it",
		                    t + i0, n);
	}
	mlip_gc_notice(g, word, line);
	return MLIP_OK;
}
