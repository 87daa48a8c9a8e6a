/* posix_udp.h — the AylluLite transport functions for a POSIX UDP socket, shared by the
 * examples. The library itself never touches sockets (caller-owned I/O); a program on a POSIX
 * system can copy these two functions as they are. `io_user` points to the socket's fd.
 * An ayl_addr holds a struct sockaddr_in / sockaddr_in6 as bytes.
 *
 * Thread-safety: as safe as the socket; the functions keep no state of their own. */
#ifndef AYLLU_POSIX_UDP_H
#define AYLLU_POSIX_UDP_H

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

#include "../ayllu_lite.h"

/* ayl_send_fn: send one datagram to `to`. 0 on success, -1 on a socket error. */
static int posix_udp_send(void *io_user, const ayl_addr *to, const uint8_t *data, size_t len) {
    struct sockaddr_storage sa;
    int fd = *(const int *)io_user;
    memset(&sa, 0, sizeof sa);
    memcpy(&sa, to->bytes, to->len);
    return sendto(fd, data, len, 0, (struct sockaddr *)&sa, to->len) < 0 ? -1 : 0;
}

/* ayl_recv_fn: the next waiting datagram's length (0 if none), never blocking. */
static int posix_udp_recv(void *io_user, ayl_addr *from, uint8_t *buf, size_t cap) {
    struct sockaddr_storage sa;
    socklen_t sl = sizeof sa;
    ssize_t n;
    int flags = MSG_DONTWAIT;
    int fd = *(const int *)io_user;
#ifdef MSG_TRUNC
    flags |= MSG_TRUNC; /* Linux: report the true length, so oversized datagrams are counted */
#endif
    n = recvfrom(fd, buf, cap, flags, (struct sockaddr *)&sa, &sl);
    if (n < 0) {
        return (errno == EAGAIN || errno == EWOULDBLOCK) ? 0 : -1;
    }
    if (sl > AYL_ADDR_SIZE) {
        return 0; /* an address family we cannot hold */
    }
    from->len = (uint8_t)sl;
    memcpy(from->bytes, &sa, sl);
    return n == 0 ? 0 : (int)n; /* a zero-length datagram is nothing to apply */
}

/* The team and key that the environment variable AYLLU_URL gives (`team=N`, `key=HEX64` in
 * its query), which every Ayllu program reads the same way (docs/cli.md): `*team` and
 * `*keyed` are left as they are (team 0, no key by default) when the variable or the option is
 * absent. The URL's other options are ignored here: the examples are told their peer on the
 * command line. Returns 0, or -1 with a message on stderr for a malformed team= or key=.
 * Thread-safety: reads the environment; call before starting threads. */
static inline int posix_env_team_key(uint32_t *team, uint8_t key[AYL_KEY_LEN], int *keyed) {
    const char *url = getenv("AYLLU_URL");
    const char *p = url != NULL ? strchr(url, '?') : NULL;
    while (p != NULL && *p != '\0') {
        const char *item = p + 1;
        const char *end = strchr(item, '&');
        size_t len = end != NULL ? (size_t)(end - item) : strlen(item);
        if (len > 5 && strncmp(item, "team=", 5) == 0) {
            unsigned long v = 0;
            size_t i;
            for (i = 5; i < len; i++) {
                if (!isdigit((unsigned char)item[i]) || v > 429496729UL) {
                    fprintf(stderr, "AYLLU_URL: team= must be a number (u32)\n");
                    return -1;
                }
                v = v * 10 + (unsigned long)(item[i] - '0');
            }
            if (v > 4294967295UL) {
                fprintf(stderr, "AYLLU_URL: team= must be a number (u32)\n");
                return -1;
            }
            *team = (uint32_t)v;
        } else if (len >= 4 && strncmp(item, "key=", 4) == 0) {
            size_t i;
            if (len - 4 != 2 * AYL_KEY_LEN) {
                fprintf(stderr, "AYLLU_URL: key= must be 64 hex digits\n");
                return -1;
            }
            for (i = 0; i < AYL_KEY_LEN; i++) {
                char pair[3];
                pair[0] = item[4 + 2 * i];
                pair[1] = item[5 + 2 * i];
                pair[2] = '\0';
                if (!isxdigit((unsigned char)pair[0]) || !isxdigit((unsigned char)pair[1])) {
                    fprintf(stderr, "AYLLU_URL: key= must be 64 hex digits\n");
                    return -1;
                }
                key[i] = (uint8_t)strtoul(pair, NULL, 16);
            }
            *keyed = 1;
        }
        p = end;
    }
    return 0;
}

#endif
