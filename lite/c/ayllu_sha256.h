/*
 * ayllu_sha256.h -- SHA-256 (FIPS 180-4) and HMAC-SHA256 (RFC 2104) for AylluLite C.
 *
 * What it is for: the datagram MAC of the Ayllu wire protocol (spec/protocol.md,
 * "Authentication"), without depending on a crypto library that a microcontroller may not
 * have. What it promises: C99, no malloc, no global state, constant memory (the context is
 * on the caller's stack); results equal FIPS 180-4 and RFC 4231 (tests/test_sha256.c).
 * It makes no constant-time promise beyond what the algorithm gives; MAC comparison in
 * ayllu_lite.c is constant-time.
 *
 * Thread-safety: every function is reentrant; a context must not be shared by two threads
 * at once.
 */
#ifndef AYLLU_SHA256_H
#define AYLLU_SHA256_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define AYL_SHA256_LEN 32
#define AYL_SHA256_BLOCK 64

/* A running hash. Opaque in spirit: use the functions below. */
typedef struct {
    uint32_t h[8];
    uint64_t total; /* bytes hashed so far */
    uint8_t block[AYL_SHA256_BLOCK];
    size_t fill; /* bytes waiting in block */
} ayl_sha256_ctx;

/* Start a hash. Reentrant. */
void ayl_sha256_init(ayl_sha256_ctx *ctx);
/* Add len bytes. Reentrant (per context). */
void ayl_sha256_update(ayl_sha256_ctx *ctx, const void *data, size_t len);
/* Finish and write the 32-byte digest; the context must be initialised again before reuse. */
void ayl_sha256_final(ayl_sha256_ctx *ctx, uint8_t out[AYL_SHA256_LEN]);
/* One-shot digest. Reentrant. */
void ayl_sha256(const void *data, size_t len, uint8_t out[AYL_SHA256_LEN]);

/* HMAC-SHA256 of two concatenated parts (part2 may be NULL with len2 0); keys of any length.
 * Two parts let the protocol MAC a datagram without copying it. Reentrant. */
void ayl_hmac_sha256(const uint8_t *key, size_t key_len, const void *part1, size_t len1, const void *part2,
                     size_t len2, uint8_t out[AYL_SHA256_LEN]);

#ifdef __cplusplus
}
#endif
#endif
