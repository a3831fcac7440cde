/*
 * emu/bus.h -- the sensor board's I2C bus as two open-drain wires, SCL and
 * SDA.  A wire is low while any driver pulls it low; otherwise the board's
 * pull-up holds it high.  The drivers:
 *
 *   - the MCU's pins PD0 (SCL) and PD1 (SDA) as general I/O: a pin that is
 *     an output at 0 (DDRD bit set, PORTD bit clear) pulls its wire low,
 *     as the firmware's bit-banged bus clear does (NineDofBusClearP), but
 *     only while the TWI is off: with TWEN set the TWI owns both pins;
 *   - the TWI (twi.c): its transfers are events of whole bytes, so its
 *     bit-level drive is not modelled here; what it needs from the wires is
 *     whether another driver holds a line (a START waits for a free bus, a
 *     1 bit on a held SDA loses arbitration, SCL held low stalls it);
 *   - a slave stuck mid-byte (--fault stuck, chips.c decides when): it
 *     holds SDA low until the clock pulses it still expects have come,
 *     from whichever driver makes them;
 *   - a line shorted to ground for a time (--fault short).
 *
 * PIND reads the wires' levels in bits 0 and 1 (the harness chains its own
 * read after simavr's port), so the firmware sees what a real pin would.
 */
#ifndef EMU_BUS_H
#define EMU_BUS_H

#include <stdio.h>
#include "emu.h"

enum { BUS_SCL, BUS_SDA, BUS_LINES };

typedef struct emu_bus {
    emu_node_t *node;
    FILE *log;                          /* transaction log (twi.c's), or NULL */
    /* a line shorted to ground from <= t < until (until UINT64_MAX: to the end) */
    uint64_t short_from[BUS_LINES], short_until[BUS_LINES];
    /* the stuck slave: SDA held until `stuck_left` more SCL falling edges */
    const char *stuck_name;             /* the chip holding SDA, or NULL */
    unsigned stuck_left, stuck_pulses;
    int scl, sda;                       /* the levels at the last update */
    int sda_pin;                        /* ... and whether the SDA pin pulled it low */
    /* what happened, for the report */
    uint64_t gpio_falls;                /* SCL falling edges made by the pins */
    uint64_t gpio_stops;                /* STOPs made by the pins (SDA rises, SCL high) */
    uint64_t stuck_holds, stuck_freed;  /* a slave began holding SDA / let go */
    uint64_t freed_ns;                  /* when the last one let go */
    unsigned freed_after;               /* ... after this many SCL pulses */
} emu_bus_t;

/* The wires on node n (PD0, PD1): PIND reads them, DDRD / PORTD / TWCR
 * writes update them. */
emu_bus_t *bus_attach(emu_node_t *n, FILE *log);

/* 1 while a driver other than the TWI holds the line low at ns */
int bus_held(const emu_bus_t *b, int line, uint64_t ns);
/* When the lines held by others free themselves: ns when neither is held,
 * the end of the shorts when only shorts hold them, UINT64_MAX when a
 * stuck slave holds SDA (only clock pulses free it). */
uint64_t bus_free_at(const emu_bus_t *b, uint64_t ns);

/* A slave (name) begins to hold SDA low until `pulses` SCL falling edges. */
void bus_stick(emu_bus_t *b, const char *name, unsigned pulses);

/* Recompute the levels after a driver changed (counts the pins' edges). */
void bus_update(emu_bus_t *b);

#endif
