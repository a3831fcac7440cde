/*
 * emu/tests/clock_crystal.c -- the main clock against the 32768 Hz crystal
 * on timer 2 (asynchronous, AS2), as iris uses it (tests/test_emu_clock.py).
 * Timer 1 counts CPU cycles (clk/1, overflows counted); timer 2 counts the
 * crystal (clk_T2S/1).  Prints "C <cycles over 16 timer-2 overflows> <cycles
 * from TCNT2 = 0 to TCNT2 = 128>;END".
 */
#include <stdint.h>
#include <avr/interrupt.h>
#include <avr/io.h>

#include "test_out.h"

static volatile uint16_t t1_ovf;
static volatile uint8_t t2_ovf;

ISR(TIMER1_OVF_vect) { t1_ovf++; }
ISR(TIMER2_OVF_vect) { t2_ovf++; }

static uint32_t cycles(void)
{
  uint16_t hi, lo;
  cli();
  lo = TCNT1;
  hi = t1_ovf;
  if ((TIFR1 & _BV(TOV1)) && lo < 0x8000)
    hi++;
  sei();
  return ((uint32_t)hi << 16) | lo;
}

int main(void)
{
  uint32_t c0, c1, c2, c3;
  uint8_t n;
  out_init();
  TCCR1A = 0;
  TCCR1B = _BV(CS10);              /* clk/1 */
  TIMSK1 = _BV(TOIE1);
  ASSR = _BV(AS2);                 /* timer 2 from the 32768 Hz crystal */
  TCCR2A = 0;
  TCCR2B = _BV(CS20);              /* no prescaler: 128 overflows per second */
  while (ASSR & (_BV(TCN2UB) | _BV(TCR2BUB)))
    ;
  TIMSK2 = _BV(TOIE2);
  sei();
  n = t2_ovf;
  while (t2_ovf == n)
    ;
  c0 = cycles();
  n = t2_ovf;
  while ((uint8_t)(t2_ovf - n) < 16)
    ;
  c1 = cycles();
  while (TCNT2 != 0)
    ;
  c2 = cycles();
  while (TCNT2 < 128)
    ;
  c3 = cycles();
  out_s("C ");
  out_u16((uint16_t)((c1 - c0) >> 16)); out_c(':'); out_u16((uint16_t)(c1 - c0));
  out_c(' ');
  out_u16((uint16_t)((c3 - c2) >> 16)); out_c(':'); out_u16((uint16_t)(c3 - c2));
  out_s(";END");
  out_end();
  return 0;
}
