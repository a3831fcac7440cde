/*
 * avr_bench.c -- cycle counts of the per-sample work on the ATmega1281,
 * measured in simavr with timer 1 running at clk/1 (bench/bench_cycles.py).
 * Prints "<name> <cycles>;" for each item, then "END".
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <string.h>

#include "ninedof_board.h"
#include "ninedof_cal.h"
#include "ninedof_clock.h"
#include "ninedof_sampling.h"
#include "test_out.h"

static uint16_t overhead;

/* The lean TWI master's interrupt handler (NineDofTwiMasterImplP, build
 * option NINEDOF_LEAN_I2C=1) as the nesC build compiles it: the state
 * machine inlined, the end of an operation called through
 * NINEDOF_TWI_CALL_SAVING.  Debian's simavr has no working TWI, so the
 * handler is called directly, on stand-ins for TWSR / TWDR / TWCR (data
 * memory like them: the same two-cycle lds / sts). */
#define NINEDOF_TWI_FN static inline
#include "ninedof_twi.c"
static ninedof_twi_t twi;
static volatile uint8_t twsr, twdr, twcr, twi_done;
static uint8_t twi_buf[6];

static void twi_signal_done(void) { twi_done++; }

ISR(TWI_vect)
{
  if (ninedof_twi_interrupt(&twi, &twsr, &twdr, &twcr)) {
    twi.state = NINEDOF_TWI_IDLE;
    NINEDOF_TWI_CALL_SAVING(twi_signal_done);
  }
}

#define MEASURE(name, stmt)                                             \
  do {                                                                  \
    uint16_t t0_, t1_;                                                  \
    cli();                                                              \
    t0_ = TCNT1;                                                        \
    stmt;                                                               \
    t1_ = TCNT1;                                                        \
    out_s(name " ");                                                    \
    out_u16((uint16_t)(t1_ - t0_ - overhead));                          \
    out_c(';');                                                         \
  } while (0)

static ninedof_calrx_t rx;
static ninedof_cal_t cal;
static ninedof_batch_t batch;
static ninedof_samples_msg_t msg;
static ninedof_eewriter_t ew;
static ninedof_clock_t clk;
static ninedof_align_t align;
static uint16_t align_seq;
static int16_t raw[NINEDOF_BATCH * 9], out[NINEDOF_BATCH * 9];
static uint8_t bytes[3][6];
static uint8_t reply[sizeof(ninedof_cal_report_msg_t)], rtype;
static ninedof_calset_t wire;
static ninedof_cal_frag_msg_t frag;
static ninedof_cal_commit_msg_t commit;

/* a plausible calibration: all three sensors, Q14, cross-axis terms */
static void make_cal(void)
{
  uint8_t k, i;
  ninedof_cal_identity(&cal, 1, 7);
  cal.sensors = 7;
  for (k = 0; k < 3; k++) {
    for (i = 0; i < 9; i++)
      cal.s[k].a[i] = (int16_t)((i % 4 == 0) ? 16384 + 300 * (int16_t)i - 900
                                             : 170 * (int16_t)i - 600);
    for (i = 0; i < 3; i++)
      cal.s[k].c[i] = (int32_t)(i * 37L - 50L) * 16384L;
  }
}

int main(void)
{
  uint16_t i, t0, t1, addr;
  uint8_t v;

  out_init();
  TCCR1A = 0;
  TCCR1B = _BV(CS10);                 /* timer 1 at clk/1: one count per cycle */
  t0 = TCNT1;
  t1 = TCNT1;
  overhead = (uint16_t)(t1 - t0);

  for (i = 0; i < NINEDOF_BATCH * 9; i++)
    raw[i] = (int16_t)(i * 1733 - 30000);
  for (i = 0; i < 18; i++)
    bytes[i / 6][i % 6] = (uint8_t)(i * 37 + 11);
  make_cal();

  MEASURE("correct_9axes", ninedof_correct(&cal, raw, out));
  MEASURE("correct_block5", ninedof_correct_block(&cal, raw, out, NINEDOF_BATCH));
  cal.sensors = 0;
  MEASURE("correct_raw", ninedof_correct(&cal, raw, out));
  cal.sensors = 7;
  for (i = 0; i < 3; i++)
    cal.s[i].shift = 13;              /* half-scale copies: still exact */
  for (i = 0; i < 9; i++) {
    cal.s[0].a[i] /= 2; cal.s[1].a[i] /= 2; cal.s[2].a[i] /= 2;
  }
  for (i = 0; i < 3; i++) {
    cal.s[0].c[i] /= 2; cal.s[1].c[i] /= 2; cal.s[2].c[i] /= 2;
  }
  MEASURE("correct_9axes_q13", ninedof_correct(&cal, raw, out));
  make_cal();
  /* temperature terms on all three sensors (format NINEDOF_CALSET_TEMP) */
  cal.format = NINEDOF_CALSET_TEMP;
  cal.temp_sensors = 7;
  for (i = 0; i < 3; i++) {
    uint8_t j;
    cal.t[i].t_ref = -16000;
    cal.t[i].t_lo = -19000;
    cal.t[i].t_hi = -11000;
    for (j = 0; j < 3; j++) {
      cal.t[i].o[j] = (int16_t)(12000 - 9000 * (int16_t)j);
      cal.t[i].g[j] = (int16_t)(-7000 + 6000 * (int16_t)j);
    }
    cal.t[i].oshift = 22;
    cal.t[i].gshift = 32;
  }
  MEASURE("cal_set_temp", ninedof_cal_set_temp(&cal, -14100));
  MEASURE("correct_9axes_temp", ninedof_correct(&cal, raw, out));
  MEASURE("correct_block5_temp", ninedof_correct_block(&cal, raw, out, NINEDOF_BATCH));
  for (i = 0; i < 3; i++)             /* offsets only: no gain change with temperature */
    cal.t[i].g[0] = cal.t[i].g[1] = cal.t[i].g[2] = 0;
  ninedof_cal_set_temp(&cal, -14100);
  MEASURE("correct_9axes_temp_offsets", ninedof_correct(&cal, raw, out));
  MEASURE("correct_block5_temp_offsets", ninedof_correct_block(&cal, raw, out, NINEDOF_BATCH));
  make_cal();

  MEASURE("board_record", ninedof_board_record(bytes[0], bytes[1], bytes[2], out));
  ninedof_align_init(&align);
  ninedof_align_push(&align, 0, raw, out, &align_seq);
  MEASURE("align_push", (void)ninedof_align_push(&align, 1, raw, out, &align_seq));

  /* upload: fragments, commit (CRC + decode + validate), then batch with it */
  ninedof_calrx_init(&rx, 1);
  ninedof_cal_encode(&cal, &wire);
  nxp_set_u16(&frag.mote, 1);
  nxp_set_u16(&frag.version, 7);
  for (i = 0; i < sizeof(wire); i += NINEDOF_FRAG_DATA) {
    uint8_t n = (uint8_t)(sizeof(wire) - i < NINEDOF_FRAG_DATA ? sizeof(wire) - i
                                                               : NINEDOF_FRAG_DATA);
    nxp_set_u8(&frag.offset, (uint8_t)i);
    nxp_set_u8(&frag.len, n);
    memcpy(frag.data, (uint8_t *)&wire + i, n);
    if (i == 0)
      MEASURE("calrx_fragment", ninedof_calrx_handle(&rx, AM_NINEDOF_CAL_FRAG_MSG,
                                                     (uint8_t *)&frag, sizeof(frag),
                                                     reply, &rtype));
    else
      ninedof_calrx_handle(&rx, AM_NINEDOF_CAL_FRAG_MSG, (uint8_t *)&frag, sizeof(frag),
                           reply, &rtype);
  }
  MEASURE("crc16_set", (void)ninedof_crc16(0, (uint8_t *)&wire, sizeof(wire)));
  nxp_set_u16(&commit.mote, 1);
  nxp_set_u16(&commit.version, 7);
  nxp_set_u8(&commit.length, sizeof(wire));
  nxp_set_u8(&commit.action, NINEDOF_CAL_APPLY);
  nxp_set_u16(&commit.crc, ninedof_crc16(0, (uint8_t *)&wire, sizeof(wire)));
  MEASURE("calrx_commit", ninedof_calrx_handle(&rx, AM_NINEDOF_CAL_COMMIT_MSG,
                                               (uint8_t *)&commit, sizeof(commit),
                                               reply, &rtype));
  out_s("commit_status ");
  out_u16(reply[6]);
  out_c(';');

  ninedof_batch_init(&batch);
  MEASURE("batch_add", ninedof_batch_add(&batch, 0, raw));
  for (i = 1; i < NINEDOF_BATCH; i++)
    ninedof_batch_add(&batch, i, raw + 9 * i);
  MEASURE("batch_pack5", ninedof_batch_pack(&batch, &rx, &msg));
  MEASURE("calrx_flags", (void)ninedof_calrx_flags(&rx));

  ninedof_eewriter_init(&ew, 0, 1);
  MEASURE("eeprom_image", ninedof_eewriter_poll(&ew, &rx));
  MEASURE("eeprom_next_byte", ninedof_eewriter_next(&ew, &addr, &v));

  /* the sampling clock: an ordinary period, and one that ends a second
   * once the loop is locked (third second: PI update) */
  ninedof_clock_init(&clk, 244);
  for (i = 0; i < 3 * NINEDOF_RATE_HZ - 1; i++) {
    if (i == 10)
      MEASURE("clock_period", (void)ninedof_clock_next(&clk, (uint32_t)i * 1024 / 125));
    else
      (void)ninedof_clock_next(&clk, (uint32_t)i * 1024 / 125);
  }
  MEASURE("clock_update", (void)ninedof_clock_next(&clk, 3 * 1024 - 5));

  /* the TWI handler, called like the interrupt (call + reti: 8 cycles,
   * where the hardware takes 5 + a 3-cycle jump): START done -> address,
   * address ACKed, a byte read (ACK the next), the last byte (STOP: the end
   * of the operation, with its call) */
  ninedof_twi_init(&twi);
  (void)ninedof_twi_begin(&twi, 1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x68, 6, twi_buf);
  twsr = NINEDOF_TW_START;
  MEASURE("twi_isr_start", TWI_vect());
  twsr = NINEDOF_TW_MR_SLA_ACK;
  MEASURE("twi_isr_addr", TWI_vect());
  twsr = NINEDOF_TW_MR_DATA_ACK;
  for (i = 0; i < 4; i++)
    TWI_vect();
  MEASURE("twi_isr_byte", TWI_vect());
  twsr = NINEDOF_TW_MR_DATA_NACK;
  MEASURE("twi_isr_last", TWI_vect());
  cli();
  out_s("twi_done ");
  out_u16(twi_done);
  out_c(';');

  out_s("END\n");
  out_end();
  return 0;
}
