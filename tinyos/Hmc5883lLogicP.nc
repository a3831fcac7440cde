/*
 * Hmc5883lLogicP -- HMC5883L magnetometer on I2C, single-measurement mode.
 *
 * SplitControl.start: checks identification 'H' '4' '3' and writes the
 * register table of ninedof_board.c (1 sample per output, 1090 LSB/gauss),
 * whose last write starts the first single measurement.
 * ReadNow.read (async): one transaction that writes MODE = single
 * measurement (which starts the next measurement, done within 6 ms, before
 * the next 8 ms period) and, after a repeated start, reads the six data
 * registers (X, Z, Y, big-endian) that still hold the previous measurement:
 * the register pointer has moved from MODE (0x02) to DATA X MSB (0x03), so
 * the trigger write is also the pointer write.
 * SplitControl.stop: idle mode.
 *
 * Every transfer holds the bus through Resource and every path that ends an
 * operation -- success, an error returned by I2CPacket, a transfer that
 * completes with an error, a wrong chip id -- releases it before reporting.
 *
 * @author motecal
 */
#include "NineDofBoard.h"

generic module Hmc5883lLogicP(uint8_t addr) @safe()
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
  norace uint8_t cmd[2];                   /* register pointer (+ value) */
  norace uint8_t raw[NINEDOF_CHIP_DATA];   /* bytes read */
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
        cmd[0] = HMC5883L_ID_A;
        return call I2CPacket.write(I2C_START, addr, 1, cmd);
      }
      if (step == 1)
        return call I2CPacket.read(I2C_START | I2C_STOP, addr, 3, raw);
      cmd[0] = NINEDOF_HMC5883L_CONFIG[step - 2].reg;
      cmd[1] = NINEDOF_HMC5883L_CONFIG[step - 2].value;
      return call I2CPacket.write(I2C_START | I2C_STOP, addr, 2, cmd);
    case S_READING:
      if (step == 0) {                        /* next single measurement */
        cmd[0] = NINEDOF_HMC5883L_TRIGGER[0];
        cmd[1] = NINEDOF_HMC5883L_TRIGGER[1];
        return call I2CPacket.write(I2C_START, addr, 2, cmd);
      }
      return call I2CPacket.read(I2C_START | I2C_STOP, addr, NINEDOF_CHIP_DATA, raw);
    case S_STOPPING:
      cmd[0] = NINEDOF_HMC5883L_SLEEP.reg;
      cmd[1] = NINEDOF_HMC5883L_SLEEP.value;
      return call I2CPacket.write(I2C_START | I2C_STOP, addr, 2, cmd);
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
    case S_STARTING: return step == 1 + NINEDOF_HMC5883L_CONFIG_LEN;
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
        ninedof_hmc5883l_xyz(raw, v.xyz);
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
    else if (step == 1 && starting() && !ninedof_hmc5883l_id_ok(raw))
      finish(FAIL);                           /* another chip answered */
    else
      next();
  }

  default event void SplitControl.startDone(error_t error) { }
  default event void SplitControl.stopDone(error_t error) { }
  default async event void ReadNow.readDone(error_t error, ninedof_xyz_t val) { }
}
