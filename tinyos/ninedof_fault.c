/*
 * ninedof_fault.c -- see ninedof_fault.h.
 */
#include <string.h>
#include "ninedof_fault.h"
#include "ninedof_board.h"

#define ALL_CHIPS ((uint8_t)((1u << NINEDOF_CHIPS) - 1u))

void ninedof_fault_init(ninedof_fault_t *f)
{
  memset(f, 0, sizeof(*f));
  f->check_wait = NINEDOF_CHECK_TICKS;
}

void ninedof_fault_begin(ninedof_fault_t *f, uint16_t now_ms)
{
  f->busy = 1;
  f->since = now_ms;
  f->aborted = 0;
}

uint8_t ninedof_fault_end(ninedof_fault_t *f, uint8_t outcome)
{
  if (f->aborted)
    outcome = NINEDOF_OP_ABORTED;
  f->busy = 0;
  f->aborted = 0;
  if (outcome == NINEDOF_OP_NACK)
    f->n.nacks++;
  if (outcome != NINEDOF_OP_OK)
    f->check_mask = ALL_CHIPS;      /* a chip may have lost power meanwhile */
  return outcome;
}

uint8_t ninedof_fault_tick(ninedof_fault_t *f, uint16_t now_ms)
{
  if (--f->check_wait == 0) {
    f->check_wait = NINEDOF_CHECK_TICKS;
    f->check_mask |= (uint8_t)(1u << f->check_next);
    f->check_next = (uint8_t)((f->check_next + 1) % NINEDOF_CHIPS);
  }
  if (!f->busy && !f->down)
    return NINEDOF_FAULT_NONE;
  if ((uint16_t)(now_ms - f->since) < (f->down ? NINEDOF_BUSDOWN_RETRY_MS : NINEDOF_I2C_TIMEOUT_MS))
    return NINEDOF_FAULT_NONE;
  f->since = now_ms;                /* the bound starts again */
  f->n.bus_resets++;
  if (!f->busy)
    return NINEDOF_FAULT_CLEAR;     /* down and idle: try the lines again */
  f->aborted = 1;
  return NINEDOF_FAULT_ABORT;
}

uint8_t ninedof_fault_cleared(ninedof_fault_t *f, uint8_t result)
{
  if (result & (NINEDOF_BC_SDA_STUCK | NINEDOF_BC_SCL_STUCK)) {
    f->down = 1;
    return 0;
  }
  if (f->down) {
    f->down = 0;
    f->check_mask = ALL_CHIPS;      /* a short may have cut the chips' supply */
  }
  return 1;
}

uint8_t ninedof_fault_bus_down(const ninedof_fault_t *f)
{
  return f->down;
}

uint8_t ninedof_fault_check_pick(ninedof_fault_t *f)
{
  uint8_t chip;
  if (!f->check_mask)               /* the common case, at the end of every sample */
    return NINEDOF_CHECK_NONE;
  for (chip = 0; chip < NINEDOF_CHIPS; chip++) {
    if (f->check_mask & (1u << chip)) {
      f->check_mask &= (uint8_t)~(1u << chip);
      return chip;
    }
  }
  return NINEDOF_CHECK_NONE;
}

uint8_t ninedof_fault_check_done(ninedof_fault_t *f, uint8_t chip, uint8_t outcome,
                                 uint8_t value)
{
  const ninedof_chip_t *c = &NINEDOF_CHIP[chip];
  if (outcome == NINEDOF_OP_NACK)
    f->n.nacks++;
  if (outcome != NINEDOF_OP_OK) {
    f->check_mask |= (uint8_t)(1u << chip);
    return 0;
  }
  return value != c->config[c->witness].value;
}

void ninedof_fault_reinit_done(ninedof_fault_t *f, uint8_t chip, uint8_t outcome)
{
  if (outcome == NINEDOF_OP_NACK)
    f->n.nacks++;
  if (outcome == NINEDOF_OP_OK)
    f->n.chip_reinits++;
  else
    f->check_mask |= (uint8_t)(1u << chip);
}

/* ---------------------------------------------------------------------- */
enum {
  BC_WAIT,          /* SCL released: wait for it to be high, then look at SDA */
  BC_LOW,           /* SCL driven low for a half period (one pulse) */
  BC_STOP_SDA,      /* SCL low, SDA released -> pull SDA low */
  BC_STOP_SCL,      /* both low -> release SCL */
  BC_STOP_WAIT,     /* SCL released, SDA low: wait for SCL high, then release SDA */
  BC_END,           /* both released: report */
};

void ninedof_busclear_init(ninedof_busclear_t *b)
{
  b->phase = BC_WAIT;
  b->pulses = b->wait = b->steps = 0;
}

static uint8_t bc_done(uint8_t scl, uint8_t sda)
{
  return NINEDOF_BC_DONE | (scl ? 0 : NINEDOF_BC_SCL_STUCK) | (sda ? 0 : NINEDOF_BC_SDA_STUCK);
}

uint8_t ninedof_busclear_step(ninedof_busclear_t *b, uint8_t scl, uint8_t sda)
{
  if (++b->steps > NINEDOF_BUSCLEAR_MAX_STEPS)
    return bc_done(scl, sda);       /* cannot happen; the bound is the bound */
  switch (b->phase) {
  case BC_WAIT:
    if (!scl) {                     /* a slave stretches the clock */
      if (++b->wait > NINEDOF_BUSCLEAR_STRETCH)
        return bc_done(scl, sda);
      return NINEDOF_BC_SCL | NINEDOF_BC_SDA;
    }
    b->wait = 0;
    b->pulses++;
    if (sda || b->pulses > NINEDOF_BUSCLEAR_PULSES) {
      b->phase = BC_STOP_SDA;       /* SDA free (or no more pulses): the STOP */
      return NINEDOF_BC_SDA;        /* SCL low first */
    }
    b->phase = BC_LOW;
    return NINEDOF_BC_SDA;          /* SCL low: the slave shifts its next bit */
  case BC_LOW:
    b->phase = BC_WAIT;
    return NINEDOF_BC_SCL | NINEDOF_BC_SDA;
  case BC_STOP_SDA:
    b->phase = BC_STOP_SCL;
    return 0;                       /* SDA low while SCL is low */
  case BC_STOP_SCL:
    b->phase = BC_STOP_WAIT;
    return NINEDOF_BC_SCL;
  case BC_STOP_WAIT:
    if (!scl && ++b->wait <= NINEDOF_BUSCLEAR_STRETCH)
      return NINEDOF_BC_SCL;
    b->phase = BC_END;
    return NINEDOF_BC_SCL | NINEDOF_BC_SDA;   /* SDA rises while SCL is high: STOP */
  case BC_END:
    /* a slave that was sending a 1 bit shifted its next bit out at the
     * STOP's falling edge and holds SDA: go on clocking it out */
    if (scl && !sda && b->pulses <= NINEDOF_BUSCLEAR_PULSES) {
      b->phase = BC_WAIT;
      return ninedof_busclear_step(b, scl, sda);
    }
    return bc_done(scl, sda);
  default:
    return bc_done(scl, sda);
  }
}
