/*
 * emu/tests/bus_clear.c -- the firmware's bus clear against the harness's
 * wires (tests/test_emu_busclear.py): the lean TWI master's state machine
 * (tinyos/ninedof_twi.c) in the TWI interrupt reads the ITG-3200 model;
 * when a read does not end (a --fault holds a line), the TWI is switched
 * off and on again without a clear (the bus stays busy), then the pins are
 * clocked as the firmware's NineDofBusClearP does: ninedof_busclear_step
 * (tinyos/ninedof_fault.c) on PD0 (SCL) and PD1 (SDA), open drain by the
 * data direction, 5 us half periods.  Prints on UART0:
 *
 *   PINS <released> <sda low> <scl low> <both low>;   PIND & 3 with the TWI off
 *   ID <who_am_i>;
 *   MARK;                                  a write to 0x77: the fault phase starts
 *   R <i> <result>;                        12 gyro reads, 2 ms apart (255: hung)
 *   OFFON <result>;                        after a hang: the TWI off and on, read again
 *   CLEAR <busclear result>;               then the bus clear, and the TWI on again
 *   END
 * Results of reads are NINEDOF_TWI_* outcomes (0 ok).
 */
#include <stdint.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/delay.h>

#include "ninedof_board.h"
#include "ninedof_fault.h"
#include "test_out.h"
#include "twi_ops.h"

enum { SCL = 1 << 0, SDA = 1 << 1, HUNG = TWI_OP_HUNG };

static void twi_on(void)
{
  DDRD &= (uint8_t)~(SCL | SDA);
  PORTD &= (uint8_t)~(SCL | SDA);
  TWBR = NINEDOF_TWBR(F_CPU, NINEDOF_I2C_HZ);
  TWSR = 0;
  TWCR = _BV(TWEN);
}

/* NineDofBusClearP's drive(): a line released (input, pulled up) or low */
static void drive(uint8_t act)
{
  PORTD &= (uint8_t)~(SCL | SDA);
  if (act & NINEDOF_BC_SCL)
    DDRD &= (uint8_t)~SCL;
  else
    DDRD |= SCL;
  if (act & NINEDOF_BC_SDA)
    DDRD &= (uint8_t)~SDA;
  else
    DDRD |= SDA;
}

/* NineDofBusClearP's clear(), the TWI off */
static uint8_t bus_clear(void)
{
  ninedof_busclear_t bc;
  uint8_t act, pins;
  ninedof_busclear_init(&bc);
  drive(NINEDOF_BC_SCL | NINEDOF_BC_SDA);
  for (;;) {
    _delay_us(5);
    pins = PIND;
    act = ninedof_busclear_step(&bc, (pins & SCL) ? 1 : 0, (pins & SDA) ? 1 : 0);
    if (act & NINEDOF_BC_DONE) {
      drive(NINEDOF_BC_SCL | NINEDOF_BC_SDA);
      return act;
    }
    drive(act);
  }
}

static void out_pins(uint8_t act)
{
  drive(act);
  _delay_us(1);
  out_c(' ');
  out_u16(PIND & 3);
}

int main(void)
{
  uint8_t g[8], i, r;
  out_init();
  ninedof_twi_init(&twi);
  twi_op_limit = 500;                   /* 5 ms */
  /* the wires with the TWI off: released, SDA low, SCL low, both low */
  out_s("PINS");
  out_pins(NINEDOF_BC_SCL | NINEDOF_BC_SDA);
  out_pins(NINEDOF_BC_SCL);
  out_pins(NINEDOF_BC_SDA);
  out_pins(0);
  drive(NINEDOF_BC_SCL | NINEDOF_BC_SDA);
  out_c(';');
  twi_on();
  sei();
  read_regs(ITG3200_ADDR, ITG3200_WHO_AM_I, 1, g);
  out_s("ID ");
  out_hex(g, 1);
  out_c(';');
  _delay_ms(60);                        /* the ITG-3200's start-up */

  out_s("MARK ");
  g[0] = 0;
  out_u16(op(0, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x77, 1, g));
  out_c(';');
  for (i = 0; i < 12; i++) {
    r = read_regs(ITG3200_ADDR, ITG3200_GYRO_XOUT_H - 2, 8, g);
    out_s("R ");
    out_u16(i);
    out_c(' ');
    out_u16(r);
    out_c(';');
    if (r == HUNG) {
      TWCR = 0;                         /* the TWI off and on: no clock pulse */
      twi_on();
      out_s("OFFON ");
      out_u16(read_regs(ITG3200_ADDR, ITG3200_WHO_AM_I, 1, g));
      out_c(';');
      TWCR = 0;                         /* the pins are the port's */
      out_s("CLEAR ");
      out_u16(bus_clear());
      out_c(';');
      twi_on();
    }
    _delay_ms(2);
  }
  out_s("END");
  _delay_ms(1);
  out_end();
  return 0;
}
