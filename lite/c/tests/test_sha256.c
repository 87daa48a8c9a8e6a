/*
 * test_sha256.c -- checks ayllu_sha256.c against published vectors: FIPS 180-4 examples for
 * SHA-256 and RFC 4231 test cases 1-7 for HMAC-SHA256 (case 5 truncated to 128 bits, the
 * protocol's MAC length). Also checks that feeding the data in pieces, and HMAC over two
 * parts, give the same results, since the protocol MACs datagrams that way.
 */
#include <string.h>

#include "../ayllu_sha256.h"
#include "check.h"

static int hex_is(const uint8_t *got, size_t n, const char *hex) {
    static const char digits[] = "0123456789abcdef";
    size_t i;
    if (strlen(hex) != 2 * n) {
        return 0;
    }
    for (i = 0; i < n; i++) {
        if (hex[2 * i] != digits[got[i] >> 4] || hex[2 * i + 1] != digits[got[i] & 15]) {
            return 0;
        }
    }
    return 1;
}

static void sha(const char *msg, size_t len, const char *want) {
    uint8_t out[AYL_SHA256_LEN];
    ayl_sha256(msg, len, out);
    CHECK_MSG(hex_is(out, sizeof out, want), "sha256 of %zu bytes", len);
}

static void hmac(const uint8_t *key, size_t klen, const uint8_t *msg, size_t mlen, size_t outlen, const char *want,
                 int tc) {
    uint8_t out[AYL_SHA256_LEN];
    size_t split;
    ayl_hmac_sha256(key, klen, msg, mlen, NULL, 0, out);
    CHECK_MSG(hex_is(out, outlen, want), "RFC 4231 test case %d", tc);
    for (split = 0; split <= mlen; split += 7) {
        ayl_hmac_sha256(key, klen, msg, split, msg + split, mlen - split, out);
        CHECK_MSG(hex_is(out, outlen, want), "RFC 4231 test case %d split at %zu", tc, split);
    }
}

static uint8_t million[1000000];

int main(void) {
    uint8_t k[131], d[50];
    size_t i;
    ayl_sha256_ctx ctx;
    uint8_t out[AYL_SHA256_LEN];

    sha("", 0, "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    sha("abc", 3, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    sha("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq", 56,
        "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
    memset(million, 'a', sizeof million);
    ayl_sha256_init(&ctx);
    for (i = 0; i < sizeof million; i += 999) { /* odd pieces cross every block boundary */
        ayl_sha256_update(&ctx, million + i, sizeof million - i < 999 ? sizeof million - i : 999);
    }
    ayl_sha256_final(&ctx, out);
    CHECK(hex_is(out, sizeof out, "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0"));

    memset(k, 0x0b, 20);
    hmac(k, 20, (const uint8_t *)"Hi There", 8, 32,
         "b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7", 1);
    hmac((const uint8_t *)"Jefe", 4, (const uint8_t *)"what do ya want for nothing?", 28, 32,
         "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843", 2);
    memset(k, 0xaa, 20);
    memset(d, 0xdd, 50);
    hmac(k, 20, d, 50, 32, "773ea91e36800e46854db8ebd09181a72959098b3ef8c122d9635514ced565fe", 3);
    for (i = 0; i < 25; i++) {
        k[i] = (uint8_t)(i + 1);
    }
    memset(d, 0xcd, 50);
    hmac(k, 25, d, 50, 32, "82558a389a443c0ea4cc819899f2083a85f0faa3e578f8077a2e3ff46729665b", 4);
    memset(k, 0x0c, 20);
    hmac(k, 20, (const uint8_t *)"Test With Truncation", 20, 16, "a3b6167473100ee06e0c796c2955552b", 5);
    memset(k, 0xaa, 131);
    hmac(k, 131, (const uint8_t *)"Test Using Larger Than Block-Size Key - Hash Key First", 54, 32,
         "60e431591ee0b67f0d8a26aacbf5b77f8e0bc6213728c5140546040f0ee37f54", 6);
    {
        const char *m = "This is a test using a larger than block-size key and a larger than block-size data. The key "
                        "needs to be hashed before being used by the HMAC algorithm.";
        hmac(k, 131, (const uint8_t *)m, strlen(m), 32,
             "9b09ffa71b942fcb27635fbcd5b0e944bfdc63644f0713938a7f51535c3a35e2", 7);
    }
    return check_exit("test_sha256");
}
