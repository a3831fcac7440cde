/*
 * ninedof_cal.h -- on-mote calibration: fixed-point correction, validation,
 * the upload receiver, and the persistent image.  Plain C (C99, no floats):
 * compiled into the nesC firmware, tested with gcc and avr-gcc/simavr, and
 * built as a shared library that the host simulator calls through ctypes
 * (host/motecal/firmware/mote_c.py), so the simulated mote and the firmware
 * run the same code and produce bit-identical corrected samples.
 *
 * One header per part, each implemented in the .c file of its name:
 *   ninedof_calset.h   the set: native form, wire format (CRC, lengths,
 *                      encode, decode), the raw set, validation
 *   ninedof_correct.h  the fixed-point correction (temperature terms,
 *                      rounding with error feedback) and its proof
 *   ninedof_calrx.h    the upload receiver and the persistent image
 * This header includes the three and declares the accessors ninedof_ffi.c
 * defines for the host.
 */
#ifndef NINEDOF_CAL_H
#define NINEDOF_CAL_H

#include <stddef.h>
#include <stdint.h>
#include "ninedof_calset.h"
#include "ninedof_correct.h"
#include "ninedof_calrx.h"

/* ------------------------------------------------------------------------
 * Sizes and accessors for foreign-function callers
 * (host/motecal/firmware/mote_c.py through ctypes), defined in
 * ninedof_ffi.c, which the firmware does not build.
 * ---------------------------------------------------------------------- */
size_t ninedof_calrx_size(void);      /* sizeof(ninedof_calrx_t) */
size_t ninedof_cal_size(void);        /* sizeof(ninedof_cal_t) */
size_t ninedof_calset_size(void);     /* sizeof(ninedof_calset_t) */
size_t ninedof_calset_temp_size(void); /* sizeof(ninedof_calset_temp_t) */
size_t ninedof_image_size(void);      /* NINEDOF_IMAGE_MAX */
uint16_t ninedof_eeprom_legacy1(void); /* NINEDOF_EEPROM_LEGACY1 */
/* Fields of the receiver state, without knowing its layout */
uint16_t ninedof_calrx_version(const ninedof_calrx_t *rx);  /* version in force */
uint8_t ninedof_calrx_sensors(const ninedof_calrx_t *rx);   /* sensors corrected */
uint16_t ninedof_calrx_crc(const ninedof_calrx_t *rx);      /* CRC of the set in force */
uint8_t ninedof_calrx_dirty(const ninedof_calrx_t *rx);
void ninedof_calrx_set_dirty(ninedof_calrx_t *rx, uint8_t dirty);
/* Wire bytes of the set in force (ninedof_calrx_active_len of them) */
void ninedof_calrx_active(const ninedof_calrx_t *rx, uint8_t *out);
uint8_t ninedof_calrx_active_len(const ninedof_calrx_t *rx);
/* The stored set (version 0: none) and the EEPROM writer's state */
uint16_t ninedof_calrx_stored_version(const ninedof_calrx_t *rx);
uint16_t ninedof_calrx_stored_crc(const ninedof_calrx_t *rx);
uint8_t ninedof_calrx_store(const ninedof_calrx_t *rx);

#endif /* NINEDOF_CAL_H */
