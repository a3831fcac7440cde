/*
 * ninedof_calshared.h -- private to ninedof_calset.c (validation) and
 * ninedof_correct.c (the correction): what both use, defined once.  The
 * temperature terms G and O at dT are computed here, so validation bounds
 * exactly the terms the correction applies.
 *
 * The functions are static: in the nesC build, one translation unit
 * (NineDofApp.h includes both .c files), the include guard keeps one
 * definition; the host and avr-gcc builds compile each file on its own
 * and each gets its copy.  Signed right shifts are arithmetic on gcc and
 * avr-gcc (documented GCC behaviour), which the rounding relies on.
 */
#ifndef NINEDOF_CALSHARED_H
#define NINEDOF_CALSHARED_H

#include "ninedof_calset.h"

#define SENSOR_BITS ((1u << NINEDOF_SENSORS) - 1u)
#define ROUND_Q14 (1L << (NINEDOF_SHIFT_MAX - 1))

/* round(v / 2^n), half up (arithmetic shift); |v| < 2^30, n <= 30 */
static int32_t round_shift(int32_t v, uint8_t n)
{
  if (n == 0)
    return v;
  return (v + ((int32_t)1 << (n - 1))) >> n;
}

/* G = g dT / 2^gshift in Q30 of row i at dT (|dT| <= 32767), rounded half
 * up; exact for gshift <= 30.  Saturated at +-2^28 (twice the limit, only
 * sets that fail validation get there) so the correction stays defined.
 * Not inlined: with its two callers in one file gcc -Os kept it a call, and
 * so it stays in the builds that compile each file on its own (the cycles
 * of validation and of ninedof_cal_set_temp unchanged). */
#define GAIN_SAT_Q30 ((int32_t)1 << 28)
static __attribute__((noinline)) int32_t temp_gain(const ninedof_cal_temp_native_t *t,
                                                   uint8_t i, int32_t dt)
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

#endif /* NINEDOF_CALSHARED_H */
