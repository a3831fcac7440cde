/*
 * NineDofRegisters -- what the board's fault handling asks of a chip
 * driver (NineDofChipP) besides reading it: read back one register, and
 * write the chip's whole register table again.  Both async, on the bus the
 * caller holds, like ReadNow.
 *
 * @author motecal
 */
interface NineDofRegisters
{
  /* Read register `reg` (pointer write, repeated start, one byte). */
  async command error_t readRegister(uint8_t reg);
  async event void readRegisterDone(error_t error, uint8_t value);

  /* Write the start-up register table again (a chip that was reset). */
  async command error_t configure();
  async event void configureDone(error_t error);
}
