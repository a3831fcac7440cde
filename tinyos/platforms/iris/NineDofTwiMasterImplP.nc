/*
 * NineDofTwiMasterImplP -- a lean interrupt-driven TWI master behind
 * Resource + I2CPacket<TI2CBasicAddr> (build option NINEDOF_LEAN_I2C=1).
 *
 * It replaces TinyOS's Atm128I2CMasterImplP / Atm128I2CMasterPacketP /
 * HplAtm128I2CBusP for this application and owns the TWI interrupt.  Per
 * interrupt it runs one step of ninedof_twi.c (status in, TWCR command
 * out) and writes the command at once, so SCL is held only for that step.
 * When an operation ends, readDone / writeDone are signalled from the
 * interrupt, as the stock master does.
 *
 * Recovery (NineDofI2CRecover, used by the board's watchdog): the TWI
 * off, the bus cleared (NineDofBusClearP), the TWI on again, and the
 * operation under way ended with ECANCEL.  Every wait for a STOP is
 * bounded (ninedof_twi_wait_stop): no unbounded loop with interrupts off.
 *
 * Differences from the stock master: an address NACK reports ENOACK (the
 * stock EOFF) and sends the STOP at once; a written byte that is not ACKed
 * ends the operation with FAIL and a STOP (the stock writes on); an
 * operation without START that does not continue an open transfer in the
 * same direction is refused with FAIL; the bus runs at NINEDOF_I2C_HZ.
 *
 * @author motecal
 */
#include "NineDofTwi.h"
#include "ninedof_board.h"

module NineDofTwiMasterImplP @safe()
{
  provides interface Resource[uint8_t client];
  provides interface I2CPacket<TI2CBasicAddr>[uint8_t client];
  provides interface AsyncStdControl;
  provides interface NineDofI2CRecover;
  uses interface Resource as SubResource[uint8_t client];
  uses interface NineDofBusClear;
}
implementation
{
  enum {
    NO_CLIENT = 0xff,
    TWBR_FAST = NINEDOF_TWBR(PLATFORM_MHZ * 1000000UL, NINEDOF_I2C_HZ),
  };

  /* both changed only in atomic sections and read in the handler or in
   * signalDone, which runs only from the handler and from an atomic block */
  norace ninedof_twi_t twi;
  norace uint8_t client = NO_CLIENT;
  norace bool powered;

  /* ---- power (AsyncPowerManagerP) ---- */
  void twiOn() {
    DDRD &= ~((1 << 0) | (1 << 1));       /* SCL PD0, SDA PD1: inputs, no pull-ups */
    PORTD &= ~((1 << 0) | (1 << 1));
    TWSR = 0;                             /* prescaler 1 */
    TWBR = TWBR_FAST;
    TWAR = 0;
    TWCR = NINEDOF_TWCR_IDLE;
  }

  async command error_t AsyncStdControl.start() {
    atomic {
      if (powered)
        return FAIL;
      twiOn();
      ninedof_twi_init(&twi);
      powered = TRUE;
    }
    return SUCCESS;
  }

  async command error_t AsyncStdControl.stop() {
    atomic {
      if (!powered || (twi.state != NINEDOF_TWI_IDLE))
        return FAIL;
      (void)ninedof_twi_wait_stop(&TWCR);   /* the last STOP, bounded: off anyway */
      TWCR = 0;
      PORTD &= ~((1 << 0) | (1 << 1));
      powered = FALSE;
    }
    return SUCCESS;
  }

  /* ---- arbitration, as Atm128I2CMasterImplP ---- */
  async command error_t Resource.request[uint8_t id]() {
    return call SubResource.request[id]();
  }

  async command error_t Resource.immediateRequest[uint8_t id]() {
    error_t err = call SubResource.immediateRequest[id]();
    if (err == SUCCESS)
      atomic client = id;
    return err;
  }

  event void SubResource.granted[uint8_t id]() {
    atomic client = id;
    signal Resource.granted[id]();
  }

  async command error_t Resource.release[uint8_t id]() {
    atomic {
      if (client == id) {
        uint8_t cmd = ninedof_twi_release(&twi);   /* STOP for a transfer left open */
        if (cmd)
          TWCR = cmd;
        client = NO_CLIENT;
      }
    }
    return call SubResource.release[id]();
  }

  async command bool Resource.isOwner[uint8_t id]() {
    return call SubResource.isOwner[id]();
  }

  /* ---- operations ---- */
  /* The operation in state DONE has ended: IDLE (a new one may begin from
   * the event), then its outcome to the client. */
  void signalDone() {
    error_t err;
    twi.state = NINEDOF_TWI_IDLE;
    err = twi.result == NINEDOF_TWI_OK ? SUCCESS
        : twi.result == NINEDOF_TWI_ADDR_NACK ? ENOACK
        : twi.result == NINEDOF_TWI_ABORTED ? ECANCEL : FAIL;
    if (twi.sla & 1)
      signal I2CPacket.readDone[client](err, twi.sla >> 1, twi.len, twi.buf);
    else
      signal I2CPacket.writeDone[client](err, twi.sla >> 1, twi.len, twi.buf);
  }

  /* The end of an operation, from the interrupt handler.  Its event may
   * begin the client's next operation (a chip's data read after its
   * register pointer, the next chip): that one's first byte is then on
   * the wire, and its TWINT is waited for here (bounded) and served at
   * once: returning would leave it to the scheduler's loop and a new
   * entry to the handler, with SCL held meanwhile. */
  void endFromHandler() {
    signalDone();
    if (twi.state < NINEDOF_TWI_ADDR || !ninedof_twi_wait_twint(&TWCR))
      return;                               /* nothing on the wire, or not yet */
    if (ninedof_twi_interrupt(&twi, &TWSR, &TWDR, &TWCR))
      signalDone();                         /* (an address NACK: at most once more) */
  }

  task void doneTask() {
    atomic {
      if (twi.state == NINEDOF_TWI_DONE)
        signalDone();
    }
  }

  /* An operation with START: the START goes on the bus first (after a
   * STOP still going out: one SCL period; bounded: if a slave holds SCL,
   * the TWI is reset and the START waits for a free bus, the board's
   * watchdog takes over if it never is), the operation is set up while it
   * does, and the address byte goes out from here as soon as the START is
   * done (bounded wait; else the interrupt sends it). */
  void beginWithStart(uint8_t read, i2c_flags_t flags, uint8_t addr,
                      uint8_t len, uint8_t *data) {
    uint8_t cmd;
    if (!ninedof_twi_wait_stop(&TWCR)) {
      TWCR = 0;
      twiOn();
    }
    TWCR = NINEDOF_TWCR_START;
    (void)ninedof_twi_begin(&twi, read, flags, addr, len, data);
    if (ninedof_twi_wait_twint(&TWCR)) {
      cmd = ninedof_twi_started(&twi, TWSR & 0xF8);
      TWDR = twi.out;
      TWCR = cmd;
      if (twi.state == NINEDOF_TWI_DONE)
        post doneTask();                    /* lost at the START: no signal from inside the call */
    }
  }

  error_t begin(uint8_t id, uint8_t read, i2c_flags_t flags, uint16_t addr,
                uint8_t len, uint8_t *data) {
    atomic {
      uint8_t cmd;
      if (client != id)
        return FAIL;
      if (!powered)
        return EOFF;
      if (twi.state != NINEDOF_TWI_IDLE)
        return EBUSY;
      if (flags & I2C_START) {
        beginWithStart(read, flags, (uint8_t)addr, len, data);
        return SUCCESS;
      }
      /* continuing the transfer left open (TWINT is set), or only a STOP */
      cmd = ninedof_twi_begin(&twi, read, flags, (uint8_t)addr, len, data);
      if (twi.state == NINEDOF_TWI_DONE) {
        if (twi.result != NINEDOF_TWI_OK) {   /* refused: nothing to do */
          twi.state = NINEDOF_TWI_IDLE;
          return FAIL;
        }
        TWCR = cmd;                         /* only a STOP (or nothing) */
        post doneTask();                    /* no signal from inside the call */
        return SUCCESS;
      }
      TWDR = twi.out;
      TWCR = cmd;
    }
    return SUCCESS;
  }

  async command error_t I2CPacket.read[uint8_t id](i2c_flags_t flags, uint16_t addr,
                                                   uint8_t len, uint8_t *data) {
    return begin(id, 1, flags, addr, len, data);
  }

  async command error_t I2CPacket.write[uint8_t id](i2c_flags_t flags, uint16_t addr,
                                                    uint8_t len, uint8_t *data) {
    return begin(id, 0, flags, addr, len, data);
  }

  /* ---- recovery (the board's watchdog): TWI off, bus clear, TWI on,
   * the operation under way ends with ECANCEL from a task ---- */
  async command uint8_t NineDofI2CRecover.recover() {
    uint8_t r;
    atomic TWCR = 0;                        /* TWI off: the pins are ours */
    r = call NineDofBusClear.clear();
    atomic {
      if (powered)
        twiOn();
      if (ninedof_twi_abort(&twi))
        post doneTask();
    }
    return r;
  }

  /* ---- the TWI interrupt: one step, the command at once ---- */
  AVR_ATOMIC_HANDLER(SIG_2WIRE_SERIAL) {
    if (ninedof_twi_interrupt(&twi, &TWSR, &TWDR, &TWCR))
      NINEDOF_TWI_CALL_SAVING(endFromHandler);   /* no call-clobber prologue */
  }

  default event void Resource.granted[uint8_t id]() { }
  default async event void I2CPacket.readDone[uint8_t id](error_t error, uint16_t addr,
                                                          uint8_t len, uint8_t *data) { }
  default async event void I2CPacket.writeDone[uint8_t id](error_t error, uint16_t addr,
                                                           uint8_t len, uint8_t *data) { }
  default async command error_t SubResource.request[uint8_t id]() { return FAIL; }
  default async command error_t SubResource.immediateRequest[uint8_t id]() { return FAIL; }
  default async command error_t SubResource.release[uint8_t id]() { return FAIL; }
  default async command bool SubResource.isOwner[uint8_t id]() { return FALSE; }
}
