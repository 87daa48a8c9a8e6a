/*
 * Tutorial 8, two machines, one program per robot (docs/tutorials/08-two-machines.md), in C:
 * the same program runs on every robot, told only its id (1 or 2). Each robot's sonar drives
 * the motor of the other robot across the network, and each prints what its own motor
 * receives and from whom. The paper's ayInitIPCommsAs opens the node on $AYLLU_URL (the
 * subnet form on robots; unset, the machine-local default), on the real clock.
 *
 * Run, on machine A and machine B of one subnet (the URL in url.sh beside this file):
 *   make -C crates/ayllu-c build/tutorial_08_two_machines
 *   crates/ayllu-c/build/tutorial_08_two_machines 1 --for 60    # on A
 *   crates/ayllu-c/build/tutorial_08_two_machines 2 --for 60    # on B
 * Exits 0 once the other robot's values have driven this robot's motor, 1 (naming the likely
 * cause) if none arrived within the run (10 s by default). The Rust and Python programs beside
 * it are the same robot: robots in any of the three languages make a team.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <ayllu.h>

/* This robot's sonar reading: a distinct constant per robot, so each motor's value says which
 * robot it came from. */
static double reading;

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
    ayWriteFloatPort(Range, reading);
}

ayDefBehaviorClass(Motor) {
    ayINTERFACE {
        ayFloatPortLifespan(Speed, 0, seconds(0.3)); /* stale 300 ms after the last command */
    }
    ayPROCESSES {
    }
}

/* The supplier of a why report (JSON) as `nNODE/cCONN`, or "nobody". */
static void supplier_of(const char *why, char *out, size_t capacity) {
    const char *s = strstr(why, "\"supplier\"");
    const char *node = s ? strstr(s, "\"node\"") : NULL;
    const char *conn = s ? strstr(s, "\"conn\"") : NULL;
    unsigned long n = 0, c = 0;
    if (node && conn && sscanf(strchr(node, ':') + 1, "%lu", &n) == 1 && sscanf(strchr(conn, ':') + 1, "%lu", &c) == 1) {
        snprintf(out, capacity, "n%lu/c%lu", n, c);
    } else {
        snprintf(out, capacity, "nobody");
    }
}

static int usage(void) {
    fprintf(stderr, "usage: tutorial_08_two_machines ID [--for SECONDS] (ID: 1 or 2)\n");
    return 2;
}

int main(int argc, char **argv) {
    unsigned id, other;
    double seconds = 10;
    int received = 0;
    char at[64] = "", from[32];
    size_t len = 0;
    if (argc < 2 || (argc != 2 && argc != 4)) {
        return usage();
    }
    id = (unsigned)strtoul(argv[1], NULL, 10);
    if ((id != 1 && id != 2) || (argc == 4 && (strcmp(argv[2], "--for") != 0 || (seconds = atof(argv[3])) <= 0))) {
        return usage();
    }
    other = 3 - id;
    reading = 0.5 + 0.1 * id;

    ayInitIPCommsAs(id, NULL); /* NULL: $AYLLU_URL, else discovery on this machine */
    ayInitBehavior(Sonar, SONAR);
    ayInitBehavior(Motor, MOTOR);
    /* A connection to a port of another robot, by node id: no address. */
    ayRemoteConnect(SONAR, Range, other, MOTOR, Speed);
    if (ay_node_address(ayNODE, at, sizeof at, &len) != AY_OK) {
        snprintf(at, sizeof at, "?");
    }
    printf("robot %u at %s, its sonar drives robot %u's motor\n", id, at, other);
    fflush(stdout);
    for (int s = 1; s <= (int)seconds; s++) {
        char *why;
        bool fresh;
        char expected[16];
        ayRunBehaviorsFor(1.0);
        why = ayWhy(MOTOR, Speed);
        supplier_of(why, from, sizeof from);
        ayFreeReport(why);
        fresh = ayPortFreshOf(MOTOR, Speed);
        if (fresh) {
            printf("%4.1f s  MOTOR.Speed = %.1f from %s\n", (double)s, ayReadFloatPortOf(MOTOR, Speed), from);
        } else {
            printf("%4.1f s  MOTOR.Speed = stale from %s\n", (double)s, from);
        }
        fflush(stdout);
        snprintf(expected, sizeof expected, "n%u/", other);
        if (fresh && strncmp(from, expected, strlen(expected)) == 0) {
            received++;
        }
    }
    ayShutdown();
    if (received == 0) {
        fprintf(stderr,
                "nothing from robot %u in %.0f s: is it running, with the same AYLLU_URL (ttl=1 across machines, "
                "the same team= and key=)? docs/troubleshooting.md, by symptom\n",
                other, seconds);
        return 1;
    }
    return 0;
}
