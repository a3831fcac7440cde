/*
 * emu/twi.c -- the ATmega1281 TWI in master mode and the board's I2C bus
 * (twi.h).  ATmega1281 datasheet, "2-wire Serial Interface": TWCR bits,
 * the status codes of master transmitter / receiver mode, TWINT cleared by
 * writing one, TWDR writable only while TWINT is set (else TWWC), TWSTO
 * cleared by the hardware when the STOP has been sent.
 */
#include <stdlib.h>
#include <string.h>

#include "sim_io.h"
#include "twi.h"
#include "node.h"

enum { R_TWBR = 0xB8, R_TWSR = 0xB9, R_TWAR = 0xBA, R_TWDR = 0xBB, R_TWCR = 0xBC, R_TWAMR = 0xBD };
enum { TWINT = 0x80, TWEA = 0x40, TWSTA = 0x20, TWSTO = 0x10, TWWC = 0x08, TWEN = 0x04, TWIE = 0x01 };
enum { TWI_VECTOR = 39 };
enum { PH_IDLE, PH_SLA, PH_MT, PH_MR, PH_VOID };
enum { EV_START, EV_STOP, EV_SLA, EV_TX, EV_RX };

#define SAMPLE_PERIOD_NS 8000000.0

static uint64_t now_ns(const emu_twi_t *t) { return emu_node_now_ns(t->node); }
static double cyc_us(const emu_twi_t *t, uint64_t c) { return c * 1e6 / t->node->freq_hz; }

uint32_t twi_period_cycles(const emu_twi_t *t)
{
    const uint8_t *d = t->node->avr->data;
    uint32_t ps = d[R_TWSR] & 3;
    return 16u + 2u * d[R_TWBR] * (1u << (2 * ps));
}

static void logf_(emu_twi_t *t, const char *fmt, unsigned a, unsigned b)
{
    if (!t->log)
        return;
    fprintf(t->log, "%llu %d ", (unsigned long long)now_ns(t), t->node->index);
    fprintf(t->log, fmt, a, b);
    fputc('\n', t->log);
}

/* SDA held low by another driver (a short, a stuck slave) */
static int hang(const emu_twi_t *t, uint64_t ns)
{
    return bus_held(t->bus, BUS_SDA, ns);
}

/* ---- sample accounting ------------------------------------------------ */
static void burst_close(emu_twi_t *t)
{
    if (!t->in_burst)
        return;
    t->in_burst = 0;
    emu_sample_stats_t *s = &t->st;
    if (t->burst_mask != (1 << CHIP_COUNT) - 1) {
        s->other_bursts++;
        return;
    }
    double span = cyc_us(t, t->burst_last_stop - t->burst_start);
    uint64_t start_ns = (uint64_t)(t->burst_start * 1e9 / t->node->freq_hz);
    if (!s->n) {
        s->first_ns = start_ns;
        s->span_min = s->span_max = span;
    }
    s->n++;
    if (start_ns / 1000000000u < EMU_MAX_SECONDS)
        s->per_second[start_ns / 1000000000u]++;
    s->span_sum += span;
    if (span < s->span_min) s->span_min = span;
    if (span > s->span_max) s->span_max = span;
    s->wire_sum += cyc_us(t, t->burst_wire);
    s->held_sum += cyc_us(t, t->burst_held);
    if (start_ns >= s->settle_ns) {
        if (s->n_rate) {
            double iv = (start_ns - s->last_ns) / 1e3;
            if (s->n_rate == 1 || iv < s->int_min) s->int_min = iv;
            if (s->n_rate == 1 || iv > s->int_max) s->int_max = iv;
            if (iv * 1e3 > 1.5 * SAMPLE_PERIOD_NS) {
                s->gaps++;
                s->gap_periods += (uint64_t)(iv * 1e3 / SAMPLE_PERIOD_NS + 0.5) - 1;
            }
        } else {
            s->rate_first_ns = start_ns;
        }
        s->n_rate++;
    }
    s->last_ns = start_ns;
    if (t->log)
        fprintf(t->log, "%llu %d SAMPLE span_us=%.1f wire_us=%.1f held_us=%.1f\n",
                (unsigned long long)start_ns, t->node->index, span,
                cyc_us(t, t->burst_wire), cyc_us(t, t->burst_held));
}

void twi_finish(emu_twi_t *t)
{
    burst_close(t);
}

/* ---- the interrupt ------------------------------------------------------ */
static void set_twint(emu_twi_t *t, uint8_t status)
{
    avr_t *avr = t->node->avr;
    t->status = status;
    avr->data[R_TWSR] = (uint8_t)(status | (avr->data[R_TWSR] & 3));
    if (t->owner)
        t->twint_since = avr->cycle;
    avr_raise_interrupt(avr, &t->vec);      /* sets TWINT (the 'raised' bit) */
    avr->data[R_TWCR] |= TWINT;
}

static avr_cycle_count_t twi_event(avr_t *avr, avr_cycle_count_t when, void *param);

static void schedule(emu_twi_t *t, int kind, uint32_t periods, uint8_t cmd)
{
    avr_t *avr = t->node->avr;
    t->busy = 1;
    t->ev_kind = kind;
    t->ev_cmd = cmd;
    t->ev_start_cycle = avr->cycle;
    avr_cycle_timer_register(avr, (avr_cycle_count_t)periods * twi_period_cycles(t), twi_event, t);
}

static void slave_stop(emu_twi_t *t)
{
    if (t->cur) {
        t->burst_mask |= chip_stop(t->cur, now_ns(t));
        t->cur = NULL;
    }
}

/* what a START request does: start now, or wait while SDA is held low */
static void want_start(emu_twi_t *t)
{
    uint64_t ns = now_ns(t);
    if (!t->owner) {
        avr_t *avr = t->node->avr;
        if (!t->in_burst || ns - (uint64_t)(t->burst_last_stop * 1e9 / t->node->freq_hz)
                              > EMU_BURST_GAP_NS) {
            burst_close(t);
            t->in_burst = 1;
            t->burst_start = avr->cycle;
            t->burst_last_stop = avr->cycle;
            t->burst_wire = t->burst_held = 0;
            t->burst_mask = 0;
        }
    }
    uint64_t free_at = t->owner ? ns : bus_free_at(t->bus, ns);
    if (free_at != ns) {
        /* bus busy: the TWI waits for the bus to be free (a STOP, which
         * the line's release makes); a stuck slave frees it only with clock
         * pulses, which the TWI, waiting, never gives: it waits until it is
         * switched off (TWEN) */
        t->hang_waits++;
        logf_(t, "HANG-WAIT", 0, 0);
        t->busy = 1;
        t->ev_kind = EV_START;
        if (free_at == UINT64_MAX) {
            t->parked = 1;
            return;
        }
        uint64_t wait = node_ns_to_cycles(t->node, free_at - ns);
        t->ev_start_cycle = t->node->avr->cycle + wait;   /* the wait is not wire time */
        avr_cycle_timer_register(t->node->avr, wait + twi_period_cycles(t), twi_event, t);
        return;
    }
    schedule(t, EV_START, 1, 0);
}

/* SCL held low by another driver: the event on the wire waits for it */
static int scl_stalled(emu_twi_t *t, uint64_t ns)
{
    if (!bus_held(t->bus, BUS_SCL, ns))
        return 0;
    uint64_t end = t->bus->short_until[BUS_SCL];
    if (end == UINT64_MAX)
        t->parked = 1;
    else
        avr_cycle_timer_register(t->node->avr, node_ns_to_cycles(t->node, end - ns) + 1,
                                 twi_event, t);
    return 1;
}

static avr_cycle_count_t twi_event(avr_t *avr, avr_cycle_count_t when, void *param)
{
    (void)when;
    emu_twi_t *t = param;
    uint64_t ns = now_ns(t);
    int kind = t->ev_kind;
    if (kind == EV_START && !t->owner && bus_free_at(t->bus, ns) != ns) {
        t->busy = 0;                 /* still busy (a line held again): wait on */
        want_start(t);
        return 0;
    }
    if (kind != EV_START && scl_stalled(t, ns))
        return 0;
    t->busy = 0;
    if (t->in_burst)
        t->burst_wire += avr->cycle - t->ev_start_cycle;
    switch (kind) {
    case EV_START: {
        int rep = t->owner;
        slave_stop(t);               /* a repeated START ends the slave's transfer */
        t->owner = 1;
        t->phase = PH_SLA;
        t->starts++;
        logf_(t, rep ? "Sr" : "S", 0, 0);
        set_twint(t, rep ? 0x10 : 0x08);
        break;
    }
    case EV_STOP: {
        /* a slave stuck mid-byte (--fault stuck) holds SDA low: no STOP on
         * the wire, although the TWI has done its part (TWSTO cleared) */
        emu_chip_t *c = t->cur;
        unsigned stuck = c ? chip_stuck(c, ns) : 0;
        slave_stop(t);
        t->owner = 0;
        t->phase = PH_IDLE;
        avr->data[R_TWCR] &= (uint8_t)~TWSTO;
        t->burst_last_stop = avr->cycle;
        logf_(t, stuck ? "P (SDA held: no STOP)" : "P", 0, 0);
        if (stuck)
            bus_stick(t->bus, c->name, stuck);
        if (t->ev_cmd & TWSTA)       /* STOP then START */
            want_start(t);
        break;
    }
    case EV_SLA: {
        uint8_t sla = avr->data[R_TWDR];
        int read = sla & 1;
        if (hang(t, ns) && sla != 0) {   /* SDA low: a 1 bit is lost */
            t->owner = 0; t->phase = PH_IDLE; t->arb_lost++;
            slave_stop(t);
            logf_(t, "A%02x L", sla, 0);
            set_twint(t, 0x38);
            break;
        }
        t->cur = NULL;
        for (int i = 0; i < CHIP_COUNT; i++)
            if (t->chips[i].addr7 == (sla >> 1)) {
                if (chip_addr(&t->chips[i], read, ns))
                    t->cur = &t->chips[i];
                break;
            }
        int ack = t->cur != NULL || hang(t, ns);
        t->bytes++;
        if (!ack)
            t->addr_nacks++;
        logf_(t, ack ? "A%02x a" : "A%02x n", sla, 0);
        t->phase = ack ? (read ? PH_MR : PH_MT) : PH_VOID;
        set_twint(t, read ? (ack ? 0x40 : 0x48) : (ack ? 0x18 : 0x20));
        break;
    }
    case EV_TX: {
        uint8_t b = avr->data[R_TWDR];
        t->bytes++;
        if (hang(t, ns) && b != 0) {
            t->owner = 0; t->phase = PH_IDLE; t->arb_lost++;
            slave_stop(t);
            logf_(t, "W%02x L", b, 0);
            set_twint(t, 0x38);
            break;
        }
        int ack = hang(t, ns) || (t->cur && chip_write(t->cur, b, ns));
        if (!ack)
            t->data_nacks++;
        logf_(t, ack ? "W%02x a" : "W%02x n", b, 0);
        set_twint(t, ack ? 0x28 : 0x30);
        break;
    }
    case EV_RX: {
        int ack = (t->ev_cmd & TWEA) != 0;
        uint8_t b = hang(t, ns) ? 0x00 : t->cur ? chip_read(t->cur, ns) : 0xFF;
        t->bytes++;
        avr->data[R_TWDR] = b;
        logf_(t, ack ? "R%02x a" : "R%02x n", b, 0);
        set_twint(t, ack ? 0x50 : 0x58);
        break;
    }
    }
    return 0;
}

/* ---- register writes ----------------------------------------------------- */
static void twi_disable(emu_twi_t *t);

void twi_reset(emu_twi_t *t)
{
    twi_disable(t);       /* the MCU's reset: a transfer is cut off, no STOP */
    burst_close(t);
    t->node->avr->data[R_TWSR] = 0xF8;
    t->node->avr->data[R_TWBR] = 0;
    t->node->avr->data[R_TWCR] = 0;
    t->node->avr->data[R_TWDR] = 0xFF;
}

static void twi_disable(emu_twi_t *t)
{
    avr_t *avr = t->node->avr;
    if (t->busy) {
        avr_cycle_timer_cancel(avr, twi_event, t);
        t->busy = 0;
        t->parked = 0;
    }
    if (t->owner) {                     /* the transfer is cut off; no STOP */
        slave_stop(t);
        t->owner = 0;
        t->burst_last_stop = avr->cycle;
        logf_(t, "OFF", 0, 0);
    }
    t->phase = PH_IDLE;
    t->twint_since = 0;
    avr->data[R_TWSR] = (uint8_t)(0xF8 | (avr->data[R_TWSR] & 3));
}

static void twcr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    (void)addr;
    emu_twi_t *t = param;
    uint8_t old = avr->data[R_TWCR];
    if (getenv("EMU_TWI_TRACE"))
        fprintf(stderr, "%llu TWCR %02x (was %02x) TWDR %02x pc %05x busy %d phase %d\n",
                (unsigned long long)now_ns(t), v, old, avr->data[R_TWDR], avr->pc, t->busy, t->phase);
    uint8_t flag = old & (TWINT | TWWC);
    if (v & TWINT) {                    /* writing one clears TWINT (and TWWC) */
        flag = 0;
        avr_clear_interrupt(avr, &t->vec);
        if (t->twint_since && t->in_burst)
            t->burst_held += avr->cycle - t->twint_since;
        t->twint_since = 0;
    }
    avr->data[R_TWCR] = (uint8_t)(flag | (v & (TWEA | TWSTA | TWSTO | TWEN | TWIE)));
    if ((old ^ v) & TWEN)
        bus_update(t->bus);             /* the pins go to the TWI or back to the port */
    if (!(v & TWEN)) {
        twi_disable(t);
        return;
    }
    if (!(v & TWINT)) {
        /* the interrupt is level-triggered: TWIE set while TWINT is set */
        if ((flag & TWINT) && (v & TWIE) && !(old & TWIE))
            avr_raise_interrupt(avr, &t->vec);
        return;
    }
    if (t->busy) {
        /* a START asked while the STOP is still going: it follows the STOP */
        if (t->ev_kind == EV_STOP && (v & TWSTA))
            t->ev_cmd |= TWSTA;
        return;                         /* otherwise: an operation is on the wire */
    }
    if (v & TWSTO) {
        if (t->owner) {
            schedule(t, EV_STOP, 1, v);
        } else {                        /* not on the bus: nothing to send */
            avr->data[R_TWCR] &= (uint8_t)~TWSTO;
            if (v & TWSTA)
                want_start(t);
        }
        return;
    }
    if (v & TWSTA) {
        want_start(t);
        return;
    }
    switch (t->phase) {
    case PH_SLA: schedule(t, EV_SLA, 9, v); break;
    case PH_MT: schedule(t, EV_TX, 9, v); break;
    case PH_MR: schedule(t, EV_RX, 9, v); break;
    case PH_VOID:                       /* after a NACK: bytes to nobody */
        schedule(t, (t->status & 0x40) ? EV_RX : EV_TX, 9, v);
        break;
    default:
        break;                          /* not on the bus: nothing happens */
    }
}

static void twdr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    (void)addr; (void)param;
    if (avr->data[R_TWCR] & TWINT)
        avr->data[R_TWDR] = v;
    else
        avr->data[R_TWCR] |= TWWC;
}

static void twsr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    (void)addr; (void)param;
    avr->data[R_TWSR] = (uint8_t)((avr->data[R_TWSR] & 0xF8) | (v & 3));
}

static void plain_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    (void)param;
    avr->data[addr] = v;
}

static void twi_reset_hook(void *param)
{
    twi_reset(param);
}

emu_twi_t *twi_attach(emu_node_t *n, emu_board_t *board, FILE *log)
{
    avr_t *avr = n->avr;
    emu_twi_t *t = calloc(1, sizeof *t);
    t->node = n;
    t->log = log;
    t->bus = bus_attach(n, log);
    n->reset_hook = twi_reset_hook;
    n->reset_param = t;
    for (int i = 0; i < CHIP_COUNT; i++)
        chip_init(&t->chips[i], i, board);
    t->vec.vector = TWI_VECTOR;
    t->vec.enable = (avr_regbit_t)AVR_IO_REGBIT(R_TWCR, 0);     /* TWIE */
    t->vec.raised = (avr_regbit_t)AVR_IO_REGBIT(R_TWCR, 7);     /* TWINT */
    t->vec.raise_sticky = 1;            /* TWINT stays set in the handler */
    avr_register_vector(avr, &t->vec);
    /* take the six registers from simavr's TWI: the table entries are
     * replaced, not shared (avr_register_io_write would chain both) */
    static const avr_io_addr_t regs[] = { R_TWBR, R_TWSR, R_TWAR, R_TWDR, R_TWCR, R_TWAMR };
    for (unsigned i = 0; i < sizeof regs / sizeof regs[0]; i++) {
        int a = AVR_DATA_TO_IO(regs[i]);
        avr->io[a].r.c = NULL;
        avr->io[a].r.param = NULL;
        avr->io[a].w.c = NULL;
        avr->io[a].w.param = NULL;
    }
    avr_register_io_write(avr, R_TWBR, plain_write, t);
    avr_register_io_write(avr, R_TWAR, plain_write, t);
    avr_register_io_write(avr, R_TWAMR, plain_write, t);
    avr_register_io_write(avr, R_TWSR, twsr_write, t);
    avr_register_io_write(avr, R_TWDR, twdr_write, t);
    avr_register_io_write(avr, R_TWCR, twcr_write, t);
    avr->data[R_TWSR] = 0xF8;
    avr->data[R_TWDR] = 0xFF;
    avr->data[R_TWAR] = 0xFE;
    n->twi = t;
    return t;
}
