/*
 * emu/chips.h -- register-level models of the board's three I2C chips:
 * ADXL345 (0x53), ITG-3200 (0x68), HMC5883L (0x1E).  The TWI model
 * (twi.c) calls them per bus event with the node's time in ns.
 */
#ifndef EMU_CHIPS_H
#define EMU_CHIPS_H

#include <stdint.h>
#include "board.h"

enum { CHIP_ADXL345, CHIP_ITG3200, CHIP_HMC5883L, CHIP_COUNT };

/* HMC5883L single measurement: data ready this long after the trigger */
#define EMU_HMC_MEAS_NS 6000000u
/* ITG-3200: gyro registers read 0 for this long after it leaves sleep */
#define EMU_ITG_STARTUP_NS 50000000u

typedef struct emu_chip {
    int kind;
    const char *name;
    uint8_t addr7;
    uint8_t regs[64];
    uint8_t ptr;
    uint8_t first;          /* 1: the next written byte is the register pointer */
    uint8_t reading;        /* addressed for reading */
    const emu_board_t *board;
    /* measurement state */
    uint64_t on_ns;         /* ADXL: measure on; ITG: awake since */
    int measuring;
    uint64_t last_sample_ns;/* instant of the sample in the data registers */
    uint64_t trig_ns;       /* HMC: single measurement started (UINT64_MAX: none) */
    int16_t trig_val[3];
    uint8_t locked;         /* HMC: data registers being read */
    uint8_t read_mask;      /* data bytes read in this transaction (bit per byte) */
    uint8_t temp_hi;        /* ITG-3200: TEMP_OUT_H read in this transaction */
    /* faults (ns windows, from <= t < until) */
    uint64_t nack_from, nack_until;
    uint64_t off_from, off_until;
    int off_pending_reset;  /* 1: the power-loss window is over and handled */
    /* stuck mid-byte (--fault stuck): the first read transaction from
     * stuck_at on ends with the chip one clock behind, holding SDA low for
     * stuck_pulses more SCL pulses (bus.h); 0: off */
    uint64_t stuck_at;
    unsigned stuck_pulses;
    int stuck_done;
    /* counters for the report */
    uint32_t nacked, resets, data_reads;
    uint32_t stale_reads;   /* data reads that got the same sample as the read before */
    uint64_t prev_read_sample_ns;
    int16_t last_data[3];   /* counts of the last complete data read */
    uint32_t temp_reads;    /* ITG-3200: TEMP_OUT_H and _L read in one transaction */
    int16_t last_temp;      /* ... the last such raw TEMP_OUT */
} emu_chip_t;

void chip_init(emu_chip_t *c, int kind, const emu_board_t *board);
/* power-on reset: registers to their datasheet reset values */
void chip_reset(emu_chip_t *c, uint64_t now_ns);
/* address byte for this chip: 1 = ACK */
int chip_addr(emu_chip_t *c, int read, uint64_t now_ns);
/* a byte written to the chip: 1 = ACK */
int chip_write(emu_chip_t *c, uint8_t v, uint64_t now_ns);
/* a byte read from the chip */
uint8_t chip_read(emu_chip_t *c, uint64_t now_ns);
/* STOP (or the transfer aborted): returns a bit mask, 1 << kind, if this
 * transaction read the chip's six data bytes */
int chip_stop(emu_chip_t *c, uint64_t now_ns);
/* At the STOP of a transaction: the SCL pulses the chip will hold SDA low
 * for if it gets stuck now (the read transaction the fault waits for), 0
 * otherwise.  It gets stuck once. */
unsigned chip_stuck(emu_chip_t *c, uint64_t now_ns);

#endif
