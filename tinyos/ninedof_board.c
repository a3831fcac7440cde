/*
 * ninedof_board.c -- register settings and data conversion of the 9DOF board
 * (see ninedof_board.h).  Every configuration value lives here, once.
 *
 * Sampling is 125 Hz, every 8 ms, all three chips read at the same instant:
 *  - ADXL345: full resolution (3.9 mg/LSB = 256 LSB/g at any range), +-16 g,
 *    output data rate 200 Hz, the lowest above 125 Hz (bandwidth 100 Hz), so
 *    every read finds a sample at most 5 ms old.
 *  - ITG-3200: FS_SEL = 3 (+-2000 deg/s, 14.375 LSB/(deg/s)), digital low-pass
 *    42 Hz (below the 62.5 Hz Nyquist limit of 125 Hz sampling) with its 1 kHz
 *    internal rate, sample-rate divider 3 -> 250 Hz output, samples <= 4 ms old.
 *  - HMC5883L: single-measurement mode, triggered at each read (in the same
 *    transaction) so the measurement (<= 6 ms at one sample per output) is
 *    finished before the next read 8 ms later.  Continuous mode tops out at 75 Hz and would
 *    repeat stale samples at 125 Hz.  Gain 1090 LSB/gauss (+-1.3 Ga).
 */
#include "ninedof_board.h"

const ninedof_reg_write_t NINEDOF_ADXL345_CONFIG[NINEDOF_ADXL345_CONFIG_LEN] = {
  /* DATA_FORMAT: SELF_TEST=0, SPI=0 (4-wire, unused on I2C), INT_INVERT=0,
   * FULL_RES=1 (10..13 bits, 3.9 mg/LSB), Justify=0 (right, sign-extended),
   * Range=11 (+-16 g) */
  { ADXL345_DATA_FORMAT, 0x0B },
  /* BW_RATE: LOW_POWER=0 (normal operation), Rate=1011 (200 Hz output data
   * rate, 100 Hz bandwidth) */
  { ADXL345_BW_RATE, 0x0B },
  /* FIFO_CTL: FIFO_MODE=00 (bypass: data registers hold the newest sample) */
  { ADXL345_FIFO_CTL, 0x00 },
  /* POWER_CTL: Link=0, AUTO_SLEEP=0, Measure=1 (leave standby), Sleep=0,
   * Wakeup=00; written last, as the datasheet advises configuring in standby */
  { ADXL345_POWER_CTL, 0x08 },
};

const ninedof_reg_write_t NINEDOF_ITG3200_CONFIG[NINEDOF_ITG3200_CONFIG_LEN] = {
  /* PWR_MGM: H_RESET=0, SLEEP=0, STBY_XG/YG/ZG=0 (all axes on),
   * CLK_SEL=001 (PLL with X gyro reference, recommended for stability) */
  { ITG3200_PWR_MGM, 0x01 },
  /* SMPLRT_DIV: F_sample = F_internal / (SMPLRT_DIV + 1) = 1 kHz / 4 = 250 Hz */
  { ITG3200_SMPLRT_DIV, 0x03 },
  /* DLPF_FS: FS_SEL=11 (+-2000 deg/s; the only valid setting),
   * DLPF_CFG=011 (42 Hz low-pass, 1 kHz internal sample rate) */
  { ITG3200_DLPF_FS, (3 << 3) | 3 },
  /* INT_CFG: no interrupt output (the mote polls on its own 125 Hz clock) */
  { ITG3200_INT_CFG, 0x00 },
};

const ninedof_reg_write_t NINEDOF_HMC5883L_CONFIG[NINEDOF_HMC5883L_CONFIG_LEN] = {
  /* CRA: CRA7=0 (reserved), MA=00 (1 sample per output: shortest single
   * measurement, 160 Hz possible), DO=110 (75 Hz; applies to continuous mode
   * only), MS=00 (normal measurement, no bias) */
  { HMC5883L_CRA, (0 << 5) | (6 << 2) | 0 },
  /* CRB: GN=001 (+-1.3 Ga, 1090 LSB/gauss), low bits must be 0 */
  { HMC5883L_CRB, 1 << 5 },
  /* MODE: HS=0 (no 3.4 MHz I2C), MD=01 (single measurement: starts the first) */
  { HMC5883L_MODE, 0x01 },
};

/* POWER_CTL: Measure=0 (standby, 0.1 uA) */
#define ADXL345_SLEEP_WRITE { ADXL345_POWER_CTL, 0x00 }
/* PWR_MGM: SLEEP=1 (low-power sleep), CLK_SEL=000 (internal oscillator) */
#define ITG3200_SLEEP_WRITE { ITG3200_PWR_MGM, 0x40 }
/* MODE: MD=11 (idle) */
#define HMC5883L_SLEEP_WRITE { HMC5883L_MODE, 0x03 }
/* MODE register (0x02) = MD 01: one single measurement */
#define HMC5883L_TRIGGER_WRITE { HMC5883L_MODE, 0x01 }

const ninedof_reg_write_t NINEDOF_ADXL345_SLEEP = ADXL345_SLEEP_WRITE;
const ninedof_reg_write_t NINEDOF_ITG3200_SLEEP = ITG3200_SLEEP_WRITE;
const ninedof_reg_write_t NINEDOF_HMC5883L_SLEEP = HMC5883L_SLEEP_WRITE;
const uint8_t NINEDOF_HMC5883L_TRIGGER[2] = HMC5883L_TRIGGER_WRITE;

uint8_t ninedof_adxl345_id_ok(uint8_t devid)
{
  return devid == ADXL345_DEVID_VALUE;
}

uint8_t ninedof_itg3200_id_ok(uint8_t who_am_i)
{
  return (who_am_i & ITG3200_WHO_AM_I_MASK) == ITG3200_WHO_AM_I_VALUE;
}

uint8_t ninedof_hmc5883l_id_ok(const uint8_t id[3])
{
  return id[0] == 'H' && id[1] == '4' && id[2] == '3';
}

static int16_t le16(const uint8_t *b)
{
  return (int16_t)(uint16_t)((uint16_t)b[0] | ((uint16_t)b[1] << 8));
}

static int16_t be16(const uint8_t *b)
{
  return (int16_t)(uint16_t)(((uint16_t)b[0] << 8) | b[1]);
}

void ninedof_adxl345_xyz(const uint8_t b[6], int16_t out[3])
{
  out[0] = le16(b);
  out[1] = le16(b + 2);
  out[2] = le16(b + 4);
}

void ninedof_itg3200_xyz(const uint8_t b[6], int16_t out[3])
{
  out[0] = be16(b);
  out[1] = be16(b + 2);
  out[2] = be16(b + 4);
}

int16_t ninedof_itg3200_temp(const uint8_t b[2])
{
  return be16(b);
}

void ninedof_hmc5883l_xyz(const uint8_t b[6], int16_t out[3])
{
  out[0] = be16(b);        /* 0x03, 0x04: X */
  out[2] = be16(b + 2);    /* 0x05, 0x06: Z */
  out[1] = be16(b + 4);    /* 0x07, 0x08: Y */
}

void ninedof_board_record(const uint8_t acc[6], const uint8_t gyro[6],
                          const uint8_t mag[6], int16_t rec[9])
{
  ninedof_adxl345_xyz(acc, rec);
  ninedof_itg3200_xyz(gyro, rec + 3);
  ninedof_hmc5883l_xyz(mag, rec + 6);
}

/* The three chips for the shared driver.  Witnesses: ADXL345 DATA_FORMAT
 * (reset 0x00, register map table 19), ITG-3200 DLPF_FS (reset 0x00,
 * product specification section 7), HMC5883L CRA (reset 0x10, datasheet
 * table 3).  Each is the chip's measuring range or rate, so a chip that
 * reset would otherwise send counts of another scale.  The ITG-3200 is read
 * from TEMP_OUT_H (0x1B): temperature and rates in one burst of 8 bytes
 * (the pointer auto-increments through 0x1B..0x22), 2 bytes more on the
 * wire than the rates alone and no extra transaction. */
#ifdef NINEDOF_ITG_RATES_ONLY
/* Build option for the comparison only (bench/bench_cycles.py: I2C time per
 * sample before and after the temperature): the read as it was before, six
 * bytes from GYRO_XOUT_H, no temperature (ninedof_chip_temp gives 0). */
#define ITG3200_READ_REG ITG3200_GYRO_XOUT_H
#define ITG3200_READ_LEN NINEDOF_CHIP_DATA
#define ITG3200_RATES_AT 0
#else
#define ITG3200_READ_REG ITG3200_TEMP_OUT_H
#define ITG3200_READ_LEN NINEDOF_CHIP_DATA_MAX
#define ITG3200_RATES_AT 2
#endif

const ninedof_chip_t NINEDOF_CHIP[NINEDOF_CHIPS] = {
  { ADXL345_ADDR, ADXL345_DEVID, 1, NINEDOF_ADXL345_CONFIG_LEN, NINEDOF_ADXL345_CONFIG,
    ADXL345_SLEEP_WRITE, { ADXL345_DATAX0, 0 }, 1, NINEDOF_CHIP_DATA, 0, 0x00 },
  { ITG3200_ADDR, ITG3200_WHO_AM_I, 1, NINEDOF_ITG3200_CONFIG_LEN, NINEDOF_ITG3200_CONFIG,
    ITG3200_SLEEP_WRITE, { ITG3200_READ_REG, 0 }, 1, ITG3200_READ_LEN, 2, 0x00 },
  { HMC5883L_ADDR, HMC5883L_ID_A, 3, NINEDOF_HMC5883L_CONFIG_LEN, NINEDOF_HMC5883L_CONFIG,
    HMC5883L_SLEEP_WRITE, HMC5883L_TRIGGER_WRITE, 2, NINEDOF_CHIP_DATA, 0, 0x10 },
};

uint8_t ninedof_chip_id_ok(uint8_t chip, const uint8_t *id)
{
  if (chip == NINEDOF_CHIP_ACCEL)
    return ninedof_adxl345_id_ok(id[0]);
  if (chip == NINEDOF_CHIP_GYRO)
    return ninedof_itg3200_id_ok(id[0]);
  return ninedof_hmc5883l_id_ok(id);
}

void ninedof_chip_xyz(uint8_t chip, const uint8_t *b, int16_t out[3])
{
  if (chip == NINEDOF_CHIP_ACCEL)
    ninedof_adxl345_xyz(b, out);
  else if (chip == NINEDOF_CHIP_GYRO)
    ninedof_itg3200_xyz(b + ITG3200_RATES_AT, out);   /* after TEMP_OUT_H, TEMP_OUT_L */
  else
    ninedof_hmc5883l_xyz(b, out);
}

int16_t ninedof_chip_temp(uint8_t chip, const uint8_t *b)
{
  return chip == NINEDOF_CHIP_GYRO && ITG3200_RATES_AT ? ninedof_itg3200_temp(b) : 0;
}
