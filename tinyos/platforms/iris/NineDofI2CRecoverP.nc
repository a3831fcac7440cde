/*
 * NineDofI2CRecoverP -- bus recovery for TinyOS's own I2C master
 * (Atm128I2CMasterC, the default build), without changing it.
 *
 * The stock master has no abort: an operation whose TWI interrupt never
 * comes (a slave holds SDA or SCL low) leaves it busy for good, and every
 * later operation is refused.  Recovery: the TWI off, the bus cleared
 * (NineDofBusClearP), the TWI on at the board's bit rate, and a START
 * requested with its interrupt on, if the master was waiting for one
 * (TWIE set; it clears TWIE when an operation ends).  That interrupt reaches the stock
 * master's handler in whatever state it was stuck: waiting for a START it
 * continues the operation (the START it asked for has now happened);
 * waiting for an address or data byte it finds a status it does not
 * expect and ends the operation with an error (its own i2c_abort, which
 * also resets the TWI).  Either way the operation ends and the client is
 * told.
 *
 * @author motecal
 */
#include "ninedof_board.h"

module NineDofI2CRecoverP @safe()
{
  provides interface NineDofI2CRecover;
  uses interface NineDofBusClear;
}
implementation
{
  enum {
    TWBR_FAST = NINEDOF_TWBR(PLATFORM_MHZ * 1000000UL, NINEDOF_I2C_HZ),
  };

  async command uint8_t NineDofI2CRecover.recover() {
    uint8_t r, was;
    atomic {
      /* the stock master enables the TWI interrupt with each command and
       * disables it when an operation ends: set = an operation waits */
      was = TWCR;
      TWCR = 0;                               /* TWI off: the pins are ours */
    }
    r = call NineDofBusClear.clear();
    atomic {
      TWSR &= ~((1 << TWPS1) | (1 << TWPS0));
      TWBR = TWBR_FAST;
      if (was & (1 << TWIE))
        /* a START with its interrupt: the stock master's handler runs and
         * ends (or continues) the operation it was stuck in */
        TWCR = (1 << TWINT) | (1 << TWSTA) | (1 << TWEN) | (1 << TWIE);
      else
        /* no operation in the master: on or off as it was, no command (an
         * interrupt nobody handles would repeat for ever) */
        TWCR = was & (1 << TWEN);
    }
    return r;
  }
}
