/*
 * ninedof_clock.c -- see ninedof_clock.h.
 */
#include "ninedof_clock.h"

enum {
  /* Bresenham denominator: the rate is per 125 periods, in 1/16 tick */
  CLOCK_DEN = NINEDOF_CLOCK_FRAC * NINEDOF_RATE_HZ,
  /* CPU cycles per alarm tick: timer 1 prescaler 8, TransformAlarmC / 32 */
  ALARM_CPU_DIV = 256,
  CLOCK_XTAL_LOG2 = 10,          /* NINEDOF_XTAL_HZ = 2^10 */
};

/* What the sum of (reading - grid) over one second is when every expiry
 * is on time and the grid sits on a crystal tick: the readings are the
 * floors of 1024 * i / 125, i = 0..124, and for coprime a, b the floors of
 * a * i / b (i < b) add up to (a - 1) * (b - 1) / 2. */
#define CLOCK_IDEAL_SUM ((int32_t)((NINEDOF_XTAL_HZ - 1) * (NINEDOF_RATE_HZ - 1) / 2))
/* 1/125 crystal tick -> 1/16 alarm tick at the nominal rate: 31250 * 16 /
 * (125 * 1024) = 4000 / 1024 (a loop gain: the nominal rate is enough) */
#define CLOCK_ERR_NUM ((int32_t)(NINEDOF_ALARM_HZ * NINEDOF_CLOCK_FRAC / NINEDOF_RATE_HZ))

/* The readings spread evenly over a crystal tick only if the crystal rate
 * (a power of two) and the sample rate (odd) are coprime. */
typedef char ninedof_clock_coprime[((NINEDOF_RATE_HZ & 1) &&
                                    NINEDOF_XTAL_HZ == (1UL << CLOCK_XTAL_LOG2)) ? 1 : -1];

/* floor(x / 2^n) for negative x too, without relying on >> of negatives */
static int32_t floor_shift(int32_t x, uint8_t n)
{
  return x >= 0 ? x >> n : ~(~x >> n);
}

static int32_t clamp_rate(int32_t rate)
{
  if (rate < (int32_t)NINEDOF_CLOCK_MIN)
    return (int32_t)NINEDOF_CLOCK_MIN;
  if (rate > (int32_t)NINEDOF_CLOCK_MAX)
    return (int32_t)NINEDOF_CLOCK_MAX;
  return rate;
}

/* New rate (clamped); base and step follow without a division: the rate
 * moves by much less than one period per update once locked. */
static void set_rate(ninedof_clock_t *c, int32_t rate)
{
  int32_t step;
  rate = clamp_rate(rate);
  step = (int32_t)c->step + (rate - (int32_t)c->rate);
  c->rate = (uint32_t)rate;
  while (step >= CLOCK_DEN) {
    step -= CLOCK_DEN;
    c->base++;
  }
  while (step < 0) {
    step += CLOCK_DEN;
    c->base--;
  }
  c->step = (uint16_t)step;
}

void ninedof_clock_init(ninedof_clock_t *c, uint16_t cycles_per_jiffy)
{
  uint32_t rate = NINEDOF_CLOCK_NOMINAL;
  if (cycles_per_jiffy != 0)        /* CPU Hz = cycles * 32768; alarm = CPU / 256 */
    rate = (uint32_t)cycles_per_jiffy * (32768UL / ALARM_CPU_DIV) * NINEDOF_CLOCK_FRAC;
  if (rate < NINEDOF_CLOCK_MIN || rate > NINEDOF_CLOCK_MAX)
    rate = NINEDOF_CLOCK_NOMINAL;                /* not an RC oscillator's error */
  c->rate = rate;
  c->base = (uint16_t)(rate / CLOCK_DEN);
  c->step = (uint16_t)(rate % CLOCK_DEN);
  c->integ = (int32_t)c->rate << NINEDOF_CLOCK_KI_SHIFT;
  c->grid = 0;
  c->sum = 0;
  c->error = 0;
  c->acc = 0;
  c->last = c->base;
  c->owed = 0;
  c->count = 0;
  c->synced = 0;
  c->stage = 0;
  c->resyncs = 0;
}

uint16_t ninedof_clock_first(const ninedof_clock_t *c)
{
  return c->last;
}

/* End of a second: mean phase error -> new rate. */
static void update(ninedof_clock_t *c)
{
  int32_t e = c->sum - CLOCK_IDEAL_SUM, e16;
  const int32_t lo = (int32_t)NINEDOF_CLOCK_MIN << NINEDOF_CLOCK_KI_SHIFT;
  const int32_t hi = (int32_t)NINEDOF_CLOCK_MAX << NINEDOF_CLOCK_KI_SHIFT;

  c->grid += NINEDOF_XTAL_HZ;
  c->sum = 0;
  c->count = 0;
  if (e > NINEDOF_CLOCK_RESYNC || e < -NINEDOF_CLOCK_RESYNC) {
    c->synced = 0;                 /* the next expiry starts a new grid */
    c->stage = 0;
    c->resyncs++;
    return;
  }
  e16 = floor_shift(e * CLOCK_ERR_NUM, CLOCK_XTAL_LOG2);  /* late > 0: slow down */
  if (c->stage == 0) {
    /* first second on a new grid: its mean phase holds the grid's offset
     * (the first reading is a floor: up to a tick) as well as the rate
     * error; the next second at the same rate tells them apart */
    c->error = e;
    c->stage = 1;
    return;
  }
  if (c->stage == 1) {
    /* the mean phase moved by the whole rate error over one second:
     * correct the frequency at once (to about 10 ppm), the phase by the
     * loop from here on */
    int32_t slope16 = floor_shift((e - c->error) * CLOCK_ERR_NUM, CLOCK_XTAL_LOG2);
    c->integ = clamp_rate((int32_t)c->rate - slope16) << NINEDOF_CLOCK_KI_SHIFT;
    c->stage = 2;
  }
  c->error = e;
  c->integ -= e16;                 /* integral gain 1 / 2^KI_SHIFT, exact */
  if (c->integ < lo)
    c->integ = lo;
  if (c->integ > hi)
    c->integ = hi;
  set_rate(c, (c->integ >> NINEDOF_CLOCK_KI_SHIFT) - floor_shift(e16, NINEDOF_CLOCK_KP_SHIFT));
}

uint16_t ninedof_clock_next(ninedof_clock_t *c, uint32_t xtal_now)
{
  int16_t want, p;

  if (!c->synced) {
    c->synced = 1;
    c->grid = xtal_now;
    c->sum = 0;
    c->count = 0;
  }
  c->sum += (int32_t)(xtal_now - c->grid);          /* wrap-safe */
  if (++c->count == NINEDOF_RATE_HZ)
    update(c);

  want = (int16_t)(c->base + c->owed);
  c->acc += c->step;
  if (c->acc >= CLOCK_DEN) {
    c->acc -= CLOCK_DEN;
    want++;
  }
  p = want;                                        /* at most one tick from the last */
  if (p > (int16_t)c->last + 1)
    p = (int16_t)(c->last + 1);
  else if (p < (int16_t)c->last - 1)
    p = (int16_t)(c->last - 1);
  c->owed = (int16_t)(want - p);
  c->last = (uint16_t)p;
  return (uint16_t)p;
}

uint16_t ninedof_clock_arm(uint32_t target, uint32_t now, uint16_t period, uint16_t wrap)
{
  int32_t ahead = (int32_t)(target - now);                /* wrap-safe */

  if (ahead > (int32_t)period)
    ahead -= wrap;                   /* the counter lags: an overflow not yet counted */
  if (ahead < NINEDOF_ALARM_MIN_TICKS)
    return NINEDOF_ALARM_MIN_TICKS;  /* late: at once, not a timer wrap later */
  if (ahead > (int32_t)period)
    return period;
  return (uint16_t)ahead;
}
