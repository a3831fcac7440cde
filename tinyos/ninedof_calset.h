/*
 * ninedof_calset.h -- the calibration set on the mote: its native form, the
 * wire format (CRC, lengths, encode, decode; the wire structs are
 * NineDofMsg.h's ninedof_calset_t and ninedof_calset_temp_t), the raw set,
 * and validation.  Implemented in ninedof_calset.c.  What the correction
 * does with a set, and the bounds validation's limits give it:
 * ninedof_correct.h.
 */
#ifndef NINEDOF_CALSET_H
#define NINEDOF_CALSET_H

#include <stddef.h>
#include <stdint.h>
#include "NineDofMsg.h"

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

#endif /* NINEDOF_CALSET_H */
