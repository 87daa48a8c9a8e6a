/*
 * test_served_world.c -- serving a world from C (ay_served_world_*, docs/c-api.md): robot 1's
 * node (ay_sim_body) on loopback UDP port 0, and a served world of one robot whose body greets
 * that node's address (peer=). One thread drives both: the robot's node steps between the
 * world's ticks. Checks: the body hears its robot before the start, a second of world time
 * serves two status lines, the done line carries the metrics; a stop ends the run early;
 * misuse (NULL arguments, a URL that does not parse, URLs that do not fit the team, a freed
 * handle) is refused with a status code and a message that says why.
 */
#include <stdbool.h>
#include <stdio.h>
#include <string.h>

#include "check.h"

static ay_serve_config sized(const char *const *urls, size_t n) {
    ay_serve_config c;
    memset(&c, 0, sizeof c);
    c.robots = 1;
    c.targets = 2;
    c.seed = 7;
    c.duration = 1.0;
    c.urls = urls;
    c.urls_len = n;
    c.wait = 5.0;
    c.status_every = 0.5;
    return c;
}

static void misuse(void) {
    ay_served_world *w = NULL;
    const char *nope[] = {"nope"};
    const char *three[] = {"udp://127.0.0.1:0", "udp://127.0.0.1:0", "udp://127.0.0.1:0"};
    const char *holes[] = {NULL};
    ay_serve_config c = sized(nope, 1);
    bool done = false;

    FAILS(ay_served_world_open(NULL, &w), AY_ERR_NULL, "config");
    FAILS(ay_served_world_open(&c, NULL), AY_ERR_NULL, "out");
    FAILS(ay_served_world_open(&c, &w), AY_ERR_TRANSPORT, "nope");
    c = sized(three, 3);
    FAILS(ay_served_world_open(&c, &w), AY_ERR_INVALID, "3 body URLs for 1 robots");
    c = sized(holes, 1);
    FAILS(ay_served_world_open(&c, &w), AY_ERR_NULL, "URL");
    c = sized(NULL, 1);
    FAILS(ay_served_world_open(&c, &w), AY_ERR_NULL, "urls");
    c = sized(three, 1);
    c.duration = -1.0;
    FAILS(ay_served_world_open(&c, &w), AY_ERR_PERIOD, "duration");
    c = sized(three, 1);
    c.targets = 0;
    FAILS(ay_served_world_open(&c, &w), AY_ERR_INVALID, "targets");
    c = sized(three, 1);
    c.scenario = "/nonexistent/scenario.toml";
    c.robots = 0;
    c.targets = 0;
    FAILS(ay_served_world_open(&c, &w), AY_ERR_INVALID, "nonexistent");
    CHECK(w == NULL);
    FAILS(ay_served_world_run(NULL, 1.0, NULL), AY_ERR_NULL, "world");
    FAILS(ay_served_world_done(NULL, &done), AY_ERR_NULL, "world");
    FAILS(ay_served_world_stop(NULL), AY_ERR_NULL, "world");
    FAILS(ay_served_world_free(NULL), AY_ERR_NULL, "world");

    /* A world nobody joins: it starts after its wait, and stops when asked. */
    c = sized(three, 1);
    c.duration = 60.0;
    c.wait = 0.2;
    OK(ay_served_world_open(&c, &w));
    FAILS(ay_served_world_run(w, -1.0, NULL), AY_ERR_PERIOD, "seconds");
    FAILS(ay_served_world_done(w, NULL), AY_ERR_NULL, "done");
    OK(ay_served_world_run(w, 0.1, NULL));
    OK(ay_served_world_stop(w));
    OK(ay_served_world_run(w, 0.0, NULL));
    OK(ay_served_world_done(w, &done));
    CHECK(done);
    {
        char *line = NULL;
        OK(ay_served_world_finish(w, &line));
        CHECK(line != NULL && strstr(line, "\"stopped\":true") != NULL);
        ay_string_free(line);
    }
    OK(ay_served_world_free(w));
    FAILS(ay_served_world_stop(w), AY_ERR_HANDLE, "served world");
}

int main(void) {
    ay_node *robot = NULL;
    ay_served_world *w = NULL;
    char address[128], url[256];
    const char *urls[1];
    ay_serve_config c;
    char *start = NULL, *events = NULL, *done_line = NULL;
    bool linked = false, done = false;
    int statuses = 0, i;

    misuse();

    OK(ay_node_open(1, "udp://127.0.0.1:0", &robot));
    OK(ay_sim_body(robot, 2));
    OK(ay_node_address(robot, address, sizeof address, NULL));
    snprintf(url, sizeof url, "udp://127.0.0.1:0?peer=%s", address);
    urls[0] = url;
    c = sized(urls, 1);
    OK(ay_served_world_open(&c, &w));

    /* Wait for the body to hear robot 1, stepping both (at most 5 s). */
    for (i = 0; i < 250 && !linked; i++) {
        OK(ay_node_run_for(robot, 0.02));
        OK(ay_served_world_poll(w, &linked));
    }
    CHECK(linked);
    OK(ay_served_world_start(w, &start));
    CHECK(start != NULL && strstr(start, "\"missing\":[]") != NULL);

    /* One second of world time, a tick at a time, the robot's node stepped between ticks. */
    while (!done) {
        const char *p;
        OK(ay_node_step(robot, NULL));
        OK(ay_served_world_run(w, 0.05, &events));
        for (p = events; p != NULL && (p = strstr(p, "\"observed\"")) != NULL; p++) {
            statuses++;
        }
        ay_string_free(events);
        events = NULL;
        OK(ay_served_world_done(w, &done));
    }
    CHECK_EQ_INT(statuses, 2);
    OK(ay_served_world_finish(w, &done_line));
    CHECK(done_line != NULL && strstr(done_line, "\"stopped\":false") != NULL);
    CHECK(done_line != NULL && strstr(done_line, "\"a_w\"") != NULL);
    printf("%s\n%s\n", start, done_line ? done_line : "(none)");

    ay_string_free(start);
    ay_string_free(done_line);
    OK(ay_served_world_free(w));
    OK(ay_node_free(robot));
    return check_exit("test_served_world");
}
