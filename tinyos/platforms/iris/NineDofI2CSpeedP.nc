/*
 * NineDofI2CSpeedP -- runs the I2C bus at most at NINEDOF_I2C_HZ (380 kHz: TWBR = 3, 364 kHz).
 *
 * The stock HplAtm128I2CBusP sets TWBR for a 7.37 MHz clock and 50 kHz when
 * the bus is powered, which on an 8 MHz iris is about 55 kHz.  The bus is
 * powered on every grant (AsyncPowerManagerP starts it when a client gets
 * it), so this decorator of one client's Resource writes the bit-rate
 * register each time that client has the bus, before its first transfer.
 * SCL = F_CPU / (16 + 2 * TWBR), prescaler 1: TWBR = 3 at 8 MHz (see ninedof_board.h
 * for why not 2 = 400 kHz: SCL low must stay >= 1.3 us).
 *
 * @author motecal
 */
#include "ninedof_board.h"

generic module NineDofI2CSpeedP()
{
  provides interface Resource;
  uses interface Resource as SubResource;
}
implementation
{
  enum {
    TWBR_FAST = NINEDOF_TWBR(PLATFORM_MHZ * 1000000UL, NINEDOF_I2C_HZ),
  };

  inline void fast() {
    atomic {
      TWSR &= ~((1 << TWPS1) | (1 << TWPS0));   /* prescaler 1 */
      TWBR = TWBR_FAST;
    }
  }

  async command error_t Resource.request() {
    return call SubResource.request();
  }

  async command error_t Resource.immediateRequest() {
    error_t err = call SubResource.immediateRequest();
    if (err == SUCCESS)
      fast();
    return err;
  }

  event void SubResource.granted() {
    fast();
    signal Resource.granted();
  }

  async command error_t Resource.release() {
    return call SubResource.release();
  }

  async command bool Resource.isOwner() {
    return call SubResource.isOwner();
  }
}
