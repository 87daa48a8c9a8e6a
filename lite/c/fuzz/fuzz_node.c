/*
 * fuzz_node.c -- libFuzzer target: a lite node (ports of every type, a group, one pending
 * request) applies any datagram through ayl_node_receive and answers through its send function,
 * then polls. Promises checked: no memory error or undefined behavior whatever a peer sends,
 * every result a known cause, and every datagram the node sends decodes (the encoder never
 * writes what a decoder would drop). Built and run by `make -C lite/c fuzz`.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../ayllu_lite.h"

static const ayl_str GROUPS[] = {{"Peers", 5}};

/* Every datagram the node sends must decode as an open-team datagram of its team. */
static int check_send(void *user, const ayl_addr *to, const uint8_t *data, size_t len) {
    ayl_datagram d;
    ayl_msg m;
    (void)user;
    (void)to;
    if (ayl_decode(&d, data, len, 7, NULL) != AYL_OK) {
        abort();
    }
    while (ayl_next(&d, &m) == 1) {
    }
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    static ayl_node node;
    static ayl_port ports[8];
    static ayl_peer peers[4];
    static ayl_seq_entry seqs[8];
    static ayl_pending pending[2];
    static uint8_t rx[AYL_MAX_DATAGRAM], tx[AYL_MTU], text_store[32], vec_store[8 * 4], out[2048];
    ayl_node_config cfg;
    ayl_addr from, to;
    ayl_value v;
    ayl_request_msg req;
    uint64_t id = 0;
    double vec[2] = {1.0, 2.0};
    ayl_cause c;

    memset(&node, 0, sizeof node);
    memset(ports, 0, sizeof ports);
    memset(peers, 0, sizeof peers);
    memset(seqs, 0, sizeof seqs);
    memset(pending, 0, sizeof pending);
    memset(&cfg, 0, sizeof cfg);
    cfg.node_id = 2;
    cfg.team = 7;
    cfg.seq_start = (uint64_t)1700000000 << 32;
    cfg.send = check_send;
    cfg.ports = ports;
    cfg.max_ports = 8;
    cfg.peers = peers;
    cfg.max_peers = 4;
    cfg.seqs = seqs;
    cfg.max_seqs = 8;
    cfg.pending = pending;
    cfg.max_pending = 2;
    cfg.rx = rx;
    cfg.rx_cap = sizeof rx;
    cfg.tx = tx;
    cfg.tx_cap = sizeof tx;
    cfg.name = "fuzz";
    cfg.groups = GROUPS;
    cfg.ngroups = 1;
    if (ayl_node_init(&node, &cfg) != 0) {
        abort();
    }
    v = ayl_float(0.0);
    ayl_node_expose(&node, "Drive", "Speed", &v, NULL, 0, NULL, NULL);
    v = ayl_int(0);
    ayl_node_expose(&node, "Drive", "Count", &v, NULL, 0, NULL, NULL);
    v = ayl_bool(0);
    ayl_node_expose(&node, "Drive", "On", &v, NULL, 0, NULL, NULL);
    v = ayl_text("");
    ayl_node_expose(&node, "Drive", "Mode", &v, text_store, sizeof text_store, NULL, NULL);
    v = ayl_vector(vec, 2);
    ayl_node_expose(&node, "Drive", "Goal", &v, (uint8_t *)vec_store, sizeof vec_store, NULL, NULL);

    memset(&from, 0, sizeof from);
    from.len = 4;
    from.bytes[0] = 1;
    to = from;
    /* A request waiting for its answer, so REPLY parts have somewhere to go. */
    memset(&req, 0, sizeof req);
    req.op = AYL_OP_READ;
    req.behavior = ayl_s("M");
    req.port = ayl_s("Speed");
    ayl_node_request(&node, &to, &req, out, sizeof out, &id);

    c = ayl_node_receive(&node, data, size, &from, 1000000000ull);
    if ((int)c < 0 || (int)c >= AYL_CAUSE_COUNT) {
        abort();
    }
    ayl_node_poll(&node, 2000000000ull);
    ayl_node_request_take(&node, id, NULL, NULL);
    return 0;
}
