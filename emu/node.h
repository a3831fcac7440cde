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

/* cycles at the node's clock for a time in ns, and back */
uint64_t node_ns_to_cycles(const emu_node_t *n, uint64_t ns);

#endif
