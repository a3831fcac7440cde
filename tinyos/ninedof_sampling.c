/*
 * ninedof_sampling.c -- see ninedof_sampling.h.
 */
#include <string.h>
#include "ninedof_sampling.h"

void ninedof_counters_init(ninedof_counters_t *c)
{
  memset(c, 0, sizeof(*c));
}

void ninedof_status_pack(const ninedof_counters_t *c, const ninedof_fault_counters_t *f,
                         const ninedof_calrx_t *rx, ninedof_mote_status_msg_t *msg)
{
  nxp_set_u16(&msg->seq, c->seq);
  nxp_set_u16(&msg->version, rx->active.version);
  nxp_set_u8(&msg->sensors, rx->active.sensors);
  nxp_set_u8(&msg->reserved, 0);
  nxp_set_u16(&msg->dropped, c->dropped);
  nxp_set_u16(&msg->send_fail, c->send_fail);
  nxp_set_u16(&msg->i2c_errors, c->i2c_errors);
  nxp_set_u16(&msg->late, c->late);
  nxp_set_u16(&msg->i2c_nacks, f->nacks);
  nxp_set_u16(&msg->bus_resets, f->bus_resets);
  nxp_set_u16(&msg->chip_reinits, f->chip_reinits);
}

void ninedof_temp_init(ninedof_temp_acc_t *t)
{
  memset(t, 0, sizeof(*t));
}

void ninedof_temp_add(ninedof_temp_acc_t *t, uint16_t seq, int16_t raw)
{
  if (t->count == 0xFF)
    return;                    /* the period's timer is late: keep the mean */
  t->sum += raw;
  t->count++;
  t->seq = seq;
}

uint8_t ninedof_temp_pack(ninedof_temp_acc_t *t, ninedof_mote_temp_msg_t *msg,
                          int16_t *mean)
{
  uint8_t n = t->count;

  nxp_set_u16(&msg->seq, t->seq);
  nxp_set_u8(&msg->count, n);
  nxp_set_u8(&msg->reserved, 0);
  nxp_set_i32(&msg->temp_sum, t->sum);
  if (n) {
    int32_t half = n / 2;
    *mean = (int16_t)(t->sum >= 0 ? (t->sum + half) / n : -((-t->sum + half) / n));
  }
  t->sum = 0;
  t->count = 0;
  return n != 0;
}

void ninedof_align_lost(ninedof_align_t *a)
{
  a->held = 0;
}

/* Nothing held, as after a lost read: seq and ag are read only for a held
 * read, and ninedof_align_push sets them before it holds one. */
void ninedof_align_init(ninedof_align_t *a)
{
  ninedof_align_lost(a);
}

uint8_t ninedof_align_push(ninedof_align_t *a, uint16_t seq, const int16_t rec[9],
                           int16_t out[9], uint16_t *out_seq)
{
  uint8_t done = a->held;

  if (done) {
    memcpy(out, a->ag, sizeof(a->ag));
    memcpy(out + 6, rec + 6, 3 * sizeof(rec[0]));
    *out_seq = a->seq;
  }
  memcpy(a->ag, rec, sizeof(a->ag));
  a->seq = seq;
  a->held = 1;
  return done;
}

void ninedof_batch_init(ninedof_batch_t *b)
{
  b->seq = 0;
  b->count = 0;
}

uint8_t ninedof_batch_fits(const ninedof_batch_t *b, uint16_t seq)
{
  if (b->count == 0)
    return 1;
  return b->count < NINEDOF_BATCH && (uint16_t)(b->seq + b->count) == seq;
}

uint8_t ninedof_batch_add(ninedof_batch_t *b, uint16_t seq, const int16_t rec[9])
{
  if (b->count == 0)
    b->seq = seq;
  memcpy(b->rec[b->count], rec, sizeof(b->rec[0]));
  b->count++;
  return b->count >= NINEDOF_BATCH;
}

uint8_t ninedof_batch_pack(ninedof_batch_t *b, ninedof_calrx_t *rx,
                           ninedof_samples_msg_t *msg)
{
  uint8_t k, n = b->count;
  const int16_t *src = &b->rec[0][0];
  uint8_t *dst = (uint8_t *)msg->rec;     /* n records of 9 big-endian int16 */

  if (n == 0)
    return 0;
  ninedof_calrx_correct_block(rx, &b->rec[0][0], &b->rec[0][0], n);
  nxp_set_u16(&msg->seq, b->seq);
  nxp_set_u8(&msg->flags, ninedof_calrx_flags(rx));
  nxp_set_u8(&msg->count, n);
  for (k = (uint8_t)(9 * n); k; k--) {    /* one pointer each way (NINEDOF_BATCH <= 28) */
    uint16_t v = (uint16_t)*src++;
    *dst++ = (uint8_t)(v >> 8);
    *dst++ = (uint8_t)v;
  }
  b->count = 0;
  return (uint8_t)(sizeof(msg->seq) + sizeof(msg->flags) + sizeof(msg->count) +
                   n * sizeof(ninedof_record_t));
}

uint16_t ninedof_slot_addr(uint8_t slot)
{
  return slot ? NINEDOF_EEPROM_SLOT1 : NINEDOF_EEPROM_SLOT0;
}

void ninedof_eewriter_init(ninedof_eewriter_t *w, uint8_t next_slot,
                           uint16_t next_generation)
{
  w->pos = w->len = 0;
  w->tries = 0;
  w->slot = next_slot & 1;
  w->generation = next_generation;
}

uint8_t ninedof_eewriter_busy(const ninedof_eewriter_t *w)
{
  return w->len != 0;
}

uint8_t ninedof_eewriter_poll(ninedof_eewriter_t *w, ninedof_calrx_t *rx)
{
  if (!rx->dirty)
    return 0;
  /* restart (same slot, same generation) if a write was in progress */
  w->len = ninedof_calrx_image(rx, w->generation, w->image);
  w->version = rx->active.version;
  w->crc = rx->active_crc;
  rx->dirty = 0;
  rx->store = NINEDOF_STORE_WRITING;
  w->pos = 0;
  w->tries = 0;
  return 1;
}

uint8_t ninedof_eewriter_next(ninedof_eewriter_t *w, uint16_t *addr, uint8_t *value)
{
  if (w->pos >= w->len)
    return 0;
  *addr = (uint16_t)(ninedof_slot_addr(w->slot) + w->pos);
  *value = w->image[w->pos];
  w->pos++;
  return 1;
}

uint8_t ninedof_eewriter_pending(const ninedof_eewriter_t *w)
{
  return w->len != 0 && w->pos >= w->len;
}

uint16_t ninedof_eewriter_addr(const ninedof_eewriter_t *w)
{
  return ninedof_slot_addr(w->slot);
}

uint8_t ninedof_eewriter_check(ninedof_eewriter_t *w, ninedof_calrx_t *rx,
                               const uint8_t *slot_bytes)
{
  if (!ninedof_eewriter_pending(w))
    return 0;
  if (memcmp(slot_bytes, w->image, w->len) == 0) {
    rx->stored_version = w->version;      /* a reset now brings this set back */
    rx->stored_crc = w->crc;
    rx->store = NINEDOF_STORE_IDLE;
    w->slot ^= 1;                         /* the next image goes to the other slot */
    w->generation++;
    w->len = w->pos = 0;
    return NINEDOF_EE_STORED;
  }
  if (++w->tries < NINEDOF_STORE_TRIES) {
    w->pos = 0;                           /* again; bytes already right are skipped */
    return NINEDOF_EE_AGAIN;
  }
  rx->store = NINEDOF_STORE_FAILED;
  w->len = w->pos = 0;
  return NINEDOF_EE_FAILED;
}
