/*
 * emu/tests/eeprom_reset.c -- what survives the harness's reset (--reset,
 * node_reset; tests/test_emu_reset.py).  At every boot: print
 * "B<boots in EEPROM> D<an initialised variable> E<EEPROM 0x100..0x103>;",
 * then count the boot in EEPROM byte 0, write a pattern that depends on it
 * to 0x100..0x103, change the initialised variable and stop (cli; sleep).
 * After a reset the variable is back to its initial value (the start-up
 * code ran again) and the EEPROM holds what the previous boot wrote.
 */
#include <stdint.h>
#include <avr/eeprom.h>

#include "test_out.h"

static volatile uint8_t data_var = 7;       /* .data: copied from flash at start-up */

int main(void)
{
  uint8_t boots = eeprom_read_byte((uint8_t *)0);
  out_init();
  if (boots == 0xFF)                         /* erased EEPROM */
    boots = 0;
  out_c('B');
  out_u16(boots);
  out_c(' ');
  out_c('D');
  out_u16(data_var);
  out_c(' ');
  out_c('E');
  uint8_t e[4];
  eeprom_read_block(e, (const void *)0x100, 4);
  out_hex(e, 4);
  out_c(';');
  data_var = 9;
  eeprom_write_byte((uint8_t *)0, (uint8_t)(boots + 1));
  for (uint8_t i = 0; i < 4; i++)
    eeprom_write_byte((uint8_t *)(0x100 + i), (uint8_t)(0xA0 + 16 * i + boots));
  eeprom_busy_wait();
  out_end();
  return 0;
}
