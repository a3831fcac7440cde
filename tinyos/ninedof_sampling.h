/*
 * ninedof_sampling.h -- the sampling app's logic in plain C: sequence
 * numbers, batching records into ninedof_samples_msg,
 * status counters, and the background EEPROM writer of the calibration
 * image.  NineDofAppP.nc (nesC) only wires these to timers, the radio and
 * the EEPROM; tests run them with gcc and in simavr.  The 125 Hz period
 * itself is ninedof_clock.h.
 */
#ifndef NINEDOF_SAMPLING_H
#define NINEDOF_SAMPLING_H

#include <stdint.h>
#include "NineDofMsg.h"
#include "ninedof_cal.h"
#include "ninedof_fault.h"

/* Where samples and status go, and how they are sent */
#ifndef NINEDOF_BASESTATION_ADDR
#define NINEDOF_BASESTATION_ADDR 0      /* TOS_NODE_ID of the BaseStation */
#endif
#ifndef NINEDOF_RETRIES
#define NINEDOF_RETRIES 2               /* resends of an unacknowledged sample message or
                                           calibration reply (PacketLink, same DSN) */
#endif
#ifndef NINEDOF_SEND_QUEUE
#define NINEDOF_SEND_QUEUE 4            /* sample messages waiting for the radio */
#endif

/* ---------------------------------------------------------------------- */
/* Counters (wrap at 65536; the host takes differences)                    */
/* ---------------------------------------------------------------------- */
typedef struct {
  uint16_t seq;          /* sequence number of the next period */
  uint16_t dropped;      /* samples lost because the send queue was full */
  uint16_t send_fail;    /* radio sends that failed (no ack after retries / busy) */
  uint16_t i2c_errors;   /* sensor reads that failed */
  uint16_t late;         /* periods skipped: the previous read was still running */
} ninedof_counters_t;

void ninedof_counters_init(ninedof_counters_t *c);

/* Fill a ninedof_mote_status_msg from the app's counters, the board's
 * fault counters and the set in force. */
void ninedof_status_pack(const ninedof_counters_t *c, const ninedof_fault_counters_t *f,
                         const ninedof_calrx_t *rx, ninedof_mote_status_msg_t *msg);

/* ---------------------------------------------------------------------- */
/* One instant per record                                                  */
/* ---------------------------------------------------------------------- */
/* A board read returns the accelerometer and gyroscope of its own instant,
 * but the HMC5883L's data registers hold the measurement that the previous
 * read triggered (each read writes MODE = single, which starts the next
 * one: ninedof_board.h).  The aligner holds a read's accel and gyro until
 * the next read brings the field measured at that read, and puts them in
 * one record with the sequence number of the earlier read: every record is
 * one instant (the field measured within about 1 ms of the accel/gyro
 * read), one period (8 ms) later than the read.
 *
 * A skipped period (late) changes nothing: the next read's field still
 * comes from the last read's trigger.  After a failed read it is not known
 * whether its trigger went out, so the next read starts over (no record). */
typedef struct {
  uint16_t seq;                /* period of the held read */
  uint8_t held;                /* a read is held */
  int16_t ag[6];               /* its ax ay az gx gy gz */
} ninedof_align_t;

void ninedof_align_init(ninedof_align_t *a);

/* A read of period `seq` succeeded with `rec` (ax..mz as read).  Returns 1
 * and fills `out` / `out_seq` when it completes the held read's record. */
uint8_t ninedof_align_push(ninedof_align_t *a, uint16_t seq, const int16_t rec[9],
                           int16_t out[9], uint16_t *out_seq);

/* A read failed: the held read can no longer be completed. */
void ninedof_align_lost(ninedof_align_t *a);

/* ---------------------------------------------------------------------- */
/* Board temperature                                                       */
/* ---------------------------------------------------------------------- */
/* Every successful read brings the ITG-3200's raw TEMP_OUT (same burst as
 * the rates).  The readings of one NINEDOF_TEMP_PERIOD_MS are summed; at
 * the end of the period the sum goes out in a ninedof_mote_temp_msg and
 * its mean (rounded to the nearest count) is the temperature the on-mote
 * correction uses for the next period (ninedof_calrx_set_temp). */
typedef struct {
  int32_t sum;                 /* raw TEMP_OUT readings summed this period */
  uint8_t count;               /* readings in sum (saturates at 255) */
  uint16_t seq;                /* sequence number of the newest reading's sample */
} ninedof_temp_acc_t;

void ninedof_temp_init(ninedof_temp_acc_t *t);

/* The read of period `seq` gave TEMP_OUT `raw`. */
void ninedof_temp_add(ninedof_temp_acc_t *t, uint16_t seq, int16_t raw);

/* End of a period: fill the message, start the next period.  Returns 1 and
 * the period's mean in *mean (rounded half away from zero) if it had a
 * reading, else 0 (the message then has count 0 and the seq of the last
 * reading ever made). */
uint8_t ninedof_temp_pack(ninedof_temp_acc_t *t, ninedof_mote_temp_msg_t *msg,
                          int16_t *mean);

/* ---------------------------------------------------------------------- */
/* Batching                                                                */
/* ---------------------------------------------------------------------- */
/* Records of consecutive periods, kept raw in host order; corrected and
 * packed when the batch is sent, so one calibration set and one flags byte
 * cover the whole message. */
typedef struct {
  uint16_t seq;                          /* sequence number of rec[0] */
  uint8_t count;
  int16_t rec[NINEDOF_BATCH][9];
} ninedof_batch_t;

void ninedof_batch_init(ninedof_batch_t *b);

/* Can a record of period `seq` join the batch?  No if it is full or the
 * record does not follow the last one (a period was skipped or failed):
 * only rec[0]'s sequence number travels, so records must be consecutive. */
uint8_t ninedof_batch_fits(const ninedof_batch_t *b, uint16_t seq);

/* Append (the caller checked ninedof_batch_fits); returns 1 when full. */
uint8_t ninedof_batch_add(ninedof_batch_t *b, uint16_t seq, const int16_t rec[9]);

/* Correct the records with the set in force (updating its rounding
 * residuals), write the message, empty the batch; returns the payload
 * length (4 + 18 * count), 0 if it was empty. */
uint8_t ninedof_batch_pack(ninedof_batch_t *b, ninedof_calrx_t *rx,
                           ninedof_samples_msg_t *msg);

/* ---------------------------------------------------------------------- */
/* Background EEPROM writer                                                */
/* ---------------------------------------------------------------------- */
/* Writes the image of the set in force into the slot that does not hold
 * the newest valid image, one byte per step (an EEPROM byte write takes
 * 3.4 ms; sampling goes on meanwhile), then reads the slot back: only an
 * image read back intact is stored (rx->stored_*, the report's stored set),
 * and only then does the next image go to the other slot.  A reset or power
 * loss before that leaves the slot with a bad CRC or an older generation,
 * and boot takes the other slot: the stored set.  A commit during a write
 * restarts the write of the newer image into the same slot.  An image that
 * does not read back right is written again (bytes already right are
 * skipped), NINEDOF_STORE_TRIES times in all; then rx->store =
 * NINEDOF_STORE_FAILED and the stored set stays the older one. */
#ifndef NINEDOF_STORE_TRIES
#define NINEDOF_STORE_TRIES 3
#endif

typedef struct {
  uint8_t image[NINEDOF_IMAGE_MAX];
  uint8_t len;                 /* bytes of the image being written; 0 when idle */
  uint8_t pos;                 /* next byte to hand out; == len: all out, to be checked */
  uint8_t slot;                /* slot being written / to write next */
  uint8_t tries;               /* writes of this image checked and found wrong */
  uint16_t generation;         /* generation being written / to write next */
  uint16_t version;            /* the set in the image: its version ... */
  uint16_t crc;                /* ... and CRC (the report's stored_version, stored_crc) */
} ninedof_eewriter_t;

/* After ninedof_calrx_restore(): where to write next. */
void ninedof_eewriter_init(ninedof_eewriter_t *w, uint8_t next_slot,
                           uint16_t next_generation);

/* If rx->dirty, snapshot its image, clear dirty and (re)start writing
 * (rx->store = NINEDOF_STORE_WRITING).  Returns 1 if a write was started. */
uint8_t ninedof_eewriter_poll(ninedof_eewriter_t *w, ninedof_calrx_t *rx);

/* The next byte to write: 1 and its EEPROM address and value, or 0 when
 * every byte of the image was handed out (or nothing is being written). */
uint8_t ninedof_eewriter_next(ninedof_eewriter_t *w, uint16_t *addr, uint8_t *value);

/* Every byte was handed out and the image waits for ninedof_eewriter_check:
 * read w->len bytes at ninedof_eewriter_addr(w) once the last write is done. */
uint8_t ninedof_eewriter_pending(const ninedof_eewriter_t *w);
uint16_t ninedof_eewriter_addr(const ninedof_eewriter_t *w);

/* What the EEPROM holds at the slot (w->len bytes, read after the last
 * write completed), against the image:
 *   NINEDOF_EE_STORED  the same: rx->stored_* = the image's set, rx->store =
 *                      NINEDOF_STORE_IDLE, the next image goes to the other
 *                      slot with the next generation; the writer is idle
 *   NINEDOF_EE_AGAIN   not the same: the image is written again (next())
 *   NINEDOF_EE_FAILED  not the same, NINEDOF_STORE_TRIES times: rx->store =
 *                      NINEDOF_STORE_FAILED, the writer is idle, the stored
 *                      set and the slot to write next stay as they were
 * (0 if nothing was pending). */
enum { NINEDOF_EE_STORED = 1, NINEDOF_EE_AGAIN = 2, NINEDOF_EE_FAILED = 3 };
uint8_t ninedof_eewriter_check(ninedof_eewriter_t *w, ninedof_calrx_t *rx,
                               const uint8_t *slot_bytes);

/* A write is under way or waits for its check. */
uint8_t ninedof_eewriter_busy(const ninedof_eewriter_t *w);

/* EEPROM address of a slot */
uint16_t ninedof_slot_addr(uint8_t slot);

#endif /* NINEDOF_SAMPLING_H */
