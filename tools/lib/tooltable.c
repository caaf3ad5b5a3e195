/* tooltable.c - see tooltable.h */
#include "tooltable.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "offsets.h" /* mlip_offsets_number */

static const char *const header[] = {
    "mlip tool table (LinuxCNC's format): T tool, P pocket, Z length offset (G43),",
    "D diameter, in mm; the comment after ';' is shown when the tool is asked for.",
    "Each T and each P once. After a hand edit run `mlip-tools --accept FILE`: it",
    "checks every line, shows the tools and seals the file (its last line).", NULL};

/* One tool line as read: its values, the comment, and where a bad word
 * starts (offset in the value) for the message's column. */
struct parsed {
	int32_t number, pocket;
	double z, d;
	const char *comment; /* into the value; ends at the value's end */
	size_t comment_len;
};

/* A whole number 0..max in s[0..n): 0, or -1. */
static int whole(const char *s, size_t n, int64_t max, int64_t *out)
{
	int64_t v = 0;
	size_t i;

	if (n == 0 || (n > 1 && s[0] == '0')) {
		return -1;
	}
	for (i = 0; i < n; i++) {
		if (!isdigit((unsigned char)s[i])) {
			return -1;
		}
		v = v * 10 + (s[i] - '0');
		if (v > max) {
			return -1;
		}
	}
	*out = v;
	return 0;
}

/* A strict decimal in s[0..n): [+-] digits [. digits] [e [+-] digits]. */
static int number(const char *s, size_t n, double *out)
{
	char buf[64], *end = NULL;
	size_t i = 0, digits = 0;

	if (n == 0 || n >= sizeof buf) {
		return -1;
	}
	memcpy(buf, s, n);
	buf[n] = '\0';
	if (buf[i] == '+' || buf[i] == '-') {
		i++;
	}
	for (; isdigit((unsigned char)buf[i]); i++) {
		digits++;
	}
	if (buf[i] == '.') {
		for (i++; isdigit((unsigned char)buf[i]); i++) {
			digits++;
		}
	}
	if (digits == 0) {
		return -1;
	}
	if (buf[i] == 'e' || buf[i] == 'E') {
		i++;
		if (buf[i] == '+' || buf[i] == '-') {
			i++;
		}
		if (!isdigit((unsigned char)buf[i])) {
			return -1;
		}
		while (isdigit((unsigned char)buf[i])) {
			i++;
		}
	}
	if (buf[i] != '\0') {
		return -1;
	}
	errno = 0;
	*out = strtod(buf, &end);
	return errno == 0 && isfinite(*out) ? 0 : -1;
}

static int say(char *why, size_t len, size_t *at, size_t where, const char *fmt, const char *w,
               size_t wn)
{
	char word[48];

	snprintf(word, sizeof word, "%.*s%s", (int)(wn > 40 ? 40 : wn), w, wn > 40 ? "..." : "");
	snprintf(why, len, fmt, word);
	*at = where;
	return -1;
}

/* key "T<n>", value "P1 Z12.5 D6 ;comment". 0, or -1 with why and *at: the
 * offset in the value of the word at fault ((size_t)-1: the key). */
static int parse(const char *key, const char *value, struct parsed *p, size_t *at, char *why,
                 size_t len)
{
	const char *v = value, *semi = strchr(value, ';');
	size_t end = semi ? (size_t)(semi - value) : strlen(value), i = 0;
	unsigned seen = 0;
	int64_t x;

	memset(p, 0, sizeof *p);
	if ((key[0] != 'T' && key[0] != 't') ||
	    whole(key + 1, strlen(key + 1), 2147483647, &x) != 0 || x == 0) {
		return say(why, len, at, (size_t)-1,
		           "'%s': a line starts with the tool, T and a whole number >= 1 without "
		           "leading zeros (e.g. T2)",
		           key, strlen(key));
	}
	p->number = (int32_t)x;
	while (i < end) {
		size_t w0, wn;
		char L;
		double num;
		while (i < end && (v[i] == ' ' || v[i] == '\t')) {
			i++;
		}
		if (i == end) {
			break;
		}
		w0 = i;
		while (i < end && v[i] != ' ' && v[i] != '\t') {
			i++;
		}
		wn = i - w0;
		L = (char)toupper((unsigned char)v[w0]);
		if (!strchr("PXYZABCUVWDIJQ", L) || !isalpha((unsigned char)v[w0])) {
			return say(why, len, at, w0,
			           "'%s': not a column of a tool line (P pocket, Z length, D "
			           "diameter; a comment after ';')",
			           v + w0, wn);
		}
		if (seen & (1u << (L - 'A'))) {
			return say(why, len, at, w0, "'%s': that column a second time", v + w0, wn);
		}
		seen |= 1u << (L - 'A');
		if (L == 'P') {
			if (whole(v + w0 + 1, wn - 1, MLIP_TOOLS_POCKETS, &x) != 0) {
				return say(
				    why, len, at, w0,
				    "'%s': the pocket is a whole number 0..1000 without leading "
				    "zeros",
				    v + w0, wn);
			}
			p->pocket = (int32_t)x;
			continue;
		}
		if (number(v + w0 + 1, wn - 1, &num) != 0 || fabs(num) > MLIP_TOOLS_ABS_MAX) {
			return say(
			    why, len, at, w0,
			    "'%s': not a number (a sign, digits, a point, an exponent; mm, at "
			    "most 10000)",
			    v + w0, wn);
		}
		if (L == 'Z') {
			p->z = num;
		} else if (L == 'D') {
			if (num < 0) {
				return say(why, len, at, w0, "'%s': a diameter is >= 0", v + w0,
				           wn);
			}
			p->d = num;
		} else if (num != 0) {
			return say(
			    why, len, at, w0,
			    "'%s': mlip offsets a tool along Z only (its length, G43): a "
			    "value in this column would not be applied; make it 0 or delete it",
			    v + w0, wn);
		}
	}
	if (!(seen & (1u << ('P' - 'A')))) {
		return say(why, len, at, end,
		           "%s: no P (pocket) column: every tool line has one (LinuxCNC), e.g. "
		           "T2 P2 Z30",
		           key, strlen(key));
	}
	if (semi != NULL) {
		const char *c = semi + 1;
		size_t n = strlen(c);
		while (n > 0 && (*c == ' ' || *c == '\t')) {
			c++, n--;
		}
		while (n > 0 && (c[n - 1] == ' ' || c[n - 1] == '\t')) {
			n--;
		}
		p->comment = c;
		p->comment_len = n;
	}
	return 0;
}

static void canon_text(const struct parsed *p, char *out, size_t len)
{
	char z[40], d[40];
	size_t n;

	mlip_offsets_number(p->z, z, sizeof z);
	mlip_offsets_number(p->d, d, sizeof d);
	n = (size_t)snprintf(out, len, "P%d", (int)p->pocket);
	if (p->z != 0 && n < len) {
		n += (size_t)snprintf(out + n, len - n, " Z%s", z);
	}
	if (p->d != 0 && n < len) {
		n += (size_t)snprintf(out + n, len - n, " D%s", d);
	}
	if (p->comment_len > 0 && n < len) {
		snprintf(out + n, len - n, " ;%.*s", (int)p->comment_len, p->comment);
	}
}

/* statefile.h's canon: one tool line. */
static int canon(const void *ctx, const char *key, const char *value, char *out, size_t out_len,
                 char *why, size_t why_len)
{
	struct parsed p;
	size_t at;

	(void)ctx;
	if (parse(key, value, &p, &at, why, why_len) != 0) {
		return -1;
	}
	canon_text(&p, out, out_len);
	return 0;
}

void mlip_tooltable_kind(struct mlip_sf_kind *k)
{
	memset(k, 0, sizeof(*k));
	k->what = "tool table";
	k->comment = ';';
	k->accept = "mlip-tools --accept";
	k->repair = "measure the tools again and write their lines (T P Z D ;comment), or "
	            "restore the file from a backup";
	k->required = NULL;
	k->header = header;
	k->canon = canon;
	k->ctx = NULL;
}

/* The lines of the file as written, for the column of an error and the
 * duplicates (statefile.c then checks the bytes, the seal and the rest):
 * 0, or -1 with why = "FILE:LINE:COL: ...". A file it cannot read is left
 * to mlip_sf_load's message. */
static int prescan(const char *path, char *why, size_t len)
{
	char buf[MLIP_SF_MAX_LINE + 2];
	int32_t *num = NULL, *pocket = NULL;
	uint32_t *at = NULL, n = 0, line = 0;
	int rc = 0;
	FILE *f = fopen(path, "r");

	if (f == NULL) {
		return 0;
	}
	num = malloc(sizeof *num * MLIP_TOOLS_MAX);
	pocket = malloc(sizeof *pocket * MLIP_TOOLS_MAX);
	at = malloc(sizeof *at * MLIP_TOOLS_MAX);
	while (rc == 0 && num && pocket && at && fgets(buf, sizeof buf, f) != NULL) {
		char key[MLIP_SF_KEY], what[MLIP_SF_WHY / 2];
		size_t i = 0, k0, kn, v0, off;
		struct parsed p;
		line++;
		buf[strcspn(buf, "\r\n")] = '\0';
		while (buf[i] == ' ' || buf[i] == '\t') {
			i++;
		}
		if (buf[i] == '\0' || buf[i] == ';') {
			continue;
		}
		k0 = i;
		while (buf[i] && buf[i] != ' ' && buf[i] != '\t') {
			i++;
		}
		kn = i - k0;
		while (buf[i] == ' ' || buf[i] == '\t') {
			i++;
		}
		v0 = i;
		snprintf(key, sizeof key, "%.*s", (int)(kn < sizeof key ? kn : sizeof key - 1),
		         buf + k0);
		if (parse(key, buf + v0, &p, &off, what, sizeof what) != 0) {
			snprintf(why, len, "%s:%u:%u: %s; then mlip-tools --accept %s", path,
			         (unsigned)line,
			         (unsigned)(off == (size_t)-1 ? k0 + 1 : v0 + off + 1), what, path);
			rc = -1;
			break;
		}
		for (uint32_t j = 0; j < n; j++) {
			if (num[j] == p.number || pocket[j] == p.pocket) {
				snprintf(
				    why, len,
				    "%s:%u:%u: %s %d a second time (first on line %u): each tool "
				    "and each pocket once; then mlip-tools --accept %s",
				    path, (unsigned)line,
				    (unsigned)(num[j] == p.number
				                   ? k0 + 1
				                   : v0 + strcspn(buf + v0, "Pp") + 1),
				    num[j] == p.number ? "tool" : "pocket",
				    (int)(num[j] == p.number ? p.number : p.pocket),
				    (unsigned)at[j], path);
				rc = -1;
				break;
			}
		}
		if (rc == 0 && n == MLIP_TOOLS_MAX) {
			snprintf(why, len, "%s:%u:1: more than %d tools", path, (unsigned)line,
			         MLIP_TOOLS_MAX);
			rc = -1;
		}
		if (rc == 0) {
			num[n] = p.number;
			pocket[n] = p.pocket;
			at[n++] = line;
		}
	}
	if (rc == 0 && (!num || !pocket || !at)) {
		snprintf(why, len, "%s: %s", path, strerror(ENOMEM));
		rc = -1;
	}
	free(num);
	free(pocket);
	free(at);
	fclose(f);
	return rc;
}

static int by_number(const void *a, const void *b)
{
	const struct mlip_tool *x = a, *y = b;

	return (x->number > y->number) - (x->number < y->number);
}

int mlip_tooltable_load(struct mlip_tooltable *t, const char *path, unsigned flags,
                        const char *prog, FILE *err)
{
	struct mlip_sf_kind k;
	struct mlip_sf sf;
	char why[MLIP_SF_WHY];
	int rc;

	memset(t, 0, sizeof *t);
	t->path = path;
	mlip_tooltable_kind(&k);
	if (prescan(path, why, sizeof why) != 0) {
		fprintf(err, "%s: error: %s\n", prog, why);
		return -1;
	}
	rc = mlip_sf_load(&sf, path, &k, flags, why, sizeof why);
	if (rc == -ENOENT) {
		fprintf(err,
		        "%s: %s: no such tool table: check the path; a new one: mlip-tools --init "
		        "%s\n",
		        prog, path, path);
		return -1;
	}
	if (rc != 0) {
		fprintf(err, "%s: error: %s\n", prog, why);
		return -1;
	}
	t->tools = calloc(sf.n ? sf.n : 1, sizeof *t->tools);
	t->comment = calloc(sf.n ? sf.n : 1, sizeof *t->comment);
	t->line = calloc(sf.n ? sf.n : 1, sizeof *t->line);
	if (t->tools == NULL || t->comment == NULL || t->line == NULL) {
		fprintf(err, "%s: %s: %s\n", prog, path, strerror(ENOMEM));
		mlip_sf_free(&sf);
		mlip_tooltable_free(t);
		return -1;
	}
	for (size_t i = 0; i < sf.n; i++) {
		struct parsed p;
		size_t at;
		/* canonical and checked by the load: parses */
		(void)parse(sf.rec[i].key, sf.rec[i].value, &p, &at, why, sizeof why);
		t->tools[i].number = p.number;
		t->tools[i].pocket = p.pocket;
		t->tools[i].z_mm = p.z;
		t->tools[i].d_mm = p.d;
		t->line[i] = sf.rec[i].line;
		snprintf(t->comment[i], MLIP_TOOLS_COMMENT, "%.*s", (int)p.comment_len,
		         p.comment ? p.comment : "");
		t->n++;
	}
	mlip_sf_free(&sf);
	/* sort the three arrays together: by number through an index */
	for (uint32_t i = 1; i < t->n; i++) {
		for (uint32_t j = i; j > 0 && by_number(&t->tools[j - 1], &t->tools[j]) > 0; j--) {
			struct mlip_tool tt = t->tools[j];
			char c[MLIP_TOOLS_COMMENT];
			uint32_t l = t->line[j];
			t->tools[j] = t->tools[j - 1];
			t->tools[j - 1] = tt;
			memcpy(c, t->comment[j], sizeof c);
			memcpy(t->comment[j], t->comment[j - 1], sizeof c);
			memcpy(t->comment[j - 1], c, sizeof c);
			t->line[j] = t->line[j - 1];
			t->line[j - 1] = l;
		}
	}
	return 0;
}

void mlip_tooltable_free(struct mlip_tooltable *t)
{
	free(t->tools);
	free(t->comment);
	free(t->line);
	t->tools = NULL;
	t->comment = NULL;
	t->line = NULL;
	t->n = 0;
}

const char *mlip_tooltable_comment(const struct mlip_tooltable *t, int32_t n)
{
	for (uint32_t i = 0; t != NULL && i < t->n; i++) {
		if (t->tools[i].number == n) {
			return t->comment[i];
		}
	}
	return "";
}
