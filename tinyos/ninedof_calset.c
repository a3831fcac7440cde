/*
 * ninedof_calset.c -- the calibration set: CRC, lengths, wire <-> native,
 * the raw set and validation (API: ninedof_calset.h).
 *
 * Plain C99 without floats.  Like ninedof_correct.c and ninedof_calrx.c,
 * this file is compiled
 *   - into the nesC firmware (NineDofApp.h includes it),
 *   - for the host into the shared library the simulator loads
 *     (host/motecal/firmware/mote_c.py), and
 *   - with avr-gcc for the simavr tests and the cycle benchmark.
 */
#include <string.h>
#include "ninedof_calset.h"
#include "ninedof_calshared.h"

/* ---------------------------------------------------------------------- */
/* CRC-16-CCITT (XMODEM)                                                   */
/* ---------------------------------------------------------------------- */
#if defined(__AVR__)
#include <util/crc16.h>            /* avr-libc: the same CRC in assembly */
#endif

uint16_t ninedof_crc16(uint16_t crc, const uint8_t *data, uint16_t len)
{
  while (len--) {
#if defined(__AVR__)
    crc = _crc_xmodem_update(crc, *data++);
#else
    uint8_t i;
    crc ^= (uint16_t)(*data++) << 8;
    for (i = 0; i < 8; i++)
      crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
#endif
  }
  return crc;
}

/* ---------------------------------------------------------------------- */
/* Wire <-> native                                                         */
/* ---------------------------------------------------------------------- */

uint8_t ninedof_calset_len(uint8_t format)
{
  if (format == NINEDOF_CALSET_PLAIN)
    return (uint8_t)sizeof(ninedof_calset_t);
  if (format == NINEDOF_CALSET_TEMP)
    return (uint8_t)sizeof(ninedof_calset_temp_t);
  return 0;
}

/* No temperature in force: every sensor at its t_ref (dT = 0) */
static void temp_none(ninedof_cal_t *cal)
{
  uint8_t k, i;

  cal->temp = 0;
  cal->temp_known = 0;
  cal->gain_zero = (1u << NINEDOF_SENSORS) - 1u;
  for (k = 0; k < NINEDOF_SENSORS; k++) {
    cal->eff[k] = cal->s[k];
    for (i = 0; i < 3; i++)
      cal->tg[k][i] = 0;
  }
}

uint8_t ninedof_cal_decode(const void *bytes, uint8_t len, ninedof_cal_t *out)
{
  const ninedof_calset_t *wire = (const ninedof_calset_t *)bytes;
  uint8_t k, i, bad = 0;

  memset(out, 0, sizeof(*out));
  if (len < sizeof(ninedof_calset_t))
    return NINEDOF_CAL_E_FORMAT;
  out->mote = nxp_get_u16(&wire->mote);
  out->version = nxp_get_u16(&wire->version);
  out->sensors = nxp_get_u8(&wire->sensors);
  out->format = nxp_get_u8(&wire->format);
  if (ninedof_calset_len(out->format) != len || (out->sensors & ~SENSOR_BITS) != 0)
    bad = 1;
  for (k = 0; k < NINEDOF_SENSORS; k++) {
    const ninedof_cal_sensor_t *w = &wire->s[k];
    ninedof_cal_sensor_native_t *n = &out->s[k];
    for (i = 0; i < 9; i++)
      n->a[i] = nxp_get_i16(&w->a[i]);
    for (i = 0; i < 3; i++)
      n->c[i] = nxp_get_i32(&w->c[i]);
    n->shift = nxp_get_u8(&w->shift);
    if (n->shift < NINEDOF_SHIFT_MIN || n->shift > NINEDOF_SHIFT_MAX ||
        nxp_get_u8(&w->reserved) != 0)
      bad = 1;
  }
  if (!bad && out->format == NINEDOF_CALSET_TEMP) {
    const ninedof_calset_temp_t *wt = (const ninedof_calset_temp_t *)bytes;
    out->temp_sensors = nxp_get_u8(&wt->temp_sensors);
    if ((out->temp_sensors & ~SENSOR_BITS) != 0 || nxp_get_u8(&wt->reserved) != 0)
      bad = 1;
    for (k = 0; k < NINEDOF_SENSORS; k++) {
      const ninedof_cal_temp_t *w = &wt->t[k];
      ninedof_cal_temp_native_t *n = &out->t[k];
      n->t_ref = nxp_get_i16(&w->t_ref);
      n->t_lo = nxp_get_i16(&w->t_lo);
      n->t_hi = nxp_get_i16(&w->t_hi);
      for (i = 0; i < 3; i++)
        n->o[i] = nxp_get_i16(&w->o[i]);
      for (i = 0; i < 3; i++)
        n->g[i] = nxp_get_i16(&w->g[i]);
      n->oshift = nxp_get_u8(&w->oshift);
      n->gshift = nxp_get_u8(&w->gshift);
      if (out->temp_sensors & (1u << k)) {
        if (n->oshift < NINEDOF_OSHIFT_MIN || n->oshift > NINEDOF_OSHIFT_MAX ||
            n->gshift < NINEDOF_GSHIFT_MIN || n->gshift > NINEDOF_GSHIFT_MAX ||
            out->s[k].shift != NINEDOF_SHIFT_MAX)
          bad = 1;
      }
    }
  }
  if (bad)
    return NINEDOF_CAL_E_FORMAT;
  temp_none(out);
  return NINEDOF_CAL_OK;
}

uint8_t ninedof_cal_encode(const ninedof_cal_t *cal, void *bytes)
{
  ninedof_calset_t *wire = (ninedof_calset_t *)bytes;
  uint8_t k, i, len = ninedof_calset_len(cal->format);

  nxp_set_u16(&wire->mote, cal->mote);
  nxp_set_u16(&wire->version, cal->version);
  nxp_set_u8(&wire->sensors, cal->sensors);
  nxp_set_u8(&wire->format, cal->format);
  for (k = 0; k < NINEDOF_SENSORS; k++) {
    ninedof_cal_sensor_t *w = &wire->s[k];
    const ninedof_cal_sensor_native_t *n = &cal->s[k];
    for (i = 0; i < 9; i++)
      nxp_set_i16(&w->a[i], n->a[i]);
    for (i = 0; i < 3; i++)
      nxp_set_i32(&w->c[i], n->c[i]);
    nxp_set_u8(&w->shift, n->shift);
    nxp_set_u8(&w->reserved, 0);
  }
  if (cal->format == NINEDOF_CALSET_TEMP) {
    ninedof_calset_temp_t *wt = (ninedof_calset_temp_t *)bytes;
    nxp_set_u8(&wt->temp_sensors, cal->temp_sensors);
    nxp_set_u8(&wt->reserved, 0);
    for (k = 0; k < NINEDOF_SENSORS; k++) {
      ninedof_cal_temp_t *w = &wt->t[k];
      const ninedof_cal_temp_native_t *n = &cal->t[k];
      nxp_set_i16(&w->t_ref, n->t_ref);
      nxp_set_i16(&w->t_lo, n->t_lo);
      nxp_set_i16(&w->t_hi, n->t_hi);
      for (i = 0; i < 3; i++)
        nxp_set_i16(&w->o[i], n->o[i]);
      for (i = 0; i < 3; i++)
        nxp_set_i16(&w->g[i], n->g[i]);
      nxp_set_u8(&w->oshift, n->oshift);
      nxp_set_u8(&w->gshift, n->gshift);
    }
  }
  return len;
}

void ninedof_cal_identity(ninedof_cal_t *cal, uint16_t mote, uint16_t version)
{
  uint8_t k;

  memset(cal, 0, sizeof(*cal));
  cal->mote = mote;
  cal->version = version;
  cal->sensors = 0;
  for (k = 0; k < NINEDOF_SENSORS; k++) {
    cal->s[k].a[0] = cal->s[k].a[4] = cal->s[k].a[8] = 1 << NINEDOF_SHIFT_MAX;
    cal->s[k].shift = NINEDOF_SHIFT_MAX;
  }
  temp_none(cal);
}

/* ---------------------------------------------------------------------- */
/* Validation                                                              */
/* ---------------------------------------------------------------------- */
static uint32_t abs32(int32_t v)
{
  return v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
}

/* Range of one sensor (shift already known to be 8..14). */
static uint8_t sensor_in_range(const ninedof_cal_sensor_native_t *s)
{
  uint8_t up = (uint8_t)(NINEDOF_SHIFT_MAX - s->shift);   /* to Q14 */
  uint8_t r, j;

  for (r = 0; r < 3; r++) {
    uint32_t sum = 0;
    uint32_t c = abs32(s->c[r]);
    for (j = 0; j < 3; j++) {
      int32_t q14 = (int32_t)s->a[3 * r + j] * ((int32_t)1 << up);
      uint32_t m = abs32(q14);
      if (r == j) {
        if (q14 < NINEDOF_LIMIT_DIAG_MIN_Q14 || q14 > NINEDOF_LIMIT_DIAG_MAX_Q14)
          return 0;
      } else if (m > NINEDOF_LIMIT_OFFDIAG_Q14) {
        return 0;
      }
      sum += abs32(s->a[3 * r + j]);
    }
    /* |c| <= 4096 counts in Q(shift) */
    if (c > ((uint32_t)NINEDOF_LIMIT_OFFSET_COUNTS << s->shift))
      return 0;
    /* sum |a| * 32768 + |c| < 2^31: sum <= 3 * 32768 so sum * 32768 fits
     * uint32; test without overflowing. */
    if (sum >= 65536UL || sum * 32768UL >= 0x80000000UL - c)
      return 0;
  }
  return 1;
}

/* Temperature terms of sensor k at both ends of its range (the terms are
 * linear in dT, so the ends bound them). */
static uint8_t temp_in_range(const ninedof_cal_t *cal, uint8_t k)
{
  const ninedof_cal_temp_native_t *t = &cal->t[k];
  const ninedof_cal_sensor_native_t *s = &cal->s[k];
  int32_t ends[2];
  uint8_t e, r, j;

  if (t->t_lo > t->t_hi)
    return 0;
  ends[0] = (int32_t)t->t_lo - t->t_ref;
  ends[1] = (int32_t)t->t_hi - t->t_ref;
  for (e = 0; e < 2; e++) {
    int32_t dt = ends[e];
    if (dt > 32767 || dt < -32767)
      return 0;
    for (r = 0; r < 3; r++) {
      int32_t g = temp_gain(t, r, dt);
      uint32_t sum = 0, acc, o = abs32(temp_offset(t, r, dt));
      if (g > NINEDOF_LIMIT_GAIN_Q30 || g < -NINEDOF_LIMIT_GAIN_Q30)
        return 0;
      if (o > ((uint32_t)NINEDOF_LIMIT_OFFSET_COUNTS << NINEDOF_SHIFT_MAX))
        return 0;
      for (j = 0; j < 3; j++)
        sum += abs32(s->a[3 * r + j]);
      acc = sum * 32768UL;                  /* < 2^31: sensor_in_range */
      acc += acc >> 3;                      /* |p G| <= |p| / 8 */
      /* + the gain term's truncation (< 5), 2^13 and the residual (2^13) */
      acc += abs32(s->c[r]) + o + 2UL * (uint32_t)ROUND_Q14 + 5UL;
      if (acc >= 0x80000000UL)
        return 0;
    }
  }
  return 1;
}

uint8_t ninedof_cal_validate(const ninedof_cal_t *cal, uint16_t my_id)
{
  uint8_t k;

  if (cal->mote != my_id)
    return NINEDOF_CAL_E_MOTE;
  if (cal->version == 0)
    return NINEDOF_CAL_E_VERSION;
  if (cal->sensors & ~SENSOR_BITS)
    return NINEDOF_CAL_E_FORMAT;
  for (k = 0; k < NINEDOF_SENSORS; k++)
    if (cal->s[k].shift < NINEDOF_SHIFT_MIN || cal->s[k].shift > NINEDOF_SHIFT_MAX)
      return NINEDOF_CAL_E_FORMAT;
  /* Only corrected sensors are range-checked: the others are never used. */
  if (ninedof_calset_len(cal->format) == 0 || (cal->temp_sensors & ~cal->sensors) ||
      (cal->format != NINEDOF_CALSET_TEMP && cal->temp_sensors))
    return NINEDOF_CAL_E_FORMAT;
  for (k = 0; k < NINEDOF_SENSORS; k++)
    if ((cal->temp_sensors & (1u << k)) && cal->s[k].shift != NINEDOF_SHIFT_MAX)
      return NINEDOF_CAL_E_FORMAT;
  for (k = 0; k < NINEDOF_SENSORS; k++)
    if ((cal->sensors & (1u << k)) && !sensor_in_range(&cal->s[k]))
      return NINEDOF_CAL_E_RANGE;
  for (k = 0; k < NINEDOF_SENSORS; k++)
    if ((cal->temp_sensors & (1u << k)) && !temp_in_range(cal, k))
      return NINEDOF_CAL_E_RANGE;
  return NINEDOF_CAL_OK;
}
