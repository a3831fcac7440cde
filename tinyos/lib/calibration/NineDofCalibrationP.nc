/*
 * NineDofCalibrationP -- calibration messages in, replies out, the set in
 * force, and its EEPROM image.
 *
 * Every calibration message (fragment, commit, query) goes to the shared
 * receiver (ninedof_calrx_handle, ninedof_calrx.c: the same C the host's
 * simulator runs).  It never puts a partial or invalid set in force: a
 * commit is applied only when every byte of the staged set arrived, its CRC
 * matches, and it validates; otherwise the set in force stays.  The reply
 * goes back to the sender from its own buffer, acknowledged and sent up to
 * 1 + NINEDOF_RETRIES times by PacketLink (same DSN), and again up to
 * NINEDOF_RETRIES times after EBUSY; a reply while the previous one is
 * still on its way is not sent (the host repeats its message, which the
 * receiver handles idempotently).
 *
 * An accepted set is written to the internal EEPROM in the background
 * (ninedof_eewriter, ninedof_sampling.c), one byte per 4 ms, while
 * sampling continues, into the slot that does not hold the newest valid
 * image, and read back; at boot (Init) the valid image with the newer
 * generation goes in force.  A reset in the middle of a write leaves that
 * slot with a bad CRC, and the other one wins.  The set the EEPROM holds
 * (read back intact) is what a query with NINEDOF_QUERY_STORED reports as
 * stored: the host waits for it before it tells the user the set survives
 * a reset.
 *
 * LED: yellow on while a set is being written to EEPROM (up to ~0.7 s).
 *
 * @author motecal
 */
#include <avr/eeprom.h>
#include "NineDofApp.h"

module NineDofCalibrationP @safe()
{
  provides interface Init;
  provides interface NineDofCalibration;
  uses {
    interface Leds;
    interface AMSend as FragAckSend;
    interface AMSend as CommitAckSend;
    interface AMSend as ReportSend;
    interface Receive as FragReceive;
    interface Receive as CommitReceive;
    interface Receive as QueryReceive;
    interface AMPacket;
    interface PacketLink;
    interface Timer<TMilli> as EepromTimer;
  }
}
implementation
{
  enum {
    EEPROM_TICKS = 4,            /* an EEPROM byte write takes 3.3 ms */
  };

  /* calibration in force, EEPROM writer: tasks only */
  ninedof_calrx_t rx;
  ninedof_eewriter_t eewriter;

  message_t replyMsg;
  bool replyBusy = FALSE;
  am_addr_t replyTo;
  uint8_t replyType, replyLen, replyAttempts;

  command error_t Init.init() {
    /* the two EEPROM slots, and the second slot of images built before
     * the temperature terms (NINEDOF_EEPROM_LEGACY1, read only) */
    uint8_t bootImage[2][NINEDOF_IMAGE_MAX];
    uint8_t legacy[NINEDOF_IMAGE_SIZE];
    uint8_t slot;
    uint16_t generation;

    ninedof_calrx_init(&rx, TOS_NODE_ID);
    eeprom_read_block(bootImage[0], (const void *)NINEDOF_EEPROM_SLOT0, NINEDOF_IMAGE_MAX);
    eeprom_read_block(bootImage[1], (const void *)NINEDOF_EEPROM_SLOT1, NINEDOF_IMAGE_MAX);
    eeprom_read_block(legacy, (const void *)NINEDOF_EEPROM_LEGACY1, NINEDOF_IMAGE_SIZE);
    ninedof_calrx_restore(&rx, bootImage[0], bootImage[1], legacy, &slot, &generation);
    ninedof_eewriter_init(&eewriter, slot, generation);
    return SUCCESS;
  }

  command ninedof_calrx_t *NineDofCalibration.inForce() {
    return &rx;
  }

  command void NineDofCalibration.setTemperature(int16_t raw) {
    ninedof_calrx_set_temp(&rx, raw);
  }

  void persist() {
    if (ninedof_eewriter_poll(&eewriter, &rx)) {
      call Leds.led2On();
      call EepromTimer.startPeriodic(EEPROM_TICKS);
    }
  }

  /* One EEPROM byte per tick; bytes already equal are skipped.  When every
   * byte is written (the last write done: eeprom_is_ready), the slot is
   * read back and checked: only then is the set stored, and the report
   * says so (ninedof_eewriter_check). */
  event void EepromTimer.fired() {
    uint16_t addr;
    uint8_t value;
    if (!eeprom_is_ready())
      return;
    while (ninedof_eewriter_next(&eewriter, &addr, &value)) {
      if (eeprom_read_byte((const uint8_t *)addr) != value) {
        eeprom_write_byte((uint8_t *)addr, value);   /* 3.3 ms, in hardware */
        return;
      }
    }
    if (ninedof_eewriter_pending(&eewriter)) {
      uint8_t back[NINEDOF_IMAGE_MAX];
      eeprom_read_block(back, (const void *)ninedof_eewriter_addr(&eewriter), eewriter.len);
      if (ninedof_eewriter_check(&eewriter, &rx, back) == NINEDOF_EE_AGAIN)
        return;                                      /* written again from the next tick */
    }
    call EepromTimer.stop();
    call Leds.led2Off();
  }

  /* The reply in replyMsg, to replyTo, acknowledged and repeated. */
  error_t sendReply() {
    call PacketLink.setRetries(&replyMsg, 1 + NINEDOF_RETRIES);
    call PacketLink.setRetryDelay(&replyMsg, 0);
    if (replyType == AM_NINEDOF_CAL_FRAG_ACK_MSG)
      return call FragAckSend.send(replyTo, &replyMsg, replyLen);
    if (replyType == AM_NINEDOF_CAL_COMMIT_ACK_MSG)
      return call CommitAckSend.send(replyTo, &replyMsg, replyLen);
    if (replyType == AM_NINEDOF_CAL_REPORT_MSG)
      return call ReportSend.send(replyTo, &replyMsg, replyLen);
    return FAIL;
  }

  void calibration(uint8_t type, message_t *m, void *payload, uint8_t len) {
    uint8_t reply[sizeof(ninedof_cal_report_msg_t)];
    uint8_t rtype = 0, n, *out;

    n = ninedof_calrx_handle(&rx, type, (const uint8_t *)payload, len, reply, &rtype);
    persist();
    if (n == 0 || replyBusy)
      return;
    out = (uint8_t *)call FragAckSend.getPayload(&replyMsg, n);
    if (out == NULL)
      return;
    memcpy(out, reply, n);
    replyTo = call AMPacket.source(m);
    replyType = rtype;
    replyLen = n;
    replyAttempts = 0;
    replyBusy = (sendReply() == SUCCESS);
  }

  /* Sent or given up; ended by a busy channel: again. */
  void replyDone(message_t *m, error_t err) {
    if (err == EBUSY && ++replyAttempts <= NINEDOF_RETRIES && sendReply() == SUCCESS)
      return;
    replyBusy = FALSE;
  }

  event message_t *FragReceive.receive(message_t *m, void *payload, uint8_t len) {
    calibration(AM_NINEDOF_CAL_FRAG_MSG, m, payload, len);
    return m;
  }

  event message_t *CommitReceive.receive(message_t *m, void *payload, uint8_t len) {
    calibration(AM_NINEDOF_CAL_COMMIT_MSG, m, payload, len);
    return m;
  }

  event message_t *QueryReceive.receive(message_t *m, void *payload, uint8_t len) {
    calibration(AM_NINEDOF_CAL_QUERY_MSG, m, payload, len);
    return m;
  }

  event void FragAckSend.sendDone(message_t *m, error_t err) { replyDone(m, err); }
  event void CommitAckSend.sendDone(message_t *m, error_t err) { replyDone(m, err); }
  event void ReportSend.sendDone(message_t *m, error_t err) { replyDone(m, err); }
}
