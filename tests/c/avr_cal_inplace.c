/*
 * avr_cal_inplace.c -- the correction kernel in place (in == out), the way
 * the sensor mote runs it (ninedof_batch_pack corrects its batch in place)
 * and in one translation unit, as nesC builds the image (app.c), so the
 * compiler sees that in and out are equal (tests/test_cal_inplace.py).
 * Identity matrices, offsets 1..9 counts: record r axis k must read
 * 100 r + k + (k + 1); the 9 canaries after the buffer stay 0x5A5A (23130).
 * Prints the 45 values, '|', the canaries, END.
 */
#include <stdint.h>
#include <string.h>
#include "test_out.h"
#include "ninedof_calset.c"
#include "ninedof_correct.c"
#include "ninedof_calrx.c"
static struct { int16_t rec[5][9]; int16_t canary[9]; } buf;
static ninedof_cal_t cal;
/* the mote's call (ninedof_batch_pack -> ninedof_calrx_correct_block ->
 * ninedof_correct_block), inlined whole as in the image (TinyOS builds with
 * -finline-limit=100000): flatten does that here */
__attribute__((flatten)) static void correct_in_place(void)
{
  ninedof_correct_block(&cal, &buf.rec[0][0], &buf.rec[0][0], 5);
}
static void out_i16(int16_t v) { if (v < 0) { out_c('-'); v = (int16_t)-v; } out_u16((uint16_t)v); }
int main(void)
{
  uint8_t r, k;
  out_init();
  memset(&cal, 0, sizeof cal);
  cal.sensors = 7;
  for (k = 0; k < 3; k++) {
    cal.s[k].shift = 14;
    cal.s[k].a[0] = cal.s[k].a[4] = cal.s[k].a[8] = 16384;
    for (r = 0; r < 3; r++) cal.s[k].c[r] = (int32_t)(3 * k + r + 1) << 14;
  }
  for (r = 0; r < 5; r++) for (k = 0; k < 9; k++) buf.rec[r][k] = (int16_t)(100 * r + k);
  for (k = 0; k < 9; k++) buf.canary[k] = 0x5A5A;
  correct_in_place();
  for (r = 0; r < 5; r++) for (k = 0; k < 9; k++) { out_i16(buf.rec[r][k]); out_c(' '); }
  out_c('|');
  for (k = 0; k < 9; k++) { out_i16(buf.canary[k]); out_c(' '); }
  out_s("END");
  out_end();
  return 0;
}
