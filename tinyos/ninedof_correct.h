/*
 * ninedof_correct.h -- the fixed-point correction of a calibration set
 * (ninedof_calset.h) on the mote, with its temperature terms and rounding
 * with error feedback, and the proof of its bound.  Implemented in
 * ninedof_correct.c (its AVR assembly kernels: ninedof_correct_avr.h).
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
#ifndef NINEDOF_CORRECT_H
#define NINEDOF_CORRECT_H

#include <stdint.h>
#include "ninedof_calset.h"

#define NINEDOF_MAG_OVERFLOW (-4096)
/* The gain path's residuals stay within [-(2^13 - E), 2^13 - E] (Q14): E =
 * 16, e = E / 2^14 = 2^-10 LSB (the bound above) */
#define NINEDOF_TEMP_MARGIN 16u

/* Put the board temperature `raw` (TEMP_OUT) in force for the temperature
 * terms: recomputes eff[].c (c + O) and tg (G), a few multiplications per
 * sensor, and limits the residuals of sensors on the gain path to 1/2 - e. */
void ninedof_cal_set_temp(ninedof_cal_t *cal, int16_t raw);

/* Correct one record (9 axes, ax..mz) / n records, raw and out may alias.
 * Updates the set's rounding residuals (fb of s[] or eff[]): records are
 * corrected in the order they were sampled. */
void ninedof_correct(ninedof_cal_t *cal, const int16_t raw[9], int16_t out[9]);
void ninedof_correct_block(ninedof_cal_t *cal, const int16_t *raw,
                           int16_t *out, uint16_t n);

#endif /* NINEDOF_CORRECT_H */
