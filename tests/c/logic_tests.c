/*
 * logic_tests.c -- behaviour of the firmware's plain C logic (board data
 * conversion, I2C rate, 125 Hz sampling clock, one instant per record
 * (magnetometer aligned with accel/gyro), batching, status, EEPROM
 * writer, the BaseStation's serial divisor and status), built twice by
 * tests/test_avr.py: with gcc on the host and with avr-gcc for the
 * ATmega1281 in simavr.  Prints, for the host-vs-AVR comparison, a digest
 * of every packed message ("D<hex>"), and last "CHECKS <n> FAILED <m>;END"
 * (check_summary).
 */
#include <stdint.h>
#include <string.h>

#include "ninedof_board.h"
#include "ninedof_bs.h"
#include "ninedof_cal.h"
#include "ninedof_clock.h"
#include "ninedof_sampling.h"

#include "test_out.h"
#include "test_check.h"


/* ---------------------------------------------------------------------- */
static void test_board(void)
{
  /* ADXL345: little-endian X0 X1 Y0 Y1 Z0 Z1; -1 g = -256, +16 g = 4095 */
  static const uint8_t acc[6] = { 0x00, 0x01, 0x00, 0xFF, 0xFF, 0x0F };
  /* ITG3200: big-endian XH XL ...; -32768, 1, 0x1234 */
  static const uint8_t gyr[6] = { 0x80, 0x00, 0x00, 0x01, 0x12, 0x34 };
  /* HMC5883L: X, Z, Y big-endian; Z = -4096 overflow marker */
  static const uint8_t mag[6] = { 0x01, 0x02, 0xF0, 0x00, 0xFF, 0xFE };
  static const uint8_t id[3] = { 'H', '4', '3' }, bad_id[3] = { 'H', '4', '4' };
  int16_t rec[9];

  ninedof_board_record(acc, gyr, mag, rec);
  CHECK(rec[0] == 256 && rec[1] == -256 && rec[2] == 4095);
  CHECK(rec[3] == -32768 && rec[4] == 1 && rec[5] == 0x1234);
  CHECK(rec[6] == 0x0102 && rec[7] == -2 && rec[8] == NINEDOF_HMC5883L_OVERFLOW);

  CHECK(ninedof_adxl345_id_ok(0xE5) && !ninedof_adxl345_id_ok(0xE4));
  CHECK(ninedof_itg3200_id_ok(0x68) && ninedof_itg3200_id_ok(0x69) &&
        !ninedof_itg3200_id_ok(0x00) && !ninedof_itg3200_id_ok(0xE5));
  CHECK(ninedof_hmc5883l_id_ok(id) && !ninedof_hmc5883l_id_ok(bad_id));

  /* TWBR is rounded up: SCL never faster than asked.  400 kHz at 8 MHz:
   * TWBR = 2, exact; the default 380 kHz limit gives TWBR = 3 (364 kHz,
   * SCL low >= 1.3 us); the stock driver's 65 gives ~55 kHz at 8 MHz */
  CHECK(NINEDOF_TWBR(8000000UL, 400000UL) == 2);
  CHECK(8000000UL / (16UL + 2UL * NINEDOF_TWBR(8000000UL, 400000UL)) == 400000UL);
  CHECK(NINEDOF_TWBR(8000000UL, NINEDOF_I2C_HZ) == 3);
  CHECK(NINEDOF_TWBR(8000000UL, 380000UL) == 3);
  CHECK(NINEDOF_TWBR(7372800UL, 50000UL) == 66);
  {
    uint32_t scl;
    for (scl = 50000UL; scl <= 400000UL; scl += 10000UL) {
      uint8_t t = NINEDOF_TWBR(8000000UL, scl);
      CHECK(8000000UL / (16UL + 2UL * t) <= scl);            /* never faster */
      CHECK(t == 0 || 8000000UL / (16UL + 2UL * (t - 1)) > scl); /* tightest */
    }
  }
  /* the HMC5883L trigger writes MODE = single measurement */
  CHECK(NINEDOF_HMC5883L_TRIGGER[0] == HMC5883L_MODE &&
        (NINEDOF_HMC5883L_TRIGGER[1] & 3) == 1);
}

/* ---------------------------------------------------------------------- */
/* The sampling clock (ninedof_clock.c) against a simulated mote: the alarm
 * counts the RC-oscillator clock, whose true rate is given here in crystal
 * ticks per alarm tick (Q24; nominal 2^34 / 31250 = 549756); the crystal
 * counter (1024 Hz, 32 bits) is read at each expiry after an interrupt
 * latency.  Integer arithmetic only, so host and AVR print the same. */
typedef struct {
  uint32_t k;          /* crystal ticks per alarm tick, Q24 */
  int16_t dk;          /* change of k per simulated second (drift) */
  uint16_t cpj;        /* what MeasureClockC measured at boot */
  uint16_t lat_max;    /* largest interrupt latency, 1/65536 crystal tick */
  uint32_t xtal0;      /* crystal counter at the first expiry */
  uint32_t frac0;      /* ... and the fraction of a tick it has run, Q24 */
  uint16_t seconds;    /* simulated */
  uint16_t settle;     /* seconds allowed to lock */
} clock_case_t;

#define K_NOMINAL 549756UL                  /* 2^34 / 31250 */
#define K_RC(ppm) ((uint32_t)(K_NOMINAL - (int32_t)(K_NOMINAL / 1000L) * (ppm) / 1000L))
#define LAT_US(us) ((uint16_t)((us) * 65536UL / 977UL))

static const clock_case_t CLOCK_CASES[] = {
  /* RC 2 % fast; crystal counter wraps in the first second */
  { K_RC(20000), 0, 249, LAT_US(40), 0xFFFFFE00UL, 0x123456UL, 150, 30 },
  /* RC 2 % slow; radio interrupts delay the alarm by up to 300 us */
  { K_RC(-20000), 0, 239, LAT_US(300), 0x7FFFFF00UL, 0xF00000UL, 150, 30 },
  /* warming up: the RC speeds up by 20 ppm every second (0.3 % in all) */
  { K_NOMINAL, -11, 244, LAT_US(100), 0x12345678UL, 0x800000UL, 150, 30 },
  /* cooling fast: 200 ppm per second (3 % in all) */
  { K_RC(15000), 110, 248, LAT_US(100), 0xFFFF0000UL, 0xC00000UL, 150, 30 },
  /* a boot measurement 5 % off: the loop still locks */
  { K_RC(50000), 0, 244, LAT_US(40), 0UL, 0xFF0000UL, 120, 60 },
};

static void out_i32(int32_t v)
{
  uint8_t b[4];
  b[0] = (uint8_t)((uint32_t)v >> 24);
  b[1] = (uint8_t)((uint32_t)v >> 16);
  b[2] = (uint8_t)((uint32_t)v >> 8);
  b[3] = (uint8_t)v;
  out_hex(b, 4);
}

static void test_clock_case(const clock_case_t *t)
{
  static ninedof_clock_t c;
  uint32_t k = t->k, xtal = t->xtal0, frac = t->frac0;
  uint16_t rnd = 12345;
  uint32_t x0 = (xtal << 24) | frac;
  int32_t phase = 0, phase_settle = 0, phase_lo = INT32_MAX, phase_hi = INT32_MIN;
  uint16_t p, last, sec, i, pmin = 0xFFFF, pmax = 0, smin, smax;
  uint8_t max_step = 0, max_spread = 0;

  ninedof_clock_init(&c, t->cpj);
  p = ninedof_clock_first(&c);
  for (sec = 0; sec < t->seconds; sec++) {
    smin = 0xFFFF;
    smax = 0;
    for (i = 0; i < NINEDOF_RATE_HZ; i++) {
      /* an expiry: read the crystal after the interrupt latency */
      uint32_t lat, read;
      rnd = (uint16_t)(rnd * 25173u + 13849u);
      lat = ((uint32_t)rnd * t->lat_max) >> 8;                  /* Q24 */
      read = xtal + ((frac + lat) >> 24);
      last = p;
      p = ninedof_clock_next(&c, read);
      if ((uint16_t)(p - last + 1) > 2)
        max_step = 2;                                           /* |p - last| > 1 */
      if (p < smin) smin = p;
      if (p > smax) smax = p;
      /* the alarm ticks p times: the crystal advances p * k */
      frac += (uint32_t)p * k;
      xtal += frac >> 24;
      frac &= 0xFFFFFFUL;
    }
    k = (uint32_t)((int32_t)k + t->dk);
    /* 125 periods later: ideal crystal time is the start + (sec + 1) * 1024
     * ticks, which is 0 modulo 2^32 in Q24; phase > 0 = late */
    phase = (int32_t)(((xtal << 24) | frac) - x0);
    if (sec + 1 == t->settle)
      phase_settle = phase;
    if (sec + 1 >= t->settle) {
      if (phase < phase_lo) phase_lo = phase;
      if (phase > phase_hi) phase_hi = phase;
      if (smax - smin > max_spread)
        max_spread = (uint8_t)(smax - smin);
      if (smin < pmin) pmin = smin;
      if (smax > pmax) pmax = smax;
    }
  }
  CHECK(max_step <= 1);                      /* consecutive periods: one tick at most */
  CHECK(max_spread <= 1);                    /* one second: two adjacent periods */
  CHECK(c.resyncs == 0);
  /* K <seconds> <settle> <phase lo> <phase hi> <phase settle> <phase end>
   * (Q24 crystal ticks) <shortest> <longest period> <rate x16> */
  out_c('K');
  out_i32(t->seconds);
  out_i32(t->settle);
  out_i32(phase_lo);
  out_i32(phase_hi);
  out_i32(phase_settle);
  out_i32(phase);
  out_i32(pmin);
  out_i32(pmax);
  out_i32((int32_t)c.rate);
  out_c(';');
}

static void test_clock(void)
{
  static ninedof_clock_t c;
  uint8_t n;
  uint16_t i, p;

  CHECK(NINEDOF_PERIOD_TICKS == 250);
  CHECK((uint32_t)NINEDOF_PERIOD_TICKS * NINEDOF_RATE_HZ == NINEDOF_ALARM_HZ);
  /* start: 8 MHz measured as 244 cycles per jiffy = 31232 Hz alarm */
  ninedof_clock_init(&c, 244);
  CHECK(c.rate == 244UL * 128 * 16 && ninedof_clock_first(&c) == 249);
  ninedof_clock_init(&c, 0);                /* unknown: nominal, 250 ticks */
  CHECK(c.rate == 500000UL && ninedof_clock_first(&c) == 250);
  ninedof_clock_init(&c, 1000);             /* nonsense (not within +-10 %): nominal */
  CHECK(c.rate == 500000UL && ninedof_clock_first(&c) == 250);
  /* a crystal exactly on the nominal clock: 250 ticks every time, the grid
   * is 8.192 crystal ticks per period, no correction */
  ninedof_clock_init(&c, 0);
  for (i = 0; i < 3 * NINEDOF_RATE_HZ; i++) {
    /* the crystal reading at expiry i: floor(i * 1024 / 125) + 7 */
    p = ninedof_clock_next(&c, 7UL + (uint32_t)i * 1024UL / 125UL);
    CHECK(p == 250);
  }
  CHECK(c.error == 0 && c.rate == 500000UL);
  /* a stall of two seconds restarts the phase reference, keeps the rate */
  for (i = 0; i < NINEDOF_RATE_HZ; i++)
    ninedof_clock_next(&c, 100000UL + (i == 0 ? 0 : 3000UL));
  CHECK(c.resyncs == 1 && c.rate == 500000UL && !c.synced);
  for (n = 0; n < sizeof(CLOCK_CASES) / sizeof(CLOCK_CASES[0]); n++)
    test_clock_case(&CLOCK_CASES[n]);
}

/* ---------------------------------------------------------------------- */
/* Arming the sampling alarm (ninedof_clock_arm) against a model of TinyOS's
 * Alarm32khz32C on iris at 8 MHz: timer 1 counts 1 us ticks (16 bits);
 * TransformAlarmC works in alarm ticks of 32 timer ticks, over a counter
 * (Counter32khz32C) that lags by one timer wrap, 2048 alarm ticks, in an
 * expiry due within a few us after the timer wrapped (its compare interrupt
 * preempts the overflow handler before that counts the overflow), and takes
 * a target before its counter for one in the past; Atm128AlarmC arms a
 * target within 3 timer ticks of now at now + 3, which its code writes too
 * late on iris, so that compare comes a whole wrap (65.536 ms) later.  The
 * app's handler runs (reads the counter, arms) some us after the
 * interrupt. */
typedef struct {
  uint32_t us;         /* true time, timer ticks; its low 16 bits are TCNT1 */
  uint32_t t0, dt;     /* TransformAlarmC's m_t0, m_dt */
  uint32_t fire;       /* when the compare interrupt comes */
  uint8_t lag;         /* the counter is one wrap behind */
} alarm_model_t;

enum {
  AM_WRAP = 2048,      /* 65536 >> 5: Counter32khz32C's lag, alarm ticks */
  AM_LAG_US = 8,       /* an expiry this soon after a wrap finds the overflow uncounted */
};

static uint32_t am_now(const alarm_model_t *m)
{
  return (m->us >> 5) - (m->lag ? AM_WRAP : 0);
}

static void am_hw_start(alarm_model_t *m, uint16_t t0, uint16_t dt)
{
  uint16_t now = (uint16_t)m->us, expires;
  if ((uint16_t)(now + 3 - t0) >= dt) {
    m->fire = m->us + 65536UL;                 /* compare missed: one wrap */
    return;
  }
  expires = (uint16_t)(t0 + dt);
  if (expires == 0)
    expires = 1;
  m->fire = m->us + (uint16_t)(expires - now);
}

static void am_set_alarm(alarm_model_t *m)
{
  uint32_t now = am_now(m), expires = m->t0 + m->dt, remaining = expires - now;
  if (m->t0 <= now) {
    if (expires >= m->t0 && expires <= now)
      remaining = 0;
  } else if (expires >= m->t0 || expires <= now) {
    remaining = 0;
  }
  if (remaining > 1024) {
    m->t0 = now + 1024;
    m->dt = remaining - 1024;
    remaining = 1024;
  } else {
    m->t0 += m->dt;
    m->dt = 0;
  }
  am_hw_start(m, (uint16_t)(now << 5), (uint16_t)(remaining << 5));
}

static void am_start_at(alarm_model_t *m, uint32_t t0, uint32_t dt)
{
  m->t0 = t0;
  m->dt = dt;
  am_set_alarm(m);
}

/* n periods of `period` ticks, the first expiry due at alarm tick `first`;
 * `fixed` = arm as the app does now (ninedof_clock_arm), otherwise as it
 * did (startAt(getAlarm(), period)); the handler of expiry `slow_at` runs
 * `slow_us` late.  Returns the longest time between expiries (us), counts
 * those over 1.5 periods, and the time of the last expiry. */
static uint32_t am_run(uint8_t fixed, uint16_t n, uint16_t period, uint32_t first,
                       uint16_t slow_at, uint32_t slow_us, uint16_t *gaps, uint32_t *last)
{
  static alarm_model_t m;
  uint32_t target = first, prev = 0, longest = 0, lat;
  uint16_t k = 0;

  memset(&m, 0, sizeof m);
  m.us = 5;
  am_start_at(&m, am_now(&m), first - am_now(&m));
  *gaps = 0;
  while (k < n) {
    m.us = m.fire;
    m.lag = (uint16_t)m.us < AM_LAG_US;
    if (m.dt != 0) {                           /* TransformAlarmC's intermediate */
      am_set_alarm(&m);
      continue;
    }
    if (k > 0) {
      if (m.us - prev > longest)
        longest = m.us - prev;
      if (m.us - prev > (uint32_t)period * 48)
        (*gaps)++;
    }
    prev = m.us;
    lat = 40 + (k % 7) * 10;                   /* to the handler's counter read */
    if (k == slow_at)
      lat += slow_us;
    m.us += lat;
    if ((uint16_t)m.us >= AM_LAG_US + lat)     /* the handler ran past the overflow handler */
      m.lag = 0;
    if (fixed) {
      uint32_t now = am_now(&m);
      target += period;
      am_start_at(&m, now, ninedof_clock_arm(target, now, period, AM_WRAP));
    } else {
      am_start_at(&m, m.t0 + m.dt, period);
    }
    k++;
  }
  *last = prev;
  return longest;
}

static void test_clock_arm(void)
{
  uint16_t gaps_old, gaps_new, gaps_old2, gaps_new2;
  uint32_t last_old, last_new, last_new2, longest_old, longest_new, longest_new2;
  /* 245 ticks a period; expiry 100 falls on a timer wrap: 76 + 100 * 245 = 12 * 2048 */
  const uint16_t n = 500, p = 245;
  const uint32_t first = 76;

  CHECK(ninedof_clock_arm(1000, 800, 245, 2048) == 200);            /* on time */
  CHECK(ninedof_clock_arm(1000, 755, 245, 2048) == 245);
  CHECK(ninedof_clock_arm(1000, 998, 245, 2048) == NINEDOF_ALARM_MIN_TICKS); /* late */
  CHECK(ninedof_clock_arm(1000, 1300, 245, 2048) == NINEDOF_ALARM_MIN_TICKS);
  CHECK(ninedof_clock_arm(5, 0xFFFFFFF0UL, 245, 2048) == 21);       /* counter wraps */
  /* the counter lags one overflow: 2048 ticks behind */
  CHECK(ninedof_clock_arm(1000, 800 - 2048, 245, 2048) == 200);
  CHECK(ninedof_clock_arm(100, 0xFFFFFFFFUL - 2047, 245, 2048) == 100);
  CHECK(ninedof_clock_arm(1000, 10, 245, 2048) == NINEDOF_ALARM_MIN_TICKS); /* neither */

  longest_old = am_run(0, n, p, first, 0xFFFF, 0, &gaps_old, &last_old);
  longest_new = am_run(1, n, p, first, 0xFFFF, 0, &gaps_new, &last_new);
  /* no expiry on a timer wrap (77 + k * 245), but the handler of expiry 300
   * runs 9 ms late (more than a period) */
  am_run(0, n, p, first + 1, 300, 9000, &gaps_old2, &last_new2);
  longest_new2 = am_run(1, n, p, first + 1, 300, 9000, &gaps_new2, &last_new2);
  CHECK(gaps_old > 0 && longest_old > 65536UL);   /* the model has the stall */
  CHECK(gaps_old2 > 0);
  CHECK(gaps_new == 0 && longest_new <= (uint32_t)(p + 1) * 32);
  /* the schedule keeps its phase: the last expiry is due at first + 499 periods */
  CHECK(last_new >= (first + (uint32_t)(n - 1) * p) * 32 &&
        last_new < (first + (uint32_t)(n - 1) * p) * 32 + 32);
  /* late once (9 ms + the handler's latency), then on the schedule again */
  CHECK(gaps_new2 == 0 && longest_new2 < 9000 + 200);
  CHECK(last_new2 >= (first + 1 + (uint32_t)(n - 1) * p) * 32 &&
        last_new2 < (first + 1 + (uint32_t)(n - 1) * p) * 32 + 32);
  /* A <expiries' longest gap, old> <gaps, old> <longest, new> <gaps, new>
   * <with a handler 9 ms late: gaps, old> <longest, new> <gaps, new> */
  out_c('A');
  out_i32((int32_t)longest_old);
  out_i32(gaps_old);
  out_i32((int32_t)longest_new);
  out_i32(gaps_new);
  out_i32(gaps_old2);
  out_i32((int32_t)longest_new2);
  out_i32(gaps_new2);
  out_c(';');
}

/* ---------------------------------------------------------------------- */
static ninedof_calrx_t rx;
static ninedof_batch_t batch;
static ninedof_samples_msg_t msg;

static void make_rec(int16_t rec[9], uint16_t seq)
{
  uint8_t k;
  for (k = 0; k < 9; k++)
    rec[k] = (int16_t)(uint16_t)(seq * 977u + k * 4099u);
}

/* Upload a calibration set through the receiver as the host would. */
static void upload(const ninedof_cal_t *cal)
{
  ninedof_calset_t wire;
  ninedof_cal_frag_msg_t frag;
  ninedof_cal_commit_msg_t commit;
  uint8_t reply[sizeof(ninedof_cal_report_msg_t)], rtype, off;
  const uint8_t *bytes = (const uint8_t *)&wire;

  ninedof_cal_encode(cal, &wire);
  for (off = 0; off < sizeof(wire); off += NINEDOF_FRAG_DATA) {
    uint8_t n = (uint8_t)(sizeof(wire) - off < NINEDOF_FRAG_DATA ? sizeof(wire) - off
                                                                 : NINEDOF_FRAG_DATA);
    nxp_set_u16(&frag.mote, cal->mote);
    nxp_set_u16(&frag.version, cal->version);
    nxp_set_u8(&frag.offset, off);
    nxp_set_u8(&frag.len, n);
    memcpy(frag.data, bytes + off, n);
    ninedof_calrx_handle(&rx, AM_NINEDOF_CAL_FRAG_MSG, (uint8_t *)&frag, sizeof(frag),
                         reply, &rtype);
  }
  nxp_set_u16(&commit.mote, cal->mote);
  nxp_set_u16(&commit.version, cal->version);
  nxp_set_u8(&commit.length, sizeof(wire));
  nxp_set_u8(&commit.action, NINEDOF_CAL_APPLY);
  nxp_set_u16(&commit.crc, ninedof_crc16(0, bytes, sizeof(wire)));
  ninedof_calrx_handle(&rx, AM_NINEDOF_CAL_COMMIT_MSG, (uint8_t *)&commit,
                       sizeof(commit), reply, &rtype);
  CHECK(rtype == AM_NINEDOF_CAL_COMMIT_ACK_MSG && reply[6] == NINEDOF_CAL_OK);
}

static void test_batching(void)
{
  int16_t rec[9];
  uint16_t seq;
  uint8_t len, full = 0;
  ninedof_cal_t cal;

  ninedof_calrx_init(&rx, 3);
  ninedof_batch_init(&batch);
  CHECK(ninedof_batch_pack(&batch, &rx, &msg) == 0);

  /* a full batch of consecutive periods, across the 16-bit wrap */
  for (seq = 0xFFFE; seq != 3; seq++) {
    make_rec(rec, seq);
    CHECK(ninedof_batch_fits(&batch, seq));
    full = ninedof_batch_add(&batch, seq, rec);
  }
  CHECK(full == (NINEDOF_BATCH == 5));
  CHECK(!ninedof_batch_fits(&batch, 3));
  len = ninedof_batch_pack(&batch, &rx, &msg);
  CHECK(len == 4 + 18 * NINEDOF_BATCH);
  CHECK(nxp_get_u16(&msg.seq) == 0xFFFE && nxp_get_u8(&msg.count) == NINEDOF_BATCH);
  CHECK(nxp_get_u8(&msg.flags) == 0);
  make_rec(rec, 0xFFFF);
  CHECK(nxp_get_i16(&msg.rec[1].gz) == rec[5]);           /* raw, big-endian */
  out_c('D');
  out_hex((const uint8_t *)&msg, len);
  out_c(';');

  /* a skipped period ends the batch early: count 2, then a new batch */
  ninedof_batch_add(&batch, 10, rec);
  CHECK(ninedof_batch_fits(&batch, 11));
  ninedof_batch_add(&batch, 11, rec);
  CHECK(!ninedof_batch_fits(&batch, 13));
  len = ninedof_batch_pack(&batch, &rx, &msg);
  CHECK(len == 4 + 18 * 2 && nxp_get_u8(&msg.count) == 2 && nxp_get_u16(&msg.seq) == 10);
  CHECK(ninedof_batch_fits(&batch, 13));

  /* with a calibration in force the packed records are corrected and flagged */
  ninedof_cal_identity(&cal, 3, 0x25);
  cal.sensors = 1u << NINEDOF_SENSOR_ACCEL;
  cal.s[0].a[0] = 32767;                       /* ax * (2 - 2^-14) */
  cal.s[0].c[1] = -100L * 16384;                /* ay - 100 */
  upload(&cal);
  CHECK(ninedof_calrx_flags(&rx) == (0x50 | NINEDOF_FLAG_CORRECTED));
  for (seq = 20; seq < 23; seq++) {
    make_rec(rec, seq);
    rec[0] = 1000;
    rec[1] = 50;
    ninedof_batch_add(&batch, seq, rec);
  }
  len = ninedof_batch_pack(&batch, &rx, &msg);
  CHECK(len == 4 + 18 * 3);
  CHECK(nxp_get_u8(&msg.flags) == 0x51);
  CHECK(nxp_get_i16(&msg.rec[2].ax) == 2000 && nxp_get_i16(&msg.rec[2].ay) == -50);
  make_rec(rec, 22);
  CHECK(nxp_get_i16(&msg.rec[2].gx) == rec[3]);             /* gyro not corrected */
  out_c('D');
  out_hex((const uint8_t *)&msg, len);
  out_c(';');
}

/* ---------------------------------------------------------------------- */
/* Every record one instant: a model of the board's reads, in which a read
 * returns the accelerometer and gyroscope of its own period and the field
 * measured at the last trigger (the previous read that got to its MODE
 * write).  Values encode (axis, instant), so a record is one instant when
 * all nine axes name the same one. */
static int16_t at(uint8_t k, uint16_t instant)
{
  return (int16_t)(uint16_t)(instant * 31u + k * 7u);
}

static void test_align(void)
{
  /* per period: R read, L skipped (previous read late), F failed after its
   * trigger went out, G failed before it; across the 16-bit wrap */
  static const char events[] = "RRLRFRRLLRGRRRRLR";
  ninedof_align_t a;
  int16_t rec[9], out[9];
  uint16_t seq = 0xFFF8, trigger = 0x5A5A, out_seq, last_ok = 0;
  uint8_t i, k, same, prev_ok = 0, records = 0, expected = 0;

  ninedof_align_init(&a);
  for (i = 0; events[i]; i++, seq++) {
    char e = events[i];
    if (e == 'L')
      continue;                                  /* no read: nothing changes */
    if (e != 'R') {
      if (e == 'F')
        trigger = seq;
      ninedof_align_lost(&a);
      prev_ok = 0;
      continue;
    }
    for (k = 0; k < 6; k++)
      rec[k] = at(k, seq);
    for (k = 6; k < 9; k++)
      rec[k] = at(k, trigger);                   /* the previous trigger's field */
    trigger = seq;
    if (ninedof_align_push(&a, seq, rec, out, &out_seq)) {
      records++;
      same = 1;
      for (k = 0; k < 9; k++)
        same &= out[k] == at(k, out_seq);
      CHECK(same && prev_ok && out_seq == last_ok);
    } else {
      CHECK(!prev_ok);                           /* only the first read after a start */
    }
    expected += prev_ok;
    prev_ok = 1;
    last_ok = seq;
  }
  CHECK(records == expected && records == 8);
  /* start over: nothing held */
  ninedof_align_init(&a);
  CHECK(!ninedof_align_push(&a, 7, rec, out, &out_seq));
  CHECK(ninedof_align_push(&a, 8, rec, out, &out_seq) && out_seq == 7);
}

/* ---------------------------------------------------------------------- */
static void test_status(void)
{
  ninedof_counters_t c;
  ninedof_fault_counters_t f = { 3, 0xFFFF, 2 };
  ninedof_mote_status_msg_t st;

  ninedof_counters_init(&c);
  c.seq = 0x1234;
  c.dropped = 5;
  c.send_fail = 0xFFFF;
  c.send_fail++;                                /* counters wrap */
  c.i2c_errors = 7;
  c.late = 9;
  ninedof_status_pack(&c, &f, &rx, &st);
  CHECK(nxp_get_u16(&st.seq) == 0x1234 && nxp_get_u16(&st.version) == 0x25);
  CHECK(nxp_get_u8(&st.sensors) == 1 && nxp_get_u16(&st.dropped) == 5);
  CHECK(nxp_get_u16(&st.send_fail) == 0 && nxp_get_u16(&st.i2c_errors) == 7 &&
        nxp_get_u16(&st.late) == 9);
  CHECK(sizeof(st) == 20 && nxp_get_u16(&st.i2c_nacks) == 3 &&
        nxp_get_u16(&st.bus_resets) == 0xFFFF && nxp_get_u16(&st.chip_reinits) == 2);
  out_c('D');
  out_hex((const uint8_t *)&st, sizeof(st));
  out_c(';');
}

/* ---------------------------------------------------------------------- */
/* Board temperature: readings summed per period, the message, the mean    */
static void test_temp(void)
{
  ninedof_temp_acc_t t;
  ninedof_mote_temp_msg_t m;
  int16_t mean = 0x5555;
  uint16_t i;

  ninedof_temp_init(&t);
  /* a period without a reading: count 0, no mean */
  CHECK(!ninedof_temp_pack(&t, &m, &mean) && mean == 0x5555);
  CHECK(nxp_get_u8(&m.count) == 0 && nxp_get_i32(&m.temp_sum) == 0 && sizeof(m) == 8);
  /* 125 readings around 25 C (-16000): sum, newest seq, mean rounded */
  for (i = 0; i < 125; i++)
    ninedof_temp_add(&t, (uint16_t)(0xFFC0u + i), (int16_t)(-16000 - (int16_t)(i % 3)));
  CHECK(ninedof_temp_pack(&t, &m, &mean));
  CHECK(nxp_get_u8(&m.count) == 125 && nxp_get_u16(&m.seq) == (uint16_t)(0xFFC0u + 124));
  CHECK(nxp_get_i32(&m.temp_sum) == -16000L * 125 - 124 && mean == -16001);
  CHECK(nxp_get_u8(&m.reserved) == 0);
  out_c('D');
  out_hex((const uint8_t *)&m, sizeof(m));
  out_c(';');
  /* the next period starts empty; a late timer: the count stops at 255 */
  for (i = 0; i < 300; i++)
    ninedof_temp_add(&t, i, 32767);
  CHECK(ninedof_temp_pack(&t, &m, &mean) && nxp_get_u8(&m.count) == 255);
  CHECK(nxp_get_i32(&m.temp_sum) == 32767L * 255 && mean == 32767 && nxp_get_u16(&m.seq) == 254);
  /* rounding half away from zero, both signs */
  ninedof_temp_add(&t, 1, -3);
  ninedof_temp_add(&t, 2, -4);
  CHECK(ninedof_temp_pack(&t, &m, &mean) && mean == -4);
  ninedof_temp_add(&t, 1, 3);
  ninedof_temp_add(&t, 2, 4);
  CHECK(ninedof_temp_pack(&t, &m, &mean) && mean == 4);
}

/* ---------------------------------------------------------------------- */
static uint8_t eeprom[0x300];
static ninedof_eewriter_t ew;

/* Write up to `limit` bytes (a power cut after that); returns bytes written */
static uint16_t ee_run(uint16_t limit)
{
  uint16_t addr, n = 0;
  uint8_t v;
  while (n < limit && ninedof_eewriter_next(&ew, &addr, &v)) {
    eeprom[addr] = v;
    n++;
  }
  return n;
}

/* The writer's read-back of the slot it wrote (as NineDofCalibrationP) */
static uint8_t ee_check(void)
{
  return ninedof_eewriter_check(&ew, &rx, eeprom + ninedof_eewriter_addr(&ew));
}

/* The stored set the report gives (a query with NINEDOF_QUERY_STORED) */
static void stored_report(uint16_t *version, uint16_t *crc, uint8_t *store, uint8_t *len)
{
  ninedof_cal_query_msg_t q;
  uint8_t reply[sizeof(ninedof_cal_report_msg_t)], rtype;
  const ninedof_cal_report_msg_t *rep = (const ninedof_cal_report_msg_t *)reply;

  nxp_set_u16(&q.mote, 3);
  nxp_set_u8(&q.offset, 0);
  nxp_set_u8(&q.flags, NINEDOF_QUERY_STORED);
  *len = ninedof_calrx_handle(&rx, AM_NINEDOF_CAL_QUERY_MSG, (uint8_t *)&q, sizeof(q),
                              reply, &rtype);
  *version = nxp_get_u16(&rep->stored_version);
  *crc = nxp_get_u16(&rep->stored_crc);
  *store = nxp_get_u8(&rep->store);
}

static uint8_t boot(ninedof_calrx_t *r, uint8_t *next_slot, uint16_t *next_gen)
{
  ninedof_calrx_init(r, 3);
  return ninedof_calrx_restore(r, eeprom + NINEDOF_EEPROM_SLOT0,
                               eeprom + NINEDOF_EEPROM_SLOT1, eeprom + NINEDOF_EEPROM_LEGACY1,
                               next_slot, next_gen);
}

static void test_eeprom(void)
{
  static ninedof_calrx_t r2;
  ninedof_cal_t cal;
  uint8_t slot, used;
  uint16_t gen;

  uint16_t sv, scrc;
  uint8_t store, len;

  memset(eeprom, 0xFF, sizeof(eeprom));                      /* erased EEPROM */
  used = boot(&r2, &slot, &gen);
  CHECK(used == 0xFF && slot == 0 && gen == 1);
  CHECK(r2.stored_version == 0 && r2.stored_crc == 0 && r2.store == NINEDOF_STORE_IDLE);
  ninedof_eewriter_init(&ew, slot, gen);
  CHECK(rx.store == NINEDOF_STORE_WRITING);        /* since the upload's commit */
  CHECK(ninedof_eewriter_poll(&ew, &rx));          /* rx is dirty since the upload */
  CHECK(!rx.dirty && rx.store == NINEDOF_STORE_WRITING);
  CHECK(ee_run(1000) == NINEDOF_IMAGE_SIZE);
  /* every byte written, not yet read back: not stored */
  CHECK(ninedof_eewriter_busy(&ew) && ninedof_eewriter_pending(&ew));
  stored_report(&sv, &scrc, &store, &len);
  CHECK(len == sizeof(ninedof_cal_report_msg_t) && len == 33);
  CHECK(sv == 0 && scrc == 0 && store == NINEDOF_STORE_WRITING);
  CHECK(ee_check() == NINEDOF_EE_STORED && !ninedof_eewriter_busy(&ew));
  stored_report(&sv, &scrc, &store, &len);
  CHECK(sv == 0x25 && scrc == rx.active_crc && store == NINEDOF_STORE_IDLE);
  CHECK(ee_check() == 0 && ee_run(10) == 0);       /* nothing pending */
  used = boot(&r2, &slot, &gen);
  CHECK(used == 0 && slot == 1 && gen == 2 && r2.active.version == 0x25);
  CHECK(r2.active_crc == rx.active_crc);
  CHECK(r2.stored_version == 0x25 && r2.stored_crc == rx.active_crc);   /* boot: stored */

  /* a second set goes to slot 1; power cut half-way keeps the first set,
   * and until the write is read back the first is the one reported stored */
  ninedof_cal_identity(&cal, 3, 0x26);
  cal.sensors = 1u << NINEDOF_SENSOR_GYRO;
  upload(&cal);
  CHECK(ninedof_eewriter_poll(&ew, &rx));
  CHECK(ee_run(50) == 50 && ninedof_eewriter_busy(&ew) && !ninedof_eewriter_pending(&ew));
  stored_report(&sv, &scrc, &store, &len);
  CHECK(sv == 0x25 && store == NINEDOF_STORE_WRITING);
  used = boot(&r2, &slot, &gen);
  CHECK(used == 0 && r2.active.version == 0x25 && slot == 1 && gen == 2);

  /* a newer commit during the write restarts it in the same slot */
  cal.version = 0x27;
  upload(&cal);
  CHECK(ninedof_eewriter_poll(&ew, &rx));
  CHECK(ee_run(1000) == NINEDOF_IMAGE_SIZE);
  /* written but not read back when the power goes: boot takes slot 1 (a
   * whole image), though the mote never said it was stored */
  CHECK(ee_check() == NINEDOF_EE_STORED && rx.stored_version == 0x27);
  used = boot(&r2, &slot, &gen);
  CHECK(used == 1 && r2.active.version == 0x27 && slot == 0 && gen == 3);
  CHECK(ninedof_calrx_flags(&r2) == (0x70 | NINEDOF_FLAG_CORRECTED));

  /* nothing to do when nothing changed */
  CHECK(!ninedof_eewriter_poll(&ew, &rx) && ee_run(1000) == 0);

  /* an EEPROM that does not keep a byte: read back wrong, written again,
   * NINEDOF_STORE_TRIES times, then failed; the stored set stays 0x27, and
   * the next set goes to the same slot with the same generation */
  cal.version = 0x28;
  upload(&cal);
  CHECK(ninedof_eewriter_poll(&ew, &rx));
  {
    uint8_t t;
    for (t = 1; t <= NINEDOF_STORE_TRIES; t++) {
      CHECK(ee_run(1000) == NINEDOF_IMAGE_SIZE);
      eeprom[NINEDOF_EEPROM_SLOT0 + 40] ^= 0x10;   /* the cell does not hold it */
      CHECK(ee_check() == (t < NINEDOF_STORE_TRIES ? NINEDOF_EE_AGAIN : NINEDOF_EE_FAILED));
    }
  }
  CHECK(!ninedof_eewriter_busy(&ew) && rx.store == NINEDOF_STORE_FAILED);
  stored_report(&sv, &scrc, &store, &len);
  CHECK(sv == 0x27 && store == NINEDOF_STORE_FAILED && rx.active.version == 0x28);
  used = boot(&r2, &slot, &gen);
  CHECK(used == 1 && r2.active.version == 0x27 && slot == 0 && gen == 3);
  cal.version = 0x29;                              /* the next commit: written again */
  upload(&cal);
  CHECK(rx.store == NINEDOF_STORE_WRITING && ninedof_eewriter_poll(&ew, &rx));
  CHECK(ee_run(1000) == NINEDOF_IMAGE_SIZE && ee_check() == NINEDOF_EE_STORED);
  CHECK(rx.stored_version == 0x29 && rx.store == NINEDOF_STORE_IDLE);
  used = boot(&r2, &slot, &gen);
  CHECK(used == 0 && r2.active.version == 0x29 && slot == 1 && gen == 4);
  out_c('D');
  out_hex(eeprom + NINEDOF_EEPROM_SLOT0, NINEDOF_IMAGE_SIZE);
  out_c(';');
  out_c('D');
  out_hex(eeprom + NINEDOF_EEPROM_SLOT1, NINEDOF_IMAGE_SIZE);
  out_c(';');

  /* a set an image before the temperature terms saved in its second slot
   * (0x180, inside today's slot 0) is restored, and the next write goes to
   * slot 1, which overlaps neither old slot */
  memset(eeprom, 0xFF, sizeof(eeprom));
  ninedof_calrx_image(&rx, 7, eeprom + NINEDOF_EEPROM_LEGACY1);
  used = boot(&r2, &slot, &gen);
  CHECK(used == 2 && slot == 1 && gen == 8 && r2.active.version == 0x29);
  CHECK(NINEDOF_EEPROM_SLOT0 + NINEDOF_IMAGE_MAX <= NINEDOF_EEPROM_SLOT1 &&
        NINEDOF_EEPROM_SLOT1 + NINEDOF_IMAGE_MAX <= 0x1000 &&
        NINEDOF_IMAGE_MAX <= NINEDOF_EEPROM_SLOT_SIZE);
}

/* ---------------------------------------------------------------------- */
static void test_basestation(void)
{
  ninedof_bs_counters_t c = { 1, 2, 3, 4, 5, 0xFFFF };
  ninedof_bs_status_msg_t st;

  /* 8 MHz iris: MeasureClockC finds 244 cycles per 1/32768 s */
  CHECK(ninedof_bs_ubrr(244, 250000UL) == 3);              /* TinyOS: 2 */
  CHECK((244UL << 12) / 250000UL - 1 == 2);                 /* = 333 kbaud */
  CHECK(ninedof_bs_ubrr(244, 500000UL) == 1);
  CHECK(ninedof_bs_ubrr(244, 76800UL) == 12);
  CHECK(ninedof_bs_ubrr(244, 57600UL) == 16);
  CHECK(ninedof_bs_ubrr(245, 250000UL) == 3);               /* a slightly fast clock */
  /* error of the rounded divisor at the nominal clock (8 MHz / 8 / (UBRR+1)) */
  CHECK(8000000UL / 8 / (ninedof_bs_ubrr(244, 250000UL) + 1) == 250000UL);
  CHECK(ninedof_bs_baud(244, 3) == 249856UL);
  ninedof_bs_status_pack(&c, &st);
  CHECK(nxp_get_u16(&st.radio_rx) == 1 && nxp_get_u16(&st.serial_fail) == 0xFFFF);
  out_c('D');
  out_hex((const uint8_t *)&st, sizeof(st));
  out_c(';');
}

int main(void)
{
  out_init();
  test_board();
  test_clock();
  test_clock_arm();
  test_batching();
  test_align();
  test_status();
  test_temp();
  test_eeprom();
  test_basestation();
  check_summary();
  out_end();
  return failed != 0;
}
