/*
 * Tutorial 3, two nodes over UDP (docs/tutorials/03-two-nodes-udp.md), in C: robot 1's sonar
 * writes robot 2's motor across real sockets on loopback. Each node binds port 0 (the system
 * picks a free one); robot 2 is told where robot 1 is. Both run on the real clock in one
 * program (two robots would be two programs: run each node with ayRunBehaviors()).
 * Exits non-zero if no value crosses the network within 10 s.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <ayllu.h>

ayDefBehaviorClass(Sonar) {
    ayINTERFACE {
        ayFloatPort(Range, 0);
    }
    ayPROCESSES {
        ayInitProcess(Ping, ratepersecond(20));
    }
}

ayDefProcess(Ping) {
    ayLocalPort(Range);
    ayWriteFloatPort(Range, 0.75); /* metres */
}

ayDefBehaviorClass(Motor) {
    ayINTERFACE {
        ayFloatPortLifespan(Speed, 0, seconds(0.3)); /* stale 300 ms after the last command */
    }
    ayPROCESSES {
    }
}

int main(void) {
    ay_node *r1 = NULL, *r2 = NULL;
    char r1_at[64], url[128];
    size_t len = 0;
    bool arrived = false, ok;
    double speed = 0;
    char *why = NULL;
    int turn;
    if (ay_node_open(1, "udp://127.0.0.1:0", &r1) != AY_OK ||
        ay_node_address(r1, r1_at, sizeof r1_at, &len) != AY_OK) {
        fprintf(stderr, "robot 1: %s\n", ay_last_error());
        return 1;
    }
    snprintf(url, sizeof url, "udp://127.0.0.1:0?peer=%s", r1_at);
    if (ay_node_open(2, url, &r2) != AY_OK) {
        fprintf(stderr, "robot 2: %s\n", ay_last_error());
        return 1;
    }
    printf("robot 1 at %s\n", r1_at);

    ay_set_default_node(r2); /* the macros act on the default node */
    ayInitBehavior(Motor, MOTOR);
    ay_set_default_node(r1);
    ayInitBehavior(Sonar, SONAR);
    ayRemoteConnect(SONAR, Range, 2, MOTOR, Speed); /* to the port MOTOR.Speed of node 2 */

    /* Bounded: at most 10 s, in 5 ms turns of each node. */
    for (turn = 0; turn < 1000 && !arrived; turn++) {
        ay_node_run_for(r1, 0.005);
        ay_node_run_for(r2, 0.005);
        ay_node_fresh(r2, "MOTOR", "Speed", &arrived);
    }
    if (!arrived) {
        fprintf(stderr, "tutorial 3 failed: no value crossed the network in 10 s\n");
        return 1;
    }
    ay_node_read_float(r2, "MOTOR", "Speed", &speed);
    ay_node_why_json(r2, "MOTOR", "Speed", &why);
    printf("MOTOR.Speed on robot 2 = %g\nwhy: %s\n", speed, why);
    ok = speed == 0.75 && strstr(why, "\"supplier\":{\"node\":1,") != NULL; /* from robot 1 */
    ay_string_free(why);
    if (!ok) {
        fprintf(stderr, "tutorial 3 failed: the value did not come from robot 1\n");
        return 1;
    }
    ay_set_default_node(NULL);
    ay_node_free(r2);
    ay_node_free(r1);
    return 0;
}
