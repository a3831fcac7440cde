/*
 * emu/rf230.h -- an AT86RF230 model wired as on the IRIS mote, enough for
 * TinyOS's rf230 stack (tos/chips/rf230/RF230DriverLayerP.nc with software
 * acks) and for the small test drivers in emu/tests/rf230_*.c.
 *
 * Wiring (tos/platforms/iris/chips/rf230/HplRF230C.nc): SPI0 (SS = PB0 as
 * SELN), SLP_TR = PB7, RSTN = PA6, IRQ = PD4 = ICP1 (timer 1 input capture,
 * rising edge; simavr's timer copies TCNT1 into ICR1 and raises the capture
 * vector).  The model also replaces simavr 1.6's SPI data register handler,
 * whose transfers take a fixed 100 us per byte, by one clocked from SPCR/SPSR
 * (f_osc/2 .. f_osc/128) as the hardware is.  Details: docs/emulation-radio.md.
 */
#ifndef EMU_RF230_H
#define EMU_RF230_H

#include <stdio.h>
#include "emu.h"
#include "channel.h"

int  rf230_attach(emu_node_t *node, emu_channel_t *ch);   /* SPI + pins + IRQ of iris */
void rf230_stats(emu_node_t *node, FILE *out);            /* one line: frames tx/rx/lost/crc */

#endif
