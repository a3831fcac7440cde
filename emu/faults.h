/* emu/faults.h -- fault injection on the sensor board's bus (--fault). */
#ifndef EMU_FAULTS_H
#define EMU_FAULTS_H

#include "emu.h"

/* SPEC, times in seconds of emulated time, optional @I = node index only:
 *   nack:CHIP:T:D     CHIP (adxl345 | itg3200 | hmc5883l) NACKs its address
 *                     from T for D seconds
 *   power:CHIP:T:D    CHIP loses power at T, back after D with its reset
 *                     register values (NACKs everything meanwhile)
 *   short:LINE:T[:D]  LINE (sda | scl) shorted to ground from T for D
 *                     seconds (without D: to the end of the run); only its
 *                     end frees the line, no bus clear can
 *   stuck:CHIP:T[:N]  CHIP gets stuck in the first read transaction from T
 *                     on: one clock behind, it holds SDA low over the STOP
 *                     until N more SCL pulses have come (1..9, default 8):
 *                     the bus stays busy until something clocks it
 *   unread:T:D        the host does not read the serial line (--serial) from T
 *                     for D seconds: what the MCU sends meanwhile is dropped
 * Returns 0, or -1 with a message on stderr. */
int fault_apply(const char *spec, emu_node_t **nodes, int n);

#endif
