/*
 * ninedof_clock.h -- the 125 Hz sampling period, disciplined to the 32768 Hz
 * crystal.
 *
 * The iris CPU runs on the ATmega1281's internal RC oscillator (nominally
 * 8 MHz; MeasureClockC measures it against the crystal at boot and nothing
 * in TinyOS corrects the timers for it).  The sampling alarm
 * (Alarm32khz32C: timer 1 at CPU / 8, divided by 32) therefore ticks at
 * CPU / 256, nominally 31250 Hz, but really as fast as the RC oscillator
 * happens to run: off by up to a few percent, and drifting with temperature
 * and supply voltage.  The crystal (timer 2, LocalTime<TMilli>: 32768 Hz / 32
 * = 1024 Hz) is accurate to tens of ppm.
 *
 * At every alarm expiry the app hands the crystal time to
 * ninedof_clock_next() and arms the alarm with the period it returns:
 *  - Measurement: over each group of NINEDOF_RATE_HZ periods (one second),
 *    the sum of (crystal time - ideal crystal time of that period).  The
 *    ideal times are 1024 / 125 = 8.192 crystal ticks apart, so the 125
 *    readings fall at 125 evenly spread fractions of a crystal tick and
 *    their sum resolves the mean phase to 1/125 tick (7.8 us), although
 *    each reading is only whole milliseconds.
 *  - Loop: a proportional-integral loop (gains 1/2 and 1/16, per second)
 *    sets the rate, alarm ticks per crystal second, in 1/16 tick.  It
 *    starts from MeasureClockC's boot measurement (0.4 % steps); the
 *    change of the mean phase between the first two seconds gives the
 *    rate error at once (about 10 ppm), the loop does the rest.  It
 *    keeps the phase error bounded, so over any long time the number of
 *    periods is 125 per crystal second exactly: the long-run rate is as
 *    exact as the crystal.
 *  - Periods: rate / 125 alarm ticks, the fraction spread by a Bresenham
 *    accumulator, so the periods of one second take two adjacent values.
 *    A change of rate moves a period by at most one tick from the one
 *    before (what that limit holds back is owed and paid next).
 * Cost on the ATmega1281: about 170 cycles per period, 500 for the loop
 * update once per second (bench/bench_cycles.py).
 */
#ifndef NINEDOF_CLOCK_H
#define NINEDOF_CLOCK_H

#include <stdint.h>
#include "NineDofMsg.h"

/* The sampling alarm's nominal rate: Alarm32khz32C on iris counts CPU / 256 */
#ifndef NINEDOF_ALARM_HZ
#define NINEDOF_ALARM_HZ 31250UL
#endif
/* Nominal period in alarm ticks (250 = 8 ms at 8.000 MHz) */
#define NINEDOF_PERIOD_TICKS ((uint16_t)(NINEDOF_ALARM_HZ / NINEDOF_RATE_HZ))

/* LocalTime<TMilli> on iris: the 32768 Hz crystal / 32 (timer 2) */
#define NINEDOF_XTAL_HZ 1024UL

enum {
  NINEDOF_CLOCK_FRAC = 16,               /* rate resolution: 1/16 alarm tick */
  NINEDOF_CLOCK_KP_SHIFT = 1,            /* proportional gain 1/2 */
  NINEDOF_CLOCK_KI_SHIFT = 4,            /* integral gain 1/16 */
};
/* rate (alarm ticks per crystal second, x16): nominal and the range the
 * loop may use (the RC oscillator's factory calibration is +-10 %) */
#define NINEDOF_CLOCK_NOMINAL (NINEDOF_ALARM_HZ * NINEDOF_CLOCK_FRAC)
#define NINEDOF_CLOCK_MIN (NINEDOF_CLOCK_NOMINAL / 10UL * 9UL)
#define NINEDOF_CLOCK_MAX (NINEDOF_CLOCK_NOMINAL / 10UL * 11UL)
/* A mean phase error beyond one second (the alarm interrupt stalled, or
 * the crystal counter jumped): restart the phase reference, keep the rate. */
#define NINEDOF_CLOCK_RESYNC ((int32_t)NINEDOF_XTAL_HZ * NINEDOF_RATE_HZ)

typedef struct {
  int32_t integ;       /* integrator: rate << NINEDOF_CLOCK_KI_SHIFT */
  uint32_t rate;       /* alarm ticks per crystal second, x NINEDOF_CLOCK_FRAC */
  uint32_t grid;       /* ideal crystal time of this second's first period */
  int32_t sum;         /* sum of (crystal time - grid) over this second */
  int32_t error;       /* last second's mean phase error, 1/125 crystal tick
                        * (> 0 = late), against a grid on the first reading's tick */
  uint16_t base;       /* rate / (16 * 125): the shorter period */
  uint16_t step;       /* rate % (16 * 125): Bresenham increment */
  uint16_t acc;        /* Bresenham accumulator, < 16 * 125 */
  uint16_t last;       /* the period handed out last */
  int16_t owed;        /* ticks held back by the one-tick limit */
  uint8_t count;       /* periods measured in this second */
  uint8_t synced;      /* grid set (0 until the first expiry) */
  uint8_t stage;       /* seconds measured on this grid: 0, 1, 2 = locked */
  uint16_t resyncs;    /* times the phase reference was restarted */
} ninedof_clock_t;

/* Start from MeasureClockC's CPU cycles per 1/32768 s (Atm128Calibrate.
 * cyclesPerJiffy: 244 at 8 MHz; 0 = unknown, nominal). */
void ninedof_clock_init(ninedof_clock_t *c, uint16_t cycles_per_jiffy);

/* The first period, to arm the alarm when sampling starts. */
uint16_t ninedof_clock_first(const ninedof_clock_t *c);

/* At an alarm expiry: the crystal time now (LocalTime<TMilli>, read first
 * thing in the handler) -> alarm ticks from this expiry to the next. */
uint16_t ninedof_clock_next(ninedof_clock_t *c, uint32_t xtal_now);

/* Arming the alarm for the next expiry, which the app keeps itself (the
 * expiry just handled plus the period ninedof_clock_next() returned).
 *
 * TinyOS's Alarm32khz32C on iris cannot be trusted with that target as
 * an absolute time (startAt(getAlarm(), period)):
 *  - Its counter (Counter32khz32C: timer 1's 16 bits at 1 MHz, / 32, plus
 *    an overflow count) lags by one timer wrap (2048 ticks, 65.5 ms) when
 *    the alarm's compare interrupt preempts timer 1's overflow handler,
 *    which enables interrupts before it counts the overflow: an expiry due
 *    just after the timer wraps.  TransformAlarmC then takes the target
 *    for one in the past.
 *  - A target in the past, or within 3 timer ticks (3 us) of now,
 *    Atm128AlarmC arms at now + 3 timer ticks, but on iris (timer 1 at
 *    CPU / 8) its own code takes longer than that to write the compare
 *    register: the compare is missed and the alarm waits a whole wrap of
 *    the 16-bit timer, 65.5 ms.
 * Re-armed from its previous expiry, the alarm then stays behind for good
 * (every later target is in the past too): one expiry per 65.5 ms, seen in
 * the simulated nesC run within seconds with the CPU 2 % off.
 *
 * So the app arms relative to now (startAt(now, dt)) with the dt this
 * returns, from the target, the counter now, the period the target was
 * set with (no expiry is further ahead) and the counter's lag when an
 * overflow is not yet counted (`wrap`, 2048 on iris at 8 MHz):
 *  - target - now beyond the period: the counter lags, take one wrap off
 *    (TransformAlarmC reads the same lagging counter, so a dt relative to
 *    it is right);
 *  - then below NINEDOF_ALARM_MIN_TICKS (the handler ran late by about a
 *    period or more): MIN, so the expiry comes late but at once, and the
 *    schedule keeps its phase;
 *  - never more than the period. */
enum {
  /* 3 alarm ticks (96 us): TransformAlarmC rounds now down to a tick and
   * may read it a tick later than the app; 2 ticks remain, more than
   * Atm128AlarmC's 3 timer ticks plus its own run time */
  NINEDOF_ALARM_MIN_TICKS = 3,
};
uint16_t ninedof_clock_arm(uint32_t target, uint32_t now, uint16_t period, uint16_t wrap);

#endif /* NINEDOF_CLOCK_H */
