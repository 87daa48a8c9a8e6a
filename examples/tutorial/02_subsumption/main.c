/*
 * Tutorial 2, two behaviors in subsumption (docs/tutorials/02-subsumption.md), in C: Wander
 * drives the motor; Avoid takes it over through an OverrideIn connection while an obstacle is
 * near (ayOverrideIn is Brooks's suppression; the paper's aySuppress only blocks).
 * Exits non-zero if what the tutorial says does not happen.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include <ayllu.h>

#define EXPECT(cond)                                                  \
    do {                                                              \
        if (!(cond)) {                                                \
            fprintf(stderr, "tutorial 2 failed: %s (line %d)\n", #cond, __LINE__); \
            exit(1);                                                  \
        }                                                             \
    } while (0)

ayDefBehaviorClass(Wander) {
    ayINTERFACE {
        ayFloatPort(Turn, 0);
    }
    ayPROCESSES {
        ayInitProcess(Drift, ratepersecond(10));
    }
}

ayDefProcess(Drift) {
    ayLocalPort(Turn);
    ayWriteFloatPort(Turn, 0.2);
}

ayDefBehaviorClass(Avoid) {
    ayINTERFACE {
        ayFloatPort(Range, 10);
        ayFloatPort(Turn, 0);
    }
    ayPROCESSES {
        ayInitTriggeredProcess(React, Range);
    }
}

ayDefProcess(React) {
    ayLocalPort(Range, Turn);
    if (ayPortFresh(Range) && ayReadFloatPort(Range) < 0.5) {
        ayWriteFloatPort(Turn, 1.0); /* hard turn away from the obstacle */
    }
}

ayDefBehaviorClass(Motor) {
    ayINTERFACE {
        ayFloatPort(Turn, 0);
    }
    ayPROCESSES {
    }
}

int main(void) {
    ay_clock *clock = NULL;
    ay_node *node = NULL;
    double turn[41];
    int tenth;
    if (ay_clock_new(&clock) != AY_OK || ay_node_open_manual(1, "mem://tutorial-02", clock, &node) != AY_OK) {
        fprintf(stderr, "cannot open the node: %s\n", ay_last_error());
        return 1;
    }
    ay_set_default_node(node);
    ayInitBehavior(Wander, WANDER);
    ayInitBehavior(Avoid, AVOID);
    ayInitBehavior(Motor, MOTOR);
    ayConnect(WANDER, Turn, MOTOR, Turn);                      /* the lower layer drives... */
    ayOverrideIn(AVOID, Turn, MOTOR, Turn, seconds(0.5));      /* ...the higher one subsumes it */

    for (tenth = 0; tenth <= 40; tenth++) {
        if (tenth >= 10 && tenth < 20) {
            ayWriteFloatPortOf(AVOID, Range, 0.3); /* an obstacle from 1 s to 2 s */
        }
        ayStep();
        turn[tenth] = ayReadFloatPortOf(MOTOR, Turn);
        if (tenth % 5 == 0) {
            printf("%.1f s  MOTOR.Turn = %g\n", tenth / 10.0, turn[tenth]);
        }
        ay_clock_advance(clock, 0.1);
    }
    EXPECT(turn[5] == 0.2);  /* Wander drives the motor before the obstacle */
    EXPECT(turn[15] == 1.0); /* Avoid has taken the motor over */
    EXPECT(turn[22] == 1.0); /* Avoid's last command still holds: its window lasts 0.5 s */
    EXPECT(turn[30] == 0.2); /* Wander has the motor back */

    ay_set_default_node(NULL);
    ay_node_free(node);
    ay_clock_free(clock);
    return 0;
}
