/*
 * ayllu_sha256.c -- SHA-256 and HMAC-SHA256 for AylluLite C (see ayllu_sha256.h).
 *
 * Written for clarity and portability (no unaligned loads, no endianness assumptions) rather
 * than speed: the protocol hashes at most one 8 KiB datagram per message received.
 */
#include "ayllu_sha256.h"

#include <string.h>

static const uint32_t K[64] = {
    0x428a2f98u, 0x71374491u, 0xb5c0fbcfu, 0xe9b5dba5u, 0x3956c25bu, 0x59f111f1u, 0x923f82a4u, 0xab1c5ed5u,
    0xd807aa98u, 0x12835b01u, 0x243185beu, 0x550c7dc3u, 0x72be5d74u, 0x80deb1feu, 0x9bdc06a7u, 0xc19bf174u,
    0xe49b69c1u, 0xefbe4786u, 0x0fc19dc6u, 0x240ca1ccu, 0x2de92c6fu, 0x4a7484aau, 0x5cb0a9dcu, 0x76f988dau,
    0x983e5152u, 0xa831c66du, 0xb00327c8u, 0xbf597fc7u, 0xc6e00bf3u, 0xd5a79147u, 0x06ca6351u, 0x14292967u,
    0x27b70a85u, 0x2e1b2138u, 0x4d2c6dfcu, 0x53380d13u, 0x650a7354u, 0x766a0abbu, 0x81c2c92eu, 0x92722c85u,
    0xa2bfe8a1u, 0xa81a664bu, 0xc24b8b70u, 0xc76c51a3u, 0xd192e819u, 0xd6990624u, 0xf40e3585u, 0x106aa070u,
    0x19a4c116u, 0x1e376c08u, 0x2748774cu, 0x34b0bcb5u, 0x391c0cb3u, 0x4ed8aa4au, 0x5b9cca4fu, 0x682e6ff3u,
    0x748f82eeu, 0x78a5636fu, 0x84c87814u, 0x8cc70208u, 0x90befffau, 0xa4506cebu, 0xbef9a3f7u, 0xc67178f2u,
};

#define ROTR(x, n) (((x) >> (n)) | ((x) << (32 - (n))))

static void compress(uint32_t h[8], const uint8_t b[64]) {
    uint32_t w[64];
    uint32_t a, bb, c, d, e, f, g, hh;
    int i;
    for (i = 0; i < 16; i++) {
        w[i] = ((uint32_t)b[4 * i] << 24) | ((uint32_t)b[4 * i + 1] << 16) | ((uint32_t)b[4 * i + 2] << 8) |
               (uint32_t)b[4 * i + 3];
    }
    for (i = 16; i < 64; i++) {
        uint32_t s0 = ROTR(w[i - 15], 7) ^ ROTR(w[i - 15], 18) ^ (w[i - 15] >> 3);
        uint32_t s1 = ROTR(w[i - 2], 17) ^ ROTR(w[i - 2], 19) ^ (w[i - 2] >> 10);
        w[i] = w[i - 16] + s0 + w[i - 7] + s1;
    }
    a = h[0];
    bb = h[1];
    c = h[2];
    d = h[3];
    e = h[4];
    f = h[5];
    g = h[6];
    hh = h[7];
    for (i = 0; i < 64; i++) {
        uint32_t t1 = hh + (ROTR(e, 6) ^ ROTR(e, 11) ^ ROTR(e, 25)) + ((e & f) ^ (~e & g)) + K[i] + w[i];
        uint32_t t2 = (ROTR(a, 2) ^ ROTR(a, 13) ^ ROTR(a, 22)) + ((a & bb) ^ (a & c) ^ (bb & c));
        hh = g;
        g = f;
        f = e;
        e = d + t1;
        d = c;
        c = bb;
        bb = a;
        a = t1 + t2;
    }
    h[0] += a;
    h[1] += bb;
    h[2] += c;
    h[3] += d;
    h[4] += e;
    h[5] += f;
    h[6] += g;
    h[7] += hh;
}

void ayl_sha256_init(ayl_sha256_ctx *ctx) {
    static const uint32_t iv[8] = {0x6a09e667u, 0xbb67ae85u, 0x3c6ef372u, 0xa54ff53au,
                                   0x510e527fu, 0x9b05688cu, 0x1f83d9abu, 0x5be0cd19u};
    memcpy(ctx->h, iv, sizeof iv);
    ctx->total = 0;
    ctx->fill = 0;
}

void ayl_sha256_update(ayl_sha256_ctx *ctx, const void *data, size_t len) {
    const uint8_t *p = (const uint8_t *)data;
    ctx->total += len;
    while (len > 0) {
        size_t n = AYL_SHA256_BLOCK - ctx->fill;
        if (n > len) {
            n = len;
        }
        memcpy(ctx->block + ctx->fill, p, n);
        ctx->fill += n;
        p += n;
        len -= n;
        if (ctx->fill == AYL_SHA256_BLOCK) {
            compress(ctx->h, ctx->block);
            ctx->fill = 0;
        }
    }
}

void ayl_sha256_final(ayl_sha256_ctx *ctx, uint8_t out[AYL_SHA256_LEN]) {
    uint64_t bits = ctx->total * 8u;
    int i;
    ctx->block[ctx->fill++] = 0x80;
    if (ctx->fill > 56) {
        memset(ctx->block + ctx->fill, 0, AYL_SHA256_BLOCK - ctx->fill);
        compress(ctx->h, ctx->block);
        ctx->fill = 0;
    }
    memset(ctx->block + ctx->fill, 0, 56 - ctx->fill);
    for (i = 0; i < 8; i++) {
        ctx->block[56 + i] = (uint8_t)(bits >> (56 - 8 * i));
    }
    compress(ctx->h, ctx->block);
    for (i = 0; i < 8; i++) {
        out[4 * i] = (uint8_t)(ctx->h[i] >> 24);
        out[4 * i + 1] = (uint8_t)(ctx->h[i] >> 16);
        out[4 * i + 2] = (uint8_t)(ctx->h[i] >> 8);
        out[4 * i + 3] = (uint8_t)ctx->h[i];
    }
}

void ayl_sha256(const void *data, size_t len, uint8_t out[AYL_SHA256_LEN]) {
    ayl_sha256_ctx ctx;
    ayl_sha256_init(&ctx);
    ayl_sha256_update(&ctx, data, len);
    ayl_sha256_final(&ctx, out);
}

/* A wipe the compiler may not drop as a dead store (a plain memset before return may be). */
static void wipe(void *p, size_t n) {
    volatile uint8_t *v = (volatile uint8_t *)p;
    while (n-- > 0) {
        *v++ = 0;
    }
}

void ayl_hmac_sha256(const uint8_t *key, size_t key_len, const void *part1, size_t len1, const void *part2,
                     size_t len2, uint8_t out[AYL_SHA256_LEN]) {
    uint8_t k[AYL_SHA256_BLOCK];
    uint8_t pad[AYL_SHA256_BLOCK];
    uint8_t inner[AYL_SHA256_LEN];
    ayl_sha256_ctx ctx;
    size_t i;
    memset(k, 0, sizeof k);
    if (key_len > AYL_SHA256_BLOCK) {
        ayl_sha256(key, key_len, k); /* RFC 2104: long keys are hashed first */
    } else if (key_len > 0) {
        memcpy(k, key, key_len);
    }
    for (i = 0; i < AYL_SHA256_BLOCK; i++) {
        pad[i] = (uint8_t)(k[i] ^ 0x36u);
    }
    ayl_sha256_init(&ctx);
    ayl_sha256_update(&ctx, pad, sizeof pad);
    ayl_sha256_update(&ctx, part1, len1);
    if (len2 > 0) {
        ayl_sha256_update(&ctx, part2, len2);
    }
    ayl_sha256_final(&ctx, inner);
    for (i = 0; i < AYL_SHA256_BLOCK; i++) {
        pad[i] = (uint8_t)(k[i] ^ 0x5cu);
    }
    ayl_sha256_init(&ctx);
    ayl_sha256_update(&ctx, pad, sizeof pad);
    ayl_sha256_update(&ctx, inner, sizeof inner);
    ayl_sha256_final(&ctx, out);
    /* Keys should not linger on the stack longer than needed. */
    wipe(k, sizeof k);
    wipe(pad, sizeof pad);
    wipe(inner, sizeof inner);
}
