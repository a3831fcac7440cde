/*
 * emu/emu.h -- the emulator harness's shared contract (docs/emulation.md).
 *
 * One emu_node_t per emulated mote: a simavr core (Debian's libsimavr 1.6)
 * running an iris ELF cycle by cycle.  The lockstep loop (main.c) advances
 * every node by quanta of EMU_QUANTUM_NS; the radio channel (E2's
 * channel.c) is stepped once per quantum.  E2's files (rf230.*, channel.*,
 * uart.*) use only the fields marked "contract".
 */
#ifndef EMU_H
#define EMU_H

#include <stdint.h>
#include <stdio.h>
#include "sim_avr.h"

#ifndef EMU_QUANTUM_NS
#define EMU_QUANTUM_NS 4000u
#endif

struct emu_twi;        /* twi.h */
struct emu_board;      /* board.h */

typedef struct emu_node {
    /* ---- contract: the fields the radio and UART models use ---- */
    avr_t   *avr;
    int      index;        /* 0 = first node on the command line */
    uint16_t am_addr;      /* TOS_NODE_ID (patched into the ELF's .data image) */
    double   freq_hz;      /* main clock (RC), e.g. 7.84e6 / 8.00e6 / 8.16e6 */
    void    *rf;           /* rf230_t *, set by rf230_attach (E2) */
    void    *uart;         /* uart0 endpoint, set by uart_attach (E2) */
    /* ---- E1's own fields ---- */
    const char *elf;       /* the image */
    int      is_base;      /* 1: the BaseStation (no sensor board) */
    uint64_t sleep_cycles; /* cycles the core spent in SLEEP */
    struct emu_twi *twi;   /* the TWI model + bus with the board's chips */
    struct emu_board *board;
    FILE    *console;      /* bytes the node sends on UART0 (--console), or NULL */
    uint32_t rom_bytes, ram_bytes;  /* text+data, data+bss of the image */
    void   **symbols;      /* the image's symbols (avr_symbol_t *), for --span */
    uint32_t nsymbols;
    /* --span FROM:TO: from reaching code address FROM (a function or a
     * global label) to the next time TO is reached */
    uint32_t span_from, span_to;   /* byte addresses; 0: off */
    int      span_is_open;
    uint64_t span_open;            /* cycle FROM was reached */
    uint64_t span_settle_cycle;
    double  *span_us;              /* every span closed after settle, us */
    uint64_t span_n, span_cap;
    uint32_t resets;       /* node_reset calls */
    /* what else is reset with the MCU (the TWI model: twi_attach sets it) */
    void   (*reset_hook)(void *param);
    void    *reset_param;
} emu_node_t;

/* emulated time of a node in nanoseconds: avr->cycle * 1e9 / avr->frequency */
uint64_t emu_node_now_ns(const emu_node_t *n);
/* the global lockstep time (ns): all nodes have run up to at least this */
uint64_t emu_global_now_ns(void);

#endif
