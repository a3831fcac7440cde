/*
 * emu/main.c -- ninedof-emu: N sensor motes (+ a BaseStation) in lockstep.
 *
 *   ninedof-emu --mote ELF[,id=N,mhz=F,xtal_ppm=P,board=FILE|none,temp=C,console=FILE,
 *                     serial=SPEC] ... [--base ELF[,...]]
 *               [--serial pty|tcp:PORT|null] [--loss P] [--seed N] [--seconds S]
 *               [--fault SPEC] ... [--settle S] [--twi-log FILE] [--console FILE]
 *               [--span FROM:TO] [--reset T[@I]] ... [--control] [--realtime]
 *               [--report json|text]
 *
 * A node's board=none: no sensor board (no TWI model); console=FILE: its
 * UART0 bytes to FILE (--console: the first node's); serial=SPEC: its
 * UART0 as a port (--serial: the BaseStation's).  --realtime: emulated
 * time never runs ahead of the wall clock (for a client on a port).
 *
 * --reset T[@I]: reset sensor mote index I (every sensor mote without @I)
 * at T s of emulated time, keeping its EEPROM (node_reset).
 * --control: read commands from stdin while running, one a line:
 *   reset I|motes [D]   reset node index I (or every sensor mote) D emulated s from now
 *   loss P              the radio channel's loss rate from now on
 *   time                print "time T" (emulated seconds) on stdout
 *   stop                end the run (the report follows)
 * Each reset prints "reset node I (id N) at T s" on stdout.
 *
 * Every node runs on Debian's libsimavr (ATmega1281) with the harness's
 * TWI model and chip models (sensor motes), the 32768 Hz crystal on
 * timer 2 (simavr's asynchronous timer 2, at exactly 32768 Hz of emulated
 * time) and its own RC clock (mhz=).  docs/emulation.md.
 */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <unistd.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "emu.h"
#include "node.h"
#include "twi.h"
#include "board.h"
#include "faults.h"
#include "report.h"
#include "channel.h"
#include "rf230.h"
#include "uart.h"

#define MAX_NODES 32

static uint64_t g_now_ns;

uint64_t emu_global_now_ns(void)
{
    return g_now_ns;
}

static void usage(void)
{
    fprintf(stderr,
            "usage: ninedof-emu --mote ELF[,id=N,mhz=F,xtal_ppm=P,board=FILE|none,temp=C,\n"
            "                          console=FILE,serial=SPEC] ... [--base ELF[,...]]\n"
            "       [--serial pty|tcp:PORT|null] [--loss P] [--seed N] [--seconds S]\n"
            "       [--fault SPEC] ... [--settle S] [--twi-log FILE] [--console FILE]\n"
            "       [--span FROM:TO] [--reset T[@I]] ... [--control] [--realtime]\n"
            "       [--report json|text]\n");
}

static int bad(const char *what, const char *arg)
{
    fprintf(stderr, "ninedof-emu: bad %s '%s'\n", what, arg);
    return 2;
}

typedef struct {
    char elf[1024];
    int id;
    double mhz;
    double xtal_ppm;
    char board[1024];
    int no_board;
    int temp_set;
    double temp_c;
    char console[1024];
    char serial[64];
} node_spec_t;

static int parse_node(const char *arg, node_spec_t *s, int default_id)
{
    char buf[2048];
    if (strlen(arg) >= sizeof buf)
        return -1;
    strcpy(buf, arg);
    s->id = default_id;
    s->mhz = 8.0;
    s->xtal_ppm = 0;
    s->board[0] = 0;
    s->no_board = 0;
    s->temp_set = 0;
    s->console[0] = 0;
    s->serial[0] = 0;
    char *save = NULL;
    char *tok = strtok_r(buf, ",", &save);
    if (!tok || strlen(tok) >= sizeof s->elf)
        return -1;
    strcpy(s->elf, tok);
    while ((tok = strtok_r(NULL, ",", &save))) {
        char *end;
        if (!strncmp(tok, "id=", 3)) {
            long v = strtol(tok + 3, &end, 0);
            if (*end || v < 0 || v > 0xFFFF)
                return -1;
            s->id = (int)v;
        } else if (!strncmp(tok, "mhz=", 4)) {
            double v = strtod(tok + 4, &end);
            if (*end || !(v >= 1.0 && v <= 20.0))
                return -1;
            s->mhz = v;
        } else if (!strncmp(tok, "xtal_ppm=", 9)) {
            double v = strtod(tok + 9, &end);
            if (*end || !(v >= -1000 && v <= 1000))
                return -1;
            s->xtal_ppm = v;
        } else if (!strncmp(tok, "temp=", 5)) {
            double v = strtod(tok + 5, &end);
            if (*end || !(v >= -40.0 && v <= 125.0))
                return -1;
            s->temp_set = 1;
            s->temp_c = v;
        } else if (!strcmp(tok, "board=none")) {
            s->no_board = 1;
        } else if (!strncmp(tok, "board=", 6) && strlen(tok + 6) < sizeof s->board) {
            strcpy(s->board, tok + 6);
        } else if (!strncmp(tok, "console=", 8) && tok[8] && strlen(tok + 8) < sizeof s->console) {
            strcpy(s->console, tok + 8);
        } else if (!strncmp(tok, "serial=", 7) && tok[7] && strlen(tok + 7) < sizeof s->serial) {
            strcpy(s->serial, tok + 7);
        } else {
            return -1;
        }
    }
    return 0;
}

/* --realtime: sleep until the wall clock has caught up with emulated time */
static void wait_for_wall(const struct timespec *t0, uint64_t now_ns)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    double wall = (t.tv_sec - t0->tv_sec) * 1e9 + (t.tv_nsec - t0->tv_nsec);
    if ((double)now_ns > wall) {
        uint64_t d = (uint64_t)((double)now_ns - wall);
        struct timespec s = { (time_t)(d / 1000000000u), (long)(d % 1000000000u) };
        nanosleep(&s, NULL);
    }
}

/* resets to do: at time at_ns, node index (or -1: every sensor mote) */
typedef struct { uint64_t at_ns; int node; int done; } reset_t;
#define MAX_RESETS 256
static reset_t g_resets[MAX_RESETS];
static int g_nresets;

static int add_reset(uint64_t at_ns, int node)
{
    if (g_nresets == MAX_RESETS)
        return -1;
    g_resets[g_nresets++] = (reset_t){ at_ns, node, 0 };
    return 0;
}

static int pending_resets(void)
{
    for (int r = 0; r < g_nresets; r++)
        if (!g_resets[r].done)
            return 1;
    return 0;
}

/* one command line from --control (stdin); 1 when it asks to stop */
static int control_line(char *line, int nspec, emu_channel_t *ch)
{
    char what[16] = "";
    double a = 0;
    if (sscanf(line, "reset %15s %lf", what, &a) >= 1) {
        char *end;
        long i = strtol(what, &end, 10);
        int node = !strcmp(what, "motes") ? -1 : (*end || i < 0 || i >= nspec) ? -2 : (int)i;
        if (node == -2 || !(a >= 0) || add_reset(g_now_ns + (uint64_t)(a * 1e9), node) < 0)
            fprintf(stdout, "error: bad control command: %s\n", line);
    } else if (sscanf(line, "loss %lf", &a) == 1 && a >= 0 && a <= 1 && ch) {
        channel_set_loss(ch, a);
        fprintf(stdout, "loss %g at %.6f s\n", a, g_now_ns / 1e9);
    } else if (!strncmp(line, "time", 4)) {
        fprintf(stdout, "time %.6f\n", g_now_ns / 1e9);
    } else if (!strncmp(line, "stop", 4)) {
        return 1;
    } else if (line[0]) {
        fprintf(stdout, "error: bad control command: %s\n", line);
    }
    fflush(stdout);
    return 0;
}

/* poll stdin without blocking; 1 when a command asked to stop */
static int control_poll(int *open_, int nspec, emu_channel_t *ch)
{
    static char buf[1024];
    static size_t have;
    struct pollfd p = { .fd = 0, .events = POLLIN };
    while (*open_ && poll(&p, 1, 0) > 0) {
        ssize_t got = read(0, buf + have, sizeof buf - 1 - have);
        if (got <= 0) {
            *open_ = 0;          /* stdin closed: keep running to --seconds */
            break;
        }
        have += (size_t)got;
        buf[have] = 0;
        char *nl;
        while ((nl = strchr(buf, '\n'))) {
            *nl = 0;
            int stop = control_line(buf, nspec, ch);
            size_t used = (size_t)(nl + 1 - buf);
            memmove(buf, nl + 1, have - used + 1);
            have -= used;
            if (stop)
                return 1;
        }
        if (have == sizeof buf - 1)
            have = 0;
    }
    return 0;
}

int main(int argc, char **argv)
{
    /* a TCP client that goes away (a motecal command exiting with serial
     * bytes unread: its kernel answers with a reset) must not kill the
     * harness with SIGPIPE on the next write: write() then fails with EPIPE
     * and uart.c drops the client */
    signal(SIGPIPE, SIG_IGN);
    node_spec_t specs[MAX_NODES];
    int nspec = 0, base = -1;
    const char *serial = NULL, *report = "text", *twi_log = NULL, *console = NULL;
    char span_from[128] = "", span_to[128] = "";
    const char *faults[64];
    int nfault = 0;
    double loss = 0, seconds = 10, settle = -1;
    unsigned long seed = 1;
    int control = 0, realtime = 0;
    const char *reset_args[MAX_RESETS];
    int nreset_args = 0;

    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        char *end;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage();
            return 0;
        }
        if (!strcmp(a, "--control")) {
            control = 1;
            continue;
        }
        if (!strcmp(a, "--realtime")) {
            realtime = 1;
            continue;
        }
        if (!v) {
            usage();
            return 2;
        }
        i++;
        if (!strcmp(a, "--mote") || !strcmp(a, "--base")) {
            if (nspec == MAX_NODES)
                return bad("node count (max 32)", v);
            int is_base = !strcmp(a, "--base");
            if (is_base && base >= 0)
                return bad("second --base", v);
            if (parse_node(v, &specs[nspec], is_base ? 0 : nspec + 1) < 0)
                return bad(a, v);
            if (is_base)
                base = nspec;
            nspec++;
        } else if (!strcmp(a, "--serial")) {
            serial = v;
        } else if (!strcmp(a, "--loss")) {
            loss = strtod(v, &end);
            if (*end || !(loss >= 0 && loss <= 1))
                return bad("--loss (0..1)", v);
        } else if (!strcmp(a, "--seed")) {
            seed = strtoul(v, &end, 0);
            if (*end)
                return bad("--seed", v);
        } else if (!strcmp(a, "--seconds")) {
            seconds = strtod(v, &end);
            if (*end || !(seconds > 0 && seconds <= 3600))
                return bad("--seconds (0..3600]", v);
        } else if (!strcmp(a, "--settle")) {
            settle = strtod(v, &end);
            if (*end || !(settle >= 0))
                return bad("--settle", v);
        } else if (!strcmp(a, "--fault")) {
            if (nfault == 64)
                return bad("--fault count", v);
            faults[nfault++] = v;
        } else if (!strcmp(a, "--report")) {
            if (strcmp(v, "json") && strcmp(v, "text"))
                return bad("--report (json|text)", v);
            report = v;
        } else if (!strcmp(a, "--span")) {
            const char *colon = strchr(v, ':');
            if (!colon || colon == v || !colon[1] || (size_t)(colon - v) >= sizeof span_from
                || strlen(colon + 1) >= sizeof span_to)
                return bad("--span (FROM:TO, two function names)", v);
            memcpy(span_from, v, (size_t)(colon - v));
            span_from[colon - v] = 0;
            strcpy(span_to, colon + 1);
        } else if (!strcmp(a, "--reset")) {
            if (nreset_args == MAX_RESETS)
                return bad("--reset count", v);
            reset_args[nreset_args++] = v;
        } else if (!strcmp(a, "--twi-log")) {
            twi_log = v;
        } else if (!strcmp(a, "--console")) {
            console = v;
        } else {
            usage();
            return 2;
        }
    }
    if (!nspec) {
        usage();
        return 2;
    }
    if (settle < 0)
        settle = seconds >= 10 ? 5.0 : 0.0;
    FILE *log = NULL;
    if (twi_log && !(log = fopen(twi_log, "w"))) {
        fprintf(stderr, "ninedof-emu: cannot write %s: %s\n", twi_log, strerror(errno));
        return 2;
    }
    FILE *con = NULL;
    if (console && !(con = strcmp(console, "-") ? fopen(console, "wb") : stdout)) {
        fprintf(stderr, "ninedof-emu: cannot write %s: %s\n", console, strerror(errno));
        return 2;
    }

    emu_node_t *nodes[MAX_NODES];
    emu_channel_t *ch = channel_new(loss, (uint32_t)seed);
    for (int i = 0; i < nspec; i++) {
        nodes[i] = node_new(specs[i].elf, i, (uint16_t)specs[i].id, specs[i].mhz * 1e6);
        if (!nodes[i])
            return 2;
        nodes[i]->is_base = i == base;
        if (specs[i].xtal_ppm != 0 && node_crystal_ppm(nodes[i], specs[i].xtal_ppm) < 0) {
            fprintf(stderr, "ninedof-emu: simavr refused the crystal at %g ppm\n", specs[i].xtal_ppm);
            return 2;
        }
        if (i != base && !specs[i].no_board) {
            emu_board_t *b = specs[i].board[0] ? board_load(specs[i].board) : board_synthetic();
            if (!b)
                return 2;
            if (specs[i].temp_set)
                board_set_temp(b, specs[i].temp_c);
            nodes[i]->board = b;
            twi_attach(nodes[i], b, log);
            nodes[i]->twi->st.settle_ns = (uint64_t)(settle * 1e9);
            if (span_from[0] && node_span(nodes[i], span_from, span_to,
                                          (uint64_t)(settle * 1e9)) < 0)
                return 2;
        }
        if (ch)
            rf230_attach(nodes[i], ch);
        const char *port = specs[i].serial[0] ? specs[i].serial : i == base ? serial : NULL;
        if (port && uart_attach(nodes[i], port) < 0)
            return 2;
        if (specs[i].console[0]) {
            FILE *f = !strcmp(specs[i].console, "-") ? stdout : fopen(specs[i].console, "wb");
            if (!f) {
                fprintf(stderr, "ninedof-emu: cannot write %s: %s\n", specs[i].console, strerror(errno));
                return 2;
            }
            node_console(nodes[i], f);
        } else if (i == 0 && con && !port) {
            node_console(nodes[i], con);
        }
    }
    for (int f = 0; f < nfault; f++)
        if (fault_apply(faults[f], nodes, nspec) < 0)
            return 2;
    for (int r = 0; r < nreset_args; r++) {
        const char *v = reset_args[r];
        char *end;
        double t = strtod(v, &end);
        long node = -1;
        if (*end == '@')
            node = end[1] >= '0' && end[1] <= '9' ? strtol(end + 1, &end, 10) : -2;
        if (end == v || *end || !(t >= 0) || node < -1 || node >= nspec
            || (node >= 0 && node == base))
            return bad("--reset (T or T@I: seconds, a sensor mote's node index)", v);
        add_reset((uint64_t)(t * 1e9), (int)node);
    }
    int stdin_open = control;
    if (control) {
        setvbuf(stdout, NULL, _IOLBF, 0);
        fcntl(0, F_SETFL, fcntl(0, F_GETFL) | O_NONBLOCK);
    }

    /* lockstep: every node runs to the end of each quantum, then the channel */
    uint64_t end_ns = (uint64_t)(seconds * 1e9);
    uint64_t settle_ns = (uint64_t)(settle * 1e9);
    uint64_t cyc0[MAX_NODES] = { 0 }, sleep0[MAX_NODES] = { 0 };
    int settled = 0, state[MAX_NODES];
    for (int i = 0; i < nspec; i++)
        state[i] = cpu_Running;
    uint64_t quanta = 0;
    struct timespec wall0;
    clock_gettime(CLOCK_MONOTONIC, &wall0);
    while (g_now_ns < end_ns) {
        uint64_t q = g_now_ns + EMU_QUANTUM_NS;
        int live = 0;
        if (control && ++quanta % 250 == 0 && control_poll(&stdin_open, nspec, ch))
            break;            /* every 1 ms of emulated time */
        for (int r = 0; r < g_nresets; r++) {
            reset_t *rs = &g_resets[r];
            if (rs->done || rs->at_ns > g_now_ns)
                continue;
            rs->done = 1;
            for (int i = 0; i < nspec; i++) {
                if ((rs->node >= 0 && i != rs->node) || (rs->node < 0 && i == base))
                    continue;
                node_reset(nodes[i]);
                state[i] = nodes[i]->avr->state;
                fprintf(stdout, "reset node %d (id %u) at %.6f s\n", i, nodes[i]->am_addr,
                        g_now_ns / 1e9);
                fflush(stdout);
            }
        }
        for (int i = 0; i < nspec; i++) {
            if (state[i] == cpu_Done || state[i] == cpu_Crashed)
                continue;
            state[i] = node_run_until(nodes[i], q);
            if (state[i] != cpu_Done && state[i] != cpu_Crashed)
                live++;
            uart_poll(nodes[i], q);
        }
        g_now_ns = q;
        if (getenv("EMU_PC_TRACE") && g_now_ns % 100000000u == 0)
            for (int i = 0; i < nspec; i++)
                fprintf(stderr, "t=%.1f node %d pc %05x state %d cycle %llu sreg_i %d int_state %d\n",
                        g_now_ns / 1e9, i, nodes[i]->avr->pc, nodes[i]->avr->state,
                        (unsigned long long)nodes[i]->avr->cycle, nodes[i]->avr->sreg[S_I],
                        nodes[i]->avr->interrupt_state);
        if (ch)
            channel_step(ch, g_now_ns);
        if (realtime && g_now_ns % 1000000u == 0)
            wait_for_wall(&wall0, g_now_ns);
        if (!settled && g_now_ns >= settle_ns) {
            settled = 1;
            for (int i = 0; i < nspec; i++) {
                cyc0[i] = nodes[i]->avr->cycle;
                sleep0[i] = nodes[i]->sleep_cycles;
            }
        }
        if (!live && !pending_resets() && !stdin_open)
            break;
    }
    for (int i = 0; i < nspec; i++) {
        uart_poll(nodes[i], g_now_ns + 1000000000u);     /* what is still on the line */
        if (nodes[i]->twi)
            twi_finish(nodes[i]->twi);
    }
    if (log)
        fclose(log);
    if (con && con != stdout)
        fclose(con);

    return report_write(stdout, !strcmp(report, "json"), nodes, nspec, state, cyc0, sleep0,
                        settle, g_now_ns, ch, span_from, span_to);
}
