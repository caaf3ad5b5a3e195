/*
 * mlip/text/format.h - the one message formatter of the core: bounded,
 * always NUL-terminated, no stdio, no locale, no allocation (the core has
 * no snprintf). Both readers (G-code, INI) and the CAN id rules write their
 * error messages with it.
 */
#ifndef MLIP_TEXT_FORMAT_H
#define MLIP_TEXT_FORMAT_H

#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#define MLIP_TEXT_TOKEN   32 /* bytes of input quoted by mlip_tb_token */
#define MLIP_TEXT_EXCERPT 24 /* bytes of input quoted by mlip_tb_excerpt */

/* A message being written into buf[0..cap): what does not fit is dropped. */
struct mlip_tb {
	char *p;
	size_t n, cap;
};

void mlip_tb_init(struct mlip_tb *b, char *buf, size_t cap);
void mlip_tb_putc(struct mlip_tb *b, char c);
void mlip_tb_puts(struct mlip_tb *b, const char *s);
void mlip_tb_uint(struct mlip_tb *b, uint64_t v);
/* 0x and upper-case hex digits, at least ndig of them */
void mlip_tb_hex(struct mlip_tb *b, uint32_t v, int ndig);
/* a byte as 'c' when printable ASCII (not space), else as 0xNN */
void mlip_tb_byte(struct mlip_tb *b, unsigned char c);
/* v with three decimals, like "%.3f" ("nan", "inf", "huge" beyond 1e15) */
void mlip_tb_fixed3(struct mlip_tb *b, double v);
/* v the way %.9g prints it, with a short exponent ("1e9" for "1e+09"):
 * nine significant digits show anything typed in a config file as typed,
 * and the INI reader takes the result back */
void mlip_tb_double(struct mlip_tb *b, double v);
/* a G or M code from its value*10: 'G', 641 -> "G64.1" */
void mlip_tb_code(struct mlip_tb *b, char letter, int code10);
/* a piece of input, cut to MLIP_TEXT_TOKEN bytes on a UTF-8 character
 * boundary (so the message stays valid UTF-8), "..." when cut */
void mlip_tb_token(struct mlip_tb *b, const char *s, size_t n);
/* a piece of input as one printable ASCII line: at most MLIP_TEXT_EXCERPT
 * bytes, any other byte shown as '?' */
void mlip_tb_excerpt(struct mlip_tb *b, const char *s, size_t n);

/* printf-like, with these conversions only: %s (string), %c (char), %u
 * (unsigned), %f (double, mlip_tb_fixed3), %g (double, mlip_tb_double), %G
 * and %M (int code*10, mlip_tb_code), %b (int, a byte: mlip_tb_byte), %t
 * (const char *, size_t: mlip_tb_excerpt), %T (const char *, size_t:
 * mlip_tb_token); any other character after '%' stands for itself ("%%"). */
void mlip_tb_format(struct mlip_tb *b, const char *fmt, ...);
void mlip_tb_vformat(struct mlip_tb *b, const char *fmt, va_list ap);

#endif
