/*
 * avr_cal_main.c -- runs the calibration C code (tinyos/ninedof_calset.c,
 * ninedof_correct.c, ninedof_calrx.c) on the ATmega1281 in simavr.
 *
 * tests/test_avr.py generates "vectors.h" (calibration sets, raw records and
 * a script of upload messages, all in flash), builds this file with avr-gcc
 * and compares what it prints on UART0 with the host build (motecal.firmware.mote_c)
 * bit for bit.  Output: hex tokens, each item ending in ';', then "END".
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#include <avr/sleep.h>
#include <string.h>

#include "ninedof_cal.h"
#include "test_out.h"
#include "vectors.h"

static void out_hex8(uint8_t v)
{
  out_hex(&v, 1);
}

static void out_hex16(uint16_t v)
{
  out_hex8((uint8_t)(v >> 8));
  out_hex8((uint8_t)v);
}

static ninedof_calrx_t rx;
static ninedof_cal_t cal;
static uint8_t wire[NINEDOF_CALSET_MAX];
static int16_t raw[NINEDOF_BATCH * 9];
static int16_t out[NINEDOF_BATCH * 9];
static uint8_t msg[255];
static uint8_t reply[sizeof(ninedof_cal_report_msg_t)];
static uint8_t img0[NINEDOF_IMAGE_MAX], img1[NINEDOF_IMAGE_MAX];

int main(void)
{
  uint16_t i, r, pos;
  uint8_t k;

  out_init();

  /* 1. every calibration set over every record (at its temperature, if
   * one is given): C<status><records>; */
  for (i = 0; i < NCAL; i++) {
    uint8_t len = pgm_read_byte(&CALSET_LEN[i]);
    memcpy_P(wire, CALSETS[i], len);
    out_c('C');
    out_hex8(ninedof_cal_decode(wire, len, &cal));
    out_hex8(ninedof_cal_validate(&cal, MOTE_ID));
    if (pgm_read_byte(&CAL_HAS_TEMP[i]))
      ninedof_cal_set_temp(&cal, (int16_t)pgm_read_word(&CAL_TEMP[i]));
    for (r = 0; r < NREC; r++) {
      memcpy_P(raw, &RAW[r * 9], 18);
      ninedof_correct(&cal, raw, out);
      for (k = 0; k < 9; k++)
        out_hex16((uint16_t)out[k]);
    }
    out_c(';');
  }

  /* 2. the upload script through the receiver: R<type><len><reply>; */
  ninedof_calrx_init(&rx, MOTE_ID);
  pos = 0;
  while (pos < MSGS_LEN) {
    uint8_t type = pgm_read_byte(&MSGS[pos]);
    uint8_t len = pgm_read_byte(&MSGS[pos + 1]);
    uint8_t rtype = 0, n;
    memcpy_P(msg, &MSGS[pos + 2], len);
    pos += 2u + len;
    n = ninedof_calrx_handle(&rx, type, msg, len, reply, &rtype);
    out_c('R');
    out_hex8(rtype);
    out_hex8(n);
    out_hex(reply, n);
    out_c(';');
  }

  /* 3. flags, dirty, and the records corrected in batches with the set in force */
  out_c('F');
  out_hex8(ninedof_calrx_flags(&rx));
  out_hex8(rx.dirty);
  for (r = 0; r < NREC; r += NINEDOF_BATCH) {
    uint16_t n = (uint16_t)(NREC - r < NINEDOF_BATCH ? NREC - r : NINEDOF_BATCH);
    memcpy_P(raw, &RAW[r * 9], n * 18u);
    ninedof_calrx_correct_block(&rx, raw, raw, n);   /* in place */
    for (k = 0; k < n * 9; k++)
      out_hex16((uint16_t)raw[k]);
  }
  out_c(';');

  /* 4. image and restore: I<image>; S<slot><next slot><next generation><flags>; */
  k = ninedof_calrx_image(&rx, 0x1234, img0);
  out_c('I');
  out_hex(img0, k);
  out_c(';');
  memset(img1, 0xFF, sizeof(img1));
  {
    uint8_t slot, next_slot = 0;
    uint16_t next_gen = 0;
    ninedof_calrx_init(&rx, MOTE_ID);
    slot = ninedof_calrx_restore(&rx, img1, img0, NULL, &next_slot, &next_gen);
    out_c('S');
    out_hex8(slot);
    out_hex8(next_slot);
    out_hex16(next_gen);
    out_hex8(ninedof_calrx_flags(&rx));
    out_c(';');
  }
  out_c('E');
  out_c('N');
  out_c('D');
  out_c('\n');
  out_end();
  return 0;
}
