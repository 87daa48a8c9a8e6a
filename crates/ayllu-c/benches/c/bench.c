/*
 * bench.c -- the C half of `make bench-c` (crates/ayllu-c/benches/c_vs_rust.rs runs it and
 * prints it beside the same operations from Rust, measured in the same run): a port write
 * crossing one Normal connection (through a port handle, and by name), and a process
 * activation (a C process body writing its own port, driven by a manual clock). Prints one
 * JSON line of nanoseconds per operation (the best of 5 rounds).
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "ayllu_sys.h"

static double now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e9 + (double)t.tv_nsec;
}

static void must(ay_status s, const char *what) {
    if (s != AY_OK) {
        fprintf(stderr, "bench: %s: %s\n", what, ay_last_error());
        exit(1);
    }
}

static ay_port out_port = {0xFFFF};

static void tick(ay_ctx *ctx, void *user) {
    int64_t *n = (int64_t *)user;
    if (out_port.index == 0xFFFF) {
        must(ay_ctx_port(ctx, "Out", &out_port), "ay_ctx_port");
    }
    must(ay_ctx_write_int(ctx, out_port, ++*n), "ay_ctx_write_int");
}

int main(int argc, char **argv) {
    long writes = argc > 1 ? atol(argv[1]) : 1000000;
    long activations = argc > 2 ? atol(argv[2]) : 200000;
    ay_clock *clock;
    ay_node *node;
    ay_class *relay, *ticker;
    ay_endpoint a = {AY_LOCAL, 0, NULL, "A", "V"}, b = {AY_LOCAL, 0, NULL, "B", "V"};
    ay_port_ref ref;
    int64_t n = 0;
    double best_ref = 1e30, best_named = 1e30, best_activation = 1e30;
    must(ay_clock_new(&clock), "ay_clock_new");
    must(ay_node_open_manual(1, "mem://bench-c", clock, &node), "ay_node_open_manual");
    must(ay_class_new("Relay", &relay), "ay_class_new");
    must(ay_class_port_int(relay, "V", 0, AY_PORT_NORMAL, 0, 0, NULL), "port");
    must(ay_node_define(node, relay), "define");
    must(ay_node_create(node, "Relay", "A"), "create");
    must(ay_node_create(node, "Relay", "B"), "create");
    must(ay_node_connect(node, &a, &b, AY_NORMAL, 0, 0, NULL), "connect");
    must(ay_node_port(node, "A", "V", &ref), "port handle");
    must(ay_class_new("Ticker", &ticker), "ay_class_new");
    must(ay_class_port_int(ticker, "Out", 0, AY_PORT_NORMAL, 0, 0, NULL), "port");
    must(ay_class_every_hz(ticker, "Tick", 1000.0, tick, &n), "every_hz");
    must(ay_node_define(node, ticker), "define");
    must(ay_node_create(node, "Ticker", "T"), "create");
    for (int round = 0; round < 5; round++) {
        double t0 = now_ns();
        for (long i = 0; i < writes; i++) {
            must(ay_node_write_int_ref(node, ref, i), "write");
        }
        double t1 = now_ns();
        for (long i = 0; i < writes / 4; i++) {
            must(ay_node_write_int(node, "A", "V", i), "write by name");
        }
        double t2 = now_ns();
        for (long i = 0; i < activations; i++) {
            must(ay_clock_advance(clock, 0.001), "advance");
            must(ay_node_step(node, NULL), "step");
        }
        double t3 = now_ns();
        if ((t1 - t0) / writes < best_ref) best_ref = (t1 - t0) / writes;
        if ((t2 - t1) / (writes / 4) < best_named) best_named = (t2 - t1) / (writes / 4);
        if ((t3 - t2) / activations < best_activation) best_activation = (t3 - t2) / activations;
    }
    {
        int64_t b_value = 0;
        ay_node_read_int(node, "B", "V", &b_value);
        if (b_value != writes / 4 - 1 || n < activations) {
            fprintf(stderr, "bench: the work was not done (B.V %lld, activations %lld)\n", (long long)b_value, (long long)n);
            return 1;
        }
    }
    printf("{\"write_ref_ns\":%.2f,\"write_named_ns\":%.2f,\"activation_ns\":%.2f}\n", best_ref, best_named, best_activation);
    must(ay_node_free(node), "free");
    must(ay_clock_free(clock), "free");
    return 0;
}
