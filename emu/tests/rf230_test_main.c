/*
 * emu/tests/rf230_test_main.c -- a minimal lockstep harness for the radio
 * and UART models (rf230.c, channel.c, uart.c), independent of the full
 * harness (main.c): loads ELF images with Debian's libsimavr, runs them in
 * quanta of EMU_QUANTUM_NS, steps the channel and polls the UARTs once per
 * quantum.  Used by tests/test_emu_radio.py and docs/emulation-radio.md.
 *
 *   rf230-test [--loss P] [--seed N] [--ms T] [--realtime] [--stop-when-done]
 *              --node ELF[,mhz=F][,id=N][,serial=SPEC][,console=FILE]
 *                    [,unread=FROM_MS:UNTIL_MS] ...
 *
 * Ends after T emulated ms (default 1000) or, with --stop-when-done, when
 * every node has stopped (sleep with interrupts off).  Prints one stats line
 * per radio, per UART and for the channel on stderr.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <fcntl.h>
#include <unistd.h>

#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_irq.h"
#include "sim_cycle_timers.h"
#include "sim_core.h"
#include "sim_interrupts.h"
#include "avr_uart.h"

#include "emu.h"
#include "channel.h"
#include "rf230.h"
#include "uart.h"

#define MAX_NODES 16

static uint64_t g_now;

uint64_t emu_node_now_ns(const emu_node_t *n)
{
    return (uint64_t)((long double)n->avr->cycle * 1e9L / (long double)n->avr->frequency);
}

uint64_t emu_global_now_ns(void)
{
    return g_now;
}

static void no_sleep(avr_t *avr, avr_cycle_count_t how_long)
{
    (void)avr; (void)how_long;   /* run as fast as possible */
}

/* simavr 1.6's run loop with one change (the same as the full harness's
 * node.c): an interrupt that became pending while interrupts were off is
 * taken when SLEEP follows SEI, as on the AVR (SEI lets one more
 * instruction run); TinyOS's McuSleep (sei; sleep; cli) needs it. */
static void run_one(avr_t *avr)
{
    avr_flashaddr_t new_pc = avr->pc;
    if (avr->state == cpu_Running) {
        uint16_t op = (uint16_t)(avr->flash[avr->pc] | (avr->flash[avr->pc + 1] << 8));
        new_pc = avr_run_one(avr);
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
        avr->cycle += 1 + sleep;
    }
    if (avr->state == cpu_Running || avr->state == cpu_Sleeping) {
        if (avr->interrupt_state)
            avr_service_interrupts(avr);
    }
}

static void console_out(avr_irq_t *irq, uint32_t v, void *param)
{
    (void)irq;
    fputc((int)(v & 0xFF), (FILE *)param);
    fflush((FILE *)param);
}

static avr_cycle_count_t quantum_end(avr_t *avr, avr_cycle_count_t when, void *param)
{
    (void)avr; (void)when; (void)param;
    return 0;
}

static void patch_u16(elf_firmware_t *fw, const char *name, uint16_t v)
{
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
    if (!found || addr < data_start)
        return;
    uint32_t off = fw->flashsize - fw->datasize + (addr - data_start);
    if (off + 2 <= fw->flashsize) {
        fw->flash[off] = (uint8_t)v;
        fw->flash[off + 1] = (uint8_t)(v >> 8);
    }
}

static void usage(void)
{
    fprintf(stderr, "usage: rf230-test [--loss P] [--seed N] [--ms T] [--realtime] [--stop-when-done] "
            "--node ELF[,mhz=F][,id=N][,serial=pty|tcp:PORT|null][,console=FILE][,unread=A:B] ...\n");
    exit(2);
}

int main(int argc, char **argv)
{
    double loss = 0;
    uint32_t seed = 1;
    double ms = 1000;
    int realtime = 0, stop_when_done = 0;
    emu_node_t *nodes[MAX_NODES];
    int nn = 0;
    struct { char *serial, *console; double ufrom, uuntil; } opt[MAX_NODES];
    memset(opt, 0, sizeof opt);

    /* parse everything first (bad input: one line, exit 2) */
    char *elfs[MAX_NODES];
    double mhz[MAX_NODES];
    int ids[MAX_NODES];
    for (int i = 1; i < argc; i++) {
        char *a = argv[i];
        if (!strcmp(a, "--loss") && i + 1 < argc) {
            loss = atof(argv[++i]);
            if (loss < 0 || loss > 1) { fprintf(stderr, "rf230-test: --loss must be in 0..1\n"); return 2; }
        } else if (!strcmp(a, "--seed") && i + 1 < argc) {
            seed = (uint32_t)strtoul(argv[++i], NULL, 10);
        } else if (!strcmp(a, "--ms") && i + 1 < argc) {
            ms = atof(argv[++i]);
        } else if (!strcmp(a, "--realtime")) {
            realtime = 1;
        } else if (!strcmp(a, "--stop-when-done")) {
            stop_when_done = 1;
        } else if (!strcmp(a, "--node") && i + 1 < argc) {
            if (nn == MAX_NODES) { fprintf(stderr, "rf230-test: too many nodes\n"); return 2; }
            char *spec = strdup(argv[++i]);
            char *save = NULL;
            elfs[nn] = strtok_r(spec, ",", &save);
            mhz[nn] = 8.0;
            ids[nn] = nn;
            for (char *kv; (kv = strtok_r(NULL, ",", &save));) {
                if (!strncmp(kv, "mhz=", 4)) mhz[nn] = atof(kv + 4);
                else if (!strncmp(kv, "id=", 3)) ids[nn] = atoi(kv + 3);
                else if (!strncmp(kv, "serial=", 7)) opt[nn].serial = kv + 7;
                else if (!strncmp(kv, "console=", 8)) opt[nn].console = kv + 8;
                else if (!strncmp(kv, "unread=", 7)) {
                    if (sscanf(kv + 7, "%lf:%lf", &opt[nn].ufrom, &opt[nn].uuntil) != 2) {
                        fprintf(stderr, "rf230-test: bad unread=%s (FROM_MS:UNTIL_MS)\n", kv + 7);
                        return 2;
                    }
                } else { fprintf(stderr, "rf230-test: unknown node option '%s'\n", kv); return 2; }
            }
            if (mhz[nn] < 1 || mhz[nn] > 20) { fprintf(stderr, "rf230-test: mhz out of range\n"); return 2; }
            nn++;
        } else {
            usage();
        }
    }
    if (!nn)
        usage();

    emu_channel_t *ch = channel_new(loss, seed);
    for (int i = 0; i < nn; i++) {
        elf_firmware_t fw;
        memset(&fw, 0, sizeof fw);
        /* libsimavr prints "Loaded ..." on stdout, where the serial
         * endpoints' addresses go: keep stdout clean */
        if (access(elfs[i], R_OK)) {
            fprintf(stderr, "rf230-test: cannot read %s\n", elfs[i]);
            return 2;
        }
        fflush(stdout);
        int saved = dup(1), devnull = open("/dev/null", O_WRONLY);
        dup2(devnull, 1);
        int bad = elf_read_firmware(elfs[i], &fw) != 0 || !fw.flash;
        if (bad) {
            dup2(saved, 1);
            fprintf(stderr, "rf230-test: cannot load %s\n", elfs[i]);
            return 2;
        }
        patch_u16(&fw, "TOS_NODE_ID", (uint16_t)ids[i]);
        patch_u16(&fw, "ActiveMessageAddressC__addr", (uint16_t)ids[i]);
        patch_u16(&fw, "ActiveMessageAddressC$addr", (uint16_t)ids[i]);
        patch_u16(&fw, "node_id", (uint16_t)ids[i]);
        avr_t *avr = avr_make_mcu_by_name("atmega1281");
        if (!avr) { fprintf(stderr, "rf230-test: libsimavr has no atmega1281\n"); return 2; }
        avr_init(avr);
        avr->log = LOG_ERROR;
        strcpy(fw.mmcu, "atmega1281");
        fw.frequency = (uint32_t)(mhz[i] * 1e6 + 0.5);
        avr_load_firmware(avr, &fw);
        fflush(stdout);
        dup2(saved, 1);
        close(saved);
        close(devnull);
        avr->frequency = fw.frequency;
        avr->sleep = no_sleep;
        avr->run = run_one;
        uint32_t flags = 0;
        avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
        flags &= ~(uint32_t)(AVR_UART_FLAG_STDIO | AVR_UART_FLAG_POLL_SLEEP);
        avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
        emu_node_t *n = calloc(1, sizeof *n);
        n->avr = avr;
        n->index = i;
        n->am_addr = (uint16_t)ids[i];
        n->freq_hz = mhz[i] * 1e6;
        nodes[i] = n;
        if (rf230_attach(n, ch)) { fprintf(stderr, "rf230-test: rf230_attach failed\n"); return 2; }
        if (opt[i].serial && uart_attach(n, opt[i].serial))
            return 2;
        if (opt[i].serial && opt[i].uuntil > opt[i].ufrom)
            uart_set_unread(n, (uint64_t)(opt[i].ufrom * 1e6), (uint64_t)(opt[i].uuntil * 1e6));
        if (opt[i].console) {
            FILE *f = !strcmp(opt[i].console, "-") ? stdout : fopen(opt[i].console, "wb");
            if (!f) { fprintf(stderr, "rf230-test: cannot write %s\n", opt[i].console); return 2; }
            avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                                    console_out, f);
        }
    }

    uint64_t end_ns = (uint64_t)(ms * 1e6);
    struct timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int status = 0;
    for (g_now = 0; g_now < end_ns;) {
        uint64_t q_end = g_now + EMU_QUANTUM_NS;
        int running = 0;
        for (int i = 0; i < nn; i++) {
            avr_t *avr = nodes[i]->avr;
            uint64_t end = (uint64_t)((long double)q_end * avr->frequency / 1e9L + 0.5L);
            if (avr->state == cpu_Done || avr->state == cpu_Crashed)
                continue;
            running++;
            if (avr->cycle < end)
                avr_cycle_timer_register(avr, end - avr->cycle, quantum_end, NULL);
            while (avr->cycle < end) {
                int st = avr_run(avr);
                if (st == cpu_Done || st == cpu_Crashed)
                    break;
            }
            if (avr->state == cpu_Crashed) {
                fprintf(stderr, "rf230-test: node %d crashed at pc 0x%x\n", i, avr->pc);
                status = 1;
            }
        }
        g_now = q_end;
        channel_step(ch, g_now);
        for (int i = 0; i < nn; i++)
            uart_poll(nodes[i], g_now);
        if (stop_when_done && !running)
            break;
        if (realtime && (g_now % 1000000ull) == 0) {
            struct timespec t;
            clock_gettime(CLOCK_MONOTONIC, &t);
            double wall = (t.tv_sec - t0.tv_sec) * 1e9 + (t.tv_nsec - t0.tv_nsec);
            if ((double)g_now > wall) {
                uint64_t d = (uint64_t)((double)g_now - wall);
                struct timespec s = { (time_t)(d / 1000000000ull), (long)(d % 1000000000ull) };
                nanosleep(&s, NULL);
            }
        }
    }
    for (int i = 0; i < nn; i++)            /* what is still on the line */
        uart_poll(nodes[i], g_now + 1000000000ull);
    for (int i = 0; i < nn; i++) {
        fprintf(stderr, "node %d: cpu_state=%d cycles=%llu pc=0x%x\n", i, nodes[i]->avr->state,
                (unsigned long long)nodes[i]->avr->cycle, nodes[i]->avr->pc);
        if (getenv("RF230_TEST_DEBUG")) {
            uint8_t *d = nodes[i]->avr->data;
            fprintf(stderr, "  UCSR0A=%02x B=%02x C=%02x UBRR0=%02x%02x ASSR=%02x TCCR2A=%02x TCCR2B=%02x TCNT2=%02x OCR2A=%02x TIMSK2=%02x TIFR2=%02x TIMSK1=%02x TCCR1B=%02x SREG=%02x\n",
                    d[0xC0], d[0xC1], d[0xC2], d[0xC5], d[0xC4], d[0xB6], d[0xB0], d[0xB1], d[0xB2], d[0xB3], d[0x70], d[0x37], d[0x6F], d[0x81], d[0x5F]);
        }
        rf230_stats(nodes[i], stderr);
        uart_stats(nodes[i], stderr);
    }
    channel_stats(ch, stderr);
    fprintf(stderr, "emulated_ms=%.3f\n", g_now / 1e6);
    return status;
}
