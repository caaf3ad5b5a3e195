/*
 * mlip/text/chars.h - the character classes both readers (G-code, INI) use,
 * in the C locale whatever the process's locale (<ctype.h> follows it), and
 * the UTF-8 check of RFC 3629.
 */
#ifndef MLIP_TEXT_CHARS_H
#define MLIP_TEXT_CHARS_H

#include <stddef.h>

static inline int mlip_is_digit(int c)
{
	return c >= '0' && c <= '9';
}

static inline int mlip_is_alpha(int c)
{
	return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z');
}

/* space or tab: what separates tokens in both languages */
static inline int mlip_is_blank(int c)
{
	return c == ' ' || c == '\t';
}

static inline char mlip_upper(char c)
{
	return (c >= 'a' && c <= 'z') ? (char)(c - 'a' + 'A') : c;
}

/* Length of the well-formed UTF-8 sequence at p[0..n) (RFC 3629: no
 * overlong forms, no surrogates, nothing above U+10FFFF), or 0. n >= 1. */
size_t mlip_utf8_len(const unsigned char *p, size_t n);

#endif
