/*
 * Tutorial 6, recording a team and asking why in the past
 * (docs/tutorials/06-recording-why-in-the-past.md), in C: two robots share a task by BLE, each
 * node a flight recorder (ay_node_record); robot 1 (the more eligible) dies at 3 s and robot 2
 * takes over. `ayllu replay DIR/n2.mcap --at 2s why W.Out` then asks robot 2's recording.
 *
 * Run: `tutorial_06_recording_why_in_the_past DIR` (default: the current folder); writes
 * DIR/n1.mcap and DIR/n2.mcap. Exits non-zero if what the tutorial says does not happen.
 */
#include <stdio.h>
#include <stdlib.h>

#include <ayllu.h>

#define EXPECT(cond)                                                                \
    do {                                                                            \
        if (!(cond)) {                                                              \
            fprintf(stderr, "tutorial 6 failed: %s (line %d)\n", #cond, __LINE__);   \
            exit(1);                                                                \
        }                                                                           \
    } while (0)

ayDefBehaviorClass(Worker) {
    ayINTERFACE {
        ayFloatPort(Out, 0);
    }
    ayPROCESSES {
        ayInitProcess(Work, ratepersecond(10));
    }
}

ayDefProcess(Work) {
    ayLocalPort(Out, BLE_Local);
    ayWriteFloatPort(BLE_Local, ayNodeId() == 1 ? 0.9 : 0.5); /* how well suited this robot is */
    ayWriteFloatPort(Out, 1.0);                               /* doing the task */
}

/* Both robots, stepped together for `seconds` of virtual time (robot 1 only while alive). */
static void run_for(ay_clock *clock, ay_node **robots, int alive_from, double seconds) {
    int tick, i;
    for (tick = 0; tick < (int)(seconds * 100 + 0.5); tick++) {
        for (i = alive_from; i < 2; i++) {
            ay_set_default_node(robots[i]);
            ayStep();
        }
        ay_clock_advance(clock, 0.01);
    }
}

int main(int argc, char **argv) {
    const char *dir = argc > 1 ? argv[1] : ".";
    ayBROADCAST peers = ayMakeBroadcast("Peers");
    ay_clock *clock = NULL;
    ay_node *robots[2];
    char path[512];
    uint64_t written[2] = {0, 0};
    int i;
    EXPECT(ay_clock_new(&clock) == AY_OK);
    for (i = 0; i < 2; i++) {
        EXPECT(ay_node_open_manual((uint32_t)i + 1, "mem://tutorial-06", clock, &robots[i]) == AY_OK);
        snprintf(path, sizeof path, "%s/n%d.mcap", dir, i + 1);
        /* Record first: a replay rebuilds the node from its first definition. */
        EXPECT(ay_node_record(robots[i], path, 0) == AY_OK);
        ay_set_default_node(robots[i]);
        ayInitBehavior(Worker, W);
        ayBLE(W, peers, Out, ratepersecond(1));
    }
    run_for(clock, robots, 0, 3.0);
    ay_set_default_node(robots[0]);
    EXPECT(ayBLEClaiming(W)); /* robot 1 holds the task */
    EXPECT(ay_node_stop_recording(robots[0], &written[0]) == AY_OK);
    ay_set_default_node(NULL);
    ay_node_free(robots[0]); /* robot 1 dies */
    run_for(clock, robots, 1, 5.0);
    ay_set_default_node(robots[1]);
    EXPECT(ayBLEClaiming(W)); /* robot 2 took it over */
    EXPECT(ay_node_stop_recording(robots[1], &written[1]) == AY_OK);
    printf("recorded %s/n1.mcap (%llu journal entries) and %s/n2.mcap (%llu)\n", dir,
           (unsigned long long)written[0], dir, (unsigned long long)written[1]);
    EXPECT(written[0] > 0 && written[1] > 0);
    ay_set_default_node(NULL);
    ay_node_free(robots[1]);
    ay_clock_free(clock);
    return 0;
}
