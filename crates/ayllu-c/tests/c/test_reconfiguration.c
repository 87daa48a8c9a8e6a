/*
 * test_reconfiguration.c -- structure changes from inside C processes and transactions from C
 * (docs/semantics.md R1-R12), with the expectations of crates/ayllu-core/tests/
 * structure_from_process.rs: a process recruits a helper (create + connect) applied when it
 * returns, reads the outcomes on its next activation (a connection id, a refusal with its
 * status and message), and a behavior removes itself, handing over to a successor; the
 * transaction call refuses bad plans. Manual clock over mem://: nothing depends on speed.
 */
#include <stdint.h>
#include <stdlib.h>

#include "check.h"

static ay_clock *clock_;

static void at(double ms) {
    OK(ay_clock_set(clock_, ms / 1000.0));
}

static ay_endpoint local(const char *behavior, const char *port) {
    ay_endpoint e;
    e.scope = AY_LOCAL;
    e.node = 0;
    e.group = NULL;
    e.behavior = behavior;
    e.port = port;
    return e;
}

/* What the Boss's process saw, for the test to check after each poll. */
static int seen_pending_helper = -1;
static size_t seen_count = 99;
static ay_status seen_outcome[3];
static uint64_t seen_connection;

/* Boss.Go: 1 recruits Helper (create, connect Boss.Out -> Helper.In, and a bad create);
 * 2 reads the outcomes; 3 hands over to Boss2 and removes itself. Writes Out = 10 * Go. */
static void boss(ay_ctx *ctx, void *user) {
    (void)user;
    ay_port go, out;
    int64_t g = 0;
    OK(ay_ctx_port(ctx, "Go", &go));
    OK(ay_ctx_port(ctx, "Out", &out));
    OK(ay_ctx_read_int(ctx, go, &g));
    OK(ay_ctx_change_count(ctx, &seen_count));
    for (size_t i = 0; i < seen_count && i < 3; i++) {
        seen_outcome[i] = ay_ctx_change_outcome(ctx, i, i == 1 ? &seen_connection : NULL);
    }
    if (g == 1) {
        ay_endpoint s = local("Boss", "Out"), d = local("Helper", "In");
        size_t index = 99;
        OK(ay_ctx_create(ctx, "Sink", "Helper", &index));
        CHECK_EQ_INT(index, 0);
        OK(ay_ctx_connect(ctx, &s, &d, AY_NORMAL, 0.0, 0, &index));
        CHECK_EQ_INT(index, 1);
        OK(ay_ctx_create(ctx, "NoSuchClass", "Ghost", NULL));
        /* Refused at the call, not queued (R2). */
        FAILS(ay_ctx_create(ctx, "Sink", "", NULL), AY_ERR_INVALID, "empty");
        FAILS(ay_ctx_connect(ctx, &s, &d, AY_SUPPRESS, 0.0, 0, NULL), AY_ERR_PERIOD, "period");
        /* Not applied while the process runs (R1). */
        ay_port h;
        seen_pending_helper = ay_ctx_port(ctx, "Helper", &h) == AY_OK;
    }
    if (g == 3) {
        ay_endpoint s = local("Boss2", "Out"), d = local("Helper", "In");
        OK(ay_ctx_create(ctx, "Boss", "Boss2", NULL));
        OK(ay_ctx_connect(ctx, &s, &d, AY_NORMAL, 0.0, 0, NULL));
        OK(ay_ctx_remove(ctx, "Boss", NULL));
    }
    OK(ay_ctx_write_int(ctx, out, 10 * g));
}

static void process_changes(void) {
    ay_node *node = NULL;
    ay_class *b = NULL, *sink = NULL;
    OK(ay_node_open_manual(1, "mem://reconf-c", clock_, &node));
    OK(ay_class_new("Boss", &b));
    OK(ay_class_port_int(b, "Go", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_port_int(b, "Out", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_on_write(b, "Steer", "Go", boss, NULL));
    OK(ay_node_define(node, b));
    OK(ay_class_new("Sink", &sink));
    OK(ay_class_port_int(sink, "In", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_node_define(node, sink));
    OK(ay_node_create(node, "Boss", "Boss"));

    at(0);
    OK(ay_node_write_int(node, "Boss", "Go", 1));
    OK(ay_node_step(node, NULL));
    CHECK_EQ_INT(seen_pending_helper, 0);
    CHECK_EQ_INT(seen_count, 0);
    int64_t v = -1;
    /* The wave ran before the connection existed (R4): nothing arrived. */
    FAILS(ay_node_read_int(node, "Helper", "In", &v), AY_ERR_ABSENT, "fresh");

    at(10);
    OK(ay_node_write_int(node, "Boss", "Go", 2));
    OK(ay_node_step(node, NULL));
    CHECK_EQ_INT(seen_count, 3);
    CHECK_EQ_INT(seen_outcome[0], AY_OK);
    CHECK_EQ_INT(seen_outcome[1], AY_OK);
    CHECK(seen_connection != 0);
    CHECK_EQ_INT(seen_outcome[2], AY_ERR_UNKNOWN);
    OK(ay_node_read_int(node, "Helper", "In", &v));
    CHECK_EQ_INT(v, 20);

    at(20);
    OK(ay_node_write_int(node, "Boss", "Go", 3));
    OK(ay_node_step(node, NULL));
    FAILS(ay_node_read_int(node, "Boss", "Go", &v), AY_ERR_UNKNOWN, "Boss");
    OK(ay_node_read_int(node, "Helper", "In", &v));
    CHECK_EQ_INT(v, 30); /* its last write crossed its connection before it went (R3) */
    at(30);
    OK(ay_node_write_int(node, "Boss2", "Out", 7));
    OK(ay_node_read_int(node, "Helper", "In", &v));
    CHECK_EQ_INT(v, 7);

    /* Outside a process, the context calls refuse. */
    FAILS(ay_ctx_create(NULL, "Sink", "X", NULL), AY_ERR_NULL, "ctx");
    OK(ay_node_free(node));
}

static void transactions(void) {
    ay_node *node = NULL;
    OK(ay_node_open_manual(9, "mem://reconf-c-txn", clock_, &node));
    char report[256];
    size_t length = 0;
    FAILS(ay_node_apply(node, "[[node]]\nid = 2\nchanges = [{ op = \"connect\", from = \"A\" }]\n", report,
                        sizeof report, &length),
          AY_ERR_INVALID, "BEHAVIOR.PORT");
    FAILS(ay_node_apply(node, "[[node]]\nid = 9\nchanges = []\n", report, sizeof report, &length), AY_ERR_INVALID,
          "cannot be part");
    FAILS(ay_node_apply(node, NULL, report, sizeof report, &length), AY_ERR_NULL, "plan");
    OK(ay_node_free(node));
}

int main(void) {
    OK(ay_clock_new(&clock_));
    process_changes();
    transactions();
    OK(ay_clock_free(clock_));
    return check_exit("test_reconfiguration");
}
