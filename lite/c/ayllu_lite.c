/*
 * ayllu_lite.c -- AylluLite for C (see ayllu_lite.h for what it promises).
 *
 * Layout: values and UTF-8, decoding (a bounds-checked reader with a sticky error), encoding
 * (a bounds-checked writer), then the node. Integers are read and written byte by byte in
 * little-endian order, so the code neither assumes the host's endianness nor makes unaligned
 * loads, which some microcontrollers fault on.
 */
#include "ayllu_lite.h"

#include <string.h>

#include "ayllu_sha256.h"

/* ----- causes -------------------------------------------------------------------------------- */

static const char *const CAUSE_NAMES[AYL_CAUSE_COUNT] = {
    "ok",        "oversized",     "truncated",   "bad_magic",        "bad_version",  "bad_flags",
    "wrong_team", "unauthenticated", "unexpected_auth", "bad_mac",   "replayed",     "malformed",
    "unknown_kind", "stale",      "type_mismatch", "unknown_behavior", "unknown_port", "suppressed",
    "overridden_in", "too_large", "not_member", "amplification_limited",
};

const char *ayl_cause_name(ayl_cause cause) {
    if ((int)cause < 0 || cause >= AYL_CAUSE_COUNT) {
        return "?";
    }
    return CAUSE_NAMES[cause];
}

/* ----- little-endian helpers ----------------------------------------------------------------- */

static uint64_t get_le(const uint8_t *p, int n) {
    uint64_t v = 0;
    int i;
    for (i = n - 1; i >= 0; i--) {
        v = (v << 8) | p[i];
    }
    return v;
}

static void put_le(uint8_t *p, uint64_t v, int n) {
    int i;
    for (i = 0; i < n; i++) {
        p[i] = (uint8_t)(v >> (8 * i));
    }
}

static uint64_t double_bits(double d) {
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    return u;
}

static double bits_double(uint64_t u) {
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

/* ----- values -------------------------------------------------------------------------------- */

ayl_value ayl_bool(int b) {
    ayl_value v;
    memset(&v, 0, sizeof v);
    v.type = AYL_BOOL;
    v.u.b = b ? 1 : 0;
    return v;
}

ayl_value ayl_int(int64_t i) {
    ayl_value v;
    memset(&v, 0, sizeof v);
    v.type = AYL_INT;
    v.u.i = i;
    return v;
}

ayl_value ayl_float(double f) {
    ayl_value v;
    memset(&v, 0, sizeof v);
    v.type = AYL_FLOAT;
    v.u.f64_bits = double_bits(f);
    return v;
}

ayl_value ayl_text_n(const char *s, size_t len) {
    ayl_value v;
    memset(&v, 0, sizeof v);
    v.type = AYL_TEXT;
    v.u.data.ptr = (const uint8_t *)s;
    v.u.data.len = len;
    return v;
}

ayl_value ayl_text(const char *s) { return ayl_text_n(s, s ? strlen(s) : 0); }

ayl_value ayl_bytes(const void *p, size_t len) {
    ayl_value v;
    memset(&v, 0, sizeof v);
    v.type = AYL_BYTES;
    v.u.data.ptr = (const uint8_t *)p;
    v.u.data.len = len;
    return v;
}

ayl_value ayl_vector(const double *d, size_t n) {
    ayl_value v;
    memset(&v, 0, sizeof v);
    v.type = AYL_VECTOR;
    v.u.vec.d = d;
    v.u.vec.n = n;
    return v;
}

double ayl_value_float(const ayl_value *v) { return bits_double(v->u.f64_bits); }

static uint64_t vec_bits(const ayl_value *v, size_t i) {
    if (v->u.vec.le != NULL) {
        return get_le(v->u.vec.le + 8 * i, 8);
    }
    return double_bits(v->u.vec.d[i]);
}

double ayl_value_vector_at(const ayl_value *v, size_t i) { return bits_double(vec_bits(v, i)); }

int ayl_value_equal(const ayl_value *a, const ayl_value *b) {
    size_t i;
    if (a->type != b->type) {
        return 0;
    }
    switch (a->type) {
    case AYL_BOOL:
        return a->u.b == b->u.b;
    case AYL_INT:
        return a->u.i == b->u.i;
    case AYL_FLOAT:
        return a->u.f64_bits == b->u.f64_bits;
    case AYL_TEXT:
    case AYL_BYTES:
        return a->u.data.len == b->u.data.len &&
               (a->u.data.len == 0 || memcmp(a->u.data.ptr, b->u.data.ptr, a->u.data.len) == 0);
    case AYL_VECTOR:
        if (a->u.vec.n != b->u.vec.n) {
            return 0;
        }
        for (i = 0; i < a->u.vec.n; i++) {
            if (vec_bits(a, i) != vec_bits(b, i)) {
                return 0;
            }
        }
        return 1;
    }
    return 0;
}

int ayl_utf8_valid(const uint8_t *p, size_t len) {
    size_t i = 0;
    while (i < len) {
        uint8_t c = p[i];
        size_t n;
        uint32_t cp;
        uint32_t min;
        size_t k;
        if (c < 0x80) {
            i++;
            continue;
        } else if ((c & 0xE0) == 0xC0) {
            n = 1;
            cp = c & 0x1Fu;
            min = 0x80;
        } else if ((c & 0xF0) == 0xE0) {
            n = 2;
            cp = c & 0x0Fu;
            min = 0x800;
        } else if ((c & 0xF8) == 0xF0) {
            n = 3;
            cp = c & 0x07u;
            min = 0x10000;
        } else {
            return 0;
        }
        if (len - i - 1 < n) {
            return 0; /* the sequence is cut off */
        }
        for (k = 1; k <= n; k++) {
            if ((p[i + k] & 0xC0) != 0x80) {
                return 0;
            }
            cp = (cp << 6) | (p[i + k] & 0x3Fu);
        }
        if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) {
            return 0;
        }
        i += n + 1;
    }
    return 1;
}

ayl_str ayl_s(const char *s) {
    ayl_str r;
    r.ptr = s ? s : "";
    r.len = s ? strlen(s) : 0;
    return r;
}

int ayl_hello_group(const ayl_hello_msg *h, size_t i, ayl_str *out) {
    const uint8_t *p = h->groups_wire;
    size_t k;
    if (i >= h->ngroups) {
        return 0;
    }
    if (h->groups != NULL) {
        *out = h->groups[i];
        return 1;
    }
    if (p == NULL) {
        return 0;
    }
    /* Validated by ayl_decode: each name is a length byte then that many bytes. */
    for (k = 0; k < i; k++) {
        p += 1 + p[0];
    }
    out->ptr = (const char *)(p + 1);
    out->len = p[0];
    return 1;
}

int ayl_kind_known(uint8_t kind) {
    return kind == AYL_KIND_PORT || kind == AYL_KIND_HELLO || kind == AYL_KIND_REQUEST || kind == AYL_KIND_REPLY ||
           kind == AYL_KIND_CHALLENGE || kind == AYL_KIND_ECHO;
}

/* ----- decoding ------------------------------------------------------------------------------ */

/* Reads one message body. Any short read or invalid field sets `bad` and later reads return
 * zeros, so a decoder is a straight sequence of reads with one check at the end: a body
 * shorter than its fields is malformed. */
typedef struct {
    const uint8_t *b;
    size_t pos;
    size_t end;
    int bad;
} reader;

static const uint8_t *rd_take(reader *r, size_t n) {
    const uint8_t *p;
    if (r->bad || r->end - r->pos < n) {
        r->bad = 1;
        return NULL;
    }
    p = r->b + r->pos;
    r->pos += n;
    return p;
}

static uint64_t rd_int(reader *r, int n) {
    const uint8_t *p = rd_take(r, (size_t)n);
    return p ? get_le(p, n) : 0;
}

static ayl_str rd_text(reader *r, size_t n) {
    ayl_str s;
    const uint8_t *p = rd_take(r, n);
    s.ptr = "";
    s.len = 0;
    if (p == NULL) {
        return s;
    }
    if (!ayl_utf8_valid(p, n)) {
        r->bad = 1;
        return s;
    }
    s.ptr = (const char *)p;
    s.len = n;
    return s;
}

static ayl_str rd_str8(reader *r, int nonempty) {
    ayl_str s = rd_text(r, (size_t)rd_int(r, 1));
    if (nonempty && s.len == 0) {
        r->bad = 1;
    }
    return s;
}

/* PORT's appended group: read when the bytes after the value are a whole str8 of UTF-8; an
 * empty one, or bytes that are not a whole str8, leave it empty and are ignored as a later
 * field would be (spec/protocol.md, PORT). */
static void rd_optional_group(reader *r, ayl_str *group) {
    size_t n;
    group->ptr = "";
    group->len = 0;
    if (r->bad || r->pos >= r->end) {
        return;
    }
    n = r->b[r->pos];
    if (r->end - r->pos - 1 < n || !ayl_utf8_valid(r->b + r->pos + 1, n)) {
        return;
    }
    group->ptr = (const char *)(r->b + r->pos + 1);
    group->len = n;
    r->pos += 1 + n;
}

static ayl_str rd_str16(reader *r) { return rd_text(r, (size_t)rd_int(r, 2)); }

static void rd_kind_period(reader *r, ayl_conn_kind *kind, uint64_t *period) {
    uint8_t k = (uint8_t)rd_int(r, 1);
    *period = rd_int(r, 8);
    if (k > AYL_WRITE_INHIBIT || (k == AYL_NORMAL) != (*period == 0)) {
        r->bad = 1;
    }
    *kind = (ayl_conn_kind)k;
}

static void rd_value(reader *r, ayl_value *v) {
    uint8_t t = (uint8_t)rd_int(r, 1);
    memset(v, 0, sizeof *v);
    v->type = (ayl_type)t;
    switch (t) {
    case AYL_BOOL: {
        uint8_t b = (uint8_t)rd_int(r, 1);
        if (b > 1) {
            r->bad = 1;
        }
        v->u.b = b;
        break;
    }
    case AYL_INT:
        v->u.i = (int64_t)rd_int(r, 8);
        break;
    case AYL_FLOAT:
        v->u.f64_bits = rd_int(r, 8);
        break;
    case AYL_TEXT: {
        ayl_str s = rd_str16(r);
        v->u.data.ptr = (const uint8_t *)s.ptr;
        v->u.data.len = s.len;
        break;
    }
    case AYL_BYTES: {
        size_t n = (size_t)rd_int(r, 2);
        v->u.data.ptr = rd_take(r, n);
        v->u.data.len = v->u.data.ptr ? n : 0;
        break;
    }
    case AYL_VECTOR: {
        size_t n = (size_t)rd_int(r, 1);
        v->u.vec.le = rd_take(r, 8 * n);
        v->u.vec.n = v->u.vec.le ? n : 0;
        break;
    }
    default:
        r->bad = 1;
    }
}

static void rd_endpoint(reader *r, ayl_endpoint *e) {
    uint8_t tag = (uint8_t)rd_int(r, 1);
    memset(e, 0, sizeof *e);
    if (tag == 1) {
        e->node = (uint32_t)rd_int(r, 4);
    } else if (tag == 2) {
        e->is_group = 1;
        e->group = rd_str8(r, 1);
    } else {
        r->bad = 1; /* tag 0 ("local") is never sent */
    }
    e->behavior = rd_str8(r, 0);
    e->port = rd_str8(r, 0);
}

static ayl_cause decode_body(uint8_t kind, reader *r, ayl_msg *m) {
    memset(m, 0, sizeof *m);
    m->kind = kind;
    switch (kind) {
    case AYL_KIND_PORT: {
        ayl_port_msg *p = &m->u.port;
        p->conn = rd_int(r, 8);
        p->seq = rd_int(r, 8);
        rd_kind_period(r, &p->kind, &p->period_ns);
        p->priority = (int32_t)(uint32_t)rd_int(r, 4);
        p->behavior = rd_str8(r, 1);
        p->port = rd_str8(r, 1);
        rd_value(r, &p->value);
        rd_optional_group(r, &p->group);
        break;
    }
    case AYL_KIND_HELLO: {
        size_t i;
        m->u.hello.interval_ms = (uint32_t)rd_int(r, 4);
        m->u.hello.name = rd_str8(r, 0);
        m->u.hello.ngroups = (size_t)rd_int(r, 1);
        m->u.hello.groups_wire = r->b + r->pos;
        for (i = 0; i < m->u.hello.ngroups; i++) {
            (void)rd_str8(r, 1);
        }
        if (m->u.hello.interval_ms == 0) {
            r->bad = 1;
        }
        break;
    }
    case AYL_KIND_REQUEST: {
        ayl_request_msg *q = &m->u.request;
        q->id = rd_int(r, 8);
        q->op = (uint8_t)rd_int(r, 1);
        switch (q->op) {
        case AYL_OP_CONNECT:
            q->src_behavior = rd_str8(r, 0);
            q->src_port = rd_str8(r, 0);
            rd_endpoint(r, &q->dest);
            rd_kind_period(r, &q->kind, &q->period_ns);
            q->priority = (int32_t)(uint32_t)rd_int(r, 4);
            break;
        case AYL_OP_DISCONNECT:
            q->conn = rd_int(r, 8);
            break;
        case AYL_OP_WHY:
        case AYL_OP_READ:
            q->behavior = rd_str8(r, 0);
            q->port = rd_str8(r, 0);
            break;
        case AYL_OP_LIST:
            break; /* no arguments */
        default:
            /* Unknown ops are answered, not dropped; their arguments (and so where a signature
             * would start) are unknown. */
            return r->bad ? AYL_MALFORMED : AYL_OK;
        }
        /* An optional operator signature after the arguments. Anything else there, or a tag
         * without 64 bytes after it, is ignored like any extra body bytes. */
        if (!r->bad && r->end - r->pos >= 1 + AYL_SIGNATURE_LEN && r->b[r->pos] == AYL_SIGNATURE_TAG) {
            q->has_signature = 1;
            memcpy(q->signature, r->b + r->pos + 1, AYL_SIGNATURE_LEN);
            r->pos += 1 + AYL_SIGNATURE_LEN;
        }
        break;
    }
    case AYL_KIND_CHALLENGE:
    case AYL_KIND_ECHO: {
        const uint8_t *c = rd_take(r, AYL_COOKIE_LEN); /* shorter: malformed */
        if (c != NULL) {
            memcpy(m->u.cookie.cookie, c, AYL_COOKIE_LEN);
        }
        break;
    }
    case AYL_KIND_REPLY: {
        ayl_reply_msg *y = &m->u.reply;
        uint8_t status;
        y->id = rd_int(r, 8);
        status = (uint8_t)rd_int(r, 1);
        y->part = (uint16_t)rd_int(r, 2);
        y->parts = (uint16_t)rd_int(r, 2);
        if (status > 1 || y->parts < 1 || y->parts > AYL_MAX_PARTS || y->part >= y->parts ||
            (status == 1 && y->parts != 1)) {
            r->bad = 1; /* only reports come in parts; errors too have parts = 1 */
        } else if (status == 1) {
            y->result = AYL_RESULT_ERROR;
            y->text = rd_str16(r);
        } else {
            uint8_t res = (uint8_t)rd_int(r, 1);
            y->result = (ayl_result)res;
            if (res == AYL_RESULT_REPORT) {
                y->text = rd_str16(r);
            } else if (y->parts != 1) {
                r->bad = 1; /* only reports come in parts */
            } else if (res == AYL_RESULT_CONNECTION) {
                y->conn = rd_int(r, 8);
            } else if (res == AYL_RESULT_VALUE) {
                rd_value(r, &y->value);
            } else {
                r->bad = 1;
            }
        }
        break;
    }
    default:
        break;
    }
    /* Extra bytes after the fields are ignored: fields are only ever appended. */
    return r->bad ? AYL_MALFORMED : AYL_OK;
}

/* Walks the messages area: the next message's header and body bounds. */
static ayl_cause next_frame(const uint8_t *buf, size_t pos, size_t end, uint8_t *kind, size_t *body, size_t *len) {
    if (end - pos < 3) {
        return AYL_TRUNCATED;
    }
    *kind = buf[pos];
    *len = (size_t)get_le(buf + pos + 1, 2);
    *body = pos + 3;
    if (*len > end - *body) {
        return AYL_TRUNCATED;
    }
    return AYL_OK;
}

static int ct_equal(const uint8_t *a, const uint8_t *b, size_t n) {
    uint8_t d = 0;
    size_t i;
    for (i = 0; i < n; i++) {
        d |= (uint8_t)(a[i] ^ b[i]); /* no early exit: a MAC check must not leak timing */
    }
    return d == 0;
}

ayl_cause ayl_decode(ayl_datagram *d, const uint8_t *buf, size_t len, uint32_t team, const uint8_t *key) {
    uint8_t flags;
    size_t pos;
    memset(d, 0, sizeof *d);
    if (len > AYL_MAX_DATAGRAM) {
        return AYL_OVERSIZED;
    }
    if (len < AYL_HEADER_LEN) {
        return AYL_TRUNCATED;
    }
    if (buf[0] != 0x41 || buf[1] != 0x59) {
        return AYL_BAD_MAGIC;
    }
    if (buf[2] != AYL_VERSION) {
        return AYL_BAD_VERSION;
    }
    flags = buf[3];
    if (flags & ~AYL_FLAG_AUTH) {
        return AYL_BAD_FLAGS;
    }
    if ((uint32_t)get_le(buf + 4, 4) != team) {
        return AYL_WRONG_TEAM;
    }
    d->team = team;
    d->sender = (uint32_t)get_le(buf + 8, 4);
    d->seq = get_le(buf + 12, 8);
    d->auth = (flags & AYL_FLAG_AUTH) != 0;
    d->buf = buf;
    d->end = len;
    if (d->auth) {
        uint8_t mac[AYL_SHA256_LEN];
        if (key == NULL) {
            return AYL_UNEXPECTED_AUTH;
        }
        if (len < AYL_HEADER_LEN + AYL_MAC_LEN) {
            return AYL_TRUNCATED;
        }
        d->end = len - AYL_MAC_LEN;
        ayl_hmac_sha256(key, AYL_KEY_LEN, buf, d->end, NULL, 0, mac);
        if (!ct_equal(mac, buf + d->end, AYL_MAC_LEN)) {
            return AYL_BAD_MAC;
        }
    } else if (key != NULL) {
        return AYL_UNAUTHENTICATED;
    }
    /* Validate every message now: a malformed datagram is dropped whole (N4). */
    for (pos = AYL_HEADER_LEN; pos < d->end;) {
        uint8_t kind;
        size_t body, blen;
        ayl_cause c = next_frame(buf, pos, d->end, &kind, &body, &blen);
        if (c != AYL_OK) {
            return c;
        }
        if (ayl_kind_known(kind)) {
            reader r;
            ayl_msg m;
            r.b = buf;
            r.pos = body;
            r.end = body + blen;
            r.bad = 0;
            c = decode_body(kind, &r, &m);
            if (c != AYL_OK) {
                return c;
            }
        }
        pos = body + blen;
    }
    d->pos = AYL_HEADER_LEN;
    return AYL_OK;
}

int ayl_next(ayl_datagram *d, ayl_msg *out) {
    uint8_t kind;
    size_t body, blen;
    if (d->buf == NULL || d->pos >= d->end || next_frame(d->buf, d->pos, d->end, &kind, &body, &blen) != AYL_OK) {
        return 0;
    }
    d->pos = body + blen;
    if (ayl_kind_known(kind)) {
        reader r;
        r.b = d->buf;
        r.pos = body;
        r.end = body + blen;
        r.bad = 0;
        (void)decode_body(kind, &r, out); /* validated by ayl_decode */
    } else {
        memset(out, 0, sizeof *out);
        out->kind = kind;
        out->u.unknown.code = kind;
        out->u.unknown.length = (uint16_t)blen;
    }
    return 1;
}

int ayl_replay_accept(ayl_replay_window *w, uint64_t seq) {
    uint64_t diff;
    if (!w->any || seq > w->newest) {
        if (w->any) {
            diff = seq - w->newest;
            /* Shift the older numbers up and mark the old newest as seen; numbers that fall
             * out of the 64-wide window are forgotten (and then refused as too old). */
            if (diff > 64) {
                w->bits = 0;
            } else if (diff == 64) {
                w->bits = (uint64_t)1 << 63;
            } else {
                w->bits = (w->bits << diff) | ((uint64_t)1 << (diff - 1));
            }
        }
        w->newest = seq;
        w->any = 1;
        return 1;
    }
    diff = w->newest - seq;
    if (diff == 0 || diff > 64 || (w->bits & ((uint64_t)1 << (diff - 1)))) {
        return 0;
    }
    w->bits |= (uint64_t)1 << (diff - 1);
    return 1;
}

/* ----- encoding ------------------------------------------------------------------------------ */

typedef struct {
    uint8_t *b;
    size_t pos;
    size_t cap;
    int err; /* first error, sticky, like the reader */
} wbuf;

static void wr_bytes(wbuf *w, const void *p, size_t n) {
    if (w->err) {
        return;
    }
    if (w->cap - w->pos < n) {
        w->err = AYL_E_NOSPACE;
        return;
    }
    if (n > 0) {
        memcpy(w->b + w->pos, p, n);
    }
    w->pos += n;
}

static void wr_int(wbuf *w, uint64_t v, int n) {
    uint8_t tmp[8];
    put_le(tmp, v, n);
    wr_bytes(w, tmp, (size_t)n);
}

static void wr_text(wbuf *w, const char *p, size_t n, int lenbytes, int nonempty) {
    size_t max = lenbytes == 1 ? 0xFFu : 0xFFFFu;
    if (n > max || (nonempty && n == 0) || (n > 0 && !ayl_utf8_valid((const uint8_t *)p, n))) {
        if (!w->err) {
            w->err = AYL_E_INVALID;
        }
        return;
    }
    wr_int(w, n, lenbytes);
    wr_bytes(w, p, n);
}

static void wr_str8(wbuf *w, ayl_str s, int nonempty) { wr_text(w, s.ptr, s.len, 1, nonempty); }

static void invalid(wbuf *w) {
    if (!w->err) {
        w->err = AYL_E_INVALID;
    }
}

static void wr_kind_period(wbuf *w, ayl_conn_kind kind, uint64_t period) {
    if ((unsigned)kind > AYL_WRITE_INHIBIT || (kind == AYL_NORMAL) != (period == 0)) {
        invalid(w);
    }
    wr_int(w, (uint64_t)kind, 1);
    wr_int(w, period, 8);
}

static void wr_value(wbuf *w, const ayl_value *v) {
    size_t i;
    wr_int(w, (uint64_t)v->type, 1);
    switch (v->type) {
    case AYL_BOOL:
        wr_int(w, v->u.b ? 1u : 0u, 1);
        break;
    case AYL_INT:
        wr_int(w, (uint64_t)v->u.i, 8);
        break;
    case AYL_FLOAT:
        wr_int(w, v->u.f64_bits, 8);
        break;
    case AYL_TEXT:
        wr_text(w, (const char *)v->u.data.ptr, v->u.data.len, 2, 0);
        break;
    case AYL_BYTES:
        if (v->u.data.len > 0xFFFFu) {
            invalid(w);
        }
        wr_int(w, v->u.data.len, 2);
        wr_bytes(w, v->u.data.ptr, v->u.data.len);
        break;
    case AYL_VECTOR:
        if (v->u.vec.n > 0xFFu || (v->u.vec.n > 0 && v->u.vec.le == NULL && v->u.vec.d == NULL)) {
            invalid(w);
            break;
        }
        wr_int(w, v->u.vec.n, 1);
        for (i = 0; i < v->u.vec.n; i++) {
            wr_int(w, vec_bits(v, i), 8);
        }
        break;
    default:
        invalid(w);
    }
}

static void wr_body(wbuf *w, const ayl_msg *m) {
    switch (m->kind) {
    case AYL_KIND_PORT: {
        const ayl_port_msg *p = &m->u.port;
        wr_int(w, p->conn, 8);
        wr_int(w, p->seq, 8);
        wr_kind_period(w, p->kind, p->period_ns);
        wr_int(w, (uint32_t)p->priority, 4);
        wr_str8(w, p->behavior, 1);
        wr_str8(w, p->port, 1);
        wr_value(w, &p->value);
        if (p->group.len > 0) {
            wr_str8(w, p->group, 1);
        }
        break;
    }
    case AYL_KIND_HELLO: {
        size_t i;
        if (m->u.hello.interval_ms == 0 || m->u.hello.ngroups > 0xFFu) {
            invalid(w);
        }
        wr_int(w, m->u.hello.interval_ms, 4);
        wr_str8(w, m->u.hello.name, 0);
        wr_int(w, m->u.hello.ngroups, 1);
        for (i = 0; i < m->u.hello.ngroups; i++) {
            ayl_str g;
            if (!ayl_hello_group(&m->u.hello, i, &g)) {
                invalid(w);
                break;
            }
            wr_str8(w, g, 1);
        }
        break;
    }
    case AYL_KIND_REQUEST: {
        const ayl_request_msg *q = &m->u.request;
        wr_int(w, q->id, 8);
        wr_int(w, q->op, 1);
        switch (q->op) {
        case AYL_OP_CONNECT:
            wr_str8(w, q->src_behavior, 0);
            wr_str8(w, q->src_port, 0);
            if (q->dest.is_group) {
                wr_int(w, 2, 1);
                wr_str8(w, q->dest.group, 1);
            } else {
                wr_int(w, 1, 1);
                wr_int(w, q->dest.node, 4);
            }
            wr_str8(w, q->dest.behavior, 0);
            wr_str8(w, q->dest.port, 0);
            wr_kind_period(w, q->kind, q->period_ns);
            wr_int(w, (uint32_t)q->priority, 4);
            break;
        case AYL_OP_DISCONNECT:
            wr_int(w, q->conn, 8);
            break;
        case AYL_OP_WHY:
        case AYL_OP_READ:
            wr_str8(w, q->behavior, 0);
            wr_str8(w, q->port, 0);
            break;
        case AYL_OP_LIST:
            break;
        default:
            if (q->has_signature) {
                invalid(w); /* a decoder would not see a signature after unknown arguments */
            }
            break;
        }
        if (q->has_signature) {
            wr_int(w, AYL_SIGNATURE_TAG, 1);
            wr_bytes(w, q->signature, AYL_SIGNATURE_LEN);
        }
        break;
    }
    case AYL_KIND_CHALLENGE:
    case AYL_KIND_ECHO:
        wr_bytes(w, m->u.cookie.cookie, AYL_COOKIE_LEN);
        break;
    case AYL_KIND_REPLY: {
        const ayl_reply_msg *y = &m->u.reply;
        if (y->parts < 1 || y->parts > AYL_MAX_PARTS || y->part >= y->parts ||
            (y->result != AYL_RESULT_REPORT && y->parts != 1) || (unsigned)y->result > AYL_RESULT_REPORT) {
            invalid(w);
        }
        wr_int(w, y->id, 8);
        wr_int(w, y->result == AYL_RESULT_ERROR ? 1u : 0u, 1);
        wr_int(w, y->part, 2);
        wr_int(w, y->parts, 2);
        if (y->result == AYL_RESULT_ERROR) {
            wr_text(w, y->text.ptr, y->text.len, 2, 0);
            break;
        }
        wr_int(w, (uint64_t)y->result, 1);
        if (y->result == AYL_RESULT_CONNECTION) {
            wr_int(w, y->conn, 8);
        } else if (y->result == AYL_RESULT_VALUE) {
            wr_value(w, &y->value);
        } else {
            wr_text(w, y->text.ptr, y->text.len, 2, 0);
        }
        break;
    }
    default:
        invalid(w); /* skipped kinds are for decoders; an encoder has nothing to put in them */
    }
}

/* One message (kind, length, body) at buf[0..cap): its length, or a negative ayl_error. */
static int encode_message(uint8_t *buf, size_t cap, const ayl_msg *m) {
    wbuf w;
    size_t blen;
    w.b = buf;
    w.pos = 0;
    w.cap = cap;
    w.err = 0;
    wr_int(&w, m->kind, 1);
    wr_int(&w, 0, 2); /* length, patched below */
    wr_body(&w, m);
    if (w.err) {
        return w.err;
    }
    blen = w.pos - 3;
    if (blen > 0xFFFFu) {
        return AYL_E_INVALID;
    }
    put_le(buf + 1, blen, 2);
    return (int)w.pos;
}

int ayl_writer_begin(ayl_writer *w, uint8_t *buf, size_t cap, uint32_t team, uint32_t sender, uint64_t seq,
                     int auth) {
    w->buf = buf;
    w->cap = cap;
    w->len = 0;
    w->auth = auth != 0;
    if (cap < AYL_HEADER_LEN + (w->auth ? AYL_MAC_LEN : 0)) {
        return AYL_E_NOSPACE;
    }
    buf[0] = 0x41;
    buf[1] = 0x59;
    buf[2] = AYL_VERSION;
    buf[3] = w->auth ? AYL_FLAG_AUTH : 0;
    put_le(buf + 4, team, 4);
    put_le(buf + 8, sender, 4);
    put_le(buf + 12, seq, 8);
    w->len = AYL_HEADER_LEN;
    return 0;
}

static size_t writer_room(const ayl_writer *w) {
    size_t limit = w->cap - (w->auth ? AYL_MAC_LEN : 0);
    if (limit > AYL_MAX_DATAGRAM - (w->auth ? AYL_MAC_LEN : 0)) {
        limit = AYL_MAX_DATAGRAM - (w->auth ? AYL_MAC_LEN : 0);
    }
    return limit > w->len ? limit - w->len : 0;
}

int ayl_writer_add(ayl_writer *w, const ayl_msg *m) {
    int n;
    if (w->len < AYL_HEADER_LEN) {
        return AYL_E_INVALID;
    }
    n = encode_message(w->buf + w->len, writer_room(w), m);
    if (n < 0) {
        return n;
    }
    w->len += (size_t)n;
    return 0;
}

/* An already encoded message (a request kept for retries). */
static int writer_add_raw(ayl_writer *w, const uint8_t *msg, size_t len) {
    if (len > writer_room(w)) {
        return AYL_E_NOSPACE;
    }
    memcpy(w->buf + w->len, msg, len);
    w->len += len;
    return 0;
}

int ayl_writer_finish(ayl_writer *w, const uint8_t *key) {
    if (w->len < AYL_HEADER_LEN) {
        return AYL_E_INVALID;
    }
    if (w->auth) {
        uint8_t mac[AYL_SHA256_LEN];
        if (key == NULL) {
            return AYL_E_INVALID;
        }
        ayl_hmac_sha256(key, AYL_KEY_LEN, w->buf, w->len, NULL, 0, mac);
        memcpy(w->buf + w->len, mac, AYL_MAC_LEN); /* room was kept by writer_room */
        w->len += AYL_MAC_LEN;
    }
    return (int)w->len;
}

/* ----- the node: helpers --------------------------------------------------------------------- */

static int cstr_eq(const char *c, ayl_str s) { return strlen(c) == s.len && memcmp(c, s.ptr, s.len) == 0; }

static void advance(ayl_node *n, uint64_t now) {
    if (now > n->now_ns) {
        n->now_ns = now; /* time never goes backwards (S8) */
    }
}

/* Encode `m` (or the encoded message `raw`) as the only message of a new datagram in cfg.tx,
 * numbered n->seq + 1. Returns its length or a negative ayl_error. */
static int encode_datagram(ayl_node *n, const ayl_msg *m, const uint8_t *raw, size_t raw_len) {
    ayl_writer w;
    int rc = ayl_writer_begin(&w, n->cfg.tx, n->cfg.tx_cap, n->cfg.team, n->cfg.node_id, n->seq + 1, n->keyed);
    if (rc < 0) {
        return rc;
    }
    rc = m ? ayl_writer_add(&w, m) : writer_add_raw(&w, raw, raw_len);
    if (rc < 0) {
        return rc;
    }
    return ayl_writer_finish(&w, n->keyed ? n->key : NULL);
}

/* Send the datagram encode_datagram left in cfg.tx (`len` bytes), using up its number. */
static int transmit(ayl_node *n, const ayl_addr *to, size_t len) {
    n->seq++; /* only numbers actually used: strictly increasing either way */
    if (n->cfg.send(n->cfg.io_user, to, n->cfg.tx, len) < 0) {
        n->send_failures++;
        return AYL_E_SEND;
    }
    n->sent++;
    return 0;
}

/* Encode `m` as the only message of a new datagram and send it. */
static int send_msgs(ayl_node *n, const ayl_addr *to, const ayl_msg *m, const uint8_t *raw, size_t raw_len) {
    int len = encode_datagram(n, m, raw, raw_len);
    return len < 0 ? len : transmit(n, to, (size_t)len);
}

static ayl_port *find_port(const ayl_node *n, const char *behavior, size_t blen, const char *port, size_t plen) {
    size_t i;
    for (i = 0; i < n->cfg.max_ports; i++) {
        ayl_port *p = &n->cfg.ports[i];
        if (p->behavior != NULL && strlen(p->behavior) == blen && memcmp(p->behavior, behavior, blen) == 0 &&
            strlen(p->port) == plen && memcmp(p->port, port, plen) == 0) {
            return p;
        }
    }
    return NULL;
}

static int behavior_exists(const ayl_node *n, ayl_str b) {
    size_t i;
    for (i = 0; i < n->cfg.max_ports; i++) {
        if (n->cfg.ports[i].behavior != NULL && cstr_eq(n->cfg.ports[i].behavior, b)) {
            return 1;
        }
    }
    return 0;
}

static size_t value_payload_len(const ayl_value *v) {
    if (v->type == AYL_TEXT || v->type == AYL_BYTES) {
        return v->u.data.len;
    }
    if (v->type == AYL_VECTOR) {
        return 8 * v->u.vec.n;
    }
    return 0;
}

/* Copy a value into caller storage so it no longer points into a datagram or the caller's
 * variables; vectors are kept as little-endian bytes. AYL_E_NOSPACE if it does not fit. */
static int copy_value(ayl_value *dst, const ayl_value *src, uint8_t *storage, size_t cap) {
    size_t need = value_payload_len(src);
    size_t i;
    if (need > cap) {
        return AYL_E_NOSPACE;
    }
    *dst = *src;
    if (src->type == AYL_TEXT || src->type == AYL_BYTES) {
        if (need > 0) {
            memmove(storage, src->u.data.ptr, need);
        }
        dst->u.data.ptr = storage;
    } else if (src->type == AYL_VECTOR) {
        for (i = 0; i < src->u.vec.n; i++) {
            uint64_t b = vec_bits(src, i);
            put_le(storage + 8 * i, b, 8);
        }
        dst->u.vec.le = storage;
        dst->u.vec.d = NULL;
    }
    return 0;
}

/* ----- the node: setup and ports ------------------------------------------------------------- */

int ayl_node_init(ayl_node *node, const ayl_node_config *cfg) {
    memset(node, 0, sizeof *node);
    if (cfg->send == NULL || cfg->tx == NULL || cfg->rx == NULL || cfg->tx_cap < AYL_HEADER_LEN + AYL_MAC_LEN ||
        cfg->rx_cap < AYL_HEADER_LEN + AYL_MAC_LEN || cfg->peers == NULL || cfg->max_peers == 0 ||
        cfg->node_id == 0 /* reserved, as in libayllu and AylluLite Python: ids are 1 to 2^32-1 */) {
        return AYL_E_INVALID;
    }
    node->cfg = *cfg;
    if (node->cfg.hello_interval_ms == 0) {
        node->cfg.hello_interval_ms = 1000;
    }
    if (cfg->key != NULL) {
        memcpy(node->key, cfg->key, AYL_KEY_LEN);
        node->keyed = 1;
    }
    if (cfg->broadcast != NULL) {
        node->broadcast = *cfg->broadcast;
        node->has_broadcast = 1;
    }
    node->cfg.key = NULL;       /* the copy is what is used */
    node->cfg.broadcast = NULL; /* likewise */
    /* spec: start at boot_seconds << 32 so a restarted client's numbers exceed its old ones.
     * Request ids and per-connection sequence numbers are remembered by receivers across our
     * restart too (answered requests, stale drops), so they start from the same base. */
    node->seq = cfg->seq_start;
    node->next_id = cfg->seq_start + 1;
    node->next_conn = 1;
    {
        /* Refuse a bad name or group list now rather than failing every HELLO later. */
        ayl_msg m;
        memset(&m, 0, sizeof m);
        m.kind = AYL_KIND_HELLO;
        m.u.hello.interval_ms = node->cfg.hello_interval_ms;
        m.u.hello.name = ayl_s(cfg->name);
        m.u.hello.groups = cfg->groups;
        m.u.hello.ngroups = cfg->groups != NULL ? cfg->ngroups : 0;
        if (encode_message(node->cfg.tx, node->cfg.tx_cap, &m) < 0) {
            return AYL_E_INVALID;
        }
    }
    return 0;
}

int ayl_node_expose(ayl_node *node, const char *behavior, const char *port, const ayl_value *initial,
                    uint8_t *storage, size_t storage_cap, ayl_write_fn on_write, void *user) {
    size_t i;
    ayl_port *slot = NULL;
    size_t blen = behavior ? strlen(behavior) : 0;
    size_t plen = port ? strlen(port) : 0;
    if (blen == 0 || blen > 255 || plen == 0 || plen > 255 || !ayl_utf8_valid((const uint8_t *)behavior, blen) ||
        !ayl_utf8_valid((const uint8_t *)port, plen) || (unsigned)initial->type > AYL_VECTOR) {
        return AYL_E_INVALID;
    }
    if (find_port(node, behavior, blen, port, plen) != NULL) {
        return AYL_E_EXISTS;
    }
    for (i = 0; i < node->cfg.max_ports && slot == NULL; i++) {
        if (node->cfg.ports[i].behavior == NULL) {
            slot = &node->cfg.ports[i];
        }
    }
    if (slot == NULL) {
        return AYL_E_NOSPACE;
    }
    memset(slot, 0, sizeof *slot);
    if (copy_value(&slot->value, initial, storage, storage ? storage_cap : 0) < 0) {
        return AYL_E_NOSPACE;
    }
    slot->behavior = behavior;
    slot->port = port;
    slot->storage = storage;
    slot->storage_cap = storage ? storage_cap : 0;
    slot->on_write = on_write;
    slot->user = user;
    return (int)(slot - node->cfg.ports);
}

const ayl_value *ayl_node_get(const ayl_node *node, const char *behavior, const char *port) {
    ayl_port *p = find_port(node, behavior, strlen(behavior), port, strlen(port));
    return p ? &p->value : NULL;
}

int ayl_node_set(ayl_node *node, const char *behavior, const char *port, const ayl_value *value) {
    ayl_port *p = find_port(node, behavior, strlen(behavior), port, strlen(port));
    if (p == NULL) {
        return AYL_E_NOTFOUND;
    }
    if (value->type != p->value.type) {
        return AYL_E_INVALID;
    }
    return copy_value(&p->value, value, p->storage, p->storage_cap);
}

/* ----- the node: peers ----------------------------------------------------------------------- */

static int peer_alive(const ayl_node *n, const ayl_peer *p) {
    return p->is_static || n->now_ns - p->last_heard_ns <= (uint64_t)p->interval_ms * 3000000u;
}

static ayl_peer *find_peer(ayl_node *n, uint32_t id) {
    size_t i;
    for (i = 0; i < n->cfg.max_peers; i++) {
        if (n->cfg.peers[i].used && n->cfg.peers[i].node == id) {
            return &n->cfg.peers[i];
        }
    }
    return NULL;
}

/* An entry for `id`: its own, a free one, or the least recently heard non-configured one. */
static ayl_peer *peer_slot(ayl_node *n, uint32_t id) {
    ayl_peer *p = find_peer(n, id);
    ayl_peer *oldest = NULL;
    size_t i;
    if (p != NULL) {
        return p;
    }
    for (i = 0; i < n->cfg.max_peers; i++) {
        ayl_peer *c = &n->cfg.peers[i];
        if (!c->used) {
            p = c;
            break;
        }
        if (!c->is_static && (oldest == NULL || c->last_heard_ns < oldest->last_heard_ns)) {
            oldest = c;
        }
    }
    if (p == NULL) {
        p = oldest;
    }
    if (p != NULL) {
        memset(p, 0, sizeof *p);
        p->used = 1;
        p->node = id;
        p->interval_ms = 1000;
    }
    return p;
}

int ayl_node_add_peer(ayl_node *node, uint32_t node_id, const ayl_addr *addr) {
    ayl_peer *p = find_peer(node, node_id);
    if (p == NULL) {
        p = peer_slot(node, node_id);
    }
    if (p == NULL) {
        return AYL_E_NOSPACE;
    }
    p->is_static = 1;
    p->addr = *addr;
    return 0;
}

const ayl_addr *ayl_node_peer_addr(ayl_node *node, uint32_t node_id) {
    ayl_peer *p = find_peer(node, node_id);
    return p != NULL && peer_alive(node, p) && p->addr.len > 0 ? &p->addr : NULL;
}

int ayl_node_send_hello(ayl_node *node, uint64_t now_ns) {
    ayl_msg m;
    size_t i;
    int rc = 0;
    advance(node, now_ns);
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_HELLO;
    m.u.hello.interval_ms = node->cfg.hello_interval_ms;
    m.u.hello.name = ayl_s(node->cfg.name);
    m.u.hello.groups = node->cfg.groups;
    m.u.hello.ngroups = node->cfg.groups != NULL ? node->cfg.ngroups : 0;
    for (i = 0; i < node->cfg.max_peers; i++) {
        ayl_peer *p = &node->cfg.peers[i];
        if (p->used && p->addr.len > 0 && peer_alive(node, p)) {
            int r = send_msgs(node, &p->addr, &m, NULL, 0);
            rc = rc < 0 ? rc : r;
        }
    }
    if (node->has_broadcast) {
        int r = send_msgs(node, &node->broadcast, &m, NULL, 0);
        rc = rc < 0 ? rc : r;
    }
    node->next_hello_ns = node->now_ns + (uint64_t)node->cfg.hello_interval_ms * 1000000u;
    return rc;
}

/* ----- the node: connections ----------------------------------------------------------------- */

int ayl_conn_open(ayl_node *node, ayl_conn *c, const ayl_addr *to, const char *behavior, const char *port,
                  ayl_conn_kind kind, uint64_t period_ns, int32_t priority) {
    size_t blen = behavior ? strlen(behavior) : 0;
    size_t plen = port ? strlen(port) : 0;
    if ((unsigned)kind > AYL_WRITE_INHIBIT || (kind == AYL_NORMAL) != (period_ns == 0) || blen == 0 || blen > 255 ||
        plen == 0 || plen > 255) {
        return AYL_E_INVALID; /* refused now rather than at every send */
    }
    memset(c, 0, sizeof *c);
    c->to = *to;
    c->behavior = behavior;
    c->port = port;
    c->kind = kind;
    c->period_ns = period_ns;
    c->priority = priority;
    c->conn = node->next_conn++;
    c->seq = node->cfg.seq_start;
    return 0;
}

int ayl_conn_send(ayl_node *node, ayl_conn *c, const ayl_value *value) {
    ayl_msg m;
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_PORT;
    m.u.port.conn = c->conn;
    m.u.port.seq = c->seq + 1;
    m.u.port.kind = c->kind;
    m.u.port.period_ns = c->period_ns;
    m.u.port.priority = c->priority;
    m.u.port.behavior = ayl_s(c->behavior);
    m.u.port.port = ayl_s(c->port);
    m.u.port.value = *value;
    c->seq++; /* even if the send fails: +1 per message, and a lost one is just lost (N1) */
    return send_msgs(node, &c->to, &m, NULL, 0);
}

/* ----- the node: requests -------------------------------------------------------------------- */

static ayl_pending *find_pending(ayl_node *n, uint64_t id) {
    size_t i;
    for (i = 0; i < n->cfg.max_pending; i++) {
        if (n->cfg.pending[i].state != AYL_REQ_FREE && n->cfg.pending[i].id == id) {
            return &n->cfg.pending[i];
        }
    }
    return NULL;
}

static void flush_requests(ayl_node *n) {
    size_t i;
    for (i = 0; i < n->cfg.max_pending; i++) {
        ayl_pending *p = &n->cfg.pending[i];
        if (p->state != AYL_REQ_PENDING || p->next_send_ns > n->now_ns) {
            continue;
        }
        if (p->sends >= AYL_RETRY_LIMIT) {
            p->state = AYL_REQ_FAILED;
            continue;
        }
        p->sends++;
        p->next_send_ns = n->now_ns + AYL_RETRY_INTERVAL_NS;
        (void)send_msgs(n, &p->to, NULL, p->msg, p->msg_len); /* a failed send is retried */
    }
}

static int addr_eq(const ayl_addr *a, const ayl_addr *b) {
    return a->len == b->len && a->len <= AYL_ADDR_SIZE && memcmp(a->bytes, b->bytes, a->len) == 0;
}

/* The node configured at `to`, else one heard there recently; NULL if none. */
static const ayl_peer *peer_at(const ayl_node *n, const ayl_addr *to) {
    const ayl_peer *heard = NULL;
    size_t i;
    for (i = 0; i < n->cfg.max_peers; i++) {
        const ayl_peer *p = &n->cfg.peers[i];
        if (p->used && addr_eq(&p->addr, to) && peer_alive(n, p)) {
            if (p->is_static) {
                return p;
            }
            heard = heard ? heard : p;
        }
    }
    return heard;
}

/* What an operator signature covers (spec, "Operator signature"): a context string, team,
 * requester, receiver, then the REQUEST body from the id through the last argument. */
static const char SIGNED_CONTEXT[] = "ayllu operator request v1"; /* with its NUL: 26 bytes */
#define SIGNED_HEAD (sizeof SIGNED_CONTEXT + 12)

/* Sign q (its id final, no signature yet) for node `receiver`, using `scratch` for the signed
 * bytes. Returns 0 or a negative ayl_error. */
static int sign_request(ayl_node *n, uint32_t receiver, ayl_request_msg *q, uint8_t *scratch, size_t cap) {
    ayl_msg m;
    int len;
    if (cap < SIGNED_HEAD) {
        return AYL_E_NOSPACE;
    }
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_REQUEST;
    m.u.request = *q;
    m.u.request.has_signature = 0;
    /* The message's kind and length land just before the body, where the head's last 3 bytes
     * go; they are overwritten next. */
    len = encode_message(scratch + SIGNED_HEAD - 3, cap - (SIGNED_HEAD - 3), &m);
    if (len < 0) {
        return len;
    }
    memcpy(scratch, SIGNED_CONTEXT, sizeof SIGNED_CONTEXT);
    put_le(scratch + sizeof SIGNED_CONTEXT, n->cfg.team, 4);
    put_le(scratch + sizeof SIGNED_CONTEXT + 4, n->cfg.node_id, 4);
    put_le(scratch + sizeof SIGNED_CONTEXT + 8, receiver, 4);
    if (n->cfg.sign(n->cfg.sign_user, scratch, SIGNED_HEAD - 3 + (size_t)len, q->signature) < 0) {
        return AYL_E_INVALID;
    }
    q->has_signature = 1;
    return 0;
}

int ayl_node_request(ayl_node *node, const ayl_addr *to, const ayl_request_msg *req, uint8_t *out, size_t out_cap,
                     uint64_t *id) {
    ayl_pending *slot = NULL;
    ayl_msg m;
    size_t i;
    int len;
    for (i = 0; i < node->cfg.max_pending && slot == NULL; i++) {
        if (node->cfg.pending[i].state == AYL_REQ_FREE) {
            slot = &node->cfg.pending[i];
        }
    }
    if (slot == NULL) {
        return AYL_E_NOSPACE;
    }
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_REQUEST;
    m.u.request = *req;
    m.u.request.id = node->next_id;
    m.u.request.has_signature = 0;
    if (node->cfg.sign != NULL && (req->op == AYL_OP_CONNECT || req->op == AYL_OP_DISCONNECT)) {
        const ayl_peer *receiver = peer_at(node, to);
        if (receiver == NULL) {
            return AYL_E_NOTFOUND;
        }
        len = sign_request(node, receiver->node, &m.u.request, slot->msg, sizeof slot->msg);
        if (len < 0) {
            return len;
        }
    }
    len = encode_message(slot->msg, sizeof slot->msg, &m);
    if (len < 0) {
        return len;
    }
    node->next_id++;
    slot->msg_len = (uint16_t)len;
    slot->id = m.u.request.id;
    slot->to = *to;
    slot->sends = 0;
    slot->next_send_ns = 0;
    slot->out = out;
    slot->out_cap = out ? out_cap : 0;
    slot->out_len = 0;
    slot->parts = 0;
    slot->parts_seen = 0;
    slot->out_overflow = 0;
    slot->hurried = 0;
    memset(&slot->answer, 0, sizeof slot->answer);
    slot->state = AYL_REQ_PENDING;
    if (id != NULL) {
        *id = slot->id;
    }
    flush_requests(node); /* first send now */
    return 0;
}

ayl_req_state ayl_node_request_take(ayl_node *node, uint64_t id, ayl_reply_msg *answer, int *overflow) {
    ayl_pending *p = find_pending(node, id);
    ayl_req_state s;
    if (p == NULL) {
        return AYL_REQ_FREE;
    }
    s = p->state;
    if (s == AYL_REQ_DONE && answer != NULL) {
        *answer = p->answer;
    }
    if (overflow != NULL) {
        *overflow = p->out_overflow;
    }
    if (s == AYL_REQ_DONE || s == AYL_REQ_FAILED) {
        p->state = AYL_REQ_FREE;
    }
    return s;
}

void ayl_node_request_cancel(ayl_node *node, uint64_t id) {
    ayl_pending *p = find_pending(node, id);
    if (p != NULL) {
        p->state = AYL_REQ_FREE;
    }
}

/* Copy into the request's out buffer at `at` (cutting and flagging what does not fit). */
static size_t out_put(ayl_pending *p, size_t at, const void *src, size_t len) {
    if (at >= p->out_cap) {
        if (len > 0) {
            p->out_overflow = 1;
        }
        return 0;
    }
    if (len > p->out_cap - at) {
        len = p->out_cap - at;
        p->out_overflow = 1;
    }
    if (len > 0) {
        memcpy(p->out + at, src, len);
    }
    return len;
}

static void apply_reply(ayl_node *n, const ayl_reply_msg *y) {
    ayl_pending *p = find_pending(n, y->id);
    if (p == NULL || p->state != AYL_REQ_PENDING) {
        return; /* a late duplicate of something already answered */
    }
    if (y->result != AYL_RESULT_REPORT) {
        p->answer = *y;
        if (y->result == AYL_RESULT_ERROR) {
            p->out_len = out_put(p, 0, y->text.ptr, y->text.len);
            p->answer.text.ptr = (const char *)p->out;
            p->answer.text.len = p->out_len;
        } else if (y->result == AYL_RESULT_VALUE) {
            size_t need = value_payload_len(&y->value);
            if (need > p->out_cap) {
                p->out_overflow = 1;
                memset(&p->answer.value, 0, sizeof p->answer.value);
                p->answer.value.type = y->value.type;
            } else {
                (void)copy_value(&p->answer.value, &y->value, p->out, p->out_cap);
                p->out_len = need;
            }
        }
        p->state = AYL_REQ_DONE;
        return;
    }
    /* A report part. Parts are kept in part order in `out` as they arrive: part k goes after
     * every present part below k, and the present parts above k move up to make room. */
    if (p->parts == 0) {
        p->parts = y->parts;
    }
    if (y->parts != p->parts || (p->parts_seen >> y->part) & 1u) {
        return; /* inconsistent with earlier parts, or a repeat */
    }
    {
        size_t at = 0;
        size_t tail = 0;
        size_t len = y->text.len;
        uint16_t k;
        for (k = 0; k < p->parts; k++) {
            if ((p->parts_seen >> k) & 1u) {
                if (k < y->part) {
                    at += p->part_len[k];
                } else {
                    tail += p->part_len[k];
                }
            }
        }
        if (p->out_overflow || p->out_len + len > p->out_cap) {
            p->out_overflow = 1; /* cut: the report is no longer usable, but still completes */
            len = 0;
        } else {
            memmove(p->out + at + len, p->out + at, tail);
            memcpy(p->out + at, y->text.ptr, len);
        }
        p->part_len[y->part] = (uint16_t)len;
        p->out_len += len;
        p->parts_seen |= (uint64_t)1 << y->part;
    }
    if (p->parts_seen == (p->parts == 64 ? ~(uint64_t)0 : (((uint64_t)1 << p->parts) - 1))) {
        p->answer.id = y->id;
        p->answer.part = 0;
        p->answer.parts = 1;
        p->answer.result = AYL_RESULT_REPORT;
        p->answer.text.ptr = (const char *)p->out;
        p->answer.text.len = p->out_len;
        p->state = AYL_REQ_DONE;
    }
    /* Otherwise the retry timer asks again for the missing parts: the node answers from memory. */
}

/* Return routability (spec, "CHALLENGE and ECHO"): send the cookie back at once, to the
 * address the CHALLENGE came from, in a datagram no larger than the CHALLENGE's (so nobody can
 * use this to amplify). Then the requests waiting on that address go again now rather than at
 * their next retry: the node, the address proven, answers them in full. Only once per request,
 * so forged CHALLENGEs cannot make us repeat a request more often than the retries do. */
static void answer_challenge(ayl_node *n, const ayl_cookie_msg *c, const ayl_addr *from) {
    ayl_msg m;
    size_t i;
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_ECHO;
    m.u.cookie = *c;
    n->challenged++;
    (void)send_msgs(n, from, &m, NULL, 0); /* a failed send is counted; the retries go on */
    for (i = 0; i < n->cfg.max_pending; i++) {
        ayl_pending *p = &n->cfg.pending[i];
        if (p->state != AYL_REQ_PENDING || p->hurried || p->sends == 0 || p->sends >= AYL_RETRY_LIMIT ||
            !addr_eq(&p->to, from)) {
            continue;
        }
        p->hurried = 1;
        p->sends++;
        p->next_send_ns = n->now_ns + AYL_RETRY_INTERVAL_NS;
        (void)send_msgs(n, &p->to, NULL, p->msg, p->msg_len);
    }
}

/* ----- the node: return routability (the 3x rule) ------------------------------------------- */

/* The budget entry of `addr`, or NULL. */
static ayl_budget *find_budget(ayl_node *n, const ayl_addr *addr) {
    size_t i;
    for (i = 0; i < AYL_BUDGETS; i++) {
        if (n->budgets[i].used && addr_eq(&n->budgets[i].addr, addr)) {
            return &n->budgets[i];
        }
    }
    return NULL;
}

/* A datagram of `len` bytes from `from` was accepted: it may be answered with 3x that. A new
 * address takes a free entry, else the least recently heard one's (which then starts over from
 * nothing, so what is sent to any address stays within 3x of what came from it). */
static void budget_heard(ayl_node *n, const ayl_addr *from, size_t len) {
    ayl_budget *b = find_budget(n, from);
    size_t i;
    n->heard++;
    if (b == NULL) {
        for (i = 0; i < AYL_BUDGETS; i++) {
            ayl_budget *c = &n->budgets[i];
            if (!c->used) {
                b = c;
                break;
            }
            if (b == NULL || c->heard < b->heard) {
                b = c;
            }
        }
        memset(b, 0, sizeof *b);
        b->used = 1;
        b->addr = *from;
    }
    b->heard = n->heard;
    /* Saturates far above anything real, so that 3x it cannot overflow. */
    b->received = b->received + len > UINT64_MAX / 4 ? UINT64_MAX / 4 : b->received + len;
}

/* Send the answer encode_datagram left in cfg.tx (`len` bytes, or a negative ayl_error) to
 * `to` if it fits in `to`'s budget, charging it; else count it and send nothing. */
static int send_answer(ayl_node *n, const ayl_addr *to, int len) {
    ayl_budget *b;
    if (len < 0) {
        return len;
    }
    b = find_budget(n, to);
    if (b == NULL || b->answered + (uint64_t)len > b->received * AYL_AMPLIFICATION_FACTOR) {
        n->counters[AYL_AMPLIFICATION_LIMITED]++;
        return 0;
    }
    b->answered += (uint64_t)len;
    return transmit(n, to, (size_t)len);
}

/* ----- the node: serving requests ------------------------------------------------------------ */

/* JSON text of a name, escaped, into the writer. */
static void json_string(wbuf *w, const char *s) {
    static const char hex[] = "0123456789abcdef";
    wr_bytes(w, "\"", 1);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') {
            char e[2];
            e[0] = '\\';
            e[1] = (char)c;
            wr_bytes(w, e, 2);
        } else if (c == '\n' || c == '\r' || c == '\t' || c == '\b' || c == '\f') {
            char e[2];
            e[0] = '\\';
            e[1] = c == '\n' ? 'n' : c == '\r' ? 'r' : c == '\t' ? 't' : c == '\b' ? 'b' : 'f';
            wr_bytes(w, e, 2);
        } else if (c < 0x20) {
            char e[6];
            e[0] = '\\';
            e[1] = 'u';
            e[2] = '0';
            e[3] = '0';
            e[4] = hex[c >> 4];
            e[5] = hex[c & 15];
            wr_bytes(w, e, 6);
        } else {
            wr_bytes(w, &c, 1);
        }
    }
    wr_bytes(w, "\"", 1);
}

static void json_uint(wbuf *w, uint64_t v) {
    char d[20];
    int k = 0;
    do {
        d[k++] = (char)('0' + v % 10);
        v /= 10;
    } while (v > 0);
    while (k > 0) {
        wr_bytes(w, &d[--k], 1);
    }
}

/* The LIST report of a lite node, straight into a REPLY in the send buffer:
 * {"node":N,"lite":true,"behaviors":[{"name":B,"ports":[P,...]},...]}, behaviors in order of
 * first exposure, ports in order of exposure (the same text ayllu_lite.py gives). */
static int list_reply(ayl_node *n, ayl_writer *wr, uint64_t id) {
    wbuf w;
    size_t i, j, text_at;
    int first_b = 1;
    w.b = wr->buf + wr->len;
    w.pos = 0;
    w.cap = writer_room(wr);
    w.err = 0;
    wr_int(&w, AYL_KIND_REPLY, 1);
    wr_int(&w, 0, 2);
    wr_int(&w, id, 8);
    wr_int(&w, 0, 1);
    wr_int(&w, 0, 2);
    wr_int(&w, 1, 2);
    wr_int(&w, AYL_RESULT_REPORT, 1);
    wr_int(&w, 0, 2);
    text_at = w.pos;
    wr_bytes(&w, "{\"node\":", 8);
    json_uint(&w, n->cfg.node_id);
    wr_bytes(&w, ",\"lite\":true,\"behaviors\":[", 26);
    for (i = 0; i < n->cfg.max_ports; i++) {
        const ayl_port *p = &n->cfg.ports[i];
        int seen = 0, first_p = 1;
        if (p->behavior == NULL) {
            continue;
        }
        for (j = 0; j < i && !seen; j++) {
            seen = n->cfg.ports[j].behavior != NULL && strcmp(n->cfg.ports[j].behavior, p->behavior) == 0;
        }
        if (seen) {
            continue;
        }
        wr_bytes(&w, first_b ? "{\"name\":" : ",{\"name\":", first_b ? 8 : 9);
        first_b = 0;
        json_string(&w, p->behavior);
        wr_bytes(&w, ",\"ports\":[", 10);
        for (j = i; j < n->cfg.max_ports; j++) {
            const ayl_port *q = &n->cfg.ports[j];
            if (q->behavior != NULL && strcmp(q->behavior, p->behavior) == 0) {
                if (!first_p) {
                    wr_bytes(&w, ",", 1);
                }
                first_p = 0;
                json_string(&w, q->port);
            }
        }
        wr_bytes(&w, "]}", 2);
    }
    wr_bytes(&w, "]}", 2);
    if (w.err || w.pos - 3 > 0xFFFFu) {
        return AYL_E_NOSPACE;
    }
    put_le(w.b + 1, w.pos - 3, 2);
    put_le(w.b + text_at - 2, w.pos - text_at, 2);
    wr->len += w.pos;
    return 0;
}

/* A lite node owns no connections and no behaviors beyond its exposed registers, so it
 * answers READ and LIST and refuses the rest. Reads are idempotent, so there is nothing to
 * remember between repeats of a request. Every answer, errors included, goes through
 * send_answer: within 3x of what `from` sent (spec, "CHALLENGE and ECHO"). */
static void serve(ayl_node *n, const ayl_request_msg *q, const ayl_addr *from) {
    ayl_msg m;
    int len;
    memset(&m, 0, sizeof m);
    m.kind = AYL_KIND_REPLY;
    m.u.reply.id = q->id;
    m.u.reply.parts = 1;
    m.u.reply.result = AYL_RESULT_ERROR;
    if (q->op == AYL_OP_READ) {
        ayl_port *p = find_port(n, q->behavior.ptr, q->behavior.len, q->port.ptr, q->port.len);
        if (p != NULL) {
            m.u.reply.result = AYL_RESULT_VALUE;
            m.u.reply.value = p->value;
        } else {
            m.u.reply.text = ayl_s("no such port");
        }
    } else if (q->op == AYL_OP_LIST) {
        ayl_writer w;
        if (ayl_writer_begin(&w, n->cfg.tx, n->cfg.tx_cap, n->cfg.team, n->cfg.node_id, n->seq + 1, n->keyed) == 0 &&
            list_reply(n, &w, q->id) == 0 && (len = ayl_writer_finish(&w, n->keyed ? n->key : NULL)) > 0) {
            (void)send_answer(n, from, len); /* a failed send is counted; the requester retries */
            return;
        }
        m.u.reply.text = ayl_s("report too large for an AylluLite node");
    } else if (q->op == AYL_OP_CONNECT || q->op == AYL_OP_DISCONNECT || q->op == AYL_OP_WHY) {
        m.u.reply.text = ayl_s("not supported by an AylluLite node");
    } else {
        m.u.reply.text = ayl_s("unknown operation");
    }
    len = encode_datagram(n, &m, NULL, 0);
    if (len == AYL_E_NOSPACE) {
        /* A value too large for one datagram: say so rather than stay silent and make the
         * requester retry 25 times. */
        m.u.reply.result = AYL_RESULT_ERROR;
        m.u.reply.text = ayl_s("answer too large for one datagram");
        len = encode_datagram(n, &m, NULL, 0);
    }
    (void)send_answer(n, from, len);
}

/* ----- the node: receiving ------------------------------------------------------------------- */

static ayl_seq_entry *seq_entry(ayl_node *n, uint32_t sender, uint64_t conn, int *found) {
    ayl_seq_entry *oldest = NULL;
    size_t i;
    *found = 0;
    for (i = 0; i < n->cfg.max_seqs; i++) {
        ayl_seq_entry *e = &n->cfg.seqs[i];
        if (e->used && e->sender == sender && e->conn == conn) {
            *found = 1;
            return e;
        }
    }
    /* Table full: reuse the entry updated longest ago (the core clears its whole table). */
    for (i = 0; i < n->cfg.max_seqs; i++) {
        ayl_seq_entry *e = &n->cfg.seqs[i];
        if (!e->used) {
            return e;
        }
        if (oldest == NULL || e->touched_ns < oldest->touched_ns) {
            oldest = e;
        }
    }
    return oldest;
}

static void refresh_window(ayl_port *p, uint8_t kind, uint32_t node, uint64_t conn, uint64_t now, uint64_t end) {
    ayl_window *slot = NULL;
    size_t i;
    for (i = 0; i < AYL_PORT_WINDOWS; i++) {
        ayl_window *w = &p->windows[i];
        if (w->kind == kind && w->holder_node == node && w->holder_conn == conn && w->end_ns > now) {
            if (end > w->end_ns) {
                w->end_ns = end; /* refresh, never shorten (D6.1) */
            }
            return;
        }
    }
    for (i = 0; i < AYL_PORT_WINDOWS; i++) {
        ayl_window *w = &p->windows[i];
        if (w->kind == 0 || w->end_ns <= now) {
            slot = w;
            break;
        }
        /* No free slot: give up the window that ends first; it would have mattered least. */
        if (slot == NULL || w->end_ns < slot->end_ns) {
            slot = w;
        }
    }
    slot->kind = kind;
    slot->holder_node = node;
    slot->holder_conn = conn;
    slot->end_ns = end;
}

/* Truth table 1 of docs/semantics.md: may a connection write from (node, conn) be stored? */
static ayl_cause admit(const ayl_port *p, uint32_t node, uint64_t conn, uint64_t now) {
    int override_open = 0, holds_pass = 0;
    size_t i;
    for (i = 0; i < AYL_PORT_WINDOWS; i++) {
        const ayl_window *w = &p->windows[i];
        if (w->kind == 0 || w->end_ns <= now) {
            continue;
        }
        if (w->kind == AYL_SUPPRESS) {
            return AYL_SUPPRESSED;
        }
        override_open = 1;
        holds_pass |= w->holder_node == node && w->holder_conn == conn;
    }
    return override_open && !holds_pass ? AYL_OVERRIDDEN_IN : AYL_OK;
}

/* Whether cfg.groups lists `group`. */
static int joined(const ayl_node *n, ayl_str group) {
    size_t i;
    for (i = 0; i < n->cfg.ngroups; i++) {
        const ayl_str *g = &n->cfg.groups[i];
        if (g->len == group.len && memcmp(g->ptr, group.ptr, group.len) == 0) {
            return 1;
        }
    }
    return 0;
}

/* Same order as the core's receive: stale, unknown names, the connection's own window,
 * storing, type. */
static void apply_port(ayl_node *n, uint32_t sender, const ayl_port_msg *m) {
    int found;
    ayl_seq_entry *e = seq_entry(n, sender, m->conn, &found);
    ayl_port *p;
    ayl_cause c;
    if (found && m->seq <= e->newest) {
        n->counters[AYL_STALE]++;
        return;
    }
    if (e != NULL) {
        e->used = 1;
        e->sender = sender;
        e->conn = m->conn;
        e->newest = m->seq;
        e->touched_ns = n->now_ns;
    }
    p = find_port(n, m->behavior.ptr, m->behavior.len, m->port.ptr, m->port.len);
    if (p == NULL) {
        n->counters[behavior_exists(n, m->behavior) ? AYL_UNKNOWN_PORT : AYL_UNKNOWN_BEHAVIOR]++;
        return;
    }
    if (m->kind != AYL_NORMAL) {
        uint64_t end = n->now_ns + m->period_ns;
        if (end < n->now_ns) {
            end = UINT64_MAX; /* saturate, like the core's time */
        }
        if (m->kind == AYL_SUPPRESS || m->kind == AYL_OVERRIDE_IN) {
            refresh_window(p, (uint8_t)m->kind, sender, m->conn, n->now_ns, end);
        }
    }
    if (m->kind == AYL_SUPPRESS || m->kind == AYL_INHIBIT || m->kind == AYL_WRITE_INHIBIT) {
        return; /* these kinds never write the value */
    }
    c = admit(p, sender, m->conn, n->now_ns);
    if (c != AYL_OK) {
        n->counters[c]++;
        return;
    }
    if (m->value.type != p->value.type) {
        n->counters[AYL_TYPE_MISMATCH]++;
        return;
    }
    if (copy_value(&p->value, &m->value, p->storage, p->storage_cap) < 0) {
        n->counters[AYL_TOO_LARGE]++;
        return;
    }
    p->writes++;
    if (p->on_write != NULL) {
        p->on_write(p->user, p->behavior, p->port, &p->value, sender, m->conn);
    }
}

ayl_cause ayl_node_receive(ayl_node *node, const uint8_t *data, size_t len, const ayl_addr *from, uint64_t now_ns) {
    ayl_datagram d;
    ayl_msg m;
    ayl_peer *peer;
    ayl_cause c;
    advance(node, now_ns);
    c = ayl_decode(&d, data, len, node->cfg.team, node->keyed ? node->key : NULL);
    if (c != AYL_OK) {
        node->counters[c]++;
        return c;
    }
    if (d.sender == node->cfg.node_id) {
        return AYL_OK; /* our own broadcast coming back: a group excludes its sender */
    }
    peer = find_peer(node, d.sender);
    if (peer == NULL) {
        peer = peer_slot(node, d.sender);
    }
    if (peer == NULL && node->keyed) {
        /* Every entry is a configured peer: with no window to check, freshness cannot be
         * proved, and accepting could let a replay through. */
        node->counters[AYL_REPLAYED]++;
        return AYL_REPLAYED;
    }
    if (d.auth && !ayl_replay_accept(&peer->replay, d.seq)) {
        node->counters[AYL_REPLAYED]++;
        return AYL_REPLAYED;
    }
    node->counters[AYL_OK]++;
    budget_heard(node, from, len); /* before its requests are answered: they may use it */
    if (peer != NULL) {
        if (!peer->is_static) {
            peer->addr = *from; /* a configured address stays what it was configured to be */
        }
        peer->last_heard_ns = node->now_ns;
    }
    while (ayl_next(&d, &m)) {
        switch (m.kind) {
        case AYL_KIND_PORT:
            if (m.u.port.group.len > 0 && !joined(node, m.u.port.group)) {
                /* Sent to a group we have not joined: a shared broadcast address reaches us
                 * anyway, and S10 says only members apply it (D-S10.6). */
                node->counters[AYL_NOT_MEMBER]++;
                break;
            }
            apply_port(node, d.sender, &m.u.port);
            break;
        case AYL_KIND_HELLO:
            if (peer != NULL) {
                peer->interval_ms = m.u.hello.interval_ms < AYL_MAX_PEER_INTERVAL_MS ? m.u.hello.interval_ms
                                                                                     : AYL_MAX_PEER_INTERVAL_MS;
            }
            break;
        case AYL_KIND_REQUEST:
            serve(node, &m.u.request, from);
            break;
        case AYL_KIND_REPLY:
            apply_reply(node, &m.u.reply);
            break;
        case AYL_KIND_CHALLENGE:
            answer_challenge(node, &m.u.cookie, from);
            break;
        case AYL_KIND_ECHO:
            break; /* a lite node sends no CHALLENGE (its answers keep to the 3x budget): no cookie to check */
        default:
            node->counters[AYL_UNKNOWN_KIND]++;
        }
    }
    return AYL_OK;
}

int ayl_node_poll(ayl_node *node, uint64_t now_ns) {
    int handled = 0;
    advance(node, now_ns);
    if (node->cfg.recv != NULL) {
        for (;;) {
            ayl_addr from;
            int len;
            memset(&from, 0, sizeof from);
            len = node->cfg.recv(node->cfg.io_user, &from, node->cfg.rx, node->cfg.rx_cap);
            if (len <= 0) {
                break;
            }
            if ((size_t)len > node->cfg.rx_cap) {
                node->counters[AYL_OVERSIZED]++; /* did not fit: its tail is gone */
            } else {
                (void)ayl_node_receive(node, node->cfg.rx, (size_t)len, &from, now_ns);
            }
            handled++;
        }
    }
    if (node->now_ns >= node->next_hello_ns) {
        (void)ayl_node_send_hello(node, node->now_ns);
    }
    flush_requests(node);
    return handled;
}

uint64_t ayl_node_next_deadline(const ayl_node *node) {
    uint64_t t = node->next_hello_ns;
    size_t i;
    for (i = 0; i < node->cfg.max_pending; i++) {
        const ayl_pending *p = &node->cfg.pending[i];
        if (p->state == AYL_REQ_PENDING && p->next_send_ns < t) {
            t = p->next_send_ns;
        }
    }
    return t;
}
