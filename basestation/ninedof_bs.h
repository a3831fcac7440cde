/*
 * ninedof_bs.h -- the BaseStation's plain C: its counters and the serial
 * bit-rate divisor.  Tested on the host and in simavr (tests/test_avr.py).
 */
#ifndef NINEDOF_BS_H
#define NINEDOF_BS_H

#include <stdint.h>
#include "NineDofMsg.h"

#ifndef NINEDOF_BS_QUEUE
#define NINEDOF_BS_QUEUE 12     /* messages buffered in each direction */
#endif
#ifndef NINEDOF_BS_RETRIES
#define NINEDOF_BS_RETRIES 2    /* resends of an unacknowledged radio message */
#endif

typedef struct {
  uint16_t radio_rx;       /* packets received from the radio */
  uint16_t radio_drops;    /* radio -> serial queue full */
  uint16_t serial_rx;      /* packets received from the serial line */
  uint16_t serial_drops;   /* serial -> radio queue full */
  uint16_t radio_fail;     /* radio sends that failed after the retries */
  uint16_t serial_fail;    /* serial sends that failed after the retries */
} ninedof_bs_counters_t;

void ninedof_bs_status_pack(const ninedof_bs_counters_t *c, ninedof_bs_status_msg_t *msg);

/* UBRR for `baud` with the UART in double-speed mode (U2X = 1), from the
 * CPU cycles per 1/32768 s that MeasureClockC measured at boot, rounded to
 * the nearest divisor:  UBRR = round(cycles * 32768 / (8 * baud)) - 1.
 * (TinyOS truncates instead: at 8 MHz, 244 cycles, 250000 baud gives 2,
 * i.e. 333 kbaud; rounding gives 3, exactly 250 kbaud.) */
uint16_t ninedof_bs_ubrr(uint16_t cycles_per_jiffy, uint32_t baud);

/* The bit rate a divisor gives at a clock of `cycles_per_jiffy` * 32768 Hz */
uint32_t ninedof_bs_baud(uint16_t cycles_per_jiffy, uint16_t ubrr);

#endif
