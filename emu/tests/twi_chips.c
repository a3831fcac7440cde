/*
 * emu/tests/twi_chips.c -- the harness's TWI and chip models from the AVR
 * side (tests/test_emu_chips.py): the lean TWI master's state machine
 * (tinyos/ninedof_twi.c) driven from the TWI interrupt, reading the three
 * chip models through ninedof-emu's bus.  Prints on UART0:
 *
 *   ID <adxl devid> <itg who_am_i> <hmc id a,b,c>;
 *   CFG <result of each register write, 11 digits>;
 *   S <i> <adxl 6 bytes> <itg temp+gyro 8 bytes> <hmc 6 bytes> <results>;   x 20, every 8 ms
 *   HMC2 <6 bytes>; HMC8 <6 bytes>;    read 2 ms / 8 ms after a trigger
 *   HMCP <r> <6 bytes> <r> <7 bytes> <r> <2 bytes>;   reads without a pointer write
 *   MARK;                              a write to 0x77 (nobody): the fault phase starts
 *   F <i> <adxl r> <power_ctl> <itg r> <who_am_i>;  x 40, every 5 ms
 *   END
 * Results are NINEDOF_TWI_* outcomes (0 ok, 1 address NACK, ...).
 */
#include <stdint.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/delay.h>

#include "ninedof_board.h"
#include "test_out.h"
#include "twi_ops.h"

static uint8_t write_reg(uint8_t addr, uint8_t reg, uint8_t v)
{
  uint8_t b[2] = { reg, v };
  return op(0, NINEDOF_I2C_START | NINEDOF_I2C_STOP, addr, 2, b);
}

static void out_digit(uint8_t d) { out_c((char)('0' + d)); }

int main(void)
{
  uint8_t a[8], g[8], m[8], i, r1, r2, r3;
  out_init();
  ninedof_twi_init(&twi);
  TWBR = NINEDOF_TWBR(F_CPU, NINEDOF_I2C_HZ);
  TWSR = 0;
  TWCR = _BV(TWEN);
  sei();

  read_regs(ADXL345_ADDR, ADXL345_DEVID, 1, a);
  read_regs(ITG3200_ADDR, ITG3200_WHO_AM_I, 1, g);
  read_regs(HMC5883L_ADDR, HMC5883L_ID_A, 3, m);
  out_s("ID "); out_hex(a, 1); out_c(' '); out_hex(g, 1); out_c(' '); out_hex(m, 3); out_c(';');

  out_s("CFG ");
  for (i = 0; i < NINEDOF_ADXL345_CONFIG_LEN; i++)
    out_digit(write_reg(ADXL345_ADDR, NINEDOF_ADXL345_CONFIG[i].reg, NINEDOF_ADXL345_CONFIG[i].value));
  for (i = 0; i < NINEDOF_ITG3200_CONFIG_LEN; i++)
    out_digit(write_reg(ITG3200_ADDR, NINEDOF_ITG3200_CONFIG[i].reg, NINEDOF_ITG3200_CONFIG[i].value));
  for (i = 0; i < NINEDOF_HMC5883L_CONFIG_LEN; i++)
    out_digit(write_reg(HMC5883L_ADDR, NINEDOF_HMC5883L_CONFIG[i].reg, NINEDOF_HMC5883L_CONFIG[i].value));
  out_c(';');
  _delay_ms(60);                        /* the ITG-3200's start-up */

  for (i = 0; i < 20; i++) {
    r1 = read_regs(ADXL345_ADDR, ADXL345_DATAX0, 6, a);
    r2 = read_regs(ITG3200_ADDR, ITG3200_GYRO_XOUT_H - 2, 8, g);   /* TEMP_OUT_H first */
    /* the firmware's magnetometer read: trigger (the pointer write) + read */
    r3 = op(0, NINEDOF_I2C_START, HMC5883L_ADDR, 2, (uint8_t *)NINEDOF_HMC5883L_TRIGGER);
    if (!r3)
      r3 = op(1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, HMC5883L_ADDR, 6, m);
    out_s("S "); out_u16(i); out_c(' '); out_hex(a, 6); out_c(' '); out_hex(g, 8); out_c(' ');
    out_hex(m, 6); out_c(' '); out_digit(r1); out_digit(r2); out_digit(r3); out_c(';');
    _delay_ms(7);
  }

  /* single-measurement timing: 2 ms after the trigger the previous one */
  write_reg(HMC5883L_ADDR, HMC5883L_MODE, 0x01);
  _delay_ms(2);
  read_regs(HMC5883L_ADDR, HMC5883L_DATA_X_MSB, 6, m);
  out_s("HMC2 "); out_hex(m, 6); out_c(';');
  _delay_ms(6);
  read_regs(HMC5883L_ADDR, HMC5883L_DATA_X_MSB, 6, m);
  out_s("HMC8 "); out_hex(m, 6); out_c(';');
  /* the HMC5883L's pointer without a pointer write: after HMC8's six
   * bytes (0x03..0x08) it is back at 0x03, so six more are the same data
   * and a seventh is X MSB again; after the identification (0x0A..0x0C)
   * it is at 0x00 (CRA, CRB) */
  r1 = op(1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, HMC5883L_ADDR, 6, m);
  out_s("HMCP "); out_digit(r1); out_c(' '); out_hex(m, 6);
  r1 = op(1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, HMC5883L_ADDR, 7, m);
  out_c(' '); out_digit(r1); out_c(' '); out_hex(m, 7);
  read_regs(HMC5883L_ADDR, HMC5883L_ID_A, 3, m);
  r1 = op(1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, HMC5883L_ADDR, 2, m);
  out_c(' '); out_digit(r1); out_c(' '); out_hex(m, 2); out_c(';');

  out_s("MARK ");
  out_digit(write_reg(0x77, 0, 0));
  out_c(';');
  for (i = 0; i < 40; i++) {
    r1 = read_regs(ADXL345_ADDR, ADXL345_POWER_CTL, 1, a);
    r2 = read_regs(ITG3200_ADDR, ITG3200_WHO_AM_I, 1, g);
    out_s("F "); out_u16(i); out_c(' '); out_digit(r1); out_c(' '); out_hex(a, 1); out_c(' ');
    out_digit(r2); out_c(' '); out_hex(g, 1); out_c(';');
    _delay_ms(5);
  }
  out_s("END");
  _delay_ms(1);
  out_end();
  return 0;
}
