/*
 * emu/twi.h -- the ATmega1281 TWI (I2C master) and the board's bus, in
 * place of simavr 1.6's TWI (whose status after the address ACK is wrong):
 * read/write callbacks on TWBR TWSR TWAR TWDR TWCR TWAMR in the public
 * avr_t io table, the TWI interrupt raised by the harness.  Bus timing
 * from TWBR and the prescaler: SCL period = 16 + 2 * TWBR * 4^TWPS CPU
 * cycles; a START, a repeated START and a STOP take one period, a byte
 * nine.  Master modes only (the iris is the only master on its bus).
 * The wires (bus.h) tell it whether another driver holds a line: a START
 * waits until the bus is free, a 1 bit on a held SDA loses arbitration,
 * bytes read on it are 0, and a held SCL stalls the transfer on the wire.
 */
#ifndef EMU_TWI_H
#define EMU_TWI_H

#include <stdio.h>
#include "emu.h"
#include "bus.h"
#include "chips.h"

/* per-second sample counts are kept for this many seconds */
#define EMU_MAX_SECONDS 3600

/* A sample = a burst of transfers with less than this idle between them */
#define EMU_BURST_GAP_NS 1000000u

typedef struct emu_sample_stats {
    uint64_t n;                 /* bursts that read all three chips' data */
    uint64_t first_ns, last_ns; /* start of the first / last one */
    double span_sum, span_min, span_max;  /* us: first START asked -> last STOP done */
    double wire_sum;            /* us: START/STOP/bytes on the wire */
    double held_sum;            /* us: SCL held low waiting for the CPU (TWINT set) */
    uint64_t other_bursts;      /* bursts that did not read all three (start-up, failures) */
    uint64_t gaps;              /* periods with no sample (interval > 1.5 periods) */
    uint64_t gap_periods;       /* sum of missing periods */
    double int_min, int_max;    /* us between consecutive samples */
    uint64_t settle_ns;         /* samples before this do not count for rate/gaps */
    uint64_t n_rate;            /* samples at or after settle_ns */
    uint64_t rate_first_ns;
    uint32_t per_second[EMU_MAX_SECONDS];  /* samples starting in each emulated second */
} emu_sample_stats_t;

typedef struct emu_twi {
    emu_node_t *node;
    avr_int_vector_t vec;       /* the TWI interrupt (vector 39) */
    emu_chip_t chips[CHIP_COUNT];
    emu_chip_t *cur;            /* addressed slave, or NULL */
    int owner;                  /* 1: this master holds the bus (START .. STOP) */
    int phase;                  /* what the next TWINT-clearing command does */
    uint8_t status;             /* TWSR status (upper 5 bits) */
    int busy;                   /* an operation on the wire, event pending */
    int ev_kind;
    uint8_t ev_cmd;
    uint64_t ev_start_cycle;
    emu_bus_t *bus;             /* the two wires */
    int parked;                 /* an event waits for a line only clock pulses free */
    /* burst / sample accounting, in CPU cycles of this node */
    int in_burst;
    uint64_t burst_start, burst_last_stop, burst_wire, burst_held;
    uint64_t twint_since;       /* TWINT set while owning the bus (0: not) */
    int burst_mask;
    emu_sample_stats_t st;
    /* counters */
    uint64_t starts, bytes, addr_nacks, data_nacks, arb_lost;
    uint64_t hang_waits;        /* STARTs that waited for the bus (a line held low) */
    FILE *log;                  /* transaction log, or NULL */
} emu_twi_t;

/* Put the TWI model on the node, with the three chips on the board. */
emu_twi_t *twi_attach(emu_node_t *n, emu_board_t *board, FILE *log);
/* Close the last burst (end of the run). */
void twi_finish(emu_twi_t *t);
/* the MCU was reset: a transfer in progress is cut off (the slave sees no
 * STOP), the TWI registers hold their reset values; the chips keep theirs
 * (the sensor board is not reset with the MCU) */
void twi_reset(emu_twi_t *t);
/* SCL period in CPU cycles for the current TWBR / TWPS */
uint32_t twi_period_cycles(const emu_twi_t *t);

#endif
