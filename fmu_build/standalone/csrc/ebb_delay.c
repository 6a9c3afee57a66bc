/*
 * ebb_delay.c -- the channels' converter delays as delay lines (ebb_instance.h; ebb_model.acquisition.delay_line).
 *
 * A sigma-delta converter reports its channel late by the group delay of its decimation filter; after the force's
 * channel a sensor is d samples late.  A host has only the past, so the delayed output is a weighted sum of the
 * sensor's undelayed outputs yu of past samples:
 *   y[k] = sum_j w_j yu[k - j]      (lags j ascending, generated into ebb_config.h by delay_taps),
 * j = d, w = 1 for whole samples; the band-limited kernel's taps for a fraction (lags >= 0 only: the builder refuses
 * the rest).  Each delayed sensor keeps yu[k-1] ... yu[k-L] in a ring of L = EBB_DELAY_LEN samples (the largest
 * lag); lag 0 is the current undelayed output.  At the rest start every past sample is yu[0] (the output held
 * before the record, as the Python model's delay_outputs holds it).  A delay line is past samples, not a
 * continuous-time state: an FMU with one is co-simulation only.
 */
#include <stdlib.h>
#include <string.h>

#include "ebb_instance.h"

/* the ring's length (1 when nothing is delayed: no division by a zero constant in loops that never run) */
static const int RING = EBB_DELAY_LEN > 0 ? EBB_DELAY_LEN : 1;

int ebb_delay_new(ebb_instance *c)
{
    c->dline = NULL;
    c->dhead = 0;
    if (EBB_NDELAYED == 0) return 0;
    c->dline = calloc((size_t)EBB_NDELAYED * (size_t)RING, sizeof(double));
    return c->dline ? 0 : -1;
}

void ebb_delay_free(ebb_instance *c)
{
    free(c->dline);
    c->dline = NULL;
}

int ebb_delay_refuse_exchange(const ebb_instance *c, const char *function)
{
    if (EBB_NDELAYED == 0) return 0;
    return ebb_fail(c, function, "this FMU is for co-simulation only: the converter delays of sensor(s) %s are "
                    "delay lines of past output samples, not continuous-time states (no model exchange)",
                    EBB_DELAYED_NAMES);
}

/* the rest start: every past sample of each delayed sensor is its undelayed output now */
void ebb_delay_fill(ebb_instance *c)
{
    c->dhead = 0;
    for (int o = 0; o < EBB_NSENS; o++) {
        const int d = EBB_SENS_DELAYED[o];
        if (d < 0) continue;
        const double now = ebb_undelayed(c, o);
        for (int s = 0; s < RING; s++) c->dline[d * RING + s] = now;
    }
}

/* before a sample's step: the undelayed outputs of this sample (current state and input) become lag 1 */
void ebb_delay_push(ebb_instance *c)
{
    if (EBB_NDELAYED == 0) return;
    c->dhead = (c->dhead + 1) % RING;
    for (int o = 0; o < EBB_NSENS; o++) {
        const int d = EBB_SENS_DELAYED[o];
        if (d >= 0) c->dline[d * RING + c->dhead] = ebb_undelayed(c, o);
    }
}

/* the ring's slot of lag j >= 1 (the latest sample, lag 1, at dhead) */
static int slot(int head, int j)
{
    return (head + RING - j + 1) % RING;
}

double ebb_delay_output(const ebb_instance *c, int o, double now)
{
    const int d = o < EBB_NSENS ? EBB_SENS_DELAYED[o] : -1;
    if (d < 0) return now;
    double acc = 0.0;
    for (int t = EBB_DELAY_TAP0[d]; t < EBB_DELAY_TAP0[d + 1]; t++) {
        const int j = EBB_DELAY_LAG[t];
        acc += EBB_DELAY_WEIGHT[t] * (j == 0 ? now : c->dline[d * RING + slot(c->dhead, j)]);
    }
    return acc;
}

/* the derivative of output o in the input, from its undelayed one: only the lag-0 tap sees the current input */
double ebb_delay_feedthrough(int o, double undelayed)
{
    const int d = o < EBB_NSENS ? EBB_SENS_DELAYED[o] : -1;
    if (d < 0) return undelayed;
    const int t = EBB_DELAY_TAP0[d];
    return EBB_DELAY_LAG[t] == 0 ? EBB_DELAY_WEIGHT[t] * undelayed : 0.0;
}

/* saved states: the rings unrolled, lag 1 ... L of each delayed sensor (restored with the latest at slot 0) */
void ebb_delay_save(const ebb_instance *c, double *line)
{
    for (int d = 0; d < EBB_NDELAYED; d++)
        for (int j = 1; j <= RING; j++) line[d * RING + j - 1] = c->dline[d * RING + slot(c->dhead, j)];
}

void ebb_delay_load(ebb_instance *c, const double *line)
{
    c->dhead = 0;
    for (int d = 0; d < EBB_NDELAYED; d++)
        for (int j = 1; j <= RING; j++) c->dline[d * RING + slot(0, j)] = line[d * RING + j - 1];
}
