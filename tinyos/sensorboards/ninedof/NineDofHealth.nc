/*
 * NineDofHealth -- the 9DOF board's fault handling (ninedof_fault.h):
 * the watchdog's clock and the fault counters.
 *
 * @author motecal
 */
#include "ninedof_fault.h"

interface NineDofHealth
{
  /* Call once per sampling period (any context; the mote calls it from its
   * 125 Hz alarm, and once a second while the board is being started).  An
   * operation that has run NINEDOF_I2C_TIMEOUT_MS (16 binary ms of the
   * crystal) at a tick is aborted: the bus is cleared, the TWI
   * re-initialised, and the operation ends with an error (readDone /
   * startDone / stopDone).  Ticks that come in a burst abort nothing early. */
  async command void tick();

  /* NACKs, bus resets (watchdog aborts), chip re-initialisations so far */
  async command ninedof_fault_counters_t counters();
}
