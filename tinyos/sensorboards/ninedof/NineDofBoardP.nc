/*
 * NineDofBoardP -- the 9DOF board as one sensor: SplitControl configures the
 * three chips one after the other; ReadNow reads the nine axes of one
 * instant, the three chips back to back on the fast-mode (364 kHz) bus, and
 * returns them as one record (ax..mz, counts) with the board temperature
 * (the ITG-3200's TEMP_OUT, read in the same burst as its rates).
 *
 * Each operation holds the board's bus (Bus = NineDofBusP.Hold) from start
 * to end, so the chips get their turns on it without arbitration: one
 * grant per sample (see the README for the timing).  Every path that ends
 * an operation -- success, a chip reporting an error, a chip refusing to
 * start -- releases the bus before it reports.
 *
 * Faults (decisions in ninedof_fault.c, see ninedof_fault.h):
 *  - Health.tick, once per sampling period, runs the watchdog: an
 *    operation that has run NINEDOF_I2C_TIMEOUT_MS (16 binary ms of the
 *    crystal, LocalTime<TMilli>) at a tick is aborted through Recover (bus
 *    clear, TWI re-initialised, the master ends the transfer with an
 *    error) and ends with that error.
 *  - The bus clear's result decides what follows (ninedof_fault_cleared):
 *    a line still low puts the bus down.  While it is down no operation
 *    begins (read, start and stop return FAIL at once), and the tick
 *    clears the bus again once every NINEDOF_BUSDOWN_RETRY_MS (and aborts
 *    an operation the master could not end on that schedule, not every
 *    16 ms); the first clear that finds both lines high brings the bus up
 *    and every chip is checked with the next reads.
 *  - After a sample has been reported, one chip's witness register may be
 *    read back (on a schedule, and for every chip after a failure), as an
 *    operation of its own (a bus grant, the watchdog, no event); a chip
 *    found with its reset value gets its register table written again, in
 *    the same grant.  A read asked for meanwhile is refused (EBUSY), as
 *    during any operation.  So the check (about 0.2 ms once a second) is
 *    not part of a read's time from read() to readDone.
 *  - NACKs, watchdog aborts and re-initialisations are counted
 *    (Health.counters).
 *
 * SplitControl follows TEP 115 (start while starting: SUCCESS; while on:
 * EALREADY; while stopping: EBUSY; stop likewise).  A read while the board
 * is off is refused with EOFF, while it is busy with EBUSY.
 *
 * @author motecal
 */
#include "NineDofBoard.h"

module NineDofBoardP @safe()
{
  provides interface Init;
  provides interface SplitControl;
  provides interface ReadNow<ninedof_raw_t>;
  provides interface NineDofHealth as Health;
  uses {
    interface Resource as Bus;
    interface NineDofI2CRecover as Recover;
    interface LocalTime<TMilli> as Clock;
    interface SplitControl as ChipControl[uint8_t chip];
    interface ReadNow<ninedof_xyz_t> as Chip[uint8_t chip];
    interface NineDofRegisters as Registers[uint8_t chip];
  }
}
implementation
{
  enum { B_OFF, B_STARTING, B_ON, B_STOPPING };

  uint8_t power = B_OFF;
  error_t controlResult;         /* tasks only */
  bool reading = FALSE;          /* a sample under way */
  bool readWaiting = FALSE;      /* ... waiting for the bus */
  norace ninedof_raw_t sample;   /* written only while `reading` */
  ninedof_fault_t fault;

  command error_t Init.init() {
    ninedof_fault_init(&fault);
    return SUCCESS;
  }

  uint8_t outcome(error_t err) {
    if (err == SUCCESS)
      return NINEDOF_OP_OK;
    /* ENOACK: the lean master's NACK; EOFF: the stock master's */
    return (err == ENOACK || err == EOFF) ? NINEDOF_OP_NACK : NINEDOF_OP_FAIL;
  }

  /* binary ms of the crystal, for the watchdog */
  uint16_t now() {
    return (uint16_t)call Clock.get();
  }

  /* ---- the watchdog ---- */
  async command void Health.tick() {
    uint8_t act, result;
    uint16_t t = now();
    atomic act = ninedof_fault_tick(&fault, t);
    if (act == NINEDOF_FAULT_NONE)
      return;
    /* ABORT: the bus clear, and the operation's done event follows (if the
     * master can end it); CLEAR: the bus is down and idle, the lines are
     * tried again (this board is the bus's only client and begins nothing
     * while it is down) */
    result = call Recover.recover();
    atomic ninedof_fault_cleared(&fault, result);
  }

  async command ninedof_fault_counters_t Health.counters() {
    atomic return fault.n;
  }

  /* ---- start / stop: accel, gyro, mag in turn, on the held bus ---- */
  task void controlDone() {
    uint8_t p;
    error_t err = controlResult;
    atomic {
      p = power;
      if (p == B_STARTING)
        power = err == SUCCESS ? B_ON : B_OFF;
      else
        power = err == SUCCESS ? B_OFF : B_ON;
    }
    if (p == B_STARTING)
      signal SplitControl.startDone(err);
    else
      signal SplitControl.stopDone(err);
  }

  /* End of start/stop: release the bus, then report. */
  void controlEnd(error_t err) {
    call Bus.release();
    atomic ninedof_fault_end(&fault, outcome(err));
    controlResult = err;
    post controlDone();
  }

  bool starting() {
    atomic return power == B_STARTING;
  }

  /* Start or stop one chip; EALREADY counts as done. */
  error_t step(uint8_t chip) {
    return starting() ? call ChipControl.start[chip]() : call ChipControl.stop[chip]();
  }

  void run(uint8_t chip) {
    for (; chip < NINEDOF_CHIPS; chip++) {
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

  event void ChipControl.startDone[uint8_t chip](error_t err) { chipDone(chip, err); }
  event void ChipControl.stopDone[uint8_t chip](error_t err) { chipDone(chip, err); }

  error_t configure(uint8_t from, uint8_t to, uint8_t done) {
    error_t err;
    uint16_t t = now();
    atomic {
      if (power == to)
        return SUCCESS;          /* the done event under way */
      if (power == done)
        return EALREADY;
      if (power != from || reading)
        return EBUSY;
      if (ninedof_fault_bus_down(&fault))
        return FAIL;             /* a line is stuck low: nothing can begin */
      power = to;
      ninedof_fault_begin(&fault, t);
    }
    err = call Bus.request();
    if (err != SUCCESS) {
      atomic {
        power = from;
        ninedof_fault_end(&fault, NINEDOF_OP_FAIL);
      }
    }
    return err;
  }

  command error_t SplitControl.start() {
    return configure(B_OFF, B_STARTING, B_ON);
  }

  command error_t SplitControl.stop() {
    return configure(B_ON, B_STOPPING, B_OFF);
  }

  /* ---- one sample: accel, gyro, mag back to back, on the held bus ---- */
  void checkStart();

  /* End of a sample: release the bus, then report. */
  void readEnd(error_t err) {
    ninedof_raw_t done = sample;
    uint8_t i;
    if (err != SUCCESS) {
      for (i = 0; i < 9; i++)
        done.axis[i] = 0;
      done.temp = 0;
    }
    call Bus.release();
    atomic {
      reading = FALSE;
      ninedof_fault_end(&fault, outcome(err));
    }
    NINEDOF_SPAN_MARK(ninedof_span_readdone);   /* the signal (emulator's --span) */
    signal ReadNow.readDone(err, done);
    if (err == SUCCESS)
      checkStart();
  }

  async command error_t ReadNow.read() {
    error_t err;
    uint16_t t;
    NINEDOF_SPAN_MARK(ninedof_span_read);   /* the read's entry (emulator's --span) */
    t = now();
    atomic {
      if (power != B_ON)
        return power == B_OFF ? EOFF : EBUSY;
      if (reading)
        return EBUSY;
      if (ninedof_fault_bus_down(&fault))
        return FAIL;                     /* a line is stuck low: refused at once */
      reading = TRUE;
      ninedof_fault_begin(&fault, t);
    }
    if (call Bus.immediateRequest() == SUCCESS) {
      err = call Chip.read[0]();
      if (err != SUCCESS)
        call Bus.release();
    } else {
      atomic readWaiting = TRUE;         /* bus busy: read when it comes */
      err = call Bus.request();
      if (err != SUCCESS)
        atomic readWaiting = FALSE;
    }
    if (err != SUCCESS) {
      atomic {                           /* no readDone will follow */
        reading = FALSE;
        ninedof_fault_end(&fault, outcome(err));
      }
    }
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
    err = call Chip.read[0]();
    if (err != SUCCESS)
      readEnd(err);
  }

  /* ---- the configuration check: one witness read back, after a sample ---- */
  void checkEnd(bool held) {
    if (held)
      call Bus.release();
    atomic {
      reading = FALSE;
      ninedof_fault_end(&fault, NINEDOF_OP_OK);   /* counted by check_done / reinit_done */
    }
  }

  void checkStart() {
    uint8_t chip;
    uint16_t t;
    const ninedof_chip_t *d;
    atomic {
      if (reading || power != B_ON || ninedof_fault_bus_down(&fault))
        return;                          /* a read began from readDone, or the bus is down: next time */
      chip = ninedof_fault_check_pick(&fault);
      if (chip == NINEDOF_CHECK_NONE)
        return;                          /* the common case */
      reading = TRUE;                    /* a read now is refused (EBUSY) */
    }
    t = now();
    atomic ninedof_fault_begin(&fault, t);
    if (call Bus.immediateRequest() != SUCCESS) {
      atomic ninedof_fault_check_done(&fault, chip, NINEDOF_OP_FAIL, 0);   /* due again */
      checkEnd(FALSE);
      return;
    }
    d = &NINEDOF_CHIP[chip];
    if (call Registers.readRegister[chip](d->config[d->witness].reg) != SUCCESS) {
      atomic ninedof_fault_check_done(&fault, chip, NINEDOF_OP_FAIL, 0);
      checkEnd(TRUE);
    }
  }

  async event void Chip.readDone[uint8_t chip](error_t err, ninedof_xyz_t v) {
    if (err == SUCCESS) {
      sample.axis[3 * chip] = v.xyz[0];
      sample.axis[3 * chip + 1] = v.xyz[1];
      sample.axis[3 * chip + 2] = v.xyz[2];
      if (chip == NINEDOF_CHIP_GYRO)
        sample.temp = v.temp;
      if (chip + 1 == NINEDOF_CHIPS) {
        readEnd(SUCCESS);
        return;
      }
      err = call Chip.read[chip + 1]();
      if (err == SUCCESS)
        return;
    }
    readEnd(err);
  }

  async event void Registers.readRegisterDone[uint8_t chip](error_t err, uint8_t value) {
    bool reinit;
    atomic reinit = ninedof_fault_check_done(&fault, chip, outcome(err), value);
    if (reinit && call Registers.configure[chip]() != SUCCESS)
      atomic ninedof_fault_reinit_done(&fault, chip, NINEDOF_OP_FAIL);
    else if (reinit)
      return;                            /* configureDone ends the check */
    checkEnd(TRUE);
  }

  async event void Registers.configureDone[uint8_t chip](error_t err) {
    atomic ninedof_fault_reinit_done(&fault, chip, outcome(err));
    checkEnd(TRUE);
  }

  default command error_t ChipControl.start[uint8_t chip]() { return FAIL; }
  default command error_t ChipControl.stop[uint8_t chip]() { return FAIL; }
  default async command error_t Chip.read[uint8_t chip]() { return FAIL; }
  default async command error_t Registers.readRegister[uint8_t chip](uint8_t r) { return FAIL; }
  default async command error_t Registers.configure[uint8_t chip]() { return FAIL; }
  default async command uint8_t Recover.recover() { return NINEDOF_BC_DONE; }
  default event void SplitControl.startDone(error_t err) { }
  default event void SplitControl.stopDone(error_t err) { }
  default async event void ReadNow.readDone(error_t err, ninedof_raw_t val) { }
}
