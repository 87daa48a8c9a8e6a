/* A C99 program built with `pkg-config --cflags --libs ayllu` against an installed
 * libayllu: one write through a connection on mem://. Exits 0 if the value arrived. */
#include <ayllu.h>
#include <stdio.h>

ayDefBehaviorClass(Relay) {
    ayINTERFACE {
        ayIntPort(V, 0);
    }
}

int main(void) {
    int64_t got;
    ayInitIPCommsAs(1, "mem://pkgconfig");
    ayInitBehavior(Relay, A);
    ayInitBehavior(Relay, B);
    ayConnect(A, V, B, V);
    ayWriteIntPortOf(A, V, 7);
    got = ayReadIntPortOf(B, V);
    ayShutdown();
    printf("pkgconfig_consumer: B.V = %lld (want 7)\n", (long long)got);
    return got == 7 ? 0 : 1;
}
