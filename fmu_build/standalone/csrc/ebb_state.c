/*
 * ebb_state.c -- saved states of the standalone beam FMU (ebb_instance.h): get, set, serialise, deserialise.
 */
#include <stdlib.h>
#include <string.h>

#include "ebb_instance.h"

/* ------------------------------------------------------------------ saved states */
/* Everything a continuation depends on (the model follows from p, rebuilt when p differs), then the delay lines'
 * past outputs (ebb_delay.c: EBB_DELAY_STORE doubles after the snapshot, none without delays).  Serialised as the
 * GUID and the raw snapshot: restorable by this FMU on this platform. */
#define EBB_STATE_MAGIC 0x45424253u                /* "EBBS" */
typedef struct {
    unsigned magic;
    int exchange, at_start;
    double p[EBB_NPARAM];
    double u[EBB_NACT];
    double xi[EBB_NSTATES];
    double hist[2 * EBB_NACT + 1];
    double x[EBB_NSTATES];
    double time;
} Snapshot;
#define EBB_STATE_BYTES (sizeof(Snapshot) + sizeof(double) * EBB_DELAY_STORE)

int ebb_state_check(ebb_instance *c, const char *function, const void *state)
{
    const Snapshot *s = state;
    if (!s || s->magic != EBB_STATE_MAGIC) return ebb_fail(c, function, "not a state of this FMU");
    if (s->exchange != c->exchange)
        return ebb_fail(c, function, "the state is of a %s instance, this one is %s",
                        s->exchange ? "model-exchange" : "co-simulation",
                        c->exchange ? "model-exchange" : "co-simulation");
    return 0;
}

void *ebb_state_get(ebb_instance *c, const char *function, void *reuse)
{
    Snapshot *s = reuse ? (Snapshot *)reuse : malloc(EBB_STATE_BYTES);
    if (!s) { ebb_fail(c, function, "out of memory"); return NULL; }
    memset(s, 0, sizeof(*s));
    s->magic = EBB_STATE_MAGIC;
    s->exchange = c->exchange;
    s->at_start = c->at_start;
    memcpy(s->p, c->p, sizeof(s->p));
    memcpy(s->u, c->u, sizeof(s->u));
    memcpy(s->xi, c->xi, sizeof(s->xi));
    memcpy(s->hist, c->hist, sizeof(s->hist));
    memcpy(s->x, c->x, sizeof(s->x));
    s->time = c->time;
    ebb_delay_save(c, (double *)(s + 1));
    return s;
}

int ebb_state_set(ebb_instance *c, const char *function, const void *state)
{
    if (ebb_state_check(c, function, state) != 0) return -1;
    const Snapshot *s = state;
    if (memcmp(c->p, s->p, sizeof(c->p)) != 0) c->stale = 1;   /* another parameter set: rebuilt when used */
    memcpy(c->p, s->p, sizeof(c->p));
    memcpy(c->u, s->u, sizeof(c->u));
    memcpy(c->xi, s->xi, sizeof(c->xi));
    memcpy(c->hist, s->hist, sizeof(c->hist));
    memcpy(c->x, s->x, sizeof(c->x));
    c->at_start = s->at_start;
    c->time = s->time;
    ebb_delay_load(c, (const double *)(s + 1));
    return 0;
}

size_t ebb_state_size(void) { return sizeof(EBB_GUID) + EBB_STATE_BYTES; }

int ebb_state_serialize(ebb_instance *c, const char *function, const void *state, unsigned char bytes[],
                        size_t size)
{
    if (ebb_state_check(c, function, state) != 0) return -1;
    if (size < ebb_state_size())
        return ebb_fail(c, function, "%zu bytes given, the state takes %zu", size, ebb_state_size());
    memcpy(bytes, EBB_GUID, sizeof(EBB_GUID));
    memcpy(bytes + sizeof(EBB_GUID), state, EBB_STATE_BYTES);
    return 0;
}

void *ebb_state_deserialize(ebb_instance *c, const char *function, const unsigned char bytes[], size_t size,
                            void *reuse)
{
    if (!bytes || size != ebb_state_size() || memcmp(bytes, EBB_GUID, sizeof(EBB_GUID)) != 0) {
        ebb_fail(c, function, "the %zu bytes are not a serialised state of this FMU (GUID %s)", size, EBB_GUID);
        return NULL;
    }
    Snapshot tmp;
    memcpy(&tmp, bytes + sizeof(EBB_GUID), sizeof(Snapshot));
    if (ebb_state_check(c, function, &tmp) != 0) return NULL;
    Snapshot *s = reuse ? (Snapshot *)reuse : malloc(EBB_STATE_BYTES);
    if (!s) { ebb_fail(c, function, "out of memory"); return NULL; }
    memcpy(s, bytes + sizeof(EBB_GUID), EBB_STATE_BYTES);
    return s;
}
