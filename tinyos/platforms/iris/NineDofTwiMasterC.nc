/*
 * NineDofTwiMasterC -- one client of the lean TWI master (build option
 * NINEDOF_LEAN_I2C=1, selected in HplNineDofI2CC): the same Resource +
 * I2CPacket<TI2CBasicAddr> as TinyOS's Atm128I2CMasterC, arbitrated and
 * powered on demand the same way (FcfsArbiterC + AsyncPowerManagerP), with
 * the bus in fast mode (NINEDOF_I2C_HZ: TWBR = 3, 364 kHz at 8 MHz), and
 * the bus recovery (NineDofI2CRecover, shared by all clients).
 *
 * @author motecal
 */
#include "NineDofTwi.h"

generic configuration NineDofTwiMasterC()
{
  provides interface Resource;
  provides interface I2CPacket<TI2CBasicAddr>;
  provides interface NineDofI2CRecover;
}
implementation
{
  enum {
    CLIENT_ID = unique(UQ_NINEDOF_TWI),
  };

  components NineDofTwiMasterP as Master;

  Resource = Master.Resource[CLIENT_ID];
  I2CPacket = Master.I2CPacket[CLIENT_ID];
  NineDofI2CRecover = Master;
}
