/*
 * NineDofBoardC -- the 9DOF sensor stick (ADXL345 + ITG-3200 + HMC5883L on
 * the iris I2C bus): SplitControl to configure it, ReadNow<ninedof_raw_t>
 * for the nine axes of one instant.
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
  components NineDofBoardP;
  components new Adxl345C(ADXL345_ADDR) as Accel;
  components new Itg3200C(ITG3200_ADDR) as Gyro;
  components new Hmc5883lC(HMC5883L_ADDR) as Mag;

  SplitControl = NineDofBoardP;
  ReadNow = NineDofBoardP;
  NineDofBoardP.AccelControl -> Accel;
  NineDofBoardP.GyroControl -> Gyro;
  NineDofBoardP.MagControl -> Mag;
  NineDofBoardP.Accel -> Accel;
  NineDofBoardP.Gyro -> Gyro;
  NineDofBoardP.Mag -> Mag;
}
