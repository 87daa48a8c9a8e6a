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

/* The URL every Ayllu program reads (docs/cli.md): the environment variable AYLLU_URL if it
 * is set and not empty, else AYL_URL_DEFAULT, parsed whole by ayl_url_parse -- a malformed or
 * unknown option is refused here as the Rust runtime and AylluLite Python refuse it
 * (spec/vectors/urls.json). The URL's text is copied into `text` (cap bytes), which *url points
 * into and which must outlive it. Returns 0, or -1 with the reason on stderr.
 * Thread-safety: reads the environment; call before starting threads. */
static inline int posix_env_url(ayl_url *url, char *text, size_t cap) {
    const char *env = getenv(AYL_URL_ENV);
    const char *from = AYL_URL_DEFAULT;
    char err[256];
    size_t i = 0;
    if (env != NULL) {
        while (isspace((unsigned char)env[i])) {
            i++;
        }
        if (env[i] != '\0') {
            from = env;
        }
    }
    if (strlen(from) >= cap) {
        fprintf(stderr, "%s: longer than this program's %zu bytes\n", AYL_URL_ENV, cap - 1);
        return -1;
    }
    strcpy(text, from);
    /* Trailing white space (a newline from a file) is not part of the URL, as in Python. */
    for (i = strlen(text); i > 0 && isspace((unsigned char)text[i - 1]); i--) {
        text[i - 1] = '\0';
    }
    if (ayl_url_parse(url, text + strspn(text, " \t\r\n"), err, sizeof err) != 0) {
        fprintf(stderr, "%s: %s\n", from == env ? AYL_URL_ENV : "the default URL", err);
        return -1;
    }
    return 0;
}

#endif
