/*
 * ninedof_board.h -- the 9DOF sensor board in plain C: the I2C addresses and
 * register settings of the three chips (one table, each value named after
 * its datasheet fields), how each chip's data bytes become a record, and
 * the I2C bit-rate arithmetic.  Included by the nesC chip drivers
 * (Adxl345LogicP, Itg3200LogicP, Hmc5883lLogicP, NineDofBoardP) and tested
 * on the host and in simavr (tests/test_avr.py, tests/c/logic_tests.c).
 */
#ifndef NINEDOF_BOARD_H
#define NINEDOF_BOARD_H

#include <stdint.h>

/* 7-bit I2C addresses on the 9DOF stick */
enum {
  ADXL345_ADDR = 0x53,        /* ALT ADDRESS pin low */
  ITG3200_ADDR = 0x68,        /* AD0 pin low */
  HMC5883L_ADDR = 0x1E,       /* fixed */
};

/* ---------------------------------------------------------------------- */
/* Registers                                                               */
/* ---------------------------------------------------------------------- */
enum {
  /* ADXL345 (datasheet rev. E, register map table 19) */
  ADXL345_DEVID = 0x00,       /* reads 0xE5 */
  ADXL345_BW_RATE = 0x2C,
  ADXL345_POWER_CTL = 0x2D,
  ADXL345_INT_ENABLE = 0x2E,
  ADXL345_DATA_FORMAT = 0x31,
  ADXL345_DATAX0 = 0x32,      /* X0 X1 Y0 Y1 Z0 Z1: little-endian */
  ADXL345_FIFO_CTL = 0x38,
  ADXL345_DEVID_VALUE = 0xE5,

  /* ITG-3200 (product specification rev. 1.4, section 7) */
  ITG3200_WHO_AM_I = 0x00,    /* bits 6..1 = 110100 */
  ITG3200_SMPLRT_DIV = 0x15,
  ITG3200_DLPF_FS = 0x16,
  ITG3200_INT_CFG = 0x17,
  ITG3200_TEMP_OUT_H = 0x1B,  /* TH TL, then the rates: one burst of 8 */
  ITG3200_GYRO_XOUT_H = 0x1D, /* XH XL YH YL ZH ZL: big-endian */
  ITG3200_PWR_MGM = 0x3E,
  ITG3200_WHO_AM_I_VALUE = 0x68,
  ITG3200_WHO_AM_I_MASK = 0x7E,

  /* HMC5883L (datasheet rev. E, table 2) */
  HMC5883L_CRA = 0x00,
  HMC5883L_CRB = 0x01,
  HMC5883L_MODE = 0x02,
  HMC5883L_DATA_X_MSB = 0x03, /* XH XL ZH ZL YH YL: big-endian, X Z Y order! */
  HMC5883L_STATUS = 0x09,
  HMC5883L_ID_A = 0x0A,       /* 'H' '4' '3' */
};

/* One register write of a chip's start-up configuration. */
typedef struct {
  uint8_t reg;
  uint8_t value;
} ninedof_reg_write_t;

/* Start-up configuration of each chip, in the order written (ninedof_board.c
 * names every field of every value).  Lengths below. */
extern const ninedof_reg_write_t NINEDOF_ADXL345_CONFIG[];
extern const ninedof_reg_write_t NINEDOF_ITG3200_CONFIG[];
extern const ninedof_reg_write_t NINEDOF_HMC5883L_CONFIG[];
enum {
  NINEDOF_ADXL345_CONFIG_LEN = 4,
  NINEDOF_ITG3200_CONFIG_LEN = 4,
  NINEDOF_HMC5883L_CONFIG_LEN = 3,
};

/* The write that puts each chip in its low-power state (SplitControl.stop) */
extern const ninedof_reg_write_t NINEDOF_ADXL345_SLEEP;
extern const ninedof_reg_write_t NINEDOF_ITG3200_SLEEP;
extern const ninedof_reg_write_t NINEDOF_HMC5883L_SLEEP;

/* The write that starts one HMC5883L single measurement: MODE = single.
 * Its register pointer then auto-increments to 0x03 (DATA_X_MSB), so a
 * read after a repeated start gets the six data registers, which still
 * hold the previous measurement until the new one is done (datasheet:
 * "I2C Communication Protocol", pointer auto-increment): trigger and read
 * are one transaction. */
extern const uint8_t NINEDOF_HMC5883L_TRIGGER[2];

/* ---------------------------------------------------------------------- */
/* One descriptor per chip: everything the shared register-table driver    */
/* (NineDofChipP) needs to start, read, check and stop it.                 */
/* ---------------------------------------------------------------------- */
enum {
  NINEDOF_CHIP_ACCEL = 0,     /* ADXL345 */
  NINEDOF_CHIP_GYRO = 1,      /* ITG-3200 */
  NINEDOF_CHIP_MAG = 2,       /* HMC5883L */
  NINEDOF_CHIPS = 3,
};

typedef struct {
  uint8_t addr;                       /* 7-bit I2C address */
  uint8_t id_reg;                     /* identity register(s): */
  uint8_t id_len;                     /*   bytes read there */
  uint8_t config_len;                 /* start-up writes, in order */
  const ninedof_reg_write_t *config;
  ninedof_reg_write_t sleep;          /* SplitControl.stop's write */
  /* a read: write these read_len bytes (register pointer, or the
   * HMC5883L's trigger, which leaves its pointer on the data), repeated
   * start, data_len bytes (NINEDOF_CHIP_DATA, or NINEDOF_CHIP_DATA_MAX for
   * the ITG-3200: TEMP_OUT and the rates in one burst from 0x1B) */
  uint8_t read_cmd[2];
  uint8_t read_len;
  uint8_t data_len;
  /* the witness: the config write whose register is read back on a
   * schedule; it differs from its power-on reset value (witness_reset,
   * datasheet), so a chip that lost power and came back answers with
   * witness_reset and is configured again (ninedof_fault.h) */
  uint8_t witness;                    /* index into config */
  uint8_t witness_reset;
} ninedof_chip_t;

extern const ninedof_chip_t NINEDOF_CHIP[NINEDOF_CHIPS];

/* 1 if the id_len bytes read from id_reg are the expected chip's */
uint8_t ninedof_chip_id_ok(uint8_t chip, const uint8_t *id);
/* The data_len data bytes of a read -> x, y, z counts */
void ninedof_chip_xyz(uint8_t chip, const uint8_t *b, int16_t out[3]);
/* The temperature in the data bytes of a read: the ITG-3200's raw TEMP_OUT
 * (-13200 at 35 C, 280 LSB per C); 0 for the other chips */
int16_t ninedof_chip_temp(uint8_t chip, const uint8_t *b);

/* Identity checks (1 = the expected chip answered) */
uint8_t ninedof_adxl345_id_ok(uint8_t devid);
uint8_t ninedof_itg3200_id_ok(uint8_t who_am_i);
uint8_t ninedof_hmc5883l_id_ok(const uint8_t id[3]);

/* ---------------------------------------------------------------------- */
/* Data bytes -> counts                                                    */
/* ---------------------------------------------------------------------- */
enum {
  NINEDOF_CHIP_DATA = 6,      /* axis bytes read from each chip */
  NINEDOF_CHIP_DATA_MAX = 8,  /* bytes of the longest read: ITG-3200 TEMP_OUT + rates */
  NINEDOF_HMC5883L_OVERFLOW = -4096,
};

/* ADXL345 DATAX0..DATAZ1 (little-endian, full resolution, right-justified,
 * already sign-extended by the chip) -> ax, ay, az */
void ninedof_adxl345_xyz(const uint8_t b[6], int16_t out[3]);
/* ITG3200 GYRO_XOUT_H..GYRO_ZOUT_L (big-endian) -> gx, gy, gz */
void ninedof_itg3200_xyz(const uint8_t b[6], int16_t out[3]);
/* ITG3200 TEMP_OUT_H, TEMP_OUT_L (big-endian) -> raw temperature */
int16_t ninedof_itg3200_temp(const uint8_t b[2]);
/* HMC5883L data registers 0x03..0x08 (big-endian, X, Z, Y) -> mx, my, mz */
void ninedof_hmc5883l_xyz(const uint8_t b[6], int16_t out[3]);
/* All three into one record ax..mz */
void ninedof_board_record(const uint8_t acc[6], const uint8_t gyro[6],
                          const uint8_t mag[6], int16_t rec[9]);

/* ---------------------------------------------------------------------- */
/* I2C bit rate (ATmega1281 TWI: SCL = F_CPU / (16 + 2 * TWBR * 4^TWPS))    */
/* ---------------------------------------------------------------------- */
/* NINEDOF_I2C_HZ is the fastest SCL allowed; TWBR is rounded up so the bus
 * never runs faster.  All three chips are fast-mode (400 kHz) parts, but
 * fast mode also asks SCL low >= 1.3 us, and the TWI's SCL is about half
 * low: at TWBR = 2 (exactly 400 kHz at 8 MHz) that is 1.25 us, and less on
 * a fast RC oscillator.  380 kHz gives TWBR = 3: 364 kHz, SCL low ~1.375 us,
 * within the limit for a CPU clock up to 5 % fast. */
#ifndef NINEDOF_I2C_HZ
#define NINEDOF_I2C_HZ 380000UL
#endif
#define NINEDOF_TWBR(fcpu, scl) \
  ((uint8_t)((((fcpu) + (scl) - 1UL) / (scl) - 16UL + 1UL) / 2UL))

#endif /* NINEDOF_BOARD_H */
