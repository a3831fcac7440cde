/*
 * emu/radio_api.h -- the radio, channel and UART calls main.c makes, as
 * emu-api.md fixes them (E2 implements them in rf230.c, channel.c,
 * uart.c).  radio_stub.c gives weak no-op versions so the harness links
 * and runs sensor motes without E2's files; E2's definitions replace them.
 */
#ifndef EMU_RADIO_API_H
#define EMU_RADIO_API_H

#include <stdio.h>
#include "emu.h"

typedef struct emu_channel emu_channel_t;
emu_channel_t *channel_new(double loss_rate, uint32_t seed);
void channel_step(emu_channel_t *ch, uint64_t now_ns);
int  rf230_attach(emu_node_t *node, emu_channel_t *ch);
void rf230_stats(emu_node_t *node, FILE *out);
int  uart_attach(emu_node_t *node, const char *spec);
void uart_poll(emu_node_t *node, uint64_t now_ns);
void uart_set_unread(emu_node_t *node, uint64_t from_ns, uint64_t until_ns);

#endif
