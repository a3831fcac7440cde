/*
 * NineDofBoard.h -- nesC side of the 9DOF board drivers.
 *
 * nesC has no separate C compilation units, so the board's plain C
 * (ninedof_fault.c: watchdog, bus clear, configuration check, tested on
 * the host and in simavr) is compiled in here, once for the whole
 * application; the chips' (ninedof_board.c) comes with NineDofChip.h.
 */
#ifndef NINEDOF_BOARD_NESC_H
#define NINEDOF_BOARD_NESC_H

#include "NineDofChip.h"
#include "ninedof_fault.h"
#include "ninedof_fault.c"

/* Nine axes of one sample: ax ay az gx gy gz mx my mz, and the board
 * temperature read with them (the ITG-3200's raw TEMP_OUT, same burst as
 * the rates) */
typedef struct {
  int16_t axis[9];
  int16_t temp;
} ninedof_raw_t;

/* A global label at this point of the code, no instruction: the emulator
 * harness times the board's read from its entry (ninedof_span_read) to the
 * readDone signal (ninedof_span_readdone) by the program counter
 * (`ninedof-emu --span ninedof_span_read:ninedof_span_readdone`, what
 * `make emulate` and bench/bench_cycles.py ask for).  Each label may stand
 * once in an image: the assembler refuses a second copy, so an image in
 * which the compiler duplicated the code does not build. */
#define NINEDOF_SPAN_MARK(name) asm volatile (".global " #name "\n" #name ":")

/* The chips' shares of the board's bus (NineDofBusP), in reading order:
 * NINEDOF_CHIP_ACCEL, _GYRO, _MAG (ninedof_board.h) */

#endif
