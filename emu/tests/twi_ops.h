/*
 * emu/tests/twi_ops.h -- the test programs' I2C operations (twi_chips.c,
 * bus_clear.c): the lean master's state machine (tinyos/ninedof_twi.c) run
 * from the TWI interrupt, an operation begun with interrupts off, then
 * waited for.  Include once, in the program's C file.
 */
#ifndef EMU_TESTS_TWI_OPS_H
#define EMU_TESTS_TWI_OPS_H

#include <stdint.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/delay.h>

#include "ninedof_twi.h"

enum { TWI_OP_HUNG = 255 };

static ninedof_twi_t twi;
/* how long an operation is waited for, in 10 us steps (0: for ever); one
 * that did not end by then is aborted and gives TWI_OP_HUNG */
static uint16_t twi_op_limit;

ISR(TWI_vect)
{
  (void)ninedof_twi_interrupt(&twi, &TWSR, &TWDR, &TWCR);
}

static uint8_t op(uint8_t read, uint8_t flags, uint8_t addr, uint8_t len, uint8_t *buf)
{
  uint16_t n;
  uint8_t cmd;
  cli();
  cmd = ninedof_twi_begin(&twi, read, flags, addr, len, buf);
  TWDR = twi.out;
  TWCR = cmd;
  sei();
  for (n = 0; *(volatile uint8_t *)&twi.state != NINEDOF_TWI_DONE; n++) {
    if (twi_op_limit && n == twi_op_limit) {
      cli();
      (void)ninedof_twi_abort(&twi);
      sei();
      return TWI_OP_HUNG;
    }
    if (twi_op_limit)
      _delay_us(10);
  }
  /* a STOP leaves no interrupt: wait until the TWI has sent it */
  while (TWCR & _BV(TWSTO))
    ;
  return twi.result;
}

/* write reg, repeated START, read len bytes */
static uint8_t read_regs(uint8_t addr, uint8_t reg, uint8_t len, uint8_t *buf)
{
  uint8_t r = op(0, NINEDOF_I2C_START, addr, 1, &reg);
  if (r)
    return r;
  return op(1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, addr, len, buf);
}

#endif
