/*
 * json.h -- a tiny JSON reader for the AylluLite C tests only (the library never needs JSON).
 *
 * What it is for: reading spec/vectors/vectors.json without a dependency and without malloc.
 * What it promises: RFC 8259 documents into a fixed static pool of nodes (JSON_MAX_NODES)
 * and decoded strings (JSON_MAX_TEXT), with \u escapes (surrogate pairs included) turned into
 * UTF-8; numbers are kept as their text so 64-bit integers are read exactly. One document at
 * a time; not thread-safe (static pools).
 */
#ifndef AYLLU_TEST_JSON_H
#define AYLLU_TEST_JSON_H

#include <stddef.h>
#include <stdint.h>

typedef enum { J_NULL, J_FALSE, J_TRUE, J_NUM, J_STR, J_ARR, J_OBJ } jtype;

typedef struct {
    jtype t;
    const char *key; /* member name when inside an object (decoded), else NULL */
    size_t key_len;
    const char *s; /* J_STR: decoded bytes; J_NUM: the number's text */
    size_t len;
    int first; /* J_ARR/J_OBJ: first child, -1 if none */
    int next;  /* next sibling, -1 at the end */
} jnode;

/* Parse text[0..len); returns the root index, or -1 (and a message in *err). */
int json_parse(const char *text, size_t len, const char **err);
const jnode *json_node(int i);
/* Member `key` of object i, or -1. */
int json_get(int obj, const char *key);
/* Number of children of an array or object. */
int json_count(int i);
/* Exact integers from a number's text; 0 on success. */
int json_i64(int i, int64_t *out);
int json_u64(int i, uint64_t *out);
/* 1 if string node i equals the NUL-terminated s. */
int json_str_is(int i, const char *s);

#endif
