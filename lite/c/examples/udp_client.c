/*
 * udp_client.c -- an AylluLite C client over POSIX UDP sockets: writes a port on an Ayllu node
 * (or any AylluLite peer) with any connection kind, or reads one.
 *
 * What it is for: showing how the caller-supplied send/receive functions, buffers and clock of
 * ayllu_lite.h are wired to a real socket, and giving a command-line tool to poke a running
 * team. It promises nothing beyond that: one socket, blocking only in short sleeps, no malloc.
 *
 *   udp_client [options] HOST PORT BEHAVIOR PORTNAME VALUE    write VALUE (--count times)
 *   udp_client [options] --read HOST PORT BEHAVIOR PORTNAME   print the port's value
 *
 * VALUE: true/false (bool), an integer (int), a decimal number (float), vec:1,2.5 (vector),
 * hex:00ff (bytes), anything else (text; text:... forces text).
 * Configuration: the udp:// URL in AYLLU_URL, else the shared default (as every Ayllu program;
 * parsed whole by ayl_url_parse, so a bad option is refused): its team=, key=, mtu= and
 * hello_ms=; --team and --key override them. The peer is given on the command line.
 * Options: --team N (0), --node N (900), --kind normal|suppress|inhibit|override-in|
 * override-out|write-inhibit, --period-ms N (special kinds; default 500), --priority N,
 * --key HEX64 (authenticated team), --count N (1), --interval-ms N (100).
 */
#define _POSIX_C_SOURCE 200809L

#include <arpa/inet.h>
#include <errno.h>
#include <netdb.h>
#include <netinet/in.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "../ayllu_lite.h"
#include "posix_udp.h"

static int sock = -1;

static uint64_t now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static void sleep_ms(long ms) {
    struct timespec ts;
    ts.tv_sec = ms / 1000;
    ts.tv_nsec = (ms % 1000) * 1000000L;
    nanosleep(&ts, NULL);
}

static int parse_hex(const char *s, uint8_t *out, size_t cap, size_t *len) {
    size_t n = strlen(s), i;
    if (n % 2 != 0 || n / 2 > cap) {
        return -1;
    }
    for (i = 0; i < n / 2; i++) {
        unsigned v;
        if (sscanf(s + 2 * i, "%2x", &v) != 1) {
            return -1;
        }
        out[i] = (uint8_t)v;
    }
    *len = n / 2;
    return 0;
}

static uint8_t bytes_buf[1024];
static double vec_buf[255];

static ayl_value parse_value(const char *s) {
    char *end;
    long long i;
    double d;
    if (strcmp(s, "true") == 0 || strcmp(s, "false") == 0) {
        return ayl_bool(s[0] == 't');
    }
    if (strncmp(s, "text:", 5) == 0) {
        return ayl_text(s + 5);
    }
    if (strncmp(s, "hex:", 4) == 0) {
        size_t n = 0;
        if (parse_hex(s + 4, bytes_buf, sizeof bytes_buf, &n) == 0) {
            return ayl_bytes(bytes_buf, n);
        }
    }
    if (strncmp(s, "vec:", 4) == 0) {
        size_t n = 0;
        const char *p = s + 4;
        while (*p && n < 255) {
            vec_buf[n++] = strtod(p, &end);
            if (end == p) {
                break;
            }
            p = *end == ',' ? end + 1 : end;
        }
        return ayl_vector(vec_buf, n);
    }
    errno = 0;
    i = strtoll(s, &end, 10);
    if (*s && *end == '\0' && errno == 0) {
        return ayl_int((int64_t)i);
    }
    d = strtod(s, &end);
    if (*s && *end == '\0') {
        return ayl_float(d);
    }
    return ayl_text(s);
}

static void print_value(const ayl_value *v) {
    size_t i;
    switch (v->type) {
    case AYL_BOOL:
        printf("%s\n", v->u.b ? "true" : "false");
        break;
    case AYL_INT:
        printf("%lld\n", (long long)v->u.i);
        break;
    case AYL_FLOAT:
        printf("%.17g\n", ayl_value_float(v));
        break;
    case AYL_TEXT:
        printf("%.*s\n", (int)v->u.data.len, (const char *)v->u.data.ptr);
        break;
    case AYL_BYTES:
        for (i = 0; i < v->u.data.len; i++) {
            printf("%02x", v->u.data.ptr[i]);
        }
        printf("\n");
        break;
    case AYL_VECTOR:
        for (i = 0; i < v->u.vec.n; i++) {
            printf("%s%.17g", i ? "," : "", ayl_value_vector_at(v, i));
        }
        printf("\n");
        break;
    }
}

static int usage(void) {
    fprintf(stderr, "usage: udp_client [--team N] [--node N] [--kind K] [--period-ms N] [--priority N]\n"
                    "                  [--key HEX64] [--count N] [--interval-ms N]\n"
                    "                  HOST PORT BEHAVIOR PORTNAME VALUE\n"
                    "       udp_client [--team N] [--node N] [--key HEX64] --read HOST PORT BEHAVIOR PORTNAME\n");
    return 2;
}

int main(int argc, char **argv) {
    static const char *const kinds[] = {"normal", "suppress", "inhibit", "override-in", "override-out",
                                        "write-inhibit"};
    static ayl_port ports[1];
    static ayl_peer peers[8];
    static ayl_seq_entry seqs[8];
    static ayl_pending pending[1];
    static uint8_t rx[AYL_MAX_DATAGRAM], tx[AYL_MAX_DATAGRAM], out[4096];
    static char url_text[4096];
    ayl_url url;
    uint32_t team = 0, node_id = 900;
    int kind = AYL_NORMAL, count = 1, read_mode = 0, a;
    long period_ms = 500, interval_ms = 100;
    int32_t priority = 0;
    uint8_t key[AYL_KEY_LEN];
    int keyed = 0;
    const char *pos[5];
    int npos = 0;
    struct addrinfo hints, *res = NULL;
    ayl_node_config cfg;
    ayl_node node;
    ayl_addr to;

    if (posix_env_url(&url, url_text, sizeof url_text) < 0) {
        return 2;
    }
    team = url.team;
    if (url.keyed) {
        memcpy(key, url.key, AYL_KEY_LEN);
        keyed = 1;
    }
    for (a = 1; a < argc; a++) {
        const char *o = argv[a];
        const char *arg = a + 1 < argc ? argv[a + 1] : NULL;
        if (strcmp(o, "--read") == 0) {
            read_mode = 1;
        } else if (strncmp(o, "--", 2) == 0 && arg == NULL) {
            return usage();
        } else if (strcmp(o, "--team") == 0) {
            team = (uint32_t)strtoul(argv[++a], NULL, 10);
        } else if (strcmp(o, "--node") == 0) {
            node_id = (uint32_t)strtoul(argv[++a], NULL, 10);
        } else if (strcmp(o, "--kind") == 0) {
            for (kind = 0; kind < 6 && strcmp(kinds[kind], arg) != 0; kind++) {
            }
            if (kind == 6) {
                return usage();
            }
            a++;
        } else if (strcmp(o, "--period-ms") == 0) {
            period_ms = strtol(argv[++a], NULL, 10);
        } else if (strcmp(o, "--priority") == 0) {
            priority = (int32_t)strtol(argv[++a], NULL, 10);
        } else if (strcmp(o, "--count") == 0) {
            count = atoi(argv[++a]);
        } else if (strcmp(o, "--interval-ms") == 0) {
            interval_ms = strtol(argv[++a], NULL, 10);
        } else if (strcmp(o, "--key") == 0) {
            size_t n = 0;
            if (parse_hex(argv[++a], key, sizeof key, &n) < 0 || n != AYL_KEY_LEN) {
                fprintf(stderr, "udp_client: a key is 64 hex digits\n");
                return 2;
            }
            keyed = 1;
        } else if (npos < 5) {
            pos[npos++] = o;
        } else {
            return usage();
        }
    }
    if (npos != (read_mode ? 4 : 5)) {
        return usage();
    }

    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_DGRAM;
    if (getaddrinfo(pos[0], pos[1], &hints, &res) != 0 || res->ai_addrlen > AYL_ADDR_SIZE) {
        fprintf(stderr, "udp_client: cannot resolve %s:%s\n", pos[0], pos[1]);
        return 1;
    }
    to.len = (uint8_t)res->ai_addrlen;
    memcpy(to.bytes, res->ai_addr, res->ai_addrlen);
    sock = socket(res->ai_family, SOCK_DGRAM, 0);
    freeaddrinfo(res);
    if (sock < 0) {
        perror("socket");
        return 1;
    }

    memset(&cfg, 0, sizeof cfg);
    cfg.node_id = node_id;
    cfg.team = team;
    cfg.key = keyed ? key : NULL;
    {
        /* spec: boot_seconds << 32; the low bits take the fraction of the second so that two
         * runs within one second (a script) do not reuse connection sequence numbers. */
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        cfg.seq_start = ((uint64_t)ts.tv_sec << 32) | (((uint64_t)ts.tv_nsec << 32) / 1000000000u);
    }
    cfg.send = posix_udp_send;
    cfg.recv = posix_udp_recv;
    cfg.io_user = &sock;
    cfg.ports = ports;
    cfg.max_ports = 1;
    cfg.peers = peers;
    cfg.max_peers = 8;
    cfg.seqs = seqs;
    cfg.max_seqs = 8;
    cfg.pending = pending;
    cfg.max_pending = 1;
    cfg.rx = rx;
    cfg.rx_cap = sizeof rx;
    cfg.tx = tx;
    cfg.tx_cap = url.mtu; /* the URL's mtu= (AYL_MTU unless it says otherwise) */
    cfg.hello_interval_ms = url.hello_ms;
    cfg.name = "udp_client";
    if (ayl_node_init(&node, &cfg) != 0) {
        fprintf(stderr, "udp_client: bad configuration\n");
        return 1;
    }

    if (read_mode) {
        ayl_request_msg q;
        ayl_reply_msg ans;
        uint64_t id;
        ayl_req_state st;
        memset(&q, 0, sizeof q);
        q.op = AYL_OP_READ;
        q.behavior = ayl_s(pos[2]);
        q.port = ayl_s(pos[3]);
        if (ayl_node_request(&node, &to, &q, out, sizeof out, &id) != 0) {
            fprintf(stderr, "udp_client: cannot send the request\n");
            return 1;
        }
        /* Retries happen inside poll, every 200 ms, up to 25 sends (N2). */
        while ((st = ayl_node_request_take(&node, id, &ans, NULL)) == AYL_REQ_PENDING) {
            ayl_node_poll(&node, now_ns());
            sleep_ms(5);
        }
        if (st != AYL_REQ_DONE) {
            fprintf(stderr, "udp_client: no answer\n");
            return 1;
        }
        if (ans.result == AYL_RESULT_ERROR) {
            fprintf(stderr, "udp_client: %.*s\n", (int)ans.text.len, ans.text.ptr);
            return 1;
        }
        print_value(&ans.value);
    } else {
        ayl_conn c;
        ayl_value v = parse_value(pos[4]);
        uint64_t period = kind == AYL_NORMAL ? 0 : (uint64_t)period_ms * 1000000u;
        int i;
        if (ayl_conn_open(&node, &c, &to, pos[2], pos[3], (ayl_conn_kind)kind, period, priority) != 0) {
            fprintf(stderr, "udp_client: bad connection (names, or period with kind)\n");
            return 1;
        }
        for (i = 0; i < count; i++) {
            int rc = ayl_conn_send(&node, &c, &v);
            if (rc != 0) {
                fprintf(stderr, "udp_client: send failed (%d)\n", rc);
                return 1;
            }
            ayl_node_poll(&node, now_ns()); /* also answers anything that came in */
            if (i + 1 < count) {
                sleep_ms(interval_ms);
            }
        }
    }
    close(sock);
    return 0;
}
