/*
 * conformance_client.c -- the AylluLite C side of the live-node conformance check
 * (spec/conformance.md, check 2; driven by spec/conformance).
 *
 * What it is for: letting the conformance script drive the C library against a running
 * `ayllu node`, one step at a time, with every byte encoded and decoded by ayllu_lite.c (the
 * script never encodes on this client's behalf). It is one long-lived lite node -- one socket,
 * one node id, one set of connections and sequence numbers -- so that windows, suppliers and
 * connections the script checks belong to the same holder from step to step, and so that an
 * exposed port keeps receiving while the script waits.
 *
 *   conformance_client --node N --team T [--key HEX64] [--raw-node N] IPV4 PORT
 *
 * Protocol: one command per line on stdin, exactly one answer line on stdout, "ok ..." or
 * "err WHY". Values are typed: i:5 (int), f:2.5 (float), b:true (bool), t:word (text).
 *
 *   read B P                       READ        -> ok VALUE
 *   write KIND PERIOD_MS B P VALUE PORT along this client's connection for (KIND, PERIOD, B, P)
 *                                              -> ok CONN   (the connection id the node sees)
 *   why B P | list                 WHY / LIST  -> ok JSON   (the reassembled report, one line)
 *   connect SB SP DB DP            ask the node to connect its SB.SP to this client's DB.DP
 *                                              -> ok CONN
 *   disconnect CONN                            -> ok
 *   expose B P VALUE               expose a lite port -> ok
 *   get B P                        a lite port -> ok VALUE WRITES SENDER CONN (last writer)
 *   raw CASE [VALUE VALUE]         send a deliberately malformed datagram (see craft()) -> ok LEN
 *   challenged                     CHALLENGEs received and echoed so far -> ok N
 *   quit
 *
 * Between commands the client keeps polling its socket (HELLO, incoming PORT messages), so the
 * node keeps it as a peer and can deliver to its exposed ports. No malloc: every table and
 * buffer is static. Every request gives up after REQUEST_TIMEOUT_NS, so the script's waits are
 * bounded by this side too.
 */
#define _POSIX_C_SOURCE 200809L

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#include "../ayllu_lite.h"
#include "posix_udp.h"
#include "../ayllu_sha256.h"

#define MAX_CONNS 16
#define MAX_PORTS 4
#define NAME_MAX_LEN 64
#define LINE_MAX_LEN 512
#define MAX_ARGS 8
/* Below the library's own 25 x 200 ms, so a dead node costs the script seconds, not minutes. */
#define REQUEST_TIMEOUT_NS 3000000000ull
/* A message kind no version of the protocol uses, for the unknown_kind case. */
#define UNKNOWN_KIND 0x7e

static int sock = -1;
/* Crafted datagrams leave from their own socket, as the Python side's do: the node greets a new
 * sender id with HELLO and a CHALLENGE whose cookie is bound to that id and address, and this
 * lite node, were it on the same socket, would echo a cookie that is not its own (bad_cookie). */
static int raw_sock = -1;
static ayl_node node;
static ayl_addr target; /* the Ayllu node under test */
static uint8_t key[AYL_KEY_LEN];
static int keyed;
static uint32_t raw_node;  /* sender id of the crafted datagrams: its own replay window */
static uint64_t raw_seq;   /* datagram sequence numbers of raw_node */
static uint64_t raw_conn_seq; /* PORT sequence numbers of raw_node's connections */

static ayl_port ports[MAX_PORTS];
static ayl_peer peers[8];
static ayl_seq_entry seqs[32];
static ayl_pending pending[1];
static uint8_t rx[AYL_MAX_DATAGRAM], tx[AYL_MTU];
static uint8_t answer_buf[96 * 1024]; /* a LIST report: up to 64 parts of an MTU */
static uint8_t raw_buf[AYL_MAX_DATAGRAM + 64];

/* Connections this client writes along, reused like LiteNode.write in Python: repeated writes
 * of one kind to one port travel along one connection and hold one pass. Names are copied here
 * because an ayl_conn keeps pointers to them. */
static struct {
    int used;
    char behavior[NAME_MAX_LEN];
    char port[NAME_MAX_LEN];
    ayl_conn c;
} conns[MAX_CONNS];

/* Exposed ports: names (the node keeps pointers) and who wrote them last. */
struct exposed_port {
    char behavior[NAME_MAX_LEN];
    char port[NAME_MAX_LEN];
    uint32_t sender;
    uint64_t conn;
};
static struct exposed_port exposed[MAX_PORTS];

static uint64_t now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

/* Wait for the socket (or the timeout), then let the node handle what arrived. */
static void pump(int timeout_ms) {
    struct pollfd p;
    p.fd = sock;
    p.events = POLLIN;
    p.revents = 0;
    (void)poll(&p, 1, timeout_ms);
    ayl_node_poll(&node, now_ns());
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

/* "i:5", "f:2.5", "b:true", "t:word". Returns 0 or -1. Text points into `s`. */
static int parse_value(const char *s, ayl_value *v) {
    char *end;
    if (strncmp(s, "i:", 2) == 0) {
        long long i;
        errno = 0;
        i = strtoll(s + 2, &end, 10);
        if (s[2] == '\0' || *end != '\0' || errno != 0) {
            return -1;
        }
        *v = ayl_int((int64_t)i);
        return 0;
    }
    if (strncmp(s, "f:", 2) == 0) {
        double d = strtod(s + 2, &end);
        if (s[2] == '\0' || *end != '\0') {
            return -1;
        }
        *v = ayl_float(d);
        return 0;
    }
    if (strcmp(s, "b:true") == 0 || strcmp(s, "b:false") == 0) {
        *v = ayl_bool(s[2] == 't');
        return 0;
    }
    if (strncmp(s, "t:", 2) == 0) {
        *v = ayl_text(s + 2);
        return 0;
    }
    return -1;
}

static void print_value(const ayl_value *v) {
    switch (v->type) {
    case AYL_BOOL:
        printf("b:%s", v->u.b ? "true" : "false");
        break;
    case AYL_INT:
        printf("i:%lld", (long long)v->u.i);
        break;
    case AYL_FLOAT:
        printf("f:%.17g", ayl_value_float(v));
        break;
    case AYL_TEXT:
        printf("t:%.*s", (int)v->u.data.len, (const char *)v->u.data.ptr);
        break;
    default:
        printf("x:unsupported");
        break;
    }
}

static int kind_from_name(const char *s) {
    static const char *const names[] = {"normal", "suppress", "inhibit", "override-in", "override-out",
                                        "write-inhibit"};
    int k;
    for (k = 0; k < 6; k++) {
        if (strcmp(names[k], s) == 0) {
            return k;
        }
    }
    return -1;
}

/* Send a request and wait for its whole answer. 0: *ans is the answer (ok or error reply);
 * -1: no answer (the message is in *why). */
static int request(const ayl_request_msg *q, ayl_reply_msg *ans, const char **why) {
    uint64_t id, deadline;
    int overflow = 0;
    ayl_req_state st;
    ayl_node_poll(&node, now_ns()); /* fresh time, so the first send is not repeated at once */
    if (ayl_node_request(&node, &target, q, answer_buf, sizeof answer_buf, &id) != 0) {
        *why = "cannot send the request";
        return -1;
    }
    deadline = now_ns() + REQUEST_TIMEOUT_NS;
    while ((st = ayl_node_request_take(&node, id, ans, &overflow)) == AYL_REQ_PENDING) {
        if (now_ns() > deadline) {
            ayl_node_request_cancel(&node, id);
            *why = "timeout: no answer from the node";
            return -1;
        }
        pump(5);
    }
    if (st != AYL_REQ_DONE) {
        *why = "no answer after every retry";
        return -1;
    }
    if (overflow) {
        *why = "answer larger than the client's buffer";
        return -1;
    }
    return 0;
}

/* Print a request's outcome as the answer line; `what` says which result an ok reply has. */
static void answer_request(const ayl_request_msg *q, ayl_result what) {
    ayl_reply_msg a;
    const char *why = "";
    if (request(q, &a, &why) != 0) {
        printf("err %s\n", why);
        return;
    }
    if (a.result == AYL_RESULT_ERROR) {
        printf("err node says: %.*s\n", (int)a.text.len, a.text.ptr);
        return;
    }
    if (a.result != what) {
        printf("err the reply carries result %d, expected %d\n", (int)a.result, (int)what);
        return;
    }
    switch (what) {
    case AYL_RESULT_VALUE:
        printf("ok ");
        print_value(&a.value);
        printf("\n");
        break;
    case AYL_RESULT_REPORT:
        printf("ok %.*s\n", (int)a.text.len, a.text.ptr);
        break;
    case AYL_RESULT_CONNECTION:
        printf("ok %llu\n", (unsigned long long)a.conn);
        break;
    default:
        printf("err unexpected result\n");
        break;
    }
}

static int copy_name(char *dst, const char *src) {
    if (strlen(src) >= NAME_MAX_LEN) {
        return -1;
    }
    strcpy(dst, src);
    return 0;
}

static void cmd_write(const char *kind_s, const char *period_s, const char *b, const char *p, const char *val) {
    int kind = kind_from_name(kind_s), i, slot = -1;
    uint64_t period = (uint64_t)strtoull(period_s, NULL, 10) * 1000000u;
    ayl_value v;
    if (kind < 0 || parse_value(val, &v) != 0) {
        printf("err bad kind or value\n");
        return;
    }
    for (i = 0; i < MAX_CONNS; i++) {
        if (conns[i].used && conns[i].c.kind == (ayl_conn_kind)kind && conns[i].c.period_ns == period &&
            strcmp(conns[i].behavior, b) == 0 && strcmp(conns[i].port, p) == 0) {
            slot = i;
            break;
        }
    }
    if (slot < 0) {
        for (i = 0; i < MAX_CONNS && slot < 0; i++) {
            if (!conns[i].used) {
                slot = i;
            }
        }
        if (slot < 0 || copy_name(conns[slot].behavior, b) != 0 || copy_name(conns[slot].port, p) != 0 ||
            ayl_conn_open(&node, &conns[slot].c, &target, conns[slot].behavior, conns[slot].port,
                          (ayl_conn_kind)kind, period, 0) != 0) {
            printf("err cannot open the connection (table full, names, or period with kind)\n");
            return;
        }
        conns[slot].used = 1;
    }
    i = ayl_conn_send(&node, &conns[slot].c, &v);
    if (i != 0) {
        printf("err send failed (%d)\n", i);
        return;
    }
    printf("ok %llu\n", (unsigned long long)conns[slot].c.conn);
}

/* Remembers who wrote an exposed port last: `user` is its exposed[] entry. */
static void on_write(void *user, const char *behavior, const char *port, const ayl_value *value, uint32_t sender,
                     uint64_t conn) {
    (void)behavior;
    (void)port;
    (void)value;
    ((struct exposed_port *)user)->sender = sender;
    ((struct exposed_port *)user)->conn = conn;
}

static void cmd_expose(const char *b, const char *p, const char *val) {
    int k, rc;
    ayl_value v;
    for (k = 0; k < MAX_PORTS && ports[k].behavior != NULL; k++) {
    }
    if (k == MAX_PORTS || parse_value(val, &v) != 0 || v.type == AYL_TEXT || copy_name(exposed[k].behavior, b) != 0 ||
        copy_name(exposed[k].port, p) != 0) {
        printf("err cannot expose (table full, names, or value; only bool/int/float)\n");
        return;
    }
    rc = ayl_node_expose(&node, exposed[k].behavior, exposed[k].port, &v, NULL, 0, on_write, &exposed[k]);
    if (rc < 0) {
        printf("err ayl_node_expose: %d\n", rc);
        return;
    }
    printf("ok\n");
}

static void cmd_get(const char *b, const char *p) {
    int k;
    ayl_node_poll(&node, now_ns()); /* apply whatever already arrived */
    for (k = 0; k < MAX_PORTS; k++) {
        if (ports[k].behavior != NULL && strcmp(exposed[k].behavior, b) == 0 && strcmp(exposed[k].port, p) == 0) {
            printf("ok ");
            print_value(&ports[k].value);
            printf(" %llu %lu %llu\n", (unsigned long long)ports[k].writes, (unsigned long)exposed[k].sender,
                   (unsigned long long)exposed[k].conn);
            return;
        }
    }
    printf("err no such exposed port\n");
}

/* Replace the MAC of an authenticated datagram of `len` bytes (MAC included) after its content
 * was changed, so the change -- not the MAC -- is what the receiver finds wrong. */
static void resign(uint8_t *buf, size_t len) {
    uint8_t mac[AYL_SHA256_LEN];
    ayl_hmac_sha256(key, AYL_KEY_LEN, buf, len - AYL_MAC_LEN, NULL, 0, mac);
    memcpy(buf + len - AYL_MAC_LEN, mac, AYL_MAC_LEN);
}

/* A PORT sent to `group` (NULL: node-addressed), as a node writing a group's port sends it. */
static int add_group_port(ayl_writer *w, uint64_t conn, const char *b, const char *p, const ayl_value *v,
                          const char *group) {
    ayl_msg m;
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_PORT;
    m.u.port.conn = conn;
    m.u.port.seq = ++raw_conn_seq;
    m.u.port.kind = AYL_NORMAL;
    m.u.port.behavior = ayl_s(b);
    m.u.port.port = ayl_s(p);
    m.u.port.value = *v;
    m.u.port.group = ayl_s(group);
    return ayl_writer_add(w, &m);
}

static int add_port(ayl_writer *w, uint64_t conn, const char *b, const char *p, const ayl_value *v) {
    return add_group_port(w, conn, b, p, v, NULL);
}

static int add_hello(ayl_writer *w) {
    ayl_msg m;
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_HELLO;
    m.u.hello.interval_ms = 1000;
    m.u.hello.name = ayl_s("raw");
    return ayl_writer_add(w, &m);
}

/* Build the datagram of a malformed-input case into raw_buf, from raw_node. Returns its length,
 * or -1 for an unknown case. `a` and `b` are the values of the unknown_kind case. Valid
 * datagrams are built with the library's writer and then damaged, so exactly one thing is wrong
 * with each. */
static int craft(const char *cse, const ayl_value *a, const ayl_value *b, int *copies) {
    ayl_writer w;
    int len, auth = keyed;
    uint32_t team = node.cfg.team;
    static const uint8_t other_key[AYL_KEY_LEN] = {1, 2, 3};
    const uint8_t *k = keyed ? key : NULL;
    *copies = 1;
    if (strcmp(cse, "wrong_team") == 0) {
        team += 1;
    } else if (strcmp(cse, "unexpected_auth") == 0) {
        auth = 1; /* an open node must not trust a MAC it cannot check */
        k = other_key;
    } else if (strcmp(cse, "unauthenticated") == 0) {
        auth = 0;
        k = NULL;
    }
    if (ayl_writer_begin(&w, raw_buf, sizeof raw_buf, team, raw_node, ++raw_seq, auth) != 0) {
        return -1;
    }
    if (strcmp(cse, "unknown_kind") == 0) {
        /* PORT, a message of a kind nobody knows, PORT: the writer refuses unknown kinds, so
         * that one is written by hand between the two. */
        static const uint8_t unknown[] = {UNKNOWN_KIND, 4, 0, 'a', 'b', 'c', 'd'};
        if (a == NULL || b == NULL || add_port(&w, 1, "RELAY", "In", a) != 0) {
            return -1;
        }
        memcpy(w.buf + w.len, unknown, sizeof unknown);
        w.len += sizeof unknown;
        if (add_port(&w, 2, "FRELAY", "In", b) != 0) {
            return -1;
        }
    } else if (strcmp(cse, "malformed") == 0) {
        ayl_value v = ayl_int(-1);
        if (add_port(&w, 3, "RELAY", "In", &v) != 0) {
            return -1;
        }
    } else if (strcmp(cse, "not_member") == 0) {
        /* Well formed, but sent to a group the node has not joined (D-S10.6). */
        if (a == NULL || add_group_port(&w, 4, "RELAY", "In", a, "NotJoined") != 0) {
            return -1;
        }
    } else if (add_hello(&w) != 0) {
        return -1;
    }
    len = ayl_writer_finish(&w, k);
    if (len < 0) {
        return -1;
    }
    if (strcmp(cse, "truncated") == 0) {
        return 12; /* shorter than the header */
    }
    if (strcmp(cse, "truncated_message") == 0) {
        /* Cut the message's last 2 bytes, so its length runs past the end; with a key, the MAC
         * is recomputed over what is left and written where it now belongs. */
        len -= 2;
        if (keyed) {
            resign(raw_buf, (size_t)len);
        }
        return len;
    }
    if (strcmp(cse, "bad_magic") == 0) {
        raw_buf[0] = 'X';
    } else if (strcmp(cse, "bad_version") == 0) {
        raw_buf[2] = 2;
    } else if (strcmp(cse, "bad_flags") == 0) {
        raw_buf[3] |= 0x02;
    } else if (strcmp(cse, "bad_mac") == 0) {
        if (!keyed) {
            return -1;
        }
        raw_buf[len - 1] ^= 0x01;
    } else if (strcmp(cse, "malformed") == 0) {
        /* The PORT's connection kind byte: header, message header, conn and seq before it. */
        raw_buf[AYL_HEADER_LEN + 3 + 8 + 8] = 9;
        if (keyed) {
            resign(raw_buf, (size_t)len);
        }
    } else if (strcmp(cse, "oversized") == 0) {
        memset(raw_buf + AYL_HEADER_LEN, 0, AYL_MAX_DATAGRAM + 1 - AYL_HEADER_LEN);
        return AYL_MAX_DATAGRAM + 1;
    } else if (strcmp(cse, "replayed") == 0) {
        if (!keyed) {
            return -1;
        }
        *copies = 2; /* the first is applied, the second is the replay */
    } else if (strcmp(cse, "wrong_team") != 0 && strcmp(cse, "unexpected_auth") != 0 &&
               strcmp(cse, "unauthenticated") != 0 && strcmp(cse, "unknown_kind") != 0 &&
               strcmp(cse, "not_member") != 0) {
        return -1;
    }
    return len;
}

/* In a keyed team, make raw_node known fresh before its first crafted datagram: a node with no
 * memory of a keyed sender applies its PORTs only after it answered a CHALLENGE with an
 * authenticated ECHO (spec/protocol.md, "CHALLENGE and ECHO"; docs/semantics.md D-N5.4). A node
 * that does not challenge sends nothing, and the one-second wait ends. */
static void raw_fresh(void) {
    static int done;
    ayl_writer w;
    ayl_datagram d;
    ayl_msg m;
    uint8_t in[AYL_MAX_DATAGRAM];
    struct timeval tv = {1, 0}, none = {0, 0};
    int len;
    if (!keyed || done) {
        return;
    }
    done = 1;
    if (ayl_writer_begin(&w, raw_buf, sizeof raw_buf, node.cfg.team, raw_node, ++raw_seq, 1) != 0 ||
        add_hello(&w) != 0 || (len = ayl_writer_finish(&w, key)) < 0 ||
        posix_udp_send(&raw_sock, &target, raw_buf, (size_t)len) != 0) {
        return;
    }
    setsockopt(raw_sock, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    for (;;) {
        ssize_t n = recv(raw_sock, in, sizeof in, 0);
        if (n <= 0) {
            break;
        }
        if (ayl_decode(&d, in, (size_t)n, node.cfg.team, key) != AYL_OK) {
            continue;
        }
        while (ayl_next(&d, &m)) {
            if (m.kind == AYL_KIND_CHALLENGE) {
                m.kind = AYL_KIND_ECHO;
                if (ayl_writer_begin(&w, raw_buf, sizeof raw_buf, node.cfg.team, raw_node, ++raw_seq, 1) == 0 &&
                    ayl_writer_add(&w, &m) == 0 && (len = ayl_writer_finish(&w, key)) >= 0) {
                    (void)posix_udp_send(&raw_sock, &target, raw_buf, (size_t)len);
                }
                setsockopt(raw_sock, SOL_SOCKET, SO_RCVTIMEO, &none, sizeof none);
                return;
            }
        }
    }
    setsockopt(raw_sock, SOL_SOCKET, SO_RCVTIMEO, &none, sizeof none);
}

static void cmd_raw(int argc, char **argv) {
    ayl_value a, b;
    int have, copies, len, i;
    raw_fresh();
    have = argc >= 4 && parse_value(argv[2], &a) == 0 && parse_value(argv[3], &b) == 0;
    len = craft(argv[1], have ? &a : NULL, have ? &b : NULL, &copies);
    if (len < 0) {
        printf("err unknown case or values for this team mode: %s\n", argv[1]);
        return;
    }
    for (i = 0; i < copies; i++) {
        if (posix_udp_send(&raw_sock, &target, raw_buf, (size_t)len) != 0) {
            printf("err sendto failed\n");
            return;
        }
    }
    printf("ok %d\n", len);
}

/* Run one command line; returns 0 to go on, 1 to quit. */
static int command(char *line) {
    char *argv[MAX_ARGS];
    int argc = 0;
    char *save = NULL, *t;
    ayl_request_msg q;
    for (t = strtok_r(line, " \t\r", &save); t != NULL && argc < MAX_ARGS; t = strtok_r(NULL, " \t\r", &save)) {
        argv[argc++] = t;
    }
    if (argc == 0) {
        return 0;
    }
    memset(&q, 0, sizeof q);
    if (strcmp(argv[0], "quit") == 0) {
        printf("ok\n");
        return 1;
    } else if (strcmp(argv[0], "read") == 0 && argc == 3) {
        q.op = AYL_OP_READ;
        q.behavior = ayl_s(argv[1]);
        q.port = ayl_s(argv[2]);
        answer_request(&q, AYL_RESULT_VALUE);
    } else if (strcmp(argv[0], "why") == 0 && argc == 3) {
        q.op = AYL_OP_WHY;
        q.behavior = ayl_s(argv[1]);
        q.port = ayl_s(argv[2]);
        answer_request(&q, AYL_RESULT_REPORT);
    } else if (strcmp(argv[0], "challenged") == 0 && argc == 1) {
        printf("ok %llu\n", (unsigned long long)node.challenged);
    } else if (strcmp(argv[0], "list") == 0 && argc == 1) {
        q.op = AYL_OP_LIST;
        answer_request(&q, AYL_RESULT_REPORT);
    } else if (strcmp(argv[0], "connect") == 0 && argc == 5) {
        q.op = AYL_OP_CONNECT;
        q.src_behavior = ayl_s(argv[1]);
        q.src_port = ayl_s(argv[2]);
        q.dest.node = node.cfg.node_id;
        q.dest.behavior = ayl_s(argv[3]);
        q.dest.port = ayl_s(argv[4]);
        q.kind = AYL_NORMAL;
        answer_request(&q, AYL_RESULT_CONNECTION);
    } else if (strcmp(argv[0], "disconnect") == 0 && argc == 2) {
        q.op = AYL_OP_DISCONNECT;
        q.conn = (uint64_t)strtoull(argv[1], NULL, 10);
        answer_request(&q, AYL_RESULT_CONNECTION);
    } else if (strcmp(argv[0], "write") == 0 && argc == 6) {
        cmd_write(argv[1], argv[2], argv[3], argv[4], argv[5]);
    } else if (strcmp(argv[0], "expose") == 0 && argc == 4) {
        cmd_expose(argv[1], argv[2], argv[3]);
    } else if (strcmp(argv[0], "get") == 0 && argc == 3) {
        cmd_get(argv[1], argv[2]);
    } else if (strcmp(argv[0], "raw") == 0 && argc >= 2) {
        cmd_raw(argc, argv);
    } else {
        printf("err unknown command or wrong number of arguments: %s\n", argv[0]);
    }
    return 0;
}

static int usage(void) {
    fprintf(stderr, "usage: conformance_client --node N --team T [--key HEX64] [--raw-node N] IPV4 PORT\n"
                    "       then commands on stdin (see the comment at the top of conformance_client.c)\n");
    return 2;
}

int main(int argc, char **argv) {
    static char line[LINE_MAX_LEN];
    size_t fill = 0;
    uint32_t node_id = 800, team = 0;
    const char *pos[2];
    int npos = 0, a, done = 0;
    ayl_node_config cfg;

    for (a = 1; a < argc; a++) {
        const char *o = argv[a];
        if (strncmp(o, "--", 2) == 0 && a + 1 >= argc) {
            return usage();
        }
        if (strcmp(o, "--node") == 0) {
            node_id = (uint32_t)strtoul(argv[++a], NULL, 10);
        } else if (strcmp(o, "--team") == 0) {
            team = (uint32_t)strtoul(argv[++a], NULL, 10);
        } else if (strcmp(o, "--raw-node") == 0) {
            raw_node = (uint32_t)strtoul(argv[++a], NULL, 10);
        } else if (strcmp(o, "--key") == 0) {
            size_t n = 0;
            if (parse_hex(argv[++a], key, sizeof key, &n) < 0 || n != AYL_KEY_LEN) {
                fprintf(stderr, "conformance_client: a key is 64 hex digits\n");
                return 2;
            }
            keyed = 1;
        } else if (npos < 2) {
            pos[npos++] = o;
        } else {
            return usage();
        }
    }
    if (npos != 2) {
        return usage();
    }
    if (raw_node == 0) {
        raw_node = node_id + 50;
    }

    {
        /* A numeric IPv4 address only: getaddrinfo would allocate, and the script passes one. */
        struct sockaddr_in sa;
        char *end;
        unsigned long port = strtoul(pos[1], &end, 10);
        memset(&sa, 0, sizeof sa);
        sa.sin_family = AF_INET;
        sa.sin_port = htons((uint16_t)port);
        if (inet_pton(AF_INET, pos[0], &sa.sin_addr) != 1 || *end != '\0' || port == 0 || port > 65535) {
            fprintf(stderr, "conformance_client: %s:%s is not an IPv4 address and port\n", pos[0], pos[1]);
            return 1;
        }
        target.len = (uint8_t)sizeof sa;
        memcpy(target.bytes, &sa, sizeof sa);
    }
    sock = socket(AF_INET, SOCK_DGRAM, 0);
    raw_sock = socket(AF_INET, SOCK_DGRAM, 0);
    if (sock < 0 || raw_sock < 0) {
        perror("socket");
        return 1;
    }

    memset(&cfg, 0, sizeof cfg);
    cfg.node_id = node_id;
    cfg.team = team;
    cfg.key = keyed ? key : NULL;
    {
        /* spec: boot_seconds << 32, the low half the fraction of the second, so a client run
         * twice within one second (the script runs one per team mode) still counts upwards. */
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        cfg.seq_start = ((uint64_t)ts.tv_sec << 32) | (((uint64_t)ts.tv_nsec << 32) / 1000000000u);
        raw_seq = cfg.seq_start;
        raw_conn_seq = cfg.seq_start;
    }
    cfg.send = posix_udp_send;
    cfg.recv = posix_udp_recv;
    cfg.io_user = &sock;
    cfg.ports = ports;
    cfg.max_ports = MAX_PORTS;
    cfg.peers = peers;
    cfg.max_peers = sizeof peers / sizeof peers[0];
    cfg.seqs = seqs;
    cfg.max_seqs = sizeof seqs / sizeof seqs[0];
    cfg.pending = pending;
    cfg.max_pending = 1;
    cfg.rx = rx;
    cfg.rx_cap = sizeof rx;
    cfg.tx = tx;
    cfg.tx_cap = sizeof tx;
    cfg.name = "conformance_client";
    if (ayl_node_init(&node, &cfg) != 0 || ayl_node_add_peer(&node, 1, &target) != 0) {
        fprintf(stderr, "conformance_client: bad configuration\n");
        return 1;
    }
    /* Announce ourselves at once: the node learns our address from this HELLO. */
    ayl_node_poll(&node, now_ns());

    while (!done) {
        struct pollfd fds[2];
        fds[0].fd = 0;
        fds[0].events = POLLIN;
        fds[0].revents = 0;
        fds[1].fd = sock;
        fds[1].events = POLLIN;
        fds[1].revents = 0;
        (void)poll(fds, 2, 50); /* 50 ms: HELLOs stay on time while no command comes */
        ayl_node_poll(&node, now_ns());
        if (fds[0].revents & (POLLIN | POLLHUP)) {
            /* read(2), not stdio: poll(2) cannot see lines already in a stdio buffer. */
            ssize_t n = read(0, line + fill, sizeof line - 1 - fill);
            char *nl;
            if (n <= 0) {
                break; /* the script went away */
            }
            fill += (size_t)n;
            line[fill] = '\0';
            while (!done && (nl = strchr(line, '\n')) != NULL) {
                size_t used = (size_t)(nl - line) + 1;
                *nl = '\0';
                done = command(line);
                fflush(stdout);
                memmove(line, line + used, fill - used + 1);
                fill -= used;
            }
            if (fill == sizeof line - 1) {
                printf("err line too long\n");
                fflush(stdout);
                fill = 0;
            }
        }
    }
    close(sock);
    close(raw_sock);
    return 0;
}
