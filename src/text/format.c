/*
 * format.c - the bounded message formatter of mlip/text/format.h.
 */
#include "mlip/text/format.h"

#include <math.h>

void mlip_tb_init(struct mlip_tb *b, char *buf, size_t cap)
{
	b->p = buf;
	b->n = 0;
	b->cap = cap;
	buf[0] = '\0';
}

void mlip_tb_putc(struct mlip_tb *b, char c)
{
	if (b->n + 1 < b->cap) {
		b->p[b->n++] = c;
		b->p[b->n] = '\0';
	}
}

void mlip_tb_puts(struct mlip_tb *b, const char *s)
{
	while (*s != '\0') {
		mlip_tb_putc(b, *s++);
	}
}

void mlip_tb_uint(struct mlip_tb *b, uint64_t v)
{
	char d[24];
	int k = 0;

	do {
		d[k++] = (char)('0' + v % 10);
		v /= 10;
	} while (v != 0);
	while (k > 0) {
		mlip_tb_putc(b, d[--k]);
	}
}

void mlip_tb_hex(struct mlip_tb *b, uint32_t v, int ndig)
{
	static const char hx[] = "0123456789ABCDEF";
	int shift = 28;

	mlip_tb_puts(b, "0x");
	while (shift >= 4 * ndig && (v >> shift) == 0) {
		shift -= 4;
	}
	for (; shift >= 0; shift -= 4) {
		mlip_tb_putc(b, hx[(v >> shift) & 0xFu]);
	}
}

void mlip_tb_byte(struct mlip_tb *b, unsigned char c)
{
	if (c >= 0x21 && c < 0x7F) {
		mlip_tb_putc(b, '\'');
		mlip_tb_putc(b, (char)c);
		mlip_tb_putc(b, '\'');
	} else {
		mlip_tb_hex(b, c, 2);
	}
}

void mlip_tb_fixed3(struct mlip_tb *b, double v)
{
	double r = floor(fabs(v) * 1000.0 + 0.5);
	const char *p;
	uint64_t q;

	if (v < 0 && r > 0) {
		mlip_tb_putc(b, '-');
	}
	if (!(r < 1e18)) {
		for (p = isnan(v) ? "nan" : isinf(v) ? "inf" : "huge"; *p; p++) {
			mlip_tb_putc(b, *p);
		}
		return;
	}
	q = (uint64_t)r;
	mlip_tb_uint(b, q / 1000);
	mlip_tb_putc(b, '.');
	mlip_tb_putc(b, (char)('0' + q / 100 % 10));
	mlip_tb_putc(b, (char)('0' + q / 10 % 10));
	mlip_tb_putc(b, (char)('0' + q % 10));
}

void mlip_tb_double(struct mlip_tb *b, double x)
{
	char dig[10];
	uint64_t d = 0;
	int e, k, nd;

	if (isnan(x)) {
		mlip_tb_puts(b, "nan");
		return;
	}
	if (x < 0) {
		mlip_tb_putc(b, '-');
		x = -x;
	}
	if (isinf(x)) {
		mlip_tb_puts(b, "inf");
		return;
	}
	if (x == 0) {
		mlip_tb_putc(b, '0');
		return;
	}
	/* d = x / 10^(e-8) rounded, 10^8 <= d < 10^9; log10 may be off by one */
	e = (int)floor(log10(x));
	for (k = 0; k < 3; k++) {
		int p = e - 8;
		double s = x;
		if (p < -290) { /* keep 10^p a normal double */
			s *= 1e100;
			p += 100;
		}
		d = (uint64_t)llround(s / pow(10.0, p));
		if (d >= 1000000000u) {
			e++;
		} else if (d < 100000000u) {
			e--;
		} else {
			break;
		}
	}
	for (k = 8; k >= 0; k--) {
		dig[k] = (char)('0' + d % 10);
		d /= 10;
	}
	for (nd = 9; nd > 1 && dig[nd - 1] == '0'; nd--) {
	}
	if (e >= -4 && e < 9) {
		if (e < 0) {
			mlip_tb_puts(b, "0.");
			for (k = -1; k > e; k--) {
				mlip_tb_putc(b, '0');
			}
			for (k = 0; k < nd; k++) {
				mlip_tb_putc(b, dig[k]);
			}
		} else {
			for (k = 0; k <= e; k++) {
				mlip_tb_putc(b, k < nd ? dig[k] : '0');
			}
			if (nd > e + 1) {
				mlip_tb_putc(b, '.');
				for (k = e + 1; k < nd; k++) {
					mlip_tb_putc(b, dig[k]);
				}
			}
		}
		return;
	}
	mlip_tb_putc(b, dig[0]);
	if (nd > 1) {
		mlip_tb_putc(b, '.');
		for (k = 1; k < nd; k++) {
			mlip_tb_putc(b, dig[k]);
		}
	}
	mlip_tb_putc(b, 'e');
	if (e < 0) {
		mlip_tb_putc(b, '-');
		e = -e;
	}
	mlip_tb_uint(b, (uint64_t)e);
}

void mlip_tb_code(struct mlip_tb *b, char letter, int code10)
{
	mlip_tb_putc(b, letter);
	mlip_tb_uint(b, (uint64_t)(code10 / 10));
	if (code10 % 10) {
		mlip_tb_putc(b, '.');
		mlip_tb_putc(b, (char)('0' + code10 % 10));
	}
}

void mlip_tb_token(struct mlip_tb *b, const char *s, size_t n)
{
	size_t i, cut = n;

	if (n > MLIP_TEXT_TOKEN) {
		cut = MLIP_TEXT_TOKEN;
		while (cut > 0 && ((unsigned char)s[cut] & 0xC0u) == 0x80u) {
			cut--;
		}
	}
	for (i = 0; i < cut; i++) {
		mlip_tb_putc(b, s[i]);
	}
	if (cut < n) {
		mlip_tb_puts(b, "...");
	}
}

void mlip_tb_excerpt(struct mlip_tb *b, const char *s, size_t n)
{
	size_t k;

	for (k = 0; k < n && k < MLIP_TEXT_EXCERPT; k++) {
		mlip_tb_putc(b, s[k] >= 0x20 && s[k] < 0x7f ? s[k] : '?');
	}
}

void mlip_tb_vformat(struct mlip_tb *b, const char *fmt, va_list ap)
{
	const char *s;
	size_t n;

	for (; *fmt; fmt++) {
		if (*fmt != '%' || !fmt[1]) {
			mlip_tb_putc(b, *fmt);
			continue;
		}
		switch (*++fmt) {
		case 's':
			mlip_tb_puts(b, va_arg(ap, const char *));
			break;
		case 'c':
			mlip_tb_putc(b, (char)va_arg(ap, int));
			break;
		case 'u':
			mlip_tb_uint(b, va_arg(ap, unsigned));
			break;
		case 'f':
			mlip_tb_fixed3(b, va_arg(ap, double));
			break;
		case 'g':
			mlip_tb_double(b, va_arg(ap, double));
			break;
		case 'G':
		case 'M':
			mlip_tb_code(b, *fmt, va_arg(ap, int));
			break;
		case 'b':
			mlip_tb_byte(b, (unsigned char)(va_arg(ap, int) & 0xFF));
			break;
		case 't':
		case 'T':
			s = va_arg(ap, const char *);
			n = va_arg(ap, size_t);
			if (*fmt == 't') {
				mlip_tb_excerpt(b, s, n);
			} else {
				mlip_tb_token(b, s, n);
			}
			break;
		default:
			mlip_tb_putc(b, *fmt);
			break;
		}
	}
}

void mlip_tb_format(struct mlip_tb *b, const char *fmt, ...)
{
	va_list ap;

	va_start(ap, fmt);
	mlip_tb_vformat(b, fmt, ap);
	va_end(ap);
}
