/*
 * Itg3200C -- public component of one ITG-3200 gyroscope (0x68 with AD0 low, 0x69 high):
 * SplitControl configures it (or puts it to sleep), ReadNow<ninedof_xyz_t>
 * reads its three axes in counts from any context (async).  Each instance
 * is its own client of the arbitrated I2C bus (HplNineDofI2CC, fast mode, 364 kHz), for
 * a chip on its own; on the 9DOF board NineDofBoardC wires the three logic
 * modules to one shared client instead (NineDofBusP).
 *
 * @author motecal
 */
#include "NineDofBoard.h"

generic configuration Itg3200C(uint8_t addr)
{
  provides interface SplitControl;
  provides interface ReadNow<ninedof_xyz_t>;
}
implementation
{
  components new Itg3200LogicP(addr) as Logic, new HplNineDofI2CC() as Bus;

  SplitControl = Logic;
  ReadNow = Logic;
  Logic.Resource -> Bus;
  Logic.I2CPacket -> Bus;
}
