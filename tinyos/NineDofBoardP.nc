/*
 * NineDofBoardP -- the 9DOF board as one sensor: SplitControl configures the
 * three chips one after the other; ReadNow reads the nine axes of one
 * instant, the three chips back to back on the 400 kHz bus (about 1 ms, see
 * the README), and returns them as one record (ax..mz, counts).
 *
 * @author motecal
 */
#include "NineDofBoard.h"

module NineDofBoardP @safe()
{
  provides interface SplitControl;
  provides interface ReadNow<ninedof_raw_t>;
  uses {
    interface SplitControl as AccelControl;
    interface SplitControl as GyroControl;
    interface SplitControl as MagControl;
    interface ReadNow<ninedof_xyz_t> as Accel;
    interface ReadNow<ninedof_xyz_t> as Gyro;
    interface ReadNow<ninedof_xyz_t> as Mag;
  }
}
implementation
{
  enum { C_IDLE, C_STARTING, C_STOPPING };

  uint8_t control = C_IDLE;      /* tasks only */
  error_t controlResult;
  bool reading = FALSE;
  norace ninedof_raw_t sample;   /* written only while `reading` */

  /* ---- start / stop: accel, gyro, mag in turn ---- */
  task void controlDone() {
    uint8_t c = control;
    control = C_IDLE;
    if (c == C_STARTING)
      signal SplitControl.startDone(controlResult);
    else
      signal SplitControl.stopDone(controlResult);
  }

  void controlFailed(error_t err) {
    controlResult = err;
    post controlDone();
  }

  /* Start or stop one chip; EALREADY counts as done. */
  error_t step(uint8_t chip) {
    error_t err;
    if (chip == 0)
      err = (control == C_STARTING) ? call AccelControl.start() : call AccelControl.stop();
    else if (chip == 1)
      err = (control == C_STARTING) ? call GyroControl.start() : call GyroControl.stop();
    else
      err = (control == C_STARTING) ? call MagControl.start() : call MagControl.stop();
    return err;
  }

  void run(uint8_t chip) {
    for (; chip < 3; chip++) {
      error_t err = step(chip);
      if (err == SUCCESS)
        return;                  /* its done event continues with chip + 1 */
      if (err != EALREADY) {
        controlFailed(err);
        return;
      }
    }
    controlResult = SUCCESS;
    post controlDone();
  }

  void chipDone(uint8_t chip, error_t err) {
    if (err != SUCCESS)
      controlFailed(err);
    else
      run(chip + 1);
  }

  command error_t SplitControl.start() {
    if (control != C_IDLE)
      return EBUSY;
    control = C_STARTING;
    run(0);
    return SUCCESS;
  }

  command error_t SplitControl.stop() {
    if (control != C_IDLE)
      return EBUSY;
    control = C_STOPPING;
    run(0);
    return SUCCESS;
  }

  event void AccelControl.startDone(error_t err) { chipDone(0, err); }
  event void GyroControl.startDone(error_t err) { chipDone(1, err); }
  event void MagControl.startDone(error_t err) { chipDone(2, err); }
  event void AccelControl.stopDone(error_t err) { chipDone(0, err); }
  event void GyroControl.stopDone(error_t err) { chipDone(1, err); }
  event void MagControl.stopDone(error_t err) { chipDone(2, err); }

  /* ---- one sample: accel, gyro, mag back to back ---- */
  void readFailed(error_t err) {
    ninedof_raw_t none;
    uint8_t i;
    for (i = 0; i < 9; i++)
      none.axis[i] = 0;
    atomic reading = FALSE;
    signal ReadNow.readDone(err, none);
  }

  async command error_t ReadNow.read() {
    error_t err;
    atomic {
      if (reading)
        return EBUSY;
      reading = TRUE;
    }
    err = call Accel.read();
    if (err != SUCCESS)
      atomic reading = FALSE;
    return err;
  }

  async event void Accel.readDone(error_t err, ninedof_xyz_t v) {
    if (err == SUCCESS) {
      sample.axis[0] = v.xyz[0]; sample.axis[1] = v.xyz[1]; sample.axis[2] = v.xyz[2];
      err = call Gyro.read();
    }
    if (err != SUCCESS)
      readFailed(err);
  }

  async event void Gyro.readDone(error_t err, ninedof_xyz_t v) {
    if (err == SUCCESS) {
      sample.axis[3] = v.xyz[0]; sample.axis[4] = v.xyz[1]; sample.axis[5] = v.xyz[2];
      err = call Mag.read();
    }
    if (err != SUCCESS)
      readFailed(err);
  }

  async event void Mag.readDone(error_t err, ninedof_xyz_t v) {
    ninedof_raw_t done;
    if (err != SUCCESS) {
      readFailed(err);
      return;
    }
    sample.axis[6] = v.xyz[0]; sample.axis[7] = v.xyz[1]; sample.axis[8] = v.xyz[2];
    done = sample;
    atomic reading = FALSE;
    signal ReadNow.readDone(SUCCESS, done);
  }

  default event void SplitControl.startDone(error_t err) { }
  default event void SplitControl.stopDone(error_t err) { }
  default async event void ReadNow.readDone(error_t err, ninedof_raw_t val) { }
}
