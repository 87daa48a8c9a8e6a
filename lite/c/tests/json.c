/*
 * json.c -- the tests' tiny JSON reader (see json.h). Recursive descent over static pools;
 * strict enough to notice a broken vectors file, no more.
 */
#include "json.h"

#include <string.h>

#define JSON_MAX_NODES 200000
#define JSON_MAX_TEXT (8u << 20)
#define JSON_MAX_DEPTH 64

static jnode nodes[JSON_MAX_NODES];
static int nnodes;
static char text_pool[JSON_MAX_TEXT];
static size_t ntext;

typedef struct {
    const char *p;
    const char *end;
    const char *err;
} parser;

static void ws(parser *ps) {
    while (ps->p < ps->end && (*ps->p == ' ' || *ps->p == '\t' || *ps->p == '\n' || *ps->p == '\r')) {
        ps->p++;
    }
}

static int fail(parser *ps, const char *msg) {
    if (ps->err == NULL) {
        ps->err = msg;
    }
    return -1;
}

static int new_node(parser *ps, jtype t) {
    if (nnodes >= JSON_MAX_NODES) {
        return fail(ps, "too many JSON nodes");
    }
    memset(&nodes[nnodes], 0, sizeof nodes[nnodes]);
    nodes[nnodes].t = t;
    nodes[nnodes].first = -1;
    nodes[nnodes].next = -1;
    return nnodes++;
}

static int put_byte(parser *ps, unsigned c) {
    if (ntext >= JSON_MAX_TEXT) {
        return fail(ps, "JSON text pool full");
    }
    text_pool[ntext++] = (char)c;
    return 0;
}

static int put_utf8(parser *ps, uint32_t cp) {
    if (cp < 0x80) {
        return put_byte(ps, cp);
    }
    if (cp < 0x800) {
        put_byte(ps, 0xC0 | (cp >> 6));
        return put_byte(ps, 0x80 | (cp & 0x3F));
    }
    if (cp < 0x10000) {
        put_byte(ps, 0xE0 | (cp >> 12));
        put_byte(ps, 0x80 | ((cp >> 6) & 0x3F));
        return put_byte(ps, 0x80 | (cp & 0x3F));
    }
    put_byte(ps, 0xF0 | (cp >> 18));
    put_byte(ps, 0x80 | ((cp >> 12) & 0x3F));
    put_byte(ps, 0x80 | ((cp >> 6) & 0x3F));
    return put_byte(ps, 0x80 | (cp & 0x3F));
}

static int hex4(parser *ps, uint32_t *out) {
    int i;
    *out = 0;
    if (ps->end - ps->p < 4) {
        return fail(ps, "short \\u escape");
    }
    for (i = 0; i < 4; i++) {
        char c = *ps->p++;
        *out <<= 4;
        if (c >= '0' && c <= '9') {
            *out |= (uint32_t)(c - '0');
        } else if (c >= 'a' && c <= 'f') {
            *out |= (uint32_t)(c - 'a' + 10);
        } else if (c >= 'A' && c <= 'F') {
            *out |= (uint32_t)(c - 'A' + 10);
        } else {
            return fail(ps, "bad \\u escape");
        }
    }
    return 0;
}

/* A string at ps->p (after the quote), decoded into the text pool. */
static int string(parser *ps, const char **s, size_t *len) {
    size_t start = ntext;
    while (ps->p < ps->end && *ps->p != '"') {
        unsigned char c = (unsigned char)*ps->p++;
        if (c == '\\') {
            char e;
            if (ps->p >= ps->end) {
                return fail(ps, "cut escape");
            }
            e = *ps->p++;
            switch (e) {
            case '"':
            case '\\':
            case '/':
                put_byte(ps, (unsigned)e);
                break;
            case 'b':
                put_byte(ps, '\b');
                break;
            case 'f':
                put_byte(ps, '\f');
                break;
            case 'n':
                put_byte(ps, '\n');
                break;
            case 'r':
                put_byte(ps, '\r');
                break;
            case 't':
                put_byte(ps, '\t');
                break;
            case 'u': {
                uint32_t cp, lo;
                if (hex4(ps, &cp) < 0) {
                    return -1;
                }
                if (cp >= 0xD800 && cp <= 0xDBFF) {
                    if (ps->end - ps->p < 2 || ps->p[0] != '\\' || ps->p[1] != 'u') {
                        return fail(ps, "lone surrogate");
                    }
                    ps->p += 2;
                    if (hex4(ps, &lo) < 0 || lo < 0xDC00 || lo > 0xDFFF) {
                        return fail(ps, "bad surrogate pair");
                    }
                    cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
                }
                put_utf8(ps, cp);
                break;
            }
            default:
                return fail(ps, "unknown escape");
            }
        } else {
            put_byte(ps, c);
        }
    }
    if (ps->p >= ps->end) {
        return fail(ps, "unterminated string");
    }
    ps->p++;
    *s = text_pool + start;
    *len = ntext - start;
    return ps->err ? -1 : 0;
}

static int value(parser *ps, int depth);

static int container(parser *ps, int depth, int is_obj) {
    int me = new_node(ps, is_obj ? J_OBJ : J_ARR);
    int last = -1;
    char close = is_obj ? '}' : ']';
    if (me < 0) {
        return -1;
    }
    ws(ps);
    if (ps->p < ps->end && *ps->p == close) {
        ps->p++;
        return me;
    }
    for (;;) {
        const char *key = NULL;
        size_t key_len = 0;
        int child;
        ws(ps);
        if (is_obj) {
            if (ps->p >= ps->end || *ps->p != '"') {
                return fail(ps, "expected a member name");
            }
            ps->p++;
            if (string(ps, &key, &key_len) < 0) {
                return -1;
            }
            ws(ps);
            if (ps->p >= ps->end || *ps->p != ':') {
                return fail(ps, "expected ':'");
            }
            ps->p++;
        }
        child = value(ps, depth + 1);
        if (child < 0) {
            return -1;
        }
        nodes[child].key = key;
        nodes[child].key_len = key_len;
        if (last < 0) {
            nodes[me].first = child;
        } else {
            nodes[last].next = child;
        }
        last = child;
        ws(ps);
        if (ps->p < ps->end && *ps->p == ',') {
            ps->p++;
            continue;
        }
        if (ps->p < ps->end && *ps->p == close) {
            ps->p++;
            return me;
        }
        return fail(ps, "expected ',' or a closing bracket");
    }
}

static int literal(parser *ps, const char *word, jtype t) {
    size_t n = strlen(word);
    if ((size_t)(ps->end - ps->p) < n || memcmp(ps->p, word, n) != 0) {
        return fail(ps, "bad literal");
    }
    ps->p += n;
    return new_node(ps, t);
}

static int value(parser *ps, int depth) {
    if (depth > JSON_MAX_DEPTH) {
        return fail(ps, "too deep");
    }
    ws(ps);
    if (ps->p >= ps->end) {
        return fail(ps, "unexpected end");
    }
    switch (*ps->p) {
    case '{':
        ps->p++;
        return container(ps, depth, 1);
    case '[':
        ps->p++;
        return container(ps, depth, 0);
    case '"': {
        int me = new_node(ps, J_STR);
        ps->p++;
        if (me < 0 || string(ps, &nodes[me].s, &nodes[me].len) < 0) {
            return -1;
        }
        return me;
    }
    case 't':
        return literal(ps, "true", J_TRUE);
    case 'f':
        return literal(ps, "false", J_FALSE);
    case 'n':
        return literal(ps, "null", J_NULL);
    default: {
        const char *start = ps->p;
        int me;
        while (ps->p < ps->end && strchr("+-0123456789.eE", *ps->p) != NULL) {
            ps->p++;
        }
        if (ps->p == start) {
            return fail(ps, "unexpected character");
        }
        me = new_node(ps, J_NUM);
        if (me >= 0) {
            nodes[me].s = start;
            nodes[me].len = (size_t)(ps->p - start);
        }
        return me;
    }
    }
}

int json_parse(const char *text, size_t len, const char **err) {
    parser ps;
    int root;
    nnodes = 0;
    ntext = 0;
    ps.p = text;
    ps.end = text + len;
    ps.err = NULL;
    root = value(&ps, 0);
    ws(&ps);
    if (root >= 0 && ps.p != ps.end) {
        root = fail(&ps, "trailing characters");
    }
    if (err != NULL) {
        *err = ps.err;
    }
    return root;
}

const jnode *json_node(int i) { return &nodes[i]; }

int json_get(int obj, const char *key) {
    size_t n = strlen(key);
    int c;
    if (obj < 0 || nodes[obj].t != J_OBJ) {
        return -1;
    }
    for (c = nodes[obj].first; c >= 0; c = nodes[c].next) {
        if (nodes[c].key_len == n && memcmp(nodes[c].key, key, n) == 0) {
            return c;
        }
    }
    return -1;
}

int json_count(int i) {
    int n = 0, c;
    if (i < 0) {
        return 0;
    }
    for (c = nodes[i].first; c >= 0; c = nodes[c].next) {
        n++;
    }
    return n;
}

int json_u64(int i, uint64_t *out) {
    const jnode *n;
    size_t k;
    uint64_t v = 0;
    if (i < 0 || nodes[i].t != J_NUM || nodes[i].len == 0) {
        return -1;
    }
    n = &nodes[i];
    for (k = 0; k < n->len; k++) {
        unsigned d;
        if (n->s[k] < '0' || n->s[k] > '9') {
            return -1;
        }
        d = (unsigned)(n->s[k] - '0');
        if (v > (UINT64_MAX - d) / 10) {
            return -1;
        }
        v = v * 10 + d;
    }
    *out = v;
    return 0;
}

int json_i64(int i, int64_t *out) {
    jnode saved;
    uint64_t mag;
    int neg, rc;
    if (i < 0 || nodes[i].t != J_NUM || nodes[i].len == 0) {
        return -1;
    }
    neg = nodes[i].s[0] == '-';
    saved = nodes[i];
    if (neg) {
        nodes[i].s++;
        nodes[i].len--;
    }
    rc = json_u64(i, &mag);
    nodes[i] = saved;
    if (rc < 0 || mag > (neg ? (uint64_t)INT64_MAX + 1 : (uint64_t)INT64_MAX)) {
        return -1;
    }
    *out = neg ? (mag == (uint64_t)INT64_MAX + 1 ? INT64_MIN : -(int64_t)mag) : (int64_t)mag;
    return 0;
}

int json_str_is(int i, const char *s) {
    size_t n = strlen(s);
    return i >= 0 && nodes[i].t == J_STR && nodes[i].len == n && memcmp(nodes[i].s, s, n) == 0;
}
