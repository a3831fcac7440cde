/*
 * Adxl345C -- public component of one ADXL345 accelerometer (0x53 with ALT ADDRESS low, 0x1D high):
 * SplitControl configures it (or puts it to sleep), ReadNow<ninedof_xyz_t>
 * reads its three axes in counts from any context (async).  Each instance
 * is its own client of the arbitrated I2C bus (HplNineDofI2CC, fast mode, 364 kHz), for
 * a chip on its own; on the 9DOF board NineDofBoardC wires the three logic
 * modules to one shared client instead (NineDofBusP).
 *
 * @author motecal
 */
#include "NineDofBoard.h"

generic configuration Adxl345C(uint8_t addr)
{
  provides interface SplitControl;
  provides interface ReadNow<ninedof_xyz_t>;
}
implementation
{
  components new Adxl345LogicP(addr) as Logic, new HplNineDofI2CC() as Bus;

  SplitControl = Logic;
  ReadNow = Logic;
  Logic.Resource -> Bus;
  Logic.I2CPacket -> Bus;
}
