/*
 * fuzz_url.c -- libFuzzer target: ayl_url_parse on any text (the bytes up to the first NUL).
 * Promises checked: no memory error or undefined behavior, a result of 0 or AYL_E_INVALID, a
 * NUL-terminated message on refusal, and text fields inside the URL on success. Built and run
 * by `make -C lite/c fuzz`.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../ayllu_lite.h"

static void inside(const char *url, size_t n, ayl_str s) {
    if (s.len > 0 && (s.ptr < url || s.ptr + s.len > url + n)) {
        abort();
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    static char url[8192 + 1];
    char err[64];
    ayl_url u;
    size_t n = size < sizeof url - 1 ? size : sizeof url - 1, i;
    int rc;
    memcpy(url, data, n);
    url[n] = '\0';
    n = strlen(url);
    rc = ayl_url_parse(&u, url, err, sizeof err);
    if (rc == 0) {
        inside(url, n, u.bind.host);
        inside(url, n, u.name);
        inside(url, n, u.state);
        inside(url, n, u.operator_secret);
        for (i = 0; i < u.npeers; i++) {
            inside(url, n, u.peers[i].host);
        }
        for (i = 0; i < u.ngroups; i++) {
            inside(url, n, u.groups[i].name);
        }
    } else if (rc != AYL_E_INVALID || memchr(err, '\0', sizeof err) == NULL) {
        abort();
    }
    return 0;
}
