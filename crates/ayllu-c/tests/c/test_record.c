/*
 * test_record.c -- flight recording from C (spec/flight-recorder.md): a node whose process is
 * a C function records into an MCAP file; the recording replays with no C code, reproducing
 * every value its ports accepted bit for bit (ay_recording_check); misuse is refused with a
 * message that says why.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "check.h"
#include "ayllu.h"

static ay_port in_, out_;

/* Out := 2 In + 0.25, on every value In accepts. */
static void twice(ay_ctx *ctx, void *user) {
    double x = 0.0;
    (void)user;
    OK(ay_ctx_read_float(ctx, in_, &x));
    OK(ay_ctx_write_float(ctx, out_, 2.0 * x + 0.25));
}

/* Define class Twice on `node` and create T, its process `twice`. */
static void define_twice(ay_node *node) {
    ay_class *c = NULL;
    OK(ay_class_new("Twice", &c));
    OK(ay_class_port_float(c, "In", 0.0, AY_PORT_NORMAL, 0, 0, &in_));
    OK(ay_class_port_float(c, "Out", 0.0, AY_PORT_NORMAL, 0, 0, &out_));
    OK(ay_class_on_write(c, "Twice", "In", twice, NULL));
    OK(ay_node_define(node, c));
    OK(ay_node_create(node, "Twice", "T"));
}

int main(void) {
    ay_clock *clock = NULL;
    ay_node *node = NULL;
    uint64_t written = 0, checked = 0;
    char path[512], stem[480];
    const char *dir = getenv("TMPDIR");
    int i;
    /* A name no other run uses at the same time (no getpid in strict C99). */
    snprintf(path, sizeof path, "%s/ayllu-c-record-%ld-%lx.mcap", dir ? dir : "/tmp", (long)time(NULL),
             (unsigned long)(uintptr_t)&written);

    OK(ay_clock_new(&clock));
    OK(ay_node_open_manual(1, "mem://c-record", clock, &node));
    FAILS(ay_node_record(node, path, 1000), AY_ERR_INVALID, "65536");
    FAILS(ay_node_record(node, NULL, 0), AY_ERR_NULL, "path");
    OK(ay_node_record(node, path, 0));
    FAILS(ay_node_record(node, path, 0), AY_ERR_TRANSPORT, "already");
    define_twice(node);
    for (i = 0; i < 200; i++) {
        OK(ay_clock_set(clock, i * 0.01));
        OK(ay_node_write_float(node, "T", "In", sin(i * 0.1) / 3.0));
        OK(ay_node_step(node, NULL));
    }
    OK(ay_node_stop_recording(node, &written));
    CHECK(written > 600);
    OK(ay_node_stop_recording(node, &written));
    CHECK_EQ_INT(written, 0);

    /* Replayed with no C code: every In and Out value reproduced. */
    OK(ay_recording_check(path, &checked));
    CHECK_EQ_INT(checked, 400);
    FAILS(ay_recording_check("/nonexistent/ayllu.mcap", NULL), AY_ERR_TRANSPORT, "nonexistent");

    /* Too late: classes are defined already. */
    FAILS(ay_node_record(node, path, 0), AY_ERR_TRANSPORT, "before defining");
    OK(ay_node_free(node));

    /* The macro layer's forms, on the default node. */
    OK(ay_node_open_manual(2, "mem://c-record", clock, &node));
    OK(ay_set_default_node(node));
    ayRecord(path);
    ayStep();
    ayStopRecording();
    OK(ay_recording_check(path, &checked));
    CHECK_EQ_INT(checked, 0);
    OK(ay_set_default_node(NULL));
    OK(ay_node_free(node));
    remove(path);

    /* A rolling recording keeps the last 2 s of a 10 s run: replayed from its oldest
     * checkpoint (every second), each In and Out of the last 2 s to 3 s. */
    snprintf(stem, sizeof stem, "%s/ayllu-c-rolling-%ld-%lx", dir ? dir : "/tmp", (long)time(NULL),
             (unsigned long)(uintptr_t)&written);
    snprintf(path, sizeof path, "%s.mcap", stem);
    OK(ay_node_open_manual(3, "mem://c-record", clock, &node));
    FAILS(ay_node_record_last(node, path, 0, -1.0), AY_ERR_PERIOD, "negative");
    OK(ay_node_record_last(node, path, 0, 2.0));
    define_twice(node);
    for (i = 0; i < 1000; i++) {
        OK(ay_clock_set(clock, 2.0 + i * 0.01));
        OK(ay_node_write_float(node, "T", "In", sin(i * 0.1) / 3.0));
        OK(ay_node_step(node, NULL));
    }
    OK(ay_node_stop_recording(node, &written));
    OK(ay_recording_check(path, &checked));
    CHECK(checked >= 400 && checked <= 600);
    OK(ay_node_free(node));
    OK(ay_clock_free(clock));
    remove(path);
    for (i = 1; i < 64; i++) {
        snprintf(path, sizeof path, "%s.%d.mcap", stem, i);
        remove(path);
    }
    return check_exit("test_record");
}
