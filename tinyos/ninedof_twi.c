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
  t->buf = 0;
  t->len = t->idx = t->sla = t->flags = t->out = 0;
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

/* Command for receiving byte number idx (0-based): ACK unless it is the
 * last one and ACK_END is not set. */
TWI_INLINE uint8_t twi_rx_cmd(const ninedof_twi_t *t, uint8_t idx)
{
  return (uint8_t)(idx + 1) < t->len || (t->flags & NINEDOF_I2C_ACK_END)
      ? NINEDOF_TWCR_NEXT_ACK : NINEDOF_TWCR_NEXT;
}

NINEDOF_TWI_FN uint8_t ninedof_twi_begin(ninedof_twi_t *t, uint8_t read, uint8_t flags,
                                         uint8_t addr, uint8_t len, uint8_t *buf)
{
  read = read ? 1 : 0;
  t->buf = buf;
  t->len = len;
  t->idx = 0;
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
    return twi_rx_cmd(t, 0);
  }
  t->state = NINEDOF_TWI_TX;
  t->out = buf[0];
  t->idx = 1;
  return NINEDOF_TWCR_NEXT;
}

NINEDOF_TWI_FN uint8_t ninedof_twi_step(ninedof_twi_t *t, uint8_t status, uint8_t data)
{
  /* the states in order of frequency (18 of the 34 interrupts of a sample
   * are bytes read): the dispatch is part of the time SCL is held */
  uint8_t i, s = t->state;
  if (s == NINEDOF_TWI_RX) {
    if ((status & 0xF0) == 0x50) {  /* MR_DATA_ACK 0x50 or MR_DATA_NACK 0x58 */
      i = t->idx;
      t->buf[i++] = data;
      t->idx = i;
      if (i < t->len)
        return twi_rx_cmd(t, i);
      return twi_finish(t);
    }
  } else if (s == NINEDOF_TWI_TX) {
    if (status == NINEDOF_TW_MT_DATA_ACK) {
    send:
      i = t->idx;
      if (i < t->len) {
        t->out = t->buf[i];
        t->idx = i + 1;
        return NINEDOF_TWCR_NEXT;
      }
      return twi_finish(t);
    }
    if (status == NINEDOF_TW_MT_DATA_NACK)
      return twi_fail(t, NINEDOF_TWI_DATA_NACK, NINEDOF_TWCR_STOP);
  } else if (s == NINEDOF_TWI_ADDR) {
    if (status == NINEDOF_TW_MT_SLA_ACK) {
      t->state = NINEDOF_TWI_TX;
      goto send;
    }
    if (status == NINEDOF_TW_MR_SLA_ACK) {
      t->state = NINEDOF_TWI_RX;
      if (t->len == 0)              /* as the stock master: nothing read */
        return twi_finish(t);
      return twi_rx_cmd(t, 0);
    }
    if (status == NINEDOF_TW_MT_SLA_NACK || status == NINEDOF_TW_MR_SLA_NACK)
      return twi_fail(t, NINEDOF_TWI_ADDR_NACK, NINEDOF_TWCR_STOP);
  } else if (s == NINEDOF_TWI_START) {
    if (status == NINEDOF_TW_START || status == NINEDOF_TW_REP_START) {
      /* out is still the address byte ninedof_twi_begin set */
      t->state = NINEDOF_TWI_ADDR;
      return NINEDOF_TWCR_NEXT;
    }
  } else {                          /* IDLE / DONE: an interrupt nobody asked for */
    return NINEDOF_TWCR_IDLE;       /* no interrupt, no outcome */
  }
  if (status == NINEDOF_TW_ARB_LOST)
    return twi_fail(t, NINEDOF_TWI_ARB_LOST, NINEDOF_TWCR_RELEASE);
  return twi_fail(t, NINEDOF_TWI_BUS_ERROR, NINEDOF_TWCR_STOP);
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
