/*
 * ayllu_lite.h -- AylluLite for C: a client of the Ayllu wire protocol, version 1.
 *
 * What it is for: letting a program that is not an Ayllu node -- a microcontroller driving a
 * motor, a sensor board, a C process -- take part in an Ayllu team (Werger, *Ayllu*, section 3,
 * "AylluLite"): expose ports that Ayllu nodes write, write Ayllu nodes' ports with any
 * connection kind, and ask nodes to connect, read, explain (WHY) and list.
 *
 * What it promises:
 *  - Bytes on the wire follow spec/protocol.md exactly. The decoder drops what the spec drops,
 *    with the spec's cause (ayl_cause_name gives the spec's name); the encoder refuses what a
 *    decoder would drop, so nothing this library sends is malformed.
 *  - C99, no malloc, no global mutable state, no clock and no sockets: every buffer is the
 *    caller's, time is passed in (monotonic nanoseconds), and datagrams leave and arrive through
 *    caller-supplied functions. It fits a microcontroller; examples/udp_client.c shows POSIX.
 *  - Decoding is zero-copy: decoded strings and values point into the datagram buffer, which
 *    must outlive them. The node copies what it keeps (port values, request results).
 *  - Lite ports are plain registers (Normal ports): no aggregation, no priority, no outgoing
 *    connections. Windows that decide *storing* follow docs/semantics.md S6: a suppress window
 *    blocks every connection write; open override-in windows admit only their holders.
 *    Suppress, inhibit and write-inhibit messages never write the value; inhibit, override-out
 *    and write-inhibit windows only stop propagation, which lite ports never do.
 *  - With a team key every datagram sent is authenticated and every datagram received must
 *    carry a valid MAC and a sequence number not seen before (64-wide window per sender).
 *  - Return routability (spec, "CHALLENGE and ECHO"): every CHALLENGE received is answered at
 *    once, through the caller's send function, with an ECHO of its cookie to the address it
 *    came from; the requests waiting on that address are then sent again (once each), so a
 *    node that limits what it sends to unproven addresses answers them in full. Retries go on
 *    as before. The lite node's own answers (READ, LIST, error replies) are single datagrams,
 *    held to the spec's 3x rule: the bytes answered to an address are at most 3 times the bytes
 *    received from it (ayl_budget; AYL_BUDGETS addresses remembered). It sends no CHALLENGE, so
 *    an answer over the budget is not sent (counted AYL_AMPLIFICATION_LIMITED) and goes out at
 *    a later retry of the request instead, once the retries have brought the budget up to it.
 *  - Operator signatures are carried (decoded, encoded) but not made here: there is no Ed25519
 *    in this library. Give the node a signer (ayl_node_config.sign, e.g. Monocypher's) and it
 *    signs every CONNECT and DISCONNECT it sends; without one they go unsigned, and a node that
 *    requires an operator key refuses them.
 *
 * Thread-safety, in general: codec functions (ayl_decode, ayl_next, ayl_writer_*, ayl_value_*,
 * ayl_replay_accept, ayl_cause_name, ayl_utf8_valid) touch only their arguments and are
 * reentrant. Every ayl_node_* and ayl_conn_* function mutates the node and is NOT thread-safe:
 * serialise all calls on one node (one task, or a lock of yours). Different nodes are
 * independent. Callbacks run inside ayl_node_poll/ayl_node_receive, on the caller's thread,
 * and must not call ayl_node_* on the same node.
 */
#ifndef AYLLU_LITE_H
#define AYLLU_LITE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ----- protocol constants (spec/protocol.md) ------------------------------------------------ */

#define AYL_VERSION 1
#define AYL_FLAG_AUTH 0x01u
#define AYL_HEADER_LEN 20
#define AYL_MAC_LEN 16
#define AYL_KEY_LEN 32
#define AYL_MAX_DATAGRAM 8192 /* largest datagram a receiver accepts */
#define AYL_MTU 1472          /* default largest datagram a sender sends */
#define AYL_MAX_PARTS 64
#define AYL_RETRY_INTERVAL_NS 200000000ull /* requests are sent again every 200 ms ... */
#define AYL_RETRY_LIMIT 25                 /* ... up to 25 sends (N2) */
/* The longest HELLO period a peer is believed (ms), as the Rust node's: a forged HELLO
 * announcing 0xFFFFFFFF ms would otherwise keep its address greeted for months. */
#define AYL_MAX_PEER_INTERVAL_MS 60000u

/* Message kinds. */
#define AYL_KIND_PORT 0x01
#define AYL_KIND_HELLO 0x02
#define AYL_KIND_REQUEST 0x10
#define AYL_KIND_REPLY 0x11
#define AYL_KIND_CHALLENGE 0x12 /* "echo this cookie" (return routability) */
#define AYL_KIND_ECHO 0x13      /* a CHALLENGE's cookie sent back */

#define AYL_COOKIE_LEN 16    /* bytes of a CHALLENGE / ECHO cookie */
#define AYL_SIGNATURE_LEN 64 /* bytes of an operator signature (Ed25519) */
#define AYL_SIGNATURE_TAG 1  /* the byte before a signature, after a REQUEST's arguments */

/* Request operations. Other codes decode (and are answered "unknown operation"). */
#define AYL_OP_CONNECT 1
#define AYL_OP_DISCONNECT 2
#define AYL_OP_LIST 3
#define AYL_OP_WHY 4
#define AYL_OP_READ 5

/* ----- compile-time sizes (override with -D) ------------------------------------------------ */

#ifndef AYL_ADDR_SIZE
#define AYL_ADDR_SIZE 28 /* room for a struct sockaddr_in6; a radio may need 2 */
#endif
#ifndef AYL_PORT_WINDOWS
#define AYL_PORT_WINDOWS 4 /* open suppress/override-in windows remembered per lite port */
#endif
#ifndef AYL_REQUEST_MAX
#define AYL_REQUEST_MAX 600 /* largest encoded REQUEST message kept for retries */
#endif
#ifndef AYL_BUDGETS
/* Addresses whose answer budget (return routability, ayl_budget) the node remembers: the
 * addresses that ask it things at about the same time. Each entry is 56 bytes with the default
 * AYL_ADDR_SIZE, held in ayl_node (8 of them: 448 of its 968 bytes on x86-64). When all are in
 * use the least recently heard address is replaced; that never lets more than 3x out (the
 * replaced address starts again from nothing), but a flood from more addresses than this can
 * cost a real requester its saved budget, so its larger answers then need more retries. At
 * least 1. */
#define AYL_BUDGETS 8
#endif
#if AYL_BUDGETS < 1
#error "AYL_BUDGETS must be at least 1"
#endif
#define AYL_AMPLIFICATION_FACTOR 3 /* answers to an address: at most 3x the bytes heard from it */

/* ----- results ------------------------------------------------------------------------------ */

/* Why a datagram or message was not applied (N4). AYL_OK is 0. Names: ayl_cause_name. */
typedef enum {
    AYL_OK = 0,
    AYL_OVERSIZED,
    AYL_TRUNCATED,
    AYL_BAD_MAGIC,
    AYL_BAD_VERSION,
    AYL_BAD_FLAGS,
    AYL_WRONG_TEAM,
    AYL_UNAUTHENTICATED,
    AYL_UNEXPECTED_AUTH,
    AYL_BAD_MAC,
    AYL_REPLAYED,
    AYL_MALFORMED,
    AYL_UNKNOWN_KIND,
    /* messages that decode but cannot be applied by a lite node */
    AYL_STALE,
    AYL_TYPE_MISMATCH,
    AYL_UNKNOWN_BEHAVIOR,
    AYL_UNKNOWN_PORT,
    AYL_SUPPRESSED,
    AYL_OVERRIDDEN_IN,
    AYL_TOO_LARGE, /* lite only: a value longer than the port's caller-supplied storage */
    AYL_NOT_MEMBER, /* a PORT sent to a group not in cfg.groups (appended: values above stay) */
    /* an answer (REPLY) not sent: it would have taken the bytes sent to the requester's address
     * above 3x the bytes received from it (return routability; the Rust node's counter of the
     * same name). Counts answers, not datagrams received. */
    AYL_AMPLIFICATION_LIMITED,
    AYL_CAUSE_COUNT
} ayl_cause;

/* The spec's name of a cause ("bad_mac"); "ok" for AYL_OK. Reentrant. */
const char *ayl_cause_name(ayl_cause cause);

/* Errors of encoding and of node calls: always negative, so lengths and indexes can share
 * the return value. */
typedef enum {
    AYL_E_NOSPACE = -1, /* a caller buffer or table is full, or a datagram would exceed its limit */
    AYL_E_INVALID = -2, /* a field a decoder would drop (empty name, period rule, bad UTF-8, ...) */
    AYL_E_NOTFOUND = -3, /* no such port, peer or request */
    AYL_E_SEND = -4,     /* the send function failed */
    AYL_E_EXISTS = -5    /* the port is already exposed */
} ayl_error;

/* ----- values -------------------------------------------------------------------------------- */

typedef struct {
    const char *ptr; /* not NUL-terminated when decoded */
    size_t len;
} ayl_str;

typedef enum { AYL_BOOL = 0, AYL_INT = 1, AYL_FLOAT = 2, AYL_TEXT = 3, AYL_BYTES = 4, AYL_VECTOR = 5 } ayl_type;

/* A port value (rule S1). Floats are kept as their IEEE 754 bits so NaN payloads survive
 * every path, including x87 FPUs that quiet signalling NaNs on load. A vector's elements are
 * either little-endian binary64 bytes (`le`, what decoding gives) or native doubles (`d`, what
 * a program usually has); exactly one is non-NULL (both NULL only when n is 0). */
typedef struct {
    ayl_type type;
    union {
        int b; /* 0 or 1 */
        int64_t i;
        uint64_t f64_bits;
        struct {
            const uint8_t *ptr;
            size_t len;
        } data; /* AYL_TEXT (UTF-8) and AYL_BYTES */
        struct {
            const uint8_t *le;
            const double *d;
            size_t n;
        } vec;
    } u;
} ayl_value;

/* Constructors and accessors. Reentrant. ayl_text takes a NUL-terminated string. */
ayl_value ayl_bool(int b);
ayl_value ayl_int(int64_t i);
ayl_value ayl_float(double f);
ayl_value ayl_text(const char *s);
ayl_value ayl_text_n(const char *s, size_t len);
ayl_value ayl_bytes(const void *p, size_t len);
ayl_value ayl_vector(const double *d, size_t n);
double ayl_value_float(const ayl_value *v); /* AYL_FLOAT only */
double ayl_value_vector_at(const ayl_value *v, size_t i);
/* Same type and same contents (floats compared by bits, vectors element by element). */
int ayl_value_equal(const ayl_value *a, const ayl_value *b);
/* Strict UTF-8 (RFC 3629: no overlongs, no surrogates, at most U+10FFFF). */
int ayl_utf8_valid(const uint8_t *p, size_t len);
/* A string from a NUL-terminated C string (NULL gives the empty string). */
ayl_str ayl_s(const char *s);

/* ----- messages ------------------------------------------------------------------------------ */

typedef enum {
    AYL_NORMAL = 0,
    AYL_SUPPRESS = 1,
    AYL_INHIBIT = 2,
    AYL_OVERRIDE_IN = 3,
    AYL_OVERRIDE_OUT = 4,
    AYL_WRITE_INHIBIT = 5
} ayl_conn_kind;

typedef struct {
    uint64_t conn;
    uint64_t seq;
    ayl_conn_kind kind;
    uint64_t period_ns; /* 0 for AYL_NORMAL and only for it */
    int32_t priority;
    ayl_str behavior; /* non-empty */
    ayl_str port;     /* non-empty */
    ayl_value value;
    /* The group the message was sent to (the optional field appended to PORT), or empty for a
     * message to a node. A node whose cfg.groups does not list it drops the message
     * (AYL_NOT_MEMBER, docs/semantics.md D-S10.6). Zero-initialised: node-addressed. */
    ayl_str group;
} ayl_port_msg;

/* HELLO, with the broadcast groups the sender has joined (a node without broadcast delivers a
 * group's messages by unicast to the members it learnt this way). */
typedef struct {
    uint32_t interval_ms; /* > 0 */
    ayl_str name;
    size_t ngroups;             /* at most 255 */
    const ayl_str *groups;      /* for encoding: ngroups non-empty names */
    const uint8_t *groups_wire; /* when decoded: the names as on the wire (groups is NULL) */
} ayl_hello_msg;

/* Group i of a HELLO, decoded or built: 1 and *out filled, or 0 if i >= ngroups. Reentrant. */
int ayl_hello_group(const ayl_hello_msg *h, size_t i, ayl_str *out);

typedef struct {
    int is_group; /* 0: node endpoint, 1: group endpoint */
    uint32_t node;
    ayl_str group; /* non-empty when is_group */
    ayl_str behavior;
    ayl_str port;
} ayl_endpoint;

/* A REQUEST; which fields count depends on `op` (see spec/protocol.md). A request of a known
 * operation may carry the operator's signature after its arguments (spec, "Operator
 * signature"): has_signature != 0 and the 64 bytes, copied in when decoded, sent when encoded.
 * This library does not make or check signatures (no Ed25519 here); it carries them. */
typedef struct {
    uint64_t id;
    uint8_t op;
    /* CONNECT */
    ayl_str src_behavior;
    ayl_str src_port;
    ayl_endpoint dest;
    ayl_conn_kind kind;
    uint64_t period_ns;
    int32_t priority;
    /* DISCONNECT */
    uint64_t conn;
    /* WHY, READ */
    ayl_str behavior;
    ayl_str port;
    /* any known operation */
    int has_signature;
    uint8_t signature[AYL_SIGNATURE_LEN];
} ayl_request_msg;

typedef enum { AYL_RESULT_ERROR = 0, AYL_RESULT_CONNECTION = 1, AYL_RESULT_VALUE = 2, AYL_RESULT_REPORT = 3 } ayl_result;

typedef struct {
    uint64_t id;
    uint16_t part;
    uint16_t parts;
    ayl_result result; /* AYL_RESULT_ERROR: status 1 */
    ayl_str text;      /* the error message, or the report slice */
    uint64_t conn;     /* AYL_RESULT_CONNECTION */
    ayl_value value;   /* AYL_RESULT_VALUE */
} ayl_reply_msg;

/* CHALLENGE and ECHO: a 16-byte cookie, opaque to everyone but the node that made it. A node
 * sends CHALLENGE instead of an answer too large for an address it has not proven, and with the
 * HELLO that greets a new peer; the lite node answers each with an ECHO of the same cookie. */
typedef struct {
    uint8_t cookie[AYL_COOKIE_LEN];
} ayl_cookie_msg;

/* One message. `kind` is the wire kind byte; for kinds other than the six above the message
 * was skipped and only u.unknown is meaningful. CHALLENGE and ECHO use u.cookie. */
typedef struct {
    uint8_t kind;
    union {
        ayl_port_msg port;
        ayl_hello_msg hello;
        ayl_request_msg request;
        ayl_reply_msg reply;
        ayl_cookie_msg cookie;
        struct {
            uint8_t code;
            uint16_t length;
        } unknown;
    } u;
} ayl_msg;

/* 1 if this library knows the kind (it is decoded rather than skipped). Reentrant. */
int ayl_kind_known(uint8_t kind);

/* ----- decoding ------------------------------------------------------------------------------ */

/* A verified datagram, ready to iterate. Points into the caller's buffer. */
typedef struct {
    uint32_t team;
    uint32_t sender;
    uint64_t seq;
    int auth;
    const uint8_t *buf;
    size_t pos; /* next message */
    size_t end; /* end of the messages (start of the MAC) */
} ayl_datagram;

/* Check a whole datagram for a receiver of `team` holding `key` (32 bytes) or open (NULL):
 * header, team, MAC, and every message (so a datagram is applied whole or not at all). On
 * AYL_OK, `d` is ready for ayl_next. Replay protection needs state: see ayl_replay_accept.
 * Reentrant. */
ayl_cause ayl_decode(ayl_datagram *d, const uint8_t *buf, size_t len, uint32_t team, const uint8_t *key);

/* The next message of a datagram ayl_decode accepted: 1 and *out filled, or 0 at the end.
 * Unknown kinds come out with their code and length (count them as unknown_kind). Reentrant. */
int ayl_next(ayl_datagram *d, ayl_msg *out);

/* One sender's replay window (N5): the newest accepted sequence number and a bitmap of the
 * 64 before it. Zero-initialise it. */
typedef struct {
    uint64_t newest;
    uint64_t bits;
    int any;
} ayl_replay_window;

/* Record `seq` and return 1, or return 0 for a replay or a number older than the window.
 * Call only after the MAC was verified, so forged datagrams cannot move the window.
 * Reentrant (per window). */
int ayl_replay_accept(ayl_replay_window *w, uint64_t seq);

/* ----- encoding ------------------------------------------------------------------------------ */

/* Builds one datagram in a caller buffer. */
typedef struct {
    uint8_t *buf;
    size_t cap; /* bytes the datagram may use (buffer size, or less for the MTU) */
    size_t len;
    int auth;
} ayl_writer;

/* Start a datagram: header with team, sender, sequence, and AUTH when auth != 0. Returns 0
 * or AYL_E_NOSPACE. Reentrant. */
int ayl_writer_begin(ayl_writer *w, uint8_t *buf, size_t cap, uint32_t team, uint32_t sender, uint64_t seq,
                     int auth);

/* Append one message. Returns 0, AYL_E_INVALID (a field a decoder would drop; kinds this
 * library does not know are refused too) or AYL_E_NOSPACE (nothing was appended: flush and
 * start another datagram). Room for the MAC is kept when auth. Reentrant. */
int ayl_writer_add(ayl_writer *w, const ayl_msg *m);

/* Finish: append the MAC under `key` if the writer was begun with auth (key must then be
 * non-NULL). Returns the datagram length or a negative ayl_error. Reentrant. */
int ayl_writer_finish(ayl_writer *w, const uint8_t *key);

/* ----- the lite node ------------------------------------------------------------------------- */

/* A transport address, opaque to the library (a sockaddr, a radio id ...): the node only
 * stores it and hands it back to the send function. len 0 means "no address". */
typedef struct {
    uint8_t len;
    uint8_t bytes[AYL_ADDR_SIZE];
} ayl_addr;

/* Send `len` bytes to `to`. Return 0 on success, negative on failure (counted, not retried:
 * port values are best effort, requests retry on their own schedule). */
typedef int (*ayl_send_fn)(void *io_user, const ayl_addr *to, const uint8_t *data, size_t len);
/* Receive one waiting datagram without blocking: return its length (the true length even if
 * it did not fit in `cap`, so it is counted as oversized), 0 when none is waiting, negative on
 * error. Fill *from with the sender's address. */
typedef int (*ayl_recv_fn)(void *io_user, ayl_addr *from, uint8_t *buf, size_t cap);

/* Sign `len` bytes with the operator's secret key: Ed25519 (RFC 8032), the 64-byte signature
 * into `sig`. Return 0, or negative if it cannot sign (the request is then refused). This
 * library has no Ed25519: bring one (Monocypher, libsodium, TweetNaCl, a secure element). */
typedef int (*ayl_sign_fn)(void *sign_user, const uint8_t *data, size_t len, uint8_t sig[AYL_SIGNATURE_LEN]);

/* Called after a PORT message stored a value in an exposed port. `value` points into the
 * port's storage and is valid until the port is written again. */
typedef void (*ayl_write_fn)(void *user, const char *behavior, const char *port, const ayl_value *value,
                             uint32_t sender, uint64_t conn);

/* A window on a lite port (kind AYL_SUPPRESS or AYL_OVERRIDE_IN), held by (node, conn). */
typedef struct {
    uint8_t kind; /* 0: slot free */
    uint32_t holder_node;
    uint64_t holder_conn;
    uint64_t end_ns;
} ayl_window;

/* An exposed port. Zero-initialise an array of them and give it to the node; fill with
 * ayl_node_expose. */
typedef struct {
    const char *behavior; /* NUL-terminated, must outlive the node */
    const char *port;
    ayl_value value;
    uint8_t *storage; /* caller bytes for text, bytes and vector values */
    size_t storage_cap;
    uint64_t writes;
    ayl_window windows[AYL_PORT_WINDOWS];
    ayl_write_fn on_write;
    void *user;
} ayl_port;

/* A peer: configured (static) or heard from. Zero-initialise an array of them. Size the table
 * for the whole team: when it is full, the least recently heard unconfigured peer is replaced,
 * and with it goes its replay window, so its recent datagrams could be replayed once. */
typedef struct {
    uint8_t used;
    uint8_t is_static;   /* configured with ayl_node_add_peer: never forgotten */
    uint32_t node;
    ayl_addr addr;
    uint64_t last_heard_ns;
    uint32_t interval_ms; /* its HELLO interval (1000 until it says) */
    ayl_replay_window replay;
} ayl_peer;

/* What the node may still answer one address (spec, "CHALLENGE and ECHO": the 3x rule). A lite
 * node sends no CHALLENGE and checks no ECHO, so no address is ever proven to it: every REPLY it
 * sends is charged here, and one that would take `answered` above AYL_AMPLIFICATION_FACTOR x
 * `received` is not sent (counted AYL_AMPLIFICATION_LIMITED). A requester's retries add to
 * `received`, so an answer larger than 3x one request goes out at a later retry. Held in
 * ayl_node (AYL_BUDGETS entries); nothing for the caller to provide. */
typedef struct {
    uint8_t used;
    ayl_addr addr;
    uint64_t received; /* bytes of datagrams accepted from addr since this entry was made */
    uint64_t answered; /* bytes of REPLY datagrams sent to addr since */
    uint64_t heard;    /* when last heard, in datagrams accepted by the node (for replacement) */
} ayl_budget;

/* Newest sequence number applied per (sender, connection), for stale drops (N1). */
typedef struct {
    uint8_t used;
    uint32_t sender;
    uint64_t conn;
    uint64_t newest;
    uint64_t touched_ns;
} ayl_seq_entry;

typedef enum { AYL_REQ_FREE = 0, AYL_REQ_PENDING, AYL_REQ_DONE, AYL_REQ_FAILED } ayl_req_state;

/* A request in flight, with where its answer goes. Zero-initialise an array of them. */
typedef struct {
    ayl_req_state state;
    uint64_t id;
    ayl_addr to;
    uint32_t sends;
    uint64_t next_send_ns;
    uint16_t msg_len;
    uint8_t msg[AYL_REQUEST_MAX]; /* the encoded REQUEST, re-sent with a new datagram seq */
    uint8_t *out;                 /* caller bytes for the report, error text or text value */
    size_t out_cap;
    size_t out_len;
    uint16_t parts;
    uint64_t parts_seen;       /* bit i: part i arrived */
    uint16_t part_len[AYL_MAX_PARTS];
    int out_overflow;          /* the answer did not fit in out */
    int hurried;               /* sent again at once after an ECHO (once per request) */
    ayl_reply_msg answer;      /* valid in AYL_REQ_DONE; its text/value point into out */
} ayl_pending;

/* Everything a node needs, all owned by the caller. Arrays must be zero-initialised. */
typedef struct {
    uint32_t node_id;
    uint32_t team;
    const uint8_t *key;  /* 32 bytes (copied), or NULL for an open team */
    /* boot_seconds << 32, or anything above the last run's numbers; the fraction of the
     * second in the low 32 bits lets a restart within the same second start higher. Datagram
     * sequence numbers, request ids and connection sequence numbers all start here, because
     * receivers remember all three across a restart (replay window, answered requests, stale
     * drops). */
    uint64_t seq_start;
    ayl_send_fn send;
    ayl_recv_fn recv;    /* may be NULL if you feed datagrams with ayl_node_receive */
    void *io_user;
    ayl_port *ports;
    size_t max_ports;
    ayl_peer *peers;
    size_t max_peers;
    ayl_seq_entry *seqs;
    size_t max_seqs;
    ayl_pending *pending;
    size_t max_pending;
    uint8_t *rx;         /* receive buffer: AYL_MAX_DATAGRAM bytes accepts everything */
    size_t rx_cap;
    uint8_t *tx;         /* send buffer: AYL_MTU bytes is the default path MTU */
    size_t tx_cap;
    const char *name;    /* for HELLO; NULL: empty */
    const ayl_str *groups; /* joined: announced in HELLO so nodes send group traffic here, and
                            * the only groups whose PORT messages are applied; may be NULL */
    size_t ngroups;
    uint32_t hello_interval_ms; /* 0: 1000 */
    const ayl_addr *broadcast;  /* also receives HELLO; NULL: none */
    /* The operator's signer, or NULL. With it, CONNECT and DISCONNECT requests are signed (spec,
     * "Operator signature"), as nodes given the operator's public key require; without it they
     * go unsigned, and such nodes refuse them. */
    ayl_sign_fn sign;
    void *sign_user;
} ayl_node_config;

typedef struct {
    ayl_node_config cfg;
    uint8_t key[AYL_KEY_LEN];
    int keyed;
    ayl_addr broadcast;
    int has_broadcast;
    uint64_t seq;       /* last datagram sequence number sent */
    uint64_t next_id;   /* next request id */
    uint64_t next_conn; /* next connection id */
    uint64_t next_hello_ns;
    uint64_t now_ns;    /* latest time seen; time never goes backwards (S8) */
    uint64_t counters[AYL_CAUSE_COUNT]; /* drops by cause; [AYL_OK] counts datagrams applied */
    uint64_t sent;
    uint64_t send_failures;
    uint64_t challenged; /* CHALLENGEs received (each answered with an ECHO) */
    ayl_budget budgets[AYL_BUDGETS]; /* answer budgets by address (see ayl_budget) */
    uint64_t heard;      /* datagrams accepted: the clock of budgets[].heard */
} ayl_node;

/* A connection from this node to a port on another node, with its own id and sequence
 * numbers (N1). Filled by ayl_conn_open. */
typedef struct {
    ayl_addr to;
    const char *behavior;
    const char *port;
    ayl_conn_kind kind;
    uint64_t period_ns;
    int32_t priority;
    uint64_t conn;
    uint64_t seq;
} ayl_conn;

/* Set up a node. Returns 0, or AYL_E_INVALID (node id 0, which is reserved: ids are 1 to
 * 2^32-1; missing send, rx/tx buffers smaller than a header plus MAC, no peer table, or a name
 * or group list HELLO cannot carry). Not
 * thread-safe (writes *node). */
int ayl_node_init(ayl_node *node, const ayl_node_config *cfg);

/* Expose behavior.port with an initial value; the port's type is that value's type (S1).
 * `storage` (may be NULL for bool, int and float) holds text, bytes and vector values, so a
 * port never points into a receive buffer: an initial value that does not fit gives
 * AYL_E_NOSPACE, a received one that does not fit is dropped and counted as too_large.
 * Returns the port's index or a negative ayl_error. Not thread-safe. */
int ayl_node_expose(ayl_node *node, const char *behavior, const char *port, const ayl_value *initial,
                    uint8_t *storage, size_t storage_cap, ayl_write_fn on_write, void *user);

/* The current value of an exposed port, or NULL. Not thread-safe (reads the node). */
const ayl_value *ayl_node_get(const ayl_node *node, const char *behavior, const char *port);

/* Set an exposed port as its own program would (windows do not apply, D6.5). Returns 0,
 * AYL_E_NOTFOUND, AYL_E_INVALID (other type) or AYL_E_NOSPACE. Not thread-safe. */
int ayl_node_set(ayl_node *node, const char *behavior, const char *port, const ayl_value *value);

/* Configure a peer: it receives HELLOs and can be looked up by node id. Not thread-safe. */
int ayl_node_add_peer(ayl_node *node, uint32_t node_id, const ayl_addr *addr);

/* The address of a configured peer or of a node heard from within 3 of its HELLO intervals
 * (N6), or NULL. Not thread-safe. */
const ayl_addr *ayl_node_peer_addr(ayl_node *node, uint32_t node_id);

/* Open a connection to behavior.port at `to` (strings must outlive the connection). Special
 * kinds need period_ns > 0, AYL_NORMAL needs 0. Returns 0 or AYL_E_INVALID. Not thread-safe. */
int ayl_conn_open(ayl_node *node, ayl_conn *c, const ayl_addr *to, const char *behavior, const char *port,
                  ayl_conn_kind kind, uint64_t period_ns, int32_t priority);

/* Send one value along the connection, in its own datagram. Returns 0 or a negative
 * ayl_error. Not thread-safe. */
int ayl_conn_send(ayl_node *node, ayl_conn *c, const ayl_value *value);

/* Send a request to `to` and keep it for retries. Its id is chosen by the node and written
 * to *id. The answer goes to `out` (report text, error text, or a text/bytes/vector value;
 * may be NULL for CONNECT/DISCONNECT). With cfg.sign, a CONNECT or DISCONNECT is signed for
 * the node configured or heard at `to` (a signature in *req is ignored: it must cover the id
 * chosen here). Returns 0 or a negative ayl_error (AYL_E_NOSPACE: no free pending slot, or the
 * request is longer than AYL_REQUEST_MAX; AYL_E_NOTFOUND: a request to sign, and no node known
 * at `to`; AYL_E_INVALID: also when the signer failed). Not thread-safe. */
int ayl_node_request(ayl_node *node, const ayl_addr *to, const ayl_request_msg *req, uint8_t *out, size_t out_cap,
                     uint64_t *id);

/* Where request `id` stands. On AYL_REQ_DONE, *answer (if not NULL) is the whole answer:
 * result AYL_RESULT_REPORT with the reassembled report in `text`, or the single reply; its
 * text and value point into the request's `out`. On AYL_REQ_DONE and AYL_REQ_FAILED the slot is
 * released by this call (a second call says AYL_REQ_FREE). *overflow (if not NULL) is set
 * when the answer did not fit in `out` and was cut. Not thread-safe. */
ayl_req_state ayl_node_request_take(ayl_node *node, uint64_t id, ayl_reply_msg *answer, int *overflow);

/* Give up on a request and free its slot. Not thread-safe. */
void ayl_node_request_cancel(ayl_node *node, uint64_t id);

/* Apply one datagram received from `from` at `now_ns`. Returns what happened to it (AYL_OK:
 * applied; messages inside may still have been dropped and counted). A CHALLENGE inside is
 * answered at once through cfg.send: an ECHO of its cookie to `from`, then the pending
 * requests addressed to `from` (addresses compared byte for byte) are sent again once, so a
 * node limiting amplification answers them in full without waiting for the next retry. A
 * REQUEST inside is answered to `from` if the answer fits in what `from` may still be sent
 * (ayl_budget: 3x the bytes received from it, this datagram included, less those answered);
 * if not, it is counted AYL_AMPLIFICATION_LIMITED and not answered. Not thread-safe. */
ayl_cause ayl_node_receive(ayl_node *node, const uint8_t *data, size_t len, const ayl_addr *from, uint64_t now_ns);

/* Receive and apply every waiting datagram (through cfg.recv), then send HELLO if due and
 * re-send due requests. Returns the number of datagrams handled. Not thread-safe. */
int ayl_node_poll(ayl_node *node, uint64_t now_ns);

/* The earliest time ayl_node_poll has something to send (HELLO or a retry), so a caller can
 * sleep until then or until a datagram arrives. Not thread-safe (reads the node). */
uint64_t ayl_node_next_deadline(const ayl_node *node);

/* Send HELLO now to every configured and known peer and the broadcast address. Not
 * thread-safe. */
int ayl_node_send_hello(ayl_node *node, uint64_t now_ns);

/* ----- configuration: the udp:// URL every Ayllu program reads (ayllu_url.c) ---------------- */

/* The URL's grammar and limits are those of the Rust runtime's parser and of AylluLite
 * Python; spec/vectors/urls.json holds the cases all three must agree on (tests/test_url.c).
 * The library reads no environment, no file and no resolver: a program passes the text of
 * getenv("AYLLU_URL") (or AYL_URL_DEFAULT when it is unset or empty), resolves host names
 * itself, reads the operator secret's file itself, and sizes cfg.tx to the URL's mtu. */

#define AYL_URL_DEFAULT "udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=0"
#define AYL_URL_ENV "AYLLU_URL"
#ifndef AYL_URL_MAX_PEERS
#define AYL_URL_MAX_PEERS 16 /* peer= options kept; more are refused */
#endif
#ifndef AYL_URL_MAX_GROUPS
#define AYL_URL_MAX_GROUPS 8 /* group= options kept; more are refused */
#endif

/* HOST:PORT in a URL. An IPv4 literal (dotted quad, no leading zeros) is decoded into ip4
 * (is_name 0); a host name -- text with a letter -- is left to the caller's resolver (is_name
 * 1, ip4 zero). `host` points into the URL, not NUL-terminated. */
typedef struct {
    ayl_str host;
    int is_name;
    uint8_t ip4[4];
    uint16_t port;
} ayl_url_addr;

typedef struct {
    ayl_str name; /* 1 to 255 bytes, pointing into the URL */
    ayl_url_addr addr;
} ayl_url_group;

/* What a URL says; options it does not give keep their defaults (in brackets). Text fields
 * point into the URL, which must outlive this. */
typedef struct {
    ayl_url_addr bind;
    uint32_t team;               /* team= [0] */
    uint8_t key[AYL_KEY_LEN];    /* key= (64 hex digits) */
    int keyed;                   /* [0]: an open team */
    ayl_url_addr peers[AYL_URL_MAX_PEERS]; /* peer= (repeatable): greeted with HELLO */
    size_t npeers;
    ayl_url_addr broadcast;      /* broadcast= */
    int has_broadcast;
    ayl_url_group groups[AYL_URL_MAX_GROUPS]; /* group=NAME@HOST:PORT (a full node's) */
    size_t ngroups;
    ayl_url_addr discovery;      /* discovery= (multicast, 224.0.0.0/4) */
    int has_discovery;
    uint8_t ttl;                 /* ttl= (0 to 255) [1] */
    uint32_t hello_ms;           /* hello_ms= (1 to 4294967295) [1000] */
    uint32_t mtu;                /* mtu= (64 to AYL_MAX_DATAGRAM) [AYL_MTU]: size cfg.tx to it */
    uint32_t spin_us;            /* spin_us= (0 to 1000) [50]: a full node's; a lite node never polls */
    ayl_str name;                /* name= (at most 255 bytes) [empty]: for HELLO */
    ayl_str state;               /* state= (a path; a full node's): [empty] */
    uint8_t operator_key[AYL_KEY_LEN]; /* operator= (64 hex digits; a full node's: a lite node
                                        * applies no structure change; the form is checked,
                                        * not the Ed25519 point) */
    int has_operator;
    ayl_str operator_secret;     /* operator_secret= (a path: the caller reads the file) */
} ayl_url;

/* Parse `url` (NUL-terminated) into *out. Returns 0, or AYL_E_INVALID with a message naming
 * the bad part in err (NUL-terminated, cut to err_cap; err may be NULL), e.g. "team `+7` is
 * not a u32" or "unknown option `colour`". Reentrant (touches only its arguments). */
int ayl_url_parse(ayl_url *out, const char *url, char *err, size_t err_cap);

#ifdef __cplusplus
}
#endif
#endif
