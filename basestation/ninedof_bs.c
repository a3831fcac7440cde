/*
 * ninedof_bs.c -- see ninedof_bs.h.
 */
#include "ninedof_bs.h"

void ninedof_bs_status_pack(const ninedof_bs_counters_t *c, ninedof_bs_status_msg_t *msg)
{
  nxp_set_u16(&msg->radio_rx, c->radio_rx);
  nxp_set_u16(&msg->radio_drops, c->radio_drops);
  nxp_set_u16(&msg->serial_rx, c->serial_rx);
  nxp_set_u16(&msg->serial_drops, c->serial_drops);
  nxp_set_u16(&msg->radio_fail, c->radio_fail);
  nxp_set_u16(&msg->serial_fail, c->serial_fail);
}

uint16_t ninedof_bs_ubrr(uint16_t cycles_per_jiffy, uint32_t baud)
{
  uint32_t num = (uint32_t)cycles_per_jiffy << 12;     /* cycles * 32768 / 8 */
  uint32_t divisor = (num + baud / 2) / baud;
  return (uint16_t)(divisor > 0 ? divisor - 1 : 0);
}

uint32_t ninedof_bs_baud(uint16_t cycles_per_jiffy, uint16_t ubrr)
{
  return ((uint32_t)cycles_per_jiffy << 12) / ((uint32_t)ubrr + 1);
}
