/*
 * emu/rf230.c -- AT86RF230 model on the IRIS wiring (see rf230.h and
 * docs/emulation-radio.md).  Basic operating mode only (the one TinyOS's
 * RF230DriverLayerP uses): TRX_OFF, PLL_ON, RX_ON, BUSY_RX, BUSY_TX, SLEEP;
 * the extended modes (RX_AACK_ON, TX_ARET_ON) are refused and counted.
 */
#include <stdlib.h>
#include <string.h>

#include "sim_avr.h"
#include "sim_io.h"
#include "sim_irq.h"
#include "sim_interrupts.h"
#include "sim_cycle_timers.h"
#include "avr_ioport.h"
#include "avr_spi.h"
#include "avr_timer.h"

#include "rf230.h"

/* registers (RF230DriverLayer.h) */
enum {
    R_TRX_STATUS = 0x01, R_TRX_STATE = 0x02, R_TRX_CTRL_0 = 0x03, R_PHY_TX_PWR = 0x05,
    R_PHY_RSSI = 0x06, R_PHY_ED_LEVEL = 0x07, R_PHY_CC_CCA = 0x08, R_CCA_THRES = 0x09,
    R_IRQ_MASK = 0x0E, R_IRQ_STATUS = 0x0F, R_VREG_CTRL = 0x10, R_BATMON = 0x11,
    R_XOSC_CTRL = 0x12, R_PLL_CF = 0x1A, R_PLL_DCU = 0x1B, R_PART_NUM = 0x1C,
    R_VERSION_NUM = 0x1D, R_MAN_ID_0 = 0x1E, R_MAN_ID_1 = 0x1F,
};
/* TRX_STATUS values / TRX_STATE commands */
enum {
    S_P_ON = 0, S_BUSY_RX = 1, S_BUSY_TX = 2, S_RX_ON = 6, S_TRX_OFF = 8, S_PLL_ON = 9,
    S_SLEEP = 15, S_TRANSITION = 0x1F,
    C_NOP = 0, C_TX_START = 2, C_FORCE_TRX_OFF = 3,
};
enum { IRQ_PLL_LOCK = 1, IRQ_PLL_UNLOCK = 2, IRQ_RX_START = 4, IRQ_TRX_END = 8, IRQ_TRX_UR = 0x40 };

/* timing (AT86RF230 datasheet, typical values) */
#define PLL_LOCK_NS   180000ull   /* TRX_OFF -> PLL_ON / RX_ON */
#define WAKE_NS       500000ull   /* SLEEP -> TRX_OFF (datasheet 880 us typ.; shorter than
                                     the driver's own 880 us wait at any RC clock) */
#define CCA_NS        128000ull   /* 8 symbols */
#define RSSI_BUSY     11          /* about -60 dBm */
#define ED_BUSY       30

typedef struct rf230 {
    emu_node_t *node;
    avr_t *avr;
    emu_channel_t *ch;
    int port;
    uint8_t reg[64];
    uint8_t state;           /* TRX_STATUS[4:0] */
    uint8_t target;          /* state a transition in progress leads to */
    int waking;              /* SLEEP -> TRX_OFF in progress */
    uint8_t pending;         /* command for the end of BUSY_RX / BUSY_TX */
    int cca_done, cca_idle;
    uint64_t cca_from;
    uint8_t irq_status;
    int irq_line;
    avr_irq_t *irq_pin;
    uint8_t fb[129];         /* [0] PHR, [1..127] PSDU */
    uint64_t fb_wtime[129];  /* when each byte was written by the MCU */
    uint8_t lqi;
    int crc_valid;
    int seln, slp_tr, rstn;
    int pos;
    uint8_t cmd, addr;
    ch_frame_t *tx, *rx;
    /* SPI master (replaces simavr 1.6's 100 us transfers) */
    avr_spi_t *spi;
    uint8_t spi_out, spi_in;
    /* counters */
    uint32_t underruns, cca_requests, cca_busy, unsupported, spi_bytes;
} rf230_t;

static uint64_t now_ns(rf230_t *rf) { return emu_node_now_ns(rf->node); }

/* EMU_RF230_TRACE=1: every register access, command and frame on stderr */
static int trace = -1;
#define TRACE(rf, ...) do { \
    if (trace < 0) trace = getenv("EMU_RF230_TRACE") != NULL; \
    if (trace) { \
        fprintf(stderr, "%12.6f rf230[%d] ", now_ns(rf) / 1e9, (rf)->node->index); \
        fprintf(stderr, __VA_ARGS__); \
        fputc('\n', stderr); \
    } } while (0)
static int chan_no(rf230_t *rf) { return rf->reg[R_PHY_CC_CCA] & 0x1F; }

/* 802.15.4 FCS: CRC-16 (x^16 + x^12 + x^5 + 1) LSB first, init 0, as
 * avr-libc's _crc_ccitt_update, which TinyOS uses to check it */
static uint16_t crc_ccitt_update(uint16_t crc, uint8_t data)
{
    data ^= (uint8_t)crc;
    data ^= (uint8_t)(data << 4);
    return (uint16_t)((((uint16_t)data << 8) | (crc >> 8)) ^ (uint8_t)(data >> 4) ^ ((uint16_t)data << 3));
}

/* ------------------------------------------------------------------ IRQ */
static void irq_line_update(rf230_t *rf)
{
    int level = rf->irq_status != 0;
    if (level != rf->irq_line) {
        rf->irq_line = level;
        if (rf->irq_pin)
            avr_raise_irq(rf->irq_pin, level);
    }
}

static void irq_raise(rf230_t *rf, uint8_t bits)
{
    rf->irq_status |= bits & rf->reg[R_IRQ_MASK];
    irq_line_update(rf);
}

/* ---------------------------------------------------------------- reset */
static void regs_reset(rf230_t *rf)
{
    memset(rf->reg, 0, sizeof rf->reg);
    rf->reg[R_TRX_CTRL_0] = 0x19;
    rf->reg[R_PHY_TX_PWR] = 0x00;
    rf->reg[R_PHY_CC_CCA] = 0x2B;           /* CCA mode 1, channel 11 */
    rf->reg[R_CCA_THRES] = 0xC7;
    rf->reg[R_XOSC_CTRL] = 0xF0;
    rf->reg[R_PART_NUM] = 0x02;             /* AT86RF230 */
    rf->reg[R_VERSION_NUM] = 0x02;          /* revision B */
    rf->reg[R_MAN_ID_0] = 0x1F;             /* Atmel JEDEC id */
    rf->reg[R_MAN_ID_1] = 0x00;
    rf->irq_status = 0;
    rf->cca_done = rf->cca_idle = 0;
    rf->pending = 0;
}

static void ev_pll_lock(void *ctx, uint64_t t, uintptr_t arg);
static void ev_wake(void *ctx, uint64_t t, uintptr_t arg);
static void ev_cca(void *ctx, uint64_t t, uintptr_t arg);

static void abort_activity(rf230_t *rf)
{
    if (rf->tx) {
        rf->tx->corrupt = 1;                /* cut off on the air */
        rf->tx = NULL;
    }
    rf->rx = NULL;
    rf->waking = 0;
    rf->pending = 0;
    channel_cancel(rf->ch, ev_pll_lock, rf);
    channel_cancel(rf->ch, ev_wake, rf);
    channel_cancel(rf->ch, ev_cca, rf);
}

/* ------------------------------------------------------------ transmit */
static void start_tx(rf230_t *rf)
{
    TRACE(rf, "tx start");
    rf->state = S_BUSY_TX;
    rf->pending = 0;
    rf->tx = channel_tx_begin(rf->ch, rf->port, chan_no(rf), now_ns(rf));
}

static uint8_t op_tx_length(void *ctx, ch_frame_t *f)
{
    rf230_t *rf = ctx;
    if (f != rf->tx || rf->fb_wtime[0] > f->start_ns + CH_SHR_NS)
        return 0;                           /* PHR not written in time */
    return rf->fb[0] & 0x7F;
}

static void op_tx_fill(void *ctx, ch_frame_t *f)
{
    rf230_t *rf = ctx;
    int n = f->len;
    int auto_crc = (rf->reg[R_PHY_TX_PWR] & 0x80) != 0;
    int data = auto_crc ? n - 2 : n;
    if (data < 0)
        data = 0;
    memcpy(f->psdu, rf->fb + 1, (size_t)n);
    if (f == rf->tx) {
        for (int k = 0; k < data; k++) {
            /* byte k leaves the antenna from SHR + PHR + 32 us * k on */
            if (rf->fb_wtime[k + 1] > f->start_ns + CH_PHR_END_NS + (uint64_t)k * CH_BYTE_NS) {
                f->corrupt = 1;
                rf->underruns++;
                irq_raise(rf, IRQ_TRX_UR);
                break;
            }
        }
    } else {
        f->corrupt = 1;
    }
    if (auto_crc && n >= 2) {
        uint16_t crc = 0;
        for (int k = 0; k < n - 2; k++)
            crc = crc_ccitt_update(crc, f->psdu[k]);
        f->psdu[n - 2] = (uint8_t)crc;
        f->psdu[n - 1] = (uint8_t)(crc >> 8);
    }
}

static void do_cmd(rf230_t *rf, uint8_t cmd);

static void op_tx_end(void *ctx, ch_frame_t *f)
{
    rf230_t *rf = ctx;
    if (f != rf->tx)
        return;
    rf->tx = NULL;
    TRACE(rf, "tx end len %d%s%s", f->len, f->collided ? " collided" : "", f->corrupt ? " corrupt" : "");
    rf->state = S_PLL_ON;                   /* BUSY_TX ends in PLL_ON */
    uint8_t p = rf->pending;
    rf->pending = 0;
    if (p)
        do_cmd(rf, p);
    irq_raise(rf, IRQ_TRX_END);
}

/* ------------------------------------------------------------- receive */
static int op_rx_start(void *ctx, ch_frame_t *f)
{
    rf230_t *rf = ctx;
    if (rf->state != S_RX_ON || f->chan != chan_no(rf) || !rf->rstn)
        return 0;
    rf->state = S_BUSY_RX;
    rf->rx = f;
    TRACE(rf, "rx start");
    irq_raise(rf, IRQ_RX_START);
    return 1;
}

static void op_rx_end(void *ctx, ch_frame_t *f, int ok)
{
    rf230_t *rf = ctx;
    if (f != rf->rx)
        return;
    rf->rx = NULL;
    uint64_t t = now_ns(rf);
    TRACE(rf, "rx end len %d ok %d", f->len, ok);
    rf->fb[0] = f->len;
    memcpy(rf->fb + 1, f->psdu, f->len);
    if (!ok) {
        /* what a collision leaves: garbled bytes, so the FCS check fails
         * (CRC-16 catches every error confined to one byte) */
        rf->fb[1 + f->len / 2] ^= 0xA5;
    }
    for (int k = 0; k <= f->len; k++)
        rf->fb_wtime[k] = t;
    rf->lqi = ok ? 0xFF : 0x40;
    rf->crc_valid = ok;
    rf->state = S_RX_ON;
    uint8_t p = rf->pending;
    rf->pending = 0;
    if (p)
        do_cmd(rf, p);
    irq_raise(rf, IRQ_TRX_END);
}

static const ch_port_ops_t rf230_ops = {
    op_tx_length, op_tx_fill, op_tx_end, op_rx_start, op_rx_end,
};

/* ---------------------------------------------------------- state machine */
static void ev_pll_lock(void *ctx, uint64_t t, uintptr_t arg)
{
    rf230_t *rf = ctx;
    (void)t; (void)arg;
    if (rf->state != S_TRANSITION || rf->waking)
        return;
    rf->state = rf->target;
    irq_raise(rf, IRQ_PLL_LOCK);
}

static void ev_wake(void *ctx, uint64_t t, uintptr_t arg)
{
    rf230_t *rf = ctx;
    (void)t; (void)arg;
    if (!rf->waking)
        return;
    rf->waking = 0;
    rf->state = S_TRX_OFF;
}

static void ev_cca(void *ctx, uint64_t t, uintptr_t arg)
{
    rf230_t *rf = ctx;
    (void)arg;
    rf->cca_done = 1;
    rf->cca_idle = rf->rx == NULL && rf->state == S_RX_ON &&
                   !channel_busy(rf->ch, rf->port, chan_no(rf), rf->cca_from, t);
    if (!rf->cca_idle)
        rf->cca_busy++;
}

static void do_cmd(rf230_t *rf, uint8_t cmd)
{
    switch (cmd) {
    case C_NOP:
        break;
    case C_FORCE_TRX_OFF:
        if (rf->state == S_SLEEP || rf->waking)
            break;
        abort_activity(rf);
        rf->state = S_TRX_OFF;
        break;
    case C_TX_START:
        if (rf->state == S_PLL_ON)
            start_tx(rf);
        break;
    case S_TRX_OFF:
    case S_RX_ON:
    case S_PLL_ON:
        if (rf->state == S_BUSY_RX || rf->state == S_BUSY_TX) {
            rf->pending = cmd;              /* done when the frame ends */
        } else if (rf->state == S_SLEEP || rf->waking) {
            /* SPI is off while asleep */
        } else if (cmd == S_TRX_OFF) {
            channel_cancel(rf->ch, ev_pll_lock, rf);
            rf->state = S_TRX_OFF;
        } else if (rf->state == S_TRX_OFF || rf->state == S_P_ON) {
            rf->state = S_TRANSITION;
            rf->target = cmd;
            channel_at(rf->ch, now_ns(rf) + PLL_LOCK_NS, ev_pll_lock, rf, 0);
        } else if (rf->state == S_TRANSITION) {
            rf->target = cmd;               /* PLL still locking */
        } else {
            rf->state = cmd;                /* RX_ON <-> PLL_ON: 1 us */
        }
        break;
    default:
        rf->unsupported++;                  /* RX_AACK_ON, TX_ARET_ON, ... */
        break;
    }
}

/* ------------------------------------------------------------ registers */
static uint8_t reg_read(rf230_t *rf, uint8_t a)
{
    switch (a) {
    case R_TRX_STATUS:
        TRACE(rf, "read TRX_STATUS %02x", (rf->cca_done ? 0x80 : 0) | (rf->cca_idle ? 0x40 : 0) | rf->state);
        return (uint8_t)((rf->cca_done ? 0x80 : 0) | (rf->cca_idle ? 0x40 : 0) | rf->state);
    case R_IRQ_STATUS: {
        uint8_t v = rf->irq_status;
        TRACE(rf, "read IRQ_STATUS %02x", v);
        rf->irq_status = 0;
        irq_line_update(rf);
        return v;
    }
    case R_PHY_RSSI: {
        uint64_t t = now_ns(rf);
        int busy = rf->rx || channel_busy(rf->ch, rf->port, chan_no(rf), t, t);
        return (uint8_t)((rf->crc_valid ? 0x80 : 0) | (busy ? RSSI_BUSY : 0));
    }
    case R_PHY_ED_LEVEL: {
        uint64_t t = now_ns(rf);
        int busy = rf->rx || channel_busy(rf->ch, rf->port, chan_no(rf), t, t);
        return busy ? ED_BUSY : 0;
    }
    case R_VREG_CTRL:
        return rf->reg[a] | 0x44;           /* AVDD_OK, DVDD_OK */
    default:
        return rf->reg[a & 0x3F];
    }
}

static void reg_write(rf230_t *rf, uint8_t a, uint8_t v)
{
    TRACE(rf, "write reg %02x = %02x (state %02x)", a, v, rf->state);
    switch (a) {
    case R_TRX_STATE:
        rf->reg[a] = v & 0x1F;
        do_cmd(rf, v & 0x1F);
        break;
    case R_PHY_CC_CCA:
        rf->reg[a] = v & 0x7F;
        if ((v & 0x80) && rf->state == S_RX_ON) {
            rf->cca_requests++;
            rf->cca_done = rf->cca_idle = 0;
            rf->cca_from = now_ns(rf);
            channel_cancel(rf->ch, ev_cca, rf);
            channel_at(rf->ch, rf->cca_from + CCA_NS, ev_cca, rf, 0);
        }
        break;
    case R_IRQ_MASK:
        rf->reg[a] = v;
        break;
    case R_TRX_STATUS: case R_IRQ_STATUS: case R_PHY_RSSI: case R_PHY_ED_LEVEL:
    case R_PART_NUM: case R_VERSION_NUM: case R_MAN_ID_0: case R_MAN_ID_1:
        break;                              /* read only */
    default:
        rf->reg[a] = v;
        break;
    }
}

/* ----------------------------------------------------------------- SPI */
static uint8_t spi_byte(rf230_t *rf, uint8_t mosi)
{
    if (rf->seln || !rf->rstn || rf->state == S_SLEEP || rf->waking)
        return 0x00;                        /* not selected / SPI off */
    rf->spi_bytes++;
    int pos = rf->pos++;
    if (pos == 0) {
        rf->cmd = mosi;
        if ((mosi & 0xA0) == 0x20)
            TRACE(rf, "frame %s begins", (mosi & 0x40) ? "write" : "read");
        return 0x00;                        /* RF230: no PHY_STATUS byte */
    }
    uint8_t c = rf->cmd;
    if ((c & 0xC0) == 0x80) {               /* register read */
        return pos == 1 ? reg_read(rf, c & 0x3F) : 0;
    } else if ((c & 0xC0) == 0xC0) {        /* register write */
        if (pos == 1)
            reg_write(rf, c & 0x3F, mosi);
        return 0;
    } else if ((c & 0xE0) == 0x20) {        /* frame read: PHR, PSDU, LQI */
        int k = pos - 1;
        int len = rf->fb[0] & 0x7F;
        if (k <= len)
            return rf->fb[k];
        return k == len + 1 ? rf->lqi : 0;
    } else if ((c & 0xE0) == 0x60) {        /* frame write: PHR, PSDU */
        int k = pos - 1;
        if (k <= 127) {
            rf->fb[k] = mosi;
            rf->fb_wtime[k] = now_ns(rf);
        }
        return 0;
    } else if ((c & 0xE0) == 0x00 || (c & 0xE0) == 0x40) {  /* SRAM read / write */
        if (pos == 1) {
            rf->addr = mosi & 0x7F;
            return 0;
        }
        int a = rf->addr + (pos - 2);       /* address 0 = first PSDU byte */
        if (a > 126)
            return 0;
        if ((c & 0xE0) == 0x00)
            return rf->fb[1 + a];
        rf->fb[1 + a] = mosi;
        rf->fb_wtime[1 + a] = now_ns(rf);
        return 0;
    }
    return 0;
}

static avr_cycle_count_t spi_done(avr_t *avr, avr_cycle_count_t when, void *param)
{
    rf230_t *rf = param;
    (void)when;
    rf->spi_in = spi_byte(rf, rf->spi_out);
    avr_raise_interrupt(avr, &rf->spi->spi);
    return 0;
}

static void spdr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    rf230_t *rf = param;
    avr_spi_t *p = rf->spi;
    avr_core_watch_write(avr, addr, v);
    avr_clear_interrupt(avr, &p->spi);
    if (!avr_regbit_get(avr, p->spe) || !avr_regbit_get(avr, p->mstr))
        return;
    static const int div[4] = { 4, 16, 64, 128 };
    int d = div[avr->data[p->r_spcr] & 3];
    if (avr->data[p->r_spsr] & 1)           /* SPI2X */
        d /= 2;
    rf->spi_out = v;
    avr_cycle_timer_cancel(avr, spi_done, rf);
    avr_cycle_timer_register(avr, (avr_cycle_count_t)(8 * d), spi_done, rf);
}

static uint8_t spdr_read(avr_t *avr, avr_io_addr_t addr, void *param)
{
    rf230_t *rf = param;
    (void)addr;
    avr_clear_interrupt(avr, &rf->spi->spi);
    return rf->spi_in;
}

/* ------------------------------------------------ timer 1 flags (TIFR1) */
/* simavr 1.6 clears every raised flag of a timer on any write to its TIFR
 * (fixed in later simavr: write-1-to-clear per bit).  TinyOS clears OCF1A
 * when it arms its radio alarm; that also wiped a pending ICF1, i.e. the
 * radio interrupt: the IRQ line stayed high and the stack never heard from
 * the radio again.  Timer 1's TIFR1 gets the datasheet behaviour here. */
static int flag_written(avr_int_vector_t *v, avr_io_addr_t addr, uint8_t val)
{
    return v->raised.reg == addr && (val & (v->raised.mask << v->raised.bit));
}

static void tifr1_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    avr_timer_t *p = param;
    if (flag_written(&p->overflow, addr, v))
        avr_clear_interrupt(avr, &p->overflow);
    if (flag_written(&p->icr, addr, v))
        avr_clear_interrupt(avr, &p->icr);
    for (int i = 0; i < AVR_TIMER_COMP_COUNT; i++)
        if (flag_written(&p->comp[i].interrupt, addr, v))
            avr_clear_interrupt(avr, &p->comp[i].interrupt);
}

static void fix_tifr1(avr_t *avr)
{
    for (avr_io_t *io = avr->io_port; io; io = io->next)
        if (io->kind && !strcmp(io->kind, "timer") && ((avr_timer_t *)io)->name == '1') {
            avr_timer_t *p = (avr_timer_t *)io;
            avr_io_addr_t a = AVR_DATA_TO_IO(p->icr.raised.reg);
            avr->io[a].w.c = tifr1_write;
            avr->io[a].w.param = p;
        }
}

/* ---------------------------------------------------------------- pins */
static void pin_seln(avr_irq_t *irq, uint32_t v, void *param)
{
    rf230_t *rf = param;
    (void)irq;
    v = v != 0;
    if ((int)v == rf->seln)
        return;
    rf->seln = (int)v;
    if (!v)
        rf->pos = 0;                        /* a new SPI access begins */
    else if (rf->pos > 2 && (rf->cmd & 0xA0) == 0x20)
        TRACE(rf, "frame %s done, %d bytes", (rf->cmd & 0x40) ? "write" : "read", rf->pos - 1);
}

static void pin_slp_tr(avr_irq_t *irq, uint32_t v, void *param)
{
    rf230_t *rf = param;
    (void)irq;
    v = v != 0;
    if ((int)v == rf->slp_tr)
        return;
    rf->slp_tr = (int)v;
    if (!rf->rstn)
        return;
    if (v) {
        if (rf->state == S_PLL_ON)
            start_tx(rf);
        else if (rf->state == S_TRX_OFF)
            rf->state = S_SLEEP;
    } else if (rf->state == S_SLEEP) {
        rf->waking = 1;
        channel_at(rf->ch, now_ns(rf) + WAKE_NS, ev_wake, rf, 0);
    }
}

static void pin_rstn(avr_irq_t *irq, uint32_t v, void *param)
{
    rf230_t *rf = param;
    (void)irq;
    v = v != 0;
    if ((int)v == rf->rstn)
        return;
    rf->rstn = (int)v;
    if (!v) {
        abort_activity(rf);
        regs_reset(rf);
        irq_line_update(rf);
        rf->state = S_P_ON;
    } else {
        rf->state = S_TRX_OFF;              /* reset ends in TRX_OFF */
    }
}

/* ------------------------------------------------------------- attach */
int rf230_attach(emu_node_t *node, emu_channel_t *ch)
{
    avr_t *avr = node->avr;
    avr_spi_t *spi = NULL;
    for (avr_io_t *io = avr->io_port; io; io = io->next)
        if (io->kind && !strcmp(io->kind, "spi")) {
            spi = (avr_spi_t *)io;
            break;
        }
    if (!spi)
        return -1;
    rf230_t *rf = calloc(1, sizeof *rf);
    if (!rf)
        return -1;
    rf->node = node;
    rf->avr = avr;
    rf->ch = ch;
    rf->spi = spi;
    rf->port = channel_port(ch, &rf230_ops, rf);
    if (rf->port < 0) {
        free(rf);
        return -1;
    }
    regs_reset(rf);
    rf->state = S_P_ON;
    rf->seln = 1;
    rf->rstn = 1;
    rf->slp_tr = 0;
    node->rf = rf;

    avr_io_addr_t a = AVR_DATA_TO_IO(spi->r_spdr);
    avr->io[a].w.c = spdr_write;
    avr->io[a].w.param = rf;
    avr->io[a].r.c = spdr_read;
    avr->io[a].r.param = rf;

    fix_tifr1(avr);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('B'), 0), pin_seln, rf);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('B'), 7), pin_slp_tr, rf);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('A'), 6), pin_rstn, rf);
    rf->irq_pin = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('D'), 4);
    return 0;
}

void rf230_stats(emu_node_t *node, FILE *out)
{
    rf230_t *rf = node->rf;
    if (!rf) {
        fprintf(out, "rf230 node %d: no radio\n", node->index);
        return;
    }
    ch_port_stats_t *s = channel_port_stats(rf->ch, rf->port);
    fprintf(out, "rf230 node %d: tx=%u rx_ok=%u rx_crc_bad=%u lost=%u missed=%u underrun=%u "
            "cca=%u cca_busy=%u unsupported=%u state=0x%02x\n",
            node->index, s->tx, s->rx_ok, s->rx_bad, s->lost, s->missed, rf->underruns,
            rf->cca_requests, rf->cca_busy, rf->unsupported, rf->state);
}
