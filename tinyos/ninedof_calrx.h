/*
 * ninedof_calrx.h -- the calibration's upload receiver (the whole mote side
 * of the upload protocol) and the persistent image of the set in force.
 * Implemented in ninedof_calrx.c.
 */
#ifndef NINEDOF_CALRX_H
#define NINEDOF_CALRX_H

#include <stdint.h>
#include "NineDofMsg.h"
#include "ninedof_calset.h"

/* ------------------------------------------------------------------------
 * Upload receiver: the whole mote side of the upload protocol.
 * ---------------------------------------------------------------------- */
typedef struct {
  uint16_t my_id;
  /* staging */
  uint8_t staged[sizeof(ninedof_calset_temp_t)];    /* wire bytes being assembled */
  uint8_t have[(sizeof(ninedof_calset_temp_t) + 7) / 8]; /* bitmap of received bytes */
  uint16_t staged_version;                          /* 0 = nothing staged */
  /* in force */
  uint8_t active_wire[sizeof(ninedof_calset_temp_t)]; /* for read-back and CRC */
  uint8_t active_len;                               /* bytes of active_wire in use */
  ninedof_cal_t active;                             /* used by correction */
  uint16_t active_crc;
  uint8_t dirty;                                    /* in force but not yet persisted */
  int16_t temp;                                     /* board temperature (TEMP_OUT) */
  uint8_t temp_known;                               /* ... once one was set */
  /* the set the EEPROM holds (what a reset puts in force), as the EEPROM
   * writer last verified it (ninedof_eewriter_check) or boot restored it */
  uint16_t stored_version;                          /* 0: none */
  uint16_t stored_crc;
  uint8_t store;                                    /* NINEDOF_STORE_* */
} ninedof_calrx_t;

/* Start with the raw set, version 0. */
void ninedof_calrx_init(ninedof_calrx_t *rx, uint16_t my_id);

/* Handle one received message addressed to this mote (AM type and payload).
 * Writes the reply payload into `reply` (at least
 * sizeof(ninedof_cal_report_msg_t) bytes) and its AM type into *reply_type,
 * and returns the reply length (0: no reply).
 *   CAL_FRAG   -> CAL_FRAG_ACK   (stages bytes; a new version restarts staging;
 *                                 bytes past NINEDOF_CALSET_MAX: E_FRAG)
 *   CAL_COMMIT -> CAL_COMMIT_ACK (APPLY: length 102 or 164 as the set's
 *                                 format says, complete + CRC + validate, then in force;
 *                                 RESET: raw set with the given version)
 *   CAL_QUERY  -> CAL_REPORT     (bytes of the set in force; with
 *                                 NINEDOF_QUERY_STORED also the stored set and the
 *                                 writer's state, else NINEDOF_CAL_REPORT_SIZE_V1 bytes)
 * Messages of other types, or too short, get no reply.  A rejected set
 * leaves the set in force unchanged.  After an accepted commit rx->dirty = 1
 * and rx->store = NINEDOF_STORE_WRITING: the caller persists
 * ninedof_calrx_image() (ninedof_eewriter_poll clears dirty,
 * ninedof_eewriter_check records the stored set). */
uint8_t ninedof_calrx_handle(ninedof_calrx_t *rx, uint8_t am_type,
                             const uint8_t *payload, uint8_t len,
                             uint8_t *reply, uint8_t *reply_type);

/* Flags byte for sample messages: NINEDOF_FLAG_CORRECTED when any sensor is
 * corrected, version low 4 bits in bits 4-7. */
uint8_t ninedof_calrx_flags(const ninedof_calrx_t *rx);

/* Correct n records with the set in force (and its residuals). */
void ninedof_calrx_correct_block(ninedof_calrx_t *rx, const int16_t *raw,
                                 int16_t *out, uint16_t n);

/* The board temperature (raw TEMP_OUT) for the set in force, and for every
 * set put in force later. */
void ninedof_calrx_set_temp(ninedof_calrx_t *rx, int16_t raw);

/* ------------------------------------------------------------------------
 * Persistent image (internal EEPROM, two slots written alternately so a
 * reset during a write leaves the other slot valid).
 * Image: magic(2) 'N','9', generation(2), crc(2) over generation..set,
 * then the wire set (its format byte gives its length: 102 or 164 bytes).
 * Big-endian.  Slots of 256 bytes at 0x100 and 0x200.  Images built before
 * the temperature terms wrote the 108-byte image of a plain set into slots
 * at 0x100 and 0x180: the first is slot 0 here, the second
 * (NINEDOF_EEPROM_LEGACY1) is read at boot and never written, so a set an
 * old image saved stays in force after the update.
 * ---------------------------------------------------------------------- */
#define NINEDOF_IMAGE_SIZE (6 + sizeof(ninedof_calset_t))        /* plain set */
#define NINEDOF_IMAGE_MAX (6 + sizeof(ninedof_calset_temp_t))    /* largest */
#define NINEDOF_EEPROM_SLOT0 0x100
#define NINEDOF_EEPROM_SLOT1 0x200
#define NINEDOF_EEPROM_LEGACY1 0x180
#define NINEDOF_EEPROM_SLOT_SIZE 0x100

/* Build the image of the set in force with the given generation number;
 * returns its length (6 + the set's). */
uint8_t ninedof_calrx_image(const ninedof_calrx_t *rx, uint16_t generation,
                            uint8_t image[NINEDOF_IMAGE_MAX]);

/* Check an image of which `avail` bytes are at hand; returns 1 and its
 * generation if valid (magic, length within avail, CRC, decode, validate
 * for my_id), else 0. */
uint8_t ninedof_image_check(const uint8_t *image, uint8_t avail, uint16_t my_id,
                            uint16_t *generation);

/* Restore at boot from the slot images (NINEDOF_IMAGE_MAX bytes read at
 * NINEDOF_EEPROM_SLOT0, _SLOT1 and _LEGACY1; any may be invalid, legacy1
 * may be NULL and must hold a plain set): the valid one with the newest
 * generation (wrap-aware) goes in force.  Returns the slot used (0, 1, or
 * 2 for legacy1), or 0xFF if none is valid (raw set stays); the set put in
 * force is the stored set (rx->stored_*: none when 0xFF).  *next_slot
 * and *next_generation say where and with which number to write next (the
 * slot that does not hold, or overlap, the image in force). */
uint8_t ninedof_calrx_restore(ninedof_calrx_t *rx,
                              const uint8_t slot0[NINEDOF_IMAGE_MAX],
                              const uint8_t slot1[NINEDOF_IMAGE_MAX],
                              const uint8_t *legacy1,
                              uint8_t *next_slot, uint16_t *next_generation);

#endif /* NINEDOF_CALRX_H */
