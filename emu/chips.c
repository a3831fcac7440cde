/*
 * emu/chips.c -- ADXL345, ITG-3200 and HMC5883L at register level.
 *
 * Common to all three: the first byte written after the address is the
 * register pointer, every further byte written or read moves it on by one
 * (burst reads auto-increment).  Datasheets: ADXL345 rev. E (register map,
 * table 19; multi-byte reads of the data registers are consistent),
 * ITG-3200 product specification rev. 1.4 (section 7), HMC5883L rev. E
 * (registers, table 2; single-measurement mode; data output lock).
 */
#include <string.h>

#include "chips.h"

#define NEVER UINT64_MAX

static const uint8_t ADDR7[CHIP_COUNT] = { 0x53, 0x68, 0x1E };
static const char *NAMES[CHIP_COUNT] = { "adxl345", "itg3200", "hmc5883l" };

void chip_init(emu_chip_t *c, int kind, const emu_board_t *board)
{
    memset(c, 0, sizeof *c);
    c->kind = kind;
    c->name = NAMES[kind];
    c->addr7 = ADDR7[kind];
    c->board = board;
    c->nack_from = c->nack_until = 0;
    c->off_from = c->off_until = 0;
    chip_reset(c, 0);
}

void chip_reset(emu_chip_t *c, uint64_t now_ns)
{
    memset(c->regs, 0, sizeof c->regs);
    c->ptr = 0;
    c->first = 0;
    c->measuring = 0;
    c->on_ns = now_ns;
    c->last_sample_ns = NEVER;
    c->trig_ns = NEVER;
    c->locked = 0;
    c->read_mask = 0;
    switch (c->kind) {
    case CHIP_ADXL345:
        c->regs[0x00] = 0xE5;    /* DEVID */
        c->regs[0x2C] = 0x0A;    /* BW_RATE: 100 Hz */
        c->regs[0x30] = 0x02;    /* INT_SOURCE: watermark */
        break;
    case CHIP_ITG3200:
        c->regs[0x00] = 0x68;    /* WHO_AM_I */
        c->measuring = 1;        /* awake after power-on (PWR_MGM = 0) */
        break;
    case CHIP_HMC5883L:
        c->regs[0x00] = 0x10;    /* CRA: 15 Hz, 1 sample */
        c->regs[0x01] = 0x20;    /* CRB: gain 1090 */
        c->regs[0x02] = 0x01;    /* MODE: single (no measurement until written) */
        c->regs[0x0A] = 'H';
        c->regs[0x0B] = '4';
        c->regs[0x0C] = '3';
        break;
    }
}

static int powered(emu_chip_t *c, uint64_t now)
{
    if (c->off_until && now >= c->off_from && !c->off_pending_reset) {
        if (now < c->off_until)
            return 0;
        c->off_pending_reset = 1;        /* power is back: reset values */
        chip_reset(c, now);
        c->resets++;
    }
    return 1;
}

static int16_t clip(long v, long lo, long hi)
{
    return (int16_t)(v < lo ? lo : v > hi ? hi : v);
}

/* ---- ADXL345 -------------------------------------------------------- */
static void adxl_update(emu_chip_t *c, uint64_t now)
{
    if (!c->measuring)
        return;
    /* output data rate from BW_RATE's rate code: 3200 Hz / 2^(15 - code) */
    uint8_t code = c->regs[0x2C] & 0x0F;
    double odr = 3200.0 / (double)(1u << (15 - code));
    uint64_t period = (uint64_t)(1e9 / odr);
    if (now < c->on_ns + period)
        return;                          /* no sample yet */
    uint64_t k = (now - c->on_ns) / period;
    uint64_t t = c->on_ns + k * period;
    if (t == c->last_sample_ns)
        return;
    c->last_sample_ns = t;
    int16_t v[9];
    board_truth(c->board, t, v, NULL);
    uint8_t fmt = c->regs[0x31];
    int range = fmt & 3;
    for (int i = 0; i < 3; i++) {
        long x;
        if (fmt & 0x08)                  /* FULL_RES: 3.9 mg/LSB, 10..13 bits */
            x = clip(v[i], -(512L << range), (512L << range) - 1);
        else                             /* 10 bits at +-2g << range */
            x = clip(v[i] / (1 << range), -512, 511);
        c->regs[0x32 + 2 * i] = (uint8_t)(x & 0xFF);
        c->regs[0x33 + 2 * i] = (uint8_t)((x >> 8) & 0xFF);
    }
    c->regs[0x30] |= 0x80;               /* DATA_READY */
}

static void adxl_write(emu_chip_t *c, uint8_t reg, uint8_t v, uint64_t now)
{
    if (reg == 0x00 || (reg >= 0x01 && reg <= 0x1C) || reg == 0x30
        || (reg >= 0x32 && reg <= 0x37) || reg == 0x39 || reg > 0x39)
        return;                          /* read-only or reserved */
    c->regs[reg] = v;
    if (reg == 0x2D) {                   /* POWER_CTL: Measure bit */
        int m = (v & 0x08) != 0;
        if (m && !c->measuring)
            c->on_ns = now;
        c->measuring = m;
    }
}

/* ---- ITG-3200 ------------------------------------------------------- */
static void itg_update(emu_chip_t *c, uint64_t now)
{
    if (!c->measuring || now < c->on_ns + EMU_ITG_STARTUP_NS)
        return;
    double internal = (c->regs[0x16] & 7) ? 1000.0 : 8000.0;
    double fs = internal / (c->regs[0x15] + 1.0);
    uint64_t period = (uint64_t)(1e9 / fs);
    uint64_t t0 = c->on_ns + EMU_ITG_STARTUP_NS;
    uint64_t t = t0 + (now - t0) / period * period;
    if (t == c->last_sample_ns)
        return;
    c->last_sample_ns = t;
    int16_t v[9];
    double temp;
    board_truth(c->board, t, v, &temp);
    int16_t raw_t = clip((long)(-13200.0 + 280.0 * (temp - 35.0)), -32768, 32767);
    c->regs[0x1B] = (uint8_t)((uint16_t)raw_t >> 8);
    c->regs[0x1C] = (uint8_t)raw_t;
    for (int i = 0; i < 3; i++) {
        c->regs[0x1D + 2 * i] = (uint8_t)((uint16_t)v[3 + i] >> 8);
        c->regs[0x1E + 2 * i] = (uint8_t)v[3 + i];
    }
    c->regs[0x1A] |= 0x01;               /* INT_STATUS: RAW_DATA_RDY */
}

static void itg_write(emu_chip_t *c, uint8_t reg, uint8_t v, uint64_t now)
{
    if ((reg >= 0x1A && reg <= 0x22) || reg > 0x3E)
        return;                          /* read-only */
    if (reg == 0x00) {                   /* WHO_AM_I: only bits 6..1 */
        c->regs[0] = (uint8_t)((c->regs[0] & 0x81) | (v & 0x7E));
        return;
    }
    if (reg == 0x3E) {                   /* PWR_MGM */
        if (v & 0x80) {                  /* H_RESET */
            chip_reset(c, now);
            return;
        }
        int awake = !(v & 0x40);
        if (awake && !c->measuring)
            c->on_ns = now;
        c->measuring = awake;
    }
    c->regs[reg] = v;
}

/* ---- HMC5883L ------------------------------------------------------- */
static const uint16_t HMC_GAIN[8] = { 1370, 1090, 820, 660, 440, 390, 330, 230 };

static void hmc_store(emu_chip_t *c, const int16_t xyz[3])
{
    uint16_t g = HMC_GAIN[c->regs[0x01] >> 5];
    static const int order[3] = { 0, 2, 1 };   /* registers hold X, Z, Y */
    for (int j = 0; j < 3; j++) {
        long x = xyz[order[j]];
        x = (x * g + (x >= 0 ? 545 : -545)) / 1090;
        if (x < -2048 || x > 2047)
            x = -4096;                   /* overflow */
        c->regs[0x03 + 2 * j] = (uint8_t)((uint16_t)x >> 8);
        c->regs[0x04 + 2 * j] = (uint8_t)x;
    }
    c->regs[0x09] |= 0x01;               /* STATUS: RDY */
}

static void hmc_update(emu_chip_t *c, uint64_t now)
{
    if (c->locked)
        return;                          /* data output lock: applied at unlock */
    if (c->trig_ns != NEVER && now >= c->trig_ns + EMU_HMC_MEAS_NS) {
        hmc_store(c, c->trig_val);
        c->last_sample_ns = c->trig_ns;
        c->trig_ns = NEVER;
        c->regs[0x02] = (uint8_t)((c->regs[0x02] & 0x80) | 0x03);   /* back to idle */
    }
    if ((c->regs[0x02] & 3) == 0 && c->measuring) {   /* continuous */
        static const double DO_HZ[8] = { 0.75, 1.5, 3, 7.5, 15, 30, 75, 75 };
        uint64_t period = (uint64_t)(1e9 / DO_HZ[(c->regs[0x00] >> 2) & 7]);
        if (now < c->on_ns + period)
            return;
        uint64_t t = c->on_ns + (now - c->on_ns) / period * period;
        if (t != c->last_sample_ns) {
            int16_t v[9];
            board_truth(c->board, t, v, NULL);
            hmc_store(c, v + 6);
            c->last_sample_ns = t;
        }
    }
}

static void hmc_write(emu_chip_t *c, uint8_t reg, uint8_t v, uint64_t now)
{
    if (reg > 0x02)
        return;
    c->regs[reg] = v;
    if (reg == 0x02) {
        uint8_t md = v & 3;
        if (md == 1) {                   /* single measurement: starts now */
            int16_t t[9];
            board_truth(c->board, now, t, NULL);
            memcpy(c->trig_val, t + 6, sizeof c->trig_val);
            c->trig_ns = now;
            c->measuring = 0;
        } else if (md == 0) {
            c->measuring = 1;
            c->on_ns = now;
        } else {
            c->measuring = 0;
        }
    }
}

/* ---- common --------------------------------------------------------- */
static void update(emu_chip_t *c, uint64_t now)
{
    switch (c->kind) {
    case CHIP_ADXL345: adxl_update(c, now); break;
    case CHIP_ITG3200: itg_update(c, now); break;
    case CHIP_HMC5883L: hmc_update(c, now); break;
    }
}

static uint8_t data_reg(const emu_chip_t *c)
{
    return c->kind == CHIP_ADXL345 ? 0x32 : c->kind == CHIP_ITG3200 ? 0x1D : 0x03;
}

int chip_addr(emu_chip_t *c, int read, uint64_t now)
{
    if (!powered(c, now))
        return 0;
    if (c->nack_until && now >= c->nack_from && now < c->nack_until) {
        c->nacked++;
        return 0;
    }
    c->reading = (uint8_t)read;
    c->first = !read;
    c->read_mask = 0;
    if (read)
        update(c, now);   /* the data registers hold the newest sample for the whole read */
    return 1;
}

/* The register pointer after an access to reg.  The HMC5883L's (datasheet
 * rev. E, "I2C Communication Protocol"): "if (address pointer = 08) then
 * address pointer = 03, else if (address pointer >= 12) then address
 * pointer = 0, else (address pointer) = (address pointer) + 1": a burst
 * through the data registers starts over at X MSB, and a read without a
 * pointer write after one reads the data again. */
static uint8_t next_ptr(const emu_chip_t *c, uint8_t reg)
{
    if (c->kind != CHIP_HMC5883L)
        return (uint8_t)(reg + 1);
    return (uint8_t)(reg == 0x08 ? 0x03 : reg >= 12 ? 0 : reg + 1);
}

int chip_write(emu_chip_t *c, uint8_t v, uint64_t now)
{
    if (!powered(c, now))
        return 0;
    if (c->first) {
        c->first = 0;
        c->ptr = v;
        return 1;
    }
    uint8_t reg = c->ptr;
    update(c, now);
    switch (c->kind) {
    case CHIP_ADXL345: adxl_write(c, reg, v, now); break;
    case CHIP_ITG3200: itg_write(c, reg, v, now); break;
    case CHIP_HMC5883L: hmc_write(c, reg, v, now); break;
    }
    c->ptr = next_ptr(c, reg);
    return 1;
}

uint8_t chip_read(emu_chip_t *c, uint64_t now)
{
    if (!powered(c, now))
        return 0xFF;                     /* nobody drives SDA: pull-up */
    uint8_t reg = c->ptr;
    uint8_t v = reg < sizeof c->regs ? c->regs[reg] : 0;
    uint8_t d = data_reg(c);
    if (reg >= d && reg < d + 6)
        c->read_mask |= (uint8_t)(1u << (reg - d));
    switch (c->kind) {
    case CHIP_ADXL345:
        if (reg == 0x30)
            c->regs[0x30] &= (uint8_t)~0x80;
        break;
    case CHIP_ITG3200:
        if (reg == 0x1A)
            c->regs[0x1A] &= (uint8_t)~0x01;
        if (reg == 0x1B)
            c->temp_hi = 1;              /* TEMP_OUT_H read in this transaction */
        if (reg == 0x1C && c->temp_hi) {
            c->temp_reads++;
            c->last_temp = (int16_t)(uint16_t)((c->regs[0x1B] << 8) | c->regs[0x1C]);
        }
        break;
    case CHIP_HMC5883L:
        if (reg >= 0x03 && reg <= 0x08) {
            c->locked = 1;
            if (c->read_mask == 0x3F) {   /* all six read: unlock, RDY off */
                c->locked = 0;
                c->regs[0x09] &= (uint8_t)~0x01;
            }
        }
        break;
    }
    c->ptr = next_ptr(c, reg);
    return v;
}

int chip_stop(emu_chip_t *c, uint64_t now)
{
    (void)now;
    int done = c->reading && c->read_mask == 0x3F;
    if (done) {
        c->data_reads++;
        if (c->data_reads > 1 && c->last_sample_ns == c->prev_read_sample_ns)
            c->stale_reads++;             /* standby, asleep, no new measurement */
        c->prev_read_sample_ns = c->last_sample_ns;
        uint8_t d = data_reg(c);
        for (int i = 0; i < 3; i++) {
            const uint8_t *b = c->regs + d + 2 * i;
            c->last_data[i] = (int16_t)(c->kind == CHIP_ADXL345 ? (b[0] | b[1] << 8)
                                                                : (b[0] << 8 | b[1]));
        }
    }
    c->reading = 0;
    c->first = 0;
    c->read_mask = 0;
    c->temp_hi = 0;
    return done ? 1 << c->kind : 0;
}

unsigned chip_stuck(emu_chip_t *c, uint64_t now)
{
    /* a slave that missed a clock edge in the last data byte: it thinks
     * it is still sending, with 0 bits, when the master NACKs and stops */
    if (!c->stuck_pulses || c->stuck_done || !c->reading || now < c->stuck_at)
        return 0;
    c->stuck_done = 1;
    return c->stuck_pulses;
}
