/*
 * emu/node.c -- one emulated mote on Debian's libsimavr 1.6.
 */
#include <errno.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_core.h"
#include "avr_uart.h"
#include "avr_timer.h"
#include "avr_eeprom.h"

#include "node.h"

uint64_t emu_node_now_ns(const emu_node_t *n)
{
    const avr_t *a = n->avr;
    return (uint64_t)((long double)a->cycle * 1e9L / (long double)n->freq_hz);
}

uint64_t node_ns_to_cycles(const emu_node_t *n, uint64_t ns)
{
    return (uint64_t)((long double)ns * (long double)n->freq_hz / 1e9L + 0.5L);
}

/* simavr's raw sleep waits in real time; the harness runs as fast as it can
 * and counts the sleeping cycles instead (CPU load = 1 - sleep / cycles). */
static void node_sleep(avr_t *avr, avr_cycle_count_t how_long)
{
    emu_node_t *n = avr->custom.data;
    n->sleep_cycles += how_long + 1;      /* sim_avr.c adds 1 + how_long */
}

/* simavr 1.6's run loop (avr_callback_run_raw), with one difference: an
 * interrupt that became pending while interrupts were off is taken when
 * SLEEP follows SEI.  The AVR executes the instruction after SEI and then
 * the interrupt, so `sei; sleep; cli` (TinyOS's McuSleep) sleeps not at
 * all and runs the handler before the CLI.  In simavr 1.6 SLEEP does not
 * sleep when an interrupt is pending, but its two-instruction SEI delay
 * lets the CLI come first, so the interrupt waits for the next SEI that
 * is not followed by a CLI: with nothing else to wake the mote, forever. */
static void span_check(emu_node_t *n, avr_flashaddr_t pc)
{
    avr_t *avr = n->avr;
    if (pc == n->span_from) {
        n->span_open = avr->cycle;
        n->span_is_open = 1;
    } else if (pc == n->span_to && n->span_is_open) {
        if (n->span_open >= n->span_settle_cycle) {
            if (n->span_n == n->span_cap) {
                n->span_cap = n->span_cap ? 2 * n->span_cap : 4096;
                n->span_us = realloc(n->span_us, n->span_cap * sizeof *n->span_us);
            }
            n->span_us[n->span_n++] = (avr->cycle - n->span_open) * 1e6 / n->freq_hz;
        }
        n->span_is_open = 0;
    }
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

node_span_stats_t node_span_stats(const emu_node_t *n)
{
    node_span_stats_t s = { 0, 0, 0, 0, 0 };
    if (!n->span_n)
        return s;
    double *v = malloc(n->span_n * sizeof *v);
    memcpy(v, n->span_us, n->span_n * sizeof *v);
    qsort(v, n->span_n, sizeof *v, cmp_double);
    double sum = 0;
    for (uint64_t i = 0; i < n->span_n; i++)
        sum += v[i];
    uint64_t rank = (uint64_t)((99 * n->span_n + 99) / 100);     /* nearest rank, 1-based */
    s = (node_span_stats_t){ n->span_n, sum / n->span_n, v[rank - 1], v[0], v[n->span_n - 1] };
    free(v);
    return s;
}

static void node_run_one(avr_t *avr)
{
    avr_flashaddr_t new_pc = avr->pc;
    if (avr->state == cpu_Running) {
        uint16_t op = (uint16_t)(avr->flash[avr->pc] | (avr->flash[avr->pc + 1] << 8));
        emu_node_t *n = avr->custom.data;
        if (n->span_from)
            avr->run_cycle_count = 1;     /* one instruction per call: every pc is seen */
        new_pc = avr_run_one(avr);
        if (n->span_from)
            span_check(n, new_pc);
        if (op == 0x9588 && avr->state == cpu_Running && avr->sreg[S_I]
            && avr->interrupt_state < 0 && avr_has_pending_interrupts(avr))
            avr->interrupt_state = 1;
    }
    avr_cycle_count_t sleep = avr_cycle_timer_process(avr);
    avr->pc = new_pc;
    if (avr->state == cpu_Sleeping) {
        if (!avr->sreg[S_I]) {
            avr->state = cpu_Done;
            return;
        }
        avr->sleep(avr, sleep);
        avr->cycle += 1 + sleep;
    }
    if (avr->state == cpu_Running || avr->state == cpu_Sleeping) {
        if (avr->interrupt_state)
            avr_service_interrupts(avr);
    }
}

static void uart_out(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    emu_node_t *n = param;
    if (n->console) {
        fputc((int)(value & 0xFF), n->console);
        fflush(n->console);
    }
}

void node_console(emu_node_t *n, FILE *f)
{
    n->console = f;
    avr_irq_t *irq = avr_io_getirq(n->avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT);
    if (irq)
        avr_irq_register_notify(irq, uart_out, n);
}

/* Patch a 16-bit initialised variable in the flash copy of .data (what
 * __do_copy_data copies to RAM at reset): text + (addr - data start). */
static int patch_u16(elf_firmware_t *fw, const char *name, uint16_t v)
{
#if ELF_SYMBOLS
    uint32_t data_start = 0, addr = 0;
    int found = 0;
    for (uint32_t i = 0; i < fw->symbolcount; i++) {
        avr_symbol_t *s = fw->symbol[i];
        if (!strcmp(s->symbol, "__data_start"))
            data_start = s->addr;
        else if (!strcmp(s->symbol, name)) {
            addr = s->addr;
            found = 1;
        }
    }
    if (!found || !data_start || addr < data_start)
        return 0;
    uint32_t off = fw->flashsize - fw->datasize + (addr - data_start);
    if (off + 2 > fw->flashsize)
        return 0;
    fw->flash[off] = (uint8_t)v;
    fw->flash[off + 1] = (uint8_t)(v >> 8);
    return 1;
#else
    (void)fw; (void)name; (void)v;
    return 0;
#endif
}

/* simavr's messages: errors and warnings on stderr, nothing on stdout
 * (the report goes there) */
static void node_logger(avr_t *avr, const int level, const char *fmt, va_list ap)
{
    (void)avr;
    if (level <= LOG_WARNING) {
        fputs("simavr: ", stderr);
        vfprintf(stderr, fmt, ap);
    }
}

emu_node_t *node_new(const char *elf, int index, uint16_t am_addr, double freq_hz)
{
    avr_global_logger_set(node_logger);
    /* checked here so a bad file gives one line (simavr's loader adds its own) */
    FILE *f = fopen(elf, "rb");
    unsigned char magic[4] = { 0 };
    if (!f) {
        fprintf(stderr, "ninedof-emu: cannot open %s: %s\n", elf, strerror(errno));
        return NULL;
    }
    size_t got = fread(magic, 1, 4, f);
    fclose(f);
    if (got != 4 || memcmp(magic, "\177ELF", 4)) {
        fprintf(stderr, "ninedof-emu: %s is not an ELF file\n", elf);
        return NULL;
    }
    elf_firmware_t fw;
    memset(&fw, 0, sizeof fw);
    if (elf_read_firmware(elf, &fw) != 0 || !fw.flash) {
        fprintf(stderr, "ninedof-emu: cannot load %s\n", elf);
        return NULL;
    }
    avr_t *avr = avr_make_mcu_by_name("atmega1281");
    if (!avr) {
        fprintf(stderr, "ninedof-emu: libsimavr has no atmega1281\n");
        return NULL;
    }
    emu_node_t *n = calloc(1, sizeof *n);
    n->avr = avr;
    n->index = index;
    n->am_addr = am_addr;
    n->freq_hz = freq_hz;
    n->elf = elf;
    n->rom_bytes = fw.flashsize;
    n->ram_bytes = fw.datasize + fw.bsssize;

#if ELF_SYMBOLS
    n->symbols = (void **)fw.symbol;
    n->nsymbols = fw.symbolcount;
#endif
    patch_u16(&fw, "TOS_NODE_ID", am_addr);
    patch_u16(&fw, "ActiveMessageAddressC__addr", am_addr);
    patch_u16(&fw, "ActiveMessageAddressC$addr", am_addr);

    strcpy(fw.mmcu, "atmega1281");
    fw.frequency = (uint32_t)(freq_hz + 0.5);
    avr_init(avr);
    avr->log = LOG_ERROR;
    avr_load_firmware(avr, &fw);
    avr->frequency = (uint32_t)(freq_hz + 0.5);
    avr->custom.data = n;
    avr->sleep = node_sleep;
    avr->run = node_run_one;

    /* no console echo of UART0 by simavr itself (it would print coloured
     * lines on stdout): the harness copies bytes where it is asked to */
    uint32_t flags = 0;
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~(uint32_t)(AVR_UART_FLAG_STDIO | AVR_UART_FLAG_POLL_SLEEP);   /* no real-time sleeps */
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    return n;
}

int node_crystal_ppm(emu_node_t *n, double ppm)
{
    float f = (float)(32768.0 * (1.0 + ppm * 1e-6));
    return avr_ioctl(n->avr, AVR_IOCTL_TIMER_SET_FREQCLK('2'), &f) == 0 ? 0 : -1;
}

uint32_t node_symbol(const emu_node_t *n, const char *name)
{
    for (uint32_t i = 0; i < n->nsymbols; i++) {
        const avr_symbol_t *s = n->symbols[i];
        if (!strcmp(s->symbol, name))
            return s->addr;
    }
    return 0;
}

int node_span(emu_node_t *n, const char *from, const char *to, uint64_t settle_ns)
{
    uint32_t a = node_symbol(n, from), b = node_symbol(n, to);
    if (!a || !b || a >= 0x800000 || b >= 0x800000) {
        fprintf(stderr, "ninedof-emu: %s has no function %s\n", n->elf, a ? to : from);
        return -1;
    }
    n->span_from = a;
    n->span_to = b;
    n->span_settle_cycle = node_ns_to_cycles(n, settle_ns);
    return 0;
}

static avr_cycle_count_t quantum_end(avr_t *avr, avr_cycle_count_t when, void *param)
{
    (void)avr; (void)when; (void)param;
    return 0;     /* only there so a sleeping core wakes at the quantum's end */
}

int node_run_until(emu_node_t *n, uint64_t end_ns)
{
    avr_t *avr = n->avr;
    uint64_t end = node_ns_to_cycles(n, end_ns);
    if (avr->cycle >= end)
        return avr->state;
    avr_cycle_timer_register(avr, end - avr->cycle, quantum_end, n);
    while (avr->cycle < end) {
        int st = avr_run(avr);
        if (st == cpu_Done || st == cpu_Crashed)
            return st;
    }
    return avr->state;
}

int node_reset(emu_node_t *n)
{
    /* the ATmega1281's EEPROM keeps its bytes through a reset; simavr 1.6's
     * avr_reset leaves its EEPROM alone too, but the harness saves and
     * restores the 4 KB anyway, so a later simavr cannot change that */
    static uint8_t ee[4096];
    avr_eeprom_desc_t d = { .ee = ee, .offset = 0, .size = sizeof ee };
    int saved = avr_ioctl(n->avr, AVR_IOCTL_EEPROM_GET, &d) == 0;
    avr_reset(n->avr);            /* I/O registers, SP, PC, SREG, interrupts, timers */
    if (saved) {
        d.ee = ee;
        avr_ioctl(n->avr, AVR_IOCTL_EEPROM_SET, &d);
    }
    if (n->reset_hook)
        n->reset_hook(n->reset_param);
    n->span_is_open = 0;
    n->resets++;
    return saved ? 0 : -1;
}
