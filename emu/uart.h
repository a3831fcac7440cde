/*
 * emu/uart.h -- a node's UART0 as the host sees a mote's serial port: a
 * pseudo-terminal or a TCP port on 127.0.0.1 (see docs/emulation-radio.md).
 *
 * Bytes the MCU sends appear on the host side when their last bit would
 * have left the UART (10 bits per byte at the rate UBRR0/U2X0 give); bytes
 * from the host enter the MCU's receiver at the same line rate, only while
 * simavr's receive FIFO has room (its XON/XOFF signals).  A byte the host
 * side cannot take (no TCP client, pty buffer full, or inside an "unread"
 * window set by uart_set_unread) is dropped and counted, as a full host
 * buffer drops it.
 */
#ifndef EMU_UART_H
#define EMU_UART_H

#include <stdio.h>
#include "emu.h"

/* spec: "pty" (prints the pty path on stdout), "tcp:PORT" (127.0.0.1 only,
 * PORT 0 = any free port; prints socket://127.0.0.1:PORT) or "null" */
int  uart_attach(emu_node_t *node, const char *spec);
void uart_poll(emu_node_t *node, uint64_t now_ns);       /* called once per quantum */
void uart_set_unread(emu_node_t *node, uint64_t from_ns, uint64_t until_ns);
void uart_stats(emu_node_t *node, FILE *out);           /* one line */
/* the endpoint's pyserial URL or pty path ("" for null) */
const char *uart_url(emu_node_t *node);

#endif
