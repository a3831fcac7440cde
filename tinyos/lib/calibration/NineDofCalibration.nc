/*
 * NineDofCalibration -- the calibration set in force, as the sampling app
 * needs it: the receiver state of ninedof_calrx.h, for ninedof_batch_pack
 * (correction and flags of a sample message; the correction updates the
 * set's rounding residuals, nothing else) and
 * ninedof_status_pack (version and sensors of the status message).  Read
 * it from tasks: NineDofCalibrationC changes it only in tasks, so a batch
 * is never corrected with half of one set and half of another.
 *
 * @author motecal
 */
#include "ninedof_cal.h"

interface NineDofCalibration
{
  command ninedof_calrx_t *inForce();
  /* The board temperature (raw ITG-3200 TEMP_OUT) the correction uses from
   * now on, for a set with temperature terms (ninedof_calrx_set_temp).
   * From tasks only, like inForce. */
  command void setTemperature(int16_t raw);
}
