/*
 * expr.c - parameters and expressions as LinuxCNC documents them (G-code
 * overview: Parameters, Expressions, Binary Operators, Functions): a word's
 * value may be a number, a parameter (#12, #<name>, #[expr], ##2), an
 * expression in brackets or a unary function (SIN[30]); a line's settings
 * "#3 = value" take effect after every value on it has been read.
 *
 * Numbered #1..#5000 are the program's (0 before a setting; an MDI line
 * refuses that, since mlip keeps none between MDI lines); #5001.. are the
 * machine's state, read-only (the offsets, the position, the tool); named
 * ones are set first, else an error. The reader checks a whole program
 * before anything moves, so a value known only when it runs (a probe's
 * result, #5061..) is refused, not guessed. Fixed memory (struct
 * mlip_gcode_params), bounded recursion (MAX_DEPTH).
 */
#include <math.h>
#include <string.h>

#include "gc.h"
#include "mlip/text/number.h"

#define MAX_DEPTH 32
#define EQ_TOL    1e-6   /* LinuxCNC's TOLERANCE_EQUAL */
#define INT_TOL   0.0001 /* a number meant as an integer (a parameter's index) */

enum {
	OP_NONE,
	OP_POW,
	OP_MUL,
	OP_DIV,
	OP_MOD,
	OP_ADD,
	OP_SUB,
	OP_EQ,
	OP_NE,
	OP_GT,
	OP_GE,
	OP_LT,
	OP_LE,
	OP_AND,
	OP_OR,
	OP_XOR
};

struct px {
	struct mlip_gcode *g;
	const char *t;
	size_t n, i;
	uint32_t line;
	int depth;
	struct mlip_gcode_error *e;
};

static mlip_status fail(struct px *p, size_t at, mlip_status st, const char *fmt, const char *arg)
{
	return mlip_gc_fail(p->e, p->line, (uint32_t)at + 1, st, fmt, arg);
}

static void blanks(struct px *p)
{
	while (p->i < p->n && mlip_is_blank(p->t[p->i])) {
		p->i++;
	}
}

/* The letters at i (a function or an operator), upper case, in w[cap]. */
static size_t letters(const struct px *p, size_t i, char *w, size_t cap)
{
	size_t k = 0;
	while (i + k < p->n && mlip_is_alpha(p->t[i + k]) && k + 1 < cap) {
		w[k] = (char)mlip_upper(p->t[i + k]);
		k++;
	}
	w[k] = '\0';
	return k;
}

mlip_status mlip_gc_number(const char *t, size_t n, size_t j, int in_expr, uint32_t line, double *v,
                           size_t *end, struct mlip_gcode_error *e)
{
	struct mlip_number num;
	size_t k = mlip_number_lex(t, n, j, 0, &num);
	*v = mlip_number_value(&num);
	/* "1.2.3", "1e5", "--1", ".": the number runs on in number-like bytes (in
	 * an expression a sign after it is an operator) */
	if (num.ndig == 0 ||
	    (k < n && (t[k] == '.' || (!in_expr && (t[k] == '+' || t[k] == '-')))) ||
	    (k + 1 < n && (t[k] == 'e' || t[k] == 'E') &&
	     (mlip_is_digit(t[k + 1]) || t[k + 1] == '+' || t[k + 1] == '-'))) {
		while (k < n && (mlip_gc_starts_number(t[k]) || t[k] == 'e' || t[k] == 'E')) {
			k++;
		}
		return mlip_gc_fail(e, line, (uint32_t)j + 1, MLIP_E_SYNTAX,
		                    "malformed number '%t'", t + j, k - j);
	}
	*end = k;
	return MLIP_OK;
}

/* The unary functions, in the order function() switches on (EXISTS last). */
const char *const mlip_gc_functions[MLIP_GC_N_FUNCTIONS] = {"ABS", "ACOS", "ASIN", "ATAN",  "COS",
                                                            "EXP", "FIX",  "FUP",  "ROUND", "LN",
                                                            "SIN", "SQRT", "TAN",  "EXISTS"};

/* ---- the parameters --------------------------------------------------- */

/* "#<P a R am >": lower case, blanks removed, into name; i past the '>'. */
static mlip_status name_at(struct px *p, char *name)
{
	size_t at = p->i, k = 0;
	p->i++; /* '<' */
	while (p->i < p->n && p->t[p->i] != '>') {
		unsigned char c = (unsigned char)p->t[p->i++];
		if (mlip_is_blank(c)) {
			continue;
		}
		if (c < 0x21 || c > 0x7e || c == '<' || c == '#' || c == '[' || c == ']' ||
		    k + 1 >= MLIP_GCODE_NAME_LEN) {
			return fail(
			    p, at, MLIP_E_SYNTAX, "%s",
			    "a named parameter is #<name>: printable, at most 47 characters");
		}
		name[k++] = (char)(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
	}
	if (p->i >= p->n || k == 0) {
		return fail(p, at, MLIP_E_SYNTAX, "%s",
		            "a named parameter is #<name>: '>' missing");
	}
	p->i++;
	name[k] = '\0';
	return MLIP_OK;
}

static int axis_of(const struct mlip_gcode *g, int slot)
{
	return slot < 6 ? mlip_gc_axis_index(g->m, GC_AXES[slot]) : -1; /* U V W: none */
}

/* A machine-coordinate value of axis slot (X..W) in program units. */
static double units(const struct mlip_gcode *g, int i, double mm)
{
	return g->m->axis[i].kind == MLIP_AXIS_ROTARY || !g->inches ? mm : mm / MM_PER_INCH;
}

/* Position in the program's coordinates (#5420..), or the machine's. */
static double position(const struct mlip_gcode *g, int slot, int machine)
{
	int i = axis_of(g, slot);
	if (i < 0) {
		return 0.0;
	}
	return units(g, i, g->cur[i] - (machine ? 0.0 : mlip_gc_offset_of(g, i)));
}

/* #5001..#5602: the state mlip keeps, read-only. 0, or -1 not kept; -2
 * known only when the program runs. */
static int system_param(const struct mlip_gcode *g, long n, double *v)
{
	const struct mlip_gcode_offsets *o = &g->off;
	int slot, i;
	*v = 0.0;
	if (n >= 5061 && n <= 5070) {
		return -2; /* the last probe's result */
	}
	if (n == 5210) {
		*v = o->g92_on;
		return 0;
	}
	if (n == 5220) {
		*v = o->select + 1;
		return 0;
	}
	if (n == 5400) {
		*v = o->tool;
		return 0;
	}
	if ((n >= 5021 && n <= 5029) || (n >= 5420 && n <= 5428)) {
		*v = position(g, (int)(n % 10 - 1 + (n >= 5420 ? 1 : 0)), n < 5420);
		return 0;
	}
	if ((n >= 5161 && n <= 5169) || (n >= 5181 && n <= 5189) || (n >= 5211 && n <= 5219)) {
		slot = (int)(n % 10) - 1;
		i = axis_of(g, slot);
		if (i >= 0) {
			*v = units(g, i, n < 5180 ? o->g28[i] : n < 5200 ? o->g30[i] : o->g92[i]);
		}
		return 0;
	}
	if (n >= 5221 && n <= 5390 && (n - 5221) % 20 < 10) {
		slot = (int)((n - 5221) % 20);
		i = slot < 9 ? axis_of(g, slot) : -1; /* R (rotation): 0, mlip has none */
		if (i >= 0) {
			*v = units(g, i, o->coord[(n - 5221) / 20][i]);
		}
		return 0;
	}
	return -1;
}

static const struct {
	const char *name;
	int code;
} predefined[] = {
    {"_x", 0},
    {"_y", 1},
    {"_z", 2},
    {"_a", 3},
    {"_b", 4},
    {"_c", 5},
    {"_u", 6},
    {"_v", 7},
    {"_w", 8},
    {"_abs_x", 10},
    {"_abs_y", 11},
    {"_abs_z", 12},
    {"_abs_a", 13},
    {"_abs_b", 14},
    {"_abs_c", 15},
    {"_abs_u", 16},
    {"_abs_v", 17},
    {"_abs_w", 18},
    {"_metric", 20},
    {"_imperial", 21},
    {"_absolute", 22},
    {"_incremental", 23},
    {"_inverse_time", 24},
    {"_units_per_minute", 25},
    {"_units_per_rev", 26},
    {"_coord_system", 27},
    {"_tool_offset", 28},
    {"_retract_r_plane", 29},
    {"_retract_old_z", 30},
    {"_feed", 31},
    {"_rpm", 32},
    {"_current_tool", 33},
    {"_selected_tool", 34},
    {"_line", 35},
    {"_motion_mode", 36},
    {"_plane", 37},
    {"_ccomp", 38},
    {"_spindle_on", 39},
    {"_spindle_cw", 40},
    {"_mist", 41},
    {"_flood", 42},
    {"_ijk_absolute_mode", 43},
    {"_spindle_rpm_mode", 44},
    {"_spindle_css_mode", 45},
};

static int find_predefined(const char *name)
{
	for (size_t k = 0; k < sizeof predefined / sizeof predefined[0]; k++) {
		if (strcmp(name, predefined[k].name) == 0) {
			return predefined[k].code;
		}
	}
	return -1;
}

static double predefined_value(const struct mlip_gcode *g, int code, uint32_t line)
{
	static const int coord_code[] = {540, 550, 560, 570, 580, 590, 591, 592, 593};
	if (code < 20) {
		return position(g, code % 10, code >= 10);
	}
	switch (code) {
	case 20:
		return !g->inches;
	case 21:
		return g->inches;
	case 22:
		return g->absolute;
	case 23:
		return !g->absolute;
	case 24:
		return g->inverse_time;
	case 25:
		return !g->inverse_time;
	case 27:
		return coord_code[g->off.select];
	case 28:
		return g->tlo_mode != 490;
	case 29:
		return !g->retract_r;
	case 30:
		return g->retract_r;
	case 31:
		return g->feed_word > 0 ? g->feed_word : 0.0;
	case 32:
		return g->s_rpm > 0 ? g->s_rpm : 0.0;
	case 33:
		return g->off.tool;
	case 34:
		return g->tool_sel;
	case 35:
		return line;
	case 36:
		return g->cycle ? g->cycle * 10 : g->motion < 0 ? 800 : g->motion * 10;
	case 37:
		return g->plane * 10;
	case 38:
		return 400;
	case 39:
		return g->spindle != 0;
	case 40:
		return g->spindle == 3;
	case 41:
		return (g->coolant & MLIP_COOLANT_MIST) != 0;
	case 42:
		return (g->coolant & MLIP_COOLANT_FLOOD) != 0;
	case 44:
		return 1; /* G97 */
	default:
		return 0; /* G95, G90.1, G96: mlip has none */
	}
}

static int find_named(const struct mlip_gcode_params *pa, const char *name)
{
	for (uint32_t k = 0; k < pa->n_named; k++) {
		if (strcmp(pa->named[k].name, name) == 0) {
			return (int)k;
		}
	}
	return -1;
}

static mlip_status value(struct px *p, double *v);

/* The index after '#' (a real value meant as an integer) into *idx. */
static mlip_status index_at(struct px *p, long *idx)
{
	size_t at = p->i;
	double x;
	mlip_status st = value(p, &x);
	if (st != MLIP_OK) {
		return st;
	}
	if (!(fabs(x - floor(x + 0.5)) <= INT_TOL) || x < 1 || x > MLIP_GCODE_PARAM_MAX) {
		return fail(p, at, MLIP_E_RANGE, "a parameter's number is a whole number 1..%s",
		            "5602");
	}
	*idx = (long)floor(x + 0.5);
	return MLIP_OK;
}

/* '#' at p->i: a parameter's value. */
static mlip_status param(struct px *p, double *v)
{
	struct mlip_gcode_params *pa = &p->g->params;
	char name[MLIP_GCODE_NAME_LEN];
	size_t at = p->i;
	long n;
	mlip_status st;
	p->i++;
	blanks(p);
	if (p->i < p->n && p->t[p->i] == '<') {
		if ((st = name_at(p, name)) != MLIP_OK) {
			return st;
		}
		int code = find_predefined(name), k = find_named(pa, name);
		if (code >= 0) {
			*v = predefined_value(p->g, code, p->line);
			return MLIP_OK;
		}
		if (k < 0) {
			return fail(p, at, MLIP_E_RANGE,
			            "named parameter #<%s> is not set (LinuxCNC refuses it too)",
			            name);
		}
		*v = pa->named[k].value;
		return MLIP_OK;
	}
	if ((st = index_at(p, &n)) != MLIP_OK) {
		return st;
	}
	if (n <= MLIP_GCODE_PARAMS) {
		if (!pa->set[n] && p->g->mdi) {
			return mlip_gc_fail(p->e, p->line, (uint32_t)at + 1, MLIP_E_RANGE,
			                    "#%u is not set on this line: mlip keeps no parameters "
			                    "between MDI lines",
			                    (unsigned)n);
		}
		if (!pa->set[n]) {
			mlip_gc_notice_text(
			    p->g, "#",
			    "(a numbered parameter) read before any setting reads 0, "
			    "as LinuxCNC's",
			    p->line);
		}
		*v = pa->num[n];
		return MLIP_OK;
	}
	int r = system_param(p->g, n, v);
	if (r != 0) {
		return mlip_gc_fail(p->e, p->line, (uint32_t)at + 1, MLIP_E_UNSUPPORTED,
		                    r == -2
		                        ? "#%u: a probe's result is known only when the program "
		                          "runs; mlip checks the whole program before it moves"
		                        : "#%u is not a parameter mlip keeps",
		                    (unsigned)n);
	}
	return MLIP_OK;
}

/* ---- expressions ------------------------------------------------------ */

static int op_at(struct px *p, int *prec, size_t *len)
{
	static const struct {
		const char *w;
		int op, prec;
	} words[] = {{"MOD", OP_MOD, 4}, {"EQ", OP_EQ, 2},  {"NE", OP_NE, 2}, {"GT", OP_GT, 2},
	             {"GE", OP_GE, 2},   {"LT", OP_LT, 2},  {"LE", OP_LE, 2}, {"AND", OP_AND, 1},
	             {"OR", OP_OR, 1},   {"XOR", OP_XOR, 1}};
	char w[8];
	char c = p->i < p->n ? p->t[p->i] : '\0';
	*len = 1;
	if (c == '*' && p->i + 1 < p->n && p->t[p->i + 1] == '*') {
		*len = 2;
		*prec = 5;
		return OP_POW;
	}
	*prec = c == '*' || c == '/' ? 4 : 3;
	if (c == '*' || c == '/' || c == '+' || c == '-') {
		return c == '*' ? OP_MUL : c == '/' ? OP_DIV : c == '+' ? OP_ADD : OP_SUB;
	}
	*len = letters(p, p->i, w, sizeof w);
	for (size_t k = 0; k < sizeof words / sizeof words[0]; k++) {
		if (strcmp(w, words[k].w) == 0) {
			*prec = words[k].prec;
			return words[k].op;
		}
	}
	return OP_NONE;
}

static mlip_status apply(struct px *p, size_t at, int op, double *l, double r)
{
	double x = *l;
	switch (op) {
	case OP_POW:
		if (x < 0 && r != floor(r)) {
			return fail(p, at, MLIP_E_RANGE, "%s",
			            "a negative number to a non-integer power");
		}
		x = pow(x, r);
		break;
	case OP_MUL:
		x *= r;
		break;
	case OP_DIV:
	case OP_MOD:
		if (r == 0.0) {
			return fail(p, at, MLIP_E_RANGE, "%s", "division by zero");
		}
		x = op == OP_DIV ? x / r : fmod(x, r);
		x += op == OP_MOD && x < 0.0 ? fabs(r) : 0.0; /* LinuxCNC: 0 <= x < |r| */
		break;
	case OP_ADD:
		x += r;
		break;
	case OP_SUB:
		x -= r;
		break;
	case OP_EQ:
		x = fabs(x - r) < EQ_TOL;
		break;
	case OP_NE:
		x = !(fabs(x - r) < EQ_TOL);
		break;
	case OP_GT:
		x = x > r;
		break;
	case OP_GE:
		x = x >= r;
		break;
	case OP_LT:
		x = x < r;
		break;
	case OP_LE:
		x = x <= r;
		break;
	case OP_AND:
		x = x != 0.0 && r != 0.0;
		break;
	case OP_OR:
		x = x != 0.0 || r != 0.0;
		break;
	default:
		x = (x != 0.0) != (r != 0.0);
		break; /* XOR */
	}
	if (!isfinite(x)) {
		return fail(p, at, MLIP_E_RANGE, "%s", "the expression's value is not finite");
	}
	*l = x;
	return MLIP_OK;
}

/* Operators at precedence prec and above, after the value in *v. */
static mlip_status binary(struct px *p, int min_prec, double *v)
{
	for (;;) {
		int prec;
		size_t len, at;
		blanks(p);
		at = p->i;
		int op = op_at(p, &prec, &len);
		if (op == OP_NONE || prec < min_prec) {
			return MLIP_OK;
		}
		p->i += len;
		double r;
		mlip_status st = value(p, &r);
		if (st == MLIP_OK) {
			st = binary(p, prec + 1, &r); /* left to right within a precedence */
		}
		if (st == MLIP_OK) {
			st = apply(p, at, op, v, r);
		}
		if (st != MLIP_OK) {
			return st;
		}
	}
}

/* '[' at p->i: the bracketed expression. */
static mlip_status bracket(struct px *p, double *v)
{
	size_t at = p->i;
	mlip_status st;
	p->i++;
	if ((st = value(p, v)) != MLIP_OK || (st = binary(p, 1, v)) != MLIP_OK) {
		return st;
	}
	blanks(p);
	if (p->i >= p->n || p->t[p->i] != ']') {
		return fail(p, p->i < p->n ? p->i : at, MLIP_E_SYNTAX, "%s",
		            "the expression has no closing ']' here (or an unknown operator)");
	}
	p->i++;
	return MLIP_OK;
}

static mlip_status function(struct px *p, double *v)
{
	const char *const *names = mlip_gc_functions;
	char w[16];
	size_t at = p->i, k;
	mlip_status st;
	p->i += letters(p, p->i, w, sizeof w);
	for (k = 0; k < MLIP_GC_N_FUNCTIONS && strcmp(w, names[k]) != 0; k++) {
	}
	blanks(p);
	if (k == MLIP_GC_N_FUNCTIONS || p->i >= p->n || p->t[p->i] != '[') {
		return fail(p, at, MLIP_E_SYNTAX, "unknown function or word '%s'", w);
	}
	if (k == 13) { /* EXISTS[#<name>] */
		char name[MLIP_GCODE_NAME_LEN];
		p->i++;
		blanks(p);
		if (p->i + 1 >= p->n || p->t[p->i] != '#' || p->t[p->i + 1] != '<') {
			return fail(p, p->i, MLIP_E_SYNTAX, "%s",
			            "EXISTS takes one named parameter");
		}
		p->i++;
		if ((st = name_at(p, name)) != MLIP_OK) {
			return st;
		}
		blanks(p);
		if (p->i >= p->n || p->t[p->i] != ']') {
			return fail(p, p->i, MLIP_E_SYNTAX, "%s",
			            "EXISTS takes one named parameter");
		}
		p->i++;
		*v = find_predefined(name) >= 0 || find_named(&p->g->params, name) >= 0;
		return MLIP_OK;
	}
	if ((st = bracket(p, v)) != MLIP_OK) {
		return st;
	}
	double x = *v, y, d = PI / 180.0;
	switch (k) {
	case 0:
		x = fabs(x);
		break;
	case 1:
	case 2:
		if (x < -1.0 || x > 1.0) {
			return fail(p, at, MLIP_E_RANGE, "the argument of %s is outside -1..1", w);
		}
		x = (k == 1 ? acos(x) : asin(x)) / d;
		break;
	case 3: /* ATAN[y]/[x]: four quadrants, degrees */
		blanks(p);
		if (p->i >= p->n || p->t[p->i] != '/') {
			return fail(p, p->i, MLIP_E_SYNTAX, "%s", "ATAN is ATAN[y]/[x]");
		}
		p->i++;
		blanks(p);
		if (p->i >= p->n || p->t[p->i] != '[') {
			return fail(p, p->i, MLIP_E_SYNTAX, "%s", "ATAN is ATAN[y]/[x]");
		}
		if ((st = bracket(p, &y)) != MLIP_OK) {
			return st;
		}
		x = atan2(x, y) / d;
		break;
	case 4:
		x = cos(x * d);
		break;
	case 5:
		x = exp(x);
		break;
	case 6:
		x = floor(x);
		break;
	case 7:
		x = ceil(x);
		break;
	case 8:
		x = x < 0.0 ? ceil(x - 0.5) : floor(x + 0.5);
		break; /* half away from 0 */
	case 9:
		if (x <= 0.0) {
			return fail(p, at, MLIP_E_RANGE, "%s", "LN of a number not above 0");
		}
		x = log(x);
		break;
	case 10:
		x = sin(x * d);
		break;
	case 11:
		if (x < 0.0) {
			return fail(p, at, MLIP_E_RANGE, "%s", "SQRT of a negative number");
		}
		x = sqrt(x);
		break;
	default:
		x = tan(x * d);
		break;
	}
	if (!isfinite(x)) {
		return fail(p, at, MLIP_E_RANGE, "%s", "the expression's value is not finite");
	}
	*v = x;
	return MLIP_OK;
}

/* A real value at p->i: a number, #parameter, [expression], a unary
 * function, or a sign before one of those. */
static mlip_status value(struct px *p, double *v)
{
	mlip_status st;
	size_t at;
	blanks(p);
	at = p->i;
	if (p->i >= p->n) {
		return fail(p, p->n, MLIP_E_SYNTAX, "%s",
		            "a value is missing at the end of the line");
	}
	if (++p->depth > MAX_DEPTH) {
		return fail(p, at, MLIP_E_SYNTAX, "%s", "expression nested too deep (32 levels)");
	}
	char c = p->t[p->i], c1 = p->i + 1 < p->n ? p->t[p->i + 1] : '\0';
	if (c == '[') {
		st = bracket(p, v);
	} else if (c == '#') {
		st = param(p, v);
	} else if ((c == '+' || c == '-') && !mlip_is_digit(c1) && c1 != '.') {
		p->i++;
		st = value(p, v);
		*v = c == '-' ? -*v : *v;
	} else if (mlip_is_alpha(c)) {
		st = function(p, v);
	} else if (mlip_gc_starts_number(c)) {
		st = mlip_gc_number(p->t, p->n, p->i, 1, p->line, v, &p->i, p->e);
	} else {
		st = fail(p, at, MLIP_E_SYNTAX, "%s",
		          "a number, #parameter or [expression] expected");
	}
	p->depth--;
	return st;
}

/* ---- the lexer's entries ---------------------------------------------- */

mlip_status mlip_gc_real_value(struct mlip_gcode *g, const char *t, size_t n, size_t *pi,
                               uint32_t line, double *v, struct mlip_gcode_error *e)
{
	struct px p = {g, t, n, *pi, line, 0, e};
	if (g == NULL) {
		return mlip_gc_fail(e, line, (uint32_t)*pi + 1, MLIP_E_UNSUPPORTED,
		                    "parameters and expressions (# [ ]) not in a Grbl jog");
	}
	mlip_status st = value(&p, v);
	*pi = p.i;
	return st;
}

mlip_status mlip_gc_setting(struct mlip_gcode *g, const char *t, size_t n, size_t *pi,
                            uint32_t line, struct lexed *lx, struct mlip_gcode_error *e)
{
	struct px p = {g, t, n, *pi, line, 0, e};
	struct gc_setting *s = &lx->set[lx->n_set];
	mlip_status st;
	size_t at = p.i;
	if (g == NULL) {
		return mlip_gc_fail(e, line, (uint32_t)at + 1, MLIP_E_UNSUPPORTED,
		                    "parameters and expressions (# [ ]) not in a Grbl jog");
	}
	if (lx->n_set >= MAX_SETTINGS) {
		return fail(&p, at, MLIP_E_SYNTAX, "%s", "too many parameter settings on a line");
	}
	memset(s, 0, sizeof *s);
	s->col = (uint32_t)at + 1;
	p.i++;
	blanks(&p);
	if (p.i < n && t[p.i] == '<') {
		if ((st = name_at(&p, s->name)) != MLIP_OK) {
			return st;
		}
		if (find_predefined(s->name) >= 0) {
			return fail(&p, at, MLIP_E_RANGE,
			            "#<%s> is read-only (the machine's state)", s->name);
		}
	} else {
		long idx;
		if ((st = index_at(&p, &idx)) != MLIP_OK) {
			return st;
		}
		if (idx > MLIP_GCODE_PARAMS) {
			return mlip_gc_fail(
			    e, line, (uint32_t)at + 1, MLIP_E_RANGE,
			    "#%u is read-only here (the machine's state: G10 L2 sets a "
			    "work offset, G28.1/G30.1 a stored position)",
			    (unsigned)idx);
		}
		s->num = (int)idx;
	}
	blanks(&p);
	if (p.i >= n || t[p.i] != '=') {
		return fail(&p, p.i < n ? p.i : at, MLIP_E_SYNTAX, "%s",
		            "a parameter on its own is a setting: #1 = value");
	}
	p.i++;
	if ((st = value(&p, &s->value)) != MLIP_OK) {
		return st;
	}
	lx->n_set++;
	*pi = p.i;
	return MLIP_OK;
}

mlip_status mlip_gc_apply_settings(struct mlip_gcode *g, const struct lexed *lx, uint32_t line,
                                   struct mlip_gcode_error *e)
{
	struct mlip_gcode_params *pa = &g->params;
	for (int k = 0; k < lx->n_set; k++) {
		const struct gc_setting *s = &lx->set[k];
		if (s->num > 0) {
			pa->num[s->num] = s->value;
			pa->set[s->num] = 1;
			continue;
		}
		int i = find_named(pa, s->name);
		if (i < 0 && pa->n_named >= MLIP_GCODE_NAMED) {
			return mlip_gc_fail(
			    e, line, s->col, MLIP_E_RANGE,
			    "more than %u named parameters: mlip keeps at most that many",
			    (unsigned)MLIP_GCODE_NAMED);
		}
		if (i < 0) {
			i = (int)pa->n_named++;
			memcpy(pa->named[i].name, s->name, sizeof s->name);
		}
		pa->named[i].value = s->value;
	}
	return MLIP_OK;
}
