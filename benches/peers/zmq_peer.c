/* The ZeroMQ peer of `make bench-peers`: libzmq over tcp:// (ZeroMQ's patterns have no UDP
 * transport in Debian's build). pong/ping: a PAIR socket each (pong binds); send/recv:
 * PUSH/PULL (recv binds), as ZeroMQ's own local_thr/remote_thr measure throughput. */
#include <zmq.h>

#include "peer_common.h"

int main(int argc, char **argv) {
    struct peer_args a = peer_args(argc, argv, "zmq_peer");
    void *ctx = zmq_ctx_new();
    char *buf = calloc(1, a.size), *in = calloc(1, a.size + 64);
    int listen = !strcmp(a.mode, "pong") || !strcmp(a.mode, "recv");
    int type = !strcmp(a.mode, "send") ? ZMQ_PUSH : !strcmp(a.mode, "recv") ? ZMQ_PULL : ZMQ_PAIR;
    void *s = zmq_socket(ctx, type);
    if ((listen ? zmq_bind(s, a.endpoint) : zmq_connect(s, a.endpoint)) != 0) {
        fprintf(stderr, "zmq_peer: %s %s: %s\n", listen ? "bind" : "connect", a.endpoint, zmq_strerror(zmq_errno()));
        return 1;
    }
    int timeout = 5000;
    zmq_setsockopt(s, ZMQ_RCVTIMEO, &timeout, sizeof timeout);
    if (!strcmp(a.mode, "pong")) {
        for (uint64_t i = 0; i < (uint64_t)a.amount; i++) {
            int n = zmq_recv(s, in, a.size + 64, 0);
            if (n < 0) break;
            zmq_send(s, in, (size_t)n, 0);
        }
    } else if (!strcmp(a.mode, "ping")) {
        size_t rounds = (size_t)a.amount, n = 0;
        uint64_t *ns = calloc(rounds, sizeof *ns);
        for (uint64_t seq = 1; n < rounds; seq++) {
            memcpy(buf, &seq, 8);
            uint64_t t0 = now_ns();
            zmq_send(s, buf, a.size, 0);
            if (zmq_recv(s, in, a.size + 64, 0) < 0) break; /* TCP: nothing is lost */
            ns[n++] = now_ns() - t0;
        }
        print_rtt(ns, n);
    } else if (!strcmp(a.mode, "send")) {
        uint64_t sent = 0, end = now_ns() + (uint64_t)(a.amount * 1e9);
        while (now_ns() < end)
            for (int i = 0; i < 64; i++)
                if (zmq_send(s, buf, a.size, 0) >= 0) sent++;
        printf("flow sent=%llu\n", (unsigned long long)sent);
        int linger = 10000;
        zmq_setsockopt(s, ZMQ_LINGER, &linger, sizeof linger);
    } else if (!strcmp(a.mode, "recv")) {
        printf("ready\n");
        fflush(stdout);
        uint64_t count = 0, first = 0, last = 0;
        timeout = 30000;
        zmq_setsockopt(s, ZMQ_RCVTIMEO, &timeout, sizeof timeout);
        while (zmq_recv(s, in, a.size + 64, 0) >= 0) {
            last = now_ns();
            if (!count++) {
                first = last;
                timeout = 300;
                zmq_setsockopt(s, ZMQ_RCVTIMEO, &timeout, sizeof timeout);
            }
        }
        printf("flow received=%llu secs=%.6f\n", (unsigned long long)count, first ? (last - first) / 1e9 : 0.0);
    }
    zmq_close(s);
    zmq_ctx_term(ctx);
    return 0;
}
