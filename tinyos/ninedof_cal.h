/*
 * ninedof_cal.h -- on-mote calibration: fixed-point correction, validation,
 * the upload receiver, and the persistent image.  Plain C (C99, no floats):
 * compiled into the nesC firmware, tested with gcc and avr-gcc/simavr, and
 * built as a shared library that the host simulator calls through ctypes
 * (host/motecal/mote_c.py), so the simulated mote and the firmware run the
 * same code and produce bit-identical corrected samples.
 *
 * Correction, per sensor k with matrix A (Q shift) and offset c (Q shift):
 *   acc_i = c_i + sum_j A_ij * raw_j                (int32, exact)
 *   out_i = sat((acc_i + 2^(shift-1)) >> shift)     (arithmetic shift:
 *                                                    round half up)
 * sat(): accel and gyro to [-32768, 32767]; mag to [-4095, 4095], and a
 * magnetometer sample with any axis at HMC5883L_OVERFLOW (-4096) stays
 * (-4096, -4096, -4096).  Sensors whose bit is clear in `sensors` pass raw.
 * Validation guarantees acc_i cannot overflow int32 for any int16 input.
 */
#ifndef NINEDOF_CAL_H
#define NINEDOF_CAL_H

#include <stddef.h>
#include <stdint.h>
#include "NineDofMsg.h"

#define NINEDOF_MAG_OVERFLOW (-4096)
#define NINEDOF_SHIFT_MIN 8
#define NINEDOF_SHIFT_MAX 14

/* Plausibility limits (validation); A in real units = a / 2^shift */
#define NINEDOF_LIMIT_DIAG_MIN_Q14 8192     /* 0.5 */
#define NINEDOF_LIMIT_DIAG_MAX_Q14 32767    /* ~2.0 */
#define NINEDOF_LIMIT_OFFDIAG_Q14 8192      /* |A_ij| <= 0.5 */
#define NINEDOF_LIMIT_OFFSET_COUNTS 4096L   /* |c_i| <= 4096 counts */

/* Native (host byte order) form of one sensor's correction */
typedef struct {
  int16_t a[9];          /* row-major, Q(shift) */
  int32_t c[3];          /* counts, Q(shift) */
  uint8_t shift;
} ninedof_cal_sensor_native_t;

/* Native form of a calibration set */
typedef struct {
  uint16_t mote;
  uint16_t version;
  uint8_t sensors;       /* bit NINEDOF_SENSOR_x: corrected */
  ninedof_cal_sensor_native_t s[NINEDOF_SENSORS];
} ninedof_cal_t;

/* CRC-16-CCITT, XMODEM (poly 0x1021, no reflection); start with crc = 0.
 * Equals Python's binascii.crc_hqx(data, crc). */
uint16_t ninedof_crc16(uint16_t crc, const uint8_t *data, uint16_t len);

/* Wire (big-endian ninedof_calset_t) <-> native.  decode returns
 * NINEDOF_CAL_OK or NINEDOF_CAL_E_FORMAT (reserved bytes, unknown sensor bits,
 * shift outside NINEDOF_SHIFT_MIN..MAX). */
uint8_t ninedof_cal_decode(const ninedof_calset_t *wire, ninedof_cal_t *out);
void ninedof_cal_encode(const ninedof_cal_t *cal, ninedof_calset_t *wire);

/* The raw (identity) set: no sensor corrected. */
void ninedof_cal_identity(ninedof_cal_t *cal, uint16_t mote, uint16_t version);

/* Everything a set must satisfy before it is put in force on mote `my_id`:
 * NINEDOF_CAL_OK, _E_MOTE, _E_VERSION (version 0), _E_FORMAT, _E_RANGE
 * (diagonal, off-diagonal and offset limits above, scaled to the set's
 * shift, and sum_j |a_ij| * 32768 + |c_i| < 2^31 for every row). */
uint8_t ninedof_cal_validate(const ninedof_cal_t *cal, uint16_t my_id);

/* Correct one record (9 axes, ax..mz) / n records, raw and out may alias. */
void ninedof_correct(const ninedof_cal_t *cal, const int16_t raw[9], int16_t out[9]);
void ninedof_correct_block(const ninedof_cal_t *cal, const int16_t *raw,
                           int16_t *out, uint16_t n);

/* ------------------------------------------------------------------------
 * Upload receiver: the whole mote side of the upload protocol.
 * ---------------------------------------------------------------------- */
typedef struct {
  uint16_t my_id;
  /* staging */
  ninedof_calset_t staged;                          /* wire bytes being assembled */
  uint8_t have[(sizeof(ninedof_calset_t) + 7) / 8]; /* bitmap of received bytes */
  uint16_t staged_version;                          /* 0 = nothing staged */
  /* in force */
  ninedof_calset_t active_wire;                     /* for read-back and CRC */
  ninedof_cal_t active;                             /* used by correction */
  uint16_t active_crc;
  uint8_t dirty;                                    /* in force but not yet persisted */
} ninedof_calrx_t;

/* Start with the raw set, version 0. */
void ninedof_calrx_init(ninedof_calrx_t *rx, uint16_t my_id);

/* Handle one received message addressed to this mote (AM type and payload).
 * Writes the reply payload into `reply` (at least 28 bytes) and its AM type
 * into *reply_type, and returns the reply length (0: no reply).
 *   CAL_FRAG   -> CAL_FRAG_ACK   (stages bytes; a new version restarts staging)
 *   CAL_COMMIT -> CAL_COMMIT_ACK (APPLY: complete + CRC + validate, then in force;
 *                                 RESET: raw set with the given version)
 *   CAL_QUERY  -> CAL_REPORT     (bytes of the set in force)
 * Messages of other types, or too short, get no reply.  A rejected set
 * leaves the set in force unchanged.  After an accepted commit rx->dirty = 1:
 * the caller persists ninedof_calrx_image() and clears it. */
uint8_t ninedof_calrx_handle(ninedof_calrx_t *rx, uint8_t am_type,
                             const uint8_t *payload, uint8_t len,
                             uint8_t *reply, uint8_t *reply_type);

/* Flags byte for sample messages: NINEDOF_FLAG_CORRECTED when any sensor is
 * corrected, version low 4 bits in bits 4-7. */
uint8_t ninedof_calrx_flags(const ninedof_calrx_t *rx);

/* Correct n records with the set in force. */
void ninedof_calrx_correct_block(const ninedof_calrx_t *rx, const int16_t *raw,
                                 int16_t *out, uint16_t n);

/* ------------------------------------------------------------------------
 * Persistent image (internal EEPROM, two slots written alternately so a
 * reset during a write leaves the other slot valid).
 * Image: magic(2) 'N','9', generation(2), crc(2) over generation..set,
 * then the wire set (sizeof(ninedof_calset_t)).  Big-endian.
 * ---------------------------------------------------------------------- */
#define NINEDOF_IMAGE_SIZE (6 + sizeof(ninedof_calset_t))
#define NINEDOF_EEPROM_SLOT0 0x100
#define NINEDOF_EEPROM_SLOT1 0x180

/* Build the image of the set in force with the given generation number. */
void ninedof_calrx_image(const ninedof_calrx_t *rx, uint16_t generation,
                         uint8_t image[NINEDOF_IMAGE_SIZE]);

/* Check an image; returns 1 and its generation if valid (magic, CRC, decode,
 * validate for my_id), else 0. */
uint8_t ninedof_image_check(const uint8_t image[NINEDOF_IMAGE_SIZE], uint16_t my_id,
                            uint16_t *generation);

/* Restore at boot from two slot images (either may be invalid): the valid
 * one with the newer generation (wrap-aware) goes in force.  Returns the slot
 * used (0 or 1), or 0xFF if neither is valid (raw set stays). *next_slot
 * and *next_generation say where and with which number to write next. */
uint8_t ninedof_calrx_restore(ninedof_calrx_t *rx,
                              const uint8_t slot0[NINEDOF_IMAGE_SIZE],
                              const uint8_t slot1[NINEDOF_IMAGE_SIZE],
                              uint8_t *next_slot, uint16_t *next_generation);

/* ------------------------------------------------------------------------
 * Sizes and accessors for foreign-function callers (host/motecal/mote_c.py
 * through ctypes), defined in ninedof_ffi.c, which the firmware does not
 * build.
 * ---------------------------------------------------------------------- */
size_t ninedof_calrx_size(void);      /* sizeof(ninedof_calrx_t) */
size_t ninedof_cal_size(void);        /* sizeof(ninedof_cal_t) */
size_t ninedof_calset_size(void);     /* sizeof(ninedof_calset_t) */
size_t ninedof_image_size(void);      /* NINEDOF_IMAGE_SIZE */
/* Fields of the receiver state, without knowing its layout */
uint16_t ninedof_calrx_version(const ninedof_calrx_t *rx);  /* version in force */
uint8_t ninedof_calrx_sensors(const ninedof_calrx_t *rx);   /* sensors corrected */
uint16_t ninedof_calrx_crc(const ninedof_calrx_t *rx);      /* CRC of the set in force */
uint8_t ninedof_calrx_dirty(const ninedof_calrx_t *rx);
void ninedof_calrx_set_dirty(ninedof_calrx_t *rx, uint8_t dirty);
/* Wire bytes of the set in force (sizeof(ninedof_calset_t)) */
void ninedof_calrx_active(const ninedof_calrx_t *rx, uint8_t *out);

#endif /* NINEDOF_CAL_H */
