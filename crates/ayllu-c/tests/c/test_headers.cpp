// test_headers.cpp -- ayllu.h and ayllustd.h compile as C++17 (-Wall -Wextra -Werror
// -pedantic) and the macros work from C++: a class, a process, a connection, a run.
#include <cstdio>
#include <cstring>

#include "ayllustd.h"

ayDefBehaviorClass(Doubler) {
    ayINTERFACE {
        ayIntPort(In, 0);
        ayIntPort(Out, 0);
        ayFloatPortLifespan(Seen, 0, seconds(0.5));
    }
    ayPROCESSES {
        ayInitTriggeredProcess(Double, In);
    }
}

ayDefProcess(Double) {
    ayLocalPort(In, Out);
    ayWriteIntPort(Out, 2 * ayReadIntPort(In));
}

int main() {
    ay_clock *clock = nullptr;
    ay_node *node = nullptr;
    int failures = 0;
    if (ay_clock_new(&clock) != AY_OK || ay_node_open_manual(1, "mem://cpp", clock, &node) != AY_OK) {
        std::fprintf(stderr, "test_headers_cpp: %s\n", ay_last_error());
        return 1;
    }
    ay_set_default_node(node);
    ayInitBehavior(Doubler, D1);
    ayInitBehavior(Doubler, D2);
    ayConnect(D1, Out, D2, In);
    ayWriteIntPortOf(D1, In, 5);
    ayStep();
    ayStep();
    if (ayReadIntPortOf(D2, Out) != 20) {
        std::fprintf(stderr, "test_headers_cpp: D2.Out is %lld, want 20\n", static_cast<long long>(ayReadIntPortOf(D2, Out)));
        failures++;
    }
    char *why = ayWhy(D2, In);
    if (why == nullptr || std::strstr(why, "\"In\"") == nullptr) {
        failures++;
    }
    ayFreeReport(why);
    ay_node_free(node);
    ay_clock_free(clock);
    std::printf("test_headers_cpp: %s\n", failures ? "FAILED" : "C++17 compile and run ok");
    return failures ? 1 : 0;
}
