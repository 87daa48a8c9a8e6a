/*
 * ayllu_url.c -- the udp:// URL every Ayllu program reads (AYLLU_URL), for AylluLite C.
 *
 * What it is for: letting a C program be configured exactly as the Rust runtime, the `ayllu`
 * tool and AylluLite Python are -- one AYLLU_URL for the whole team -- instead of setting team,
 * key and peers in code.
 *
 * What it promises: the grammar and limits of crates/ayllu/src/udp_config.rs, checked by the
 * same vectors (spec/vectors/urls.json, tests/test_url.c): the same URLs accepted with the same
 * values, the same URLs refused, each refusal naming the bad part. No malloc, no stdio, no
 * environment, no files and no resolver: host names are handed back as text, the operator
 * secret as its path. Reentrant: it touches only its arguments.
 */
#include <string.h>

#include "ayllu_lite.h"

/* ----- the error message, built without stdio ------------------------------------------------ */

typedef struct {
    char *p;
    size_t cap;
    size_t len;
} msgbuf;

static void put(msgbuf *m, const char *s, size_t n) {
    size_t i;
    for (i = 0; i < n && m->len + 1 < m->cap; i++) {
        m->p[m->len++] = s[i];
    }
    if (m->cap > 0) {
        m->p[m->len] = '\0';
    }
}

static void put_text(msgbuf *m, const char *s) { put(m, s, strlen(s)); }

/* `before` + "`text`" + `after` (text NULL: before + after) into err; AYL_E_INVALID. */
static int fail(char *err, size_t cap, const char *before, const char *text, size_t tlen, const char *after) {
    msgbuf m;
    m.p = err;
    m.cap = err != NULL ? cap : 0;
    m.len = 0;
    if (m.cap > 0) {
        m.p[0] = '\0';
    }
    put_text(&m, before);
    if (text != NULL) {
        put_text(&m, "`");
        put(&m, text, tlen);
        put_text(&m, "`");
    }
    put_text(&m, after);
    return AYL_E_INVALID;
}

/* ----- pieces ---------------------------------------------------------------------------------- */

static int is_digit(char c) { return c >= '0' && c <= '9'; }
static int is_letter(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }

static int hex_digit(char c) {
    if (is_digit(c)) return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* ASCII decimal digits only (no sign, no space), at most `max`; 0 on success. */
static int decimal(const char *s, size_t n, uint64_t max, uint64_t *out) {
    uint64_t v = 0;
    size_t i;
    if (n == 0) {
        return -1;
    }
    for (i = 0; i < n; i++) {
        if (!is_digit(s[i])) {
            return -1;
        }
        v = v * 10 + (uint64_t)(s[i] - '0');
        if (v > max) {
            return -1; /* also stops before v could wrap */
        }
    }
    *out = v;
    return 0;
}

/* 64 hex digits into 32 bytes; 0 on success. */
static int hex32(const char *s, size_t n, uint8_t out[AYL_KEY_LEN]) {
    size_t i;
    if (n != 2 * AYL_KEY_LEN) {
        return -1;
    }
    for (i = 0; i < AYL_KEY_LEN; i++) {
        int hi = hex_digit(s[2 * i]), lo = hex_digit(s[2 * i + 1]);
        if (hi < 0 || lo < 0) {
            return -1;
        }
        out[i] = (uint8_t)(hi * 16 + lo);
    }
    return 0;
}

/* A dotted quad: four parts of 1 to 3 digits, each at most 255, no leading zero. */
static int ipv4(const char *s, size_t n, uint8_t out[4]) {
    size_t i = 0;
    int part;
    for (part = 0; part < 4; part++) {
        size_t start = i;
        uint64_t v;
        while (i < n && is_digit(s[i])) {
            i++;
        }
        if (i - start > 3 || (i - start > 1 && s[start] == '0') || decimal(s + start, i - start, 255, &v) != 0) {
            return -1;
        }
        out[part] = (uint8_t)v;
        if (part < 3) {
            if (i >= n || s[i] != '.') {
                return -1;
            }
            i++;
        }
    }
    return i == n ? 0 : -1;
}

/* HOST:PORT with an IPv4 host (a literal, or a name for the caller's resolver). */
static int address(const char *s, size_t n, const char *what, ayl_url_addr *out, char *err, size_t cap) {
    size_t colon = n, i;
    uint64_t port = 0;
    int port_ok, lettered = 0;
    for (i = 0; i < n; i++) {
        if (s[i] == ':') {
            colon = i;
        }
    }
    port_ok = colon < n && decimal(s + colon + 1, n - colon - 1, 65535, &port) == 0;
    memset(out, 0, sizeof *out);
    if (port_ok && colon >= 2 && s[0] == '[' && s[colon - 1] == ']') {
        return fail(err, cap, what, s, n, " has no IPv4 address");
    }
    if (!port_ok || colon == 0) {
        return fail(err, cap, what, s, n, " is not HOST:PORT (an IPv4 address or a host name, and a port)");
    }
    out->host.ptr = s;
    out->host.len = colon;
    out->port = (uint16_t)port;
    if (ipv4(s, colon, out->ip4) == 0) {
        return 0;
    }
    memset(out->ip4, 0, sizeof out->ip4);
    for (i = 0; i < colon; i++) {
        lettered |= is_letter(s[i]);
    }
    if (!lettered) {
        /* `1..2` or `127.1`: not an address, and not a name to ask a resolver about. */
        return fail(err, cap, what, s, n, " is not HOST:PORT (an IPv4 address or a host name, and a port)");
    }
    out->is_name = 1;
    return 0;
}

static int key_is(const char *k, size_t klen, const char *name) {
    return strlen(name) == klen && memcmp(k, name, klen) == 0;
}

/* ----- the URL --------------------------------------------------------------------------------- */

static int option(ayl_url *u, const char *k, size_t kn, const char *v, size_t vn, char *err, size_t cap) {
    uint64_t x;
    if (key_is(k, kn, "team")) {
        if (decimal(v, vn, 0xFFFFFFFFu, &x) != 0) {
            return fail(err, cap, "team ", v, vn, " is not a u32");
        }
        u->team = (uint32_t)x;
    } else if (key_is(k, kn, "key")) {
        if (hex32(v, vn, u->key) != 0) {
            return fail(err, cap, "key must be 64 hex digits", NULL, 0, "");
        }
        u->keyed = 1;
    } else if (key_is(k, kn, "peer")) {
        if (u->npeers == AYL_URL_MAX_PEERS) {
            return fail(err, cap, "peer ", v, vn, ": more peers than this build keeps (AYL_URL_MAX_PEERS)");
        }
        if (address(v, vn, "peer ", &u->peers[u->npeers], err, cap) != 0) {
            return AYL_E_INVALID;
        }
        u->npeers++;
    } else if (key_is(k, kn, "broadcast")) {
        if (address(v, vn, "broadcast ", &u->broadcast, err, cap) != 0) {
            return AYL_E_INVALID;
        }
        u->has_broadcast = 1;
    } else if (key_is(k, kn, "group")) {
        size_t at = 0;
        ayl_url_group *g;
        while (at < vn && v[at] != '@') {
            at++;
        }
        if (at == vn) {
            return fail(err, cap, "group ", v, vn, " should be NAME@ADDR:PORT");
        }
        if (at == 0 || at > 255) {
            return fail(err, cap, "group name ", v, at, " must be 1 to 255 bytes");
        }
        if (u->ngroups == AYL_URL_MAX_GROUPS) {
            return fail(err, cap, "group ", v, vn, ": more groups than this build keeps (AYL_URL_MAX_GROUPS)");
        }
        g = &u->groups[u->ngroups];
        if (address(v + at + 1, vn - at - 1, "group address ", &g->addr, err, cap) != 0) {
            return AYL_E_INVALID;
        }
        g->name.ptr = v;
        g->name.len = at;
        u->ngroups++;
    } else if (key_is(k, kn, "discovery")) {
        ayl_url_addr a;
        if (address(v, vn, "discovery ", &a, err, cap) != 0) {
            return AYL_E_INVALID;
        }
        /* A name cannot be checked here; the caller's resolver must give a multicast address. */
        if (!a.is_name && (a.ip4[0] < 224 || a.ip4[0] > 239)) {
            return fail(err, cap, "discovery ", v, vn, " must be a multicast address (224.0.0.0/4)");
        }
        u->discovery = a;
        u->has_discovery = 1;
    } else if (key_is(k, kn, "ttl")) {
        if (decimal(v, vn, 255, &x) != 0) {
            return fail(err, cap, "ttl ", v, vn, " must be a number from 0 to 255");
        }
        u->ttl = (uint8_t)x;
    } else if (key_is(k, kn, "hello_ms")) {
        if (decimal(v, vn, 0xFFFFFFFFu, &x) != 0 || x == 0) {
            return fail(err, cap, "hello_ms must be between 1 and 4294967295", NULL, 0, "");
        }
        u->hello_ms = (uint32_t)x;
    } else if (key_is(k, kn, "mtu")) {
        if (decimal(v, vn, AYL_MAX_DATAGRAM, &x) != 0 || x < 64) {
            return fail(err, cap, "mtu must be between 64 and 8192", NULL, 0, "");
        }
        u->mtu = (uint32_t)x;
    } else if (key_is(k, kn, "spin_us")) {
        if (decimal(v, vn, 1000, &x) != 0) {
            return fail(err, cap, "spin_us ", v, vn, " must be a number from 0 to 1000");
        }
        u->spin_us = (uint32_t)x;
    } else if (key_is(k, kn, "name")) {
        if (vn > 255) {
            return fail(err, cap, "name must be at most 255 bytes", NULL, 0, "");
        }
        u->name.ptr = v;
        u->name.len = vn;
    } else if (key_is(k, kn, "state")) {
        if (vn == 0) {
            return fail(err, cap, "state needs a file path", NULL, 0, "");
        }
        u->state.ptr = v;
        u->state.len = vn;
    } else if (key_is(k, kn, "operator")) {
        if (hex32(v, vn, u->operator_key) != 0) {
            return fail(err, cap, "operator must be 64 hex digits (the public key `ayllu keygen` prints)", NULL, 0,
                        "");
        }
        u->has_operator = 1;
    } else if (key_is(k, kn, "operator_secret")) {
        if (vn == 0) {
            return fail(err, cap, "operator_secret needs the path of a file that holds the secret", NULL, 0, "");
        }
        u->operator_secret.ptr = v;
        u->operator_secret.len = vn;
    } else {
        return fail(err, cap, "unknown option ", k, kn, "");
    }
    return 0;
}

int ayl_url_parse(ayl_url *out, const char *url, char *err, size_t err_cap) {
    static const char scheme[] = "udp://";
    const char *rest, *q, *end;
    size_t n;
    if (err != NULL && err_cap > 0) {
        err[0] = '\0';
    }
    if (out == NULL || url == NULL) {
        return fail(err, err_cap, "no URL", NULL, 0, "");
    }
    memset(out, 0, sizeof *out);
    out->ttl = 1;
    out->hello_ms = 1000;
    out->mtu = AYL_MTU;
    out->spin_us = 50;
    n = strlen(url);
    if (n < sizeof scheme - 1 || memcmp(url, scheme, sizeof scheme - 1) != 0) {
        return fail(err, err_cap, "", url, n, ": expected udp://HOST:PORT?...");
    }
    rest = url + sizeof scheme - 1;
    end = url + n;
    q = rest;
    while (q < end && *q != '?') {
        q++;
    }
    if (address(rest, (size_t)(q - rest), "bind address ", &out->bind, err, err_cap) != 0) {
        return AYL_E_INVALID;
    }
    while (q < end) {
        const char *pair = q + 1, *amp = pair, *eq;
        while (amp < end && *amp != '&') {
            amp++;
        }
        q = amp;
        if (amp == pair) {
            continue; /* empty pairs (`?&team=3&&`) are skipped */
        }
        eq = pair;
        while (eq < amp && *eq != '=') {
            eq++;
        }
        if (eq == amp) {
            return fail(err, err_cap, "", pair, (size_t)(amp - pair), " is not key=value");
        }
        if (option(out, pair, (size_t)(eq - pair), eq + 1, (size_t)(amp - eq - 1), err, err_cap) != 0) {
            return AYL_E_INVALID;
        }
    }
    return 0;
}
