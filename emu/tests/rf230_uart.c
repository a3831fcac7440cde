/*
 * emu/tests/rf230_uart.c -- UART0 test program for the serial endpoint
 * (emu/uart.c): at 250000 baud (U2X, UBRR 3 at 8 MHz) it prints "ready",
 * then either echoes every byte it receives (default) or, with -DSTREAM=N,
 * sends N numbered lines "L00000\n".. back to back (after STREAM_DELAY_MS)
 * and stops.
 */
#include <avr/io.h>
#include <avr/interrupt.h>
#include <avr/sleep.h>
#include <stdint.h>
#include <util/delay.h>

#ifndef STREAM_DELAY_MS
#define STREAM_DELAY_MS 0
#endif

static void putch(char c) { while (!(UCSR0A & _BV(UDRE0))); UDR0 = c; }
static void puts_(const char *s) { while (*s) putch(*s++); }

int main(void)
{
    UCSR0A = _BV(U2X0);
    UBRR0H = 0;
    UBRR0L = 3;
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
    UCSR0B = _BV(TXEN0) | _BV(RXEN0);
    puts_("ready\n");
#ifdef STREAM
    for (uint16_t i = 0; i < STREAM_DELAY_MS; i++)
        _delay_ms(1);
    for (uint16_t i = 0; i < STREAM; i++) {
        char b[8] = "L00000\n";
        uint16_t v = i;
        for (int k = 5; k >= 1; k--) { b[k] = (char)('0' + v % 10); v /= 10; }
        puts_(b);
    }
    while (!(UCSR0A & _BV(TXC0)));
    cli();
    sleep_enable();
    sleep_cpu();
#else
    for (;;) {
        if (UCSR0A & _BV(RXC0))
            putch(UDR0);
    }
#endif
    return 0;
}
