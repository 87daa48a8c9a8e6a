/*
 * test_rules.c -- the runtime's rules through libayllu's C ABI (ayllu_sys.h), with the
 * expected values of the core's rule tests (crates/ayllu-core/tests/, each file named at its
 * test): every connection kind (S6), every port kind and value type (S1, S3), freshness (S4),
 * slots and monostables (S2), periodic and triggered processes (S7), remote and group
 * endpoints (S10) and BLE (S11) over mem://, port handles, why/list reports. Time is a manual
 * clock: nothing here depends on how fast the machine is.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "check.h"

static ay_clock *clock_;

/* The clock at `ms` milliseconds. */
static void at(double ms) {
    OK(ay_clock_set(clock_, ms / 1000.0));
}

/* A node on mem://`net` with class Relay (int port V, Normal, default 0) and one Relay per
 * name (common/mod.rs: wiring). */
static ay_node *wiring(uint32_t id, const char *net, const char *const *names, int n) {
    ay_node *node = NULL;
    ay_class *relay = NULL;
    OK(ay_node_open_manual(id, net, clock_, &node));
    OK(ay_class_new("Relay", &relay));
    OK(ay_class_port_int(relay, "V", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_node_define(node, relay));
    for (int i = 0; i < n; i++) {
        OK(ay_node_create(node, "Relay", names[i]));
    }
    return node;
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

/* Connect from.V -> to.V with `kind` and a period in milliseconds. */
static uint64_t link_(ay_node *node, const char *from, const char *to, uint32_t kind, double ms) {
    ay_endpoint s = local(from, "V"), d = local(to, "V");
    uint64_t id = 0;
    OK(ay_node_connect(node, &s, &d, kind, ms / 1000.0, 0, &id));
    return id;
}

static void put(ay_node *node, double ms, const char *name, int64_t v) {
    at(ms);
    OK(ay_node_write_int(node, name, "V", v));
}

static int64_t value(ay_node *node, const char *name) {
    int64_t v = -999;
    ay_status s = ay_node_read_int(node, name, "V", &v);
    CHECK(s == AY_OK || s == AY_ERR_ABSENT);
    return v;
}

static ay_node *four(const char *net, const char *first) {
    const char *names[] = {first, "A", "D", "E"};
    return wiring(1, net, names, 4);
}

static void normal_connection(void) {
    /* connection_normal.rs: m is written to d and propagated along d's connections. */
    ay_node *node = four("mem://rules-normal", "S");
    link_(node, "A", "D", AY_NORMAL, 0);
    link_(node, "D", "E", AY_NORMAL, 0);
    put(node, 0, "A", 5);
    CHECK_EQ_INT(value(node, "D"), 5);
    CHECK_EQ_INT(value(node, "E"), 5);
    OK(ay_node_free(node));
}

static void suppress_connection(void) {
    /* connection_suppress.rs: S --Suppress(100ms)--> D <--Normal-- A, D --> E. */
    ay_node *node = four("mem://rules-suppress", "S");
    link_(node, "S", "D", AY_SUPPRESS, 100);
    link_(node, "A", "D", AY_NORMAL, 0);
    link_(node, "D", "E", AY_NORMAL, 0);
    /* suppress_message_is_not_written */
    put(node, 0, "S", 7);
    CHECK_EQ_INT(value(node, "D"), 0);
    CHECK_EQ_INT(value(node, "E"), 0);
    /* suppress_blocks_every_connection_write_for_the_period (from 1000 ms on) */
    put(node, 1000, "A", 1);
    CHECK_EQ_INT(value(node, "D"), 1);
    put(node, 1010, "S", 0);
    put(node, 1020, "A", 2);
    put(node, 1109, "A", 3);
    CHECK_EQ_INT(value(node, "D"), 1);
    CHECK_EQ_INT(value(node, "E"), 1);
    /* suppress_lapses_after_the_period: t + p is exclusive */
    put(node, 1110, "A", 4);
    CHECK_EQ_INT(value(node, "D"), 4);
    CHECK_EQ_INT(value(node, "E"), 4);
    /* suppress_is_refreshed_by_each_message */
    put(node, 2000, "S", 0);
    put(node, 2080, "S", 0);
    put(node, 2150, "A", 5);
    CHECK_EQ_INT(value(node, "D"), 4);
    put(node, 2180, "A", 6);
    CHECK_EQ_INT(value(node, "D"), 6);
    OK(ay_node_free(node));
}

static void inhibit_connection(void) {
    /* connection_inhibit.rs: I --Inhibit(100ms)--> D <--Normal-- A, D --> E: d stores, but
     * nothing propagates out of it until t + p. */
    ay_node *node = four("mem://rules-inhibit", "I");
    link_(node, "I", "D", AY_INHIBIT, 100);
    link_(node, "A", "D", AY_NORMAL, 0);
    link_(node, "D", "E", AY_NORMAL, 0);
    put(node, 0, "I", 9);
    CHECK_EQ_INT(value(node, "D"), 0);
    put(node, 10, "A", 4);
    CHECK_EQ_INT(value(node, "D"), 4);
    CHECK_EQ_INT(value(node, "E"), 0);
    put(node, 20, "D", 3); /* its own write is inhibited too */
    CHECK_EQ_INT(value(node, "E"), 0);
    put(node, 100, "A", 5);
    CHECK_EQ_INT(value(node, "E"), 5);
    OK(ay_node_free(node));
}

static void override_in_connection(void) {
    /* connection_override_in.rs: O --OverrideIn(100ms)--> D <--Normal-- A, D --> E: m is
     * written and propagated; only O may write d until t + p. */
    ay_node *node = four("mem://rules-override-in", "O");
    link_(node, "O", "D", AY_OVERRIDE_IN, 100);
    link_(node, "A", "D", AY_NORMAL, 0);
    link_(node, "D", "E", AY_NORMAL, 0);
    put(node, 0, "O", 7);
    CHECK_EQ_INT(value(node, "D"), 7);
    CHECK_EQ_INT(value(node, "E"), 7);
    put(node, 10, "A", 1);
    CHECK_EQ_INT(value(node, "D"), 7);
    put(node, 20, "O", 8);
    CHECK_EQ_INT(value(node, "E"), 8);
    put(node, 119, "A", 2);
    CHECK_EQ_INT(value(node, "D"), 8);
    put(node, 120, "A", 2);
    CHECK_EQ_INT(value(node, "D"), 2);
    CHECK_EQ_INT(value(node, "E"), 2);
    OK(ay_node_free(node));
}

static void override_out_connection(void) {
    /* connection_override_out.rs: O --OverrideOut(100ms)--> D <--Normal-- A, D --> E: m is
     * written and propagated; only what comes along O propagates out of d until t + p. */
    ay_node *node = four("mem://rules-override-out", "O");
    link_(node, "O", "D", AY_OVERRIDE_OUT, 100);
    link_(node, "A", "D", AY_NORMAL, 0);
    link_(node, "D", "E", AY_NORMAL, 0);
    put(node, 0, "O", 7);
    CHECK_EQ_INT(value(node, "D"), 7);
    CHECK_EQ_INT(value(node, "E"), 7);
    put(node, 10, "A", 1);
    CHECK_EQ_INT(value(node, "D"), 1);
    CHECK_EQ_INT(value(node, "E"), 7);
    put(node, 20, "D", 3);
    CHECK_EQ_INT(value(node, "E"), 7);
    put(node, 100, "A", 4);
    CHECK_EQ_INT(value(node, "E"), 4);
    OK(ay_node_free(node));
}

static void write_inhibit_connection(void) {
    /* connection_write_inhibit.rs: W --WriteInhibit(100ms)--> D <--Normal-- A, D --> E. */
    ay_node *node = four("mem://rules-write-inhibit", "W");
    link_(node, "W", "D", AY_WRITE_INHIBIT, 100);
    link_(node, "A", "D", AY_NORMAL, 0);
    link_(node, "D", "E", AY_NORMAL, 0);
    put(node, 0, "W", 7); /* write_inhibit_message_is_not_written */
    CHECK_EQ_INT(value(node, "D"), 0);
    put(node, 10, "D", 3); /* own_writes_are_stored_but_not_propagated */
    CHECK_EQ_INT(value(node, "D"), 3);
    CHECK_EQ_INT(value(node, "E"), 0);
    put(node, 20, "A", 5); /* connection_writes_still_propagate */
    CHECK_EQ_INT(value(node, "E"), 5);
    put(node, 100, "D", 6); /* write_inhibit_lapses */
    CHECK_EQ_INT(value(node, "E"), 6);
    OK(ay_node_free(node));
}

/* A node with class Agg: one port `In` as declared by `declare`, and Relays A, B to feed it. */
static ay_node *aggregating(const char *net, ay_status (*declare)(ay_class *)) {
    ay_node *node = NULL;
    ay_class *c = NULL;
    OK(ay_node_open_manual(1, net, clock_, &node));
    OK(ay_class_new("Agg", &c));
    OK(declare(c));
    OK(ay_node_define(node, c));
    OK(ay_node_create(node, "Agg", "P"));
    return node;
}

static ay_status max_int(ay_class *c) {
    return ay_class_port_int(c, "In", 42, AY_PORT_MAX, 0, 0, NULL);
}
static ay_status max_window(ay_class *c) {
    return ay_class_port_float(c, "In", 0, AY_PORT_MAX, 0, 1.0, NULL);
}
static ay_status min_int(ay_class *c) {
    return ay_class_port_int(c, "In", 0, AY_PORT_MIN, 0, 0, NULL);
}
static ay_status sum_float(ay_class *c) {
    return ay_class_port_float(c, "In", 0, AY_PORT_SUM, 0, 0, NULL);
}
static ay_status sum_vector(ay_class *c) {
    const double zero[2] = {0, 0};
    return ay_class_port_vector(c, "In", zero, 2, AY_PORT_SUM, 0, 0, NULL);
}
static ay_status lifespan_float(ay_class *c) {
    return ay_class_port_float(c, "In", 0, AY_PORT_NORMAL, 0.3, 0, NULL);
}

static void port_kinds(void) {
    int64_t i = 0;
    double f = 0;
    /* port_max.rs: starts empty (reads the default, not fresh); the first write sets even
     * below the default; keeps the maximum; smaller values are absorbed; reset empties. */
    ay_node *node = aggregating("mem://rules-max", max_int);
    at(0);
    CHECK(ay_node_read_int(node, "P", "In", &i) == AY_ERR_ABSENT);
    CHECK_EQ_INT(i, 42);
    OK(ay_node_write_int(node, "P", "In", -5));
    OK(ay_node_read_int(node, "P", "In", &i));
    CHECK_EQ_INT(i, -5);
    OK(ay_node_write_int(node, "P", "In", 3));
    OK(ay_node_write_int(node, "P", "In", 7));
    OK(ay_node_write_int(node, "P", "In", 5));
    OK(ay_node_read_int(node, "P", "In", &i));
    CHECK_EQ_INT(i, 7);
    OK(ay_node_reset(node, "P", "In"));
    CHECK(ay_node_read_int(node, "P", "In", &i) == AY_ERR_ABSENT);
    OK(ay_node_free(node));

    /* port.rs (PortSpec example): a 1 s window opened by the first value. */
    node = aggregating("mem://rules-max-window", max_window);
    at(0);
    OK(ay_node_write_float(node, "P", "In", 3.0));
    at(500);
    OK(ay_node_write_float(node, "P", "In", 2.0));
    OK(ay_node_read_float(node, "P", "In", &f));
    CHECK_NEAR(f, 3.0);
    at(1200);
    OK(ay_node_write_float(node, "P", "In", 2.0));
    OK(ay_node_read_float(node, "P", "In", &f));
    CHECK_NEAR(f, 2.0);
    OK(ay_node_free(node));

    /* port_min.rs: c := min(c, m). */
    node = aggregating("mem://rules-min", min_int);
    OK(ay_node_write_int(node, "P", "In", 3));
    OK(ay_node_write_int(node, "P", "In", 7));
    OK(ay_node_write_int(node, "P", "In", 1));
    OK(ay_node_read_int(node, "P", "In", &i));
    CHECK_EQ_INT(i, 1);
    OK(ay_node_free(node));

    /* port_sum.rs: c := c + m (floats add; vectors add element-wise). */
    node = aggregating("mem://rules-sum", sum_float);
    OK(ay_node_write_float(node, "P", "In", 1.5));
    OK(ay_node_write_float(node, "P", "In", 2.25));
    OK(ay_node_read_float(node, "P", "In", &f));
    CHECK_NEAR(f, 3.75);
    OK(ay_node_free(node));
    node = aggregating("mem://rules-sum-vector", sum_vector);
    {
        const double a[2] = {1, 2}, b[2] = {3, 4};
        double got[2] = {0, 0};
        size_t len = 0;
        OK(ay_node_write_vector(node, "P", "In", a, 2));
        OK(ay_node_write_vector(node, "P", "In", b, 2));
        OK(ay_node_read_vector(node, "P", "In", got, 2, &len));
        CHECK_EQ_INT(len, 2);
        CHECK_NEAR(got[0], 4);
        CHECK_NEAR(got[1], 6);
        CHECK(ay_node_read_vector(node, "P", "In", got, 1, &len) == AY_ERR_BUFFER);
        CHECK_EQ_INT(len, 2);
    }
    OK(ay_node_free(node));

    /* freshness.rs: a port with a lifespan reads as absent from last accepted + lifespan. */
    node = aggregating("mem://rules-lifespan", lifespan_float);
    at(2000);
    OK(ay_node_write_float(node, "P", "In", 1.0));
    at(2299);
    OK(ay_node_read_float(node, "P", "In", &f));
    at(2300);
    CHECK(ay_node_read_float(node, "P", "In", &f) == AY_ERR_ABSENT);
    CHECK_NEAR(f, 1.0);
    {
        bool fresh = true;
        OK(ay_node_fresh(node, "P", "In", &fresh));
        CHECK(!fresh);
    }
    OK(ay_node_free(node));
}

static void priority_port(void) {
    /* port_priority.rs: c := m iff priority(m) > priority(c); the holder may always update. */
    ay_node *node = NULL;
    ay_class *c = NULL;
    ay_endpoint lo = local("Lo", "Out"), hi = local("Hi", "Out"), p = local("P", "In");
    int64_t v = 0;
    OK(ay_node_open_manual(1, "mem://rules-priority", clock_, &node));
    OK(ay_class_new("Src", &c));
    OK(ay_class_port_int(c, "Out", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_node_define(node, c));
    OK(ay_class_new("Agg", &c));
    OK(ay_class_port_int(c, "In", 0, AY_PORT_PRIORITY, 0, 0.5, NULL));
    OK(ay_node_define(node, c));
    OK(ay_node_create(node, "Src", "Lo"));
    OK(ay_node_create(node, "Src", "Hi"));
    OK(ay_node_create(node, "Agg", "P"));
    OK(ay_node_connect(node, &lo, &p, AY_NORMAL, 0, 1, NULL));
    OK(ay_node_connect(node, &hi, &p, AY_NORMAL, 0, 2, NULL));
    at(0);
    OK(ay_node_write_int(node, "Hi", "Out", 5));
    OK(ay_node_write_int(node, "Lo", "Out", 9));
    OK(ay_node_read_int(node, "P", "In", &v));
    CHECK_EQ_INT(v, 5);
    OK(ay_node_write_int(node, "Hi", "Out", 6));
    OK(ay_node_read_int(node, "P", "In", &v));
    CHECK_EQ_INT(v, 6);
    at(600); /* the holder's lease (the window) has ended: a lower priority may take it */
    OK(ay_node_write_int(node, "Lo", "Out", 9));
    OK(ay_node_read_int(node, "P", "In", &v));
    CHECK_EQ_INT(v, 9);
    OK(ay_node_free(node));
}

static void text_and_bytes_ports(void) {
    ay_node *node = NULL;
    ay_class *c = NULL;
    char buf[16];
    uint8_t bytes[4] = {0};
    size_t len = 0;
    const uint8_t payload[3] = {1, 2, 255};
    OK(ay_node_open_manual(1, "mem://rules-text", clock_, &node));
    OK(ay_class_new("Say", &c));
    OK(ay_class_port_text(c, "Word", "none", AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_port_text(c, "Goal", "idle", AY_PORT_PRIORITY, 0, 0, NULL));
    OK(ay_class_port_bytes(c, "Blob", NULL, 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_port_bool(c, "Flag", false, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_node_define(node, c));
    OK(ay_node_create(node, "Say", "S"));
    /* Never written: reads its default, and is not fresh (rule S4). */
    CHECK(ay_node_read_text(node, "S", "Word", buf, sizeof buf, &len) == AY_ERR_ABSENT);
    CHECK(strcmp(buf, "none") == 0);
    OK(ay_node_write_text(node, "S", "Word", "hello"));
    OK(ay_node_read_text(node, "S", "Word", buf, sizeof buf, &len));
    CHECK(strcmp(buf, "hello") == 0);
    CHECK_EQ_INT(len, 5);
    CHECK(ay_node_read_text(node, "S", "Word", buf, 5, &len) == AY_ERR_BUFFER); /* no room for NUL */
    CHECK_EQ_INT(len, 5);
    OK(ay_node_write_bytes(node, "S", "Blob", payload, 3));
    OK(ay_node_read_bytes(node, "S", "Blob", bytes, sizeof bytes, &len));
    CHECK_EQ_INT(len, 3);
    CHECK(bytes[2] == 255);
    {
        bool flag = false;
        OK(ay_node_write_bool(node, "S", "Flag", true));
        OK(ay_node_read_bool(node, "S", "Flag", &flag));
        CHECK(flag);
    }
    OK(ay_node_free(node));
}

/* ---- processes ---- */

struct counts {
    int periodic;
    int triggered;
    int mono_changes;
};

static void count_up(ay_ctx *ctx, void *user) {
    struct counts *n = (struct counts *)user;
    ay_slot slot;
    ay_port out;
    int64_t k = 0;
    n->periodic++;
    OK(ay_ctx_slot(ctx, "N", &slot));
    OK(ay_ctx_port(ctx, "Out", &out));
    OK(ay_ctx_slot_get_int(ctx, slot, &k));
    OK(ay_ctx_slot_set_int(ctx, slot, k + 1));
    OK(ay_ctx_write_int(ctx, out, k + 1));
}

static void double_it(ay_ctx *ctx, void *user) {
    struct counts *n = (struct counts *)user;
    ay_port in, twice;
    ay_mono busy;
    int64_t v = 0;
    n->triggered++;
    OK(ay_ctx_port(ctx, "In", &in));
    OK(ay_ctx_port(ctx, "Twice", &twice));
    OK(ay_ctx_monostable(ctx, "Busy", &busy));
    OK(ay_ctx_read_int(ctx, in, &v));
    OK(ay_ctx_write_int(ctx, twice, 2 * v));
    OK(ay_ctx_trigger(ctx, busy, 2.0));
}

static void on_busy(ay_ctx *ctx, void *user) {
    (void)ctx;
    ((struct counts *)user)->mono_changes++;
}

static void processes(void) {
    /* process_periodic.rs, process_triggered.rs, monostable.rs. */
    struct counts n = {0, 0, 0};
    ay_node *node = NULL;
    ay_class *c = NULL;
    int64_t v = 0;
    bool high = false;
    OK(ay_node_open_manual(1, "mem://rules-processes", clock_, &node));
    at(0);
    OK(ay_class_new("Counter", &c));
    OK(ay_class_port_int(c, "Out", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_port_int(c, "In", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_port_int(c, "Twice", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_slot_int(c, "N", 0, NULL));
    OK(ay_class_monostable(c, "Busy", NULL));
    OK(ay_class_every_hz(c, "CountUp", 10.0, count_up, &n));
    OK(ay_class_on_write(c, "DoubleIt", "In", double_it, &n));
    OK(ay_class_on_monostable(c, "OnBusy", "Busy", on_busy, &n));
    OK(ay_node_define(node, c));
    OK(ay_node_create(node, "Counter", "C"));
    /* Periodic at 10 Hz from creation: activations due at 0, 100, 200 ms. */
    OK(ay_node_step(node, NULL));
    at(100);
    OK(ay_node_step(node, NULL));
    at(200);
    OK(ay_node_step(node, NULL));
    CHECK_EQ_INT(n.periodic, 3);
    OK(ay_node_read_int(node, "C", "Out", &v));
    CHECK_EQ_INT(v, 3);
    /* Late: 350 ms runs the 300 ms activation once; 700 ms skips 400..600 (no burst). */
    at(350);
    OK(ay_node_step(node, NULL));
    CHECK_EQ_INT(n.periodic, 4);
    at(700);
    OK(ay_node_step(node, NULL));
    CHECK_EQ_INT(n.periodic, 5);
    /* Triggered by a write into In: runs in the next step, once per accepted value. */
    at(750);
    OK(ay_node_write_int(node, "C", "In", 21));
    OK(ay_node_step(node, NULL));
    CHECK_EQ_INT(n.triggered, 1);
    OK(ay_node_read_int(node, "C", "Twice", &v));
    CHECK_EQ_INT(v, 42);
    /* The monostable rose at 750 ms for 2 s: high until 2749.999 ms. */
    OK(ay_node_monostable(node, "C", "Busy", &high));
    CHECK(high);
    at(2749);
    OK(ay_node_monostable(node, "C", "Busy", &high));
    CHECK(high);
    at(2750);
    OK(ay_node_monostable(node, "C", "Busy", &high));
    CHECK(!high);
    OK(ay_node_step(node, NULL));
    CHECK_EQ_INT(n.mono_changes, 2); /* rose, fell */
    /* Triggering from outside: end := max(end, now + p). */
    OK(ay_node_trigger(node, "C", "Busy", 1.0));
    at(3749);
    OK(ay_node_monostable(node, "C", "Busy", &high));
    CHECK(high);
    OK(ay_node_free(node));
}

/* process_while_fresh.rs (D7.5): activated at its due times only while its port is fresh. */
static void count_seen(ay_ctx *ctx, void *user) {
    int *runs = (int *)user;
    ay_port in;
    double v = 0.0;
    OK(ay_ctx_port(ctx, "In", &in));
    OK(ay_ctx_read_float(ctx, in, &v));
    (*runs)++;
}

static void while_fresh(void) {
    int runs = 0;
    ay_node *node = NULL;
    ay_class *c = NULL;
    OK(ay_node_open_manual(1, "mem://rules-while-fresh", clock_, &node));
    at(0);
    OK(ay_class_new("Seer", &c));
    OK(ay_class_port_float(c, "In", 0.0, AY_PORT_NORMAL, 0.15, 0, NULL));
    CHECK_EQ_INT(ay_class_every_hz_while_fresh(c, "Look", 10.0, "Nope", count_seen, &runs), AY_ERR_UNKNOWN);
    CHECK_EQ_INT(ay_class_every_hz_while_fresh(c, "Look", 0.0, "In", count_seen, &runs), AY_ERR_RATE);
    OK(ay_class_every_hz_while_fresh(c, "Look", 10.0, "In", count_seen, &runs));
    OK(ay_node_define(node, c));
    OK(ay_node_create(node, "Seer", "S"));
    /* Due every 100 ms from 0; `In` fresh for 150 ms after a write: written at 0 and 450, so
     * activated at 0, 100 and 500 only. */
    for (int t = 0; t <= 1000; t += 50) {
        at(t);
        if (t == 0 || t == 450) {
            OK(ay_node_write_float(node, "S", "In", 1.0));
        }
        OK(ay_node_step(node, NULL));
    }
    CHECK_EQ_INT(runs, 3);
    OK(ay_node_free(node));
}

/* ---- remote, group, BLE over mem:// ---- */

static ay_node *relay_node(uint32_t id, const char *net) {
    ay_node *node = NULL;
    ay_class *c = NULL;
    OK(ay_node_open_manual(id, net, clock_, &node));
    OK(ay_class_new("Relay", &c));
    OK(ay_class_port_int(c, "Out", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_port_int(c, "In", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_node_define(node, c));
    OK(ay_node_create(node, "Relay", "R"));
    return node;
}

static void step_all(ay_node **nodes, int n, double ms) {
    for (int round = 0; round < 3; round++) {
        for (int i = 0; i < n; i++) {
            OK(ay_node_step(nodes[i], NULL));
        }
        OK(ay_clock_advance(clock_, ms / 1000.0));
    }
}

static void remote_and_group(void) {
    /* node.rs (Node example) and remote.rs: (node, behavior, port) destinations; group
     * destinations reach every member but the sender (S10). */
    ay_node *nodes[3];
    ay_endpoint out = local("R", "Out");
    ay_endpoint to2 = local("R", "In"), group = local("R", "In");
    ay_endpoint from1 = local("R", "Out");
    int64_t v = 0;
    uint64_t request = 0;
    int32_t state = 0;
    for (int i = 0; i < 3; i++) {
        nodes[i] = relay_node((uint32_t)i + 1, "mem://rules-remote");
    }
    to2.scope = AY_NODE;
    to2.node = 2;
    OK(ay_node_connect(nodes[0], &out, &to2, AY_NORMAL, 0, 0, NULL));
    OK(ay_node_write_int(nodes[0], "R", "Out", 42));
    step_all(nodes, 3, 1);
    OK(ay_node_read_int(nodes[1], "R", "In", &v));
    CHECK_EQ_INT(v, 42);

    group.scope = AY_GROUP;
    group.group = "G";
    for (int i = 0; i < 3; i++) {
        OK(ay_node_join(nodes[i], "G"));
    }
    OK(ay_node_connect(nodes[2], &out, &group, AY_NORMAL, 0, 0, NULL));
    OK(ay_node_write_int(nodes[2], "R", "Out", 7));
    step_all(nodes, 3, 1);
    OK(ay_node_read_int(nodes[0], "R", "In", &v));
    CHECK_EQ_INT(v, 7);
    OK(ay_node_read_int(nodes[1], "R", "In", &v));
    CHECK_EQ_INT(v, 7);
    CHECK(ay_node_read_int(nodes[2], "R", "In", &v) == AY_ERR_ABSENT); /* not the sender */
    CHECK_EQ_INT(v, 0);

    /* A remote source: node 2 asks node 1 to connect 1.R.Out -> 2.R.In (N2). */
    from1.scope = AY_NODE;
    from1.node = 1;
    OK(ay_node_request_connect(nodes[1], &from1, &to2, AY_OVERRIDE_IN, 0.5, 0, &request));
    step_all(nodes, 3, 1);
    OK(ay_node_request_status(nodes[1], request, &state));
    CHECK_EQ_INT(state, 1);
    OK(ay_node_write_int(nodes[0], "R", "Out", 99));
    step_all(nodes, 3, 1);
    OK(ay_node_read_int(nodes[1], "R", "In", &v));
    CHECK_EQ_INT(v, 99);
    for (int i = 0; i < 3; i++) {
        OK(ay_node_free(nodes[i]));
    }
}

static void ble(void) {
    /* ble.rs: the most eligible peer claims; the others' output is write-inhibited. */
    ay_node *nodes[2];
    const double eligibility[2] = {0.8, 0.5};
    bool claiming[2] = {false, false};
    for (int i = 0; i < 2; i++) {
        ay_class *c = NULL;
        OK(ay_node_open_manual((uint32_t)i + 1, "mem://rules-ble", clock_, &nodes[i]));
        OK(ay_class_new("Task", &c));
        OK(ay_class_port_float(c, "Rotate", 0, AY_PORT_NORMAL, 0, 0, NULL));
        OK(ay_node_define(nodes[i], c));
        OK(ay_node_create(nodes[i], "Task", "T"));
        OK(ay_node_ble_join(nodes[i], "T", "Peers", "Rotate", 1.0, 0));
    }
    for (int tick = 0; tick < 60; tick++) { /* 6 s in 100 ms steps */
        for (int i = 0; i < 2; i++) {
            OK(ay_node_write_float(nodes[i], "T", "BLE_Local", eligibility[i]));
            OK(ay_node_step(nodes[i], NULL));
        }
        OK(ay_clock_advance(clock_, 0.1));
    }
    for (int i = 0; i < 2; i++) {
        OK(ay_node_ble_claiming(nodes[i], "T", &claiming[i]));
    }
    CHECK(claiming[0]);
    CHECK(!claiming[1]);
    {
        char *why = NULL;
        OK(ay_node_why_json(nodes[1], "T", "Rotate", &why));
        CHECK(why != NULL && strstr(why, "\"WriteInhibit\"") != NULL);
        OK(ay_string_free(why));
    }
    for (int i = 0; i < 2; i++) {
        OK(ay_node_free(nodes[i]));
    }
}

static void reports_and_handles(void) {
    /* introspection.rs: why and list. */
    const char *names[] = {"A", "B"};
    ay_node *node = wiring(1, "mem://rules-reports", names, 2);
    ay_port_ref a, b;
    char *json = NULL;
    int64_t v = 0;
    link_(node, "A", "B", AY_OVERRIDE_IN, 250);
    OK(ay_node_port(node, "A", "V", &a));
    OK(ay_node_port(node, "B", "V", &b));
    OK(ay_node_write_int_ref(node, a, 11));
    OK(ay_node_read_int_ref(node, b, &v));
    CHECK_EQ_INT(v, 11);
    OK(ay_node_why_json(node, "B", "V", &json));
    CHECK(json != NULL && strstr(json, "\"OverrideIn\"") != NULL);
    OK(ay_string_free(json));
    OK(ay_node_report_json(node, &json));
    CHECK(json != NULL && strstr(json, "\"Relay\"") != NULL);
    OK(ay_string_free(json));
    /* Removing a behavior removes its connections; its handles then fail (S9). */
    OK(ay_node_remove(node, "A"));
    CHECK(ay_node_write_int_ref(node, a, 1) == AY_ERR_UNKNOWN);
    OK(ay_node_free(node));
}

/* ---- the rest of the node's functions ---- */

static char behavior_name[16];

static void name_it(ay_ctx *ctx, void *user) {
    size_t len = 0;
    (void)user;
    OK(ay_ctx_behavior(ctx, behavior_name, sizeof behavior_name, &len));
    CHECK_EQ_INT(len, 3);
}

static void declare_flags(ay_class *cls, void *user) {
    (void)user;
    OK(ay_class_port_bool(cls, "On", false, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_port_float(cls, "Level", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_every_hz(cls, "NameIt", 1.0, name_it, NULL));
}

static void node_odds_and_ends(void) {
    ay_node *node = NULL;
    ay_port_ref on, level;
    uint32_t id = 0;
    double t = 0;
    bool b = false;
    double f = 0;
    char address[8];
    size_t len = 99;
    OK(ay_node_open_manual(7, "mem://rules-odds", clock_, &node));
    OK(ay_node_id(node, &id));
    CHECK_EQ_INT(id, 7);
    at(1500);
    OK(ay_node_now(node, &t));
    CHECK_NEAR(t, 1.5);
    OK(ay_clock_now(clock_, &t));
    CHECK_NEAR(t, 1.5);
    OK(ay_node_address(node, address, sizeof address, &len)); /* mem:// has no address */
    CHECK_EQ_INT(len, 0);
    CHECK(address[0] == '\0');
    OK(ay_node_define_with(node, "Flags", declare_flags, NULL));
    OK(ay_node_create(node, "Flags", "FL1"));
    OK(ay_node_step(node, NULL));
    CHECK(strcmp(behavior_name, "FL1") == 0);
    OK(ay_node_port(node, "FL1", "On", &on));
    OK(ay_node_port(node, "FL1", "Level", &level));
    OK(ay_node_write_bool_ref(node, on, true));
    OK(ay_node_write_float_ref(node, level, 0.75));
    OK(ay_node_read_bool_ref(node, on, &b));
    OK(ay_node_read_float_ref(node, level, &f));
    CHECK(b);
    CHECK_NEAR(f, 0.75);
    CHECK(ay_node_read_float_ref(node, level, NULL) == AY_ERR_NULL);
    OK(ay_node_join(node, "G"));
    OK(ay_node_leave(node, "G"));
    OK(ay_node_free(node));
}

/* Each test starts at time 0 on a clock of its own (a manual clock never goes back). */
static void run(void (*test)(void)) {
    OK(ay_clock_new(&clock_));
    test();
    OK(ay_clock_free(clock_));
    clock_ = NULL;
}

int main(void) {
    run(normal_connection);
    run(suppress_connection);
    run(inhibit_connection);
    run(override_in_connection);
    run(override_out_connection);
    run(write_inhibit_connection);
    run(port_kinds);
    run(priority_port);
    run(text_and_bytes_ports);
    run(processes);
    run(while_fresh);
    run(remote_and_group);
    run(ble);
    run(reports_and_handles);
    run(node_odds_and_ends);
    return check_exit("test_rules");
}
