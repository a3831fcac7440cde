/*
 * NineDofChipP -- one register-table driver for the board's three I2C
 * chips (ADXL345, ITG-3200, HMC5883L).  Everything that differs between
 * them is data: the chip descriptor NINEDOF_CHIP[chip] (ninedof_board.c:
 * address, identity register, register table, sleep write, read command,
 * data conversion, the witness register of the configuration check).
 *
 *   SplitControl.start   identity check, then the register table
 *   SplitControl.stop    the sleep write
 *   ReadNow.read         (async) the read command (register pointer, or
 *                        the HMC5883L's trigger), repeated start, the
 *                        descriptor's data_len bytes -> x, y, z counts (the
 *                        ITG-3200: 8 bytes from TEMP_OUT_H, the temperature
 *                        too)
 *   Registers.readRegister / configure   (async) one register read back,
 *                        the register table written again (the board's
 *                        fault handling, ninedof_fault.h)
 *
 * SplitControl follows TEP 115: start while off -> SUCCESS and one
 * startDone; while starting -> SUCCESS (the startDone to come); while on
 * -> EALREADY; while stopping -> EBUSY; stop the mirror image; a failed
 * start leaves it off, a failed stop on.  Reads and register operations
 * are refused while off (EOFF) or while another operation runs (EBUSY).
 *
 * Each operation holds the bus through Resource; every path that ends it
 * (success, an error returned by I2CPacket, a transfer that completes with
 * an error, a wrong identity) releases the bus before it reports.
 *
 * @author motecal
 */
#include "NineDofChip.h"

generic module NineDofChipP(uint8_t chip) @safe()
{
  provides interface SplitControl;
  provides interface ReadNow<ninedof_xyz_t>;
  provides interface NineDofRegisters as Registers;
  uses interface Resource;
  uses interface I2CPacket<TI2CBasicAddr>;
}
implementation
{
  enum { S_OFF, S_STARTING, S_ON, S_READING, S_REGISTER, S_CONFIG, S_STOPPING };

  uint8_t state = S_OFF;
  norace uint8_t step;                     /* transfer within the operation */
  norace uint8_t reg;                      /* register of readRegister */
  norace uint8_t buf[NINEDOF_CHIP_DATA_MAX];
  norace error_t result;

  const ninedof_chip_t *desc() {
    return &NINEDOF_CHIP[chip];
  }

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

  inline uint8_t current() __attribute__((always_inline)) {
    atomic return state;
  }

  error_t writeReg(const ninedof_reg_write_t *w) {
    buf[0] = w->reg;
    buf[1] = w->value;
    return call I2CPacket.write(I2C_START | I2C_STOP, desc()->addr, 2, buf);
  }

  /* a pointer write without STOP: the next transfer is a repeated start */
  error_t pointTo(uint8_t r) {
    buf[0] = r;
    return call I2CPacket.write(I2C_START, desc()->addr, 1, buf);
  }

  /* A read's first transfer: its command (register pointer, or the
   * HMC5883L's trigger), without STOP; the data read follows from its
   * writeDone. */
  error_t readCommand() {
    const ninedof_chip_t *d = desc();
    step = 0;
    buf[0] = d->read_cmd[0];
    buf[1] = d->read_cmd[1];
    return call I2CPacket.write(I2C_START, d->addr, d->read_len, buf);
  }

  /* Its second: the data bytes after a repeated START, with STOP. */
  inline error_t readData() __attribute__((always_inline)) {
    const ninedof_chip_t *d = desc();
    step = 1;
    return call I2CPacket.read(I2C_START | I2C_STOP, d->addr, d->data_len, buf);
  }

  /* Issue transfer `step` of the current operation. */
  error_t transfer() {
    const ninedof_chip_t *d = desc();
    switch (current()) {
    case S_STARTING:
      if (step == 0)
        return pointTo(d->id_reg);
      if (step == 1)
        return call I2CPacket.read(I2C_START | I2C_STOP, d->addr, d->id_len, buf);
      return writeReg(&d->config[step - 2]);
    case S_CONFIG:
      return writeReg(&d->config[step]);
    case S_READING:
      return step == 0 ? readCommand() : readData();
    case S_REGISTER:
      if (step == 0)
        return pointTo(reg);
      return call I2CPacket.read(I2C_START | I2C_STOP, d->addr, 1, buf);
    case S_STOPPING:
      return writeReg(&d->sleep);
    default:
      return FAIL;
    }
  }

  bool lastStep() {
    switch (current()) {
    case S_STARTING: return step == 1 + desc()->config_len;
    case S_CONFIG: return step + 1 == desc()->config_len;
    case S_READING:
    case S_REGISTER: return step == 1;
    default: return TRUE;
    }
  }

  /* Report the end of the operation (the bus is already released). */
  void report(error_t err) {
    uint8_t s = current();

    switch (s) {
    case S_REGISTER:
      atomic state = S_ON;
      signal Registers.readRegisterDone(err, err == SUCCESS ? buf[0] : 0);
      break;
    case S_CONFIG:
      atomic state = S_ON;
      signal Registers.configureDone(err);
      break;
    default:
      result = err;
      if (s == S_STARTING)
        post startDone();
      else
        post stopDone();
    }
  }

  /* End of a read: release the bus, then report the counts. */
  void readEnd(error_t err) {
    ninedof_xyz_t v;
    call Resource.release();
    if (err == SUCCESS) {
      ninedof_chip_xyz(chip, buf, v.xyz);
      v.temp = ninedof_chip_temp(chip, buf);
    } else {
      v.xyz[0] = v.xyz[1] = v.xyz[2] = v.temp = 0;
    }
    atomic state = S_ON;
    signal ReadNow.readDone(err, v);
  }

  /* End the operation: release the bus, then report. */
  void finish(error_t err) {
    if (current() == S_READING) {
      readEnd(err);
      return;
    }
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
      if (state == S_OFF)
        return EALREADY;
      if (state != S_ON)
        return EBUSY;
      state = S_STOPPING;
    }
    err = call Resource.request();
    if (err != SUCCESS)
      atomic state = S_ON;
    return err;
  }

  /* An async operation from S_ON: at once if the bus is free, else when
   * it is granted. */
  error_t runNow(uint8_t op) {
    error_t err;
    atomic {
      if (state != S_ON)
        return state == S_OFF ? EOFF : EBUSY;
      state = op;
    }
    if (call Resource.immediateRequest() == SUCCESS) {
      err = begin();
      if (err != SUCCESS)
        call Resource.release();
    } else {
      err = call Resource.request();          /* bus busy: wait for it */
    }
    if (err != SUCCESS)
      atomic state = S_ON;                    /* no done event will follow */
    return err;
  }

  /* runNow(S_READING), with the first transfer issued directly */
  async command error_t ReadNow.read() {
    error_t err;
    atomic {
      if (state != S_ON)
        return state == S_OFF ? EOFF : EBUSY;
      state = S_READING;
    }
    if (call Resource.immediateRequest() == SUCCESS) {
      err = readCommand();
      if (err != SUCCESS)
        call Resource.release();
    } else {
      err = call Resource.request();          /* bus busy: wait for it */
    }
    if (err != SUCCESS)
      atomic state = S_ON;                    /* no done event will follow */
    return err;
  }

  async command error_t Registers.readRegister(uint8_t r) {
    reg = r;
    return runNow(S_REGISTER);
  }

  async command error_t Registers.configure() {
    return runNow(S_CONFIG);
  }

  event void Resource.granted() {
    error_t err = begin();
    if (err != SUCCESS)
      finish(err);
  }

  /* The transfers of a read (once a sample, on the board's held bus):
   * the command written, then at once, from its writeDone, the data read
   * after a repeated START, and from that readDone the end.  Between the
   * two the bus is held (SCL low), so this path is kept short. */
  async event void I2CPacket.writeDone(error_t error, uint16_t a, uint8_t len, uint8_t *data) {
    if (error == SUCCESS && current() == S_READING) {
      error = readData();
      if (error == SUCCESS)
        return;
    }
    if (error != SUCCESS)
      finish(error);
    else
      next();
  }

  async event void I2CPacket.readDone(error_t error, uint16_t a, uint8_t len, uint8_t *data) {
    uint8_t s = current();
    if (s == S_READING)
      readEnd(error);                         /* a read ends with its data */
    else if (error != SUCCESS)
      finish(error);
    else if (step == 1 && s == S_STARTING && !ninedof_chip_id_ok(chip, buf))
      finish(FAIL);                           /* another chip answered */
    else
      next();
  }

  default event void SplitControl.startDone(error_t error) { }
  default event void SplitControl.stopDone(error_t error) { }
  default async event void ReadNow.readDone(error_t error, ninedof_xyz_t val) { }
  default async event void Registers.readRegisterDone(error_t error, uint8_t value) { }
  default async event void Registers.configureDone(error_t error) { }
}
