/*
 * ninedof_calrx.c -- the upload receiver and the persistent image (API:
 * ninedof_calrx.h).  Plain C99 without floats, compiled as
 * ninedof_calset.c is (the nesC firmware, the host library, avr-gcc for
 * simavr).
 */
#include <string.h>
#include "ninedof_calrx.h"
#include "ninedof_correct.h"

/* ---------------------------------------------------------------------- */
/* Upload receiver                                                         */
/* ---------------------------------------------------------------------- */
#define CALSET_MAX NINEDOF_CALSET_MAX

static void set_active(ninedof_calrx_t *rx, const uint8_t *wire, uint8_t len,
                       const ninedof_cal_t *cal)
{
  uint8_t k;

  memcpy(rx->active_wire, wire, len);
  rx->active_len = len;
  rx->active = *cal;
  for (k = 0; k < NINEDOF_SENSORS; k++) {                 /* a new set: no residual */
    memset(rx->active.s[k].fb, 0, sizeof(rx->active.s[k].fb));
    memset(rx->active.eff[k].fb, 0, sizeof(rx->active.eff[k].fb));
  }
  rx->active_crc = ninedof_crc16(0, wire, len);
  if (rx->temp_known)
    ninedof_cal_set_temp(&rx->active, rx->temp);
}

static void active_identity(ninedof_calrx_t *rx, uint16_t version)
{
  ninedof_cal_t cal;
  uint8_t wire[sizeof(ninedof_calset_t)];
  uint8_t len;

  ninedof_cal_identity(&cal, rx->my_id, version);
  len = ninedof_cal_encode(&cal, wire);
  set_active(rx, wire, len, &cal);
}

static void staging_clear(ninedof_calrx_t *rx, uint16_t version)
{
  memset(rx->staged, 0, sizeof(rx->staged));
  memset(rx->have, 0, sizeof(rx->have));
  rx->staged_version = version;
}

static uint8_t staging_complete(const ninedof_calrx_t *rx, uint8_t len)
{
  uint8_t i;

  for (i = 0; i < len; i++)
    if (!(rx->have[i >> 3] & (1u << (i & 7))))
      return 0;
  return 1;
}

void ninedof_calrx_init(ninedof_calrx_t *rx, uint16_t my_id)
{
  memset(rx, 0, sizeof(*rx));
  rx->my_id = my_id;
  staging_clear(rx, 0);
  active_identity(rx, 0);
  rx->dirty = 0;
}

void ninedof_calrx_set_temp(ninedof_calrx_t *rx, int16_t raw)
{
  rx->temp = raw;
  rx->temp_known = 1;
  ninedof_cal_set_temp(&rx->active, raw);
}

static uint8_t handle_frag(ninedof_calrx_t *rx, const ninedof_cal_frag_msg_t *m,
                           uint8_t *reply, uint8_t *reply_type)
{
  ninedof_cal_frag_ack_msg_t *ack = (ninedof_cal_frag_ack_msg_t *)reply;
  uint16_t version = nxp_get_u16(&m->version);
  uint8_t offset = nxp_get_u8(&m->offset);
  uint8_t len = nxp_get_u8(&m->len);
  uint8_t status = NINEDOF_CAL_OK;

  if (nxp_get_u16(&m->mote) != rx->my_id) {
    status = NINEDOF_CAL_E_MOTE;
  } else if (version == 0) {
    status = NINEDOF_CAL_E_VERSION;
  } else if (len == 0 || len > NINEDOF_FRAG_DATA ||
             (uint16_t)offset + len > CALSET_MAX) {
    status = NINEDOF_CAL_E_FRAG;
  } else {
    uint8_t i;
    if (version != rx->staged_version)
      staging_clear(rx, version);          /* a new version restarts staging */
    memcpy(rx->staged + offset, m->data, len);
    for (i = offset; i < offset + len; i++)
      rx->have[i >> 3] |= (uint8_t)(1u << (i & 7));
  }
  nxp_set_u16(&ack->mote, rx->my_id);
  nxp_set_u16(&ack->version, version);
  nxp_set_u8(&ack->offset, offset);
  nxp_set_u8(&ack->status, status);
  *reply_type = AM_NINEDOF_CAL_FRAG_ACK_MSG;
  return (uint8_t)sizeof(*ack);
}

static uint8_t commit_apply(ninedof_calrx_t *rx, uint16_t version, uint8_t length,
                            uint16_t crc_expected, uint16_t *crc_out)
{
  ninedof_cal_t cal;
  uint8_t status;
  uint16_t crc;

  if (version == 0 || version != rx->staged_version)
    return NINEDOF_CAL_E_VERSION;
  if (length != sizeof(ninedof_calset_t) && length != sizeof(ninedof_calset_temp_t))
    return NINEDOF_CAL_E_FORMAT;
  if (!staging_complete(rx, length))
    return NINEDOF_CAL_E_INCOMPLETE;
  crc = ninedof_crc16(0, rx->staged, length);
  *crc_out = crc;
  if (crc != crc_expected)
    return NINEDOF_CAL_E_CRC;
  status = ninedof_cal_decode(rx->staged, length, &cal);    /* length = format's */
  if (status != NINEDOF_CAL_OK)
    return status;
  status = ninedof_cal_validate(&cal, rx->my_id);
  if (status != NINEDOF_CAL_OK)
    return status;
  if (cal.version != version)
    return NINEDOF_CAL_E_VERSION;
  /* A repeated commit (its ack was lost) of the set already in force is
   * acknowledged again without another EEPROM write. */
  if (crc == rx->active_crc && length == rx->active_len &&
      memcmp(rx->staged, rx->active_wire, length) == 0)
    return NINEDOF_CAL_OK;
  set_active(rx, rx->staged, length, &cal);
  rx->dirty = 1;
  rx->store = NINEDOF_STORE_WRITING;      /* until ninedof_eewriter_check says */
  return NINEDOF_CAL_OK;
}

static uint8_t handle_commit(ninedof_calrx_t *rx, const ninedof_cal_commit_msg_t *m,
                             uint8_t *reply, uint8_t *reply_type)
{
  ninedof_cal_commit_ack_msg_t *ack = (ninedof_cal_commit_ack_msg_t *)reply;
  uint16_t version = nxp_get_u16(&m->version);
  uint8_t action = nxp_get_u8(&m->action);
  uint16_t crc = 0;
  uint8_t status;

  if (nxp_get_u16(&m->mote) != rx->my_id) {
    status = NINEDOF_CAL_E_MOTE;
  } else if (action == NINEDOF_CAL_APPLY) {
    status = commit_apply(rx, version, nxp_get_u8(&m->length),
                          nxp_get_u16(&m->crc), &crc);
  } else if (action == NINEDOF_CAL_RESET) {
    if (version == 0) {
      status = NINEDOF_CAL_E_VERSION;
    } else {
      status = NINEDOF_CAL_OK;
      if (rx->active.sensors != 0 || rx->active.version != version) {
        active_identity(rx, version);
        rx->dirty = 1;
        rx->store = NINEDOF_STORE_WRITING;
      }
      crc = rx->active_crc;
    }
  } else {
    status = NINEDOF_CAL_E_ACTION;
  }
  nxp_set_u16(&ack->mote, rx->my_id);
  nxp_set_u16(&ack->version, rx->active.version);
  nxp_set_u16(&ack->crc, crc);
  nxp_set_u8(&ack->status, status);
  nxp_set_u8(&ack->sensors, rx->active.sensors);
  *reply_type = AM_NINEDOF_CAL_COMMIT_ACK_MSG;
  return (uint8_t)sizeof(*ack);
}

/* A query of `qlen` bytes: one of NINEDOF_CAL_QUERY_SIZE_V1 bytes (a host
 * built before the stored-set report) has no flags and gets the report of
 * that time, NINEDOF_CAL_REPORT_SIZE_V1 bytes. */
static uint8_t handle_query(ninedof_calrx_t *rx, const ninedof_cal_query_msg_t *m,
                            uint8_t qlen, uint8_t *reply, uint8_t *reply_type)
{
  ninedof_cal_report_msg_t *rep = (ninedof_cal_report_msg_t *)reply;
  uint8_t offset = nxp_get_u8(&m->offset);
  uint8_t stored = qlen >= sizeof(*m) && (nxp_get_u8(&m->flags) & NINEDOF_QUERY_STORED);
  uint8_t len = 0;

  if (nxp_get_u16(&m->mote) != rx->my_id)
    return 0;
  memset(rep, 0, sizeof(*rep));
  if (offset < rx->active_len) {
    len = (uint8_t)(rx->active_len - offset);
    if (len > NINEDOF_FRAG_DATA)
      len = NINEDOF_FRAG_DATA;
    memcpy(rep->data, rx->active_wire + offset, len);
  }
  nxp_set_u16(&rep->mote, rx->my_id);
  nxp_set_u16(&rep->version, rx->active.version);
  nxp_set_u16(&rep->crc, rx->active_crc);
  nxp_set_u8(&rep->offset, offset);
  nxp_set_u8(&rep->len, len);
  *reply_type = AM_NINEDOF_CAL_REPORT_MSG;
  if (!stored)
    return NINEDOF_CAL_REPORT_SIZE_V1;
  nxp_set_u16(&rep->stored_version, rx->stored_version);
  nxp_set_u16(&rep->stored_crc, rx->stored_crc);
  nxp_set_u8(&rep->store, rx->store);
  return (uint8_t)sizeof(*rep);
}

uint8_t ninedof_calrx_handle(ninedof_calrx_t *rx, uint8_t am_type,
                             const uint8_t *payload, uint8_t len,
                             uint8_t *reply, uint8_t *reply_type)
{
  switch (am_type) {
  case AM_NINEDOF_CAL_FRAG_MSG:
    if (len < sizeof(ninedof_cal_frag_msg_t))
      return 0;
    return handle_frag(rx, (const ninedof_cal_frag_msg_t *)payload, reply, reply_type);
  case AM_NINEDOF_CAL_COMMIT_MSG:
    if (len < sizeof(ninedof_cal_commit_msg_t))
      return 0;
    return handle_commit(rx, (const ninedof_cal_commit_msg_t *)payload, reply, reply_type);
  case AM_NINEDOF_CAL_QUERY_MSG:
    if (len < NINEDOF_CAL_QUERY_SIZE_V1)             /* the query of older hosts too */
      return 0;
    return handle_query(rx, (const ninedof_cal_query_msg_t *)payload, len, reply,
                        reply_type);
  default:
    return 0;
  }
}

uint8_t ninedof_calrx_flags(const ninedof_calrx_t *rx)
{
  uint8_t f = (uint8_t)((rx->active.version << NINEDOF_FLAG_VERSION_SHIFT) &
                        NINEDOF_FLAG_VERSION_MASK);
  if (rx->active.sensors)
    f |= NINEDOF_FLAG_CORRECTED;
  return f;
}

void ninedof_calrx_correct_block(ninedof_calrx_t *rx, const int16_t *raw,
                                 int16_t *out, uint16_t n)
{
  ninedof_correct_block(&rx->active, raw, out, n);
}

/* ---------------------------------------------------------------------- */
/* Persistent image                                                        */
/* ---------------------------------------------------------------------- */
static uint16_t image_crc(const uint8_t *image, uint8_t set_len)
{
  uint16_t crc = ninedof_crc16(0, image + 2, 2);           /* generation */
  return ninedof_crc16(crc, image + 6, set_len);           /* the set */
}

uint8_t ninedof_calrx_image(const ninedof_calrx_t *rx, uint16_t generation,
                            uint8_t image[NINEDOF_IMAGE_MAX])
{
  uint16_t crc;

  image[0] = 'N';
  image[1] = '9';
  image[2] = (uint8_t)(generation >> 8);
  image[3] = (uint8_t)generation;
  memcpy(image + 6, rx->active_wire, rx->active_len);
  crc = image_crc(image, rx->active_len);
  image[4] = (uint8_t)(crc >> 8);
  image[5] = (uint8_t)crc;
  return (uint8_t)(6 + rx->active_len);
}

/* Length of the set in a well-formed image of `avail` bytes, 0 if none */
static uint8_t image_set_len(const uint8_t *image, uint8_t avail)
{
  uint8_t len;

  if (avail < NINEDOF_IMAGE_SIZE || image[0] != 'N' || image[1] != '9')
    return 0;
  len = ninedof_calset_len(image[6 + 5]);                 /* the set's format byte */
  if (len == 0 || 6 + len > avail)
    return 0;
  if (image_crc(image, len) != (uint16_t)((image[4] << 8) | image[5]))
    return 0;
  return len;
}

uint8_t ninedof_image_check(const uint8_t *image, uint8_t avail, uint16_t my_id,
                            uint16_t *generation)
{
  ninedof_cal_t cal;
  uint8_t len = image_set_len(image, avail);

  if (len == 0)
    return 0;
  if (ninedof_cal_decode(image + 6, len, &cal) != NINEDOF_CAL_OK)
    return 0;
  if (ninedof_cal_validate(&cal, my_id) != NINEDOF_CAL_OK)
    return 0;
  if (generation)
    *generation = (uint16_t)((image[2] << 8) | image[3]);
  return 1;
}

uint8_t ninedof_calrx_restore(ninedof_calrx_t *rx,
                              const uint8_t slot0[NINEDOF_IMAGE_MAX],
                              const uint8_t slot1[NINEDOF_IMAGE_MAX],
                              const uint8_t *legacy1,
                              uint8_t *next_slot, uint16_t *next_generation)
{
  const uint8_t *img[3];
  uint16_t gen[3] = { 0, 0, 0 };
  uint8_t ok[3], i, used = 0xFF, len;
  ninedof_cal_t cal;

  img[0] = slot0;
  img[1] = slot1;
  img[2] = legacy1;
  ok[0] = ninedof_image_check(slot0, NINEDOF_IMAGE_MAX, rx->my_id, &gen[0]);
  ok[1] = ninedof_image_check(slot1, NINEDOF_IMAGE_MAX, rx->my_id, &gen[1]);
  /* the old layout's slot 1 held only plain sets */
  ok[2] = legacy1 && ninedof_image_check(legacy1, NINEDOF_IMAGE_SIZE, rx->my_id, &gen[2]);
  for (i = 0; i < 3; i++)
    if (ok[i] && (used == 0xFF || (int16_t)(uint16_t)(gen[i] - gen[used]) > 0))
      used = i;                                         /* newest, wrap-aware */
  if (used == 0xFF) {
    *next_slot = 0;
    *next_generation = 1;
    return 0xFF;
  }
  len = image_set_len(img[used], used == 2 ? NINEDOF_IMAGE_SIZE : NINEDOF_IMAGE_MAX);
  ninedof_cal_decode(img[used] + 6, len, &cal);
  set_active(rx, img[used] + 6, len, &cal);
  rx->dirty = 0;
  rx->stored_version = rx->active.version;          /* what a reset brings back */
  rx->stored_crc = rx->active_crc;
  /* slot 0 spans the old slot 1: after either old slot, write slot 1 */
  *next_slot = (uint8_t)(used == 1 ? 0 : 1);
  *next_generation = (uint16_t)(gen[used] + 1);
  return used;
}
