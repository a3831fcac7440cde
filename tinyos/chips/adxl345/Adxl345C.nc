/*
 * Adxl345C -- the ADXL345 accelerometer at 0x53 (ninedof_board.h) as a TinyOS sensor:
 * SplitControl (TEP 115) checks its identity and writes its register table
 * (ninedof_board.c), or puts it to sleep; Read<ninedof_xyz_t> (TEP 114)
 * returns x, y, z in counts:
 * 256 LSB/g (full resolution, +-16 g, 200 Hz output).
 * ReadStream<ninedof_xyz_t> (TEP 114) fills buffers at a period (rounded
 * to binary ms); ReadNow<> is one read from any context (async).
 *
 * Each instance is its own client of the arbitrated I2C bus, like
 * tos/chips/sht21's generic configurations; the register-table driver is
 * shared by the three chips (lib/regchip/NineDofChipP).  On the 9DOF board,
 * NineDofBoardC reads all three at one instant under one bus grant.
 *
 * @author motecal
 */
#include "NineDofChip.h"

generic configuration Adxl345C()
{
  provides interface SplitControl;
  provides interface Read<ninedof_xyz_t>;
  provides interface ReadStream<ninedof_xyz_t>;
  provides interface ReadNow<ninedof_xyz_t>;
}
implementation
{
  components new NineDofChipC(NINEDOF_CHIP_ACCEL) as Chip;

  SplitControl = Chip;
  Read = Chip;
  ReadStream = Chip;
  ReadNow = Chip;
}
