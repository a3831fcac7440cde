/*
 * NineDofI2CRecover -- recover the I2C bus from an operation that did not
 * end (HplNineDofI2CC provides it for either master): the TWI off, the bus
 * cleared by hand (9 SCL pulses at most, then a STOP: NineDofBusClearP),
 * the TWI on again, and the master made to end the operation with an
 * error.  Bounded: returns within a few milliseconds whatever the lines do.
 *
 * @author motecal
 */
interface NineDofI2CRecover
{
  /* Returns the bus clear's result (NINEDOF_BC_DONE | _SDA_STUCK / _SCL_STUCK). */
  async command uint8_t recover();
}
