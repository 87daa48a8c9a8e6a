/*
 * test_misuse.c -- every bad call returns an error code and a message naming the problem,
 * and none crashes the process (under AddressSanitizer and UBSan, so a use after free or an
 * out-of-bounds access inside the library would fail this test too): NULL handles and
 * pointers, unknown names, wrong types, zero/negative/NaN periods and rates, unknown kind
 * constants, freed handles (nodes, classes, clocks), handles of another type, a process
 * context used outside its process, a process calling its own node, buffers too small.
 */
#include <math.h>
#include <stdint.h>

#include "check.h"

static ay_clock *clock_;
static ay_node *node_;

/* What the process below saw. */
static ay_ctx *kept_ctx;
static ay_status own_node_write = AY_OK;
static ay_status own_node_free = AY_OK;
static ay_status stranger_port = AY_OK;
static ay_status wrong_type_write = AY_OK;
static ay_status bad_handle_read = AY_OK;
static ay_status zero_trigger = AY_OK;
static ay_status nan_into_max = AY_OK;

static void meddle(ay_ctx *ctx, void *user) {
    ay_port out, max;
    ay_port bogus;
    ay_mono mono;
    int64_t v = 0;
    (void)user;
    kept_ctx = ctx;
    own_node_write = ay_node_write_int(node_, "B", "Out", 1);
    own_node_free = ay_node_free(node_);
    stranger_port = ay_ctx_port(ctx, "Nope", &out);
    OK(ay_ctx_port(ctx, "Out", &out));
    OK(ay_ctx_port(ctx, "Max", &max));
    wrong_type_write = ay_ctx_write_float(ctx, out, 1.5);
    bogus.index = 999;
    bad_handle_read = ay_ctx_read_int(ctx, bogus, &v);
    OK(ay_ctx_monostable(ctx, "M", &mono));
    zero_trigger = ay_ctx_trigger(ctx, mono, 0.0);
    nan_into_max = ay_ctx_write_float(ctx, max, NAN);
}

static void null_and_unknown(void) {
    ay_node *n = NULL;
    int64_t v = 0;
    FAILS(ay_node_open_manual(1, "mem://misuse-a", clock_, NULL), AY_ERR_NULL, "out is NULL");
    FAILS(ay_node_open_manual(0, "mem://misuse-a", clock_, &n), AY_ERR_INVALID, "node id 0");
    FAILS(ay_node_open_manual(1, NULL, clock_, &n), AY_ERR_NULL, "url is NULL");
    FAILS(ay_node_open_manual(1, "bogus://x", clock_, &n), AY_ERR_TRANSPORT, "unknown transport");
    FAILS(ay_node_open_manual(1, "mem://", clock_, &n), AY_ERR_TRANSPORT, "network name");
    FAILS(ay_node_open(1, "udp://not-an-address", &n), AY_ERR_TRANSPORT, "udp://not-an-address");
    FAILS(ay_node_open_manual(1, "mem://misuse-a", NULL, &n), AY_ERR_NULL, "clock is NULL");
    FAILS(ay_node_write_int(NULL, "B", "Out", 1), AY_ERR_NULL, "node is NULL");
    FAILS(ay_node_read_int(NULL, "B", "Out", &v), AY_ERR_NULL, "node is NULL");
    FAILS(ay_node_step(NULL, NULL), AY_ERR_NULL, "node is NULL");
    FAILS(ay_node_write_int(node_, NULL, "Out", 1), AY_ERR_NULL, "behavior is NULL");
    FAILS(ay_node_write_int(node_, "Nobody", "Out", 1), AY_ERR_UNKNOWN, "Nobody");
    FAILS(ay_node_write_int(node_, "B", "Nothing", 1), AY_ERR_UNKNOWN, "Nothing");
    FAILS(ay_node_read_int(node_, "B", "Out", NULL), AY_ERR_NULL, "out is NULL");
    FAILS(ay_node_create(node_, "NoClass", "X"), AY_ERR_UNKNOWN, "NoClass");
    FAILS(ay_node_create(node_, "Box", "B"), AY_ERR_INVALID, "B");
    FAILS(ay_node_remove(node_, "Ghost"), AY_ERR_UNKNOWN, "Ghost");
    FAILS(ay_node_disconnect(node_, 12345), AY_ERR_UNKNOWN, "12345");
    FAILS(ay_node_monostable(node_, "B", "M", NULL), AY_ERR_NULL, "out is NULL");
    {
        bool high;
        FAILS(ay_node_monostable(node_, "B", "Nope", &high), AY_ERR_UNKNOWN, "Nope");
    }
    FAILS(ay_node_trigger(node_, "B", "M", 0.0), AY_ERR_PERIOD, "above zero");
    FAILS(ay_node_trigger(node_, "B", "M", -1.0), AY_ERR_PERIOD, "negative");
    FAILS(ay_node_join(node_, ""), AY_ERR_INVALID, "name");
    FAILS(ay_node_why_json(node_, "B", "Nothing", NULL), AY_ERR_NULL, "out is NULL");
    {
        char *json = NULL;
        FAILS(ay_node_why_json(node_, "B", "Nothing", &json), AY_ERR_UNKNOWN, "Nothing");
        CHECK(json == NULL);
    }
    FAILS(ay_set_default_node((ay_node *)clock_), AY_ERR_HANDLE, "clock handle, not a node");
    CHECK(strcmp(ay_status_name(99), "AY_ERR_?") == 0);
    CHECK(strcmp(ay_status_name((int32_t)AY_ERR_PERIOD), "AY_ERR_PERIOD") == 0);
}

static void wrong_types(void) {
    double f = 0;
    char small[3];
    size_t len = 0;
    ay_class *c = NULL;
    ay_endpoint out, fl;
    FAILS(ay_node_write_float(node_, "B", "Out", 1.5), AY_ERR_TYPE, "holds int values, not float");
    FAILS(ay_node_read_float(node_, "B", "Out", &f), AY_ERR_TYPE, "int");
    FAILS(ay_node_write_text(node_, "B", "Out", "x"), AY_ERR_TYPE, "not text");
    FAILS(ay_node_read_text(node_, "B", "Word", small, sizeof small, &len), AY_ERR_BUFFER, "needed");
    CHECK_EQ_INT(len, 5);
    FAILS(ay_node_read_text(node_, "B", "Word", NULL, 0, &len), AY_ERR_BUFFER, "needed");
    /* A Normal connection between an int and a float port (D6.7). */
    out.scope = fl.scope = AY_LOCAL;
    out.node = fl.node = 0;
    out.group = fl.group = NULL;
    out.behavior = fl.behavior = "B";
    out.port = "Out";
    fl.port = "Float";
    FAILS(ay_node_connect(node_, &out, &fl, AY_NORMAL, 0, 0, NULL), AY_ERR_TYPE, "Float");
    /* Sorted as Python sorts them (one ErrorKind; its twin is test_misuse.py's
     * test_errors_are_sorted_as_the_c_library_sorts_them): a slot named as a port is unknown
     * (NotFoundError), a vector Sum without a shape a type error (ValueTypeError). */
    fl.port = "Count";
    FAILS(ay_node_connect(node_, &out, &fl, AY_NORMAL, 0, 0, NULL), AY_ERR_UNKNOWN, "is a slot");
    fl.port = "Float";
    /* Kinds a type cannot have, reserved and taken names, unknown kind constants. */
    OK(ay_class_new("Bad", &c));
    FAILS(ay_class_port_text(c, "T", "x", AY_PORT_MAX, 0, 0, NULL), AY_ERR_TYPE, "Max port cannot hold text");
    FAILS(ay_class_port_int(c, "Local", 0, AY_PORT_NORMAL, 0, 0, NULL), AY_ERR_INVALID, "Local");
    OK(ay_class_port_int(c, "X", 0, AY_PORT_NORMAL, 0, 0, NULL));
    FAILS(ay_class_port_int(c, "X", 0, AY_PORT_NORMAL, 0, 0, NULL), AY_ERR_INVALID, "X");
    FAILS(ay_class_slot_int(c, "X", 0, NULL), AY_ERR_INVALID, "X");
    FAILS(ay_class_port_int(c, "K", 0, 77, 0, 0, NULL), AY_ERR_INVALID, "77 is not a port kind");
    FAILS(ay_class_port_int(c, "", 0, AY_PORT_NORMAL, 0, 0, NULL), AY_ERR_INVALID, "empty");
    FAILS(ay_class_port_int(c, "W", 0, AY_PORT_NORMAL, 0, 1.0, NULL), AY_ERR_INVALID, "window");
    FAILS(ay_class_port_int(c, "L", 0, AY_PORT_NORMAL, -1.0, 0, NULL), AY_ERR_PERIOD, "lifespan");
    FAILS(ay_class_port_float(c, "N", 0, AY_PORT_NORMAL, NAN, 0, NULL), AY_ERR_PERIOD, "lifespan");
    FAILS(ay_class_port_vector(c, "V", NULL, 3, AY_PORT_NORMAL, 0, 0, NULL), AY_ERR_NULL, "initial");
    {
        double none[1] = {0};
        FAILS(ay_class_port_vector(c, "S", none, 0, AY_PORT_SUM, 0, 0, NULL), AY_ERR_TYPE, "takes its shape");
    }
    FAILS(ay_class_on_write(c, "P", "Nothing", meddle, NULL), AY_ERR_UNKNOWN, "Nothing");
    FAILS(ay_class_on_monostable(c, "P", "Nothing", meddle, NULL), AY_ERR_UNKNOWN, "Nothing");
    FAILS(ay_class_every_hz(c, "P", 10.0, NULL, NULL), AY_ERR_NULL, "process function");
    OK(ay_class_free(c));
}

static void periods_and_rates(void) {
    ay_class *c = NULL;
    ay_endpoint a, b;
    a.scope = b.scope = AY_LOCAL;
    a.node = b.node = 0;
    a.group = b.group = NULL;
    a.behavior = b.behavior = "B";
    a.port = b.port = "Out";
    b.behavior = "C";
    FAILS(ay_node_connect(node_, &a, &b, AY_SUPPRESS, 0.0, 0, NULL), AY_ERR_PERIOD, "above zero");
    FAILS(ay_node_connect(node_, &a, &b, AY_OVERRIDE_OUT, -0.5, 0, NULL), AY_ERR_PERIOD, "negative");
    FAILS(ay_node_connect(node_, &a, &b, AY_INHIBIT, NAN, 0, NULL), AY_ERR_PERIOD, "NaN");
    FAILS(ay_node_connect(node_, &a, &b, AY_INHIBIT, INFINITY, 0, NULL), AY_ERR_PERIOD, "inf");
    /* A wild period reads as typed (not 301 digits of seconds), with the accepted range. */
    FAILS(ay_node_connect(node_, &a, &b, AY_INHIBIT, 1e300, 0, NULL), AY_ERR_PERIOD, "1e300 s is too long");
    FAILS(ay_node_connect(node_, &a, &b, AY_INHIBIT, 1e300, 0, NULL), AY_ERR_PERIOD, "18446744073 s (about 584 years)");
    CHECK(strlen(ay_last_error()) < 200);
    /* Above zero but under the clock's 1 ns: said as such, not as a zero period (D6.8). */
    FAILS(ay_node_connect(node_, &a, &b, AY_INHIBIT, 1e-300, 0, NULL), AY_ERR_PERIOD, "1e-300 s is above zero but under 1 ns");
    FAILS(ay_node_connect(node_, &a, &b, AY_INHIBIT, 1e-300, 0, NULL), AY_ERR_PERIOD, "at least 1 ns");
    FAILS(ay_clock_advance(clock_, -1e300), AY_ERR_PERIOD, "-1e300 s is negative");
    FAILS(ay_node_connect(node_, &a, &b, AY_NORMAL, 0.2, 0, NULL), AY_ERR_PERIOD, "Normal");
    FAILS(ay_node_connect(node_, &a, &b, 42, 0.2, 0, NULL), AY_ERR_INVALID, "42 is not a connection kind");
    FAILS(ay_node_connect(node_, NULL, &b, AY_NORMAL, 0, 0, NULL), AY_ERR_NULL, "source is NULL");
    a.scope = 9;
    FAILS(ay_node_connect(node_, &a, &b, AY_NORMAL, 0, 0, NULL), AY_ERR_INVALID, "scope");
    a.scope = AY_GROUP;
    a.group = "G";
    FAILS(ay_node_connect(node_, &a, &b, AY_NORMAL, 0, 0, NULL), AY_ERR_INVALID, "group");
    a.scope = AY_NODE;
    a.node = 7;
    FAILS(ay_node_connect(node_, &a, &b, AY_NORMAL, 0, 0, NULL), AY_ERR_INVALID, "request_connect");
    OK(ay_class_new("Rated", &c));
    FAILS(ay_class_every_hz(c, "P", 0.0, meddle, NULL), AY_ERR_RATE, "rate");
    FAILS(ay_class_every_hz(c, "P", -2.0, meddle, NULL), AY_ERR_RATE, "rate");
    FAILS(ay_class_every_hz(c, "P", NAN, meddle, NULL), AY_ERR_RATE, "rate");
    FAILS(ay_class_every_hz(c, "P", 1e-300, meddle, NULL), AY_ERR_RATE, "rate of 1e-300 Hz is invalid");
    OK(ay_class_free(c));
    FAILS(ay_node_ble_join(node_, "B", "Peers", "Out", 0.0, 0), AY_ERR_RATE, "rate");
    FAILS(ay_node_ble_join(node_, "B", "Peers", "Out", 1.0, -1.0), AY_ERR_PERIOD, "negative");
    FAILS(ay_node_ble_join(node_, "B", "Peers", "Nothing", 1.0, 0), AY_ERR_UNKNOWN, "Nothing");
    FAILS(ay_clock_advance(clock_, 0.0), AY_ERR_PERIOD, "above zero");
    FAILS(ay_node_run_for(node_, -1.0), AY_ERR_PERIOD, "negative");
    FAILS(ay_sim_body(node_, 0), AY_ERR_INVALID, "targets");
}

static void contexts_and_reentry(void) {
    ay_port p;
    int64_t v = 0;
    /* Step: `meddle` runs (10 Hz, first activation at creation) and records what it saw. */
    OK(ay_node_step(node_, NULL));
    CHECK(kept_ctx != NULL);
    CHECK_EQ_INT(own_node_write, AY_ERR_BUSY);
    CHECK_EQ_INT(own_node_free, AY_ERR_BUSY);
    CHECK_EQ_INT(stranger_port, AY_ERR_UNKNOWN);
    CHECK_EQ_INT(wrong_type_write, AY_ERR_TYPE);
    CHECK_EQ_INT(bad_handle_read, AY_ERR_UNKNOWN);
    CHECK_EQ_INT(zero_trigger, AY_ERR_PERIOD);
    CHECK_EQ_INT(nan_into_max, AY_ERR_INVALID);
    /* The context outlived its call: refused, not dereferenced. */
    p.index = 3;
    FAILS(ay_ctx_write_int(kept_ctx, p, 1), AY_ERR_CONTEXT, "context");
    FAILS(ay_ctx_read_int(kept_ctx, p, &v), AY_ERR_CONTEXT, "context");
    FAILS(ay_ctx_port(kept_ctx, "Out", &p), AY_ERR_CONTEXT, "context");
    FAILS(ay_ctx_write_int(NULL, p, 1), AY_ERR_NULL, "ctx is NULL");
    /* The node still works. */
    OK(ay_node_write_int(node_, "B", "Out", 5));
    OK(ay_node_read_int(node_, "B", "Out", &v));
    CHECK_EQ_INT(v, 5);
}

static void use_after_free(void) {
    ay_node *n = NULL;
    ay_class *c = NULL;
    ay_clock *k = NULL;
    int64_t v = 0;
    OK(ay_node_open_manual(9, "mem://misuse-free", clock_, &n));
    OK(ay_node_free(n));
    FAILS(ay_node_write_int(n, "B", "Out", 1), AY_ERR_HANDLE, "not a live node");
    FAILS(ay_node_read_int(n, "B", "Out", &v), AY_ERR_HANDLE, "not a live node");
    FAILS(ay_node_step(n, NULL), AY_ERR_HANDLE, "not a live node");
    FAILS(ay_node_free(n), AY_ERR_HANDLE, "freed already");
    FAILS(ay_set_default_node(n), AY_ERR_HANDLE, "not a live node");
    OK(ay_class_new("Gone", &c));
    OK(ay_class_free(c));
    FAILS(ay_class_port_int(c, "X", 0, AY_PORT_NORMAL, 0, 0, NULL), AY_ERR_HANDLE, "not a live behavior class");
    FAILS(ay_class_free(c), AY_ERR_HANDLE, "freed already");
    /* ay_node_define consumes the class. */
    OK(ay_class_new("Taken", &c));
    OK(ay_node_define(node_, c));
    FAILS(ay_class_port_int(c, "X", 0, AY_PORT_NORMAL, 0, 0, NULL), AY_ERR_HANDLE, "not a live");
    FAILS(ay_node_define(node_, c), AY_ERR_HANDLE, "not a live");
    OK(ay_clock_new(&k));
    OK(ay_clock_free(k));
    FAILS(ay_clock_advance(k, 1.0), AY_ERR_HANDLE, "not a live clock");
    FAILS(ay_node_open_manual(9, "mem://misuse-free", k, &n), AY_ERR_HANDLE, "not a live clock");
    /* A handle of another type. */
    FAILS(ay_node_step((ay_node *)clock_, NULL), AY_ERR_HANDLE, "clock handle");
    FAILS(ay_clock_advance((ay_clock *)node_, 1.0), AY_ERR_HANDLE, "node handle");
}

static void macro_failures_go_to_the_handler(void);

int main(void) {
    ay_class *c = NULL;
    OK(ay_clock_new(&clock_));
    OK(ay_node_open_manual(1, "mem://misuse", clock_, &node_));
    OK(ay_class_new("Box", &c));
    OK(ay_class_port_int(c, "Out", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_port_float(c, "Float", 0, AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_port_float(c, "Max", 0, AY_PORT_MAX, 0, 0, NULL));
    OK(ay_class_port_text(c, "Word", "hello", AY_PORT_NORMAL, 0, 0, NULL));
    OK(ay_class_monostable(c, "M", NULL));
    OK(ay_class_slot_int(c, "Count", 0, NULL));
    OK(ay_class_every_hz(c, "Meddle", 10.0, meddle, NULL));
    OK(ay_node_define(node_, c));
    OK(ay_node_create(node_, "Box", "B"));
    OK(ay_node_create(node_, "Box", "C"));
    null_and_unknown();
    wrong_types();
    periods_and_rates();
    contexts_and_reentry();
    use_after_free();
    macro_failures_go_to_the_handler();
    OK(ay_node_free(node_));
    OK(ay_clock_free(clock_));
    return check_exit("test_misuse");
}

/* ---- the macro layer: failures reach the installed handler, with where and why ---- */

#include "ayllu.h"

static int handled;
static int32_t handled_status;
static int handled_line;
static char handled_what[128];

static void record(int32_t status, const char *what, const char *file, int line) {
    (void)file;
    handled++;
    handled_status = status;
    handled_line = line;
    strncpy(handled_what, what, sizeof handled_what - 1);
}

static void macro_failures_go_to_the_handler(void) {
    ayBROADCAST peers = ayMakeBroadcast("Peers");
    int line;
    ayOnError(record);
    OK(ay_set_default_node(node_));
    line = __LINE__ + 1;
    ayConnect(B, Out, Nobody, In);
    CHECK_EQ_INT(handled, 1);
    CHECK_EQ_INT(handled_status, AY_ERR_UNKNOWN);
    CHECK_EQ_INT(handled_line, line);
    CHECK(strcmp(handled_what, "ayConnect(B, Out, Nobody, In)") == 0);
    CHECK(strstr(ay_last_error(), "Nobody") != NULL);
    aySuppress(B, Out, C, Out, seconds(0));
    CHECK_EQ_INT(handled_status, AY_ERR_PERIOD);
    ayBLE(B, peers, Out, ratepersecond(0));
    CHECK_EQ_INT(handled_status, AY_ERR_RATE);
    ayWriteIntPortOf(B, Float, 3);
    CHECK_EQ_INT(handled_status, AY_ERR_TYPE);
    CHECK_EQ_INT(handled, 4);
    ayOnError(NULL);
    OK(ay_set_default_node(NULL));
}
