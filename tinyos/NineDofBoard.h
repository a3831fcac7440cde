/*
 * NineDofBoard.h -- nesC side of the 9DOF board drivers.
 *
 * nesC has no separate C compilation units, so the board's plain C
 * (ninedof_board.c: register tables, chip descriptors and data
 * conversion; ninedof_fault.c: watchdog, bus clear, configuration check;
 * both tested on the host and in simavr) is compiled in here, once for
 * the whole application.
 */
#ifndef NINEDOF_BOARD_NESC_H
#define NINEDOF_BOARD_NESC_H

#include "ninedof_board.h"
#include "ninedof_fault.h"
#include "ninedof_board.c"
#include "ninedof_fault.c"

/* Three axes of one chip, in counts, host byte order (x, y, z) */
typedef struct {
  int16_t xyz[3];
} ninedof_xyz_t;

/* Nine axes of one sample: ax ay az gx gy gz mx my mz */
typedef struct {
  int16_t axis[9];
} ninedof_raw_t;

/* The chips' shares of the board's bus (NineDofBusP), in reading order:
 * NINEDOF_CHIP_ACCEL, _GYRO, _MAG (ninedof_board.h) */

#endif
