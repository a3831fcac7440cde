/*
 * emu/radio_stub.c -- weak no-op radio, channel and UART (radio_api.h):
 * without E2's rf230.c / channel.c / uart.c the motes have no radio chip
 * on their SPI bus and UART0 goes nowhere.  E2's strong definitions win
 * at link time.
 */
#include "radio_api.h"

__attribute__((weak)) emu_channel_t *channel_new(double loss_rate, uint32_t seed)
{
    (void)loss_rate; (void)seed;
    return NULL;
}
__attribute__((weak)) void channel_step(emu_channel_t *ch, uint64_t now_ns)
{
    (void)ch; (void)now_ns;
}
__attribute__((weak)) int rf230_attach(emu_node_t *node, emu_channel_t *ch)
{
    (void)node; (void)ch;
    return -1;
}
__attribute__((weak)) void rf230_stats(emu_node_t *node, FILE *out)
{
    (void)node;
    fprintf(out, "radio: not modelled in this build (no rf230.c)\n");
}
__attribute__((weak)) int uart_attach(emu_node_t *node, const char *spec)
{
    (void)node; (void)spec;
    return -1;
}
__attribute__((weak)) void uart_poll(emu_node_t *node, uint64_t now_ns)
{
    (void)node; (void)now_ns;
}
__attribute__((weak)) void uart_set_unread(emu_node_t *node, uint64_t from_ns, uint64_t until_ns)
{
    (void)node; (void)from_ns; (void)until_ns;
}
