/*
 * ninedof_cal.c -- implementation of ninedof_cal.h (see there for the API).
 *
 * Plain C99 without floats.  The same file is compiled
 *   - into the nesC firmware (NineDofAppC includes it),
 *   - for the host into the shared library the simulator loads
 *     (host/motecal/mote_c.py), and
 *   - with avr-gcc for the simavr tests and the cycle benchmark.
 *
 * Correction: a validated set always fits Q14 without loss (diagonal
 * <= 32767 and off-diagonal <= 8192 in Q14 terms, |c| <= 4096 counts), so
 * a sensor stored with a lower shift is rescaled to Q14 on the fly
 * (shift 14, what the host sends, needs no copy) and one kernel does
 *   out = sat((c14 + 2^13 + sum a14_j * raw_j) >> 14)
 * which is bit-identical to the header's Q(shift) formula:
 *   (x * 2^k + 2^(s+k-1)) >> (s+k) == (x + 2^(s-1)) >> s.
 * A decodable set that is not representable in Q14 (only possible without
 * validation) takes a slower generic path with the same formula.
 * Signed right shifts are arithmetic on gcc and avr-gcc (documented GCC
 * behaviour), which the rounding rule relies on.
 */
#include <string.h>
#include "ninedof_cal.h"

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
#define SENSOR_BITS ((1u << NINEDOF_SENSORS) - 1u)
#define ROUND_Q14 (1L << (NINEDOF_SHIFT_MAX - 1))

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

/* ---------------------------------------------------------------------- */
/* Temperature terms                                                       */
/* ---------------------------------------------------------------------- */
#if defined(__GNUC__)
#define NINEDOF_TEMP_INLINE inline __attribute__((always_inline))
#else
#define NINEDOF_TEMP_INLINE inline
#endif

/* round(v / 2^n), half up (arithmetic shift); |v| < 2^30, n <= 30 */
static int32_t round_shift(int32_t v, uint8_t n)
{
  if (n == 0)
    return v;
  return (v + ((int32_t)1 << (n - 1))) >> n;
}

/* dT of sensor k at raw temperature T: clamp(T, t_lo, t_hi) - t_ref (int32) */
static int32_t temp_delta(const ninedof_cal_temp_native_t *t, int16_t raw)
{
  int16_t c = raw < t->t_lo ? t->t_lo : raw > t->t_hi ? t->t_hi : raw;
  return (int32_t)c - t->t_ref;
}

/* G = g dT / 2^gshift in Q30 of row i at dT (|dT| <= 32767), rounded half
 * up; exact for gshift <= 30.  Saturated at +-2^28 (twice the limit, only
 * sets that fail validation get there) so the correction stays defined. */
#define GAIN_SAT_Q30 ((int32_t)1 << 28)
static int32_t temp_gain(const ninedof_cal_temp_native_t *t, uint8_t i, int32_t dt)
{
  int32_t gd = (int32_t)t->g[i] * (int16_t)dt;          /* |gd| <= 2^30 */
  uint8_t sh = t->gshift;

  if (sh >= 30) {
    gd = round_shift(gd, (uint8_t)(sh - 30));             /* n <= 16 */
  } else {
    int32_t lim = GAIN_SAT_Q30 >> (30 - sh);              /* sh >= 16: >= 2^14 */
    if (gd > lim || gd < -lim)
      gd = gd < 0 ? -lim : lim;
    gd = (int32_t)((uint32_t)gd << (30 - sh));
  }
  if (gd > GAIN_SAT_Q30 || gd < -GAIN_SAT_Q30)
    gd = gd < 0 ? -GAIN_SAT_Q30 : GAIN_SAT_Q30;
  return gd;
}

/* O (Q14) of row i at dT */
static int32_t temp_offset(const ninedof_cal_temp_native_t *t, uint8_t i, int32_t dt)
{
  return round_shift((int32_t)t->o[i] * (int16_t)dt, (uint8_t)(t->oshift - 14));
}

/* A residual stored as fb (r mod 2^14, ninedof_cal.h) limited to
 * [-(2^13 - E), 2^13 - E], E = NINEDOF_TEMP_MARGIN: w = r + 2^13 = fb ^ 0x2000
 * is clamped to [E, 2^14 - E]. */
static NINEDOF_TEMP_INLINE uint16_t resid_margin(uint16_t fb)
{
  uint16_t w = fb ^ 0x2000u;

  if (w < NINEDOF_TEMP_MARGIN)
    w = NINEDOF_TEMP_MARGIN;
  else if (w > (1u << 14) - NINEDOF_TEMP_MARGIN)
    w = (1u << 14) - NINEDOF_TEMP_MARGIN;
  return (uint16_t)(w ^ 0x2000u);
}

void ninedof_cal_set_temp(ninedof_cal_t *cal, int16_t raw)
{
  uint8_t k, i;

  cal->temp = raw;
  cal->temp_known = 1;
  cal->gain_zero = 0;
  for (k = 0; k < NINEDOF_SENSORS; k++) {
    uint8_t zero = 1;
    const ninedof_cal_temp_native_t *t = &cal->t[k];
    uint8_t on = (cal->temp_sensors >> k) & 1;
    int32_t dt = on ? temp_delta(t, raw) : 0;
    /* an invalid set (never put in force) may not fit: keep it defined */
    if (dt > 32767 || dt < -32767)
      dt = 0;
    /* everything but the residuals, which carry on across temperatures */
    memcpy(&cal->eff[k], &cal->s[k], offsetof(ninedof_cal_sensor_native_t, fb));
    for (i = 0; i < 3; i++) {
      cal->tg[k][i] = on ? temp_gain(t, i, dt) : 0;
      zero &= cal->tg[k][i] == 0;
      cal->eff[k].c[i] = (int32_t)((uint32_t)cal->s[k].c[i] +
                                   (uint32_t)(on ? temp_offset(t, i, dt) : 0));
    }
    cal->gain_zero |= (uint8_t)(zero << k);
    if (!zero)              /* the gain path keeps its residuals within 1/2 - e */
      for (i = 0; i < 3; i++)
        cal->eff[k].fb[i] = resid_margin(cal->eff[k].fb[i]);
  }
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

/* ---------------------------------------------------------------------- */
/* Correction                                                              */
/* ---------------------------------------------------------------------- */
#if defined(__GNUC__)
#define NINEDOF_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define NINEDOF_ALWAYS_INLINE inline
#endif


#if defined(__AVR__) && !defined(NINEDOF_PORTABLE_KERNEL)
/*
 * AVR kernel: the nine multiply-accumulates of one sensor in one asm block.
 * Signed 16 x 16 -> 32 bit MAC with MULS/MULSU/MUL as in Atmel application
 * note AVR201 (19 cycles, against ~40 for a call to __mulhisi3 plus a 32-bit
 * add), column by column: each input is loaded once, the three accumulators
 * stay in registers, matrix and offsets are read with LDD from Z.
 * MULSU needs its operands in r16..r23 ("a" constraint).
 */
#include <stddef.h>
#ifndef NESC   /* nesC's output of offsetof is no constant expression */
typedef char ninedof_kernel_layout_check[
  (offsetof(ninedof_cal_sensor_native_t, a) == 0 &&
   offsetof(ninedof_cal_sensor_native_t, c) == 18 &&
   offsetof(ninedof_cal_sensor_native_t, fb) == 31) ? 1 : -1];
#endif

#define K_LDM(LO, HI) "ldd %A[m], Z+" #LO "\n\tldd %B[m], Z+" #HI "\n\t"
#define K_LDX "ld %A[x], X+\n\tld %B[x], X+\n\t"
#define K_LDC(ACC, B0, B1, B2, B3)                                      \
  "ldd %A[" #ACC "], Z+" #B0 "\n\tldd %B[" #ACC "], Z+" #B1 "\n\t"      \
  "ldd %C[" #ACC "], Z+" #B2 "\n\tldd %D[" #ACC "], Z+" #B3 "\n\t"
/* acc0..2 += a (row-major at Z+0) times the three int16 inputs at X+ */
#define K_MATVEC                                                        \
  K_LDX                                                                 \
  K_LDM(0, 1) K_MAC(acc0) K_LDM(6, 7) K_MAC(acc1) K_LDM(12, 13) K_MAC(acc2) \
  K_LDX                                                                 \
  K_LDM(2, 3) K_MAC(acc0) K_LDM(8, 9) K_MAC(acc1) K_LDM(14, 15) K_MAC(acc2) \
  K_LDX                                                                 \
  K_LDM(4, 5) K_MAC(acc0) K_LDM(10, 11) K_MAC(acc1) K_LDM(16, 17) K_MAC(acc2)
#define K_ROUND(ACC)  /* += 0x2000 (2^13); %A[m] holds 0x20 */          \
  "add %B[" #ACC "], %A[m]\n\tadc %C[" #ACC "], %[z]\n\t"               \
  "adc %D[" #ACC "], %[z]\n\t"
#define K_MAC(ACC)                                                      \
  "muls  %B[m], %B[x]\n\t"        /* mh*xh -> bytes 2,3 */               \
  "add   %C[" #ACC "], r0\n\t"                                          \
  "adc   %D[" #ACC "], r1\n\t"                                          \
  "mul   %A[m], %A[x]\n\t"        /* ml*xl -> bytes 0,1 */               \
  "add   %A[" #ACC "], r0\n\t"                                          \
  "adc   %B[" #ACC "], r1\n\t"                                          \
  "adc   %C[" #ACC "], %[z]\n\t"                                        \
  "adc   %D[" #ACC "], %[z]\n\t"                                        \
  "mulsu %B[m], %A[x]\n\t"        /* mh*xl -> bytes 1,2; C = sign */     \
  "sbc   %D[" #ACC "], %[z]\n\t"  /* sign extension into byte 3 */      \
  "add   %B[" #ACC "], r0\n\t"                                          \
  "adc   %C[" #ACC "], r1\n\t"                                          \
  "adc   %D[" #ACC "], %[z]\n\t"                                        \
  "mulsu %B[x], %A[m]\n\t"        /* xh*ml -> bytes 1,2; C = sign */     \
  "sbc   %D[" #ACC "], %[z]\n\t"                                        \
  "add   %B[" #ACC "], r0\n\t"                                          \
  "adc   %C[" #ACC "], r1\n\t"                                          \
  "adc   %D[" #ACC "], %[z]\n\t"

/* Where the stores of sensor_q14_acc start.  Not an input register: where the
 * compiler could see out == in (the mote corrects its batch in place,
 * ninedof_batch_pack, and nesC builds the image as one C file with
 * everything inlined) it gave an input operand `out` the register of `p`
 * (X): "movw r26, %[out]" became "movw r26, r26", X stayed where the loads
 * had taken it and every store went 6 bytes late, the last past the record
 * (found by the emulated release check; tests/test_cal_inplace.py).  Hiding
 * out's value costs two registers the kernel does not have once inlined, so
 * the kernel reads it from memory (LDS, 4 cycles against MOVW's 1). */
static int16_t *ninedof_kernel_out;

/* The nine multiply-accumulates of one sensor, the three int32
 * accumulators (c + 2^13 + A raw, Q14) stored as they are: the rounding
 * with error feedback (shape_q14) and the temperature terms (sensor_temp)
 * work on them in C. */
#define K_ST32(ACC)                                                     \
  "st X+, %A[" #ACC "]\n\tst X+, %B[" #ACC "]\n\t"                     \
  "st X+, %C[" #ACC "]\n\tst X+, %D[" #ACC "]\n\t"

static NINEDOF_ALWAYS_INLINE void sensor_q14_acc(const ninedof_cal_sensor_native_t *s,
                                                 const int16_t *in, int32_t *acc)
{
  int32_t acc0, acc1, acc2;
  int16_t m, x;
  uint8_t z;
  const int16_t *p = in;

  ninedof_kernel_out = (int16_t *)acc;
  __asm__ volatile (
    "clr %[z]\n\t"
    K_LDC(acc0, 18, 19, 20, 21)
    K_LDC(acc1, 22, 23, 24, 25)
    K_LDC(acc2, 26, 27, 28, 29)
    "ldi %A[m], 0x20\n\t"
    K_ROUND(acc0) K_ROUND(acc1) K_ROUND(acc2)
    K_MATVEC
    "clr r1\n\t"
    "lds r26, %[o]\n\t"
    "lds r27, %[o]+1\n\t"
    K_ST32(acc0) K_ST32(acc1) K_ST32(acc2)
    : [acc0] "=&r" (acc0), [acc1] "=&r" (acc1), [acc2] "=&r" (acc2),
      [m] "=&a" (m), [x] "=&a" (x), [z] "=&r" (z), [p] "+x" (p)
    : [s] "z" (s), [o] "i" (&ninedof_kernel_out)
    : "r0", "r1", "memory");
  (void)acc0; (void)acc1; (void)acc2; (void)m; (void)x; (void)z; (void)p;
}
/*
 * The kernel with the rounding with error feedback, row by row: a sensor's
 * three inputs stay in registers (x0..x2), one int32 accumulator per row,
 * c + (fb ^ 0x2000) + a_i0 x0 + a_i1 x1 + a_i2 x2, then sat16 and the new
 * residual as shape_q14 (the portable C below) does.  The whole record, the
 * magnetometer's rules included, is one asm block (q14_run), so nothing of
 * the C around it runs per sensor or per record.
 */
/* acc += fb ^ 0x2000 (= r + 2^13, the residual and the rounding constant:
 * fb = r mod 2^14, ninedof_cal.h) from Z+L, Z+H; %[k20] holds 0x20 */
#define Q_FB(L, H)                                                      \
  "ldd  %A[m], Z+" #L "\n\tldd  %B[m], Z+" #H "\n\t"                   \
  "eor  %B[m], %[k20]\n\t"                                              \
  "add  %A[acc], %A[m]\n\tadc  %B[acc], %B[m]\n\t"                      \
  "adc  %C[acc], %[z]\n\tadc  %D[acc], %[z]\n\t"
/* acc += m * XN (signed 16 x 16 -> 32, AVR201, as K_MAC) */
#define Q_MAC(XN)                                                       \
  "muls  %B[m], %B[" #XN "]\n\t"  /* mh*xh -> bytes 2,3 */               \
  "add   %C[acc], r0\n\t"                                               \
  "adc   %D[acc], r1\n\t"                                               \
  "mul   %A[m], %A[" #XN "]\n\t"  /* ml*xl -> bytes 0,1 */               \
  "add   %A[acc], r0\n\t"                                               \
  "adc   %B[acc], r1\n\t"                                               \
  "adc   %C[acc], %[z]\n\t"                                             \
  "adc   %D[acc], %[z]\n\t"                                             \
  "mulsu %B[m], %A[" #XN "]\n\t"  /* mh*xl -> bytes 1,2; C = sign */     \
  "sbc   %D[acc], %[z]\n\t"                                             \
  "add   %B[acc], r0\n\t"                                               \
  "adc   %C[acc], r1\n\t"                                               \
  "adc   %D[acc], %[z]\n\t"                                             \
  "mulsu %B[" #XN "], %A[m]\n\t"  /* xh*ml -> bytes 1,2; C = sign */     \
  "sbc   %D[acc], %[z]\n\t"                                             \
  "add   %B[acc], r0\n\t"                                               \
  "adc   %C[acc], r1\n\t"                                               \
  "adc   %D[acc], %[z]\n\t"
/* acc = c + (fb ^ 0x2000) + the row times (x0, x1, x2): row R of the
 * sensor at Z has c at Z+18+4R, fb at Z+31+2R, a at Z+6R */
#define Q_ROW(C0, C1, C2, C3, L, H, A0, A1, A2, A3, A4, A5)              \
  "ldd  %A[acc], Z+" #C0 "\n\tldd  %B[acc], Z+" #C1 "\n\t"              \
  "ldd  %C[acc], Z+" #C2 "\n\tldd  %D[acc], Z+" #C3 "\n\t"              \
  Q_FB(L, H)                                                            \
  "ldd  %A[m], Z+" #A0 "\n\tldd  %B[m], Z+" #A1 "\n\t" Q_MAC(x0)        \
  "ldd  %A[m], Z+" #A2 "\n\tldd  %B[m], Z+" #A3 "\n\t" Q_MAC(x1)        \
  "ldd  %A[m], Z+" #A4 "\n\tldd  %B[m], Z+" #A5 "\n\t" Q_MAC(x2)
/* fb = (acc & 0x3FFF) ^ 0x2000 (= r' mod 2^14, with r' = acc - 2^13 -
 * (out << 14)) to Z+L, Z+H, and m = bits 29..14 of acc = (D:C:B << 2) >> 8 */
#define Q_OUT(L, H)                                                     \
  "std  Z+" #L ", %A[acc]\n\t"                                          \
  "mov  %B[m], %B[acc]\n\t"                                             \
  "subi %B[m], 0xE0\n\t"          /* + 0x20, then the low 6 bits */      \
  "andi %B[m], 0x3F\n\t"                                                \
  "std  Z+" #H ", %B[m]\n\t"                                            \
  "lsl  %B[acc]\n\t"                                                    \
  "rol  %C[acc]\n\t"                                                    \
  "rol  %D[acc]\n\t"                                                    \
  "lsl  %B[acc]\n\t"                                                    \
  "rol  %C[acc]\n\t"                                                    \
  "rol  %D[acc]\n\t"                                                    \
  "movw %A[m], %C[acc]\n\t"
/* out = sat16(acc >> 14) stored at Y+, the new residual at Z+L, Z+H: in
 * range when bits 31..29 agree, i.e. when (D + 0x20) mod 256 < 0x40 (D
 * the top byte); saturated: fb = 0 and 0x7FFF or 0x8000. */
#define Q_SAT16(L, H)                                                   \
  "mov  %A[m], %D[acc]\n\t"                                             \
  "subi %A[m], 0xE0\n\t"          /* + 0x20 */                           \
  "andi %A[m], 0xC0\n\t"                                                \
  "breq 1f\n\t"                                                         \
  "std  Z+" #L ", %[z]\n\t"        /* saturated: no residual */          \
  "std  Z+" #H ", %[z]\n\t"                                             \
  "ldi  %A[m], 0xFF\n\t"                                                \
  "ldi  %B[m], 0x7F\n\t"                                                \
  "sbrs %D[acc], 7\n\t"                                                 \
  "rjmp 2f\n\t"                                                         \
  "ldi  %A[m], 0x00\n\t"                                                \
  "ldi  %B[m], 0x80\n\t"                                                \
  "rjmp 2f\n"                                                           \
  "1:\n\t"                                                              \
  Q_OUT(L, H)                                                           \
  "\n2:\n\t"                                                            \
  "st   Y+, %A[m]\n\t"                                                  \
  "st   Y+, %B[m]\n\t"
/* The magnetometer's axis I: sat16 then its clipping to +-4095 (the C
 * path: sat16, then mag_clip) is out = acc >> 14 when that is within
 * +-4095, else +-4095 with fb = 0 and bit I of res set.  acc >> 14 is in
 * [-4096, 4095] when bits 31..26 agree ((D + 4) mod 256 < 8), and -4096
 * (0xF000) is the one value there to clip. */
#define Q_SATMAG(L, H, I)                                               \
  "mov  %A[m], %D[acc]\n\t"                                             \
  "subi %A[m], 0xFC\n\t"          /* + 4 */                              \
  "andi %A[m], 0xF8\n\t"                                                \
  "breq 1f\n\t"                                                         \
  "std  Z+" #L ", %[z]\n\t"        /* clipped: no residual */            \
  "std  Z+" #H ", %[z]\n\t"                                             \
  "mov  %A[m], %[res]\n\t"                                              \
  "ori  %A[m], 1 << " #I "\n\t"                                         \
  "mov  %[res], %A[m]\n\t"                                              \
  "ldi  %A[m], 0xFF\n\t"          /* 4095 */                             \
  "ldi  %B[m], 0x0F\n\t"                                                \
  "sbrs %D[acc], 7\n\t"                                                 \
  "rjmp 2f\n\t"                                                         \
  "ldi  %A[m], 0x01\n\t"          /* -4095 */                            \
  "ldi  %B[m], 0xF0\n\t"                                                \
  "rjmp 2f\n"                                                           \
  "1:\n\t"                                                              \
  Q_OUT(L, H)                                                           \
  "cpi  %A[m], 0x00\n\t"                                                \
  "brne 2f\n\t"                                                         \
  "cpi  %B[m], 0xF0\n\t"                                                \
  "brne 2f\n\t"                                                         \
  "std  Z+" #L ", %[z]\n\t"        /* -4096 -> -4095, no residual */     \
  "std  Z+" #H ", %[z]\n\t"                                             \
  "mov  %A[m], %[res]\n\t"                                              \
  "ori  %A[m], 1 << " #I "\n\t"                                         \
  "mov  %[res], %A[m]\n\t"                                              \
  "ldi  %A[m], 0x01\n"                                                  \
  "2:\n\t"                                                              \
  "st   Y+, %A[m]\n\t"                                                  \
  "st   Y+, %B[m]\n\t"
/* the three inputs of the sensor at X+ */
#define Q_LOADX                                                         \
  "ld   %A[x0], X+\n\tld   %B[x0], X+\n\t"                              \
  "ld   %A[x1], X+\n\tld   %B[x1], X+\n\t"                              \
  "ld   %A[x2], X+\n\tld   %B[x2], X+\n\t"
#define Q_ROWS(SAT0, SAT1, SAT2)                                        \
  Q_ROW(18, 19, 20, 21, 31, 32, 0, 1, 2, 3, 4, 5) SAT0                  \
  Q_ROW(22, 23, 24, 25, 33, 34, 6, 7, 8, 9, 10, 11) SAT1                \
  Q_ROW(26, 27, 28, 29, 35, 36, 12, 13, 14, 15, 16, 17) SAT2
/* the magnetometer's overflow code (-4096) on input XN: to label 98 */
#define Q_OVF(XN)                                                       \
  "cpi  %A[" #XN "], 0x00\n\tbrne 5f\n\t"                               \
  "cpi  %B[" #XN "], 0xF0\n\tbrne 5f\n\t"                               \
  "rjmp 98f\n"                                                          \
  "5:\n\t"

/*
 * q14_run(set, in, out, n):
 *   n >= 1: set is the ninedof_cal_t: n records (in[0..9n), out[0..9n)),
 *     each sensor with s[k], or eff[k] when it has temperature terms (the
 *     caller made sure: all three corrected in Q14, no gain terms), the
 *     magnetometer with its rules: the overflow code passes as (-4096,
 *     -4096, -4096), beyond +-4095 is clipped, both with the axis's
 *     residual reset in s[2] and eff[2] (mag_no_residual);
 *   n = 0: set is one sensor's ninedof_cal_sensor_native_t: in[0..3),
 *     out[0..3), int16 saturation only.
 * X walks the inputs, Y the outputs; all loads of a sensor happen before its
 * first store, so in and out may alias.  Never inlined, every register
 * fixed: in and out have registers of their own (the aliasing described
 * at ninedof_kernel_out cannot occur).
 */
#define NINEDOF_KERNEL_FB 1
static __attribute__((noinline)) void q14_run(void *set, const int16_t *in, int16_t *out,
                                              uint16_t n)
{
  ninedof_cal_t *cal = (ninedof_cal_t *)set;
  ninedof_cal_sensor_native_t *s0 = (ninedof_cal_sensor_native_t *)set, *s1 = s0, *s2 = s0;
  uint8_t t = 0;

  if (n) {
    t = cal->temp_sensors;
    s0 = (t & 1) ? &cal->eff[0] : &cal->s[0];
    s1 = (t & 2) ? &cal->eff[1] : &cal->s[1];
    s2 = (t & 4) ? &cal->eff[2] : &cal->s[2];
  }
  {
  register int32_t acc __asm__("r2");
  register uint8_t z __asm__("r6");
  register uint8_t k20 __asm__("r7");
  register ninedof_cal_sensor_native_t *q0 __asm__("r8") = s0;
  register ninedof_cal_sensor_native_t *q1 __asm__("r10") = s1;
  register ninedof_cal_sensor_native_t *q2 __asm__("r12") = s2;
  register uint8_t res __asm__("r14") = 0;
  register uint8_t tt __asm__("r15") = t;
  register int16_t m __asm__("r16");
  register int16_t x0 __asm__("r18");
  register int16_t x1 __asm__("r20");
  register int16_t x2 __asm__("r22");
  register uint16_t cnt __asm__("r24") = n;
  register const int16_t *p __asm__("r26") = in;
  register int16_t *o __asm__("r28") = out;
  register ninedof_cal_sensor_native_t *zs __asm__("r30") = s0;

  __asm__ volatile (
    "clr  %[z]\n\t"
    "ldi  %A[m], 0x20\n\t"
    "mov  %[k20], %A[m]\n\t"
    "clt\n\t"
    "sbiw r24, 0\n\t"
    "brne 10f\n\t"
    "set\n\t"                       /* n = 0: one sensor, then out */
    "adiw r24, 1\n"
    "10:\n\t"                       /* a record */
    "movw r30, %A[q0]\n\t"
    Q_LOADX
    Q_ROWS(Q_SAT16(31, 32), Q_SAT16(33, 34), Q_SAT16(35, 36))
    "brtc 11f\n\t"
    "rjmp 99f\n"
    "11:\n\t"
    "movw r30, %A[q1]\n\t"
    Q_LOADX
    Q_ROWS(Q_SAT16(31, 32), Q_SAT16(33, 34), Q_SAT16(35, 36))
    "movw r30, %A[q2]\n\t"
    Q_LOADX
    Q_OVF(x0) Q_OVF(x1) Q_OVF(x2)
    Q_ROWS(Q_SATMAG(31, 32, 0), Q_SATMAG(33, 34, 1), Q_SATMAG(35, 36, 2))
    "12:\n\t"
    "sbiw r24, 1\n\t"
    "breq 99f\n\t"
    "rjmp 10b\n"
    "98:\n\t"                       /* overflow code: (-4096, -4096, -4096) */
    "ldi  %B[m], 0xF0\n\t"
    "st   Y+, %[z]\n\tst   Y+, %B[m]\n\t"
    "st   Y+, %[z]\n\tst   Y+, %B[m]\n\t"
    "st   Y+, %[z]\n\tst   Y+, %B[m]\n\t"
    "std  Z+31, %[z]\n\tstd  Z+32, %[z]\n\t"
    "std  Z+33, %[z]\n\tstd  Z+34, %[z]\n\t"
    "std  Z+35, %[z]\n\tstd  Z+36, %[z]\n\t"
    "mov  %A[m], %[res]\n\t"
    "ori  %A[m], 7\n\t"
    "mov  %[res], %A[m]\n\t"
    "rjmp 12b\n"
    "99:\n\t"
    "clr  r1\n\t"
    : [acc] "=&r" (acc), [z] "=&r" (z), [k20] "=&r" (k20), [q0] "+r" (q0),
      [q1] "+r" (q1), [q2] "+r" (q2), [res] "+r" (res), [tt] "+r" (tt), [m] "=&a" (m),
      [x0] "=&a" (x0), [x1] "=&a" (x1), [x2] "=&a" (x2), [n] "+w" (cnt),
      [p] "+x" (p), [o] "+y" (o), [zs] "+z" (zs)
    :
    : "r0", "r1", "memory");
  (void)acc; (void)z; (void)k20; (void)q0; (void)q1; (void)m;
  (void)x0; (void)x1; (void)x2; (void)cnt; (void)p; (void)o; (void)zs;
  if (res) {              /* the magnetometer's other residuals (s[2] / eff[2]) */
    uint16_t d = (uint16_t)(offsetof(ninedof_cal_t, eff) - offsetof(ninedof_cal_t, s));
    ninedof_cal_sensor_native_t *other = (ninedof_cal_sensor_native_t *)(void *)
      ((uint8_t *)q2 + (uint16_t)((tt & 4) ? (uint16_t)0 - d : d));
    uint8_t i;
    for (i = 0; i < 3; i++)
      if (res & (1u << i))
        other->fb[i] = 0;
  }
  }
}
#else
/* c + 2^13 + A raw per row (Q14), wrapping like the AVR code */
static NINEDOF_ALWAYS_INLINE void sensor_q14_acc(const ninedof_cal_sensor_native_t *s,
                                                 const int16_t *in, int32_t *acc)
{
  int16_t x0 = in[0], x1 = in[1], x2 = in[2];
  uint8_t r;

  for (r = 0; r < 3; r++) {
    const int16_t *a = s->a + 3 * r;
    uint32_t u = (uint32_t)s->c[r] + (uint32_t)ROUND_Q14;
    u += (uint32_t)((int32_t)a[0] * x0);
    u += (uint32_t)((int32_t)a[1] * x1);
    u += (uint32_t)((int32_t)a[2] * x2);
    acc[r] = (int32_t)u;
  }
}
#endif

/*
 * Rounding with error feedback (noise shaping), per axis: with x the exact
 * value (Q14 before the rounding) and r the axis's residual (Q14, in
 * [-2^13, 2^13): what the last rounding of this axis dropped),
 *   y = floor(x + r + 1/2),   r' = x + r - y.
 * So |y - x| = |r - r'| < 1 LSB on every sample, and the sum of the outputs
 * follows the sum of the exact values within 1 LSB: the mean is unbiased
 * (plain rounding of a still board's samples drops the same fraction every
 * time; ninedof_cal.h).  u = x + 2^13 is the kernel's accumulator, so
 * y = (u + r) >> 14 and r' = ((u + r) & 0x3FFF) - 2^13.  A saturated
 * sample does not feed the residual: r' = 0.
 */
static NINEDOF_ALWAYS_INLINE int16_t shape_q14(int32_t u, uint16_t *fb)
{
  /* + r, with r = (fb ^ 0x2000) - 0x2000 (fb = r mod 2^14) */
  uint32_t v = (uint32_t)u + (uint32_t)(*fb ^ 0x2000u) - 0x2000UL;
  uint8_t top = (uint8_t)(v >> 24) & 0xE0;             /* bits 31..29 */

  if (top == 0x00 || top == 0xE0) {
    uint16_t hi = (uint16_t)(v >> 16);
    uint16_t lo = (uint16_t)v;
    *fb = (uint16_t)((lo & 0x3FFFu) ^ 0x2000u);          /* r' + 2^13, as r' mod 2^14 */
    return (int16_t)(uint16_t)((uint16_t)(hi << 2) | (uint8_t)((uint8_t)(lo >> 8) >> 6));
  }
  *fb = 0;
  return (top & 0x80) ? (int16_t)INT16_MIN : (int16_t)INT16_MAX;
}

#ifndef NINEDOF_KERNEL_FB
/* One sensor in Q14 with the rounding above (the residuals in s->fb).
 * All loads happen before the first store, so in and out may alias. */
static NINEDOF_ALWAYS_INLINE void sensor_q14(ninedof_cal_sensor_native_t *s,
                                             const int16_t *in, int16_t *out)
{
  int32_t acc[3];

  sensor_q14_acc(s, in, acc);
  out[0] = shape_q14(acc[0], &s->fb[0]);
  out[1] = shape_q14(acc[1], &s->fb[1]);
  out[2] = shape_q14(acc[2], &s->fb[2]);
}
#else
static NINEDOF_ALWAYS_INLINE void sensor_q14(ninedof_cal_sensor_native_t *s,
                                             const int16_t *in, int16_t *out)
{
  q14_run(s, in, out, 0);
}
#endif

static int16_t sat16(int32_t v)
{
  if (v > INT16_MAX)
    return INT16_MAX;
  if (v < INT16_MIN)
    return INT16_MIN;
  return (int16_t)v;
}

/*
 * A sensor stored with a shift below 14 (the host never sends one, but the
 * format allows it): rescale to Q14 when that is exact and the Q14
 * accumulator cannot overflow -- always so for a valid set -- and use the
 * kernel (with its error feedback); otherwise evaluate the formula at the
 * set's own shift with plain rounding half up (the residuals stay 0),
 * wrapping like int32 hardware (only reachable for sets that were never
 * validated).
 */
static __attribute__((noinline)) void sensor_other_shift(
    ninedof_cal_sensor_native_t *s, const int16_t *in, int16_t *out)
{
  uint8_t up = (uint8_t)(NINEDOF_SHIFT_MAX - s->shift);
  int16_t lim = (int16_t)(32767 >> up);
  ninedof_cal_sensor_native_t q;
  int16_t *qa = q.a;
  int32_t *qc = q.c;
  uint8_t i, q14 = 1;

  for (i = 0; i < 9; i++) {
    if (s->a[i] > lim || s->a[i] < -lim - 1)
      q14 = 0;
    qa[i] = (int16_t)(uint16_t)((uint16_t)s->a[i] << up);
  }
  for (i = 0; i < 3 && q14; i++) {
    uint32_t bound = 0;
    uint8_t j;
    if (s->c[i] > (1L << 26) >> up || s->c[i] < -((1L << 26) >> up))
      q14 = 0;
    qc[i] = (int32_t)((uint32_t)s->c[i] << up);
    for (j = 0; j < 3; j++) {           /* sum |a| * 32768 + |c| + 2^13 < 2^31 */
      int16_t x = qa[3 * i + j];
      bound += (uint32_t)(x < 0 ? -(int32_t)x : x);
    }
    if (bound * 32768UL + (1UL << 26) + (uint32_t)ROUND_Q14 >= 0x80000000UL)
      q14 = 0;
  }
  if (q14) {
    q.shift = NINEDOF_SHIFT_MAX;
    memcpy(q.fb, s->fb, sizeof(q.fb));
    sensor_q14(&q, in, out);
    memcpy(s->fb, q.fb, sizeof(q.fb));
  } else {                              /* plain rounding, no residual */
    int16_t x0 = in[0], x1 = in[1], x2 = in[2];
    int16_t y[3];
    for (i = 0; i < 3; i++) {
      const int16_t *a = s->a + 3 * i;
      uint32_t u = (uint32_t)s->c[i] + (1UL << (s->shift - 1));
      u += (uint32_t)((int32_t)a[0] * x0);
      u += (uint32_t)((int32_t)a[1] * x1);
      u += (uint32_t)((int32_t)a[2] * x2);
      y[i] = sat16((int32_t)u >> s->shift);
    }
    out[0] = y[0]; out[1] = y[1]; out[2] = y[2];
    s->fb[0] = s->fb[1] = s->fb[2] = 0;
  }
}

/*
 * The gain term of the temperature path, t ~ p G (Q14), with G in Q30
 * (ninedof_cal.h): p = ph 2^16 + pl, G = gh 2^16 + gl (ph, gh signed,
 * pl, gl unsigned 16 bit) and
 *   t = floor((ph gh 2^16 + ph gl + pl gh) / 2^14)
 * i.e. p G / 2^30 without pl gl / 2^30 (in [0, 4)) and with the floor:
 * p G / 2^30 - 5 < t <= p G / 2^30.  The sum is exact (|ph| <= 2^15 and
 * |gh| <= 2^12: |ph gh 2^16| <= 2^43) and |t| < 2^30.
 */
#if defined(__AVR__) && !defined(NINEDOF_PORTABLE_KERNEL)
/* Twelve 8 x 8 products into a 48-bit sum (t0..t5), then bits 14..45.
 * MULSU needs r16..r23: the four halves of p and g take all eight.  A
 * signed product's sign (C after MULS/MULSU) is subtracted from the bytes
 * above it before it is added (as in K_MAC). */
#define G_SP(X, Y, LO, HI, SUBS, ADCS)                                  \
  "mulsu " X ", " Y "\n\t" SUBS                                         \
  "add " LO ", r0\n\tadc " HI ", r1\n\t" ADCS
#define G_UP(X, Y, LO, HI, ADCS)                                        \
  "mul " X ", " Y "\n\t"                                                 \
  "add " LO ", r0\n\tadc " HI ", r1\n\t" ADCS
#define G_SBC(B) "sbc " B ", %[z]\n\t"
#define G_ADC(B) "adc " B ", %[z]\n\t"
static NINEDOF_TEMP_INLINE int32_t gain_term(int32_t p, int32_t g)
{
  uint16_t ph = (uint16_t)((uint32_t)p >> 16), pl = (uint16_t)p;
  uint16_t gh = (uint16_t)((uint32_t)g >> 16), gl = (uint16_t)g;
  uint32_t t;             /* bytes 2..5 of the sum, then the result */
  uint16_t t01;           /* bytes 0, 1 */
  uint8_t z;

  __asm__ (
    "clr %[z]\n\t"
    "mul %A[ph], %A[gh]\n\tmovw %A[t], r0\n\t"          /* ph0 gh0 @2 */
    "muls %B[ph], %B[gh]\n\tmovw %C[t], r0\n\t"         /* ph1 gh1 @4 */
    "mul %A[ph], %A[gl]\n\tmovw %A[t01], r0\n\t"          /* ph0 gl0 @0 */
    G_SP("%B[ph]", "%A[gh]", "%B[t]", "%C[t]", G_SBC("%D[t]"), G_ADC("%D[t]"))     /* ph1 gh0 @3 */
    G_SP("%B[gh]", "%A[ph]", "%B[t]", "%C[t]", G_SBC("%D[t]"), G_ADC("%D[t]"))     /* gh1 ph0 @3 */
    G_SP("%B[ph]", "%B[gl]", "%A[t]", "%B[t]", G_SBC("%C[t]") G_SBC("%D[t]"), G_ADC("%C[t]") G_ADC("%D[t]"))   /* ph1 gl1 @2 */
    G_SP("%B[gh]", "%B[pl]", "%A[t]", "%B[t]", G_SBC("%C[t]") G_SBC("%D[t]"), G_ADC("%C[t]") G_ADC("%D[t]"))   /* gh1 pl1 @2 */
    G_SP("%B[ph]", "%A[gl]", "%B[t01]", "%A[t]", G_SBC("%B[t]") G_SBC("%C[t]") G_SBC("%D[t]"), G_ADC("%B[t]") G_ADC("%C[t]") G_ADC("%D[t]"))   /* ph1 gl0 @1 */
    G_SP("%B[gh]", "%A[pl]", "%B[t01]", "%A[t]", G_SBC("%B[t]") G_SBC("%C[t]") G_SBC("%D[t]"), G_ADC("%B[t]") G_ADC("%C[t]") G_ADC("%D[t]"))   /* gh1 pl0 @1 */
    G_UP("%A[ph]", "%B[gl]", "%B[t01]", "%A[t]", G_ADC("%B[t]") G_ADC("%C[t]") G_ADC("%D[t]"))   /* ph0 gl1 @1 */
    G_UP("%B[pl]", "%A[gh]", "%B[t01]", "%A[t]", G_ADC("%B[t]") G_ADC("%C[t]") G_ADC("%D[t]"))   /* pl1 gh0 @1 */
    G_UP("%A[pl]", "%A[gh]", "%A[t01]", "%B[t01]", G_ADC("%A[t]") G_ADC("%B[t]") G_ADC("%C[t]") G_ADC("%D[t]"))   /* pl0 gh0 @0 */
    /* bits 14..45: bytes 1..5 shifted left twice, bytes 2..5 */
    "lsl %B[t01]\n\trol %A[t]\n\trol %B[t]\n\trol %C[t]\n\trol %D[t]\n\t"
    "lsl %B[t01]\n\trol %A[t]\n\trol %B[t]\n\trol %C[t]\n\trol %D[t]\n\t"
    "clr r1\n\t"
    : [t] "=&r" (t), [t01] "=&r" (t01), [z] "=&r" (z)
    : [ph] "a" (ph), [pl] "a" (pl), [gh] "a" (gh), [gl] "a" (gl)
    : "r0", "r1");
  return (int32_t)t;
}
#else
static NINEDOF_TEMP_INLINE int32_t gain_term(int32_t p, int32_t g)
{
  int16_t ph = (int16_t)((uint32_t)p >> 16), gh = (int16_t)((uint32_t)g >> 16);
  uint16_t pl = (uint16_t)p, gl = (uint16_t)g;
  int64_t sum = (int64_t)((int32_t)ph * gh) * 65536 + (int64_t)ph * gl + (int64_t)gh * pl;

  return (int32_t)(sum >> 14);
}
#endif

/* shape_q14 for the gain path: the same rounding with error feedback, the
 * stored residual kept within [-(2^13 - E), 2^13 - E] (resid_margin), so
 * |out - (u - 2^13) / 2^14| <= 1 - E / 2^14 (ninedof_cal.h). */
static NINEDOF_TEMP_INLINE int16_t shape_q14_temp(int32_t u, uint16_t *fb)
{
  uint32_t v = (uint32_t)u + (uint32_t)(*fb ^ 0x2000u) - 0x2000UL;
  uint8_t top = (uint8_t)(v >> 24) & 0xE0;             /* bits 31..29 */

  if (top == 0x00 || top == 0xE0) {
    *fb = resid_margin((uint16_t)(((uint16_t)v & 0x3FFFu) ^ 0x2000u));   /* r' mod 2^14 */
    return (int16_t)(uint16_t)((v << 2) >> 16);          /* bits 29..14 */
  }
  *fb = 0;
  return (top & 0x80) ? (int16_t)INT16_MIN : (int16_t)INT16_MAX;
}

/* A sensor with temperature gain terms (shift 14, ninedof_cal.h):
 * out = sat((p + t + c + O + 2^13 + r) >> 14), t = gain_term(p, G), with
 * the error feedback of shape_q14_temp, wrapping like int32 hardware (only
 * sets that were never validated can wrap). */
static __attribute__((noinline)) void sensor_temp(ninedof_cal_t *cal, uint8_t k,
                                                  const int16_t *in, int16_t *out)
{
  ninedof_cal_sensor_native_t *s = &cal->eff[k];           /* c + O, residuals */
  const int32_t *g = cal->tg[k];
  int32_t acc[3];
  uint8_t r;

  sensor_q14_acc(s, in, acc);          /* loads done: in and out may alias */
  for (r = 0; r < 3; r++) {
    uint32_t u = (uint32_t)acc[r];
    int32_t p = (int32_t)(u - (uint32_t)s->c[r] - (uint32_t)ROUND_Q14);   /* A raw */
    u += (uint32_t)gain_term(p, g[r]);
    out[r] = shape_q14_temp((int32_t)u, &s->fb[r]);
  }
}

/* Sensor k of one record; returns 0 when the sensor passes raw. */
static NINEDOF_ALWAYS_INLINE uint8_t correct_sensor(ninedof_cal_t *cal, uint8_t k,
                                                    const int16_t *in, int16_t *out)
{
  ninedof_cal_sensor_native_t *s = &cal->s[k];

  if ((cal->sensors & cal->temp_sensors & (1u << k)) && s->shift == NINEDOF_SHIFT_MAX) {
    if (cal->gain_zero & (1u << k))
      sensor_q14(&cal->eff[k], in, out);      /* offsets only: the kernel with c + O */
    else
      sensor_temp(cal, k, in, out);
    return 1;
  }
  if ((cal->sensors & (1u << k)) && s->shift == NINEDOF_SHIFT_MAX) {
    sensor_q14(s, in, out);
    return 1;
  }
  if ((cal->sensors & (1u << k)) &&
      s->shift >= NINEDOF_SHIFT_MIN && s->shift < NINEDOF_SHIFT_MAX) {
    sensor_other_shift(s, in, out);
    return 1;
  }
  if (in != out) {
    out[0] = in[0]; out[1] = in[1]; out[2] = in[2];
  }
  return 0;
}

/* The magnetometer's overflow code and its clipping to +-4095 keep their
 * values and do not feed the residual of the axis (reset to 0). */
static NINEDOF_ALWAYS_INLINE void mag_no_residual(ninedof_cal_t *cal, uint8_t i)
{
  cal->s[NINEDOF_SENSOR_MAG].fb[i] = 0;
  cal->eff[NINEDOF_SENSOR_MAG].fb[i] = 0;
}

/* One record, sensor by sensor: every set (the AVR's common case takes
 * q14_run's loop instead, ninedof_correct_block) */
static __attribute__((noinline)) void correct_record(ninedof_cal_t *cal,
                                                    const int16_t *raw, int16_t *out)
{

  correct_sensor(cal, NINEDOF_SENSOR_ACCEL, raw, out);
  correct_sensor(cal, NINEDOF_SENSOR_GYRO, raw + 3, out + 3);
  raw += 6;
  out += 6;
  if ((cal->sensors & (1u << NINEDOF_SENSOR_MAG)) &&
      (raw[0] == NINEDOF_MAG_OVERFLOW || raw[1] == NINEDOF_MAG_OVERFLOW ||
       raw[2] == NINEDOF_MAG_OVERFLOW)) {
    out[0] = out[1] = out[2] = NINEDOF_MAG_OVERFLOW;
    mag_no_residual(cal, 0);
    mag_no_residual(cal, 1);
    mag_no_residual(cal, 2);
  } else if (correct_sensor(cal, NINEDOF_SENSOR_MAG, raw, out)) {
    uint8_t i;
    for (i = 0; i < 3; i++) {
      int16_t v = out[i];
      if ((uint16_t)(v + 4095) > 8190u) {      /* beyond +-4095 */
        out[i] = v < 0 ? -4095 : 4095;
        mag_no_residual(cal, i);
      }
    }
  }
}

/* n records, sensor by sensor */
static __attribute__((noinline)) void correct_records(ninedof_cal_t *cal, const int16_t *raw,
                                                      int16_t *out, uint16_t n)
{
  while (n--) {
    correct_record(cal, raw, out);
    raw += 9;
    out += 9;
  }
}

void ninedof_correct_block(ninedof_cal_t *cal, const int16_t *raw,
                           int16_t *out, uint16_t n)
{
#ifdef NINEDOF_KERNEL_FB
  /* The common case, the kernel on all nine axes (each sensor corrected in
   * Q14 without gain terms: with s[k], or eff[k] with temperature offsets,
   * as correct_sensor chooses), in one asm loop. */
  if ((cal->sensors & SENSOR_BITS) == SENSOR_BITS &&
      !(cal->temp_sensors & ~cal->gain_zero & SENSOR_BITS) &&
      cal->s[0].shift == NINEDOF_SHIFT_MAX && cal->s[1].shift == NINEDOF_SHIFT_MAX &&
      cal->s[2].shift == NINEDOF_SHIFT_MAX && n) {
    q14_run(cal, raw, out, n);
    return;
  }
#endif
  correct_records(cal, raw, out, n);
}

void ninedof_correct(ninedof_cal_t *cal, const int16_t raw[9], int16_t out[9])
{
  ninedof_correct_block(cal, raw, out, 1);
}

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

static uint8_t handle_query(ninedof_calrx_t *rx, const ninedof_cal_query_msg_t *m,
                            uint8_t *reply, uint8_t *reply_type)
{
  ninedof_cal_report_msg_t *rep = (ninedof_cal_report_msg_t *)reply;
  uint8_t offset = nxp_get_u8(&m->offset);
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
    if (len < sizeof(ninedof_cal_query_msg_t))
      return 0;
    return handle_query(rx, (const ninedof_cal_query_msg_t *)payload, reply, reply_type);
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
  /* slot 0 spans the old slot 1: after either old slot, write slot 1 */
  *next_slot = (uint8_t)(used == 1 ? 0 : 1);
  *next_generation = (uint16_t)(gen[used] + 1);
  return used;
}
