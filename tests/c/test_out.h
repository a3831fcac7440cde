/*
 * test_out.h -- text output of the C test programs (logic_tests.c,
 * avr_bench.c, avr_cal_main.c): on the ATmega1281 in simavr through UART0
 * (which tests/avrsim.py reads), on the host through stdio.
 *
 *   out_init()          set up the output (UART0 at the fastest rate)
 *   out_c / out_s       a character / a string
 *   out_u16             a number in decimal
 *   out_hex(p, n)       n bytes, two lowercase hex digits each
 *   out_end()           flush; on the AVR stop the program (simavr exits)
 *
 * static inline: a program need not use every one (-Wall -Werror).
 */
#ifndef TEST_OUT_H
#define TEST_OUT_H

#include <stdint.h>

#ifdef __AVR__
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>

static inline void out_init(void)
{
  UCSR0A = _BV(U2X0);
  UBRR0 = 0;
  UCSR0B = _BV(TXEN0);
}

static inline void out_c(char c)
{
  while (!(UCSR0A & _BV(UDRE0)))
    ;
  UDR0 = (uint8_t)c;
}

static inline void out_end(void)
{
  cli();
  sleep_cpu();
}
#else
#include <stdio.h>

static inline void out_init(void) { }
static inline void out_c(char c) { putchar(c); }
static inline void out_end(void) { fflush(stdout); }
#endif

static inline void out_s(const char *s)
{
  while (*s)
    out_c(*s++);
}

static inline void out_u16(uint16_t v)
{
  char buf[6];
  uint8_t i = 0;
  do {
    buf[i++] = (char)('0' + v % 10);
    v /= 10;
  } while (v);
  while (i)
    out_c(buf[--i]);
}

static inline void out_hex(const uint8_t *p, uint16_t n)
{
  static const char digits[] = "0123456789abcdef";
  while (n--) {
    out_c(digits[*p >> 4]);
    out_c(digits[*p++ & 15]);
  }
}

#endif /* TEST_OUT_H */
