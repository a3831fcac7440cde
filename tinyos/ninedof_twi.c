/*
 * ninedof_twi.c -- the lean TWI master's state machine (see ninedof_twi.h).
 *
 * ATmega1281 datasheet, "2-wire Serial Interface", tables of status codes
 * for master transmitter and master receiver mode: after each TWINT the
 * status says what just happened on the bus, and the command written to
 * TWCR (with TWDR) says what happens next.  SCL is held low from TWINT
 * until that command, so the time spent here is bus time.
 *
 * @author motecal
 */
#include "ninedof_twi.h"

/* the helpers go into the interrupt handler: an outlined one would be a call */
#ifdef __GNUC__
#define TWI_INLINE static inline __attribute__((always_inline))
#else
#define TWI_INLINE static inline
#endif

void ninedof_twi_init(ninedof_twi_t *t)
{
  t->buf = t->p = 0;
  t->len = t->left = t->sla = t->flags = t->out = 0;
  t->last = NINEDOF_TWCR_NEXT;
  t->state = NINEDOF_TWI_IDLE;
  t->result = NINEDOF_TWI_OK;
  t->open = 0;
}

/* The operation has transferred all its bytes: STOP, or hold SCL low
 * (TWINT left set, no interrupt) for the next operation.  The result is
 * still the OK ninedof_twi_begin set: only twi_fail changes it, and that
 * ends the operation. */
TWI_INLINE uint8_t twi_finish(ninedof_twi_t *t)
{
  t->state = NINEDOF_TWI_DONE;
  if (t->flags & NINEDOF_I2C_STOP) {
    t->open = 0;
    return NINEDOF_TWCR_STOP;
  }
  t->open = 1 + (t->sla & 1);       /* 1: write open, 2: read open */
  return NINEDOF_TWCR_IDLE;
}

TWI_INLINE uint8_t twi_fail(ninedof_twi_t *t, uint8_t result, uint8_t cmd)
{
  t->state = NINEDOF_TWI_DONE;
  t->result = result;
  t->open = 0;
  return cmd;
}

/* Command for receiving the next byte: ACK while more are to come after
 * it; the last one ACKed only with ACK_END. */
TWI_INLINE uint8_t twi_rx_cmd(const ninedof_twi_t *t)
{
  return t->left > 1 ? NINEDOF_TWCR_NEXT_ACK : t->last;
}

/* The next byte to send, or the end of the operation */
TWI_INLINE uint8_t twi_tx(ninedof_twi_t *t)
{
  uint8_t *p = t->p;
  if (t->left == 0)
    return twi_finish(t);
  t->left--;
  t->out = *p++;
  t->p = p;
  return NINEDOF_TWCR_NEXT;
}

NINEDOF_TWI_FN uint8_t ninedof_twi_begin(ninedof_twi_t *t, uint8_t read, uint8_t flags,
                                         uint8_t addr, uint8_t len, uint8_t *buf)
{
  read = read ? 1 : 0;
  t->buf = t->p = buf;
  t->len = t->left = len;
  t->last = (flags & NINEDOF_I2C_ACK_END) ? NINEDOF_TWCR_NEXT_ACK : NINEDOF_TWCR_NEXT;
  t->flags = flags;
  t->sla = (uint8_t)((addr & 0x7F) << 1) | read;
  t->out = t->sla;
  t->result = NINEDOF_TWI_OK;
  if (flags & NINEDOF_I2C_START) {
    t->state = NINEDOF_TWI_START;   /* a repeated START if a transfer is open */
    return NINEDOF_TWCR_START;
  }
  /* no START: continue the transfer the previous operation left open, in
   * the same direction (TWINT is set: SCL is held) */
  if (t->open != 1 + read) {        /* refused: a transfer left open stays so */
    t->state = NINEDOF_TWI_DONE;
    t->result = NINEDOF_TWI_BAD_ARGS;
    return NINEDOF_TWCR_IDLE;
  }
  if (len == 0)
    return twi_finish(t);           /* only a STOP (or nothing) */
  if (read) {
    t->state = NINEDOF_TWI_RX;
    return twi_rx_cmd(t);
  }
  t->state = NINEDOF_TWI_TX;
  return twi_tx(t);
}

/* Any status a step does not expect: arbitration lost (the bus is left to
 * the other master), else a bus error. */
TWI_INLINE uint8_t twi_unexpected(ninedof_twi_t *t, uint8_t status)
{
  if (status == NINEDOF_TW_ARB_LOST)
    return twi_fail(t, NINEDOF_TWI_ARB_LOST, NINEDOF_TWCR_RELEASE);
  return twi_fail(t, NINEDOF_TWI_BUS_ERROR, NINEDOF_TWCR_STOP);
}

/* The START (or repeated START) is on the bus: the address byte next. */
TWI_INLINE uint8_t twi_started(ninedof_twi_t *t, uint8_t status)
{
  if (status == NINEDOF_TW_START || status == NINEDOF_TW_REP_START) {
    /* out is still the address byte ninedof_twi_begin set */
    t->state = NINEDOF_TWI_ADDR;
    return NINEDOF_TWCR_NEXT;
  }
  return twi_unexpected(t, status);
}

NINEDOF_TWI_FN uint8_t ninedof_twi_started(ninedof_twi_t *t, uint8_t status)
{
  if (t->state != NINEDOF_TWI_START)
    return NINEDOF_TWCR_IDLE;       /* no START asked: nothing to do */
  return twi_started(t, status);
}

NINEDOF_TWI_FN uint8_t ninedof_twi_rx_more(const ninedof_twi_t *t, uint8_t status)
{
  if (t->state != NINEDOF_TWI_RX || status != NINEDOF_TW_MR_DATA_ACK || t->left < 2)
    return 0;
  return t->left > 2 ? NINEDOF_TWCR_NEXT_ACK : t->last;
}

NINEDOF_TWI_FN void ninedof_twi_rx_store(ninedof_twi_t *t, uint8_t data)
{
  uint8_t *p = t->p;
  *p++ = data;
  t->p = p;
  t->left--;
}

NINEDOF_TWI_FN uint8_t ninedof_twi_step(ninedof_twi_t *t, uint8_t status, uint8_t data)
{
  /* the states in order of frequency (20 of the 36 interrupts of a sample
   * are bytes read): the dispatch is part of the time SCL is held */
  uint8_t s = t->state;
  if (s == NINEDOF_TWI_RX) {
    if ((status & 0xF0) == 0x50) {  /* MR_DATA_ACK 0x50 or MR_DATA_NACK 0x58 */
      uint8_t *p = t->p;
      *p++ = data;
      t->p = p;
      if (--t->left)
        return twi_rx_cmd(t);
      return twi_finish(t);
    }
  } else if (s == NINEDOF_TWI_TX) {
    if (status == NINEDOF_TW_MT_DATA_ACK)
      return twi_tx(t);
    if (status == NINEDOF_TW_MT_DATA_NACK)
      return twi_fail(t, NINEDOF_TWI_DATA_NACK, NINEDOF_TWCR_STOP);
  } else if (s == NINEDOF_TWI_ADDR) {
    if (status == NINEDOF_TW_MT_SLA_ACK) {
      t->state = NINEDOF_TWI_TX;
      return twi_tx(t);
    }
    if (status == NINEDOF_TW_MR_SLA_ACK) {
      t->state = NINEDOF_TWI_RX;
      if (t->left == 0)             /* as the stock master: nothing read */
        return twi_finish(t);
      return twi_rx_cmd(t);
    }
    if (status == NINEDOF_TW_MT_SLA_NACK || status == NINEDOF_TW_MR_SLA_NACK)
      return twi_fail(t, NINEDOF_TWI_ADDR_NACK, NINEDOF_TWCR_STOP);
  } else if (s == NINEDOF_TWI_START) {
    return twi_started(t, status);
  } else {                          /* IDLE / DONE: an interrupt nobody asked for */
    return NINEDOF_TWCR_IDLE;       /* no interrupt, no outcome */
  }
  return twi_unexpected(t, status);
}

uint8_t ninedof_twi_abort(ninedof_twi_t *t)
{
  t->open = 0;
  if (t->state == NINEDOF_TWI_IDLE || t->state == NINEDOF_TWI_DONE)
    return 0;
  twi_fail(t, NINEDOF_TWI_ABORTED, 0);
  return 1;
}

uint8_t ninedof_twi_release(ninedof_twi_t *t)
{
  if (!t->open)
    return 0;
  t->open = 0;
  return NINEDOF_TWCR_STOP;
}
