/*
 * emu/report.c -- the harness's report at the end of a run (report.h):
 * per node its image, clock, CPU load and state, and for a sensor mote the
 * samples, I2C times, bus and wire counters, chips and the read() ->
 * readDone span; JSON (what emulate.py and the scripts read) or text.
 */
#include <stdio.h>
#include <string.h>

#include "report.h"
#include "node.h"
#include "twi.h"
#include "rf230.h"
#include "uart.h"

static const char *state_name(int st)
{
    switch (st) {
    case cpu_Done: return "done";
    case cpu_Crashed: return "crashed";
    case cpu_Sleeping: return "sleeping";
    default: return "running";
    }
}

int report_write(FILE *out, int json, emu_node_t **nodes, int nn, const int *state,
                 const uint64_t *cyc0, const uint64_t *sleep0, double settle, uint64_t now_ns,
                 emu_channel_t *ch, const char *span_from, const char *span_to)
{
    if (json)
        fprintf(out, "{\"seconds\": %.6f, \"settle\": %.3f, \"nodes\": [", now_ns / 1e9, settle);
    int rc = 0;
    for (int i = 0; i < nn; i++) {
        emu_node_t *n = nodes[i];
        uint64_t cyc = n->avr->cycle - cyc0[i];
        uint64_t slp = n->sleep_cycles - sleep0[i];
        double load = cyc ? 1.0 - (double)slp / (double)cyc : 0;
        if (state[i] == cpu_Crashed)
            rc = 1;
        emu_twi_t *t = n->twi;
        emu_sample_stats_t *s = t ? &t->st : NULL;
        double win = s && s->n_rate > 1 ? (s->last_ns - s->rate_first_ns) / 1e9 : 0;
        double rate = win > 0 ? (s->n_rate - 1) / win : 0;
        if (json) {
            fprintf(out, "%s\n {\"index\": %d, \"id\": %u, \"role\": \"%s\", \"elf\": \"%s\", "
                    "\"mhz\": %.4f, \"rom\": %u, \"ram\": %u, \"state\": \"%s\", \"cycles\": %llu, "
                    "\"cpu_load\": %.5f, \"resets\": %u, \"radio\": %s",
                    i ? "," : "", i, n->am_addr, n->is_base ? "base" : "mote", n->elf,
                    n->freq_hz / 1e6, n->rom_bytes, n->ram_bytes, state_name(state[i]),
                    (unsigned long long)n->avr->cycle, load, n->resets, n->rf ? "true" : "false");
            if (t) {
                fprintf(out, ", \"samples\": %llu, \"samples_after_settle\": %llu, "
                        "\"reads_per_s\": %.4f, \"first_sample_s\": %.6f, "
                        "\"i2c_us_mean\": %.2f, \"i2c_us_min\": %.2f, \"i2c_us_max\": %.2f, "
                        "\"wire_us_mean\": %.2f, \"held_us_mean\": %.2f, "
                        "\"interval_us_min\": %.1f, \"interval_us_max\": %.1f, "
                        "\"gaps\": %llu, \"missing_periods\": %llu, \"other_bursts\": %llu, "
                        "\"twbr\": %u, \"scl_hz\": %.0f, "
                        "\"starts\": %llu, \"bytes\": %llu, \"addr_nacks\": %llu, "
                        "\"data_nacks\": %llu, \"arb_lost\": %llu, \"hang_waits\": %llu, "
                        "\"wires\": {\"gpio_scl_pulses\": %llu, \"gpio_stops\": %llu, "
                        "\"stuck_holds\": %llu, \"stuck_freed\": %llu, \"freed_s\": %.6f, "
                        "\"freed_after_pulses\": %u, \"sda_held_at_end\": %d}, ",
                        (unsigned long long)s->n, (unsigned long long)s->n_rate, rate,
                        s->first_ns / 1e9,
                        s->n ? s->span_sum / s->n : 0, s->span_min, s->span_max,
                        s->n ? s->wire_sum / s->n : 0, s->n ? s->held_sum / s->n : 0,
                        s->int_min, s->int_max,
                        (unsigned long long)s->gaps, (unsigned long long)s->gap_periods,
                        (unsigned long long)s->other_bursts,
                        n->avr->data[0xB8], n->freq_hz / twi_period_cycles(t),
                        (unsigned long long)t->starts, (unsigned long long)t->bytes,
                        (unsigned long long)t->addr_nacks, (unsigned long long)t->data_nacks,
                        (unsigned long long)t->arb_lost, (unsigned long long)t->hang_waits,
                        (unsigned long long)t->bus->gpio_falls, (unsigned long long)t->bus->gpio_stops,
                        (unsigned long long)t->bus->stuck_holds, (unsigned long long)t->bus->stuck_freed,
                        t->bus->freed_ns / 1e9, t->bus->freed_after, t->bus->stuck_left > 0);
                fprintf(out, "\"per_second\": [");
                for (uint64_t k = 0; k < EMU_MAX_SECONDS && k < (now_ns + 999999999u) / 1000000000u; k++)
                    fprintf(out, "%s%u", k ? ", " : "", s->per_second[k]);
                fprintf(out, "], \"chips\": {");
                for (int c = 0; c < CHIP_COUNT; c++) {
                    emu_chip_t *cp = &t->chips[c];
                    fprintf(out, "%s\"%s\": {\"data_reads\": %u, \"nacked\": %u, \"resets\": %u, "
                            "\"stale_reads\": %u, \"last\": [%d, %d, %d], \"temp_reads\": %u, "
                            "\"last_temp\": %d}", c ? ", " : "", cp->name,
                            cp->data_reads, cp->nacked, cp->resets, cp->stale_reads, cp->last_data[0], cp->last_data[1],
                            cp->last_data[2], cp->temp_reads, cp->last_temp);
                }
                fprintf(out, "}");
                if (n->span_from) {
                    node_span_stats_t sp = node_span_stats(n);
                    fprintf(out, ", \"span\": {\"from\": \"%s\", \"to\": \"%s\", \"n\": %llu, "
                            "\"us_mean\": %.2f, \"us_p99\": %.2f, \"us_min\": %.2f, "
                            "\"us_max\": %.2f}", span_from, span_to, (unsigned long long)sp.n,
                            sp.mean, sp.p99, sp.min, sp.max);
                }
            }
            fprintf(out, "}");
        } else {
            fprintf(out, "node %d (id %u, %s, %.2f MHz, %s): %s, ROM %u B, RAM %u B, "
                    "CPU load %.1f %%\n", i, n->am_addr, n->is_base ? "BaseStation" : "sensor mote",
                    n->freq_hz / 1e6, n->elf, state_name(state[i]), n->rom_bytes, n->ram_bytes,
                    100 * load);
            if (t) {
                fprintf(out, "  samples %llu (%llu after %.1f s): %.3f reads/s, %llu gaps "
                        "(%llu periods missing), other bursts %llu\n",
                        (unsigned long long)s->n, (unsigned long long)s->n_rate, settle, rate,
                        (unsigned long long)s->gaps, (unsigned long long)s->gap_periods,
                        (unsigned long long)s->other_bursts);
                fprintf(out, "  I2C per sample (first START asked -> last STOP done): mean %.1f us "
                        "(min %.1f, max %.1f); on the wire %.1f us, SCL held for the CPU %.1f us; "
                        "SCL %.0f kHz\n",
                        s->n ? s->span_sum / s->n : 0, s->span_min, s->span_max,
                        s->n ? s->wire_sum / s->n : 0, s->n ? s->held_sum / s->n : 0,
                        n->freq_hz / twi_period_cycles(t) / 1e3);
                fprintf(out, "  bus: %llu starts, %llu bytes, %llu address NACKs, %llu data NACKs, "
                        "%llu arbitration lost, %llu waits for a hung bus\n",
                        (unsigned long long)t->starts, (unsigned long long)t->bytes,
                        (unsigned long long)t->addr_nacks, (unsigned long long)t->data_nacks,
                        (unsigned long long)t->arb_lost, (unsigned long long)t->hang_waits);
                fprintf(out, "  wires: %llu SCL pulses and %llu STOPs from the pins (bus clear); "
                        "a stuck slave held SDA %llu times, let go %llu times%s\n",
                        (unsigned long long)t->bus->gpio_falls, (unsigned long long)t->bus->gpio_stops,
                        (unsigned long long)t->bus->stuck_holds, (unsigned long long)t->bus->stuck_freed,
                        t->bus->stuck_left ? " (holds it now)" : "");
                if (n->span_from) {
                    node_span_stats_t sp = node_span_stats(n);
                    fprintf(out, "  %s -> %s: %llu times, mean %.1f us (p99 %.1f, min %.1f, max %.1f)\n",
                            span_from, span_to, (unsigned long long)sp.n, sp.mean, sp.p99,
                            sp.min, sp.max);
                }
                for (int c = 0; c < CHIP_COUNT; c++)
                    fprintf(out, "  %-8s data reads %u (%u stale: no new sample since the read "
                            "before), NACKed %u, power-on resets %u\n",
                            t->chips[c].name, t->chips[c].data_reads, t->chips[c].stale_reads,
                            t->chips[c].nacked, t->chips[c].resets);
            }
            if (n->rf)
                rf230_stats(n, out);
            if (n->uart)
                uart_stats(n, out);
        }
    }
    if (json)
        fprintf(out, "\n]}\n");
    else if (ch)
        channel_stats(ch, out);
    return rc;
}
