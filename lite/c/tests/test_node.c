/*
 * test_node.c -- the AylluLite C node logic through an in-memory network (no sockets, virtual
 * time): exposing ports, applying PORT writes with connection-kind semantics for storing,
 * stale and type drops, the PORT/REQUEST/HELLO datagrams the node builds (decoded and checked
 * field by field), requests with retries and multi-part report reassembly, READ/LIST served
 * by the lite node, answers held to 3x what their address sent (return routability), and
 * authentication with replay protection.
 */
#include <stdio.h>
#include <string.h>

#include "../ayllu_lite.h"
#include "check.h"

/* ----- an in-memory network: a FIFO of datagrams, each addressed by a one-byte address --------- */

#define NET_SLOTS 256
typedef struct {
    uint8_t to, from;
    size_t len;
    uint8_t data[AYL_MAX_DATAGRAM + 64];
} packet;

static packet net[NET_SLOTS];
static int net_head, net_count;
static int net_drop_to = -1; /* datagrams to this address vanish (a lost peer) */

typedef struct {
    uint8_t me;
    int sent;
} endpoint;

static ayl_addr addr_of(uint8_t a) {
    ayl_addr r;
    memset(&r, 0, sizeof r);
    r.len = 1;
    r.bytes[0] = a;
    return r;
}

static void net_inject(uint8_t from, uint8_t to, const uint8_t *data, size_t len) {
    packet *p;
    if (net_count == NET_SLOTS || to == net_drop_to) {
        return;
    }
    p = &net[(net_head + net_count++) % NET_SLOTS];
    p->to = to;
    p->from = from;
    p->len = len;
    memcpy(p->data, data, len);
}

static int mem_send(void *user, const ayl_addr *to, const uint8_t *data, size_t len) {
    endpoint *e = user;
    e->sent++;
    net_inject(e->me, to->bytes[0], data, len);
    return 0;
}

static int mem_recv(void *user, ayl_addr *from, uint8_t *buf, size_t cap) {
    endpoint *e = user;
    int i;
    for (i = 0; i < net_count; i++) {
        packet *p = &net[(net_head + i) % NET_SLOTS];
        if (p->to == e->me) {
            int len = (int)p->len;
            *from = addr_of(p->from);
            memcpy(buf, p->data, p->len < cap ? p->len : cap);
            /* remove it, keeping the order of the rest */
            for (; i < net_count - 1; i++) {
                net[(net_head + i) % NET_SLOTS] = net[(net_head + i + 1) % NET_SLOTS];
            }
            net_count--;
            return len;
        }
    }
    return 0;
}

/* The last datagram queued for `to` (without removing it), or NULL. */
static packet *net_peek(uint8_t to) {
    int i;
    for (i = net_count - 1; i >= 0; i--) {
        packet *p = &net[(net_head + i) % NET_SLOTS];
        if (p->to == to) {
            return p;
        }
    }
    return NULL;
}

static void net_clear(void) {
    net_head = 0;
    net_count = 0;
    net_drop_to = -1;
}

/* ----- a test node with its own tables ----------------------------------------------------------- */

typedef struct {
    ayl_node node;
    endpoint io;
    ayl_port ports[8];
    ayl_peer peers[4];
    ayl_seq_entry seqs[8];
    ayl_pending pending[4];
    uint8_t rx[AYL_MAX_DATAGRAM];
    uint8_t tx[AYL_MTU];
} tnode;

static const uint64_t SEQ0 = (uint64_t)1700000000 << 32;
static const uint8_t KEY[AYL_KEY_LEN] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16,
                                         17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32};
static const ayl_str GROUPS[] = {{"Peers", 5}};

static void tnode_config(tnode *t, uint32_t id, uint8_t addr, const uint8_t *key, ayl_node_config *out) {
    ayl_node_config cfg;
    memset(t, 0, sizeof *t);
    memset(&cfg, 0, sizeof cfg);
    t->io.me = addr;
    cfg.node_id = id;
    cfg.team = 7;
    cfg.key = key;
    cfg.seq_start = SEQ0;
    cfg.send = mem_send;
    cfg.recv = mem_recv;
    cfg.io_user = &t->io;
    cfg.ports = t->ports;
    cfg.max_ports = 8;
    cfg.peers = t->peers;
    cfg.max_peers = 4;
    cfg.seqs = t->seqs;
    cfg.max_seqs = 8;
    cfg.pending = t->pending;
    cfg.max_pending = 4;
    cfg.rx = t->rx;
    cfg.rx_cap = sizeof t->rx;
    cfg.tx = t->tx;
    cfg.tx_cap = sizeof t->tx;
    cfg.name = "lite";
    cfg.groups = GROUPS;
    cfg.ngroups = 1;
    *out = cfg;
}

static void tnode_init(tnode *t, uint32_t id, uint8_t addr, const uint8_t *key) {
    ayl_node_config cfg;
    tnode_config(t, id, addr, key, &cfg);
    CHECK(ayl_node_init(&t->node, &cfg) == 0);
}

#define MS 1000000ull

/* ----- write callbacks ------------------------------------------------------------------------ */

static int writes_seen;
static uint32_t last_sender;
static uint64_t last_conn;

static void on_write(void *user, const char *behavior, const char *port, const ayl_value *v, uint32_t sender,
                     uint64_t conn) {
    (void)user;
    (void)behavior;
    (void)port;
    (void)v;
    writes_seen++;
    last_sender = sender;
    last_conn = conn;
}

/* ----- tests ----------------------------------------------------------------------------------- */

static void test_port_writes_and_datagram_contents(void) {
    static tnode a, b;
    static uint8_t text_store[16], vec_store[8 * 3];
    ayl_conn c;
    ayl_value v;
    const ayl_value *got;
    ayl_datagram d;
    ayl_msg m;
    ayl_addr to_a = addr_of(1);
    double pose[3] = {1.0, -2.0, 0.5};
    net_clear();
    tnode_init(&a, 1, 1, NULL);
    tnode_init(&b, 2, 2, NULL);
    v = ayl_float(0.0);
    CHECK(ayl_node_expose(&a.node, "Drive", "Speed", &v, NULL, 0, on_write, NULL) == 0);
    CHECK(ayl_node_expose(&a.node, "Drive", "Speed", &v, NULL, 0, NULL, NULL) == AYL_E_EXISTS);
    v = ayl_text("hi");
    CHECK(ayl_node_expose(&a.node, "Say", "Text", &v, text_store, sizeof text_store, NULL, NULL) == 1);
    v = ayl_vector(NULL, 0);
    CHECK(ayl_node_expose(&a.node, "Nav", "Pose", &v, vec_store, sizeof vec_store, NULL, NULL) == 2);
    CHECK(ayl_node_expose(&a.node, "", "P", &v, NULL, 0, NULL, NULL) == AYL_E_INVALID);

    CHECK(ayl_conn_open(&b.node, &c, &to_a, "Drive", "Speed", AYL_NORMAL, 5, 0) == AYL_E_INVALID);
    CHECK(ayl_conn_open(&b.node, &c, &to_a, "Drive", "Speed", AYL_OVERRIDE_IN, 0, 0) == AYL_E_INVALID);
    CHECK(ayl_conn_open(&b.node, &c, &to_a, "Drive", "Speed", AYL_OVERRIDE_OUT, 200 * MS, -3) == 0);
    v = ayl_float(1.5);
    CHECK(ayl_conn_send(&b.node, &c, &v) == 0);

    /* The datagram B built: header and PORT fields as the spec lays them out. */
    {
        packet *p = net_peek(1);
        CHECK(p != NULL);
        if (p != NULL) {
            CHECK(ayl_decode(&d, p->data, p->len, 7, NULL) == AYL_OK);
            CHECK(d.sender == 2 && d.seq == SEQ0 + 1 && !d.auth);
            CHECK(ayl_next(&d, &m) && m.kind == AYL_KIND_PORT);
            CHECK(m.u.port.conn == c.conn && m.u.port.seq == SEQ0 + 1);
            CHECK(m.u.port.kind == AYL_OVERRIDE_OUT && m.u.port.period_ns == 200 * MS && m.u.port.priority == -3);
            CHECK(m.u.port.behavior.len == 5 && memcmp(m.u.port.behavior.ptr, "Drive", 5) == 0);
            CHECK(m.u.port.value.type == AYL_FLOAT && ayl_value_float(&m.u.port.value) == 1.5);
            CHECK(!ayl_next(&d, &m));
        }
    }
    CHECK(ayl_node_poll(&a.node, 10 * MS) == 1);
    got = ayl_node_get(&a.node, "Drive", "Speed");
    CHECK(got != NULL && ayl_value_float(got) == 1.5);
    CHECK(writes_seen == 1 && last_sender == 2 && last_conn == c.conn);

    /* Text and vectors are copied into the port's storage; too long is refused and counted. */
    {
        ayl_conn ct, cv;
        CHECK(ayl_conn_open(&b.node, &ct, &to_a, "Say", "Text", AYL_NORMAL, 0, 0) == 0);
        CHECK(ayl_conn_open(&b.node, &cv, &to_a, "Nav", "Pose", AYL_NORMAL, 0, 0) == 0);
        CHECK(ct.conn != cv.conn);
        v = ayl_text("hello");
        ayl_conn_send(&b.node, &ct, &v);
        v = ayl_vector(pose, 3);
        ayl_conn_send(&b.node, &cv, &v);
        ayl_node_poll(&a.node, 20 * MS);
        got = ayl_node_get(&a.node, "Say", "Text");
        CHECK(got->u.data.len == 5 && memcmp(got->u.data.ptr, "hello", 5) == 0 && got->u.data.ptr == text_store);
        got = ayl_node_get(&a.node, "Nav", "Pose");
        CHECK(got->u.vec.n == 3 && ayl_value_vector_at(got, 1) == -2.0);
        v = ayl_text("a text longer than sixteen bytes");
        ayl_conn_send(&b.node, &ct, &v);
        ayl_node_poll(&a.node, 30 * MS);
        CHECK(a.node.counters[AYL_TOO_LARGE] == 1);
        got = ayl_node_get(&a.node, "Say", "Text");
        CHECK(got->u.data.len == 5);
    }

    /* Drops: wrong type, unknown behavior, unknown port. */
    {
        ayl_conn c1, c2, c3;
        ayl_conn_open(&b.node, &c1, &to_a, "Drive", "Speed", AYL_NORMAL, 0, 0);
        ayl_conn_open(&b.node, &c2, &to_a, "Nope", "Speed", AYL_NORMAL, 0, 0);
        ayl_conn_open(&b.node, &c3, &to_a, "Drive", "Nope", AYL_NORMAL, 0, 0);
        v = ayl_int(3);
        ayl_conn_send(&b.node, &c1, &v);
        ayl_conn_send(&b.node, &c2, &v);
        ayl_conn_send(&b.node, &c3, &v);
        ayl_node_poll(&a.node, 40 * MS);
        CHECK(a.node.counters[AYL_TYPE_MISMATCH] == 1);
        CHECK(a.node.counters[AYL_UNKNOWN_BEHAVIOR] == 1);
        CHECK(a.node.counters[AYL_UNKNOWN_PORT] == 1);
    }
}

/* Send a PORT message from node 9 with a chosen (conn, seq, kind, period), to `group` (NULL:
 * node-addressed). */
static void inject_group_port(uint8_t to, uint64_t dseq, uint64_t conn, uint64_t seq, ayl_conn_kind kind,
                              uint64_t period, int64_t value, const char *group) {
    uint8_t buf[256];
    ayl_writer w;
    ayl_msg m;
    int len;
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_PORT;
    m.u.port.conn = conn;
    m.u.port.seq = seq;
    m.u.port.kind = kind;
    m.u.port.period_ns = period;
    m.u.port.behavior = ayl_s("B");
    m.u.port.port = ayl_s("P");
    m.u.port.value = ayl_int(value);
    m.u.port.group = ayl_s(group);
    ayl_writer_begin(&w, buf, sizeof buf, 7, 9, dseq, 0);
    CHECK(ayl_writer_add(&w, &m) == 0);
    len = ayl_writer_finish(&w, NULL);
    net_inject(9, to, buf, (size_t)len);
}

/* Send a node-addressed PORT message from node 9 with a chosen (conn, seq, kind, period). */
static void inject_port(uint8_t to, uint64_t dseq, uint64_t conn, uint64_t seq, ayl_conn_kind kind, uint64_t period,
                        int64_t value) {
    inject_group_port(to, dseq, conn, seq, kind, period, value, NULL);
}

/* D-S10.6: a PORT naming a group applies only on a member (cfg.groups); a non-member counts
 * not_member and its port keeps its value; a node-addressed PORT applies as before. */
static void test_group_membership(void) {
    static tnode a;
    static const char *const groups[] = {"Other", "Peers"};
    ayl_value v = ayl_int(0);
    int i;
    net_clear();
    tnode_init(&a, 1, 1, NULL);
    ayl_node_expose(&a.node, "B", "P", &v, NULL, 0, NULL, NULL);
    for (i = 0; i < 3; i++) {
        /* The last is node-addressed. */
        inject_group_port(1, (uint64_t)i + 1, 7, (uint64_t)i + 1, AYL_NORMAL, 0, i + 1, i < 2 ? groups[i] : NULL);
        ayl_node_poll(&a.node, 0);
        CHECK(a.node.counters[AYL_NOT_MEMBER] == 1);
        CHECK(ayl_node_get(&a.node, "B", "P")->u.i == (i == 0 ? 0 : i + 1));
    }
    CHECK(strcmp(ayl_cause_name(AYL_NOT_MEMBER), "not_member") == 0);
}

static void test_stale_and_windows(void) {
    static tnode a;
    ayl_value v = ayl_int(0);
    net_clear();
    tnode_init(&a, 1, 1, NULL);
    ayl_node_expose(&a.node, "B", "P", &v, NULL, 0, NULL, NULL);

    /* N1: per (sender, connection), only newer sequence numbers apply. */
    inject_port(1, 1, 7, 10, AYL_NORMAL, 0, 10);
    inject_port(1, 2, 7, 9, AYL_NORMAL, 0, 9);
    inject_port(1, 3, 7, 10, AYL_NORMAL, 0, 10);
    inject_port(1, 4, 8, 1, AYL_NORMAL, 0, 1); /* another connection has its own numbers */
    ayl_node_poll(&a.node, 0);
    CHECK(a.node.counters[AYL_STALE] == 2);
    CHECK(ayl_node_get(&a.node, "B", "P")->u.i == 1);

    /* Suppress: never writes, blocks every connection write for its period, then lapses. */
    inject_port(1, 5, 20, 1, AYL_SUPPRESS, 100 * MS, 55);
    inject_port(1, 6, 7, 11, AYL_NORMAL, 0, 11);
    ayl_node_poll(&a.node, 1000 * MS);
    CHECK(a.node.counters[AYL_SUPPRESSED] == 1);
    CHECK(ayl_node_get(&a.node, "B", "P")->u.i == 1);
    v = ayl_int(2); /* the program's own writes are never suppressed (D6.5) */
    CHECK(ayl_node_set(&a.node, "B", "P", &v) == 0 && ayl_node_get(&a.node, "B", "P")->u.i == 2);
    inject_port(1, 7, 7, 12, AYL_NORMAL, 0, 12);
    ayl_node_poll(&a.node, 1100 * MS); /* exactly at the end: the window is closed */
    CHECK(ayl_node_get(&a.node, "B", "P")->u.i == 12);

    /* Override-in: its holder writes, everybody else is blocked; a refresh never shortens. */
    inject_port(1, 8, 30, 1, AYL_OVERRIDE_IN, 500 * MS, 30);
    inject_port(1, 9, 30, 2, AYL_OVERRIDE_IN, 10 * MS, 31);
    inject_port(1, 10, 7, 13, AYL_NORMAL, 0, 13);
    ayl_node_poll(&a.node, 2000 * MS);
    CHECK(ayl_node_get(&a.node, "B", "P")->u.i == 31);
    CHECK(a.node.counters[AYL_OVERRIDDEN_IN] == 1);
    inject_port(1, 11, 7, 14, AYL_NORMAL, 0, 14);
    ayl_node_poll(&a.node, 2400 * MS); /* still inside the first 500 ms */
    CHECK(a.node.counters[AYL_OVERRIDDEN_IN] == 2);
    inject_port(1, 12, 7, 15, AYL_NORMAL, 0, 15);
    ayl_node_poll(&a.node, 2600 * MS);
    CHECK(ayl_node_get(&a.node, "B", "P")->u.i == 15);

    /* Inhibit and write-inhibit never write; override-out writes (its window stops only
     * propagation, which a lite port never does). */
    inject_port(1, 13, 40, 1, AYL_INHIBIT, 100 * MS, 40);
    inject_port(1, 14, 41, 1, AYL_WRITE_INHIBIT, 100 * MS, 41);
    ayl_node_poll(&a.node, 2700 * MS);
    CHECK(ayl_node_get(&a.node, "B", "P")->u.i == 15);
    inject_port(1, 15, 42, 1, AYL_OVERRIDE_OUT, 100 * MS, 42);
    ayl_node_poll(&a.node, 2700 * MS);
    CHECK(ayl_node_get(&a.node, "B", "P")->u.i == 42);
}

static void test_hello_and_peers(void) {
    static tnode a, b;
    ayl_datagram d;
    ayl_msg m;
    ayl_addr to_b = addr_of(2);
    ayl_str g;
    packet *p;
    net_clear();
    tnode_init(&a, 1, 1, NULL);
    tnode_init(&b, 2, 2, NULL);
    CHECK(ayl_node_add_peer(&a.node, 2, &to_b) == 0);
    ayl_node_poll(&a.node, 0); /* the first poll announces */
    p = net_peek(2);
    CHECK(p != NULL);
    if (p == NULL) {
        return;
    }
    CHECK(ayl_decode(&d, p->data, p->len, 7, NULL) == AYL_OK && ayl_next(&d, &m));
    CHECK(m.kind == AYL_KIND_HELLO && m.u.hello.interval_ms == 1000 && m.u.hello.ngroups == 1);
    CHECK(ayl_hello_group(&m.u.hello, 0, &g) && g.len == 5 && memcmp(g.ptr, "Peers", 5) == 0);
    CHECK(ayl_node_next_deadline(&a.node) == 1000 * MS);
    ayl_node_poll(&b.node, 0);
    CHECK(ayl_node_peer_addr(&b.node, 1) != NULL && ayl_node_peer_addr(&b.node, 1)->bytes[0] == 1);
    /* N6: forgotten after 3 intervals without a word; a configured peer never is. */
    b.node.next_hello_ns = UINT64_MAX; /* keep b quiet */
    ayl_node_poll(&b.node, 3000 * MS);
    CHECK(ayl_node_peer_addr(&b.node, 1) != NULL);
    ayl_node_poll(&b.node, 3001 * MS);
    CHECK(ayl_node_peer_addr(&b.node, 1) == NULL);
    CHECK(ayl_node_peer_addr(&a.node, 2) != NULL);
}

/* A HELLO announcing 0xFFFFFFFF ms (a forger's, to keep its address greeted for months) is
 * believed up to AYL_MAX_PEER_INTERVAL_MS, as by the Rust node. */
static void test_hello_period_is_capped(void) {
    static tnode a, b;
    ayl_addr to_b = addr_of(2);
    net_clear();
    tnode_init(&a, 1, 1, NULL);
    tnode_init(&b, 2, 2, NULL);
    a.node.cfg.hello_interval_ms = 0xFFFFFFFFu;
    CHECK(ayl_node_add_peer(&a.node, 2, &to_b) == 0);
    ayl_node_poll(&a.node, 0);
    ayl_node_poll(&b.node, 0);
    CHECK(ayl_node_peer_addr(&b.node, 1) != NULL);
    b.node.next_hello_ns = UINT64_MAX; /* keep b quiet */
    ayl_node_poll(&b.node, 3ull * AYL_MAX_PEER_INTERVAL_MS * MS);
    CHECK(ayl_node_peer_addr(&b.node, 1) != NULL);
    ayl_node_poll(&b.node, 3ull * AYL_MAX_PEER_INTERVAL_MS * MS + MS);
    CHECK(ayl_node_peer_addr(&b.node, 1) == NULL);
}

static void test_requests(void) {
    static tnode a, b;
    static uint8_t out[512];
    ayl_addr to_a = addr_of(1);
    ayl_request_msg q;
    ayl_reply_msg ans;
    uint64_t id;
    ayl_value v = ayl_text("ready");
    static uint8_t store[16];
    int overflow = 0;
    net_clear();
    tnode_init(&a, 1, 1, NULL);
    tnode_init(&b, 2, 2, NULL);
    ayl_node_expose(&a.node, "Cam", "State", &v, store, sizeof store, NULL, NULL);
    v = ayl_bool(1);
    ayl_node_expose(&a.node, "Cam", "On", &v, NULL, 0, NULL, NULL);
    v = ayl_int(4);
    ayl_node_expose(&a.node, "Arm \"2\"", "Joint", &v, NULL, 0, NULL, NULL);

    /* READ served by the lite node, answer copied into the caller's buffer. */
    memset(&q, 0, sizeof q);
    q.op = AYL_OP_READ;
    q.behavior = ayl_s("Cam");
    q.port = ayl_s("State");
    CHECK(ayl_node_request(&b.node, &to_a, &q, out, sizeof out, &id) == 0);
    CHECK(id == SEQ0 + 1);
    CHECK(ayl_node_request_take(&b.node, id, &ans, NULL) == AYL_REQ_PENDING);
    ayl_node_poll(&a.node, 0);
    ayl_node_poll(&b.node, 0);
    CHECK(ayl_node_request_take(&b.node, id, &ans, &overflow) == AYL_REQ_DONE);
    CHECK(ans.result == AYL_RESULT_VALUE && ans.value.type == AYL_TEXT && ans.value.u.data.len == 5 &&
          memcmp(ans.value.u.data.ptr, "ready", 5) == 0 && !overflow);
    CHECK(ayl_node_request_take(&b.node, id, &ans, NULL) == AYL_REQ_FREE);

    /* LIST: a small report, names escaped. */
    memset(&q, 0, sizeof q);
    q.op = AYL_OP_LIST;
    CHECK(ayl_node_request(&b.node, &to_a, &q, out, sizeof out, &id) == 0);
    ayl_node_poll(&a.node, 0);
    ayl_node_poll(&b.node, 0);
    CHECK(ayl_node_request_take(&b.node, id, &ans, NULL) == AYL_REQ_DONE);
    {
        const char *want = "{\"node\":1,\"lite\":true,\"behaviors\":[{\"name\":\"Cam\",\"ports\":[\"State\",\"On\"]},"
                           "{\"name\":\"Arm \\\"2\\\"\",\"ports\":[\"Joint\"]}]}";
        CHECK_MSG(ans.result == AYL_RESULT_REPORT && ans.text.len == strlen(want) &&
                      memcmp(ans.text.ptr, want, ans.text.len) == 0,
                  "%.*s", (int)ans.text.len, ans.text.ptr);
    }

    /* Other operations are refused with a reason; unknown ones say so. */
    memset(&q, 0, sizeof q);
    q.op = 99;
    ayl_node_request(&b.node, &to_a, &q, out, sizeof out, &id);
    ayl_node_poll(&a.node, 0);
    ayl_node_poll(&b.node, 0);
    CHECK(ayl_node_request_take(&b.node, id, &ans, NULL) == AYL_REQ_DONE);
    CHECK(ans.result == AYL_RESULT_ERROR && ans.text.len == 17 && memcmp(ans.text.ptr, "unknown operation", 17) == 0);

    /* A value that does not fit in one datagram is refused with a reason (never fragmented). */
    {
        static uint8_t log_store[2000];
        memset(log_store, 'x', sizeof log_store);
        v = ayl_text_n((const char *)log_store, sizeof log_store);
        CHECK(ayl_node_expose(&a.node, "Cam", "Log", &v, log_store, sizeof log_store, NULL, NULL) >= 0);
        memset(&q, 0, sizeof q);
        q.op = AYL_OP_READ;
        q.behavior = ayl_s("Cam");
        q.port = ayl_s("Log");
        ayl_node_request(&b.node, &to_a, &q, out, sizeof out, &id);
        ayl_node_poll(&a.node, 0);
        ayl_node_poll(&b.node, 0);
        CHECK(ayl_node_request_take(&b.node, id, &ans, NULL) == AYL_REQ_DONE);
        CHECK(ans.result == AYL_RESULT_ERROR && ans.text.len == 33 &&
              memcmp(ans.text.ptr, "answer too large for one datagram", 33) == 0);
        {
            ayl_conn c;
            ayl_addr to_b = addr_of(2);
            CHECK(ayl_conn_open(&a.node, &c, &to_b, "X", "Y", AYL_NORMAL, 0, 0) == 0);
            CHECK(ayl_conn_send(&a.node, &c, &v) == AYL_E_NOSPACE);
        }
    }

    /* The CONNECT a lite node sends so that a node's port feeds one of its ports. */
    {
        packet *p;
        ayl_datagram d;
        ayl_msg m;
        memset(&q, 0, sizeof q);
        q.op = AYL_OP_CONNECT;
        q.src_behavior = ayl_s("OBS1");
        q.src_port = ayl_s("Rotate");
        q.dest.node = 2;
        q.dest.behavior = ayl_s("Motor");
        q.dest.port = ayl_s("Turn");
        q.kind = AYL_OVERRIDE_IN;
        q.period_ns = 200 * MS;
        q.priority = 1;
        CHECK(ayl_node_request(&b.node, &to_a, &q, NULL, 0, &id) == 0);
        p = net_peek(1);
        CHECK(p != NULL && ayl_decode(&d, p->data, p->len, 7, NULL) == AYL_OK && ayl_next(&d, &m));
        CHECK(m.kind == AYL_KIND_REQUEST && m.u.request.id == id && m.u.request.op == AYL_OP_CONNECT);
        CHECK(!m.u.request.dest.is_group && m.u.request.dest.node == 2 && m.u.request.kind == AYL_OVERRIDE_IN &&
              m.u.request.period_ns == 200 * MS && m.u.request.priority == 1);
        ayl_node_poll(&a.node, 0);
        ayl_node_poll(&b.node, 0);
        CHECK(ayl_node_request_take(&b.node, id, &ans, NULL) == AYL_REQ_DONE && ans.result == AYL_RESULT_ERROR);
    }

    /* Invalid requests are refused before anything is sent. */
    memset(&q, 0, sizeof q);
    q.op = AYL_OP_CONNECT;
    q.dest.is_group = 1; /* with an empty group name */
    CHECK(ayl_node_request(&b.node, &to_a, &q, NULL, 0, &id) == AYL_E_INVALID);
}

static void test_retries(void) {
    static tnode b;
    ayl_addr nowhere = addr_of(5);
    ayl_request_msg q;
    uint64_t id, t;
    int before;
    net_clear();
    tnode_init(&b, 2, 2, NULL);
    b.node.next_hello_ns = UINT64_MAX;
    memset(&q, 0, sizeof q);
    q.op = AYL_OP_DISCONNECT;
    q.conn = 3;
    before = b.io.sent;
    ayl_node_request(&b.node, &nowhere, &q, NULL, 0, &id);
    for (t = 0; t <= 6000 * MS; t += 50 * MS) {
        ayl_node_poll(&b.node, t);
        if (t == 5000 * MS - 50 * MS) {
            CHECK(ayl_node_request_take(&b.node, id, NULL, NULL) == AYL_REQ_PENDING);
        }
    }
    CHECK_MSG(b.io.sent - before == AYL_RETRY_LIMIT, "%d sends", b.io.sent - before);
    CHECK(ayl_node_request_take(&b.node, id, NULL, NULL) == AYL_REQ_FAILED);
    {
        /* every send was a new datagram (new sequence number) carrying the same request id */
        int i, same = 1;
        uint64_t last = 0;
        for (i = 0; i < net_count; i++) {
            ayl_datagram d;
            ayl_msg m;
            packet *p = &net[(net_head + i) % NET_SLOTS];
            same &= ayl_decode(&d, p->data, p->len, 7, NULL) == AYL_OK && ayl_next(&d, &m) && m.u.request.id == id &&
                    d.seq > last;
            last = d.seq;
        }
        CHECK(same && net_count == AYL_RETRY_LIMIT);
    }
}

/* A REPLY part from node 50, fed straight into the node. */
static void feed_part(tnode *t, uint64_t dseq, uint64_t id, uint16_t part, uint16_t parts, const char *text) {
    uint8_t buf[512];
    ayl_writer w;
    ayl_msg m;
    ayl_addr from = addr_of(50);
    int len;
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_REPLY;
    m.u.reply.id = id;
    m.u.reply.part = part;
    m.u.reply.parts = parts;
    m.u.reply.result = AYL_RESULT_REPORT;
    m.u.reply.text = ayl_s(text);
    ayl_writer_begin(&w, buf, sizeof buf, 7, 50, dseq, 1);
    CHECK(ayl_writer_add(&w, &m) == 0);
    len = ayl_writer_finish(&w, KEY);
    CHECK(ayl_node_receive(&t->node, buf, (size_t)len, &from, 0) == AYL_OK);
}

static void test_report_reassembly_and_auth(void) {
    static tnode b;
    static uint8_t out[64], small[8];
    ayl_addr node50 = addr_of(50);
    ayl_request_msg q;
    ayl_reply_msg ans;
    uint64_t id, id2;
    int overflow;
    net_clear();
    tnode_init(&b, 2, 2, KEY);
    memset(&q, 0, sizeof q);
    q.op = AYL_OP_WHY;
    q.behavior = ayl_s("OBS1");
    q.port = ayl_s("Rotate");
    CHECK(ayl_node_request(&b.node, &node50, &q, out, sizeof out, &id) == 0);
    {
        /* The request went out authenticated. */
        packet *p = net_peek(50);
        ayl_datagram d;
        CHECK(p != NULL && ayl_decode(&d, p->data, p->len, 7, KEY) == AYL_OK && d.auth);
        CHECK(p != NULL && ayl_decode(&d, p->data, p->len, 7, NULL) == AYL_UNEXPECTED_AUTH);
    }
    /* Parts arrive out of order, one twice; the report is put together in part order. */
    feed_part(&b, 100, id, 2, 3, "ñ\"]}");
    feed_part(&b, 101, id, 0, 3, "{\"port\":");
    feed_part(&b, 102, id, 2, 3, "XXXX");
    CHECK(ayl_node_request_take(&b.node, id, &ans, NULL) == AYL_REQ_PENDING);
    feed_part(&b, 103, id, 1, 3, "[\"a\",\"");
    CHECK(ayl_node_request_take(&b.node, id, &ans, &overflow) == AYL_REQ_DONE);
    {
        const char *want = "{\"port\":[\"a\",\"ñ\"]}";
        CHECK_MSG(ans.result == AYL_RESULT_REPORT && ans.text.len == strlen(want) &&
                      memcmp(ans.text.ptr, want, ans.text.len) == 0 && !overflow,
                  "%.*s", (int)ans.text.len, ans.text.ptr);
    }
    /* A report larger than the caller's buffer completes, flagged as cut. */
    CHECK(ayl_node_request(&b.node, &node50, &q, small, sizeof small, &id2) == 0);
    feed_part(&b, 104, id2, 0, 2, "{\"port\":");
    feed_part(&b, 105, id2, 1, 2, "1}");
    CHECK(ayl_node_request_take(&b.node, id2, &ans, &overflow) == AYL_REQ_DONE && overflow);

    /* Replays, forgeries and unauthenticated datagrams are dropped and counted. */
    {
        uint8_t buf[128];
        ayl_writer w;
        ayl_addr from = addr_of(50);
        int len;
        static const uint8_t other[AYL_KEY_LEN] = {9};
        ayl_writer_begin(&w, buf, sizeof buf, 7, 50, 104, 1); /* seq 104 was accepted above */
        len = ayl_writer_finish(&w, KEY);
        CHECK(ayl_node_receive(&b.node, buf, (size_t)len, &from, 0) == AYL_REPLAYED);
        ayl_writer_begin(&w, buf, sizeof buf, 7, 50, 99, 1); /* within the window, never seen */
        len = ayl_writer_finish(&w, KEY);
        CHECK(ayl_node_receive(&b.node, buf, (size_t)len, &from, 0) == AYL_OK);
        CHECK(ayl_node_receive(&b.node, buf, (size_t)len, &from, 0) == AYL_REPLAYED);
        ayl_writer_begin(&w, buf, sizeof buf, 7, 50, 1000, 1);
        len = ayl_writer_finish(&w, other);
        CHECK(ayl_node_receive(&b.node, buf, (size_t)len, &from, 0) == AYL_BAD_MAC);
        ayl_writer_begin(&w, buf, sizeof buf, 7, 50, 1001, 0);
        len = ayl_writer_finish(&w, NULL);
        CHECK(ayl_node_receive(&b.node, buf, (size_t)len, &from, 0) == AYL_UNAUTHENTICATED);
        CHECK(b.node.counters[AYL_REPLAYED] == 2 && b.node.counters[AYL_BAD_MAC] == 1 &&
              b.node.counters[AYL_UNAUTHENTICATED] == 1);
    }
}

/* One message in its own datagram from `sender` at address `from_addr`, fed straight into the
 * node (keyed when key != NULL). */
static ayl_cause feed(tnode *t, uint8_t from_addr, uint32_t sender, uint64_t dseq, const ayl_msg *m,
                      const uint8_t *key) {
    uint8_t buf[AYL_MTU];
    ayl_writer w;
    ayl_addr from = addr_of(from_addr);
    int len;
    ayl_writer_begin(&w, buf, sizeof buf, 7, sender, dseq, key != NULL);
    CHECK(ayl_writer_add(&w, m) == 0);
    len = ayl_writer_finish(&w, key);
    CHECK(len > 0);
    return ayl_node_receive(&t->node, buf, (size_t)len, &from, 0);
}

/* The next datagram queued for `to`, removed and decoded: its first message in *m (1), or 0 if
 * none is queued. */
static int take_msg(uint8_t to, uint8_t *from, ayl_msg *m, const uint8_t *key) {
    static uint8_t buf[AYL_MAX_DATAGRAM];
    endpoint e;
    ayl_addr a;
    ayl_datagram d;
    int len;
    e.me = to;
    e.sent = 0;
    len = mem_recv(&e, &a, buf, sizeof buf);
    if (len <= 0) {
        return 0;
    }
    *from = a.bytes[0];
    CHECK(ayl_decode(&d, buf, (size_t)len, 7, key) == AYL_OK && ayl_next(&d, m));
    return 1;
}

static void test_challenge_is_echoed_and_report_reassembles(void) {
    /* A node limiting amplification answers a LIST with a CHALLENGE: the lite node sends an
     * ECHO of the cookie at once to the address the CHALLENGE came from, sends the request
     * again right after it (once), and reassembles the multi-part answer that follows. */
    static tnode b;
    static uint8_t out[64];
    static const uint8_t cookie[AYL_COOKIE_LEN] = "0123456789abcde"; /* with its NUL: 16 bytes */
    ayl_addr node50 = addr_of(50);
    ayl_request_msg q;
    ayl_reply_msg ans;
    ayl_msg m, got;
    uint64_t id;
    uint8_t from;
    int sent, i;
    net_clear();
    tnode_init(&b, 2, 2, NULL);
    b.node.next_hello_ns = UINT64_MAX;
    memset(&q, 0, sizeof q);
    q.op = AYL_OP_LIST;
    CHECK(ayl_node_request(&b.node, &node50, &q, out, sizeof out, &id) == 0);
    CHECK(take_msg(50, &from, &got, NULL) && got.kind == AYL_KIND_REQUEST && got.u.request.id == id);

    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_CHALLENGE;
    memcpy(m.u.cookie.cookie, cookie, AYL_COOKIE_LEN);
    /* From another address than the request went to: echoed there; the request waits. */
    sent = b.io.sent;
    CHECK(feed(&b, 51, 50, 1, &m, NULL) == AYL_OK);
    CHECK(b.io.sent - sent == 1 && net_count == 1);
    CHECK(take_msg(51, &from, &got, NULL) && from == 2 && got.kind == AYL_KIND_ECHO &&
          memcmp(got.u.cookie.cookie, cookie, AYL_COOKIE_LEN) == 0);
    /* From the request's address: the ECHO goes there, then the request again, at once. */
    m.u.cookie.cookie[0] = 'X';
    CHECK(feed(&b, 50, 50, 2, &m, NULL) == AYL_OK);
    CHECK(b.io.sent - sent == 3 && net_count == 2);
    CHECK(take_msg(50, &from, &got, NULL) && got.kind == AYL_KIND_ECHO && got.u.cookie.cookie[0] == 'X' &&
          memcmp(got.u.cookie.cookie + 1, cookie + 1, AYL_COOKIE_LEN - 1) == 0);
    CHECK(take_msg(50, &from, &got, NULL) && got.kind == AYL_KIND_REQUEST && got.u.request.id == id &&
          got.u.request.op == AYL_OP_LIST);
    /* A second CHALLENGE is echoed too, but the request is not hurried twice. */
    CHECK(feed(&b, 50, 50, 3, &m, NULL) == AYL_OK);
    CHECK(b.io.sent - sent == 4 && take_msg(50, &from, &got, NULL) && got.kind == AYL_KIND_ECHO && net_count == 0);
    CHECK(b.node.challenged == 3 && b.node.counters[AYL_UNKNOWN_KIND] == 0);
    /* An ECHO received is ignored (a lite node sends no CHALLENGE). */
    m.kind = AYL_KIND_ECHO;
    CHECK(feed(&b, 50, 50, 4, &m, NULL) == AYL_OK && net_count == 0 && b.node.counters[AYL_UNKNOWN_KIND] == 0);

    /* The full answer, parts out of order: reassembled. */
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_REPLY;
    m.u.reply.id = id;
    m.u.reply.parts = 3;
    m.u.reply.result = AYL_RESULT_REPORT;
    for (i = 0; i < 3; i++) {
        static const char *const text[] = {"{\"node\":", "50,\"ok\"", ":true}"};
        static const uint16_t order[] = {1, 2, 0};
        m.u.reply.part = order[i];
        m.u.reply.text = ayl_s(text[order[i]]);
        CHECK(feed(&b, 50, 50, 10 + (uint64_t)i, &m, NULL) == AYL_OK);
    }
    CHECK(ayl_node_request_take(&b.node, id, &ans, NULL) == AYL_REQ_DONE);
    CHECK_MSG(ans.result == AYL_RESULT_REPORT && ans.text.len == 21 &&
                  memcmp(ans.text.ptr, "{\"node\":50,\"ok\":true}", 21) == 0,
              "%.*s", (int)ans.text.len, ans.text.ptr);
}

/* Bytes queued in the network for `to`. */
static size_t net_bytes_to(uint8_t to) {
    size_t sum = 0;
    int i;
    for (i = 0; i < net_count; i++) {
        packet *p = &net[(net_head + i) % NET_SLOTS];
        sum += p->to == to ? p->len : 0;
    }
    return sum;
}

/* A REQUEST of `op` (READ of Log.Text if op is READ) from node 66 at `from_addr`, fed into the
 * node as if received: a forger writes any source address. Returns the datagram's length. */
static size_t forge_request(tnode *t, uint8_t from_addr, uint64_t dseq, uint8_t op) {
    uint8_t buf[256];
    ayl_writer w;
    ayl_msg m;
    ayl_addr from = addr_of(from_addr);
    int len;
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_REQUEST;
    m.u.request.id = 1000 + dseq;
    m.u.request.op = op;
    if (op == AYL_OP_READ) {
        m.u.request.behavior = ayl_s("Log");
        m.u.request.port = ayl_s("Text");
    }
    ayl_writer_begin(&w, buf, sizeof buf, 7, 66, dseq, 0);
    CHECK(ayl_writer_add(&w, &m) == 0);
    len = ayl_writer_finish(&w, NULL);
    CHECK(len > 0);
    CHECK(ayl_node_receive(&t->node, buf, (size_t)len, &from, 0) == AYL_OK);
    return (size_t)len;
}

static void test_answers_keep_to_three_times_what_an_address_sent(void) {
    /* Return routability (spec, "CHALLENGE and ECHO"): a lite node answers an address with at
     * most 3x the bytes it received from it, and sends no CHALLENGE; an answer over that is
     * not sent and is counted amplification_limited. */
    static tnode a, b;
    static uint8_t text_store[400], out[1024];
    static const char *const names[] = {"LeftWheelSpeed", "RightWheelSpeed", "BatteryVoltage", "Temperature",
                                        "Heading", "Odometry"};
    ayl_addr to_a = addr_of(1);
    ayl_value v;
    ayl_request_msg q;
    ayl_reply_msg ans;
    uint64_t id, t;
    size_t i, in = 0, list_len = 0, req_len = 0;
    int sends;
    net_clear();
    tnode_init(&a, 1, 1, NULL);
    a.node.next_hello_ns = UINT64_MAX;
    for (i = 0; i < 6; i++) {
        v = ayl_float(0.0);
        CHECK(ayl_node_expose(&a.node, i < 4 ? "Drive" : "Nav", names[i], &v, NULL, 0, NULL, NULL) >= 0);
    }
    memset(text_store, 'x', sizeof text_store);
    v = ayl_text_n((const char *)text_store, sizeof text_store);
    CHECK(ayl_node_expose(&a.node, "Log", "Text", &v, text_store, sizeof text_store, NULL, NULL) >= 0);

    /* One forged LIST (32 bytes) from the victim's address (9): its answer, a datagram of
     * over 96 bytes, is not sent, and is counted. */
    in = forge_request(&a, 9, 1, AYL_OP_LIST);
    CHECK_MSG(in == 32, "a LIST request is %zu bytes", in);
    CHECK(net_bytes_to(9) == 0 && a.io.sent == 0);
    CHECK(a.node.counters[AYL_AMPLIFICATION_LIMITED] == 1);
    CHECK(strcmp(ayl_cause_name(AYL_AMPLIFICATION_LIMITED), "amplification_limited") == 0);
    /* A forged READ of a 400-byte text: the same. */
    in += forge_request(&a, 9, 2, AYL_OP_READ);
    CHECK(net_bytes_to(9) == 0 && a.node.counters[AYL_AMPLIFICATION_LIMITED] == 2);

    /* A flood of forged requests at one victim: whatever goes out stays within 3x of it. */
    for (i = 3; i < 60; i++) {
        in += forge_request(&a, 9, i, i % 2 ? AYL_OP_LIST : AYL_OP_READ);
        CHECK_MSG(net_bytes_to(9) <= 3 * in, "%zu bytes answered to %zu received", net_bytes_to(9), in);
    }
    CHECK(a.node.counters[AYL_AMPLIFICATION_LIMITED] > 30);
    CHECK_MSG(net_bytes_to(9) > 2 * in, "the budget is used, not wasted: %zu of %zu", net_bytes_to(9), 3 * in);

    /* A real requester (node 2 at address 2) asks for the LIST: its first request is too small
     * for the answer, its retries bring the budget up to it, and it gets the whole report. */
    net_clear();
    tnode_init(&b, 2, 2, NULL);
    b.node.next_hello_ns = UINT64_MAX; /* nothing but the request adds to its budget */
    memset(&q, 0, sizeof q);
    q.op = AYL_OP_LIST;
    CHECK(ayl_node_request(&b.node, &to_a, &q, out, sizeof out, &id) == 0);
    req_len = net_peek(1)->len;
    for (t = 0; t < 5000 * MS && ayl_node_request_take(&b.node, id, &ans, NULL) == AYL_REQ_PENDING; t += 50 * MS) {
        packet *reply;
        ayl_node_poll(&a.node, t);
        reply = net_peek(2);
        list_len = reply != NULL ? reply->len : list_len;
        ayl_node_poll(&b.node, t);
    }
    sends = (int)b.pending[0].sends;
    printf("test_node: a %zu-byte LIST answer to %zu-byte requests went out at send %d\n", list_len, req_len, sends);
    CHECK(ayl_node_request_take(&b.node, id, &ans, NULL) == AYL_REQ_FREE); /* taken in the loop */
    CHECK_MSG(ans.result == AYL_RESULT_REPORT && ans.text.len > 150 && memcmp(ans.text.ptr, "{\"node\":1,", 10) == 0,
              "%.*s", (int)ans.text.len, ans.text.ptr);
    /* Answered at the first send whose total reaches a third of the answer, and no later. */
    CHECK_MSG(list_len > 3 * req_len && (size_t)sends == (list_len + 3 * req_len - 1) / (3 * req_len),
              "a %zu-byte answer to %zu-byte requests took %d sends", list_len, req_len, sends);

    /* A small answer (at most 3x its request) goes out at once, to any address. */
    q.op = AYL_OP_READ;
    q.behavior = ayl_s("Nav");
    q.port = ayl_s("Heading");
    CHECK(ayl_node_request(&b.node, &to_a, &q, out, sizeof out, &id) == 0);
    ayl_node_poll(&a.node, t);
    ayl_node_poll(&b.node, t);
    CHECK(ayl_node_request_take(&b.node, id, &ans, NULL) == AYL_REQ_DONE && ans.result == AYL_RESULT_VALUE);

    /* The table holds AYL_BUDGETS addresses; a new one replaces the least recently heard, which
     * starts over from nothing when it comes back. */
    for (i = 0; i < AYL_BUDGETS; i++) {
        (void)forge_request(&a, (uint8_t)(100 + i), 500 + i, 99);
    }
    CHECK(a.node.budgets[0].used && a.node.budgets[AYL_BUDGETS - 1].used);
    {
        size_t found2 = 0, found100 = 0;
        for (i = 0; i < AYL_BUDGETS; i++) {
            found2 += a.node.budgets[i].addr.bytes[0] == 2;
            found100 += a.node.budgets[i].addr.bytes[0] == 100;
        }
        CHECK_MSG(found2 == 0 && found100 == 1, "the requester at 2 (heard longest ago) replaced: %zu %zu", found2,
                  found100);
    }
}

/* The golden vector request_disconnect_signed: DISCONNECT 19, id 49, node 3 to node 9, team 7,
 * signed by the operator whose seed is 32 x 0x11. */
static const char SIGNED_DISCONNECT_HEX[] =
    "1052003100000000000000021300000000000000016f1ff1ce1117b1368077e0eaf80a3a0eade9635dca673be30f5d4322b7fd7fd"
    "77c60569d5d164190a8470a0bd8ae49b930d81b62aea9847fe48dfd4a3980ff0c";
static uint8_t signed_seen[256];
static size_t signed_seen_len;
static int signs;

static int fake_sign(void *user, const uint8_t *data, size_t len, uint8_t sig[AYL_SIGNATURE_LEN]) {
    /* Stands in for Ed25519 (not in this library): records what it is asked to sign and gives
     * the vector's signature, which is the real signature of exactly the bytes expected below. */
    const uint8_t *vector_sig = user;
    signs++;
    signed_seen_len = len < sizeof signed_seen ? len : sizeof signed_seen;
    memcpy(signed_seen, data, signed_seen_len);
    memcpy(sig, vector_sig, AYL_SIGNATURE_LEN);
    return 0;
}

static void test_operator_signatures(void) {
    static tnode c;
    static uint8_t want_msg[sizeof SIGNED_DISCONNECT_HEX / 2];
    static const char context[] = "ayllu operator request v1"; /* with its NUL: 26 bytes */
    static const uint8_t want_tail[] = {7,  0, 0, 0, 3, 0, 0, 0, 9, 0, 0, 0, /* team, requester, receiver */
                                        49, 0, 0, 0, 0, 0, 0, 0, 2, 19, 0, 0, 0, 0, 0, 0, 0}; /* id, op, conn */
    ayl_addr node9 = addr_of(9), stranger = addr_of(10);
    ayl_request_msg q;
    ayl_msg got;
    uint64_t id;
    uint8_t from;
    size_t i;
    for (i = 0; i < sizeof want_msg; i++) {
        unsigned hi, lo;
        hi = (unsigned)(SIGNED_DISCONNECT_HEX[2 * i] <= '9' ? SIGNED_DISCONNECT_HEX[2 * i] - '0'
                                                            : SIGNED_DISCONNECT_HEX[2 * i] - 'a' + 10);
        lo = (unsigned)(SIGNED_DISCONNECT_HEX[2 * i + 1] <= '9' ? SIGNED_DISCONNECT_HEX[2 * i + 1] - '0'
                                                                : SIGNED_DISCONNECT_HEX[2 * i + 1] - 'a' + 10);
        want_msg[i] = (uint8_t)(hi * 16 + lo);
    }
    net_clear();
    tnode_init(&c, 3, 3, NULL);
    c.node.cfg.sign = fake_sign;
    c.node.cfg.sign_user = want_msg + sizeof want_msg - AYL_SIGNATURE_LEN;
    c.node.next_hello_ns = UINT64_MAX;
    CHECK(ayl_node_add_peer(&c.node, 9, &node9) == 0);
    c.node.next_id = 49;
    memset(&q, 0, sizeof q);
    q.op = AYL_OP_DISCONNECT;
    q.conn = 19;
    CHECK(ayl_node_request(&c.node, &node9, &q, NULL, 0, &id) == 0 && id == 49 && signs == 1);
    CHECK(signed_seen_len == sizeof context + sizeof want_tail && memcmp(signed_seen, context, sizeof context) == 0 &&
          memcmp(signed_seen + sizeof context, want_tail, sizeof want_tail) == 0);
    {
        /* The REQUEST as sent is the vector's, byte for byte. */
        packet *p = net_peek(9);
        CHECK(p != NULL && p->len == AYL_HEADER_LEN + sizeof want_msg &&
              memcmp(p->data + AYL_HEADER_LEN, want_msg, sizeof want_msg) == 0);
    }
    CHECK(take_msg(9, &from, &got, NULL) && got.u.request.has_signature);
    /* Reads are not signed; a structure change to an address where no node is known is refused. */
    memset(&q, 0, sizeof q);
    q.op = AYL_OP_READ;
    q.behavior = ayl_s("B");
    q.port = ayl_s("P");
    CHECK(ayl_node_request(&c.node, &stranger, &q, NULL, 0, &id) == 0 && signs == 1);
    CHECK(take_msg(10, &from, &got, NULL) && !got.u.request.has_signature);
    q.op = AYL_OP_DISCONNECT;
    CHECK(ayl_node_request(&c.node, &stranger, &q, NULL, 0, &id) == AYL_E_NOTFOUND && signs == 1);
}

static void test_replay_window_and_codec_edges(void) {
    ayl_replay_window w;
    uint8_t buf[64];
    ayl_writer wr;
    ayl_msg m;
    memset(&w, 0, sizeof w);
    CHECK(ayl_replay_accept(&w, 100) && !ayl_replay_accept(&w, 100));
    CHECK(ayl_replay_accept(&w, 98) && !ayl_replay_accept(&w, 98));
    CHECK(ayl_replay_accept(&w, 101));
    CHECK(ayl_replay_accept(&w, 101 - 64));  /* N-64 is still in the window */
    CHECK(!ayl_replay_accept(&w, 101 - 65)); /* older than the window */
    CHECK(ayl_replay_accept(&w, 1000) && ayl_replay_accept(&w, 999) && !ayl_replay_accept(&w, 101));
    CHECK(ayl_replay_accept(&w, 1064) && ayl_replay_accept(&w, 1063) && !ayl_replay_accept(&w, 1000));

    /* The writer refuses what a decoder would drop, and keeps room for the MAC. */
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_HELLO;
    CHECK(ayl_writer_begin(&wr, buf, sizeof buf, 1, 1, 1, 0) == 0 && ayl_writer_add(&wr, &m) == AYL_E_INVALID);
    m.u.hello.interval_ms = 1;
    m.u.hello.name.ptr = "\xff";
    m.u.hello.name.len = 1;
    CHECK(ayl_writer_add(&wr, &m) == AYL_E_INVALID);
    m.kind = 0x7e;
    CHECK(ayl_writer_add(&wr, &m) == AYL_E_INVALID);
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_PORT;
    m.u.port.behavior = ayl_s("B");
    m.u.port.port = ayl_s("P");
    m.u.port.value = ayl_text("0123456789012345678901234567890123456789");
    CHECK(ayl_writer_begin(&wr, buf, sizeof buf, 1, 1, 1, 1) == 0 && ayl_writer_add(&wr, &m) == AYL_E_NOSPACE);
    CHECK(wr.len == AYL_HEADER_LEN); /* nothing was appended */
    CHECK(ayl_writer_finish(&wr, KEY) == AYL_HEADER_LEN + AYL_MAC_LEN);
    CHECK(ayl_utf8_valid((const uint8_t *)"\xc3\xb1", 2) && !ayl_utf8_valid((const uint8_t *)"\xc3", 1));
    CHECK(!ayl_utf8_valid((const uint8_t *)"\xed\xa0\x80", 3)); /* a surrogate */
    CHECK(!ayl_utf8_valid((const uint8_t *)"\xc0\x80", 2));     /* overlong */
    CHECK(!ayl_utf8_valid((const uint8_t *)"\xf4\x90\x80\x80", 4)); /* above U+10FFFF */
    CHECK(ayl_utf8_valid((const uint8_t *)"\xf0\x9f\x98\x80", 4));

    /* Signatures follow known operations only; a cookie is 16 bytes; a tag without 64 bytes
     * after it is no signature (extra bytes, ignored). */
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_REQUEST;
    m.u.request.op = 99;
    m.u.request.has_signature = 1;
    CHECK(ayl_writer_begin(&wr, buf, sizeof buf, 1, 1, 1, 0) == 0 && ayl_writer_add(&wr, &m) == AYL_E_INVALID);
    {
        static const uint8_t head[AYL_HEADER_LEN] = {0x41, 0x59, 1, 0, 1, 0, 0, 0, 2, 0, 0, 0, 1};
        uint8_t dg[AYL_HEADER_LEN + 3 + 9 + 64];
        ayl_datagram d;
        ayl_msg got;
        memcpy(dg, head, sizeof head);
        dg[AYL_HEADER_LEN] = AYL_KIND_CHALLENGE;
        dg[AYL_HEADER_LEN + 1] = 15;
        dg[AYL_HEADER_LEN + 2] = 0;
        memset(dg + AYL_HEADER_LEN + 3, 'c', 15);
        CHECK(ayl_decode(&d, dg, AYL_HEADER_LEN + 3 + 15, 1, NULL) == AYL_MALFORMED);
        dg[AYL_HEADER_LEN] = AYL_KIND_REQUEST; /* LIST, id 5, tag 1 and 63 bytes */
        dg[AYL_HEADER_LEN + 1] = 9 + 64;
        memset(dg + AYL_HEADER_LEN + 3, 0, 9 + 64);
        dg[AYL_HEADER_LEN + 3] = 5;
        dg[AYL_HEADER_LEN + 3 + 8] = AYL_OP_LIST;
        dg[AYL_HEADER_LEN + 3 + 9] = AYL_SIGNATURE_TAG;
        CHECK(ayl_decode(&d, dg, sizeof dg, 1, NULL) == AYL_OK && ayl_next(&d, &got));
        CHECK(got.kind == AYL_KIND_REQUEST && got.u.request.id == 5 && !got.u.request.has_signature);
    }
}

static void test_oversized_receive(void) {
    static tnode a;
    static uint8_t big[AYL_MAX_DATAGRAM + 1];
    net_clear();
    tnode_init(&a, 1, 1, NULL);
    memset(big, 0, sizeof big);
    net_inject(3, 1, big, sizeof big);
    ayl_node_poll(&a.node, 0);
    CHECK(a.node.counters[AYL_OVERSIZED] == 1);
}

/* Node id 0 is reserved (libayllu's ay_node_new and AylluLite Python refuse it too); every
 * other u32 is a node id. */
static void test_node_id_zero_is_refused(void) {
    static tnode t;
    ayl_node_config cfg;
    tnode_config(&t, 0, 1, NULL, &cfg);
    CHECK(ayl_node_init(&t.node, &cfg) == AYL_E_INVALID);
    tnode_config(&t, 0xFFFFFFFFu, 1, NULL, &cfg);
    CHECK(ayl_node_init(&t.node, &cfg) == 0);
}

int main(void) {
    test_node_id_zero_is_refused();
    test_port_writes_and_datagram_contents();
    test_stale_and_windows();
    test_group_membership();
    test_hello_and_peers();
    test_hello_period_is_capped();
    test_requests();
    test_retries();
    test_report_reassembly_and_auth();
    test_challenge_is_echoed_and_report_reassembles();
    test_answers_keep_to_three_times_what_an_address_sent();
    test_operator_signatures();
    test_replay_window_and_codec_edges();
    test_oversized_receive();
    return check_exit("test_node");
}
