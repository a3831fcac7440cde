/*
 * NineDofTwiMasterP -- the lean TWI master shared by its clients: an FCFS
 * arbiter, power on the first grant and off when the bus is free again
 * (AsyncPowerManagerP), as in TinyOS's Atm128I2CMasterP; the bus clear for
 * its recovery.
 *
 * @author motecal
 */
#include "NineDofTwi.h"

configuration NineDofTwiMasterP
{
  provides interface Resource[uint8_t client];
  provides interface I2CPacket<TI2CBasicAddr>[uint8_t client];
  provides interface NineDofI2CRecover;
}
implementation
{
  components new FcfsArbiterC(UQ_NINEDOF_TWI) as Arbiter;
  components new AsyncPowerManagerP() as Power;
  components NineDofTwiMasterImplP as Impl, NineDofBusClearP, BusyWaitMicroC;

  Resource = Impl.Resource;
  I2CPacket = Impl.I2CPacket;
  NineDofI2CRecover = Impl;
  Impl.SubResource -> Arbiter;
  Impl.NineDofBusClear -> NineDofBusClearP;
  NineDofBusClearP.BusyWait -> BusyWaitMicroC;
  Power.AsyncStdControl -> Impl;
  Power.ResourceDefaultOwner -> Arbiter;
  Power.ArbiterInfo -> Arbiter;
}
