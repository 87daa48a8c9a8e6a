/* ayllu.h — behaviors in C as the paper writes them (Werger, "Ayllu: Distributed
 * Port-Arbitrated Behavior-Based Control", section 3 and Fig. 2), over libayllu's C ABI
 * (ayllu_sys.h). docs/c-api.md has the guide and, for every form C cannot write as the paper
 * printed it, the paper's form, ours, and why.
 *
 *   ayDefBehaviorClass(Counter) {
 *     ayINTERFACE { ayIntPort(In, 0); ayIntPort(Out, 0); }
 *     ayPROCESSES { ayInitProcess(Count, ratepersecond(10)); }
 *   }
 *   ayDefProcess(Count) {
 *     ayLocalPort(In, Out);
 *     ayWriteIntPort(Out, ayReadIntPort(In) + 1);
 *   }
 *
 * Conventions:
 *  - names are written bare, as in the paper (ayConnect(VISION, Target1Angle, OBS1, TargetX));
 *    the macros turn them into strings;
 *  - the macros work on the default node, opened by ayInitIPComms (or set with
 *    ay_set_default_node); the functions of ayllu_sys.h take any node explicitly;
 *  - the paper's macros have no error returns: a call that fails is reported to the handler
 *    installed with ay_set_error_handler, by default a message on stderr
 *    (`ayllu: FILE:LINE: WHAT: WHY`) and exit status 70. Reading a port that holds no fresh
 *    value is not a failure (ayPortFresh tells);
 *  - C99 or later, or C++11 or later; no allocation in the macros.
 */
#ifndef AYLLU_H
#define AYLLU_H

#include "ayllu_sys.h"

#ifdef __cplusplus
extern "C" {
#endif

#if defined(__GNUC__) || defined(__clang__)
#define AY_UNUSED_ __attribute__((unused))
#else
#define AY_UNUSED_
#endif

/* ---- failures ------------------------------------------------------------------------- */

/* Report a failed call (any status but AY_OK) to the error handler; returns the status. */
static inline ay_status ay_checked_(ay_status s, const char *what, const char *file, int line) {
    if (s != AY_OK) {
        ay_report_error((int32_t)s, what, file, line);
    }
    return s;
}
#define ay_check_(call, what) ay_checked_((call), (what), __FILE__, __LINE__)

/* Install `handler` for the macros' failures (NULL: print and exit 70). */
#define ayOnError(handler) ((void)ay_set_error_handler(handler))

/* ---- periods and rates ---------------------------------------------------------------- */

/* A period in seconds (connections, lifespans, windows, monostables). */
#define aySeconds(x) ((double)(x))
/* A process rate in activations per second. */
#define ayRatePerSecond(x) ((double)(x))
#ifndef AYLLU_NO_SHORT_NAMES
/* The paper's spellings. Define AYLLU_NO_SHORT_NAMES if they clash with your code. */
#define seconds(x) aySeconds(x)
#define ratepersecond(x) ayRatePerSecond(x)
#endif

/* ---- behavior classes ----------------------------------------------------------------- */

/* Define behavior class `Class`; the block that follows declares its interface and
 * processes (it runs when the class is first needed on a node, by ayInitBehavior). */
#define ayDefBehaviorClass(Class)                                                             \
    void ayClass_##Class(ay_class *ayClass_, void *ayUser_);                                  \
    void ayClass_##Class(ay_class *ayClass_ AY_UNUSED_, void *ayUser_ AY_UNUSED_)
#define ayINTERFACE
#define ayPROCESSES

/* Port kinds (rule S3), for the ...PortEx forms. */
#define ayNORMAL AY_PORT_NORMAL
#define ayMAX AY_PORT_MAX
#define ayMIN AY_PORT_MIN
#define aySUM AY_PORT_SUM
#define ayPRIORITY AY_PORT_PRIORITY

/* A port of any kind with a lifespan (seconds, 0: none; rule S4) and a window (seconds, 0:
 * none; aggregating kinds only). */
#define ayIntPortEx(Name, Init, Kind, Lifespan, Window)                                       \
    ay_check_(ay_class_port_int(ayClass_, #Name, (Init), (Kind), (Lifespan), (Window), NULL), \
              "ayIntPort(" #Name ")")
#define ayFloatPortEx(Name, Init, Kind, Lifespan, Window)                                       \
    ay_check_(ay_class_port_float(ayClass_, #Name, (Init), (Kind), (Lifespan), (Window), NULL), \
              "ayFloatPort(" #Name ")")
#define ayBoolPortEx(Name, Init, Kind, Lifespan, Window)                                       \
    ay_check_(ay_class_port_bool(ayClass_, #Name, (Init), (Kind), (Lifespan), (Window), NULL), \
              "ayBoolPort(" #Name ")")
#define ayTextPortEx(Name, Init, Kind, Lifespan, Window)                                       \
    ay_check_(ay_class_port_text(ayClass_, #Name, (Init), (Kind), (Lifespan), (Window), NULL), \
              "ayTextPort(" #Name ")")
/* A vector port: its default is the `Length` doubles at `Init` (the shape for good). */
#define ayVectorPortEx(Name, Init, Length, Kind, Lifespan, Window)                                  \
    ay_check_(ay_class_port_vector(ayClass_, #Name, (Init), (Length), (Kind), (Lifespan), (Window), \
                                   NULL),                                                           \
              "ayVectorPort(" #Name ")")

/* A bytes port (Normal or Priority): its default is the `Length` bytes at `Init`. */
#define ayBytesPortEx(Name, Init, Length, Kind, Lifespan, Window)                                  \
    ay_check_(ay_class_port_bytes(ayClass_, #Name, (Init), (Length), (Kind), (Lifespan), (Window), \
                                  NULL),                                                           \
              "ayBytesPort(" #Name ")")

/* The paper's forms: a Normal port, and the MaxPort, MinPort, SumPort and PriorityPort. */
#define ayIntPort(Name, Init) ayIntPortEx(Name, Init, ayNORMAL, 0, 0)
#define ayMaxIntPort(Name, Init) ayIntPortEx(Name, Init, ayMAX, 0, 0)
#define ayMinIntPort(Name, Init) ayIntPortEx(Name, Init, ayMIN, 0, 0)
#define aySumIntPort(Name, Init) ayIntPortEx(Name, Init, aySUM, 0, 0)
#define ayPriorityIntPort(Name, Init) ayIntPortEx(Name, Init, ayPRIORITY, 0, 0)
#define ayFloatPort(Name, Init) ayFloatPortEx(Name, Init, ayNORMAL, 0, 0)
#define ayMaxFloatPort(Name, Init) ayFloatPortEx(Name, Init, ayMAX, 0, 0)
#define ayMinFloatPort(Name, Init) ayFloatPortEx(Name, Init, ayMIN, 0, 0)
#define aySumFloatPort(Name, Init) ayFloatPortEx(Name, Init, aySUM, 0, 0)
#define ayPriorityFloatPort(Name, Init) ayFloatPortEx(Name, Init, ayPRIORITY, 0, 0)
#define ayBoolPort(Name, Init) ayBoolPortEx(Name, Init, ayNORMAL, 0, 0)
#define ayMaxBoolPort(Name, Init) ayBoolPortEx(Name, Init, ayMAX, 0, 0)
#define ayMinBoolPort(Name, Init) ayBoolPortEx(Name, Init, ayMIN, 0, 0)
#define ayPriorityBoolPort(Name, Init) ayBoolPortEx(Name, Init, ayPRIORITY, 0, 0)
#define ayTextPort(Name, Init) ayTextPortEx(Name, Init, ayNORMAL, 0, 0)
#define ayPriorityTextPort(Name, Init) ayTextPortEx(Name, Init, ayPRIORITY, 0, 0)
#define ayVectorPort(Name, Init, Length) ayVectorPortEx(Name, Init, Length, ayNORMAL, 0, 0)
#define aySumVectorPort(Name, Init, Length) ayVectorPortEx(Name, Init, Length, aySUM, 0, 0)
#define ayBytesPort(Name, Init, Length) ayBytesPortEx(Name, Init, Length, ayNORMAL, 0, 0)
#define ayPriorityBytesPort(Name, Init, Length) ayBytesPortEx(Name, Init, Length, ayPRIORITY, 0, 0)
/* A Normal port that reads as absent `Lifespan` seconds after its last value (rule S4). */
#define ayIntPortLifespan(Name, Init, Lifespan) ayIntPortEx(Name, Init, ayNORMAL, Lifespan, 0)
#define ayFloatPortLifespan(Name, Init, Lifespan) ayFloatPortEx(Name, Init, ayNORMAL, Lifespan, 0)
#define ayBoolPortLifespan(Name, Init, Lifespan) ayBoolPortEx(Name, Init, ayNORMAL, Lifespan, 0)
#define ayTextPortLifespan(Name, Init, Lifespan) ayTextPortEx(Name, Init, ayNORMAL, Lifespan, 0)

/* Slots: registers only the behavior's processes see (rule S2). */
#define ayIntSlot(Name, Init) \
    ay_check_(ay_class_slot_int(ayClass_, #Name, (Init), NULL), "ayIntSlot(" #Name ")")
#define ayFloatSlot(Name, Init) \
    ay_check_(ay_class_slot_float(ayClass_, #Name, (Init), NULL), "ayFloatSlot(" #Name ")")
#define ayBoolSlot(Name, Init) \
    ay_check_(ay_class_slot_bool(ayClass_, #Name, (Init), NULL), "ayBoolSlot(" #Name ")")
#define ayTextSlot(Name, Init) \
    ay_check_(ay_class_slot_text(ayClass_, #Name, (Init), NULL), "ayTextSlot(" #Name ")")
/* A monostable: true for a while after it is triggered (rule S2). */
#define ayMonostable(Name) \
    ay_check_(ay_class_monostable(ayClass_, #Name, NULL), "ayMonostable(" #Name ")")

/* ---- processes ------------------------------------------------------------------------ */

/* A periodic process, `Rate` activations per second (rule S7). The process is defined with
 * ayDefProcess, before or after the class. */
#define ayInitProcess(Name, Rate)                                                      \
    do {                                                                               \
        extern void Name(ay_ctx *, void *);                                            \
        ay_check_(ay_class_every_hz(ayClass_, #Name, (Rate), Name, ayUser_),           \
                  "ayInitProcess(" #Name ")");                                         \
    } while (0)
/* A periodic process, `Rate` activations per second, activated only while port `Port` of its
 * behavior holds a fresh value (D7.5): a due time at which `Port` is stale is skipped, not run. */
#define ayInitProcessWhileFresh(Name, Rate, Port)                                      \
    do {                                                                               \
        extern void Name(ay_ctx *, void *);                                            \
        ay_check_(ay_class_every_hz_while_fresh(ayClass_, #Name, (Rate), #Port, Name, ayUser_), \
                  "ayInitProcessWhileFresh(" #Name ", " #Port ")");                    \
    } while (0)
/* A process run whenever port `Port` of its behavior accepts a value. */
#define ayInitTriggeredProcess(Name, Port)                                             \
    do {                                                                               \
        extern void Name(ay_ctx *, void *);                                            \
        ay_check_(ay_class_on_write(ayClass_, #Name, #Port, Name, ayUser_),            \
                  "ayInitTriggeredProcess(" #Name ", " #Port ")");                     \
    } while (0)
/* A process run whenever monostable `Mono` of its behavior rises or falls. */
#define ayInitMonostableProcess(Name, Mono)                                            \
    do {                                                                               \
        extern void Name(ay_ctx *, void *);                                            \
        ay_check_(ay_class_on_monostable(ayClass_, #Name, #Mono, Name, ayUser_),       \
                  "ayInitMonostableProcess(" #Name ", " #Mono ")");                    \
    } while (0)

/* Define process `Name`; the block that follows is its body. It runs to completion and must
 * not block. Inside: ayLocalPort, ayReadIntPort, ayWriteIntPort, ... and ayUSER. */
#define ayDefProcess(Name)                                                             \
    void Name(ay_ctx *ayCtx_, void *ayUser_);                                          \
    void Name(ay_ctx *ayCtx_ AY_UNUSED_, void *ayUser_ AY_UNUSED_)
/* The user pointer given with ayInitBehaviorWith (NULL otherwise). */
#define ayUSER ayUser_
/* The running process's context, for the ay_ctx_... functions of ayllu_sys.h. */
#define ayCTX ayCtx_

/* Apply m to each of up to 12 arguments, separated by `;`. */
#define AY_NARGS_(...) AY_NARGS_I_(__VA_ARGS__, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0)
#define AY_NARGS_I_(a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, a12, n, ...) n
#define AY_CAT_(a, b) AY_CAT_I_(a, b)
#define AY_CAT_I_(a, b) a##b
#define AY_EACH_(m, ...) AY_CAT_(AY_EACH_, AY_NARGS_(__VA_ARGS__))(m, __VA_ARGS__)
#define AY_EACH_1(m, a) m(a)
#define AY_EACH_2(m, a, ...) m(a); AY_EACH_1(m, __VA_ARGS__)
#define AY_EACH_3(m, a, ...) m(a); AY_EACH_2(m, __VA_ARGS__)
#define AY_EACH_4(m, a, ...) m(a); AY_EACH_3(m, __VA_ARGS__)
#define AY_EACH_5(m, a, ...) m(a); AY_EACH_4(m, __VA_ARGS__)
#define AY_EACH_6(m, a, ...) m(a); AY_EACH_5(m, __VA_ARGS__)
#define AY_EACH_7(m, a, ...) m(a); AY_EACH_6(m, __VA_ARGS__)
#define AY_EACH_8(m, a, ...) m(a); AY_EACH_7(m, __VA_ARGS__)
#define AY_EACH_9(m, a, ...) m(a); AY_EACH_8(m, __VA_ARGS__)
#define AY_EACH_10(m, a, ...) m(a); AY_EACH_9(m, __VA_ARGS__)
#define AY_EACH_11(m, a, ...) m(a); AY_EACH_10(m, __VA_ARGS__)
#define AY_EACH_12(m, a, ...) m(a); AY_EACH_11(m, __VA_ARGS__)

static inline ay_port ay_port_named_(ay_ctx *ctx, const char *name, const char *file, int line) {
    ay_port p;
    p.index = 0xFFFF;
    ay_checked_(ay_ctx_port(ctx, name, &p), name, file, line);
    return p;
}
static inline ay_slot ay_slot_named_(ay_ctx *ctx, const char *name, const char *file, int line) {
    ay_slot s;
    s.index = 0xFFFF;
    ay_checked_(ay_ctx_slot(ctx, name, &s), name, file, line);
    return s;
}
static inline ay_mono ay_mono_named_(ay_ctx *ctx, const char *name, const char *file, int line) {
    ay_mono m;
    m.index = 0xFFFF;
    ay_checked_(ay_ctx_monostable(ctx, name, &m), name, file, line);
    return m;
}
#define AY_LOCAL_PORT_(p) const ay_port p AY_UNUSED_ = ay_port_named_(ayCtx_, #p, __FILE__, __LINE__)
#define AY_LOCAL_SLOT_(s) const ay_slot s AY_UNUSED_ = ay_slot_named_(ayCtx_, #s, __FILE__, __LINE__)
#define AY_LOCAL_MONO_(m) const ay_mono m AY_UNUSED_ = ay_mono_named_(ayCtx_, #m, __FILE__, __LINE__)
/* Bring ports (slots, monostables) of the running behavior into scope by name: the paper's
 * `ayLocalPort TargetX, TargetY;` (BLE_Local, BLE_Inhibit, BLE_Best name the BLE ports). */
#define ayLocalPort(...) AY_EACH_(AY_LOCAL_PORT_, __VA_ARGS__)
#define ayLocalSlot(...) AY_EACH_(AY_LOCAL_SLOT_, __VA_ARGS__)
#define ayLocalMonostable(...) AY_EACH_(AY_LOCAL_MONO_, __VA_ARGS__)

/* Reads: what the port reads as (its default while empty); ayPortFresh says if it is fresh. */
#define AY_READ_FN_(T, Name, Fn)                                                              \
    static inline T Name(ay_ctx *ctx, ay_port p, const char *what, const char *file, int line) { \
        T v = 0;                                                                              \
        ay_status s = Fn(ctx, p, &v);                                                         \
        if (s != AY_OK && s != AY_ERR_ABSENT) {                                               \
            ay_report_error((int32_t)s, what, file, line);                                    \
        }                                                                                     \
        return v;                                                                             \
    }
AY_READ_FN_(int64_t, ay_read_int_, ay_ctx_read_int)
AY_READ_FN_(double, ay_read_float_, ay_ctx_read_float)
AY_READ_FN_(bool, ay_read_bool_, ay_ctx_read_bool)
static inline bool ay_fresh_(ay_ctx *ctx, ay_port p, const char *what, const char *file, int line) {
    bool fresh = false;
    ay_checked_(ay_ctx_fresh(ctx, p, &fresh), what, file, line);
    return fresh;
}
static inline const char *ay_read_text_(ay_ctx *ctx, ay_port p, char *buffer, size_t capacity,
                                        const char *what, const char *file, int line) {
    ay_status s = ay_ctx_read_text(ctx, p, buffer, capacity, NULL);
    if (s != AY_OK && s != AY_ERR_ABSENT) {
        ay_report_error((int32_t)s, what, file, line);
        if (capacity > 0) {
            buffer[0] = '\0';
        }
    }
    return buffer;
}
#define ayReadIntPort(P) ay_read_int_(ayCtx_, (P), "ayReadIntPort(" #P ")", __FILE__, __LINE__)
#define ayReadFloatPort(P) ay_read_float_(ayCtx_, (P), "ayReadFloatPort(" #P ")", __FILE__, __LINE__)
#define ayReadBoolPort(P) ay_read_bool_(ayCtx_, (P), "ayReadBoolPort(" #P ")", __FILE__, __LINE__)
/* Copies the text into `Buffer` (`Capacity` bytes) and returns it. */
#define ayReadTextPort(P, Buffer, Capacity) \
    ay_read_text_(ayCtx_, (P), (Buffer), (Capacity), "ayReadTextPort(" #P ")", __FILE__, __LINE__)
/* Whether the port holds a fresh value (rule S4): not stale, not an empty aggregating port. */
#define ayPortFresh(P) ay_fresh_(ayCtx_, (P), "ayPortFresh(" #P ")", __FILE__, __LINE__)

/* Writes to the behavior's own ports (rule S6: never blocked by suppression). */
#define ayWriteIntPort(P, V) \
    ((void)ay_check_(ay_ctx_write_int(ayCtx_, (P), (int64_t)(V)), "ayWriteIntPort(" #P ")"))
#define ayWriteFloatPort(P, V) \
    ((void)ay_check_(ay_ctx_write_float(ayCtx_, (P), (double)(V)), "ayWriteFloatPort(" #P ")"))
#define ayWriteBoolPort(P, V) \
    ((void)ay_check_(ay_ctx_write_bool(ayCtx_, (P), (V) ? true : false), "ayWriteBoolPort(" #P ")"))
#define ayWriteTextPort(P, V) \
    ((void)ay_check_(ay_ctx_write_text(ayCtx_, (P), (V)), "ayWriteTextPort(" #P ")"))
#define ayWriteVectorPort(P, V, Length) \
    ((void)ay_check_(ay_ctx_write_vector(ayCtx_, (P), (V), (Length)), "ayWriteVectorPort(" #P ")"))
#define ayWriteBytesPort(P, V, Length) \
    ((void)ay_check_(ay_ctx_write_bytes(ayCtx_, (P), (V), (Length)), "ayWriteBytesPort(" #P ")"))
/* Vectors and bytes: copy into `Buffer` (`Capacity` items); the length, 0 on failure. */
static inline size_t ay_read_vector_(ay_ctx *ctx, ay_port p, double *buffer, size_t capacity,
                                     const char *what, const char *file, int line) {
    size_t length = 0;
    ay_status s = ay_ctx_read_vector(ctx, p, buffer, capacity, &length);
    if (s != AY_OK && s != AY_ERR_ABSENT) {
        ay_report_error((int32_t)s, what, file, line);
        return 0;
    }
    return length;
}
static inline size_t ay_read_bytes_(ay_ctx *ctx, ay_port p, uint8_t *buffer, size_t capacity,
                                    const char *what, const char *file, int line) {
    size_t length = 0;
    ay_status s = ay_ctx_read_bytes(ctx, p, buffer, capacity, &length);
    if (s != AY_OK && s != AY_ERR_ABSENT) {
        ay_report_error((int32_t)s, what, file, line);
        return 0;
    }
    return length;
}
#define ayReadVectorPort(P, Buffer, Capacity) \
    ay_read_vector_(ayCtx_, (P), (Buffer), (Capacity), "ayReadVectorPort(" #P ")", __FILE__, __LINE__)
#define ayReadBytesPort(P, Buffer, Capacity) \
    ay_read_bytes_(ayCtx_, (P), (Buffer), (Capacity), "ayReadBytesPort(" #P ")", __FILE__, __LINE__)
/* Empty an aggregating port now (the paper's end of "the current cycle"). */
#define ayResetPort(P) ((void)ay_check_(ay_ctx_reset(ayCtx_, (P)), "ayResetPort(" #P ")"))

/* Slots. */
#define AY_SLOT_FN_(T, Name, Fn)                                                               \
    static inline T Name(ay_ctx *ctx, ay_slot s, const char *what, const char *file, int line) { \
        T v = 0;                                                                               \
        ay_checked_(Fn(ctx, s, &v), what, file, line);                                         \
        return v;                                                                              \
    }
AY_SLOT_FN_(int64_t, ay_slot_int_, ay_ctx_slot_get_int)
AY_SLOT_FN_(double, ay_slot_float_, ay_ctx_slot_get_float)
AY_SLOT_FN_(bool, ay_slot_bool_, ay_ctx_slot_get_bool)
#define ayReadIntSlot(S) ay_slot_int_(ayCtx_, (S), "ayReadIntSlot(" #S ")", __FILE__, __LINE__)
#define ayReadFloatSlot(S) ay_slot_float_(ayCtx_, (S), "ayReadFloatSlot(" #S ")", __FILE__, __LINE__)
#define ayReadBoolSlot(S) ay_slot_bool_(ayCtx_, (S), "ayReadBoolSlot(" #S ")", __FILE__, __LINE__)
#define ayWriteIntSlot(S, V) \
    ((void)ay_check_(ay_ctx_slot_set_int(ayCtx_, (S), (int64_t)(V)), "ayWriteIntSlot(" #S ")"))
#define ayWriteFloatSlot(S, V) \
    ((void)ay_check_(ay_ctx_slot_set_float(ayCtx_, (S), (double)(V)), "ayWriteFloatSlot(" #S ")"))
#define ayWriteBoolSlot(S, V) \
    ((void)ay_check_(ay_ctx_slot_set_bool(ayCtx_, (S), (V) ? true : false), "ayWriteBoolSlot(" #S ")"))

/* Monostables: high until max(end, now + Period) after a trigger (rule S2). */
static inline bool ay_is_high_(ay_ctx *ctx, ay_mono m, const char *what, const char *file, int line) {
    bool high = false;
    ay_checked_(ay_ctx_is_high(ctx, m, &high), what, file, line);
    return high;
}
#define ayTrigger(M, Period) ((void)ay_check_(ay_ctx_trigger(ayCtx_, (M), (Period)), "ayTrigger(" #M ")"))
#define ayIsHigh(M) ay_is_high_(ayCtx_, (M), "ayIsHigh(" #M ")", __FILE__, __LINE__)

/* The node's time of this activation (seconds) and its id. */
static inline double ay_now_(ay_ctx *ctx) {
    double t = 0;
    ay_check_(ay_ctx_now(ctx, &t), "ayNow()");
    return t;
}
static inline uint32_t ay_node_id_(ay_ctx *ctx) {
    uint32_t id = 0;
    ay_check_(ay_ctx_node(ctx, &id), "ayNodeId()");
    return id;
}
#define ayNow() ay_now_(ayCtx_)
#define ayNodeId() ay_node_id_(ayCtx_)

/* ---- the node: behaviors, outside access ---------------------------------------------- */

/* The node the macros work on. */
#define ayNODE (ay_default_node())

/* The paper's ayInitIPComms(): open the default node, id from $AYLLU_NODE, address from
 * $AYLLU_URL (else discovery on this machine). ayInitIPCommsAs names both. */
#define ayInitIPComms() ((void)ay_check_(ay_open_default(0, NULL), "ayInitIPComms()"))
#define ayInitIPCommsAs(Id, Url) ((void)ay_check_(ay_open_default((Id), (Url)), "ayInitIPCommsAs"))
/* Close the default node (its socket, behaviors and processes). */
#define ayShutdown() ((void)ay_check_(ay_close_default(), "ayShutdown()"))

/* Create behavior `Name` of class `Class`, defining the class on first use. */
#define ayInitBehaviorWith(Class, Name, User)                                          \
    do {                                                                               \
        extern void ayClass_##Class(ay_class *, void *);                               \
        ay_check_(ay_node_init_behavior(ayNODE, #Class, ayClass_##Class, (User), #Name), \
                  "ayInitBehavior(" #Class ", " #Name ")");                            \
    } while (0)
#define ayInitBehavior(Class, Name) ayInitBehaviorWith(Class, Name, NULL)
/* Remove behavior `Name` and its connections (rule S9). */
#define ayRemoveBehavior(Name) \
    ((void)ay_check_(ay_node_remove(ayNODE, #Name), "ayRemoveBehavior(" #Name ")"))

/* Outside a process: write and read a port of the default node by name. */
#define ayWriteIntPortOf(B, P, V) \
    ((void)ay_check_(ay_node_write_int(ayNODE, #B, #P, (int64_t)(V)), "ayWriteIntPortOf(" #B ", " #P ")"))
#define ayWriteFloatPortOf(B, P, V) \
    ((void)ay_check_(ay_node_write_float(ayNODE, #B, #P, (double)(V)), "ayWriteFloatPortOf(" #B ", " #P ")"))
#define ayWriteBoolPortOf(B, P, V)                                                              \
    ((void)ay_check_(ay_node_write_bool(ayNODE, #B, #P, (V) ? true : false),                    \
                     "ayWriteBoolPortOf(" #B ", " #P ")"))
#define ayWriteTextPortOf(B, P, V) \
    ((void)ay_check_(ay_node_write_text(ayNODE, #B, #P, (V)), "ayWriteTextPortOf(" #B ", " #P ")"))
#define AY_READ_OF_FN_(T, Name, Fn)                                                           \
    static inline T Name(const char *b, const char *p, const char *file, int line) {          \
        T v = 0;                                                                              \
        ay_status s = Fn(ay_default_node(), b, p, &v);                                        \
        if (s != AY_OK && s != AY_ERR_ABSENT) {                                               \
            ay_report_error((int32_t)s, p, file, line);                                       \
        }                                                                                     \
        return v;                                                                             \
    }
AY_READ_OF_FN_(int64_t, ay_read_int_of_, ay_node_read_int)
AY_READ_OF_FN_(double, ay_read_float_of_, ay_node_read_float)
AY_READ_OF_FN_(bool, ay_read_bool_of_, ay_node_read_bool)
#define ayReadIntPortOf(B, P) ay_read_int_of_(#B, #P, __FILE__, __LINE__)
#define ayReadFloatPortOf(B, P) ay_read_float_of_(#B, #P, __FILE__, __LINE__)
#define ayReadBoolPortOf(B, P) ay_read_bool_of_(#B, #P, __FILE__, __LINE__)
static inline bool ay_fresh_of_(const char *b, const char *p, const char *file, int line) {
    bool fresh = false;
    ay_checked_(ay_node_fresh(ay_default_node(), b, p, &fresh), p, file, line);
    return fresh;
}
#define ayPortFreshOf(B, P) ay_fresh_of_(#B, #P, __FILE__, __LINE__)

/* ---- connections (rules S6, S10) ------------------------------------------------------- */

/* A broadcast group (the paper's ayBROADCAST): a name the transport delivers to every node
 * that joined it, except the sender. */
typedef struct {
    const char *name;
} ay_group;
#define ayBROADCAST ay_group
/* The paper passes a subnet broadcast address; here it is the group's name (the udp:// URL's
 * broadcast= or peer= say where the group's datagrams go). The string must outlive its use. */
static inline ay_group ayMakeBroadcast(const char *name) {
    ay_group g;
    g.name = name;
    return g;
}

static inline ay_endpoint ay_at_(const char *b, const char *p) {
    ay_endpoint e;
    e.scope = AY_LOCAL;
    e.node = 0;
    e.group = NULL;
    e.behavior = b;
    e.port = p;
    return e;
}
static inline ay_endpoint ay_on_(uint32_t node, const char *b, const char *p) {
    ay_endpoint e = ay_at_(b, p);
    e.scope = AY_NODE;
    e.node = node;
    return e;
}
static inline ay_endpoint ay_in_(ay_group g, const char *b, const char *p) {
    ay_endpoint e = ay_at_(b, p);
    e.scope = AY_GROUP;
    e.group = g.name;
    return e;
}
/* Endpoints: (behavior, port) here; (node, behavior, port) — the paper's (host, behavior,
 * port), a host being a node id; (group, behavior, port) on every other node of a group. */
#define ayAt(B, P) ay_at_(#B, #P)
#define ayOn(Node, B, P) ay_on_((Node), #B, #P)
#define ayIn(Group, B, P) ay_in_((Group), #B, #P)

static inline uint64_t ay_connect_(uint32_t kind, ay_endpoint s, ay_endpoint d, double period,
                                   int32_t priority, const char *what, const char *file, int line) {
    uint64_t id = 0;
    if (d.scope == AY_GROUP && ay_node_join(ay_default_node(), d.group) != AY_OK) {
        ay_report_error((int32_t)AY_ERR_INVALID, what, file, line);
        return 0;
    }
    ay_checked_(ay_node_connect(ay_default_node(), &s, &d, kind, period, priority, &id), what, file, line);
    return id;
}
/* Any kind between any endpoints; returns the connection's id (for ayDisconnect). A group
 * destination also joins this node to the group (the paper's broadcast reaches every host of
 * the subnet: here, every node that joined). Kinds: AY_NORMAL (period 0), AY_SUPPRESS,
 * AY_INHIBIT, AY_OVERRIDE_IN, AY_OVERRIDE_OUT, AY_WRITE_INHIBIT. */
#define ayConnectEndpoints(Kind, Src, Dst, Period) \
    ay_connect_((Kind), (Src), (Dst), (Period), 0, "ayConnectEndpoints", __FILE__, __LINE__)
#define ayConnectPriority(SB, SP, DB, DP, Priority)                                         \
    ay_connect_(AY_NORMAL, ayAt(SB, SP), ayAt(DB, DP), 0, (Priority),                      \
                "ayConnectPriority(" #SB ", " #SP ", " #DB ", " #DP ")", __FILE__, __LINE__)
#define ayDisconnect(Id) ((void)ay_check_(ay_node_disconnect(ayNODE, (Id)), "ayDisconnect"))

#define AY_LOCAL_KIND_(Kind, Name, SB, SP, DB, DP, Period)                                  \
    ay_connect_((Kind), ayAt(SB, SP), ayAt(DB, DP), (Period), 0,                           \
                Name "(" #SB ", " #SP ", " #DB ", " #DP ")", __FILE__, __LINE__)
#define AY_REMOTE_KIND_(Kind, Name, SB, SP, Node, DB, DP, Period)                           \
    ay_connect_((Kind), ayAt(SB, SP), ayOn(Node, DB, DP), (Period), 0,                     \
                Name "(" #SB ", " #SP ", " #Node ", " #DB ", " #DP ")", __FILE__, __LINE__)
#define AY_GROUP_KIND_(Kind, Name, SB, SP, Group, DB, DP, Period)                           \
    ay_connect_((Kind), ayAt(SB, SP), ayIn(Group, DB, DP), (Period), 0,                    \
                Name "(" #SB ", " #SP ", " #Group ", " #DB ", " #DP ")", __FILE__, __LINE__)

/* Local: (behavior, port) -> (behavior, port). */
#define ayConnect(SB, SP, DB, DP) AY_LOCAL_KIND_(AY_NORMAL, "ayConnect", SB, SP, DB, DP, 0)
#define aySuppress(SB, SP, DB, DP, Period) AY_LOCAL_KIND_(AY_SUPPRESS, "aySuppress", SB, SP, DB, DP, Period)
#define ayInhibit(SB, SP, DB, DP, Period) AY_LOCAL_KIND_(AY_INHIBIT, "ayInhibit", SB, SP, DB, DP, Period)
#define ayOverrideIn(SB, SP, DB, DP, Period) AY_LOCAL_KIND_(AY_OVERRIDE_IN, "ayOverrideIn", SB, SP, DB, DP, Period)
#define ayOverrideOut(SB, SP, DB, DP, Period) AY_LOCAL_KIND_(AY_OVERRIDE_OUT, "ayOverrideOut", SB, SP, DB, DP, Period)
#define ayInhibitWrite(SB, SP, DB, DP, Period) AY_LOCAL_KIND_(AY_WRITE_INHIBIT, "ayInhibitWrite", SB, SP, DB, DP, Period)
/* Remote: (behavior, port) -> (node, behavior, port). */
#define ayRemoteConnect(SB, SP, Node, DB, DP) AY_REMOTE_KIND_(AY_NORMAL, "ayRemoteConnect", SB, SP, Node, DB, DP, 0)
#define ayRemoteSuppress(SB, SP, Node, DB, DP, Period) \
    AY_REMOTE_KIND_(AY_SUPPRESS, "ayRemoteSuppress", SB, SP, Node, DB, DP, Period)
#define ayRemoteInhibit(SB, SP, Node, DB, DP, Period) \
    AY_REMOTE_KIND_(AY_INHIBIT, "ayRemoteInhibit", SB, SP, Node, DB, DP, Period)
#define ayRemoteOverrideIn(SB, SP, Node, DB, DP, Period) \
    AY_REMOTE_KIND_(AY_OVERRIDE_IN, "ayRemoteOverrideIn", SB, SP, Node, DB, DP, Period)
#define ayRemoteOverrideOut(SB, SP, Node, DB, DP, Period) \
    AY_REMOTE_KIND_(AY_OVERRIDE_OUT, "ayRemoteOverrideOut", SB, SP, Node, DB, DP, Period)
#define ayRemoteInhibitWrite(SB, SP, Node, DB, DP, Period) \
    AY_REMOTE_KIND_(AY_WRITE_INHIBIT, "ayRemoteInhibitWrite", SB, SP, Node, DB, DP, Period)
/* Broadcast: (behavior, port) -> (group, behavior, port) on every other node of the group. */
#define ayBroadcastConnect(SB, SP, Group, DB, DP) \
    AY_GROUP_KIND_(AY_NORMAL, "ayBroadcastConnect", SB, SP, Group, DB, DP, 0)
#define ayBroadcastSuppress(SB, SP, Group, DB, DP, Period) \
    AY_GROUP_KIND_(AY_SUPPRESS, "ayBroadcastSuppress", SB, SP, Group, DB, DP, Period)
#define ayBroadcastInhibit(SB, SP, Group, DB, DP, Period) \
    AY_GROUP_KIND_(AY_INHIBIT, "ayBroadcastInhibit", SB, SP, Group, DB, DP, Period)
#define ayBroadcastOverrideIn(SB, SP, Group, DB, DP, Period) \
    AY_GROUP_KIND_(AY_OVERRIDE_IN, "ayBroadcastOverrideIn", SB, SP, Group, DB, DP, Period)
#define ayBroadcastOverrideOut(SB, SP, Group, DB, DP, Period) \
    AY_GROUP_KIND_(AY_OVERRIDE_OUT, "ayBroadcastOverrideOut", SB, SP, Group, DB, DP, Period)
#define ayBroadcastInhibitWrite(SB, SP, Group, DB, DP, Period) \
    AY_GROUP_KIND_(AY_WRITE_INHIBIT, "ayBroadcastInhibitWrite", SB, SP, Group, DB, DP, Period)

/* BLE in one call (rule S11): `B`'s Local to the peers' Best, its Inhibit write-inhibiting
 * the peers' `Out` for twice the claim period plus delay and margin (2.3 s at 1 Hz), and the
 * select process claiming `Rate` times a second. ayBLEInhibitFor chooses the period (a
 * period too short for the rate is accepted and warned about in ayReport()). */
#define ayBLE(B, Group, Out, Rate) \
    ((void)ay_check_(ay_node_ble_join(ayNODE, #B, (Group).name, #Out, (Rate), 0), "ayBLE(" #B ")"))
#define ayBLEInhibitFor(B, Group, Out, Rate, Period)                                       \
    ((void)ay_check_(ay_node_ble_join(ayNODE, #B, (Group).name, #Out, (Rate), (Period)),   \
                     "ayBLEInhibitFor(" #B ")"))
static inline bool ay_claiming_(const char *b, const char *file, int line) {
    bool claiming = false;
    ay_checked_(ay_node_ble_claiming(ay_default_node(), b, &claiming), b, file, line);
    return claiming;
}
/* Whether behavior `B` holds a BLE claim now. */
#define ayBLEClaiming(B) ay_claiming_(#B, __FILE__, __LINE__)

/* ---- running ----------------------------------------------------------------------- */

/* Run the default node until ay_request_stop() (from a process, a thread or a signal
 * handler). */
#define ayRunBehaviors() ((void)ay_check_(ay_node_run(ayNODE), "ayRunBehaviors()"))
/* Run it for `Seconds` of real time (or until ay_request_stop()). */
#define ayRunBehaviorsFor(Seconds) ((void)ay_check_(ay_node_run_for(ayNODE, (Seconds)), "ayRunBehaviorsFor"))
/* One turn of the loop (with a manual clock: after advancing it). */
#define ayStep() ((void)ay_check_(ay_node_step(ayNODE, NULL), "ayStep()"))

/* ---- flight recording ------------------------------------------------------------- */

/* Record the default node into the MCAP file `Path` (a string; Foxglove opens it, `ayllu
 * replay Path --at 12.5s why OBS1.Rotate` plays it back): call it right after ayInitIPComms,
 * before defining classes. At most 1 GiB in numbered segments; ay_node_record sets another
 * cap. Closed by ayStopRecording() or when the node is freed. */
#define ayRecord(Path) ((void)ay_check_(ay_node_record(ayNODE, (Path), 0), "ayRecord"))
/* Stop recording the default node and close the file. */
#define ayStopRecording() ((void)ay_check_(ay_node_stop_recording(ayNODE, NULL), "ayStopRecording()"))

/* ---- why and list ------------------------------------------------------------------- */

static inline char *ay_why_(const char *b, const char *p, const char *file, int line) {
    char *json = NULL;
    ay_checked_(ay_node_why_json(ay_default_node(), b, p, &json), p, file, line);
    return json;
}
static inline char *ay_report_(const char *file, int line) {
    char *json = NULL;
    ay_checked_(ay_node_report_json(ay_default_node(), &json), "ayReport()", file, line);
    return json;
}
/* Why port (B, P) holds and passes what it does, as JSON (free with ayFreeReport). */
#define ayWhy(B, P) ay_why_(#B, #P, __FILE__, __LINE__)
/* The whole node (behaviors, connections, groups, counters, warnings) as JSON. */
#define ayReport() ay_report_(__FILE__, __LINE__)
#define ayFreeReport(Json) ((void)ay_string_free(Json))

#ifdef __cplusplus
}
#endif

#endif /* AYLLU_H */
