/* emu/board.h -- what the 9DOF board senses: true raw counts over time. */
#ifndef EMU_BOARD_H
#define EMU_BOARD_H

#include <stdint.h>

/* Axes in the firmware's record order: ax ay az gx gy gz mx my mz, raw
 * counts at the settings of tinyos/ninedof_board.c (ADXL345 full
 * resolution 256 LSB/g, ITG-3200 14.375 LSB/(deg/s), HMC5883L gain 1090
 * LSB/gauss).  The chip models rescale for other settings. */
typedef struct emu_board {
    double rate_hz;       /* rows per second (table) */
    long nrows;           /* 0: the synthetic board */
    int16_t (*rows)[9];
    float *temp_c;        /* per row (table), NaN-free */
    int temp_set;         /* 1: temp_c_set replaces the board's temperature */
    double temp_c_set;    /* the harness's temp= option, degrees C */
} emu_board_t;

/* The synthetic board (no table given): for t in whole ms k = t_ns / 1e6,
 * axis i reads EMU_SYN_BASE[i] + ((k * (i + 1)) % 512) * EMU_SYN_SIGN[i],
 * temperature 25 C.  tests/emu_board.py computes the same. */
emu_board_t *board_synthetic(void);

/* A table written by host glue (emu/board.py): first line
 *   # motecal-emu-board rate_hz=R
 * then one row per 1/R s: nine integers, optionally a tenth field, the
 * temperature in C.  After the last row the last row holds.
 * NULL (message on stderr) on a bad file. */
emu_board_t *board_load(const char *path);

/* The temperature board_truth reports from now on, whatever the board or
 * table says (ninedof-emu --mote ELF,temp=C): what the ITG-3200 model's
 * TEMP_OUT registers read. */
void board_set_temp(emu_board_t *b, double temp_c);

/* The true counts at time t_ns (row floor(t * rate)). */
void board_truth(const emu_board_t *b, uint64_t t_ns, int16_t out[9], double *temp_c);

#endif
