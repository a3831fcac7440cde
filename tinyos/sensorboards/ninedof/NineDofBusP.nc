/*
 * NineDofBusP -- the 9DOF board's share of the I2C bus.
 *
 * One client of the iris I2C master (HplNineDofI2CC, fast mode, 364 kHz) for the whole
 * board.  The board (NineDofBoardP) holds it for a whole operation through
 * Hold: one arbitration, one bus power-up and one bit-rate setting for the
 * three reads of a sample, instead of one per chip.  While the board holds
 * the bus, the three chip drivers (NineDofChipP, the same module a chip
 * on its own uses: I2CPacket + Resource) take turns on it through
 * Share[chip] and I2CPacket[chip]: a chip gets its share at once if no other
 * chip has it, its transfers go to the bus, their completion events come
 * back to it (as Atm128I2CMasterImplP does for the bus's own clients), and
 * its release only hands the share back to the board.  A chip asking while
 * the board does not hold the bus is refused (EOFF).
 *
 * @author motecal
 */
#include "NineDofBoard.h"

module NineDofBusP @safe()
{
  provides interface Resource as Hold;
  provides interface Resource as Share[uint8_t chip];
  provides interface I2CPacket<TI2CBasicAddr>[uint8_t chip];
  uses interface Resource as Bus;
  uses interface I2CPacket<TI2CBasicAddr> as BusPacket;
}
implementation
{
  enum { NONE = 0xFF };

  bool held = FALSE;             /* the board has the bus */
  uint8_t owner = NONE;          /* the chip that has the share */
  uint8_t waiting = NONE;        /* the chip whose request() is being granted */

  /* ------------------------------------------------------------ the board */
  async command error_t Hold.immediateRequest() {
    error_t err = call Bus.immediateRequest();
    if (err == SUCCESS)
      atomic held = TRUE;
    return err;
  }

  async command error_t Hold.request() {
    return call Bus.request();
  }

  event void Bus.granted() {
    atomic held = TRUE;
    signal Hold.granted();
  }

  async command error_t Hold.release() {
    atomic {
      held = FALSE;
      owner = NONE;
      waiting = NONE;
    }
    return call Bus.release();
  }

  async command bool Hold.isOwner() {
    return call Bus.isOwner();
  }

  /* ------------------------------------------------------------ the chips */
  async command error_t Share.immediateRequest[uint8_t chip]() {
    atomic {
      if (!held)
        return EOFF;
      if (owner != NONE || waiting != NONE)
        return EBUSY;
      owner = chip;
    }
    return SUCCESS;
  }

  task void grant() {
    uint8_t chip;
    atomic {
      chip = waiting;
      waiting = NONE;
      if (chip == NONE || !held || owner != NONE)
        return;                          /* the board let go meanwhile */
      owner = chip;
    }
    signal Share.granted[chip]();
  }

  async command error_t Share.request[uint8_t chip]() {
    atomic {
      if (!held)
        return EOFF;
      if (owner != NONE || waiting != NONE)
        return EBUSY;
      waiting = chip;
    }
    post grant();
    return SUCCESS;
  }

  async command error_t Share.release[uint8_t chip]() {
    atomic {
      if (owner != chip)
        return FAIL;
      owner = NONE;
    }
    return SUCCESS;
  }

  async command bool Share.isOwner[uint8_t chip]() {
    atomic return owner == chip;
  }

  async command error_t I2CPacket.write[uint8_t chip](i2c_flags_t flags, uint16_t addr,
                                                      uint8_t len, uint8_t *data) {
    atomic {
      if (owner != chip)
        return FAIL;
    }
    return call BusPacket.write(flags, addr, len, data);
  }

  async command error_t I2CPacket.read[uint8_t chip](i2c_flags_t flags, uint16_t addr,
                                                     uint8_t len, uint8_t *data) {
    atomic {
      if (owner != chip)
        return FAIL;
    }
    return call BusPacket.read(flags, addr, len, data);
  }

  async event void BusPacket.writeDone(error_t error, uint16_t addr, uint8_t len,
                                       uint8_t *data) {
    uint8_t chip;
    atomic chip = owner;
    signal I2CPacket.writeDone[chip](error, addr, len, data);
  }

  async event void BusPacket.readDone(error_t error, uint16_t addr, uint8_t len,
                                      uint8_t *data) {
    uint8_t chip;
    atomic chip = owner;
    signal I2CPacket.readDone[chip](error, addr, len, data);
  }

  default event void Hold.granted() { }
  default event void Share.granted[uint8_t chip]() { }
  default async event void I2CPacket.writeDone[uint8_t chip](error_t error, uint16_t addr,
                                                             uint8_t len, uint8_t *data) { }
  default async event void I2CPacket.readDone[uint8_t chip](error_t error, uint16_t addr,
                                                            uint8_t len, uint8_t *data) { }
}
