/*
 * NineDofBusClear -- the I2C bus clear (UM10204 3.1.16) on the pins, with
 * the TWI switched off by the caller.
 *
 * @author motecal
 */
interface NineDofBusClear
{
  /* Returns NINEDOF_BC_DONE | NINEDOF_BC_SDA_STUCK / _SCL_STUCK (ninedof_fault.h). */
  async command uint8_t clear();
}
