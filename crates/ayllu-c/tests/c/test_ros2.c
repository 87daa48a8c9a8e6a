/*
 * test_ros2.c -- the ROS 2 body's entry point from C (ay_ros2_body, ayInitRos2Body) says
 * what went wrong, whole, through ay_last_error() and the macros' handler.
 *
 * Built by `make test` against the default libayllu (no ROS 2 body): the call fails with
 * AY_ERR_INVALID and says how to build a library that has the body. Built by `make ros2`
 * (-DAYLLU_TEST_ROS2, against libayllu built with the cargo feature `ros2` in target/ros2):
 * a wrong mapping file fails with the file, the field and the fix in the message, and a missing
 * one with its name. Either way the arguments are checked first, the same in both builds. No
 * DDS participant is started (every call here fails before one would be).
 */
#include <stdint.h>
#include <stdio.h>

#include "check.h"

#include "ayllustd.h"

static int handled;
static int32_t handled_status;
static char handled_what[128];

static void record(int32_t status, const char *what, const char *file, int line) {
    (void)file;
    (void)line;
    handled++;
    handled_status = status;
    strncpy(handled_what, what, sizeof handled_what - 1);
}

#ifdef AYLLU_TEST_ROS2
/* A mapping file with a misspelt key: the message names the file, where, and the key meant. */
static const char *write_bad_mapping(void) {
    static const char *path = "build/test_ros2_bad.toml";
    FILE *f = fopen(path, "w");
    if (f == NULL) {
        return NULL;
    }
    fputs("[[topic]]\nname = \"scan\"\ntype = \"sensor_msgs/msg/LaserScan\"\ndirections = \"in\"\n", f);
    fclose(f);
    return path;
}
#endif

int main(void) {
    ay_clock *clock = NULL;
    ay_node *node = NULL;
    OK(ay_clock_new(&clock));
    OK(ay_node_open_manual(1, "mem://ros2", clock, &node));

    /* Misuse is reported as such, whichever way the library was built. */
    FAILS(ay_ros2_body(NULL, "robot.toml"), AY_ERR_NULL, "node");
    FAILS(ay_ros2_body(node, NULL), AY_ERR_NULL, "mapping_file");

    ayOnError(record);
    OK(ay_set_default_node(node));
#ifndef AYLLU_TEST_ROS2
    FAILS(ay_ros2_body(node, "robot.toml"), AY_ERR_INVALID,
          "ay_ros2_body: libayllu was built without the ROS 2 body: build it with `make ros2` (docs/ros2.md)");
    /* Fig. 2's one changed line, on this build: the handler hears it, with the macro's name. */
    ayInitRos2Body("robot.toml");
    CHECK_EQ_INT(handled, 1);
    CHECK_EQ_INT(handled_status, AY_ERR_INVALID);
    CHECK(strcmp(handled_what, "ayInitRos2Body") == 0);
    CHECK(strstr(ay_last_error(), "built without the ROS 2 body") != NULL);
#else
    {
        const char *bad = write_bad_mapping();
        CHECK(bad != NULL);
        if (bad != NULL) {
            FAILS(ay_ros2_body(node, bad), AY_ERR_INVALID, "ay_ros2_body: build/test_ros2_bad.toml: ");
            CHECK(strstr(ay_last_error(), "unknown key `directions`: did you mean `direction`?") != NULL);
            ayInitRos2Body(bad);
            CHECK_EQ_INT(handled, 1);
            CHECK_EQ_INT(handled_status, AY_ERR_INVALID);
            CHECK(strcmp(handled_what, "ayInitRos2Body") == 0);
            remove(bad);
        }
        FAILS(ay_ros2_body(node, "build/no_such_mapping.toml"), AY_ERR_TRANSPORT, "no_such_mapping.toml");
    }
#endif
    ayOnError(NULL);
    OK(ay_set_default_node(NULL));
    OK(ay_node_free(node));
    OK(ay_clock_free(clock));
    return check_exit("test_ros2");
}
