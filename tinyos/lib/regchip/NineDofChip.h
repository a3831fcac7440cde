/*
 * NineDofChip.h -- nesC side of the register-table chip driver
 * (NineDofChipP): the chip descriptors, register tables and data
 * conversion of ninedof_board.c (plain C, tested on the host and in
 * simavr), compiled in here once for the whole application, and the type
 * a read returns.
 */
#ifndef NINEDOF_CHIP_NESC_H
#define NINEDOF_CHIP_NESC_H

#include "ninedof_board.h"
#include "ninedof_board.c"

/* Three axes of one chip, in counts, host byte order (x, y, z), and the
 * chip's temperature where its read carries one (ITG-3200: raw TEMP_OUT,
 * read in the same burst as the rates; 0 for the other chips) */
typedef struct {
  int16_t xyz[3];
  int16_t temp;
} ninedof_xyz_t;

#endif
