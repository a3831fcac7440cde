/*
 * HplNineDofI2CC -- binds a 9DOF chip (or the whole board, NineDofBoardC)
 * to the iris I2C master: a client of Atm128I2CMasterC (arbitrated, powered
 * on demand) whose Resource runs the bus in fast mode, 364 kHz (NineDofI2CSpeedP).  The only platform-specific part of
 * the board drivers, in the manner of tos/platforms/ucmini/chips/sht21.
 *
 * @author motecal
 */
generic configuration HplNineDofI2CC()
{
  provides interface Resource;
  provides interface I2CPacket<TI2CBasicAddr>;
}
implementation
{
  components new Atm128I2CMasterC() as I2C, new NineDofI2CSpeedP() as Speed;

  Resource = Speed;
  Speed.SubResource -> I2C;
  I2CPacket = I2C;
}
