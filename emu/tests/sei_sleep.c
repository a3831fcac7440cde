/*
 * emu/tests/sei_sleep.c -- an interrupt that became pending while interrupts
 * were off is taken at `sei; sleep; cli` (TinyOS's McuSleep), before the
 * CLI, as on the AVR (tests/test_emu_cli.py).  The TWI interrupt is made
 * pending by a START with interrupts off.  Prints "I<handler runs before
 * the cli>;END".
 */
#include <stdint.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>

#include "test_out.h"

static volatile uint8_t hits;

ISR(TWI_vect)
{
  hits++;
  TWCR = _BV(TWINT) | _BV(TWSTO) | _BV(TWEN);   /* STOP, no more interrupts */
}

int main(void)
{
  uint8_t seen;
  out_init();
  TWBR = 3;
  cli();
  TWCR = _BV(TWINT) | _BV(TWSTA) | _BV(TWEN) | _BV(TWIE);
  while (!(TWCR & _BV(TWINT)))                   /* the START is done: pending */
    ;
  set_sleep_mode(SLEEP_MODE_IDLE);
  sleep_enable();
  __asm__ __volatile__("sei\n\tsleep\n\tcli" ::: "memory");
  seen = hits;
  out_s("I");
  out_u16(seen);
  out_s(";END");
  out_end();
  return 0;
}
