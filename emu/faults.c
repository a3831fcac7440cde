/* emu/faults.c -- parse --fault and arm the windows in the models. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "faults.h"
#include "twi.h"
#include "uart.h"

static int chip_index(const char *name)
{
    static const char *names[CHIP_COUNT] = { "adxl345", "itg3200", "hmc5883l" };
    for (int i = 0; i < CHIP_COUNT; i++)
        if (!strcmp(name, names[i]))
            return i;
    return -1;
}

int fault_apply(const char *spec, emu_node_t **nodes, int n)
{
    char buf[128];
    if (strlen(spec) >= sizeof buf)
        goto bad;
    strcpy(buf, spec);
    int only = -1;
    char *at = strchr(buf, '@');
    if (at) {
        *at = 0;
        char *end;
        only = (int)strtol(at + 1, &end, 10);
        if (*end || only < 0 || only >= n)
            goto bad;
    }
    char kind[16] = "", chip[16] = "", tail[8] = "";
    double t0, d;
    int c = -1, line = -1, got;
    unsigned pulses = 8;
    if ((got = sscanf(buf, "short:%15[a-z]:%lf:%lf%1s", chip, &t0, &d, tail)) >= 2 && got <= 3) {
        strcpy(kind, "short");
        line = !strcmp(chip, "sda") ? BUS_SDA : !strcmp(chip, "scl") ? BUS_SCL : -1;
        if (line < 0)
            goto bad;
        if (got == 2)
            d = 1e9;                  /* to the end of the run */
    } else if ((got = sscanf(buf, "stuck:%15[a-z0-9]:%lf:%u%1s", chip, &t0, &pulses, tail)) >= 2
               && got <= 3) {
        strcpy(kind, "stuck");
        c = chip_index(chip);
        if (c < 0 || pulses < 1 || pulses > 9)
            goto bad;
        d = 1;
    } else if (sscanf(buf, "unread:%lf:%lf", &t0, &d) == 2) {
        strcpy(kind, "unread");
    } else if (sscanf(buf, "%15[a-z]:%15[a-z0-9]:%lf:%lf", kind, chip, &t0, &d) == 4
               && (!strcmp(kind, "nack") || !strcmp(kind, "power"))) {
        c = chip_index(chip);
        if (c < 0)
            goto bad;
    } else {
        goto bad;
    }
    if (!(t0 >= 0) || !(d > 0))
        goto bad;
    uint64_t from = (uint64_t)(t0 * 1e9), until = (uint64_t)((t0 + d) * 1e9);
    if (!strcmp(kind, "unread")) {    /* the host stops reading the serial line */
        int any = 0;
        for (int i = 0; i < n; i++)
            if (nodes[i]->uart && (only < 0 || i == only)) {
                uart_set_unread(nodes[i], from, until);
                any = 1;
            }
        if (!any) {
            fprintf(stderr, "ninedof-emu: --fault '%s': no node has a serial port (--serial)\n", spec);
            return -1;
        }
        return 0;
    }
    for (int i = 0; i < n; i++) {
        emu_twi_t *t = nodes[i]->twi;
        if (!t || (only >= 0 && i != only))
            continue;
        if (!strcmp(kind, "short")) {
            t->bus->short_from[line] = from;
            t->bus->short_until[line] = d >= 1e9 ? UINT64_MAX : until;
        } else if (!strcmp(kind, "stuck")) {
            t->chips[c].stuck_at = from;
            t->chips[c].stuck_pulses = pulses;
        } else if (!strcmp(kind, "nack")) {
            t->chips[c].nack_from = from; t->chips[c].nack_until = until;
        } else {
            t->chips[c].off_from = from; t->chips[c].off_until = until;
        }
    }
    return 0;
bad:
    fprintf(stderr, "ninedof-emu: bad --fault '%s' (nack:CHIP:T:D, power:CHIP:T:D, short:sda|scl:T[:D], "
            "stuck:CHIP:T[:N], unread:T:D; seconds, optional @NODE; CHIP adxl345|itg3200|hmc5883l, "
            "N 1..9)\n", spec);
    return -1;
}
