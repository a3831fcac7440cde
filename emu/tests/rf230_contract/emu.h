/*
 * The harness contract of docs/emulation.md (emu-api.md), for building the
 * radio's own test harness (rf230_test_main.c) before or without E1's
 * emu/emu.h.  Only used when emu/emu.h is not on the include path first.
 */
#ifndef EMU_H
#define EMU_H

#include <stdint.h>
#include <stdio.h>
#include "sim_avr.h"

#ifndef EMU_QUANTUM_NS
#define EMU_QUANTUM_NS 4000u
#endif

typedef struct emu_node {
    avr_t   *avr;
    int      index;
    uint16_t am_addr;
    double   freq_hz;
    void    *rf;
    void    *uart;
} emu_node_t;

uint64_t emu_node_now_ns(const emu_node_t *n);
uint64_t emu_global_now_ns(void);

#endif
