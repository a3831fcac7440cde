/* emu/report.h -- the harness's report at the end of a run (report.c). */
#ifndef EMU_REPORT_H
#define EMU_REPORT_H

#include <stdio.h>
#include "emu.h"
#include "channel.h"

/* Write the report of nn nodes (JSON when json, else text) to out: state[i]
 * the node's last cpu state, cyc0/sleep0 its cycles and sleeping cycles at
 * the settle time (loads count from there), now_ns the end of the run, ch
 * the radio channel (or NULL), span_from/to the --span names.  Returns 1
 * when a node crashed, else 0. */
int report_write(FILE *out, int json, emu_node_t **nodes, int nn, const int *state,
                 const uint64_t *cyc0, const uint64_t *sleep0, double settle, uint64_t now_ns,
                 emu_channel_t *ch, const char *span_from, const char *span_to);

#endif
