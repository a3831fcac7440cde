/*
 * NineDofBusClearP -- the I2C bus clear on the iris TWI pins (SCL = PD0,
 * SDA = PD1), open drain by hand: a line is released by making its pin an
 * input (the board's pull-ups raise it) and driven low by making it an
 * output at 0.  The sequence is ninedof_busclear_step (ninedof_fault.c,
 * tested against a model of the lines and a stuck slave): up to 9 SCL
 * pulses until the slave lets SDA go, then a STOP.  Half periods of
 * NINEDOF_BUSCLEAR_HALF_US (5 us: 100 kHz, standard mode, which every
 * chip takes); at most NINEDOF_BUSCLEAR_MAX_STEPS of them, so it returns
 * within about 2 ms whatever the lines do.  Interrupts stay on (I2C has no
 * lower bound on the clock).  The caller switches the TWI off first, since
 * an enabled TWI owns the pins.
 *
 * @author motecal
 */
#include "ninedof_fault.h"

module NineDofBusClearP @safe()
{
  provides interface NineDofBusClear;
  uses interface BusyWait<TMicro, uint16_t>;
}
implementation
{
  enum {
    SCL = 1 << 0,      /* PD0 */
    SDA = 1 << 1,      /* PD1 */
    HALF_US = 5,
  };

  void drive(uint8_t act) {
    atomic {
      PORTD &= ~(SCL | SDA);
      if (act & NINEDOF_BC_SCL)
        DDRD &= ~SCL;
      else
        DDRD |= SCL;
      if (act & NINEDOF_BC_SDA)
        DDRD &= ~SDA;
      else
        DDRD |= SDA;
    }
  }

  async command uint8_t NineDofBusClear.clear() {
    ninedof_busclear_t bc;
    uint8_t act, pins;

    ninedof_busclear_init(&bc);
    drive(NINEDOF_BC_SCL | NINEDOF_BC_SDA);
    for (;;) {
      call BusyWait.wait(HALF_US);
      pins = PIND;
      act = ninedof_busclear_step(&bc, (pins & SCL) ? 1 : 0, (pins & SDA) ? 1 : 0);
      if (act & NINEDOF_BC_DONE) {
        drive(NINEDOF_BC_SCL | NINEDOF_BC_SDA);
        return act;
      }
      drive(act);
    }
  }
}
