/*
 * NineDofBaseP -- radio <-> serial bridge for the 9DOF motes.
 *
 * Behaves like TinyOS's apps/BaseStation: every packet heard on the radio
 * (whatever its destination) goes to the serial line with the mote's source
 * and group, every packet from the serial line goes out on the radio to its
 * destination.  Differences: queues of NINEDOF_BS_QUEUE (12) messages each
 * way, sized for six 125 Hz motes; a full queue drops the packet and counts
 * it; a unicast radio send asks for an acknowledgement and is repeated up
 * to NINEDOF_BS_RETRIES times by the radio stack's PacketLink layer (the
 * same frame, same DSN: the mote drops a repeat of a frame it got), then
 * counted as failed and dropped (the stock BaseStation retries forever and
 * blocks its queue); a send that ends in EBUSY (the channel busy through
 * all of the radio stack's backoff rounds) is started again up to
 * NINEDOF_BS_RETRIES times; the serial line
 * runs at PLATFORM_BAUDRATE (250000 by default) with a correctly rounded
 * divisor; a ninedof_bs_status_msg with the counters goes to the serial line
 * every 2 s.
 *
 * LEDs: green  toggles for every packet forwarded radio -> serial
 *       yellow toggles for every packet forwarded serial -> radio
 *       red    toggles for every packet dropped or failed
 *
 * @author motecal
 */
#include "NineDofBase.h"

module NineDofBaseP @safe()
{
  uses {
    interface Boot;
    interface Leds;
    interface Atm128Calibrate;
    interface Timer<TMilli> as StatusTimer;

    interface SplitControl as SerialControl;
    interface AMSend as UartSend[am_id_t id];
    interface Receive as UartReceive[am_id_t id];
    interface Packet as UartPacket;
    interface AMPacket as UartAMPacket;

    interface SplitControl as RadioControl;
    interface AMSend as RadioSend[am_id_t id];
    interface Receive as RadioReceive[am_id_t id];
    interface Receive as RadioSnoop[am_id_t id];
    interface Packet as RadioPacket;
    interface AMPacket as RadioAMPacket;
    interface PacketAcknowledgements as RadioAcks;
    interface PacketLink as RadioLink;
  }
}
implementation
{
  enum {
    QUEUE = NINEDOF_BS_QUEUE,
    STATUS_TICKS = (uint32_t)NINEDOF_STATUS_PERIOD_MS * 1024UL / 1000UL,
  };

  /* A queue of message buffers: `count` filled from `out` on; the buffer
   * a receive fills is swapped in, the one it replaces goes back to the
   * radio/serial stack. */
  typedef struct {
    message_t *slot[QUEUE];
    uint8_t out, count;
    bool busy, on;
    uint8_t attempts;
  } queue_t;

  message_t uartBufs[QUEUE], radioBufs[QUEUE];
  queue_t toUart, toRadio;
  message_t statusMsg;
  bool statusPending = FALSE, statusSending = FALSE;
  ninedof_bs_counters_t counters;

  task void uartSendTask();
  task void radioSendTask();

  void queueInit(queue_t *q, message_t *bufs) {
    uint8_t i;
    for (i = 0; i < QUEUE; i++)
      q->slot[i] = &bufs[i];
    q->out = q->count = 0;
    q->busy = q->on = FALSE;
    q->attempts = 0;
  }

  /* Keep `msg` in the queue; returns the buffer to give back, or NULL if full. */
  message_t *enqueue(queue_t *q, message_t *msg) {
    uint8_t in;
    message_t *spare;
    if (!q->on || q->count == QUEUE)
      return NULL;
    in = (uint8_t)((q->out + q->count) % QUEUE);
    spare = q->slot[in];
    q->slot[in] = msg;
    q->count++;
    return spare;
  }

  void dequeue(queue_t *q) {
    q->out = (uint8_t)((q->out + 1) % QUEUE);
    q->count--;
    q->attempts = 0;
  }

  event void Boot.booted() {
    uint16_t ubrr = ninedof_bs_ubrr(call Atm128Calibrate.cyclesPerJiffy(), PLATFORM_BAUDRATE);

    /* TinyOS truncates the divisor (333 kbaud for 250000 at 8 MHz); set the
     * rounded one before the UART is switched on.  U2X stays set. */
    atomic {
      UBRR0H = (uint8_t)(ubrr >> 8);
      UBRR0L = (uint8_t)ubrr;
    }
    queueInit(&toUart, uartBufs);
    queueInit(&toRadio, radioBufs);
    call RadioControl.start();
    call SerialControl.start();
  }

  event void RadioControl.startDone(error_t err) {
    if (err != SUCCESS) {
      call RadioControl.start();
      return;
    }
    toRadio.on = TRUE;
    post radioSendTask();
  }

  event void SerialControl.startDone(error_t err) {
    if (err != SUCCESS) {
      call SerialControl.start();
      return;
    }
    toUart.on = TRUE;
    call StatusTimer.startPeriodic(STATUS_TICKS);
    post uartSendTask();
  }

  event void RadioControl.stopDone(error_t err) { }
  event void SerialControl.stopDone(error_t err) { }

  /* ------------------------------------------------------- radio -> serial */
  message_t *fromRadio(message_t *msg) {
    message_t *spare;
    counters.radio_rx++;
    spare = enqueue(&toUart, msg);
    if (spare == NULL) {
      counters.radio_drops++;
      call Leds.led0Toggle();
      return msg;
    }
    post uartSendTask();
    return spare;
  }

  event message_t *RadioReceive.receive[am_id_t id](message_t *msg, void *payload, uint8_t len) {
    return fromRadio(msg);
  }

  event message_t *RadioSnoop.receive[am_id_t id](message_t *msg, void *payload, uint8_t len) {
    return fromRadio(msg);
  }

  task void uartSendTask() {
    message_t *msg;
    uint8_t len;
    am_id_t id;
    am_addr_t dest, src;
    am_group_t group;

    if (toUart.busy || statusSending || !toUart.on)
      return;
    if (statusPending) {
      ninedof_bs_status_msg_t *p = (ninedof_bs_status_msg_t *)call UartPacket.getPayload(
        &statusMsg, sizeof(ninedof_bs_status_msg_t));
      if (p != NULL) {
        ninedof_bs_status_pack(&counters, p);
        call UartAMPacket.setSource(&statusMsg, TOS_NODE_ID);
        call UartAMPacket.setGroup(&statusMsg, TOS_AM_GROUP);
        if (call UartSend.send[AM_NINEDOF_BS_STATUS_MSG](AM_BROADCAST_ADDR, &statusMsg,
                                                         sizeof(ninedof_bs_status_msg_t))
            == SUCCESS) {
          statusPending = FALSE;
          statusSending = TRUE;
          return;
        }
      }
      statusPending = FALSE;
    }
    if (toUart.count == 0)
      return;
    msg = toUart.slot[toUart.out];
    if (toUart.attempts == 0) {
      /* first attempt: turn the radio packet into a serial packet (the two
       * headers share the same bytes of message_t) */
      len = call RadioPacket.payloadLength(msg);
      id = call RadioAMPacket.type(msg);
      dest = call RadioAMPacket.destination(msg);
      src = call RadioAMPacket.source(msg);
      group = call RadioAMPacket.group(msg);
      call UartPacket.clear(msg);
      call UartPacket.setPayloadLength(msg, len);
      call UartAMPacket.setDestination(msg, dest);
      call UartAMPacket.setType(msg, id);
      call UartAMPacket.setSource(msg, src);
      call UartAMPacket.setGroup(msg, group);
    }
    len = call UartPacket.payloadLength(msg);
    id = call UartAMPacket.type(msg);
    dest = call UartAMPacket.destination(msg);
    if (call UartSend.send[id](dest, msg, len) == SUCCESS) {
      toUart.busy = TRUE;
    } else {
      if (++toUart.attempts > NINEDOF_BS_RETRIES) {
        counters.serial_fail++;
        call Leds.led0Toggle();
        dequeue(&toUart);
      }
      post uartSendTask();
    }
  }

  event void UartSend.sendDone[am_id_t id](message_t *msg, error_t err) {
    if (msg == &statusMsg) {
      statusSending = FALSE;
    } else {
      toUart.busy = FALSE;
      if (err == SUCCESS) {
        call Leds.led1Toggle();
        dequeue(&toUart);
      } else if (++toUart.attempts > NINEDOF_BS_RETRIES) {
        counters.serial_fail++;
        call Leds.led0Toggle();
        dequeue(&toUart);
      }
      /* else: the same message again */
    }
    post uartSendTask();
  }

  event void StatusTimer.fired() {
    statusPending = TRUE;
    post uartSendTask();
  }

  /* ------------------------------------------------------- serial -> radio */
  event message_t *UartReceive.receive[am_id_t id](message_t *msg, void *payload, uint8_t len) {
    message_t *spare;
    counters.serial_rx++;
    spare = enqueue(&toRadio, msg);
    if (spare == NULL) {
      counters.serial_drops++;
      call Leds.led0Toggle();
      return msg;
    }
    post radioSendTask();
    return spare;
  }

  task void radioSendTask() {
    message_t *msg;
    uint8_t len;
    am_id_t id;
    am_addr_t dest;

    if (toRadio.busy || toRadio.count == 0 || !toRadio.on)
      return;
    msg = toRadio.slot[toRadio.out];
    if (toRadio.attempts == 0) {
      /* first attempt: turn the serial packet into a radio packet */
      len = call UartPacket.payloadLength(msg);
      dest = call UartAMPacket.destination(msg);
      id = call UartAMPacket.type(msg);
      call RadioPacket.clear(msg);
      call RadioPacket.setPayloadLength(msg, len);
      call RadioAMPacket.setDestination(msg, dest);
      call RadioAMPacket.setType(msg, id);
    }
    len = call RadioPacket.payloadLength(msg);
    dest = call RadioAMPacket.destination(msg);
    id = call RadioAMPacket.type(msg);
    /* unicast: acknowledged, up to 1 + NINEDOF_BS_RETRIES transmissions */
    call RadioLink.setRetries(msg, dest != AM_BROADCAST_ADDR ? 1 + NINEDOF_BS_RETRIES : 0);
    call RadioLink.setRetryDelay(msg, 0);
    if (call RadioSend.send[id](dest, msg, len) == SUCCESS) {
      toRadio.busy = TRUE;
    } else {
      if (++toRadio.attempts > NINEDOF_BS_RETRIES) {
        counters.radio_fail++;
        call Leds.led0Toggle();
        dequeue(&toRadio);
      }
      post radioSendTask();
    }
  }

  /* The radio stack has made its tries: delivered, ended by a busy channel
   * (EBUSY: again), or given up. */
  event void RadioSend.sendDone[am_id_t id](message_t *msg, error_t err) {
    bool delivered = (err == SUCCESS) &&
      (call RadioAMPacket.destination(msg) == AM_BROADCAST_ADDR || call RadioAcks.wasAcked(msg));
    toRadio.busy = FALSE;
    if (delivered) {
      call Leds.led2Toggle();
      dequeue(&toRadio);
    } else if (err != EBUSY || ++toRadio.attempts > NINEDOF_BS_RETRIES) {
      counters.radio_fail++;
      call Leds.led0Toggle();
      dequeue(&toRadio);
    }
    post radioSendTask();
  }
}
