/*
 * Tutorial 1, a first behavior (docs/tutorials/01-first-behavior.md), in C with the paper's
 * macros: the class Avoid with two ports, a slot, a monostable and two processes, on a node
 * whose clock is manual, so the program decides when time passes.
 *
 * Build and run (what `make -C crates/ayllu-c tutorials` does):
 *   cc -std=c99 -Wall -Wextra -Werror -Icrates/ayllu-c/include main.c \
 *      target/debug/libayllu_c.a -lpthread -ldl -lm -o first && ./first
 * Exits non-zero if what the tutorial says does not happen.
 */
#include <stdio.h>
#include <stdlib.h>

#include <ayllu.h>

#define EXPECT(cond)                                                  \
    do {                                                              \
        if (!(cond)) {                                                \
            fprintf(stderr, "tutorial 1 failed: %s (line %d)\n", #cond, __LINE__); \
            exit(1);                                                  \
        }                                                             \
    } while (0)

ayDefBehaviorClass(Avoid) {
    ayINTERFACE {
        ayFloatPort(Range, 10); /* metres, written by a sonar */
        ayFloatPort(Turn, 0);   /* rad/s, to the motors */
        ayIntSlot(Seen, 0);     /* internal: not connectable */
        ayMonostable(Backing);  /* high for a while after a trigger */
    }
    ayPROCESSES {
        ayInitTriggeredProcess(React, Range); /* runs whenever Range accepts a value */
        ayInitProcess(Steer, ratepersecond(10));
    }
}

ayDefProcess(React) {
    ayLocalPort(Range);
    ayLocalSlot(Seen);
    ayLocalMonostable(Backing);
    if (ayPortFresh(Range) && ayReadFloatPort(Range) < 0.5) {
        ayTrigger(Backing, seconds(2));
        ayWriteIntSlot(Seen, ayReadIntSlot(Seen) + 1);
    }
}

ayDefProcess(Steer) {
    ayLocalPort(Turn);
    ayLocalMonostable(Backing);
    ayWriteFloatPort(Turn, ayIsHigh(Backing) ? 1.0 : 0.0);
}

int main(void) {
    ay_clock *clock = NULL;
    ay_node *node = NULL;
    bool backing = false;
    int i;
    if (ay_clock_new(&clock) != AY_OK || ay_node_open_manual(1, "mem://tutorial-01", clock, &node) != AY_OK) {
        fprintf(stderr, "cannot open the node: %s\n", ay_last_error());
        return 1;
    }
    ay_set_default_node(node); /* the node the macros use */
    ayInitBehavior(Avoid, A);

    ayWriteFloatPortOf(A, Range, 0.3); /* at 0 s, as a sonar would */
    ayStep();                          /* React, then Steer's first activation */
    ay_node_monostable(node, "A", "Backing", &backing);
    printf("0.0 s: Range 0.3 m -> Turn %.1f, Backing %s\n", ayReadFloatPortOf(A, Turn), backing ? "true" : "false");
    EXPECT(ayReadFloatPortOf(A, Turn) == 1.0 && backing);

    for (i = 0; i < 20; i++) { /* 2 s in ten steps a second */
        ay_clock_advance(clock, 0.1);
        ayStep();
    }
    ay_node_monostable(node, "A", "Backing", &backing);
    printf("2.0 s: Turn %.1f, Backing %s\n", ayReadFloatPortOf(A, Turn), backing ? "true" : "false");
    EXPECT(ayReadFloatPortOf(A, Turn) == 0.0 && !backing);

    ay_set_default_node(NULL);
    ay_node_free(node);
    ay_clock_free(clock);
    return 0;
}
