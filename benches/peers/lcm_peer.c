/* The LCM peer of `make bench-peers`: LCM's C library (liblcm, udpm:// multicast with ttl=0,
 * inside the harness's own network namespace). pong echoes channel PING to PONG; ping times
 * round trips; send publishes FLOW for a time; recv counts it. */
#include <lcm/lcm.h>

#include "peer_common.h"

static lcm_t *lc;
static uint64_t got_seq, count;
static void echo(const lcm_recv_buf_t *rbuf, const char *channel, void *user) {
    (void)channel;
    (void)user;
    lcm_publish(lc, "PONG", rbuf->data, rbuf->data_size);
    count++;
}
static void pong(const lcm_recv_buf_t *rbuf, const char *channel, void *user) {
    (void)channel;
    (void)user;
    if (rbuf->data_size >= 8) memcpy(&got_seq, rbuf->data, 8);
}
static void flow(const lcm_recv_buf_t *rbuf, const char *channel, void *user) {
    (void)rbuf;
    (void)channel;
    (void)user;
    count++;
}

int main(int argc, char **argv) {
    struct peer_args a = peer_args(argc, argv, "lcm_peer");
    lc = lcm_create(a.endpoint);
    if (!lc) {
        fprintf(stderr, "lcm_peer: lcm_create(%s) failed\n", a.endpoint);
        return 1;
    }
    char *buf = calloc(1, a.size);
    if (!strcmp(a.mode, "pong")) {
        lcm_subscribe(lc, "PING", echo, NULL);
        while (count < (uint64_t)a.amount && lcm_handle_timeout(lc, 5000) > 0) {}
    } else if (!strcmp(a.mode, "ping")) {
        lcm_subscribe(lc, "PONG", pong, NULL);
        size_t rounds = (size_t)a.amount, n = 0;
        uint64_t *ns = calloc(rounds, sizeof *ns), seq = 0, give_up = now_ns() + 120000000000ull;
        while (n < rounds && now_ns() < give_up) {
            seq++;
            memcpy(buf, &seq, 8);
            uint64_t t0 = now_ns();
            lcm_publish(lc, "PING", buf, (unsigned)a.size);
            /* A lost ping (the pong not subscribed yet) is sent again as the next round. */
            while (got_seq != seq && lcm_handle_timeout(lc, 200) > 0) {}
            if (got_seq == seq) ns[n++] = now_ns() - t0;
        }
        print_rtt(ns, n);
    } else if (!strcmp(a.mode, "send")) {
        uint64_t sent = 0, end = now_ns() + (uint64_t)(a.amount * 1e9);
        while (now_ns() < end)
            for (int i = 0; i < 64; i++)
                if (lcm_publish(lc, "FLOW", buf, (unsigned)a.size) == 0) sent++;
        printf("flow sent=%llu\n", (unsigned long long)sent);
    } else if (!strcmp(a.mode, "recv")) {
        lcm_subscribe(lc, "FLOW", flow, NULL);
        printf("ready\n");
        fflush(stdout);
        uint64_t first = 0, last = 0;
        while (lcm_handle_timeout(lc, count == 0 ? 30000 : 300) > 0) {
            last = now_ns();
            if (!first) first = last;
        }
        printf("flow received=%llu secs=%.6f\n", (unsigned long long)count, first ? (last - first) / 1e9 : 0.0);
    }
    lcm_destroy(lc);
    free(buf);
    return 0;
}
