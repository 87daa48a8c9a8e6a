/*
 * The concepts page's code (docs/concepts.md), in C with the paper's macros: each section
 * between the --8<-- markers is shown on that page beside the same in Rust and Python; this
 * program runs them all and checks what the page says (exit 1 otherwise).
 */
#include <stdio.h>
#include <stdlib.h>

#include <ayllu.h>

#define EXPECT(cond)                                                               \
    do {                                                                           \
        if (!(cond)) {                                                             \
            fprintf(stderr, "concepts failed: %s (line %d)\n", #cond, __LINE__);    \
            exit(1);                                                               \
        }                                                                          \
    } while (0)

static ay_clock *clock_;

static ay_node *open_node(uint32_t id, const char *url) {
    ay_node *node = NULL;
    if (ay_node_open_manual(id, url, clock_, &node) != AY_OK) {
        fprintf(stderr, "%s\n", ay_last_error());
        exit(1);
    }
    ay_set_default_node(node);
    return node;
}

/* --8<-- [start:behavior] */
/* A behavior class: its registers (ports, slots, monostables) and its processes. */
ayDefBehaviorClass(Observer) {
    ayINTERFACE {
        ayFloatPortLifespan(TargetX, 0, seconds(0.25)); /* a port, typed by its default */
        ayFloatPort(Rotate, 0);
        ayIntSlot(Seen, 0);      /* a slot: internal state, never connectable */
        ayMonostable(Tracking);  /* true for a while after each trigger */
    }
    ayPROCESSES {
        ayInitTriggeredProcess(Saw, TargetX);   /* runs whenever TargetX accepts a value */
        ayInitProcess(Turn, ratepersecond(20)); /* 20 times a second */
    }
}

ayDefProcess(Saw) {
    ayLocalSlot(Seen);
    ayLocalMonostable(Tracking);
    ayTrigger(Tracking, seconds(1));
    ayWriteIntSlot(Seen, ayReadIntSlot(Seen) + 1);
}

ayDefProcess(Turn) {
    ayLocalPort(TargetX, Rotate);
    ayLocalMonostable(Tracking);
    /* ayPortFresh is false once TargetX is stale: rule S4 */
    ayWriteFloatPort(Rotate, ayPortFresh(TargetX) && ayIsHigh(Tracking) ? -0.5 * ayReadFloatPort(TargetX) : 0.0);
}
/* --8<-- [end:behavior] */

static void behaviors_and_processes(void) {
    ay_node *node = open_node(1, "mem://concepts-1");
    bool tracking = false;
    /* --8<-- [start:instance] */
    ayInitBehavior(Observer, OBS1);        /* a behavior: an instance of the class */
    ayWriteFloatPortOf(OBS1, TargetX, 0.4); /* as a camera would */
    ayStep();                              /* Saw runs, then Turn */
    EXPECT(ayReadFloatPortOf(OBS1, Rotate) == -0.2);
    /* --8<-- [end:instance] */
    ay_node_monostable(node, "OBS1", "Tracking", &tracking);
    EXPECT(tracking);
    ay_clock_advance(clock_, 0.3);
    ayStep();
    EXPECT(ayReadFloatPortOf(OBS1, Rotate) == 0.0); /* TargetX went stale after 250 ms */
    ay_set_default_node(NULL);
    ay_node_free(node);
}

ayDefBehaviorClass(Cmd) {
    ayINTERFACE {
        ayFloatPort(Out, 0);
    }
    ayPROCESSES {
    }
}

static void connections(void) {
    ay_node *node = open_node(1, "mem://concepts-2");
    char *why;
    ayInitBehavior(Cmd, A);
    ayInitBehavior(Cmd, B);
    ayInitBehavior(Cmd, C);
    ayInitBehavior(Cmd, D);
    ayInitBehavior(Cmd, E);
    ayInitBehavior(Cmd, F);
    ayInitBehavior(Cmd, G);
    /* --8<-- [start:connections] */
    ayConnect(A, Out, G, Out);
    aySuppress(B, Out, G, Out, seconds(0.5)); /* the window's period */
    ayInhibit(C, Out, G, Out, seconds(0.5));
    ayOverrideIn(D, Out, G, Out, seconds(0.5));
    ayOverrideOut(E, Out, G, Out, seconds(0.5));
    ayInhibitWrite(F, Out, G, Out, seconds(0.5));
    /* --8<-- [end:connections] */
    ayWriteFloatPortOf(B, Out, 1.0); /* opens a suppress window on G */
    ayWriteFloatPortOf(A, Out, 2.0); /* refused */
    why = ayWhy(G, Out);
    EXPECT(ayReadFloatPortOf(G, Out) == 0.0);
    EXPECT(why != NULL);
    ayFreeReport(why);
    ay_set_default_node(NULL);
    ay_node_free(node);
}

/* --8<-- [start:aggregating] */
/* The highest value offered within the last second wins; the port forgets it after that. */
ayDefBehaviorClass(Task) {
    ayINTERFACE {
        ayFloatPortEx(Bid, 0, ayMAX, 0, seconds(1)); /* default, kind, lifespan, window */
    }
    ayPROCESSES {
    }
}
/* --8<-- [end:aggregating] */

static void aggregating_ports(void) {
    ay_node *node = open_node(1, "mem://concepts-3");
    /* --8<-- [start:aggregating-use] */
    ayInitBehavior(Task, T);
    ayWriteFloatPortOf(T, Bid, 3.0);
    ayWriteFloatPortOf(T, Bid, 2.0); /* absorbed: below the maximum */
    EXPECT(ayReadFloatPortOf(T, Bid) == 3.0);
    /* --8<-- [end:aggregating-use] */
    ay_set_default_node(NULL);
    ay_node_free(node);
}

/* --8<-- [start:ble] */
ayDefBehaviorClass(Worker) {
    ayINTERFACE {
        ayIntPort(Out, 0);
    }
    ayPROCESSES {
        ayInitProcess(Work, ratepersecond(10));
    }
}

ayDefProcess(Work) {
    static const double eligibility[] = {0, 0.2, 0.9, 0.5}; /* how well suited each robot is */
    ayLocalPort(Out, BLE_Local);
    ayWriteFloatPort(BLE_Local, eligibility[ayNodeId()]);
    ayWriteIntPort(Out, (int64_t)ayNodeId());
}

static void ble(void) {
    ay_node *nodes[3];
    ayBROADCAST peers = ayMakeBroadcast("Peers");
    int i, tick;
    for (i = 0; i < 3; i++) { /* three nodes on one virtual clock */
        nodes[i] = open_node((uint32_t)i + 1, "mem://concepts-ble");
        ayInitBehavior(Worker, W);
        /* Join the group: the most eligible claims the task, write-inhibiting the others' Out. */
        ayBLE(W, peers, Out, ratepersecond(2));
    }
    for (tick = 0; tick < 300; tick++) {
        for (i = 0; i < 3; i++) {
            ay_set_default_node(nodes[i]);
            ayStep();
        }
        ay_clock_advance(clock_, 0.01);
    }
    for (i = 0; i < 3; i++) {
        ay_set_default_node(nodes[i]);
        EXPECT(ayBLEClaiming(W) == (i == 1)); /* robot 2 is the most eligible */
    }
    /* --8<-- [end:ble] */
    ay_set_default_node(NULL);
    for (i = 0; i < 3; i++) {
        ay_node_free(nodes[i]);
    }
}

int main(void) {
    if (ay_clock_new(&clock_) != AY_OK) {
        return 1;
    }
    behaviors_and_processes();
    connections();
    aggregating_ports();
    ble();
    ay_clock_free(clock_);
    printf("every concept ran as the page says\n");
    return 0;
}
