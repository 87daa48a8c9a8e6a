/*
 * test_url.c -- ayl_url_parse against the shared URL vectors (spec/vectors/urls.json), which
 * the Rust runtime's parser and AylluLite Python read too: every good URL gives exactly the
 * listed values, every other one is refused with a message naming the bad part. Then what the
 * vectors cannot say: defaults, host names left to the caller, the build's limits on peers and
 * groups, and error buffers that are small or absent.
 */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "../ayllu_lite.h"
#include "check.h"
#include "json.h"

static char file_buf[1 << 16];

static int str_is(ayl_str s, const jnode *want) { return s.len == want->len && memcmp(s.ptr, want->s, s.len) == 0; }

static int addr_is(const ayl_url_addr *a, const jnode *want) {
    char text[32];
    int n = snprintf(text, sizeof text, "%u.%u.%u.%u:%u", a->ip4[0], a->ip4[1], a->ip4[2], a->ip4[3], a->port);
    return !a->is_name && n > 0 && (size_t)n == want->len && memcmp(text, want->s, want->len) == 0;
}

static int hex_is(const uint8_t *bytes, const jnode *want) {
    char text[2 * AYL_KEY_LEN + 1];
    size_t i;
    for (i = 0; i < AYL_KEY_LEN; i++) {
        snprintf(text + 2 * i, 3, "%02x", bytes[i]);
    }
    return want->len == 2 * AYL_KEY_LEN && memcmp(text, want->s, want->len) == 0;
}

static int number_is(uint64_t got, int node) {
    uint64_t want = 0;
    return json_u64(node, &want) == 0 && got == want;
}

/* Whether member node f is called k (member names are not NUL-terminated). */
static int named(const jnode *f, const char *k) { return f->key_len == strlen(k) && memcmp(f->key, k, f->key_len) == 0; }

/* One listed field of a good vector against the parse. */
static void check_field(const char *name, const ayl_url *u, int field) {
    const jnode *f = json_node(field);
    int ok = 1;
    if (named(f, "ok")) {
        return;
    } else if (named(f, "bind")) {
        ok = addr_is(&u->bind, f);
    } else if (named(f, "team")) {
        ok = number_is(u->team, field);
    } else if (named(f, "key")) {
        ok = u->keyed && hex_is(u->key, f);
    } else if (named(f, "peers")) {
        int p;
        size_t i = 0;
        ok = (size_t)json_count(field) == u->npeers;
        for (p = f->first; ok && p >= 0; p = json_node(p)->next, i++) {
            ok = addr_is(&u->peers[i], json_node(p));
        }
    } else if (named(f, "broadcast")) {
        ok = u->has_broadcast && addr_is(&u->broadcast, f);
    } else if (named(f, "groups")) {
        int g;
        size_t i = 0;
        ok = (size_t)json_count(field) == u->ngroups;
        for (g = f->first; ok && g >= 0; g = json_node(g)->next, i++) {
            int gname = json_node(g)->first;
            ok = str_is(u->groups[i].name, json_node(gname)) &&
                 addr_is(&u->groups[i].addr, json_node(json_node(gname)->next));
        }
    } else if (named(f, "discovery")) {
        ok = u->has_discovery && addr_is(&u->discovery, f);
    } else if (named(f, "ttl")) {
        ok = number_is(u->ttl, field);
    } else if (named(f, "hello_ms")) {
        ok = number_is(u->hello_ms, field);
    } else if (named(f, "mtu")) {
        ok = number_is(u->mtu, field);
    } else if (named(f, "spin_us")) {
        ok = number_is(u->spin_us, field);
    } else if (named(f, "name")) {
        ok = str_is(u->name, f);
    } else if (named(f, "state")) {
        ok = str_is(u->state, f);
    } else if (named(f, "operator")) {
        ok = u->has_operator && hex_is(u->operator_key, f);
    } else {
        CHECK_MSG(0, "%s: the vector lists `%.*s`, which this test does not know", name, (int)f->key_len, f->key);
        return;
    }
    CHECK_MSG(ok, "%s: %.*s differs", name, (int)f->key_len, f->key);
}

static void vectors(const char *path) {
    FILE *f = fopen(path, "rb");
    size_t len;
    const char *jerr = NULL;
    int root, v, count = 0;
    if (f == NULL) {
        CHECK_MSG(0, "%s cannot be read", path);
        return;
    }
    len = fread(file_buf, 1, sizeof file_buf, f);
    fclose(f);
    CHECK(len < sizeof file_buf);
    root = json_parse(file_buf, len, &jerr);
    CHECK_MSG(root >= 0, "%s: %s", path, jerr ? jerr : "parse error");
    if (root < 0) {
        return;
    }
    for (v = json_node(json_get(root, "urls"))->first; v >= 0; v = json_node(v)->next, count++) {
        static char url[2048];
        const jnode *name = json_node(json_get(v, "name"));
        const jnode *text = json_node(json_get(v, "url"));
        int expect = json_get(v, "expect");
        int good = json_node(json_get(expect, "ok"))->t == J_TRUE;
        char err[200], label[64];
        ayl_url u;
        int rc, field;
        snprintf(label, sizeof label, "%.*s", (int)name->len, name->s);
        CHECK(text->len < sizeof url);
        memcpy(url, text->s, text->len);
        url[text->len] = '\0';
        rc = ayl_url_parse(&u, url, err, sizeof err);
        if (good) {
            CHECK_MSG(rc == 0, "%s: refused (%s), the vectors accept it", label, err);
            if (rc == 0) {
                for (field = json_node(expect)->first; field >= 0; field = json_node(field)->next) {
                    check_field(label, &u, field);
                }
            }
        } else {
            const jnode *mentions = json_node(json_get(expect, "mentions"));
            char want[64];
            snprintf(want, sizeof want, "%.*s", (int)mentions->len, mentions->s);
            CHECK_MSG(rc == AYL_E_INVALID, "%s: accepted, the vectors refuse it", label);
            CHECK_MSG(strstr(err, want) != NULL, "%s: `%s` does not mention `%s`", label, err, want);
        }
    }
    CHECK_MSG(count > 40, "the file holds the whole set (%d urls)", count);
}

static void defaults_names_and_limits(void) {
    ayl_url u;
    char err[120], tiny[8];
    char many[64 + 20 * (AYL_URL_MAX_PEERS + 1)];
    int i;
    size_t n;

    CHECK(ayl_url_parse(&u, AYL_URL_DEFAULT, err, sizeof err) == 0);
    CHECK(u.team == 0 && !u.keyed && u.npeers == 0 && !u.has_broadcast && u.ngroups == 0);
    CHECK(u.has_discovery && u.discovery.ip4[0] == 239 && u.discovery.port == 7390 && u.ttl == 0);
    CHECK(u.hello_ms == 1000 && u.mtu == AYL_MTU && u.spin_us == 50 && u.name.len == 0);
    CHECK(ayl_url_parse(&u, "udp://0.0.0.0:0", err, sizeof err) == 0 && u.ttl == 1);

    /* A host name is the caller's to resolve: kept as text. */
    CHECK(ayl_url_parse(&u, "udp://0.0.0.0:0?peer=robot-1.local:7400&discovery=mcast.lan:7400", err, sizeof err) ==
          0);
    CHECK(u.npeers == 1 && u.peers[0].is_name && u.peers[0].port == 7400);
    CHECK(u.peers[0].host.len == 13 && memcmp(u.peers[0].host.ptr, "robot-1.local", 13) == 0);
    CHECK(u.has_discovery && u.discovery.is_name);

    /* The build keeps AYL_URL_MAX_PEERS peers and refuses more, naming the option. */
    n = (size_t)snprintf(many, sizeof many, "udp://0.0.0.0:0?");
    for (i = 0; i < AYL_URL_MAX_PEERS; i++) {
        n += (size_t)snprintf(many + n, sizeof many - n, "peer=10.0.0.%d:7400&", i + 1);
    }
    CHECK(ayl_url_parse(&u, many, err, sizeof err) == 0 && u.npeers == AYL_URL_MAX_PEERS);
    snprintf(many + n, sizeof many - n, "peer=10.0.1.1:7400");
    CHECK(ayl_url_parse(&u, many, err, sizeof err) == AYL_E_INVALID && strstr(err, "AYL_URL_MAX_PEERS") != NULL);

    /* Error buffers: cut and terminated when small; none at all is fine. */
    memset(tiny, 'x', sizeof tiny);
    CHECK(ayl_url_parse(&u, "udp://0.0.0.0:0?colour=red", tiny, sizeof tiny) == AYL_E_INVALID);
    CHECK(tiny[sizeof tiny - 1] == '\0' && strlen(tiny) == sizeof tiny - 1);
    CHECK(ayl_url_parse(&u, "udp://0.0.0.0:0?colour=red", NULL, 0) == AYL_E_INVALID);
    CHECK(ayl_url_parse(&u, "udp://0.0.0.0:0?colour=red", tiny, 0) == AYL_E_INVALID);
    CHECK(ayl_url_parse(NULL, "udp://0.0.0.0:0", err, sizeof err) == AYL_E_INVALID);
    CHECK(ayl_url_parse(&u, NULL, err, sizeof err) == AYL_E_INVALID);

    /* The message quotes the bad text. */
    CHECK(ayl_url_parse(&u, "udp://0.0.0.0:0?team=+7", err, sizeof err) == AYL_E_INVALID);
    CHECK(strcmp(err, "team `+7` is not a u32") == 0);
}

/* Mutated URLs (bytes flipped, cut, the grammar's own characters inserted), a bounded
 * deterministic run: under the tests' AddressSanitizer/UBSan build any read outside the URL or
 * the error buffer fails; every result is 0 or AYL_E_INVALID, and text fields point into the
 * URL. (libFuzzer covers the runtime's parser: fuzz/fuzz_targets/udp_url.rs.) */
static void mutations(void) {
    static const char *const seeds[] = {
        AYL_URL_DEFAULT,
        "udp://127.0.0.1:7400?team=7&key=00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff"
        "&peer=10.0.0.2:7401&group=Peers@239.1.2.3:7500&name=r1&state=/x&mtu=1200&operator_secret=/k",
        "udp://robot.local:1?peer=a.b:2&broadcast=255.255.255.255:3&discovery=239.1.1.1:4&hello_ms=5",
    };
    static const char specials[] = "&=?:@.[]+-09aZ%";
    uint32_t rng = 12345u;
    int i;
    for (i = 0; i < 20000; i++) {
        char url[300], err[40];
        const char *seed = seeds[i % 3];
        size_t n = strlen(seed), edits, e;
        ayl_url u;
        int rc;
        memcpy(url, seed, n + 1);
        rng = rng * 1103515245u + 12345u;
        edits = 1 + (rng >> 16) % 4;
        for (e = 0; e < edits && n > 0; e++) {
            size_t at;
            rng = rng * 1103515245u + 12345u;
            at = (rng >> 8) % n;
            switch ((rng >> 24) % 4) {
            case 0: url[at] = (char)((rng >> 3) & 0xff); if (url[at] == '\0') url[at] = 'x'; break;
            case 1: url[at] = specials[(rng >> 4) % (sizeof specials - 1)]; break;
            case 2: n = at; url[n] = '\0'; break;
            default:
                if (n + 1 < sizeof url) {
                    memmove(url + at + 1, url + at, n - at + 1);
                    url[at] = specials[(rng >> 5) % (sizeof specials - 1)];
                    n++;
                }
            }
        }
        rc = ayl_url_parse(&u, url, err, sizeof err);
        CHECK(rc == 0 || rc == AYL_E_INVALID);
        if (rc == 0) {
            CHECK(u.bind.host.ptr >= url && u.bind.host.ptr + u.bind.host.len <= url + n);
            CHECK(u.name.len == 0 || (u.name.ptr >= url && u.name.ptr + u.name.len <= url + n));
            CHECK(u.npeers <= AYL_URL_MAX_PEERS && u.ngroups <= AYL_URL_MAX_GROUPS);
        } else {
            CHECK(strlen(err) < sizeof err && err[0] != '\0');
        }
    }
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s spec/vectors/urls.json\n", argv[0]);
        return 2;
    }
    vectors(argv[1]);
    defaults_names_and_limits();
    mutations();
    return check_exit("test_url");
}
