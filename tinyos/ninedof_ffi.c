/*
 * ninedof_ffi.c -- sizes of the C structures for callers that cannot see
 * the C types (the host simulator loads this code through ctypes).  Only
 * the host library is built from this file; the firmware does not use it.
 */
#include <string.h>
#include "ninedof_cal.h"
#include "ninedof_sampling.h"

size_t ninedof_calrx_size(void) { return sizeof(ninedof_calrx_t); }
size_t ninedof_cal_size(void) { return sizeof(ninedof_cal_t); }
size_t ninedof_calset_size(void) { return sizeof(ninedof_calset_t); }
size_t ninedof_calset_temp_size(void) { return sizeof(ninedof_calset_temp_t); }
size_t ninedof_image_size(void) { return NINEDOF_IMAGE_MAX; }
size_t ninedof_eewriter_size(void) { return sizeof(ninedof_eewriter_t); }
uint16_t ninedof_eeprom_legacy1(void) { return NINEDOF_EEPROM_LEGACY1; }

uint16_t ninedof_calrx_version(const ninedof_calrx_t *rx) { return rx->active.version; }
uint8_t ninedof_calrx_sensors(const ninedof_calrx_t *rx) { return rx->active.sensors; }
uint16_t ninedof_calrx_crc(const ninedof_calrx_t *rx) { return rx->active_crc; }
uint8_t ninedof_calrx_dirty(const ninedof_calrx_t *rx) { return rx->dirty; }
void ninedof_calrx_set_dirty(ninedof_calrx_t *rx, uint8_t dirty) { rx->dirty = dirty; }

void ninedof_calrx_active(const ninedof_calrx_t *rx, uint8_t *out)
{
  memcpy(out, rx->active_wire, rx->active_len);
}

uint8_t ninedof_calrx_active_len(const ninedof_calrx_t *rx) { return rx->active_len; }

uint16_t ninedof_calrx_stored_version(const ninedof_calrx_t *rx) { return rx->stored_version; }
uint16_t ninedof_calrx_stored_crc(const ninedof_calrx_t *rx) { return rx->stored_crc; }
uint8_t ninedof_calrx_store(const ninedof_calrx_t *rx) { return rx->store; }

/* The status message as the firmware packs it (ninedof_status_pack), from
 * the counters in the order of ninedof_counters_t then
 * ninedof_fault_counters_t: seq, dropped, send_fail, i2c_errors, late,
 * nacks, bus_resets, chip_reinits.  Returns the payload length. */
uint8_t ninedof_status_payload(const uint16_t counters[8], const ninedof_calrx_t *rx,
                               uint8_t *out)
{
  ninedof_counters_t c;
  ninedof_fault_counters_t f;
  ninedof_mote_status_msg_t msg;

  memset(&c, 0, sizeof(c));             /* a counter added later and not set here: 0 */
  memset(&f, 0, sizeof(f));
  c.seq = counters[0];
  c.dropped = counters[1];
  c.send_fail = counters[2];
  c.i2c_errors = counters[3];
  c.late = counters[4];
  f.nacks = counters[5];
  f.bus_resets = counters[6];
  f.chip_reinits = counters[7];
  ninedof_status_pack(&c, &f, rx, &msg);
  memcpy(out, &msg, sizeof(msg));
  return (uint8_t)sizeof(msg);
}
