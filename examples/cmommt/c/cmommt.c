/*
 * cmommt.c -- the paper's Fig. 2 (Werger, "Ayllu", section 4.2: the whole W-CMOMMT
 * controller), in C with ayllu.h, as one robot of a team: one OS process per robot, its body
 * served by `ayllu sim serve` (or, on a real robot, a driver exposing the same ports).
 *
 * It is the figure as printed except where the figure cannot run or is wrong; every change is
 * marked `CHANGED:` with what the paper printed and why (docs/cmommt.md lists the errata the
 * Rust controller fixes, docs/c-api.md the forms C cannot write as printed).
 *
 *   cmommt ROBOT URL [SECONDS [SEED]]
 *
 * ROBOT is the robot's number (its node id, 1..999: the server's body for it is node
 * 1000+ROBOT), URL this node's udp:// address (`udp://127.0.0.1:0?peer=...`: port 0 binds a
 * free port, reported on the first line of stdout as {"listening":ADDR,"node":ROBOT}), SECONDS
 * how long to run (default: until SIGINT/SIGTERM), SEED the wander seed (default 1). The
 * server's --udp URL for this robot names ADDR as its peer.
 */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>

#include <ayllu.h>
#include <ayllustd.h> /* for MakeWanderBeh and MakeSafeVelBeh */

/* The number of targets (one observer layer each) and their lifespan in the observer. */
#define TARGETS 4
#define SEEN_FOR seconds(0.25)

ayDefBehaviorClass(ObserveTarget) {
    ayINTERFACE {
        /* CHANGED: the paper printed ayIntPort(TargetX, 0) and ayIntPort(TargetY, 0), pixels.
         * The body reports the bearing (rad, positive to the right) and the apparent height
         * as floats (docs/cmommt.md, change 5), and the inputs go stale 0.25 s after the
         * target leaves the view (a lifespan, rule S4) so that the layer can fall silent
         * (change 3). */
        ayFloatPortLifespan(TargetX, 0, SEEN_FOR);
        ayFloatPortLifespan(TargetY, 0, SEEN_FOR);
        ayFloatPort(Rotate, 0); /* CHANGED: ayIntPort; rad/s, positive to the left */
    }
    ayPROCESSES {
        ayInitProcess(TurnToTarget, ratepersecond(20));
        /* CHANGED: the paper printed ayInitProcess(BLE_Select, ratepersecond(1)) here. The
         * select process is the library's, added with its rate by ayBLE in MakeObserver
         * (BLE in one call), which also makes the two broadcast connections. */
    }
}

ayDefProcess(TurnToTarget) {
    /* CHANGED: the paper printed `ayLocalPort TargetX, TargetY, Rotate, BLE_Local;` — a
     * declaration list C cannot give values to; ours is a macro call. */
    ayLocalPort(TargetX, TargetY, Rotate, BLE_Local);
    /* CHANGED: the paper wrote both ports every cycle, also from stale or default
     * coordinates, so a higher layer overrode the lower ones forever and claimed a target it
     * could not see; here nothing is written unless the target is in view (change 3). */
    if (ayPortFresh(TargetX) && ayPortFresh(TargetY)) {
        /* CHANGED: ayWriteIntPort(Rotate, ayVISCENTERX - ayReadIntPort(TargetX)): pixels
         * from the image centre; here the bearing, turned into a left-positive turn rate. */
        ayWriteFloatPort(Rotate, -ayReadFloatPort(TargetX));
        /* CHANGED: ayWriteIntPort(BLE_Local, ayMAXVISY-ReadPort(TargetY)) (ReadPort: a typo);
         * here the apparent height itself, larger when closer (same ordering). */
        ayWriteFloatPort(BLE_Local, ayReadFloatPort(TargetY));
    }
}
/* BLE_Local is local eligibility estimate */

/* CHANGED: the paper's last two lines were
 *   ayBroadcastConnect(OBS##num, BLE_Local, Peers, OBS##1, BLE_Best);
 *   ayBroadcastInhibitWrite(OBS##num, BLE_Inhibit, Peers, OBS##num, Rotate, seconds(0.5));
 * with BLE_Select at 1 Hz in the class. ayBLE makes exactly these two connections and the
 * select process, with two errata fixed: eligibility goes to the *same* layer on the peers
 * (OBS##num, not OBS##1: change 1), and the claim inhibits for 2.3 s, twice the 1 s claim
 * period plus delay and margin, not 0.5 s, which lapses between claims (change 2).
 * CHANGED: ayInitBehavior(Observer, ...): the class is the one defined above. */
#define MakeObserver(num, next)                                      \
    ayInitBehavior(ObserveTarget, OBS##num);                         \
    ayConnect(VISION, Target##num##Angle, OBS##num, TargetX);        \
    ayConnect(VISION, Target##num##Bottom, OBS##num, TargetY);       \
    ayOverrideOut(OBS##num, Rotate, next, Rotate, seconds(0.2));     \
    ayBLE(OBS##num, Peers, Rotate, ratepersecond(1))

static void stop(int signal_number) {
    (void)signal_number;
    ay_request_stop(); /* async-signal-safe */
}

/* CHANGED: `void main ()`, which C does not allow; the robot's number, address, run time and
 * wander seed come from the command line. */
int main(int argc, char **argv) {
    char address[128];
    unsigned long robot;
    double run_for;
    unsigned long long seed;
    if (argc < 3) {
        fprintf(stderr, "usage: %s ROBOT URL [SECONDS [SEED]]\n", argv[0]);
        return 2;
    }
    robot = strtoul(argv[1], NULL, 10);
    run_for = argc > 3 ? strtod(argv[3], NULL) : -1;
    seed = argc > 4 ? strtoull(argv[4], NULL, 10) : 1;

    /* CHANGED: the paper passed the subnet's broadcast address ("10.255.255.255"); a group is
     * named here, and the node's udp:// URL says where the group's datagrams go (broadcast=,
     * or peer= for unicast to the peers that announced the group). "Peers" is the group the
     * Rust controllers use, so C and Rust robots can share a team. */
    ayBROADCAST Peers = ayMakeBroadcast("Peers");
    /* CHANGED: ayInitIPComms() before the body, which is behaviors on this node: the node's
     * id and address are the robot's number and the URL (ayInitIPComms() alone reads them
     * from $AYLLU_NODE and $AYLLU_URL). */
    ayInitIPCommsAs((uint32_t)robot, argv[2]);
    /* CHANGED: ayInitPioControl("/dev/ttyS0") drove a Pioneer's serial port; here the body
     * (VISION, SONAR, BASE) is served over UDP by `ayllu sim serve`. On a ROS 2 robot this is
     * the one line that changes: ayInitRos2Body("robot.toml") makes the body the robot's
     * topics (docs/ros2.md; `make ros2-c` builds this file so, with AYLLU_ROS2_BODY). */
#ifdef AYLLU_ROS2_BODY
    ayInitRos2Body(AYLLU_ROS2_BODY);
#else
    ayInitSimBody(TARGETS);
#endif

    MakeSafeVelBeh(VEL);
    /* CHANGED: MakeWanderBeh(WANDER): seeded, to compare with the Rust team in the same world. */
    MakeWanderBehSeeded(WANDER, seed);
    /* CHANGED: the paper made five layers (OBS5 .. OBS1) for four targets; one per target
     * (change 4). */
    MakeObserver(4, WANDER);
    MakeObserver(3, OBS4);
    MakeObserver(2, OBS3);
    MakeObserver(1, OBS2);

    /* Where this robot listens, for the server's --udp URL (and the test that starts it). */
    if (ay_node_address(ayNODE, address, sizeof address, NULL) != AY_OK) {
        fprintf(stderr, "cmommt: %s\n", ay_last_error());
        return 1;
    }
    printf("{\"listening\":\"%s\",\"node\":%lu}\n", address, robot);
    fflush(stdout);

    signal(SIGINT, stop);
    signal(SIGTERM, stop);
    if (run_for > 0) {
        ayRunBehaviorsFor(seconds(run_for));
    } else {
        ayRunBehaviors();
    }
    ayShutdown();
    return 0;
}
