/*
 * twi_isr_test.c -- NINEDOF_TWI_CALL_SAVING (tinyos/ninedof_twi.h) on the
 * ATmega1281 in simavr: an interrupt handler with no call of its own calls,
 * through the macro, a function that overwrites every register the avr-gcc
 * ABI lets it clobber and RAMPZ.  Timer 0 interrupts a register-heavy
 * computation every 97 cycles; the result and RAMPZ must be those of the
 * same computation without interrupts.  Prints "H<hits> R<ok> Z<ok>;END".
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <stdint.h>

#include "ninedof_twi.h"
#include "test_out.h"

static volatile uint16_t hits;
static volatile uint16_t iterations = 3000;   /* volatile: two real runs of work() */

static void clobber(void)
{
  __asm__ __volatile__(
    "ldi r18, 0xA5\n\tldi r19, 0x5A\n\tldi r20, 0xA5\n\tldi r21, 0x5A\n\t"
    "ldi r22, 0xA5\n\tldi r23, 0x5A\n\tldi r24, 0xA5\n\tldi r25, 0x5A\n\t"
    "ldi r26, 0xA5\n\tldi r27, 0x5A\n\tldi r30, 0xA5\n\tldi r31, 0x5A\n\t"
    "mov r0, r18\n\tout 0x3b, r18\n\tset\n\tsec\n\tsez"
    : : : "r0", "r18", "r19", "r20", "r21", "r22", "r23", "r24", "r25",
          "r26", "r27", "r30", "r31", "memory");
  hits++;
}

ISR(TIMER0_COMPA_vect)
{
  NINEDOF_TWI_CALL_SAVING(clobber);
}

/* many values live at once, no calls: most of them sit in r18..r31 */
static uint32_t __attribute__((noinline, noclone)) work(void)
{
  uint16_t n = iterations;
  uint32_t a = 1, b = 2, c = 3, d = 4;
  uint16_t e = 5, f = 6, g = 7, h = 8;
  uint16_t i;
  for (i = 0; i < n; i++) {
    a = a * 33u + (b ^ i);
    b = (b << 3) ^ (b >> 5) ^ c;
    c += d ^ (a >> 7);
    d = (d >> 1) ^ (-(d & 1) & 0xEDB88320u) ^ e;
    e = (uint16_t)(e * 5 + f);
    f ^= (uint16_t)(g << 1) + h;
    g += (uint16_t)(a >> 16);
    h = (uint16_t)(h * 3) ^ (uint16_t)i;
  }
  return a ^ b ^ c ^ d ^ ((uint32_t)e << 16) ^ f ^ ((uint32_t)g << 8) ^ h;
}

int main(void)
{
  uint32_t quiet, busy;
  uint8_t rampz;

  out_init();
  quiet = work();
  RAMPZ = 0;
  OCR0A = 97;
  TCCR0A = _BV(WGM01);                   /* CTC */
  TCCR0B = _BV(CS00);                    /* clk/1 */
  TIMSK0 = _BV(OCIE0A);
  sei();
  busy = work();
  rampz = RAMPZ;
  cli();
  TIMSK0 = 0;
  out_c('H');
  out_u16(hits);
  out_s(" R");
  out_u16(busy == quiet);
  out_s(" Z");
  out_u16(rampz == 0);
  out_s(";END\n");
  out_end();
  return 0;
}
