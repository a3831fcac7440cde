/* emu/node.h -- one emulated mote: load an ELF into a simavr core. */
#ifndef EMU_NODE_H
#define EMU_NODE_H

#include "emu.h"

/* Load ELF into a new ATmega1281 core at freq_hz (the RC clock), patch
 * TOS_NODE_ID / ActiveMessageAddressC__addr to am_addr when the image has
 * them (as tos-set-symbols does), replace simavr's real-time sleep with
 * a counter of sleeping cycles.  NULL (message on stderr) on failure. */
emu_node_t *node_new(const char *elf, int index, uint16_t am_addr, double freq_hz);

/* Copy every byte the node writes on UART0 to f (test programs print there). */
void node_console(emu_node_t *n, FILE *f);

/* Run the node until its time reaches end_ns (or it stops).  Returns the
 * core state (cpu_Done / cpu_Crashed when the program ended). */
int node_run_until(emu_node_t *n, uint64_t end_ns);

/* The 32768 Hz crystal on timer 2 off by ppm (simavr's virtual AS2 clock,
 * a float: about 0.1 ppm resolution).  0, or -1 if simavr refuses. */
int node_crystal_ppm(emu_node_t *n, double ppm);

/* byte address of a symbol of the image, 0 if it has none */
uint32_t node_symbol(const emu_node_t *n, const char *name);

/* Time every run from code address `from` (a function's entry or a global
 * label, e.g. the firmware's NINEDOF_SPAN_MARK) to the next time `to` is
 * reached; reaching `from` again first starts the span again (a read that
 * was refused ends nothing).  Spans that start after settle_ns count.  0,
 * or -1 with a message when the image lacks one of them. */
int node_span(emu_node_t *n, const char *from, const char *to, uint64_t settle_ns);

/* The spans so far: count, mean, 99th percentile (nearest rank), min, max
 * in us (all 0 without any). */
typedef struct { uint64_t n; double mean, p99, min, max; } node_span_stats_t;
node_span_stats_t node_span_stats(const emu_node_t *n);

/* Reset the MCU as its RESET pin would (simavr's avr_reset: registers,
 * PC 0, interrupts and cycle timers cleared; RAM as it was; the program's
 * start-up code runs again), keeping its EEPROM and the time, and calls
 * n->reset_hook (the TWI model cuts a transfer in progress); the board's
 * chips and the radio (reset by the firmware's RSTN) are not reset.  0, or
 * -1 if the EEPROM could not be saved (it is then what simavr left). */
int node_reset(emu_node_t *n);

/* cycles at the node's clock for a time in ns, and back */
uint64_t node_ns_to_cycles(const emu_node_t *n, uint64_t ns);

#endif
