/*
 * ninedof_correct.c -- the fixed-point correction (API and proofs:
 * ninedof_correct.h): the temperature terms in force, the kernels with
 * their rounding and error feedback, record by record.  The AVR assembly
 * kernels are in ninedof_correct_avr.h, included below.
 *
 * Plain C99 without floats, compiled as ninedof_calset.c is (the nesC
 * firmware, the host library, avr-gcc for simavr).
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
#include "ninedof_correct.h"
#include "ninedof_calshared.h"

/* ---------------------------------------------------------------------- */
/* Temperature terms                                                       */
/* ---------------------------------------------------------------------- */
#if defined(__GNUC__)
#define NINEDOF_TEMP_INLINE inline __attribute__((always_inline))
#else
#define NINEDOF_TEMP_INLINE inline
#endif

/* dT of sensor k at raw temperature T: clamp(T, t_lo, t_hi) - t_ref (int32) */
static int32_t temp_delta(const ninedof_cal_temp_native_t *t, int16_t raw)
{
  int16_t c = raw < t->t_lo ? t->t_lo : raw > t->t_hi ? t->t_hi : raw;
  return (int32_t)c - t->t_ref;
}

/* A residual stored as fb (r mod 2^14, ninedof_calset.h) limited to
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

/* ---------------------------------------------------------------------- */
/* Correction                                                              */
/* ---------------------------------------------------------------------- */
#if defined(__GNUC__)
#define NINEDOF_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define NINEDOF_ALWAYS_INLINE inline
#endif


#if defined(__AVR__) && !defined(NINEDOF_PORTABLE_KERNEL)
#include "ninedof_correct_avr.h"   /* sensor_q14_acc, q14_run, gain_term */
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
 * time; ninedof_correct.h).  u = x + 2^13 is the kernel's accumulator, so
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
 * (ninedof_correct.h): p = ph 2^16 + pl, G = gh 2^16 + gl (ph, gh signed,
 * pl, gl unsigned 16 bit) and
 *   t = floor((ph gh 2^16 + ph gl + pl gh) / 2^14)
 * i.e. p G / 2^30 without pl gl / 2^30 (in [0, 4)) and with the floor:
 * p G / 2^30 - 5 < t <= p G / 2^30.  The sum is exact (|ph| <= 2^15 and
 * |gh| <= 2^12: |ph gh 2^16| <= 2^43) and |t| < 2^30.
 */
#if !defined(__AVR__) || defined(NINEDOF_PORTABLE_KERNEL)
/* (the AVR's: ninedof_correct_avr.h) */
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
 * |out - (u - 2^13) / 2^14| <= 1 - E / 2^14 (ninedof_correct.h). */
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

/* A sensor with temperature gain terms (shift 14, ninedof_correct.h):
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
