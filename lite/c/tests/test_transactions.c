/*
 * test_transactions.c -- AylluLite refuses transaction requests cleanly (spec/conformance.md
 * "Transactions"): every vector of spec/vectors/transactions.json (PREPARE, COMMIT, ABORT)
 * decodes to one REQUEST whose operation this library does not know, with the code its
 * `lite_expect` gives; a lite node answers such a request with "unknown operation" (the
 * path test_node.c covers with operation 127), so a coordinator aborts a plan naming it.
 */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "../ayllu_lite.h"
#include "check.h"
#include "json.h"

static char file_buf[1 << 16];

static int hexval(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    return -1;
}

int main(int argc, char **argv) {
    FILE *f;
    size_t len;
    const char *err = NULL;
    int root, v, count = 0;
    if (argc != 2) {
        fprintf(stderr, "usage: %s spec/vectors/transactions.json\n", argv[0]);
        return 2;
    }
    f = fopen(argv[1], "rb");
    if (f == NULL) {
        printf("test_transactions: SKIP: %s is absent\n", argv[1]);
        return 0;
    }
    len = fread(file_buf, 1, sizeof file_buf, f);
    fclose(f);
    root = json_parse(file_buf, len, &err);
    if (root < 0) {
        fprintf(stderr, "test_transactions: %s: %s\n", argv[1], err ? err : "parse error");
        return 2;
    }
    for (v = json_node(json_get(root, "vectors"))->first; v >= 0; v = json_node(v)->next) {
        const jnode *hex = json_node(json_get(v, "hex"));
        int expect = json_get(json_get(v, "lite_expect"), "messages");
        uint64_t code = 0, id = 0;
        uint8_t bin[4096];
        size_t n = hex->len / 2, i;
        ayl_datagram d;
        ayl_msg m;
        CHECK(n <= sizeof bin);
        for (i = 0; i < n && i < sizeof bin; i++) {
            bin[i] = (uint8_t)(hexval(hex->s[2 * i]) * 16 + hexval(hex->s[2 * i + 1]));
        }
        CHECK(json_u64(json_get(json_node(expect)->first, "code"), &code) == 0);
        CHECK(json_u64(json_get(json_node(expect)->first, "id"), &id) == 0);
        CHECK(ayl_decode(&d, bin, n, 7, NULL) == AYL_OK);
        CHECK(ayl_next(&d, &m) == 1);
        CHECK(m.kind == AYL_KIND_REQUEST);
        CHECK(m.u.request.op == code && code >= 6 && code <= 8);
        CHECK(m.u.request.id == id);
        CHECK(m.u.request.op != AYL_OP_READ && m.u.request.op != AYL_OP_LIST);
        CHECK(ayl_next(&d, &m) == 0);
        count++;
    }
    CHECK(count == 5);
    printf("test_transactions: %d vectors refused as unknown operations\n", count);
    return check_exit("test_transactions");
}
