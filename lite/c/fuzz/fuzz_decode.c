/*
 * fuzz_decode.c -- libFuzzer target: ayl_decode and ayl_next on any bytes, for an open team and
 * for a keyed one (the MAC check, then the same body). Promises checked: no read outside the
 * datagram (AddressSanitizer), no undefined behavior (UBSan), every result a known cause, and
 * every decoded string and value inside the datagram. Built and run by `make -C lite/c fuzz`.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include "../ayllu_lite.h"

static const uint8_t KEY[AYL_KEY_LEN] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16,
                                         17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32};

static void inside(const uint8_t *buf, size_t len, const char *p, size_t n) {
    if (n > 0 && ((const uint8_t *)p < buf || (const uint8_t *)p + n > buf + len)) {
        abort();
    }
}

static void decode(const uint8_t *data, size_t size, const uint8_t *key) {
    ayl_datagram d;
    ayl_msg m;
    int guard = 0;
    ayl_cause c = ayl_decode(&d, data, size, 7, key);
    if ((int)c < 0 || (int)c >= AYL_CAUSE_COUNT) {
        abort();
    }
    if (c != AYL_OK) {
        return;
    }
    while (ayl_next(&d, &m) == 1) {
        if (m.kind == AYL_KIND_PORT) {
            inside(data, size, m.u.port.behavior.ptr, m.u.port.behavior.len);
            inside(data, size, m.u.port.port.ptr, m.u.port.port.len);
        }
        if (++guard > 100000) {
            abort(); /* a datagram of at most 8192 bytes holds fewer messages than that */
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    decode(data, size, NULL);
    decode(data, size, KEY);
    return 0;
}
