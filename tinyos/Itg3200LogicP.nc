/*
 * Itg3200LogicP -- ITG-3200 gyroscope on I2C.
 *
 * SplitControl.start: checks WHO_AM_I (0x68/0x69) and writes the register
 * table of ninedof_board.c (+-2000 deg/s, 42 Hz low-pass, 250 Hz output,
 * PLL clock).  The gyro PLL settles within 50 ms of this.
 * ReadNow.read (async): GYRO_XOUT_H..GYRO_ZOUT_L in one transaction
 * (pointer write, repeated start, six bytes, big-endian) -> counts.
 * SplitControl.stop: sleep.
 *
 * Every transfer holds the bus through Resource and every path that ends an
 * operation -- success, an error returned by I2CPacket, a transfer that
 * completes with an error, a wrong chip id -- releases it before reporting.
 *
 * @author motecal
 */
#include "NineDofBoard.h"

generic module Itg3200LogicP(uint8_t addr) @safe()
{
  provides interface SplitControl;
  provides interface ReadNow<ninedof_xyz_t>;
  uses interface Resource;
  uses interface I2CPacket<TI2CBasicAddr>;
}
implementation
{
  enum { S_OFF, S_STARTING, S_ON, S_READING, S_STOPPING };

  uint8_t state = S_OFF;
  norace uint8_t step;                     /* transfer within the operation */
  norace uint8_t buf[NINEDOF_CHIP_DATA];
  norace error_t result;

  task void startDone() {
    error_t err = result;
    atomic state = (err == SUCCESS) ? S_ON : S_OFF;
    signal SplitControl.startDone(err);
  }

  task void stopDone() {
    error_t err = result;
    atomic state = (err == SUCCESS) ? S_OFF : S_ON;
    signal SplitControl.stopDone(err);
  }

  /* Issue transfer `step` of the current operation. */
  error_t transfer() {
    uint8_t s;
    atomic s = state;
    switch (s) {
    case S_STARTING:
      if (step == 0) {
        buf[0] = ITG3200_WHO_AM_I;
        return call I2CPacket.write(I2C_START, addr, 1, buf);
      }
      if (step == 1)
        return call I2CPacket.read(I2C_START | I2C_STOP, addr, 1, buf);
      buf[0] = NINEDOF_ITG3200_CONFIG[step - 2].reg;
      buf[1] = NINEDOF_ITG3200_CONFIG[step - 2].value;
      return call I2CPacket.write(I2C_START | I2C_STOP, addr, 2, buf);
    case S_READING:
      if (step == 0) {
        buf[0] = ITG3200_GYRO_XOUT_H;
        return call I2CPacket.write(I2C_START, addr, 1, buf);
      }
      return call I2CPacket.read(I2C_START | I2C_STOP, addr, NINEDOF_CHIP_DATA, buf);
    case S_STOPPING:
      buf[0] = NINEDOF_ITG3200_SLEEP.reg;
      buf[1] = NINEDOF_ITG3200_SLEEP.value;
      return call I2CPacket.write(I2C_START | I2C_STOP, addr, 2, buf);
    default:
      return FAIL;
    }
  }

  bool starting() {
    atomic return state == S_STARTING;
  }

  bool lastStep() {
    uint8_t s;
    atomic s = state;
    switch (s) {
    case S_STARTING: return step == 1 + NINEDOF_ITG3200_CONFIG_LEN;
    case S_READING: return step == 1;
    default: return TRUE;
    }
  }

  /* Report the end of the operation (the bus is already released). */
  void report(error_t err) {
    uint8_t s;
    ninedof_xyz_t v;

    atomic s = state;
    if (s == S_READING) {
      if (err == SUCCESS)
        ninedof_itg3200_xyz(buf, v.xyz);
      else
        v.xyz[0] = v.xyz[1] = v.xyz[2] = 0;
      atomic state = S_ON;
      signal ReadNow.readDone(err, v);
    } else {
      result = err;
      if (s == S_STARTING)
        post startDone();
      else
        post stopDone();
    }
  }

  /* End the operation: release the bus, then report. */
  void finish(error_t err) {
    call Resource.release();
    report(err);
  }

  /* The bus is ours: the operation's first transfer. */
  error_t begin() {
    step = 0;
    return transfer();
  }

  void next() {
    error_t err;
    if (lastStep()) {
      finish(SUCCESS);
      return;
    }
    step++;
    err = transfer();
    if (err != SUCCESS)
      finish(err);
  }

  command error_t SplitControl.start() {
    error_t err;
    atomic {
      if (state == S_STARTING)
        return SUCCESS;                       /* startDone will come */
      if (state != S_OFF)
        return state == S_STOPPING ? EBUSY : EALREADY;
      state = S_STARTING;
    }
    err = call Resource.request();
    if (err != SUCCESS)
      atomic state = S_OFF;
    return err;
  }

  command error_t SplitControl.stop() {
    error_t err;
    atomic {
      if (state == S_STOPPING)
        return SUCCESS;                       /* stopDone will come */
      if (state != S_ON)
        return state == S_OFF ? EALREADY : EBUSY;
      state = S_STOPPING;
    }
    err = call Resource.request();
    if (err != SUCCESS)
      atomic state = S_ON;
    return err;
  }

  async command error_t ReadNow.read() {
    error_t err;
    atomic {
      if (state != S_ON)
        return state == S_OFF ? EOFF : EBUSY;
      state = S_READING;
    }
    if (call Resource.immediateRequest() == SUCCESS) {
      err = begin();
      if (err != SUCCESS)
        call Resource.release();
    } else {
      err = call Resource.request();          /* bus busy: wait for it */
    }
    if (err != SUCCESS)
      atomic state = S_ON;                    /* no readDone will follow */
    return err;
  }

  event void Resource.granted() {
    error_t err = begin();
    if (err != SUCCESS)
      finish(err);
  }

  async event void I2CPacket.writeDone(error_t error, uint16_t a, uint8_t len, uint8_t *data) {
    if (error != SUCCESS)
      finish(error);
    else
      next();
  }

  async event void I2CPacket.readDone(error_t error, uint16_t a, uint8_t len, uint8_t *data) {
    if (error != SUCCESS)
      finish(error);
    else if (step == 1 && starting() && !ninedof_itg3200_id_ok(buf[0]))
      finish(FAIL);                           /* another chip answered */
    else
      next();
  }

  default event void SplitControl.startDone(error_t error) { }
  default event void SplitControl.stopDone(error_t error) { }
  default async event void ReadNow.readDone(error_t error, ninedof_xyz_t val) { }
}
