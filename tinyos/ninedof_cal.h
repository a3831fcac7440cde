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
 *   out_i = sat((acc_i + r_i + 2^(shift-1)) >> shift)   (arithmetic shift)
 *   r_i  <- acc_i + r_i - (out_i << shift)          (the residual)
 * i.e. rounding half up with error feedback: r_i (fb in the sensor's
 * native form, per row, in Q14 units; Q14 is the kernel's shift for every
 * valid set, and a sensor with temperature terms keeps it in eff[k]) is what the
 * last rounding of axis i dropped, in [-1/2, 1/2) LSB, so every output is
 * within 1 LSB of the exact value (|out - x| = |r - r'| < 1) and the mean
 * of the outputs follows the mean of the exact values (within 1 LSB over
 * the whole run): plain rounding of a still board's samples, whose exact
 * values keep the same fraction, would be biased by up to 1/2 LSB.  The
 * residuals are 0 after decode/identity, when a set is put in force and at
 * boot; a saturated sample (int16 or the magnetometer's +-4095 clipping)
 * or a magnetometer overflow sample sets the axis's residual to 0.  A set
 * that is not representable in Q14 (never valid) rounds without residual.
 * sat(): accel and gyro to [-32768, 32767]; mag to [-4095, 4095], and a
 * magnetometer sample with any axis at HMC5883L_OVERFLOW (-4096) stays
 * (-4096, -4096, -4096).  Sensors whose bit is clear in `sensors` pass raw.
 * Validation guarantees acc_i cannot overflow int32 for any int16 input.
 *
 * Temperature terms (a set of format NINEDOF_CALSET_TEMP, NineDofMsg.h):
 * for a sensor with its bit in temp_sensors (its shift must be 14), with T
 * the temperature in force (ninedof_cal_set_temp: raw TEMP_OUT; until one
 * is set, each sensor's t_ref, i.e. no temperature term) and
 * dT = clamp(T, t_lo, t_hi) - t_ref, per row i, in Q14 units:
 *   p   = sum_j a_ij raw_j                                  (exact)
 *   G   = round(g_i dT 2^(30 - gshift))    (Q30, exact for gshift <= 30)
 *   O   = round(o_i dT 2^(14 - oshift))    (Q14)
 *   t   = floor((ph gh 2^16 + ph gl + pl gh) / 2^14)  with p = ph 2^16 + pl,
 *         G = gh 2^16 + gl (16-bit halves, the high ones signed)
 *   x'  = p + t + c_i + O,   out_i = sat((x' + r_i + 2^13) >> 14)
 * G and O are recomputed only when T changes.  Offsets only (every G of
 * the sensor 0) is the plain kernel with c + O and its residuals; with a
 * gain, after each rounding the stored residual is clamped to
 * [-(2^13 - E), 2^13 - E], E = NINEDOF_TEMP_MARGIN = 16 (e = 2^-10 LSB),
 * and set_temp clamps it so on entering the gain path.
 *
 * Bound: with X = ((1 + g_i dT / 2^gshift) p + c_i) + o_i dT 2^(14-oshift)
 * the exact value (Q14; fixedpoint.reference_correct, in LSB X / 2^14),
 * |out_i - X / 2^14| < 1 - 2^-11 LSB for every valid set, T and input.
 * Proof.  (1) d = |x' - X| < 6.25: p G / 2^30 - t is in [0, 5) (the
 * dropped pl gl / 2^30 < 4, and the floor), |p| |G / 2^30 - g dT /
 * 2^gshift| <= |p| 2^-31 < 0.75 (validation: |p| <= (32767 + 2 * 8192)
 * 2^15 < 0.75 * 2^31), |O - o dT 2^(14-oshift)| <= 1/2.  (2) Rounding with
 * error feedback: v = x' + r + 2^13, out 2^14 = v - 2^13 - r' with the new
 * raw residual r' in [-2^13, 2^13), so out 2^14 - x' = r - r'; on the gain
 * path the stored r is in [-(2^13 - E), 2^13 - E], hence |out 2^14 - x'|
 * <= 2^14 - E, and |out - X / 2^14| <= (2^14 - E + d) / 2^14 < 1 - 9.75 /
 * 2^14 < 1 - 2^-11.  Offsets only: t = 0, d <= 1/2, and r, r' are
 * integers in [-2^13, 2^13), so |r - r'| <= 2^14 - 1 and the error is <=
 * 1 - 2^-15.  Saturation (int16, the magnetometer's +-4095) clips out and
 * the reference alike and clipping never increases a distance.  []
 * The clamp costs the mean at most e per clamped sample: over N samples
 * sum(out - x' / 2^14) = r_0 - r'_N + (what the clamps dropped), so the
 * mean of N outputs is within (1 + e n_c) / N + d / 2^14 of the exact mean,
 * n_c the clamped samples (a clamp needs |r'| > 1/2 - e: rare; e at worst).
 * Validation keeps the sums in int32: |G| <= 1/8 (|G| <= 2^27 at both
 * ends of the range), |O| <= 4096 counts, (9/8) sum_j |a_ij| 2^15 + |c_i|
 * + |O| + 2^14 + 5 < 2^31; then |ph| <= 24576 and |gh| <= 2^11.
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
  /* rounding with error feedback: per row the residual r of the last
   * rounding (Q14, in [-2^13, 2^13)) stored as r mod 2^14, so 0 = none;
   * the only field the correction writes */
  uint16_t fb[3];
} ninedof_cal_sensor_native_t;

/* Native form of one sensor's temperature terms (ninedof_cal_temp_t) */
typedef struct {
  int16_t t_ref, t_lo, t_hi;   /* raw TEMP_OUT */
  int16_t o[3];          /* counts per TEMP_OUT count, Q(oshift) */
  int16_t g[3];          /* relative per TEMP_OUT count, Q(gshift) */
  uint8_t oshift, gshift;
} ninedof_cal_temp_native_t;

#define NINEDOF_OSHIFT_MIN 14
#define NINEDOF_OSHIFT_MAX 40
#define NINEDOF_GSHIFT_MIN 16
#define NINEDOF_GSHIFT_MAX 46
#define NINEDOF_LIMIT_GAIN_Q30 (1L << 27)    /* |g dT| <= 1/8 over the range */
/* The gain path's residuals stay within [-(2^13 - E), 2^13 - E] (Q14): E =
 * 16, e = E / 2^14 = 2^-10 LSB (the header comment's bound) */
#define NINEDOF_TEMP_MARGIN 16u

/* Native form of a calibration set */
typedef struct {
  uint16_t mote;
  uint16_t version;
  uint8_t sensors;       /* bit NINEDOF_SENSOR_x: corrected */
  uint8_t format;        /* NINEDOF_CALSET_PLAIN or _TEMP */
  ninedof_cal_sensor_native_t s[NINEDOF_SENSORS];
  uint8_t temp_sensors;  /* bit NINEDOF_SENSOR_x: temperature terms (format TEMP) */
  ninedof_cal_temp_native_t t[NINEDOF_SENSORS];
  /* the temperature terms at the temperature in force (ninedof_cal_set_temp) */
  int16_t temp;          /* raw TEMP_OUT in force */
  uint8_t temp_known;    /* 0: none set yet, each sensor at its t_ref */
  /* per sensor with temperature terms: the correction at that temperature
   * for the kernel (a, shift as in s[k]; c = c + O, Q14), and whether its
   * gain terms are all 0 (then the kernel alone is the whole correction) */
  ninedof_cal_sensor_native_t eff[NINEDOF_SENSORS];
  uint8_t gain_zero;                /* bit k: tg[k] all 0 */
  int32_t tg[NINEDOF_SENSORS][3];   /* G = g dT / 2^gshift, Q30 */
} ninedof_cal_t;

/* Bytes of a set of the given format (0 for an unknown format). */
uint8_t ninedof_calset_len(uint8_t format);
#define NINEDOF_CALSET_MAX ((uint8_t)sizeof(ninedof_calset_temp_t))   /* 164 */

/* CRC-16-CCITT, XMODEM (poly 0x1021, no reflection); start with crc = 0.
 * Equals Python's binascii.crc_hqx(data, crc). */
uint16_t ninedof_crc16(uint16_t crc, const uint8_t *data, uint16_t len);

/* Wire (big-endian ninedof_calset_t, or ninedof_calset_temp_t) <-> native.
 * decode takes the set's `len` bytes and returns NINEDOF_CAL_OK or
 * NINEDOF_CAL_E_FORMAT (a length that is not the format's, an unknown
 * format, reserved bytes, unknown sensor bits, shift outside
 * NINEDOF_SHIFT_MIN..MAX, temperature terms on a sensor whose shift is not
 * 14 or with shifts outside their ranges).  The decoded set has no
 * temperature in force (each sensor at its t_ref).  encode writes
 * ninedof_calset_len(cal->format) bytes and returns that length. */
uint8_t ninedof_cal_decode(const void *wire, uint8_t len, ninedof_cal_t *out);
uint8_t ninedof_cal_encode(const ninedof_cal_t *cal, void *wire);

/* Put the board temperature `raw` (TEMP_OUT) in force for the temperature
 * terms: recomputes eff[].c (c + O) and tg (G), a few multiplications per
 * sensor, and limits the residuals of sensors on the gain path to 1/2 - e. */
void ninedof_cal_set_temp(ninedof_cal_t *cal, int16_t raw);

/* The raw (identity) set: no sensor corrected. */
void ninedof_cal_identity(ninedof_cal_t *cal, uint16_t mote, uint16_t version);

/* Everything a set must satisfy before it is put in force on mote `my_id`:
 * NINEDOF_CAL_OK, _E_MOTE, _E_VERSION (version 0), _E_FORMAT, _E_RANGE
 * (diagonal, off-diagonal and offset limits above, scaled to the set's
 * shift, and sum_j |a_ij| * 32768 + |c_i| < 2^31 for every row; with
 * temperature terms, at both ends of the range: t_lo <= t_hi, |dT| <=
 * 32767, |G| <= 2^27 (|g dT| <= 1/8), |O| <= 4096 counts, and the
 * accumulator (9/8) sum_j |a_ij| 32768 + |c_i| + |O| + 2^14 + 5 < 2^31). */
uint8_t ninedof_cal_validate(const ninedof_cal_t *cal, uint16_t my_id);

/* Correct one record (9 axes, ax..mz) / n records, raw and out may alias.
 * Updates the set's rounding residuals (fb of s[] or eff[]): records are
 * corrected in the order they were sampled. */
void ninedof_correct(ninedof_cal_t *cal, const int16_t raw[9], int16_t out[9]);
void ninedof_correct_block(ninedof_cal_t *cal, const int16_t *raw,
                           int16_t *out, uint16_t n);

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
} ninedof_calrx_t;

/* Start with the raw set, version 0. */
void ninedof_calrx_init(ninedof_calrx_t *rx, uint16_t my_id);

/* Handle one received message addressed to this mote (AM type and payload).
 * Writes the reply payload into `reply` (at least 28 bytes) and its AM type
 * into *reply_type, and returns the reply length (0: no reply).
 *   CAL_FRAG   -> CAL_FRAG_ACK   (stages bytes; a new version restarts staging;
 *                                 bytes past NINEDOF_CALSET_MAX: E_FRAG)
 *   CAL_COMMIT -> CAL_COMMIT_ACK (APPLY: length 102 or 152 as the set's
 *                                 format says, complete + CRC + validate, then in force;
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
 * then the wire set (its format byte gives its length: 102 or 152 bytes).
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
 * 2 for legacy1), or 0xFF if none is valid (raw set stays).  *next_slot
 * and *next_generation say where and with which number to write next (the
 * slot that does not hold, or overlap, the image in force). */
uint8_t ninedof_calrx_restore(ninedof_calrx_t *rx,
                              const uint8_t slot0[NINEDOF_IMAGE_MAX],
                              const uint8_t slot1[NINEDOF_IMAGE_MAX],
                              const uint8_t *legacy1,
                              uint8_t *next_slot, uint16_t *next_generation);

/* ------------------------------------------------------------------------
 * Sizes and accessors for foreign-function callers (host/motecal/mote_c.py
 * through ctypes), defined in ninedof_ffi.c, which the firmware does not
 * build.
 * ---------------------------------------------------------------------- */
size_t ninedof_calrx_size(void);      /* sizeof(ninedof_calrx_t) */
size_t ninedof_cal_size(void);        /* sizeof(ninedof_cal_t) */
size_t ninedof_calset_size(void);     /* sizeof(ninedof_calset_t) */
size_t ninedof_calset_temp_size(void); /* sizeof(ninedof_calset_temp_t) */
size_t ninedof_image_size(void);      /* NINEDOF_IMAGE_MAX */
uint16_t ninedof_eeprom_legacy1(void); /* NINEDOF_EEPROM_LEGACY1 */
/* Fields of the receiver state, without knowing its layout */
uint16_t ninedof_calrx_version(const ninedof_calrx_t *rx);  /* version in force */
uint8_t ninedof_calrx_sensors(const ninedof_calrx_t *rx);   /* sensors corrected */
uint16_t ninedof_calrx_crc(const ninedof_calrx_t *rx);      /* CRC of the set in force */
uint8_t ninedof_calrx_dirty(const ninedof_calrx_t *rx);
void ninedof_calrx_set_dirty(ninedof_calrx_t *rx, uint8_t dirty);
/* Wire bytes of the set in force (ninedof_calrx_active_len of them) */
void ninedof_calrx_active(const ninedof_calrx_t *rx, uint8_t *out);
uint8_t ninedof_calrx_active_len(const ninedof_calrx_t *rx);

#endif /* NINEDOF_CAL_H */
