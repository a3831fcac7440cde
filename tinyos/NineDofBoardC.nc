/*
 * NineDofBoardC -- the 9DOF sensor stick (ADXL345 + ITG-3200 + HMC5883L on
 * the iris I2C bus): SplitControl to configure it, ReadNow<ninedof_raw_t>
 * for the nine axes of one instant.
 *
 * The three chip logic modules share one client of the I2C master
 * (NineDofBusP over HplNineDofI2CC), which the board holds for a whole
 * sample: the bus is arbitrated and powered up once per sample, not once
 * per chip.  (Adxl345C, Itg3200C and Hmc5883lC are the same chips with a
 * bus client each, for use on their own.)
 *
 * @author motecal
 */
#include "NineDofBoard.h"

configuration NineDofBoardC
{
  provides interface SplitControl;
  provides interface ReadNow<ninedof_raw_t>;
}
implementation
{
  components NineDofBoardP, NineDofBusP, new HplNineDofI2CC() as I2C;
  components new Adxl345LogicP(ADXL345_ADDR) as Accel;
  components new Itg3200LogicP(ITG3200_ADDR) as Gyro;
  components new Hmc5883lLogicP(HMC5883L_ADDR) as Mag;

  SplitControl = NineDofBoardP;
  ReadNow = NineDofBoardP;

  NineDofBusP.Bus -> I2C;
  NineDofBusP.BusPacket -> I2C;
  NineDofBoardP.Bus -> NineDofBusP.Hold;

  Accel.Resource -> NineDofBusP.Share[NINEDOF_CHIP_ACCEL];
  Accel.I2CPacket -> NineDofBusP.I2CPacket[NINEDOF_CHIP_ACCEL];
  Gyro.Resource -> NineDofBusP.Share[NINEDOF_CHIP_GYRO];
  Gyro.I2CPacket -> NineDofBusP.I2CPacket[NINEDOF_CHIP_GYRO];
  Mag.Resource -> NineDofBusP.Share[NINEDOF_CHIP_MAG];
  Mag.I2CPacket -> NineDofBusP.I2CPacket[NINEDOF_CHIP_MAG];

  NineDofBoardP.AccelControl -> Accel;
  NineDofBoardP.GyroControl -> Gyro;
  NineDofBoardP.MagControl -> Mag;
  NineDofBoardP.Accel -> Accel;
  NineDofBoardP.Gyro -> Gyro;
  NineDofBoardP.Mag -> Mag;
}
