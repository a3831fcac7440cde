/*
 * HplNineDofI2CC -- binds a 9DOF chip (or the whole board, NineDofBoardC)
 * to the iris I2C master, in fast mode at 364 kHz (NINEDOF_I2C_HZ), with
 * the bus recovery the board's watchdog uses (NineDofI2CRecover).  The
 * only platform-specific part of the board drivers, in the manner of
 * tos/platforms/ucmini/chips/sht21.
 *
 * Default: a client of TinyOS's Atm128I2CMasterC (arbitrated, powered on
 * demand) whose Resource sets the bit rate on each grant (NineDofI2CSpeedP);
 * recovery by NineDofI2CRecoverP.
 * Built with NINEDOF_LEAN_I2C=1: a client of the lean TWI master
 * (NineDofTwiMasterC, state machine in ninedof_twi.c), same interfaces; it
 * recovers the bus itself.
 *
 * @author motecal
 */
generic configuration HplNineDofI2CC()
{
  provides interface Resource;
  provides interface I2CPacket<TI2CBasicAddr>;
  provides interface NineDofI2CRecover;
}
implementation
{
#if defined(NINEDOF_LEAN_I2C) && NINEDOF_LEAN_I2C
  components new NineDofTwiMasterC() as I2C;

  Resource = I2C;
  I2CPacket = I2C;
  NineDofI2CRecover = I2C;
#else
  components new Atm128I2CMasterC() as I2C, new NineDofI2CSpeedP() as Speed;
  components NineDofI2CRecoverP, NineDofBusClearP, BusyWaitMicroC;

  Resource = Speed;
  Speed.SubResource -> I2C;
  I2CPacket = I2C;
  NineDofI2CRecover = NineDofI2CRecoverP;
  NineDofI2CRecoverP.NineDofBusClear -> NineDofBusClearP;
  NineDofBusClearP.BusyWait -> BusyWaitMicroC;
#endif
}
