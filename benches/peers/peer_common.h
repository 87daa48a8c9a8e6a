/* What the C peers of `make bench-peers` share (benches/peers/run): arguments, clock and the
 * output lines every peer prints (`rtt_ns N N ...`, `flow sent=N`, `flow received=N secs=S`). */
#ifndef PEER_COMMON_H
#define PEER_COMMON_H
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static inline uint64_t now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000000000u + (uint64_t)t.tv_nsec;
}

static inline void print_rtt(const uint64_t *ns, size_t n) {
    printf("rtt_ns");
    for (size_t i = 0; i < n; i++) printf(" %llu", (unsigned long long)ns[i]);
    printf("\n");
    fflush(stdout);
}

struct peer_args {
    const char *mode, *endpoint;
    size_t size;
    double amount;
};

static inline struct peer_args peer_args(int argc, char **argv, const char *name) {
    if (argc < 5) {
        fprintf(stderr, "usage: %s ping|pong|send|recv ENDPOINT PAYLOAD_BYTES COUNT_OR_SECONDS\n", name);
        exit(2);
    }
    struct peer_args a = {argv[1], argv[2], (size_t)atol(argv[3]), atof(argv[4])};
    if (a.size < 8) a.size = 8;
    return a;
}
#endif
