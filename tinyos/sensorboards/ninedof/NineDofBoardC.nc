/*
 * NineDofBoardC -- the 9DOF sensor stick (ADXL345 + ITG-3200 + HMC5883L on
 * the iris I2C bus): SplitControl to configure it, ReadNow<ninedof_raw_t>
 * for the nine axes of one instant, NineDofHealth for the fault handling
 * (watchdog tick, counters; see NineDofBoardP and ninedof_fault.h).
 *
 * The three chips run the one register-table driver (NineDofChipP) and
 * share one client of the I2C master (NineDofBusP over HplNineDofI2CC),
 * which the board holds for a whole sample: the bus is arbitrated and
 * powered up once per sample, not once per chip.  (Adxl345C, Itg3200C and
 * Hmc5883lC are the same chips with a bus client each, providing Read<>,
 * for use on their own.)
 *
 * @author motecal
 */
#include "NineDofBoard.h"

configuration NineDofBoardC
{
  provides interface SplitControl;
  provides interface ReadNow<ninedof_raw_t>;
  provides interface NineDofHealth;
}
implementation
{
  components MainC, LocalTimeMilliC, NineDofBoardP, NineDofBusP, new HplNineDofI2CC() as I2C;
  components new NineDofChipP(NINEDOF_CHIP_ACCEL) as Accel;
  components new NineDofChipP(NINEDOF_CHIP_GYRO) as Gyro;
  components new NineDofChipP(NINEDOF_CHIP_MAG) as Mag;

  SplitControl = NineDofBoardP;
  ReadNow = NineDofBoardP;
  NineDofHealth = NineDofBoardP;
  MainC.SoftwareInit -> NineDofBoardP;

  NineDofBusP.Bus -> I2C;
  NineDofBusP.BusPacket -> I2C;
  NineDofBoardP.Bus -> NineDofBusP.Hold;
  NineDofBoardP.Recover -> I2C;
  NineDofBoardP.Clock -> LocalTimeMilliC;

  Accel.Resource -> NineDofBusP.Share[NINEDOF_CHIP_ACCEL];
  Accel.I2CPacket -> NineDofBusP.I2CPacket[NINEDOF_CHIP_ACCEL];
  Gyro.Resource -> NineDofBusP.Share[NINEDOF_CHIP_GYRO];
  Gyro.I2CPacket -> NineDofBusP.I2CPacket[NINEDOF_CHIP_GYRO];
  Mag.Resource -> NineDofBusP.Share[NINEDOF_CHIP_MAG];
  Mag.I2CPacket -> NineDofBusP.I2CPacket[NINEDOF_CHIP_MAG];

  NineDofBoardP.ChipControl[NINEDOF_CHIP_ACCEL] -> Accel;
  NineDofBoardP.ChipControl[NINEDOF_CHIP_GYRO] -> Gyro;
  NineDofBoardP.ChipControl[NINEDOF_CHIP_MAG] -> Mag;
  NineDofBoardP.Chip[NINEDOF_CHIP_ACCEL] -> Accel;
  NineDofBoardP.Chip[NINEDOF_CHIP_GYRO] -> Gyro;
  NineDofBoardP.Chip[NINEDOF_CHIP_MAG] -> Mag;
  NineDofBoardP.Registers[NINEDOF_CHIP_ACCEL] -> Accel;
  NineDofBoardP.Registers[NINEDOF_CHIP_GYRO] -> Gyro;
  NineDofBoardP.Registers[NINEDOF_CHIP_MAG] -> Mag;
}
