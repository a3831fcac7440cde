/*
 * NineDofMsg.h -- the one definition of every message motecal exchanges.
 *
 * Included by the nesC firmware (tinyos/, basestation/), by the plain C
 * logic files (through nx_plain.h, which gives nx types to gcc/avr-gcc), and
 * parsed by the host: host/motecal/line/protocol.py declares the same layouts and
 * tests/test_protocol_header.py fails if the two ever differ.  TinyOS's MIG
 * can generate Java/Python classes from it (mig python -target=iris
 * NineDofMsg.h ninedof_samples_msg).
 *
 * All multi-byte fields are network types: big-endian on the wire.
 */
#ifndef NINEDOF_MSG_H
#define NINEDOF_MSG_H

#ifndef NESC
#include "nx_plain.h"   /* plain C build (tests, simulator library) */
#endif

/* ---------------------------------------------------------------------- */
/* Active message types                                                    */
/* ---------------------------------------------------------------------- */
enum {
  AM_NINEDOF_SAMPLES_MSG = 0x60,      /* mote -> PC: batch of 9-axis records */
  AM_NINEDOF_CAL_FRAG_MSG = 0x61,     /* PC -> mote: fragment of a calibration set */
  AM_NINEDOF_CAL_FRAG_ACK_MSG = 0x62, /* mote -> PC: fragment received / rejected */
  AM_NINEDOF_CAL_COMMIT_MSG = 0x63,   /* PC -> mote: apply (or reset) with CRC */
  AM_NINEDOF_CAL_COMMIT_ACK_MSG = 0x64, /* mote -> PC: result, CRC, version in force */
  AM_NINEDOF_CAL_QUERY_MSG = 0x65,    /* PC -> mote: read back part of the set in force */
  AM_NINEDOF_CAL_REPORT_MSG = 0x66,   /* mote -> PC: that part */
  AM_NINEDOF_MOTE_STATUS_MSG = 0x67,  /* mote -> PC: counters, every NINEDOF_STATUS_PERIOD */
  AM_NINEDOF_BS_STATUS_MSG = 0x68,    /* BaseStation -> PC: its counters */
  AM_NINEDOF_MOTE_TEMP_MSG = 0x69,    /* mote -> PC: board temperature, every NINEDOF_TEMP_PERIOD */
};

/* The issue text calls the sample message type AM_NINEDOF_SAMPLES. */
enum { AM_NINEDOF_SAMPLES = AM_NINEDOF_SAMPLES_MSG };

/* ---------------------------------------------------------------------- */
/* Sizes                                                                   */
/* ---------------------------------------------------------------------- */
#ifndef NINEDOF_BATCH
/* Records per sample message.  5 lets 6 motes at 125 Hz share one
 * 250000 baud serial line and one 802.15.4 channel (see `make bench`,
 * link budget).  Needs TOSH_DATA_LENGTH >= 4 + 18 * NINEDOF_BATCH. */
#define NINEDOF_BATCH 5
#endif

enum {
  NINEDOF_RATE_HZ = 125,
  NINEDOF_RECORD_SIZE = 18,           /* 9 x int16 */
  NINEDOF_FRAG_DATA = 20,             /* calibration bytes per fragment/report */
  NINEDOF_STATUS_PERIOD_MS = 2000,
  NINEDOF_TEMP_PERIOD_MS = 1000,
};

/* ---------------------------------------------------------------------- */
/* How messages change                                                     */
/* ---------------------------------------------------------------------- */
/* A message only ever grows at its end.  A host decodes a payload of one
 * of the message's earlier sizes (below: an older image's or host's) with
 * the fields it lacks absent, and a longer payload (a newer image's) by the
 * fields it knows, ignoring the rest (MessageSpec.decode in
 * host/motecal/line/protocol.py).  A reply grows only when its request asks
 * for it, through a request field appended at the same time, so hosts built
 * before a change keep working with images built after it, and the other
 * way round.  tests/test_protocol_header.py checks these sizes against
 * protocol.py and that each ends at a field. */
enum {
  NINEDOF_MOTE_STATUS_SIZE_V1 = 14,   /* before i2c_nacks, bus_resets, chip_reinits */
  NINEDOF_CAL_QUERY_SIZE_V1 = 3,      /* before flags */
  NINEDOF_CAL_REPORT_SIZE_V1 = 28,    /* before stored_version, stored_crc, store */
};

/* Sample message flags */
enum {
  NINEDOF_FLAG_CORRECTED = 0x01,      /* records are corrected on the mote */
  NINEDOF_FLAG_VERSION_SHIFT = 4,     /* bits 4-7: low 4 bits of the calibration version */
  NINEDOF_FLAG_VERSION_MASK = 0xF0,
};

/* ---------------------------------------------------------------------- */
/* Samples (mote -> PC)                                                    */
/* ---------------------------------------------------------------------- */
typedef nx_struct ninedof_record {
  nx_int16_t ax, ay, az;   /* ADXL345 counts, full resolution 256 LSB/g */
  nx_int16_t gx, gy, gz;   /* ITG3200 counts, 14.375 LSB/(deg/s) */
  nx_int16_t mx, my, mz;   /* HMC5883L counts, 1090 LSB/gauss, -4096 = overflow */
} ninedof_record_t;

typedef nx_struct ninedof_samples_msg {
  nx_uint16_t seq;         /* sequence number of rec[0]; wraps at 65536 */
  nx_uint8_t flags;        /* NINEDOF_FLAG_* */
  nx_uint8_t count;        /* valid records, 1..NINEDOF_BATCH; length = 4 + 18*count */
  ninedof_record_t rec[NINEDOF_BATCH];
} ninedof_samples_msg_t;

/* ---------------------------------------------------------------------- */
/* Calibration set: what is uploaded, CRC-checked, stored and applied.     */
/* For each sensor: out = sat16((A_q * raw + c_q + 2^(shift-1)) >> shift), */
/* in the sensor's nominal counts.  A_q = round(A * 2^shift) row-major,    */
/* c_q = round(c_counts * 2^shift).  See tinyos/ninedof_correct.h.         */
/* ---------------------------------------------------------------------- */
enum {
  NINEDOF_SENSOR_ACCEL = 0,
  NINEDOF_SENSOR_GYRO = 1,
  NINEDOF_SENSOR_MAG = 2,
  NINEDOF_SENSORS = 3,
};

typedef nx_struct ninedof_cal_sensor {
  nx_int16_t a[9];         /* 3x3 matrix, row-major, Q(shift) */
  nx_int32_t c[3];         /* offset in counts, Q(shift) */
  nx_uint8_t shift;        /* fractional bits, 8..14 */
  nx_uint8_t reserved;     /* 0 */
} ninedof_cal_sensor_t;

typedef nx_struct ninedof_calset {
  nx_uint16_t mote;        /* target mote id (TOS_NODE_ID) */
  nx_uint16_t version;     /* 1..65535; low 4 bits go into every sample's flags */
  nx_uint8_t sensors;      /* bit NINEDOF_SENSOR_x set: that sensor is corrected */
  nx_uint8_t format;       /* NINEDOF_CALSET_PLAIN (0; "reserved, 0" in images
                              built before the temperature terms) or _TEMP */
  ninedof_cal_sensor_t s[NINEDOF_SENSORS];
} ninedof_calset_t;

/* ---------------------------------------------------------------------- */
/* Calibration set with temperature terms (format NINEDOF_CALSET_TEMP).    */
/* The plain set followed by a temperature block; a set without            */
/* temperature terms is the plain set alone, byte for byte what images    */
/* built before the temperature terms accept.  Those images refuse the     */
/* longer set: its fragments past byte 102 get NINEDOF_CAL_E_FRAG, and     */
/* nothing changes on the mote.  For sensor k with its bit in              */
/* temp_sensors, T the board temperature (raw ITG-3200 TEMP_OUT) and       */
/* dT = clamp(T, t_lo, t_hi) - t_ref (TEMP_OUT counts):                    */
/*   out_i = sat(((1 + g_i dT / 2^gshift) (A_q raw)_i + c_q,i) / 2^shift   */
/*               + o_i dT / 2^oshift)                                      */
/* (the calibration's TempModel in counts: scale_per_c and offset_per_c    */
/* per TEMP_OUT count).  See tinyos/ninedof_correct.h.                     */
/* ---------------------------------------------------------------------- */
enum {
  NINEDOF_CALSET_PLAIN = 0,     /* ninedof_calset_t, 102 bytes */
  NINEDOF_CALSET_TEMP = 1,      /* ninedof_calset_temp_t, 164 bytes */
};

typedef nx_struct ninedof_cal_temp {
  nx_int16_t t_ref;        /* raw TEMP_OUT at which the plain correction holds */
  nx_int16_t t_lo;         /* calibrated range, raw TEMP_OUT: T is clamped to it */
  nx_int16_t t_hi;
  nx_int16_t o[3];         /* offset change, counts per TEMP_OUT count, Q(oshift) */
  nx_int16_t g[3];         /* relative gain change per TEMP_OUT count, Q(gshift) */
  nx_uint8_t oshift;       /* 14..40 */
  nx_uint8_t gshift;       /* 16..46 */
} ninedof_cal_temp_t;

typedef nx_struct ninedof_calset_temp {
  ninedof_calset_t base;   /* base.format = NINEDOF_CALSET_TEMP */
  nx_uint8_t temp_sensors; /* bit NINEDOF_SENSOR_x: that sensor has temperature terms */
  nx_uint8_t reserved;     /* 0 */
  ninedof_cal_temp_t t[NINEDOF_SENSORS];
} ninedof_calset_temp_t;

/* Reason codes in acks; the host prints their meaning (protocol.py). */
enum {
  NINEDOF_CAL_OK = 0,
  NINEDOF_CAL_E_MOTE = 1,       /* set or message addressed to another mote */
  NINEDOF_CAL_E_FRAG = 2,       /* fragment offset/length outside the set */
  NINEDOF_CAL_E_INCOMPLETE = 3, /* commit before every byte arrived */
  NINEDOF_CAL_E_CRC = 4,        /* CRC over the staged set does not match */
  NINEDOF_CAL_E_VERSION = 5,    /* version 0, or not the version being staged */
  NINEDOF_CAL_E_RANGE = 6,      /* plausibility limits (matrix, offsets, overflow) */
  NINEDOF_CAL_E_FORMAT = 7,     /* shift, reserved bytes or length invalid */
  NINEDOF_CAL_E_STORAGE = 8,    /* could not persist the set */
  NINEDOF_CAL_E_ACTION = 9,     /* unknown commit action */
};

/* Commit actions */
enum {
  NINEDOF_CAL_APPLY = 1,        /* validate the staged set and put it in force */
  NINEDOF_CAL_RESET = 2,        /* back to raw output; version becomes `version` */
};

/* ---------------------------------------------------------------------- */
/* Calibration upload (PC -> mote, through the BaseStation and the radio)  */
/* ---------------------------------------------------------------------- */
typedef nx_struct ninedof_cal_frag_msg {
  nx_uint16_t mote;        /* target mote (also the AM destination) */
  nx_uint16_t version;     /* version of the set being staged */
  nx_uint8_t offset;       /* byte offset into ninedof_calset_t */
  nx_uint8_t len;          /* valid bytes in data, 1..NINEDOF_FRAG_DATA */
  nx_uint8_t data[NINEDOF_FRAG_DATA];
} ninedof_cal_frag_msg_t;

typedef nx_struct ninedof_cal_frag_ack_msg {
  nx_uint16_t mote;        /* the acknowledging mote */
  nx_uint16_t version;     /* version being staged */
  nx_uint8_t offset;       /* echo of the fragment */
  nx_uint8_t status;       /* NINEDOF_CAL_OK or NINEDOF_CAL_E_* */
} ninedof_cal_frag_ack_msg_t;

typedef nx_struct ninedof_cal_commit_msg {
  nx_uint16_t mote;
  nx_uint16_t version;     /* the staged set's version (APPLY) or the new version (RESET) */
  nx_uint8_t length;       /* sizeof(ninedof_calset_t) */
  nx_uint8_t action;       /* NINEDOF_CAL_APPLY or NINEDOF_CAL_RESET */
  nx_uint16_t crc;         /* CRC-16-CCITT (XMODEM) over the whole set */
} ninedof_cal_commit_msg_t;

typedef nx_struct ninedof_cal_commit_ack_msg {
  nx_uint16_t mote;
  nx_uint16_t version;     /* version in force after the commit */
  nx_uint16_t crc;         /* CRC the mote computed over the staged set */
  nx_uint8_t status;       /* NINEDOF_CAL_OK or NINEDOF_CAL_E_* */
  nx_uint8_t sensors;      /* sensors corrected now */
} ninedof_cal_commit_ack_msg_t;

typedef nx_struct ninedof_cal_query_msg {
  nx_uint16_t mote;
  nx_uint8_t offset;       /* first byte wanted of the set in force */
  /* Appended with the stored-set report (NINEDOF_CAL_QUERY_SIZE_V1 bytes
   * before): a host built before sends the query without it, and an image
   * built before ignores it (it answers the report without the stored set). */
  nx_uint8_t flags;        /* NINEDOF_QUERY_STORED: answer with the stored set */
} ninedof_cal_query_msg_t;

/* Query flags */
enum {
  NINEDOF_QUERY_STORED = 0x01,  /* the report's stored_* fields are wanted */
};

typedef nx_struct ninedof_cal_report_msg {
  nx_uint16_t mote;
  nx_uint16_t version;     /* version in force */
  nx_uint16_t crc;         /* CRC of the whole set in force */
  nx_uint8_t offset;
  nx_uint8_t len;          /* 0 when offset is past the end */
  nx_uint8_t data[NINEDOF_FRAG_DATA];
  /* Appended with the stored-set report: sent only in reply to a query with
   * NINEDOF_QUERY_STORED (else the report ends here, at
   * NINEDOF_CAL_REPORT_SIZE_V1 bytes, as hosts built before expect it). */
  nx_uint16_t stored_version; /* version of the set the EEPROM holds, written and
                                 read back: the set a reset or power loss puts in
                                 force; 0: none (a reset gives raw output, version 0) */
  nx_uint16_t stored_crc;  /* CRC of that set (0 when none) */
  nx_uint8_t store;        /* NINEDOF_STORE_*: the EEPROM writer's state */
} ninedof_cal_report_msg_t;

/* The EEPROM writer's state (ninedof_cal_report_msg.store) */
enum {
  NINEDOF_STORE_IDLE = 0,       /* nothing to write: the stored set is the newest it was given */
  NINEDOF_STORE_WRITING = 1,    /* writing (or about to read back) the set in force */
  NINEDOF_STORE_FAILED = 2,     /* the set in force was written but did not read back
                                   right, NINEDOF_STORE_TRIES times: not stored */
};

/* ---------------------------------------------------------------------- */
/* Status counters                                                         */
/* ---------------------------------------------------------------------- */
typedef nx_struct ninedof_mote_status_msg {
  nx_uint16_t seq;           /* next sample sequence number */
  nx_uint16_t version;       /* calibration version in force */
  nx_uint8_t sensors;        /* sensors corrected */
  nx_uint8_t reserved;
  nx_uint16_t dropped;       /* samples lost: send queue full */
  nx_uint16_t send_fail;     /* radio sends that failed (no ack / busy) */
  nx_uint16_t i2c_errors;    /* sensor reads that failed */
  nx_uint16_t late;          /* periods whose read had not finished in time */
  /* Appended with the fault handling (ninedof_fault.h); a mote built before
   * sends the message without them (NINEDOF_MOTE_STATUS_SIZE_V1 bytes). */
  nx_uint16_t i2c_nacks;     /* I2C operations a chip did not acknowledge */
  nx_uint16_t bus_resets;    /* bus clears run: after a hung I2C operation was aborted, and each retry while the bus is down */
  nx_uint16_t chip_reinits;  /* chips found with reset registers, configured again */
} ninedof_mote_status_msg_t;

typedef nx_struct ninedof_bs_status_msg {
  nx_uint16_t radio_rx;      /* packets received from the radio */
  nx_uint16_t radio_drops;   /* radio->serial queue full */
  nx_uint16_t serial_rx;     /* packets received from the serial line */
  nx_uint16_t serial_drops;  /* serial->radio queue full */
  nx_uint16_t radio_fail;    /* radio sends that failed */
  nx_uint16_t serial_fail;   /* serial sends that failed */
} ninedof_bs_status_msg_t;

/* ---------------------------------------------------------------------- */
/* Board temperature (mote -> PC)                                          */
/* ---------------------------------------------------------------------- */
/* The ITG3200's TEMP_OUT (0x1B-0x1C) is read in the same burst as the
 * rates.  It goes in a message of its own, not in the sample header or the
 * status message, so that hosts built before it keep decoding samples and
 * status unchanged (they ignore an AM type they do not know) and hosts
 * built after it work with images that never send it.  Temperature moves
 * over minutes; one message a second per mote adds about 1 % to the link.
 * Degrees C = 35 + (temp_sum / count + 13200) / 280 (ITG-3200 datasheet). */
typedef nx_struct ninedof_mote_temp_msg {
  nx_uint16_t seq;           /* sequence number of the newest sample averaged */
  nx_uint8_t count;          /* readings summed in temp_sum (0: no reading) */
  nx_uint8_t reserved;       /* 0 */
  nx_int32_t temp_sum;       /* sum of the raw TEMP_OUT readings of the period */
} ninedof_mote_temp_msg_t;

#endif /* NINEDOF_MSG_H */
