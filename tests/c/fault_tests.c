/*
 * fault_tests.c -- the board's fault handling (tinyos/ninedof_fault.c) and
 * the chip descriptors it relies on (tinyos/ninedof_board.c), built twice
 * by tests/test_fault.py: with gcc on the host and with avr-gcc in simavr.
 *
 *  - the bus clear against a model of the two open-drain lines and a
 *    slave that holds SDA low for the rest of the byte it was sending,
 *    stretches the clock, or has a line shorted to ground;
 *  - the watchdog, the counters and the check schedule step by step;
 *  - a 2400-period scenario of a board whose chips reset, stop answering
 *    and hang the bus, run by the decisions alone;
 *  - what the board does when a bus clear fails (a line shorted to
 *    ground): the bus down, reads refused, a clear every 256 ms, the bus
 *    up and every chip checked when a clear finds the lines high, for a
 *    master that ends an aborted operation (lean) and one that cannot
 *    (stock).
 *
 * Prints "B<name>:<pulses>:<result>:<stop>;" per bus-clear case,
 * "S<hex>;" for the scenario and "D<master>:<hex>;" per short scenario
 * (read by the Python test), then
 * "CHECKS <n> FAILED <m>;END" (test_check.h).
 */
#include <stdint.h>
#include <string.h>

#include "ninedof_board.h"
#include "ninedof_fault.h"

#include "test_out.h"
#include "test_check.h"

/* ---------------------------------------------------------------------- */
/* Bus clear                                                               */
/* ---------------------------------------------------------------------- */
typedef struct {
  uint16_t bits;         /* bits still to put on SDA, LSB first (1 = release) */
  uint8_t nbits;
  uint8_t sda_low;       /* the slave drives SDA low now */
  uint8_t stretch;       /* half periods it holds SCL low after a falling edge */
  uint8_t hold;          /* ... left */
  uint8_t short_sda, short_scl;
  /* master's drive */
  uint8_t m_scl, m_sda;
  /* what the bus saw */
  uint8_t falls, starts, stops, sda_fall_scl_high;
} bus_t;

static uint8_t bus_scl(const bus_t *b) { return b->m_scl && !b->hold && !b->short_scl; }
static uint8_t bus_sda(const bus_t *b) { return b->m_sda && !b->sda_low && !b->short_sda; }

/* One bus clear on `b`; returns the result (NINEDOF_BC_DONE | ...). */
static uint8_t run_clear(bus_t *b, uint16_t *steps)
{
  ninedof_busclear_t bc;
  uint8_t act;
  b->m_scl = b->m_sda = 1;
  ninedof_busclear_init(&bc);
  for (*steps = 0; *steps < 1000; (*steps)++) {
    uint8_t scl = bus_scl(b), sda = bus_sda(b), scl2, sda2;
    act = ninedof_busclear_step(&bc, scl, sda);
    if (act & NINEDOF_BC_DONE)
      return act;
    if (b->hold)
      b->hold--;
    b->m_scl = act & NINEDOF_BC_SCL ? 1 : 0;
    b->m_sda = act & NINEDOF_BC_SDA ? 1 : 0;
    scl2 = bus_scl(b);
    if (scl && !scl2 && !b->short_scl) {          /* falling edge: next bit */
      b->falls++;
      if (b->nbits) {
        b->sda_low = !(b->bits & 1);
        b->bits >>= 1;
        b->nbits--;
      } else {
        b->sda_low = 0;
      }
      b->hold = b->stretch;
      scl2 = bus_scl(b);
    }
    sda2 = bus_sda(b);
    if (scl && scl2 && sda && !sda2)
      b->starts++;
    if (scl && scl2 && !sda && sda2)
      b->stops++;
    if (scl2 && !b->m_sda && sda)
      b->sda_fall_scl_high++;
  }
  return 0;
}

static void clear_case(const char *name, bus_t *b, uint8_t want_pulses, uint8_t want_result)
{
  uint16_t steps;
  uint8_t r = run_clear(b, &steps);
  CHECK(r == want_result);
  CHECK(b->falls == want_pulses && b->falls <= NINEDOF_BUSCLEAR_PULSES + 1);
  CHECK(b->stops <= 1);
  CHECK(b->starts == 0 && b->sda_fall_scl_high == 0);   /* never a START */
  CHECK(steps <= NINEDOF_BUSCLEAR_MAX_STEPS);
  if (!(r & (NINEDOF_BC_SCL_STUCK | NINEDOF_BC_SDA_STUCK)))
    CHECK(b->stops == 1 && b->m_scl && b->m_sda);
  out_c('B');
  out_s(name);
  out_c(':');
  out_u16(b->falls);
  out_c(':');
  out_u16(r);
  out_c(':');
  out_u16(b->stops);
  out_c(';');
}

static void test_busclear(void)
{
  bus_t b;
  uint8_t k;

  /* a free bus: no pulse, one STOP */
  memset(&b, 0, sizeof(b));
  clear_case("free", &b, 1, NINEDOF_BC_DONE);

  /* a slave sending a byte, with k low bits left on the bus (the first is
   * on SDA now): k pulses let it go; 9 pulses cover a whole byte + ACK */
  for (k = 1; k <= 9; k++) {
    char name[6] = "low0";
    memset(&b, 0, sizeof(b));
    b.sda_low = 1;
    b.bits = 0;                  /* k - 1 more low bits, then released */
    b.nbits = (uint8_t)(k - 1);
    name[3] = (char)('0' + k);
    clear_case(name, &b, (uint8_t)(k + 1), NINEDOF_BC_DONE);   /* + the STOP's fall */
  }
  /* mixed bits: 0 (now), 1, 0, 0, 1, then released */
  memset(&b, 0, sizeof(b));
  b.sda_low = 1;
  b.bits = 0x9;                  /* 1, 0, 0, 1 */
  b.nbits = 4;
  clear_case("mixed", &b, 5, NINEDOF_BC_DONE);   /* SDA high after pulse 1: a STOP
                                                   * tried, the slave sends on; again at 4 */
  /* clock stretching: 6 half periods after every falling edge */
  memset(&b, 0, sizeof(b));
  b.sda_low = 1;
  b.nbits = 3;
  b.stretch = 6;
  clear_case("stretch", &b, 5, NINEDOF_BC_DONE);
  /* SDA shorted to ground: 9 pulses, the STOP attempt, reported stuck */
  memset(&b, 0, sizeof(b));
  b.short_sda = 1;
  clear_case("sdashort", &b, 10, NINEDOF_BC_DONE | NINEDOF_BC_SDA_STUCK);
  /* SCL shorted to ground: given up after the stretch bound */
  memset(&b, 0, sizeof(b));
  b.short_scl = 1;
  clear_case("sclshort", &b, 0, NINEDOF_BC_DONE | NINEDOF_BC_SCL_STUCK);
}

/* ---------------------------------------------------------------------- */
/* Chip descriptors: the table the driver and the check use                */
/* ---------------------------------------------------------------------- */
static void test_chip_table(void)
{
  uint8_t chip, i, n;
  static const uint8_t adxl_id[1] = { 0xE5 }, itg_id[1] = { 0x69 }, hmc_id[3] = { 'H', '4', '3' };
  static const uint8_t bytes[6] = { 1, 2, 3, 4, 5, 6 };
  int16_t a[3], b[3];

  for (chip = 0; chip < NINEDOF_CHIPS; chip++) {
    const ninedof_chip_t *c = &NINEDOF_CHIP[chip];
    CHECK(c->witness < c->config_len && c->read_len >= 1 && c->read_len <= 2);
    /* the witness tells a reset chip from a configured one */
    CHECK(c->config[c->witness].value != c->witness_reset);
    for (i = 0, n = 0; i < c->config_len; i++)
      n += c->config[i].reg == c->config[c->witness].reg;
    CHECK(n == 1);
    CHECK(c->id_len >= 1 && c->id_len <= NINEDOF_CHIP_DATA);
  }
  CHECK(NINEDOF_CHIP[NINEDOF_CHIP_ACCEL].config == NINEDOF_ADXL345_CONFIG);
  CHECK(NINEDOF_CHIP[NINEDOF_CHIP_GYRO].config == NINEDOF_ITG3200_CONFIG);
  CHECK(NINEDOF_CHIP[NINEDOF_CHIP_MAG].config == NINEDOF_HMC5883L_CONFIG);
  CHECK(NINEDOF_CHIP[NINEDOF_CHIP_ACCEL].sleep.reg == NINEDOF_ADXL345_SLEEP.reg &&
        NINEDOF_CHIP[NINEDOF_CHIP_ACCEL].sleep.value == NINEDOF_ADXL345_SLEEP.value);
  CHECK(NINEDOF_CHIP[NINEDOF_CHIP_GYRO].sleep.value == NINEDOF_ITG3200_SLEEP.value);
  CHECK(NINEDOF_CHIP[NINEDOF_CHIP_MAG].read_cmd[0] == NINEDOF_HMC5883L_TRIGGER[0] &&
        NINEDOF_CHIP[NINEDOF_CHIP_MAG].read_cmd[1] == NINEDOF_HMC5883L_TRIGGER[1]);
  CHECK(ninedof_chip_id_ok(NINEDOF_CHIP_ACCEL, adxl_id) && ninedof_chip_id_ok(NINEDOF_CHIP_GYRO, itg_id));
  CHECK(ninedof_chip_id_ok(NINEDOF_CHIP_MAG, hmc_id) && !ninedof_chip_id_ok(NINEDOF_CHIP_ACCEL, itg_id));
  ninedof_chip_xyz(NINEDOF_CHIP_MAG, bytes, a);
  ninedof_hmc5883l_xyz(bytes, b);
  CHECK(a[0] == b[0] && a[1] == b[1] && a[2] == b[2]);
  ninedof_chip_xyz(NINEDOF_CHIP_ACCEL, bytes, a);
  CHECK(a[0] == 0x0201);
  CHECK(ninedof_chip_temp(NINEDOF_CHIP_ACCEL, bytes) == 0 &&
        ninedof_chip_temp(NINEDOF_CHIP_MAG, bytes) == 0);
  /* ITG-3200: one burst of 8 from TEMP_OUT_H (0x1B), temperature then the
   * rates (0x1D..0x22); the other chips 6 bytes from their data pointer */
  {
    const ninedof_chip_t *g = &NINEDOF_CHIP[NINEDOF_CHIP_GYRO];
    static const uint8_t burst[8] = { 0xCC, 0x70, 0x01, 0x02, 0xFF, 0xFE, 0x80, 0x00 };
    CHECK(g->read_len == 1 && g->read_cmd[0] == ITG3200_TEMP_OUT_H && ITG3200_TEMP_OUT_H == 0x1B);
    CHECK(g->data_len == 8 && NINEDOF_CHIP_DATA_MAX == 8 && ITG3200_TEMP_OUT_H + 2 == ITG3200_GYRO_XOUT_H);
    CHECK(NINEDOF_CHIP[NINEDOF_CHIP_ACCEL].data_len == 6 && NINEDOF_CHIP[NINEDOF_CHIP_MAG].data_len == 6);
    ninedof_chip_xyz(NINEDOF_CHIP_GYRO, burst, a);
    CHECK(a[0] == 0x0102 && a[1] == -2 && a[2] == -32768);
    CHECK(ninedof_chip_temp(NINEDOF_CHIP_GYRO, burst) == -13200);   /* 0xCC70: 35 C */
  }
  for (chip = 0; chip < NINEDOF_CHIPS; chip++)
    CHECK(NINEDOF_CHIP[chip].data_len <= NINEDOF_CHIP_DATA_MAX);
}

/* ---------------------------------------------------------------------- */
/* Watchdog, counters, schedule                                            */
/* ---------------------------------------------------------------------- */
static void test_decisions(void)
{
  ninedof_fault_t f;
  uint16_t t, now;
  uint8_t picks[3], n;

  ninedof_fault_init(&f);
  /* an operation that ends within its period is never aborted (the clock
   * wraps on the way) */
  for (t = 0, now = 0xFF00; t < 500; t++, now += 8) {
    ninedof_fault_begin(&f, (uint16_t)(now + 1));
    CHECK(ninedof_fault_end(&f, NINEDOF_OP_OK) == NINEDOF_OP_OK);
    CHECK(ninedof_fault_tick(&f, now) == NINEDOF_FAULT_NONE);
  }
  CHECK(f.n.bus_resets == 0 && f.n.nacks == 0);

  /* a hung one, begun at a tick (as the mote's reads are), ticks 8 ms
   * apart: aborted at the first tick NINEDOF_I2C_TIMEOUT_MS after it
   * began, and again every NINEDOF_I2C_TIMEOUT_MS until it ends */
  ninedof_fault_init(&f);
  ninedof_fault_begin(&f, 0xFFF8);
  for (t = 1, now = 0xFFF8; t <= 10; t++) {
    now += 8;
    CHECK(ninedof_fault_tick(&f, now) == (t % 2 == 0 ? NINEDOF_FAULT_ABORT : NINEDOF_FAULT_NONE));
  }
  CHECK(f.n.bus_resets == 5);
  /* it ends with whatever the master says: counted as aborted, not a NACK */
  CHECK(ninedof_fault_end(&f, NINEDOF_OP_NACK) == NINEDOF_OP_ABORTED && f.n.nacks == 0);
  for (t = 0; t < 10; t++)
    CHECK(ninedof_fault_tick(&f, (uint16_t)(now + 100 * t)) == NINEDOF_FAULT_NONE);
  /* begun 1 ms after a tick: aborted at the third tick (23 ms) */
  ninedof_fault_begin(&f, 1);
  CHECK(ninedof_fault_tick(&f, 8) == NINEDOF_FAULT_NONE && ninedof_fault_tick(&f, 16) == NINEDOF_FAULT_NONE);
  CHECK(ninedof_fault_tick(&f, 24) == NINEDOF_FAULT_ABORT);
  ninedof_fault_end(&f, NINEDOF_OP_FAIL);
  while (ninedof_fault_check_pick(&f) != NINEDOF_CHECK_NONE)
    ;
  /* ticks in a burst (a late timer catching up) abort nothing that has
   * not run NINEDOF_I2C_TIMEOUT_MS */
  ninedof_fault_begin(&f, 1000);
  for (t = 0; t < 20; t++)
    CHECK(ninedof_fault_tick(&f, 1000 + NINEDOF_I2C_TIMEOUT_MS - 1) == NINEDOF_FAULT_NONE);
  CHECK(ninedof_fault_tick(&f, 1000 + NINEDOF_I2C_TIMEOUT_MS) == NINEDOF_FAULT_ABORT);
  CHECK(ninedof_fault_tick(&f, 1000 + NINEDOF_I2C_TIMEOUT_MS) == NINEDOF_FAULT_NONE);
  ninedof_fault_end(&f, NINEDOF_OP_FAIL);
  CHECK(f.n.bus_resets == 7);
  /* ... and every chip gets checked with the next three reads */
  for (n = 0; n < 3; n++)
    picks[n] = ninedof_fault_check_pick(&f);
  CHECK(picks[0] == 0 && picks[1] == 1 && picks[2] == 2);
  CHECK(ninedof_fault_check_pick(&f) == NINEDOF_CHECK_NONE);

  /* NACKs are counted, other failures not */
  ninedof_fault_begin(&f, 0);
  ninedof_fault_end(&f, NINEDOF_OP_NACK);
  ninedof_fault_begin(&f, 0);
  ninedof_fault_end(&f, NINEDOF_OP_FAIL);
  CHECK(f.n.nacks == 1 && f.n.bus_resets == 7);
  while (ninedof_fault_check_pick(&f) != NINEDOF_CHECK_NONE)
    ;

  /* the schedule: one chip every NINEDOF_CHECK_TICKS ticks, in turn */
  ninedof_fault_init(&f);
  for (t = 1, n = 0; t <= 6 * NINEDOF_CHECK_TICKS; t++) {
    uint8_t c;
    ninedof_fault_tick(&f, (uint16_t)(8 * t));
    c = ninedof_fault_check_pick(&f);
    if (t % NINEDOF_CHECK_TICKS == 0) {
      CHECK(c == n % 3);
      n++;
    } else {
      CHECK(c == NINEDOF_CHECK_NONE);
    }
  }
  CHECK(n == 6);

  /* check outcomes */
  {
    const ninedof_chip_t *g = &NINEDOF_CHIP[NINEDOF_CHIP_GYRO];
    CHECK(!ninedof_fault_check_done(&f, NINEDOF_CHIP_GYRO, NINEDOF_OP_OK,
                                    g->config[g->witness].value));
    CHECK(ninedof_fault_check_done(&f, NINEDOF_CHIP_GYRO, NINEDOF_OP_OK, g->witness_reset));
    ninedof_fault_reinit_done(&f, NINEDOF_CHIP_GYRO, NINEDOF_OP_OK);
    CHECK(f.n.chip_reinits == 1 && ninedof_fault_check_pick(&f) == NINEDOF_CHECK_NONE);
    /* a failed check or re-init: the chip is checked again with the next read */
    CHECK(!ninedof_fault_check_done(&f, NINEDOF_CHIP_MAG, NINEDOF_OP_NACK, 0));
    CHECK(ninedof_fault_check_pick(&f) == NINEDOF_CHIP_MAG && f.n.nacks == 1);
    ninedof_fault_reinit_done(&f, NINEDOF_CHIP_ACCEL, NINEDOF_OP_FAIL);
    CHECK(f.n.chip_reinits == 1 && ninedof_fault_check_pick(&f) == NINEDOF_CHIP_ACCEL);
    ninedof_fault_reinit_done(&f, NINEDOF_CHIP_ACCEL, NINEDOF_OP_NACK);
    CHECK(f.n.nacks == 2 && ninedof_fault_check_pick(&f) == NINEDOF_CHIP_ACCEL);
  }
  /* counters wrap */
  ninedof_fault_init(&f);
  f.n.nacks = 0xFFFF;
  ninedof_fault_begin(&f, 0);
  ninedof_fault_end(&f, NINEDOF_OP_NACK);
  CHECK(f.n.nacks == 0);
}

/* ---------------------------------------------------------------------- */
/* A board run by the decisions: what the nesC board does each period      */
/* ---------------------------------------------------------------------- */
typedef struct {
  uint8_t witness;       /* the witness register's value now */
  uint8_t absent;        /* NACKs everything */
} chip_model_t;

static void test_scenario(void)
{
  enum { PERIODS = 2400, GYRO_RESET = 300, MAG_OFF = 900, MAG_ON = 950, HANG = 1500,
         HANG_END = 1507, ACCEL_RESET = 2000 };
  ninedof_fault_t f;
  chip_model_t chip[3];
  uint16_t t, good = 0, bad = 0, wrong = 0, late = 0, first_wrong[3], fixed_at[3];
  uint8_t c, hung = 0, reading = 0;
  uint8_t out[20];

  ninedof_fault_init(&f);
  for (c = 0; c < 3; c++) {
    const ninedof_chip_t *d = &NINEDOF_CHIP[c];
    chip[c].witness = d->config[d->witness].value;
    chip[c].absent = 0;
    first_wrong[c] = fixed_at[c] = 0;
  }
  for (t = 1; t <= PERIODS; t++) {
    uint8_t outcome = NINEDOF_OP_OK, pick;
    /* the world */
    if (t == GYRO_RESET || t == ACCEL_RESET) {
      c = t == GYRO_RESET ? NINEDOF_CHIP_GYRO : NINEDOF_CHIP_ACCEL;
      chip[c].witness = NINEDOF_CHIP[c].witness_reset;          /* brown-out */
      first_wrong[c] = t;
    }
    if (t == MAG_OFF)
      chip[NINEDOF_CHIP_MAG].absent = 1;
    if (t == MAG_ON) {                                        /* back, reset */
      chip[NINEDOF_CHIP_MAG].absent = 0;
      chip[NINEDOF_CHIP_MAG].witness = NINEDOF_CHIP[NINEDOF_CHIP_MAG].witness_reset;
      first_wrong[NINEDOF_CHIP_MAG] = t;
    }
    /* the period: the watchdog first, then a read if none is under way */
    if (ninedof_fault_tick(&f, (uint16_t)(8 * t)) == NINEDOF_FAULT_ABORT) {
      if (t >= HANG_END) {                     /* the bus clear worked */
        ninedof_fault_end(&f, NINEDOF_OP_FAIL);
        reading = 0;
        bad++;
      }
    }
    if (reading) {
      late++;
      continue;
    }
    ninedof_fault_begin(&f, (uint16_t)(8 * t));
    if (t == HANG) {                           /* the bus hangs: no end */
      reading = hung = 1;
      continue;
    }
    for (c = 0; c < 3; c++)
      if (chip[c].absent)
        outcome = NINEDOF_OP_NACK;
    if (ninedof_fault_end(&f, outcome) != NINEDOF_OP_OK) {
      bad++;
      continue;
    }
    good++;
    for (c = 0; c < 3; c++)
      if (chip[c].witness != NINEDOF_CHIP[c].config[NINEDOF_CHIP[c].witness].value)
        wrong++;                               /* a record with a chip's wrong scale */
    pick = ninedof_fault_check_pick(&f);
    if (pick != NINEDOF_CHECK_NONE) {
      if (ninedof_fault_check_done(&f, pick, NINEDOF_OP_OK, chip[pick].witness)) {
        chip[pick].witness = NINEDOF_CHIP[pick].config[NINEDOF_CHIP[pick].witness].value;
        ninedof_fault_reinit_done(&f, pick, NINEDOF_OP_OK);
        fixed_at[pick] = t;
      }
    }
  }
  CHECK(hung && !reading);
  CHECK(f.n.nacks == MAG_ON - MAG_OFF);
  CHECK(f.n.bus_resets == 4);          /* at HANG + 2, + 4, + 6, + 8 */
  CHECK(f.n.chip_reinits == 3);
  /* detection delays: a silent reset within one round of the schedule;
   * a chip that came back after NACKs within the three reads after */
  CHECK(fixed_at[NINEDOF_CHIP_GYRO] >= GYRO_RESET &&
        fixed_at[NINEDOF_CHIP_GYRO] - GYRO_RESET <= 3 * NINEDOF_CHECK_TICKS);
  CHECK(fixed_at[NINEDOF_CHIP_ACCEL] >= ACCEL_RESET &&
        fixed_at[NINEDOF_CHIP_ACCEL] - ACCEL_RESET <= 3 * NINEDOF_CHECK_TICKS);
  CHECK(fixed_at[NINEDOF_CHIP_MAG] >= MAG_ON && fixed_at[NINEDOF_CHIP_MAG] - MAG_ON <= 3);
  CHECK(good + bad + late == PERIODS);
  /* sampling went on: every period but the NACKed, hung and aborted ones */
  CHECK(bad == MAG_ON - MAG_OFF + 1 && late == HANG_END - HANG);
  out_c('S');
  {
    uint16_t v[10] = { good, bad, late, wrong, f.n.nacks, f.n.bus_resets, f.n.chip_reinits,
                       (uint16_t)(fixed_at[0] - ACCEL_RESET), (uint16_t)(fixed_at[1] - GYRO_RESET),
                       (uint16_t)(fixed_at[2] - MAG_ON) };
    for (c = 0; c < 10; c++) {
      out[2 * c] = (uint8_t)(v[c] >> 8);
      out[2 * c + 1] = (uint8_t)v[c];
    }
    out_hex(out, 20);
  }
  out_c(';');
  (void)first_wrong;
}

/* ---------------------------------------------------------------------- */
/* A line shorted to ground: what the board does when a clear fails        */
/* ---------------------------------------------------------------------- */
/* 1200 periods of 8 ms; SDA shorted from SHORT to SHORT_END.  `lean`: the
 * master ends an aborted operation (lean: ECANCEL), else it stays under
 * way until the bus is free again (stock; its pending START then completes
 * the read).  The clear's result comes from the line: stuck while shorted. */
static void short_case(uint8_t lean)
{
  enum { PERIODS = 1200, SHORT = 200, SHORT_END = 600 };
  ninedof_fault_t f;
  uint16_t t, good = 0, refused = 0, ended_bad = 0, late = 0, clears = 0, clears_down = 0;
  uint16_t up_at = 0, last_clear = 0, max_apart = 0, first_good_after = 0;
  uint8_t reading = 0, hung = 0, v[20], k, c;

  ninedof_fault_init(&f);
  for (t = 1; t <= PERIODS; t++) {
    uint16_t now = (uint16_t)(8 * t);
    uint8_t shorted = t >= SHORT && t < SHORT_END, act;
    if (!shorted && hung && !lean) {          /* the stock master's START completes */
      hung = 0;
    }
    act = ninedof_fault_tick(&f, now);
    if (act != NINEDOF_FAULT_NONE) {
      uint8_t result = shorted ? NINEDOF_BC_DONE | NINEDOF_BC_SDA_STUCK : NINEDOF_BC_DONE;
      clears++;
      if (ninedof_fault_bus_down(&f)) {
        clears_down++;
        if (last_clear && (uint16_t)(t - last_clear) > max_apart)
          max_apart = (uint16_t)(t - last_clear);
      }
      last_clear = t;
      CHECK(act == (reading ? NINEDOF_FAULT_ABORT : NINEDOF_FAULT_CLEAR));
      if (!ninedof_fault_cleared(&f, result)) {
        CHECK(shorted);
      } else if (t >= SHORT_END && !up_at) {
        up_at = t;
      }
      if (reading && lean) {                  /* ECANCEL: the read ends */
        ninedof_fault_end(&f, NINEDOF_OP_FAIL);
        reading = hung = 0;
        ended_bad++;
      }
    }
    if (reading && !hung) {                   /* the stock read completed late */
      CHECK(ninedof_fault_end(&f, NINEDOF_OP_OK) == NINEDOF_OP_ABORTED);
      reading = 0;
      ended_bad++;
    }
    if (reading) {
      late++;
      continue;
    }
    if (ninedof_fault_bus_down(&f)) {         /* refused at once, no bus request */
      refused++;
      continue;
    }
    ninedof_fault_begin(&f, now);
    if (shorted) {                            /* its START waits for a free bus */
      reading = hung = 1;
      continue;
    }
    CHECK(ninedof_fault_end(&f, NINEDOF_OP_OK) == NINEDOF_OP_OK);
    good++;
    if (t >= SHORT_END && !first_good_after)
      first_good_after = t;
    /* every chip is checked with the reads after the bus came back */
    c = ninedof_fault_check_pick(&f);
    if (c != NINEDOF_CHECK_NONE)
      ninedof_fault_check_done(&f, c, NINEDOF_OP_OK,
                               NINEDOF_CHIP[c].config[NINEDOF_CHIP[c].witness].value);
  }
  CHECK(good + refused + ended_bad + late == PERIODS);
  /* one abort 16-24 ms into the short finds it; from then one clear every
   * NINEDOF_BUSDOWN_RETRY_MS (32 periods of 8 binary ms), not one every 16 ms */
  CHECK(max_apart == NINEDOF_BUSDOWN_RETRY_MS / 8);
  CHECK(clears == f.n.bus_resets && f.n.nacks == 0);
  CHECK(clears_down >= (SHORT_END - SHORT) * 8 / NINEDOF_BUSDOWN_RETRY_MS
        && clears_down <= (SHORT_END - SHORT) * 8 / NINEDOF_BUSDOWN_RETRY_MS + 2);
  /* the bus up with the first clear after the short */
  CHECK(up_at >= SHORT_END && up_at < SHORT_END + NINEDOF_BUSDOWN_RETRY_MS / 8 + 1);
  CHECK(first_good_after >= up_at && first_good_after <= up_at + 1);
  CHECK(!ninedof_fault_bus_down(&f) && !reading);
  /* reads: the one under way when the short began is aborted at the second
   * tick after it began (16 ms); lean: it ends, later reads are refused
   * until the bus is up; stock: it stays under way through the short (the
   * periods are late) and completes when SDA is free, counted as aborted,
   * and reads are refused until the next clear finds the lines high */
  if (lean)
    CHECK(ended_bad == 1 && late == 1 && refused == up_at - (SHORT + 2));
  else
    CHECK(ended_bad == 1 && late == SHORT_END - SHORT - 1 && refused == up_at - SHORT_END);
  out_c('D');
  out_c(lean ? 'L' : 'S');
  out_c(':');
  {
    uint16_t w[10] = { good, refused, ended_bad, late, f.n.bus_resets, clears_down, max_apart,
                       (uint16_t)(up_at - SHORT_END), (uint16_t)(first_good_after - SHORT_END),
                       f.n.chip_reinits };
    for (k = 0; k < 10; k++) {
      v[2 * k] = (uint8_t)(w[k] >> 8);
      v[2 * k + 1] = (uint8_t)w[k];
    }
    out_hex(v, 20);
  }
  out_c(';');
}

static void test_short(void)
{
  ninedof_fault_t f;
  short_case(1);
  short_case(0);
  /* the decisions alone: a failed clear puts the bus down, a good one up
   * again with every chip due for a check */
  ninedof_fault_init(&f);
  CHECK(!ninedof_fault_bus_down(&f));
  CHECK(ninedof_fault_cleared(&f, NINEDOF_BC_DONE) && !ninedof_fault_bus_down(&f));
  CHECK(ninedof_fault_check_pick(&f) == NINEDOF_CHECK_NONE);
  CHECK(!ninedof_fault_cleared(&f, NINEDOF_BC_DONE | NINEDOF_BC_SCL_STUCK));
  CHECK(ninedof_fault_bus_down(&f));
  /* down and idle: nothing for NINEDOF_BUSDOWN_RETRY_MS after the clear
   * (f.since 0), then a retry, counted */
  CHECK(ninedof_fault_tick(&f, NINEDOF_BUSDOWN_RETRY_MS - 1) == NINEDOF_FAULT_NONE);
  CHECK(ninedof_fault_tick(&f, NINEDOF_BUSDOWN_RETRY_MS) == NINEDOF_FAULT_CLEAR);
  CHECK(f.n.bus_resets == 1);
  CHECK(ninedof_fault_cleared(&f, NINEDOF_BC_DONE) && !ninedof_fault_bus_down(&f));
  CHECK(ninedof_fault_check_pick(&f) == 0 && ninedof_fault_check_pick(&f) == 1 &&
        ninedof_fault_check_pick(&f) == 2);
  CHECK(ninedof_fault_tick(&f, 2 * NINEDOF_BUSDOWN_RETRY_MS) == NINEDOF_FAULT_NONE);
}

int main(void)
{
  out_init();
  test_busclear();
  test_chip_table();
  test_decisions();
  test_scenario();
  test_short();
  check_summary();
  out_end();
  return failed != 0;
}
