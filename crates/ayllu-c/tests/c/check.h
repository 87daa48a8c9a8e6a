/*
 * check.h -- the test harness of libayllu's C tests (as lite/c's): CHECK records a failure
 * with file and line and carries on, so one run reports every broken expectation; main
 * returns check_exit() so make sees a non-zero status on any failure. OK(call) checks that a
 * call returned AY_OK and prints ay_last_error() if not; FAILS(call, status, word) checks the
 * status and that the thread's message mentions `word`.
 */
#ifndef AYLLU_C_TEST_CHECK_H
#define AYLLU_C_TEST_CHECK_H

#include <stdio.h>
#include <string.h>

#include "ayllu_sys.h"

static int check_failures;
static int check_count;

#define CHECK(cond)                                                                          \
    do {                                                                                     \
        check_count++;                                                                       \
        if (!(cond)) {                                                                       \
            check_failures++;                                                                \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);        \
        }                                                                                    \
    } while (0)

#define CHECK_EQ_INT(got, want)                                                              \
    do {                                                                                     \
        long long got_ = (long long)(got), want_ = (long long)(want);                        \
        check_count++;                                                                       \
        if (got_ != want_) {                                                                 \
            check_failures++;                                                                \
            fprintf(stderr, "%s:%d: CHECK failed: %s == %s (got %lld, want %lld)\n",        \
                    __FILE__, __LINE__, #got, #want, got_, want_);                          \
        }                                                                                    \
    } while (0)

#define CHECK_NEAR(got, want)                                                                \
    do {                                                                                     \
        double got_ = (double)(got), want_ = (double)(want);                                 \
        check_count++;                                                                       \
        if (got_ - want_ > 1e-9 || want_ - got_ > 1e-9) {                                    \
            check_failures++;                                                                \
            fprintf(stderr, "%s:%d: CHECK failed: %s == %s (got %g, want %g)\n",            \
                    __FILE__, __LINE__, #got, #want, got_, want_);                          \
        }                                                                                    \
    } while (0)

#define OK(call)                                                                             \
    do {                                                                                     \
        ay_status s_ = (call);                                                               \
        check_count++;                                                                       \
        if (s_ != AY_OK) {                                                                   \
            check_failures++;                                                                \
            fprintf(stderr, "%s:%d: %s returned %s: %s\n", __FILE__, __LINE__, #call,       \
                    ay_status_name((int32_t)s_), ay_last_error());                           \
        }                                                                                    \
    } while (0)

#define FAILS(call, status, word)                                                            \
    do {                                                                                     \
        ay_status s_ = (call);                                                               \
        check_count++;                                                                       \
        if (s_ != (status) || strstr(ay_last_error(), (word)) == NULL) {                     \
            check_failures++;                                                                \
            fprintf(stderr, "%s:%d: %s: wanted %s mentioning \"%s\", got %s: %s\n",         \
                    __FILE__, __LINE__, #call, ay_status_name((int32_t)(status)), (word),   \
                    ay_status_name((int32_t)s_), ay_last_error());                           \
        }                                                                                    \
    } while (0)

static int check_exit(const char *name) {
    if (check_failures) {
        fprintf(stderr, "%s: %d of %d checks FAILED\n", name, check_failures, check_count);
        return 1;
    }
    printf("%s: %d checks passed\n", name, check_count);
    return 0;
}

#endif
