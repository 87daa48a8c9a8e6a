/*
 * test_macros.c -- every macro of ayllu.h and ayllustd.h, used as a program would, with the
 * expected values of the core's rule tests: a class declaring every port kind and type,
 * lifespans, windows, slots and a monostable; periodic, port-triggered and
 * monostable-triggered processes using ayLocalPort/ayRead.../ayWrite...; every connection kind
 * as a local, remote and broadcast macro; BLE in one call; why and list; the run loops; the
 * standard behaviors and the simulator's body. Nodes run on manual clocks (mem://), except
 * for the real-time run loops, whose checks do not depend on timing.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "check.h"
#include "ayllustd.h"

static const double zero2[2] = {0, 0};

struct seen {
    int ticks;
    int while_fresh;
    int triggered;
    int mono_changes;
    int64_t last_i;
    double now;
    uint32_t node;
    char text[16];
    bool stale_life;
    bool b_read;
    size_t vec_len;
    double vec0;
    size_t blob_len;
    uint8_t blob2;
};
static struct seen seen;

ayDefBehaviorClass(Everything) {
    ayINTERFACE {
        ayIntPort(I, 0);
        ayMaxIntPort(MaxI, 0);
        ayMinIntPort(MinI, 0);
        aySumIntPort(SumI, 0);
        ayPriorityIntPort(PrioI, 0);
        ayFloatPort(F, 0);
        ayMaxFloatPort(MaxF, 0);
        ayMinFloatPort(MinF, 0);
        aySumFloatPort(SumF, 0);
        ayPriorityFloatPort(PrioF, 0);
        ayBoolPort(B, false);
        ayMaxBoolPort(MaxB, false);
        ayMinBoolPort(MinB, true);
        ayPriorityBoolPort(PrioB, false);
        ayTextPort(T, "none");
        ayPriorityTextPort(PrioT, "idle");
        ayVectorPort(Vec, zero2, 2);
        aySumVectorPort(SumVec, zero2, 2);
        ayBytesPort(Blob, NULL, 0);
        ayPriorityBytesPort(PrioBlob, NULL, 0);
        ayBytesPortEx(BlobLife, NULL, 0, ayNORMAL, seconds(0.3), 0);
        ayIntPortLifespan(LifeI, 0, seconds(0.3));
        ayFloatPortLifespan(LifeF, 0, seconds(0.3));
        ayBoolPortLifespan(LifeB, false, seconds(0.3));
        ayTextPortLifespan(LifeT, "", seconds(0.3));
        ayIntPortEx(WinI, 0, ayMAX, 0, seconds(1));
        ayFloatPortEx(WinF, 0, ayMIN, 0, seconds(1));
        ayBoolPortEx(WinB, false, ayMAX, seconds(2), seconds(1));
        ayTextPortEx(WinT, "", ayPRIORITY, 0, seconds(1));
        ayVectorPortEx(WinVec, zero2, 2, aySUM, 0, seconds(1));
        ayIntPortEx(Normal, 0, ayNORMAL, 0, 0);
        ayIntSlot(Count, 0);
        ayFloatSlot(Acc, 0);
        ayBoolSlot(Flag, false);
        ayTextSlot(Label, "x");
        ayMonostable(Busy);
    }
    ayPROCESSES {
        ayInitProcess(Tick, ratepersecond(10));
        ayInitTriggeredProcess(OnI, I);
        ayInitProcessWhileFresh(WhileLifeF, ratepersecond(10), LifeF);
        ayInitMonostableProcess(OnBusy, Busy);
    }
}

ayDefProcess(Tick) {
    ayLocalPort(F, B, T, Vec, SumI, SumF, LifeI, BLE_Local, Blob);
    ayLocalSlot(Count, Acc, Flag);
    double v[2];
    int64_t n = ayReadIntSlot(Count) + 1;
    ayWriteIntSlot(Count, n);
    ayWriteFloatSlot(Acc, ayReadFloatSlot(Acc) + 0.5);
    ayWriteBoolSlot(Flag, !ayReadBoolSlot(Flag));
    ayWriteFloatPort(F, ayReadFloatSlot(Acc));
    ayWriteBoolPort(B, ayReadBoolSlot(Flag));
    seen.b_read = ayReadBoolPort(B);
    ayWriteTextPort(T, n % 2 ? "odd" : "even");
    v[0] = (double)n;
    v[1] = -(double)n;
    ayWriteVectorPort(Vec, v, 2);
    {
        const uint8_t bytes[3] = {1, 2, (uint8_t)n};
        uint8_t back[8];
        double vec[4];
        ayWriteBytesPort(Blob, bytes, 3);
        seen.blob_len = ayReadBytesPort(Blob, back, sizeof back);
        seen.blob2 = back[2];
        seen.vec_len = ayReadVectorPort(Vec, vec, 4);
        seen.vec0 = vec[0];
    }
    ayWriteIntPort(SumI, 1);
    ayWriteFloatPort(SumF, 0.25);
    ayWriteFloatPort(BLE_Local, 0.5);
    ayReadTextPort(T, seen.text, sizeof seen.text);
    seen.stale_life = !ayPortFresh(LifeI);
    seen.now = ayNow();
    seen.node = ayNodeId();
    seen.ticks++;
    (void)ayUSER;
    (void)ayCTX;
}

ayDefProcess(OnI) {
    ayLocalPort(I, MaxI, MinI);
    ayLocalMonostable(Busy);
    seen.last_i = ayReadIntPort(I);
    ayWriteIntPort(MaxI, seen.last_i);
    ayWriteIntPort(MinI, seen.last_i);
    if (!ayIsHigh(Busy)) {
        ayTrigger(Busy, seconds(1));
    }
    if (seen.last_i < 0) {
        ayResetPort(MaxI);
    }
    seen.triggered++;
}

/* Activated only while LifeF is fresh (D7.5). */
ayDefProcess(WhileLifeF) {
    seen.while_fresh++;
}

ayDefProcess(OnBusy) {
    seen.mono_changes++;
}

/* A relay: one int port V (common/mod.rs's wiring, as a macro class). */
ayDefBehaviorClass(Relay) {
    ayINTERFACE {
        ayIntPort(V, 0);
    }
}

static ay_clock *clock_;

static ay_node *open_node(uint32_t id, const char *net) {
    ay_node *node = NULL;
    OK(ay_node_open_manual(id, net, clock_, &node));
    OK(ay_set_default_node(node));
    return node;
}

static void at(double ms) {
    OK(ay_clock_set(clock_, ms / 1000.0));
}

static void everything(void) {
    ay_node *node = open_node(1, "mem://macros-everything");
    char *json;
    at(0);
    ayInitBehavior(Everything, X);
    ayStep();
    at(100);
    ayStep();
    at(200);
    ayStep();
    CHECK_EQ_INT(seen.ticks, 3);
    CHECK_EQ_INT(seen.node, 1);
    CHECK_NEAR(seen.now, 0.2);
    CHECK(strcmp(seen.text, "odd") == 0);
    CHECK(seen.stale_life);
    CHECK_EQ_INT(seen.blob_len, 3);
    CHECK_EQ_INT(seen.blob2, 3);
    CHECK_EQ_INT(seen.vec_len, 2);
    CHECK_NEAR(seen.vec0, 3);
    CHECK_NEAR(ayReadFloatPortOf(X, F), 1.5);
    CHECK(ayReadBoolPortOf(X, B)); /* toggled three times */
    CHECK(seen.b_read);
    CHECK_EQ_INT(ayReadIntPortOf(X, SumI), 3);
    CHECK_NEAR(ayReadFloatPortOf(X, SumF), 0.75);
    CHECK_NEAR(ayReadFloatPortOf(X, BLE_Local), 0.5);
    /* Triggered by I; the monostable rises once (1 s) and falls. */
    ayWriteIntPortOf(X, I, 7);
    ayStep();
    CHECK_EQ_INT(seen.triggered, 1);
    CHECK_EQ_INT(seen.last_i, 7);
    ayWriteIntPortOf(X, I, 3);
    ayStep();
    CHECK_EQ_INT(ayReadIntPortOf(X, MaxI), 7); /* port_max.rs: keeps the maximum */
    CHECK_EQ_INT(ayReadIntPortOf(X, MinI), 3); /* port_min.rs */
    CHECK_EQ_INT(seen.mono_changes, 1);
    at(1200);
    ayStep();
    CHECK_EQ_INT(seen.mono_changes, 2);
    ayWriteIntPortOf(X, I, -1);
    ayStep();
    CHECK(!ayPortFreshOf(X, MaxI)); /* reset by the process */
    /* Lifespans: fresh for 0.3 s. */
    ayWriteIntPortOf(X, LifeI, 1);
    ayWriteFloatPortOf(X, LifeF, 1);
    ayWriteBoolPortOf(X, LifeB, true);
    ayWriteTextPortOf(X, LifeT, "here");
    CHECK(ayPortFreshOf(X, LifeI) && ayPortFreshOf(X, LifeF) && ayPortFreshOf(X, LifeB) && ayPortFreshOf(X, LifeT));
    CHECK_EQ_INT(seen.while_fresh, 0); /* LifeF was stale at every due time so far */
    at(1300);
    ayStep();
    CHECK_EQ_INT(seen.while_fresh, 1);
    at(1500);
    CHECK(!ayPortFreshOf(X, LifeI) && !ayPortFreshOf(X, LifeF) && !ayPortFreshOf(X, LifeB) && !ayPortFreshOf(X, LifeT));
    /* Windows: an aggregating port empties 1 s after its window opened. */
    ayWriteIntPortOf(X, WinI, 5);
    ayWriteFloatPortOf(X, WinF, 2);
    ayWriteBoolPortOf(X, WinB, true);
    ayWriteTextPortOf(X, WinT, "go");
    CHECK_EQ_INT(ayReadIntPortOf(X, WinI), 5);
    at(2500);
    CHECK(!ayPortFreshOf(X, WinI) && !ayPortFreshOf(X, WinF) && !ayPortFreshOf(X, WinB) && !ayPortFreshOf(X, WinT));
    ayWriteIntPortOf(X, WinI, 2);
    CHECK_EQ_INT(ayReadIntPortOf(X, WinI), 2);
    /* Bool Max/Min, priority ports written from inside the behavior. */
    ayWriteBoolPortOf(X, MaxB, true);
    ayWriteBoolPortOf(X, MaxB, false);
    CHECK(ayReadBoolPortOf(X, MaxB));
    ayWriteBoolPortOf(X, MinB, false);
    ayWriteBoolPortOf(X, MinB, true);
    CHECK(!ayReadBoolPortOf(X, MinB));
    ayWriteIntPortOf(X, PrioI, 4);
    ayWriteFloatPortOf(X, PrioF, 4.5);
    ayWriteBoolPortOf(X, PrioB, true);
    ayWriteTextPortOf(X, PrioT, "busy");
    CHECK_EQ_INT(ayReadIntPortOf(X, PrioI), 4);
    CHECK_NEAR(ayReadFloatPortOf(X, MaxF), 0); /* never written: its default */
    CHECK_NEAR(ayReadFloatPortOf(X, MinF), 0);
    ayWriteIntPortOf(X, Normal, 9);
    CHECK_EQ_INT(ayReadIntPortOf(X, Normal), 9);
    /* why and list. */
    json = ayWhy(X, MaxI);
    CHECK(json != NULL && strstr(json, "\"Max\"") != NULL);
    ayFreeReport(json);
    json = ayReport();
    CHECK(json != NULL && strstr(json, "\"Everything\"") != NULL && strstr(json, "\"OnBusy\"") != NULL);
    ayFreeReport(json);
    ayRemoveBehavior(X);
    CHECK(ay_node_read_int(node, "X", "I", NULL) == AY_ERR_UNKNOWN);
    OK(ay_node_free(node));
}

static ay_node *relays(uint32_t id, const char *net) {
    ay_node *node = open_node(id, net);
    ayInitBehavior(Relay, S);
    ayInitBehavior(Relay, A);
    ayInitBehavior(Relay, D);
    ayInitBehavior(Relay, E);
    ayConnect(A, V, D, V);
    ayConnect(D, V, E, V);
    return node;
}

static void local_connections(void) {
    /* The rule tests' wiring (S --kind(100ms)--> D <--Normal-- A, D --> E), one macro each. */
    ay_node *node;
    uint64_t id;
    node = relays(1, "mem://macros-suppress");
    at(0);
    aySuppress(S, V, D, V, seconds(0.1));
    ayWriteIntPortOf(S, V, 7);
    ayWriteIntPortOf(A, V, 1);
    CHECK_EQ_INT(ayReadIntPortOf(D, V), 0); /* connection_suppress.rs */
    OK(ay_node_free(node));

    node = relays(1, "mem://macros-inhibit");
    ayInhibit(S, V, D, V, seconds(0.1));
    ayWriteIntPortOf(S, V, 7);
    ayWriteIntPortOf(A, V, 4);
    CHECK_EQ_INT(ayReadIntPortOf(D, V), 4); /* connection_inhibit.rs: stored, */
    CHECK_EQ_INT(ayReadIntPortOf(E, V), 0); /* not propagated */
    OK(ay_node_free(node));

    node = relays(1, "mem://macros-override-in");
    ayOverrideIn(S, V, D, V, seconds(0.1));
    ayWriteIntPortOf(S, V, 7);
    ayWriteIntPortOf(A, V, 1);
    CHECK_EQ_INT(ayReadIntPortOf(D, V), 7); /* connection_override_in.rs */
    CHECK_EQ_INT(ayReadIntPortOf(E, V), 7);
    OK(ay_node_free(node));

    node = relays(1, "mem://macros-override-out");
    ayOverrideOut(S, V, D, V, seconds(0.1));
    ayWriteIntPortOf(S, V, 7);
    ayWriteIntPortOf(A, V, 1);
    CHECK_EQ_INT(ayReadIntPortOf(D, V), 1); /* connection_override_out.rs */
    CHECK_EQ_INT(ayReadIntPortOf(E, V), 7);
    OK(ay_node_free(node));

    node = relays(1, "mem://macros-write-inhibit");
    ayInhibitWrite(S, V, D, V, seconds(0.1));
    ayWriteIntPortOf(S, V, 7);
    ayWriteIntPortOf(D, V, 3);
    CHECK_EQ_INT(ayReadIntPortOf(E, V), 0); /* connection_write_inhibit.rs */
    ayWriteIntPortOf(A, V, 5);
    CHECK_EQ_INT(ayReadIntPortOf(E, V), 5);
    OK(ay_node_free(node));

    /* Any endpoints; disconnect; connection priority. */
    node = relays(1, "mem://macros-endpoints");
    id = ayConnectEndpoints(AY_NORMAL, ayAt(S, V), ayAt(A, V), 0);
    ayWriteIntPortOf(S, V, 8);
    CHECK_EQ_INT(ayReadIntPortOf(E, V), 8);
    ayDisconnect(id);
    ayWriteIntPortOf(S, V, 9);
    CHECK_EQ_INT(ayReadIntPortOf(E, V), 8);
    CHECK(ayConnectPriority(S, V, E, V, 3) != 0);
    OK(ay_node_free(node));
}

static void step_both(ay_node *a, ay_node *b) {
    for (int i = 0; i < 3; i++) {
        OK(ay_node_step(a, NULL));
        OK(ay_node_step(b, NULL));
        OK(ay_clock_advance(clock_, 0.001));
    }
}

static void remote_and_broadcast_connections(void) {
    ay_node *two = relays(2, "mem://macros-remote");
    ay_node *one = relays(1, "mem://macros-remote");
    ayBROADCAST peers = ayMakeBroadcast("Peers");
    /* One node's macros reach the other's ports: the paper's (host, behavior, port). */
    ayRemoteConnect(A, V, 2, A, V);
    ayRemoteSuppress(S, V, 2, S, V, seconds(0.1));
    ayRemoteInhibit(S, V, 2, E, V, seconds(0.1));
    ayRemoteOverrideIn(E, V, 2, D, V, seconds(0.1));
    ayRemoteOverrideOut(E, V, 2, E, V, seconds(0.1));
    ayRemoteInhibitWrite(S, V, 2, A, V, seconds(0.1));
    CHECK(ayConnectEndpoints(AY_NORMAL, ayAt(S, V), ayOn(2, E, V), 0) != 0);
    CHECK(ayConnectEndpoints(AY_INHIBIT, ayAt(S, V), ayIn(peers, S, V), aySeconds(0.1)) != 0);
    ayWriteIntPortOf(A, V, 6); /* 1.A -> 2.A (and locally 1.D, 1.E -> 2.D by override) */
    step_both(one, two);
    OK(ay_set_default_node(two));
    CHECK_EQ_INT(ayReadIntPortOf(A, V), 6);
    CHECK_EQ_INT(ayReadIntPortOf(D, V), 6);
    /* Broadcast: to every other node of the group; this node joins it. */
    ayBroadcastConnect(S, V, peers, S, V);
    ayBroadcastSuppress(S, V, peers, A, V, seconds(0.1));
    ayBroadcastInhibit(S, V, peers, D, V, seconds(0.1));
    ayBroadcastOverrideIn(S, V, peers, E, V, seconds(0.1));
    ayBroadcastOverrideOut(A, V, peers, E, V, seconds(0.1));
    ayBroadcastInhibitWrite(A, V, peers, D, V, seconds(0.1));
    OK(ay_set_default_node(one));
    OK(ay_node_join(one, "Peers"));
    OK(ay_set_default_node(two));
    ayWriteIntPortOf(S, V, 4);
    step_both(one, two);
    OK(ay_set_default_node(one));
    CHECK_EQ_INT(ayReadIntPortOf(S, V), 4);
    CHECK_EQ_INT(ayReadIntPortOf(E, V), 4); /* override in from node 2 */
    OK(ay_node_free(one));
    OK(ay_node_free(two));
}

static void ble_in_one_call(void) {
    ay_node *nodes[2];
    ayBROADCAST peers = ayMakeBroadcast("Peers");
    for (int i = 0; i < 2; i++) {
        nodes[i] = open_node((uint32_t)i + 1, "mem://macros-ble");
        ayInitBehavior(Relay, OBS1);
        ayInitBehavior(Relay, OBS2);
        ayBLE(OBS1, peers, V, ratepersecond(1));
        ayBLEInhibitFor(OBS2, peers, V, ratepersecond(1), seconds(0.5));
    }
    for (int tick = 0; tick < 50; tick++) {
        for (int i = 0; i < 2; i++) {
            OK(ay_set_default_node(nodes[i]));
            ayWriteFloatPortOf(OBS1, BLE_Local, i == 0 ? 0.9 : 0.1);
            ayStep();
        }
        OK(ay_clock_advance(clock_, 0.1));
    }
    OK(ay_set_default_node(nodes[0]));
    CHECK(ayBLEClaiming(OBS1));
    CHECK(!ayBLEClaiming(OBS2)); /* no eligibility written: no claim */
    {
        char *report = ayReport(); /* 0.5 s at 1 Hz is too short: warned (D11.2) */
        CHECK(report != NULL && strstr(report, "shorter than twice the claim period") != NULL);
        ayFreeReport(report);
    }
    OK(ay_set_default_node(nodes[1]));
    CHECK(!ayBLEClaiming(OBS1));
    OK(ay_node_free(nodes[0]));
    OK(ay_node_free(nodes[1]));
}

static void standard_behaviors_and_body(void) {
    ay_node *node = open_node(1, "mem://macros-std");
    ayBROADCAST peers = ayMakeBroadcast("Peers");
    double ranges[64];
    size_t beams = 0;
    at(0);
    ayInitSimBody(4);
    MakeSafeVelBeh(VEL);
    MakeWanderBehSeeded(WANDER, 7);
    MakeWanderBeh(WANDER2);
    MakeStdObserver(1, WANDER, peers, ratepersecond(1));
    CHECK(ay_node_read_vector(node, "SONAR", "Ranges", ranges, 64, &beams) == AY_ERR_ABSENT);
    for (size_t k = 0; k < beams; k++) {
        ranges[k] = 5.0;
    }
    OK(ay_node_write_vector(node, "SONAR", "Ranges", ranges, beams));
    ayWriteFloatPortOf(VISION, Target1Angle, 0.3);
    ayWriteFloatPortOf(VISION, Target1Bottom, 50);
    ayStep();
    CHECK_NEAR(ayReadFloatPortOf(OBS1, Rotate), -0.3);
    CHECK_NEAR(ayReadFloatPortOf(BASE, Rotate), -0.3); /* the observer overrides WANDER */
    CHECK_NEAR(ayReadFloatPortOf(BASE, Translate), 0.4); /* clear ahead: full speed */
    OK(ay_node_free(node));
}

static void stop_after_three(ay_ctx *ctx, void *user) {
    int *n = (int *)user;
    (void)ctx;
    if (++*n == 3) {
        ay_request_stop();
    }
}

ayDefBehaviorClass(Stopper) {
    ayPROCESSES {
        ayInitProcess(StopAfterThree, ayRatePerSecond(100));
    }
}

ayDefProcess(StopAfterThree) {
    stop_after_three(ayCTX, ayUSER);
}

static void run_loops(void) {
    int activations = 0;
    /* ayInitIPComms on mem:// with the real clock; run until a process asks to stop. */
    ayInitIPCommsAs(5, "mem://macros-run");
    ayInitBehaviorWith(Stopper, STOP, &activations);
    ayRunBehaviors();
    CHECK(ay_stop_requested());
    CHECK(activations >= 3);
    ay_clear_stop();
    ayRunBehaviorsFor(seconds(0.05));
    CHECK(activations > 3);
    ayShutdown();
    CHECK(ay_default_node() == NULL);
}

int main(void) {
    OK(ay_clock_new(&clock_));
    everything();
    local_connections();
    remote_and_broadcast_connections();
    ble_in_one_call();
    standard_behaviors_and_body();
    OK(ay_clock_free(clock_));
    run_loops();
    return check_exit("test_macros");
}
