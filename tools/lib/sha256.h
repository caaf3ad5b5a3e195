/*
 * sha256.h - SHA-256 (FIPS 180-4), streaming, for the host tools: the
 * checksum of a state file (statefile.h) and the per-chunk hashes that pin a
 * program between its check and its run (program.h). Not a secret: a hash
 * a local user cannot steer to a collision, so that a file changed on
 * purpose is found as surely as one changed by accident.
 */
#ifndef MLIP_TOOLS_SHA256_H
#define MLIP_TOOLS_SHA256_H

#include <stddef.h>
#include <stdint.h>

#define MLIP_SHA256_BYTES 32

struct mlip_sha256 {
	uint32_t h[8];
	uint64_t bytes;
	uint8_t buf[64];
	size_t n;
};

void mlip_sha256_init(struct mlip_sha256 *s);
void mlip_sha256_update(struct mlip_sha256 *s, const void *data, size_t len);
void mlip_sha256_final(struct mlip_sha256 *s, uint8_t out[MLIP_SHA256_BYTES]);
/* One call: out = SHA-256(data). */
void mlip_sha256(const void *data, size_t len, uint8_t out[MLIP_SHA256_BYTES]);
/* The first hex_len / 2 bytes of digest as lowercase hex (hex_len + 1 bytes). */
void mlip_sha256_hex(const uint8_t digest[MLIP_SHA256_BYTES], char *hex, size_t hex_len);

#endif
