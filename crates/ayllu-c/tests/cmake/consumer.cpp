// A C++17 program using the installed headers (<ayllu.h>, as the paper includes them) and
// library: a relay on mem://, one write through a connection. Exits 0 if the value arrived.
#include <ayllu.h>

#include <cstdio>

ayDefBehaviorClass(Relay) {
    ayINTERFACE {
        ayIntPort(V, 0);
    }
}

int main() {
    ayInitIPCommsAs(1, "mem://consumer");
    ayInitBehavior(Relay, A);
    ayInitBehavior(Relay, B);
    ayConnect(A, V, B, V);
    ayWriteIntPortOf(A, V, 42);
    const long long got = static_cast<long long>(ayReadIntPortOf(B, V));
    ayShutdown();
    std::printf("consumer: B.V = %lld (want 42)\n", got);
    return got == 42 ? 0 : 1;
}
