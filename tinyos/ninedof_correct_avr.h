/*
 * ninedof_correct_avr.h -- the correction's AVR assembly kernels
 * (sensor_q14_acc, q14_run, gain_term), private to ninedof_correct.c,
 * which includes it on the AVR unless NINEDOF_PORTABLE_KERNEL is defined
 * (then its portable C versions of sensor_q14_acc and gain_term are used
 * and there is no q14_run).  Uses ninedof_correct.c's NINEDOF_ALWAYS_INLINE
 * and NINEDOF_TEMP_INLINE, defined before the include.
 */
#ifndef NINEDOF_CORRECT_AVR_H
#define NINEDOF_CORRECT_AVR_H

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
 * residual as shape_q14 (the portable C in ninedof_correct.c) does.  The
 * whole record, the magnetometer's rules included, is one asm block
 * (q14_run), so nothing of the C around it runs per sensor or per record.
 */
/* acc += fb ^ 0x2000 (= r + 2^13, the residual and the rounding constant:
 * fb = r mod 2^14, ninedof_calset.h) from Z+L, Z+H; %[k20] holds 0x20 */
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

/* gain_term, t ~ p G (what t is: ninedof_correct.c, above its portable C).
 * Twelve 8 x 8 products into a 48-bit sum (t0..t5), then bits 14..45.
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

#endif /* NINEDOF_CORRECT_AVR_H */
