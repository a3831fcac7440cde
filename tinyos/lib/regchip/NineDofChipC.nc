/*
 * NineDofChipC -- one of the board's chips on its own (chip =
 * NINEDOF_CHIP_ACCEL, _GYRO or _MAG, ninedof_board.h): the register-table
 * driver (NineDofChipP) on its own client of the arbitrated I2C bus
 * (HplNineDofI2CC), with TinyOS's Read<> (from a task) and ReadStream<>
 * (buffers filled on a binary-ms timer, NineDofReadStreamP) beside the
 * async ReadNow<>.  One read at a time: while one runs, the others are
 * refused (EBUSY) or, for ReadStream<>, the period is skipped.  Start it with SplitControl (identity check + register table)
 * before reading; stop puts the chip to sleep.  Each instance is a client
 * of its own: instances for the three chips, or for one chip in several
 * users, share the bus through its arbiter.  The public names are
 * Adxl345C, Itg3200C and Hmc5883lC (tinyos/chips/).
 *
 * @author motecal
 */
#include "NineDofChip.h"

generic configuration NineDofChipC(uint8_t chip)
{
  provides interface SplitControl;
  provides interface Read<ninedof_xyz_t>;
  provides interface ReadStream<ninedof_xyz_t>;
  provides interface ReadNow<ninedof_xyz_t>;
}
implementation
{
  components new NineDofChipP(chip) as Logic, new HplNineDofI2CC() as Bus;
  components new NineDofReadP() as Reader;
  components new NineDofReadStreamP() as Stream, new TimerMilliC() as StreamTimer;

  SplitControl = Logic;
  ReadNow = Logic;
  Read = Reader;
  ReadStream = Stream;
  Reader.ReadNow -> Logic;
  Stream.ReadNow -> Logic;
  Stream.Timer -> StreamTimer;
  Logic.Resource -> Bus;
  Logic.I2CPacket -> Bus;
}
