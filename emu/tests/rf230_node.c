/*
 * emu/tests/rf230_node.c -- a minimal AT86RF230 driver for the ATmega1281 on
 * the IRIS wiring, used to test the radio model (emu/rf230.c) in simavr.
 * Built with avr-gcc in three roles (-DROLE=...):
 *   ROLE_TX   sends NFRAMES frames of PSDU length LEN every PERIOD_US, the
 *             way TinyOS's RF230DriverLayerP does (PLL_ON, SLP_TR pulse,
 *             frame write, RX_ON queued, TRX_END by input capture), and
 *             checks each state on the way; with -DTX_IDLE_PLL it stays in
 *             PLL_ON between frames (deaf), so two of them can collide
 *   ROLE_RX   listens and checks every frame's FCS in software, as TinyOS
 *             does (_crc_ccitt_update over PSDU incl. FCS must be 0)
 *   ROLE_CCA  runs clear channel assessments back to back and counts them
 *   ROLE_TIFR a pending radio interrupt survives clearing OCF1A in TIFR1
 * Lines go out on UART0 at 250000 baud; the Python test reads them.
 */
#include <avr/io.h>
#include <avr/interrupt.h>
#include <avr/sleep.h>
#include <util/crc16.h>
#include <stdint.h>

#define ROLE_TX 1
#define ROLE_RX 2
#define ROLE_CCA 3
#define ROLE_TIFR 4
#ifndef ROLE
#define ROLE ROLE_TX
#endif
#ifndef NFRAMES
#define NFRAMES 20
#endif
#ifndef LEN
#define LEN 20                      /* PSDU length incl. the 2 FCS bytes */
#endif
#ifndef PERIOD_US
#define PERIOD_US 4000
#endif
#ifndef START_US
#define START_US 3000
#endif
#ifndef RUN_MS
#define RUN_MS 200
#endif
#ifndef CHANNEL
#define CHANNEL 26
#endif

volatile uint16_t TOS_NODE_ID = 0xFFFF;     /* patched by the harness, as in a TinyOS image */

/* ------------------------------------------------------------- output */
static void uart_init(void)
{
    UCSR0A = _BV(U2X0);                     /* first: simavr 1.6 takes the rate */
    UBRR0H = 0;                             /* when UBRR0L is written */
    UBRR0L = 3;                             /* 250000 baud at 8 MHz, U2X */
    UCSR0B = _BV(TXEN0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
}
static void putch(char c) { while (!(UCSR0A & _BV(UDRE0))); UDR0 = c; }
static void puts_(const char *s) { while (*s) putch(*s++); }
static void putu(uint32_t v)
{
    char b[11];
    int i = 0;
    do { b[i++] = (char)('0' + v % 10); v /= 10; } while (v);
    while (i) putch(b[--i]);
}
static void puthex(uint8_t v)
{
    static const char h[] = "0123456789abcdef";
    putch(h[v >> 4]);
    putch(h[v & 15]);
}
static void kv(const char *k, uint32_t v) { putch(' '); puts_(k); putch('='); putu(v); }
static void kx(const char *k, uint8_t v) { putch(' '); puts_(k); putch('='); puthex(v); }

/* ---------------------------------------------------------- time: timer 1 at 1 MHz */
static volatile uint16_t t1_high;            /* overflow count: 32-bit microseconds */
ISR(TIMER1_OVF_vect) { t1_high++; }
static uint32_t now_us(void)
{
    uint16_t h, l;
    uint8_t s = SREG;
    cli();
    l = TCNT1;
    h = t1_high;
    if ((TIFR1 & _BV(TOV1)) && l < 0x8000)
        h++;
    SREG = s;
    return ((uint32_t)h << 16) | l;
}
static void wait_until(uint32_t t) { while ((int32_t)(now_us() - t) < 0); }
static void wait_us(uint32_t us) { wait_until(now_us() + us); }

/* ---------------------------------------------------------- radio IRQ (ICP1) */
static volatile uint8_t irq_count;
static volatile uint16_t irq_icr, irq_tcnt;
ISR(TIMER1_CAPT_vect)
{
    irq_tcnt = TCNT1;
    irq_icr = ICR1;
    irq_count++;
}

/* ------------------------------------------------------------------ SPI */
#define SELN_LOW()  (PORTB &= ~_BV(PB0))
#define SELN_HIGH() (PORTB |= _BV(PB0))
static uint8_t spi(uint8_t v)
{
    SPDR = v;
    while (!(SPSR & _BV(SPIF)));
    return SPDR;
}
static void reg_write(uint8_t r, uint8_t v) { SELN_LOW(); spi(0xC0 | r); spi(v); SELN_HIGH(); }
static uint8_t reg_read(uint8_t r) { uint8_t v; SELN_LOW(); spi(0x80 | r); v = spi(0); SELN_HIGH(); return v; }

enum { TRX_STATUS = 1, TRX_STATE = 2, PHY_TX_PWR = 5, PHY_RSSI = 6, PHY_CC_CCA = 8,
       IRQ_MASK = 0x0E, IRQ_STATUS = 0x0F, PART_NUM = 0x1C, MAN_ID_0 = 0x1E };
enum { ST_BUSY_RX = 1, ST_BUSY_TX = 2, ST_RX_ON = 6, ST_TRX_OFF = 8, ST_PLL_ON = 9 };
enum { IRQ_PLL_LOCK = 1, IRQ_RX_START = 4, IRQ_TRX_END = 8, IRQ_TRX_UR = 0x40 };

static uint8_t status(void) { return reg_read(TRX_STATUS) & 0x1F; }

/* wait for the next IRQ edge (input capture), at most `us` */
static uint8_t wait_irq(uint8_t seen, uint32_t us)
{
    uint32_t t0 = now_us();
    while (irq_count == seen)
        if (now_us() - t0 > us)
            return 0;
    return 1;
}

static void radio_init(void)
{
    DDRB |= _BV(PB0) | _BV(PB1) | _BV(PB2) | _BV(PB7);   /* SELN, SCK, MOSI, SLP_TR */
    SELN_HIGH();
    PORTB &= ~_BV(PB7);
    DDRA |= _BV(PA6);                                     /* RSTN */
    DDRD &= ~_BV(PD4);                                    /* IRQ = ICP1 */
    SPCR = _BV(SPE) | _BV(MSTR);
    SPSR = _BV(SPI2X);                                    /* f/2 = 4 MHz */

    PORTA &= ~_BV(PA6);
    wait_us(6);
    PORTA |= _BV(PA6);
    uint8_t st = status();
    reg_write(TRX_STATE, ST_TRX_OFF);
    puts_("init");
    kx("part", reg_read(PART_NUM));
    kx("man", reg_read(MAN_ID_0));
    kv("status", st);
    reg_write(IRQ_MASK, IRQ_PLL_LOCK | IRQ_RX_START | IRQ_TRX_END | IRQ_TRX_UR);
    reg_write(PHY_TX_PWR, 0x80);                          /* TX_AUTO_CRC_ON */
    reg_write(PHY_CC_CCA, (3 << 5) | CHANNEL);
    /* sleep and wake as TinyOS does at start */
    PORTB |= _BV(PB7);
    wait_us(100);
    uint8_t asleep = status();                            /* SPI off: 0 */
    PORTB &= ~_BV(PB7);
    wait_us(880);
    kv("sleep", asleep);
    kv("awake", status());
    putch('\n');

    /* RX_ON: PLL lock interrupt through timer 1 input capture */
    TCCR1B |= _BV(ICES1);
    TIFR1 = _BV(ICF1);
    TIMSK1 |= _BV(ICIE1);
    reg_read(IRQ_STATUS);
    uint8_t seen = irq_count;
    uint16_t t0 = TCNT1;
    reg_write(TRX_STATE, ST_RX_ON);
    uint8_t mid = reg_read(TRX_STATUS);
    uint8_t got = wait_irq(seen, 2000);
    uint8_t irq = reg_read(IRQ_STATUS);
    puts_("rx_on");
    kx("during", mid);
    kv("irq", got);
    kx("irq_status", irq);
    kv("lock_us", (uint16_t)(irq_icr - t0));
    kv("icr_lag", (uint16_t)(irq_tcnt - irq_icr));
    kv("status", status());
    putch('\n');
}

static void finish(void)
{
    puts_("done\n");
    while (!(UCSR0A & _BV(TXC0)));
    cli();
    sleep_enable();
    sleep_cpu();                                          /* simavr: cpu_Done */
}

#if ROLE == ROLE_TX
static void role(void)
{
    uint8_t buf[LEN];
    uint32_t next = now_us() + START_US;
#ifdef TX_IDLE_PLL
    reg_write(TRX_STATE, ST_PLL_ON);
#endif
    for (uint16_t i = 0; i < NFRAMES; i++) {
        wait_until(next);
        next += PERIOD_US;
        buf[0] = (uint8_t)(i >> 8);
        buf[1] = (uint8_t)i;
        buf[2] = (uint8_t)TOS_NODE_ID;
        for (uint8_t k = 3; k < LEN - 2; k++)
            buf[k] = (uint8_t)(k * 7 + i);
        reg_write(TRX_STATE, ST_PLL_ON);
        uint8_t s1 = status();
        uint8_t seen = irq_count;
        cli();
        PORTB |= _BV(PB7);                               /* SLP_TR: start */
        uint16_t t0 = TCNT1;
        sei();
        PORTB &= ~_BV(PB7);
        SELN_LOW();
        spi(0x60);
        spi(LEN);
        for (uint8_t k = 0; k < LEN - 2; k++)
            spi(buf[k]);
        SELN_HIGH();
        uint8_t s2 = status();
#ifndef TX_IDLE_PLL
        reg_write(TRX_STATE, ST_RX_ON);                  /* queued until TRX_END */
#endif
        uint8_t s3 = status();
        uint8_t got = wait_irq(seen, 20000);
        uint8_t irq = reg_read(IRQ_STATUS);
        puts_("tx");
        kv("seq", i);
        kx("pll", s1);
        kx("busy", s2);
        kx("queued", s3);
        kv("irq", got);
        kx("irq_status", irq);
        kv("air_us", (uint16_t)(irq_icr - t0));
        kx("after", status());
        putch('\n');
    }
}
#elif ROLE == ROLE_RX
static void role(void)
{
    uint8_t buf[128];
    uint16_t ok = 0, bad = 0;
    uint32_t end = now_us() + (uint32_t)RUN_MS * 1000;
    uint16_t t_start = 0;
    uint8_t seen = irq_count;
    while ((int32_t)(now_us() - end) < 0) {
        if (!wait_irq(seen, 1000))
            continue;
        seen = irq_count;
        uint16_t icr = irq_icr;
        uint8_t irq = reg_read(IRQ_STATUS);
        if (irq & IRQ_RX_START) {
            t_start = icr;
            if (!(irq & IRQ_TRX_END)) {
                uint8_t s = reg_read(TRX_STATUS);
                uint8_t rssi = reg_read(PHY_RSSI) & 0x1F;
                puts_("rx_start");
                kx("status", s);
                kv("rssi", rssi);
                putch('\n');
            }
        }
        if (irq & IRQ_TRX_END) {
            uint8_t len, lqi;
            uint16_t crc = 0;
            SELN_LOW();
            spi(0x20);
            len = spi(0);
            for (uint8_t k = 0; k < len && k < sizeof buf; k++) {
                buf[k] = spi(0);
                crc = _crc_ccitt_update(crc, buf[k]);
            }
            lqi = spi(0);
            SELN_HIGH();
            if (crc == 0) ok++; else bad++;
            puts_("rx");
            kv("seq", ((uint16_t)buf[0] << 8) | buf[1]);
            kv("from", buf[2]);
            kv("len", len);
            kv("crc_ok", crc == 0);
            kx("lqi", lqi);
            kv("start_to_end_us", (uint16_t)(icr - t_start));
            kx("status", status());
            putch('\n');
        }
    }
    puts_("rx_summary");
    kv("ok", ok);
    kv("bad", bad);
    putch('\n');
}
#elif ROLE == ROLE_TIFR
/* the radio interrupt pending while interrupts are off must survive
 * clearing another timer 1 flag (TinyOS clears OCF1A when it arms its
 * radio alarm): simavr 1.6 cleared all of them */
static void role(void)
{
    reg_write(TRX_STATE, ST_TRX_OFF);
    reg_read(IRQ_STATUS);
    uint8_t seen = irq_count;
    cli();
    reg_write(TRX_STATE, ST_RX_ON);                 /* PLL_LOCK in 180 us */
    uint16_t t0 = TCNT1;
    while ((uint16_t)(TCNT1 - t0) < 400);
    uint8_t pending = (TIFR1 & _BV(ICF1)) != 0;
    TIFR1 = _BV(OCF1A);
    uint8_t kept = (TIFR1 & _BV(ICF1)) != 0;
    sei();
    wait_us(10);
    puts_("tifr");
    kv("pending", pending);
    kv("kept", kept);
    kv("isr", irq_count != seen);
    TIFR1 = _BV(ICF1);
    kv("cleared", !(TIFR1 & _BV(ICF1)));
    putch('\n');
}
#elif ROLE == ROLE_CCA
static void role(void)
{
    uint16_t busy = 0, idle = 0, rssi_busy = 0;
    uint32_t end = now_us() + (uint32_t)RUN_MS * 1000;
    while ((int32_t)(now_us() - end) < 0) {
        reg_write(PHY_CC_CCA, 0x80 | (3 << 5) | CHANNEL);
        uint8_t early = reg_read(TRX_STATUS);
        wait_us(140);
        uint8_t s = reg_read(TRX_STATUS);
        if (early & 0x80)
            puts_("cca_done_early\n");
        if (!(s & 0x80))
            continue;
        if (s & 0x40) idle++; else busy++;
        if (reg_read(PHY_RSSI) & 0x1F) rssi_busy++;
    }
    puts_("cca");
    kv("busy", busy);
    kv("idle", idle);
    kv("rssi_busy", rssi_busy);
    putch('\n');
}
#endif

int main(void)
{
    TCCR1A = 0;
    TCCR1B = _BV(CS11);                                   /* clk/8 = 1 MHz */
    TIMSK1 = _BV(TOIE1);
    uart_init();
    sei();
    radio_init();
    role();
    finish();
    return 0;
}
