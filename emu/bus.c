/*
 * emu/bus.c -- the board's two I2C wires (bus.h).
 */
#include <stdlib.h>

#include "sim_io.h"
#include "bus.h"

enum { R_PIND = 0x29, R_DDRD = 0x2A, R_PORTD = 0x2B, R_TWCR = 0xBC };
enum { TWEN = 0x04 };

typedef struct {
    emu_bus_t bus;
    avr_io_read_t orig_read;            /* simavr's PIND read (the port) */
    void *orig_param;
} bus_impl_t;

static uint64_t now_ns(const emu_bus_t *b) { return emu_node_now_ns(b->node); }

static void logf_(const emu_bus_t *b, const char *what, const char *name, unsigned n)
{
    if (!b->log)
        return;
    fprintf(b->log, "%llu %d %s", (unsigned long long)now_ns(b), b->node->index, what);
    if (name)
        fprintf(b->log, " %s %u", name, n);
    fputc('\n', b->log);
}

static int shorted(const emu_bus_t *b, int line, uint64_t ns)
{
    return b->short_until[line] && ns >= b->short_from[line] && ns < b->short_until[line];
}

int bus_held(const emu_bus_t *b, int line, uint64_t ns)
{
    return shorted(b, line, ns) || (line == BUS_SDA && b->stuck_left);
}

uint64_t bus_free_at(const emu_bus_t *b, uint64_t ns)
{
    if (b->stuck_left)
        return UINT64_MAX;
    uint64_t t = ns;
    for (int pass = 0; pass < BUS_LINES && t != UINT64_MAX; pass++)
        for (int line = 0; line < BUS_LINES; line++)
            if (shorted(b, line, t))
                t = b->short_until[line];
    return t;
}

/* the pins pull a line low: an output at 0, and the TWI off */
static int pin_low(const emu_bus_t *b, int line)
{
    const uint8_t *d = b->node->avr->data;
    uint8_t bit = (uint8_t)(1u << line);           /* PD0 = SCL, PD1 = SDA */
    return !(d[R_TWCR] & TWEN) && (d[R_DDRD] & bit) && !(d[R_PORTD] & bit);
}

void bus_update(emu_bus_t *b)
{
    uint64_t ns = now_ns(b);
    int scl = !(pin_low(b, BUS_SCL) || shorted(b, BUS_SCL, ns));
    if (b->scl && !scl) {                           /* a falling edge of SCL */
        if (pin_low(b, BUS_SCL)) {
            b->gpio_falls++;
            logf_(b, "C", NULL, 0);
        }
        if (b->stuck_left && --b->stuck_left == 0) {
            b->stuck_freed++;
            b->freed_ns = ns;
            b->freed_after = b->stuck_pulses;
            logf_(b, "FREED", b->stuck_name, b->stuck_pulses);
        }
    }
    int sda_pin = pin_low(b, BUS_SDA);
    int sda = !(sda_pin || bus_held(b, BUS_SDA, ns));
    if (scl && b->scl && !b->sda && sda && b->sda_pin) {
        b->gpio_stops++;                            /* the pin lets SDA rise, SCL high */
        logf_(b, "P gpio", NULL, 0);
    }
    b->scl = scl;
    b->sda = sda;
    b->sda_pin = sda_pin;
}

void bus_stick(emu_bus_t *b, const char *name, unsigned pulses)
{
    b->stuck_name = name;
    b->stuck_pulses = b->stuck_left = pulses;
    b->stuck_holds++;
    logf_(b, "STUCK", name, pulses);
    bus_update(b);
}

static uint8_t pind_read(avr_t *avr, avr_io_addr_t addr, void *param)
{
    bus_impl_t *bi = param;
    uint8_t v = bi->orig_read ? bi->orig_read(avr, addr, bi->orig_param) : avr->data[addr];
    bus_update(&bi->bus);                           /* a short may have begun or ended */
    v = (uint8_t)((v & ~3u) | (bi->bus.scl ? 1u : 0u) | (bi->bus.sda ? 2u : 0u));
    avr->data[addr] = v;
    return v;
}

static void gpio_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    (void)avr; (void)addr; (void)v;
    bus_update(param);                              /* after simavr's port has the value */
}

emu_bus_t *bus_attach(emu_node_t *n, FILE *log)
{
    avr_t *avr = n->avr;
    bus_impl_t *bi = calloc(1, sizeof *bi);
    emu_bus_t *b = &bi->bus;
    b->node = n;
    b->log = log;
    b->scl = b->sda = 1;
    int a = AVR_DATA_TO_IO(R_PIND);                 /* PIND: the port's read, then the wires */
    bi->orig_read = avr->io[a].r.c;
    bi->orig_param = avr->io[a].r.param;
    avr->io[a].r.c = pind_read;
    avr->io[a].r.param = bi;
    avr_register_io_write(avr, R_DDRD, gpio_write, b);    /* chained after the port's */
    avr_register_io_write(avr, R_PORTD, gpio_write, b);
    return b;
}
