/*
 * NineDofBoardP -- the 9DOF board as one sensor: SplitControl configures the
 * three chips one after the other; ReadNow reads the nine axes of one
 * instant, the three chips back to back on the fast-mode (364 kHz) bus, and returns
 * them as one record (ax..mz, counts).
 *
 * Each operation holds the board's bus (Bus = NineDofBusP.Hold) from start
 * to end, so the chips get their turns on it without arbitration: one
 * grant per sample (see the README for the timing).  Every path that ends
 * an operation -- success, a chip reporting an error, a chip refusing to
 * start -- releases the bus before it reports.  A read while the board is
 * being configured, or configuring while a read runs, is refused (EBUSY).
 *
 * @author motecal
 */
#include "NineDofBoard.h"

module NineDofBoardP @safe()
{
  provides interface SplitControl;
  provides interface ReadNow<ninedof_raw_t>;
  uses {
    interface Resource as Bus;
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

  uint8_t control = C_IDLE;      /* configuration under way */
  error_t controlResult;         /* tasks only */
  bool reading = FALSE;          /* a sample under way */
  bool readWaiting = FALSE;      /* ... waiting for the bus */
  norace ninedof_raw_t sample;   /* written only while `reading` */

  /* ---- start / stop: accel, gyro, mag in turn, on the held bus ---- */
  task void controlDone() {
    uint8_t c;
    atomic {
      c = control;
      control = C_IDLE;
    }
    if (c == C_STARTING)
      signal SplitControl.startDone(controlResult);
    else
      signal SplitControl.stopDone(controlResult);
  }

  /* End of start/stop: release the bus, then report. */
  void controlEnd(error_t err) {
    call Bus.release();
    controlResult = err;
    post controlDone();
  }

  bool starting() {
    atomic return control == C_STARTING;
  }

  /* Start or stop one chip; EALREADY counts as done. */
  error_t step(uint8_t chip) {
    bool start = starting();
    if (chip == 0)
      return start ? call AccelControl.start() : call AccelControl.stop();
    if (chip == 1)
      return start ? call GyroControl.start() : call GyroControl.stop();
    return start ? call MagControl.start() : call MagControl.stop();
  }

  void run(uint8_t chip) {
    for (; chip < 3; chip++) {
      error_t err = step(chip);
      if (err == SUCCESS)
        return;                  /* its done event continues with chip + 1 */
      if (err != EALREADY) {
        controlEnd(err);
        return;
      }
    }
    controlEnd(SUCCESS);
  }

  void chipDone(uint8_t chip, error_t err) {
    if (err != SUCCESS)
      controlEnd(err);
    else
      run(chip + 1);
  }

  error_t configure(uint8_t what) {
    error_t err;
    atomic {
      if (control != C_IDLE || reading)
        return EBUSY;
      control = what;
    }
    err = call Bus.request();
    if (err != SUCCESS)
      atomic control = C_IDLE;
    return err;
  }

  command error_t SplitControl.start() {
    return configure(C_STARTING);
  }

  command error_t SplitControl.stop() {
    return configure(C_STOPPING);
  }

  event void AccelControl.startDone(error_t err) { chipDone(0, err); }
  event void GyroControl.startDone(error_t err) { chipDone(1, err); }
  event void MagControl.startDone(error_t err) { chipDone(2, err); }
  event void AccelControl.stopDone(error_t err) { chipDone(0, err); }
  event void GyroControl.stopDone(error_t err) { chipDone(1, err); }
  event void MagControl.stopDone(error_t err) { chipDone(2, err); }

  /* ---- one sample: accel, gyro, mag back to back, on the held bus ---- */
  /* End of a sample that failed: release the bus, then report. */
  void readFailed(error_t err) {
    ninedof_raw_t none;
    uint8_t i;
    call Bus.release();
    for (i = 0; i < 9; i++)
      none.axis[i] = 0;
    atomic reading = FALSE;
    signal ReadNow.readDone(err, none);
  }

  async command error_t ReadNow.read() {
    error_t err;
    atomic {
      if (reading || control != C_IDLE)
        return EBUSY;
      reading = TRUE;
    }
    if (call Bus.immediateRequest() == SUCCESS) {
      err = call Accel.read();
      if (err != SUCCESS)
        call Bus.release();
    } else {
      atomic readWaiting = TRUE;         /* bus busy: read when it comes */
      err = call Bus.request();
      if (err != SUCCESS)
        atomic readWaiting = FALSE;
    }
    if (err != SUCCESS)
      atomic reading = FALSE;            /* no readDone will follow */
    return err;
  }

  event void Bus.granted() {
    bool forRead;
    error_t err;
    atomic {
      forRead = readWaiting;
      readWaiting = FALSE;
    }
    if (!forRead) {
      run(0);                            /* start / stop */
      return;
    }
    err = call Accel.read();
    if (err != SUCCESS)
      readFailed(err);
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
    call Bus.release();
    atomic reading = FALSE;
    signal ReadNow.readDone(SUCCESS, done);
  }

  default event void SplitControl.startDone(error_t err) { }
  default event void SplitControl.stopDone(error_t err) { }
  default async event void ReadNow.readDone(error_t err, ninedof_raw_t val) { }
}
