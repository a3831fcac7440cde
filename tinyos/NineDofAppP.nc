/*
 * NineDofAppP -- 125 Hz 9DOF sampling mote.
 *
 * Every 8 ms of the 32768 Hz crystal the board reads the nine axes; each
 * period has a sequence number.  The magnetometer's data are those of the
 * measurement the previous read triggered, so the record of a period is
 * completed by the next read (ninedof_align_push): accel, gyro and field of
 * one instant, one period later.  The period is timed by a
 * "32 kHz" alarm, which on iris counts the CPU's RC oscillator (nominally
 * 31250 Hz, 250 ticks), due at its own previous expiry plus the number of
 * ticks ninedof_clock.c computes (armed relative to now, see
 * ninedof_clock_arm: never in the past, never by a lagging counter, which
 * on iris cost a 65.5 ms timer wrap per expiry): at each expiry it takes the
 * crystal time (LocalTime<TMilli>) and keeps the long-run rate at 125.000
 * Hz of the crystal, periods differing by at most one tick.  Records of
 * consecutive periods are batched NINEDOF_BATCH to a message, corrected with the
 * calibration in force and flagged (ninedof_sampling.c, ninedof_correct.c) and
 * sent to the BaseStation (address 0) through a queue of NINEDOF_SEND_QUEUE
 * messages; when the queue is full the batch is dropped and counted.  A
 * ninedof_mote_status_msg goes out every 2 s from its own buffer, without
 * acknowledgement (the next one replaces a lost one).  Every read also
 * brings the board temperature (the ITG-3200's TEMP_OUT, same I2C burst as
 * the rates); the readings of each second are summed (ninedof_temp_add)
 * and sent as a ninedof_mote_temp_msg every NINEDOF_TEMP_PERIOD_MS, from
 * its own buffer without acknowledgement, and the second's mean becomes
 * the temperature of the on-mote correction (Calibration.setTemperature)
 * for the next second.  Until the first mean (the first second after
 * boot), the correction takes the latest single reading instead (set
 * before each batch is corrected, when it changed), so a warming board is
 * not corrected at the sensors' reference temperature.  The calibration
 * upload, the set in force and its EEPROM image are NineDofCalibrationC's
 * (lib/calibration); this module only reads the set in force
 * (NineDofCalibration) to correct and flag each batch.
 *
 * Sample messages ask for an acknowledgement and
 * are sent up to 1 + NINEDOF_RETRIES times by the radio stack's PacketLink
 * layer, which repeats a frame with its sequence number (DSN), so the
 * receiver drops a repeat whose first copy got through.  A sample message
 * that ends in EBUSY (the channel was busy through all of the
 * radio stack's backoff rounds) is sent again, up to NINEDOF_RETRIES times;
 * that is a new DSN, so if an earlier try got through unacknowledged the
 * BaseStation forwards it twice (the logger drops the duplicate).  The sample, status and reply buffers take
 * turns on the radio (AMSenderC's round robin).
 *
 * The board's watchdog (NineDofHealth.tick, ninedof_fault.h) runs on the
 * 125 Hz alarm: a read still under way 16 ms (two periods) after it began is
 * aborted and the bus recovered, so sampling never stops for good; a chip
 * that was reset is found by a read-back and configured again.  NACKs,
 * watchdog aborts and re-initialisations are counted.
 *
 * LEDs: red    on   = sensor board not answering (retried every second);
 *              flash = a failed sensor read (on for FLASH_TICKS, then off;
 *                      a run of failures keeps it on)
 *       green  toggles every 125 samples (one second) while sampling
 *       yellow on   = a new calibration is being written to EEPROM (~0.4 s;
 *                     NineDofCalibrationC)
 *
 * @author motecal
 */
#include <MicaTimer.h>
#include "NineDofApp.h"
#include "NineDofBoard.h"

module NineDofAppP @safe()
{
  uses {
    interface Boot;
    interface Leds;
    interface SplitControl as BoardControl;
    interface ReadNow<ninedof_raw_t> as Board;
    interface NineDofHealth as Health;
    interface Alarm<T32khz, uint32_t> as Alarm;
    interface LocalTime<TMilli> as Crystal;
    interface Atm128Calibrate;
    interface SplitControl as RadioControl;
    interface AMSend as SampleSend;
    interface AMSend as StatusSend;
    interface AMSend as TempSend;
    interface NineDofCalibration as Calibration;
    interface PacketAcknowledgements as Acks;
    interface PacketLink;
    interface Pool<message_t> as SamplePool;
    interface Queue<message_t*> as SendQueue;
    interface Timer<TMilli> as StatusTimer;
    interface Timer<TMilli> as TempTimer;
    interface Timer<TMilli> as RetryTimer;
    interface Timer<TMilli> as FlashTimer;
  }
}
implementation
{
  enum {
    BASESTATION = NINEDOF_BASESTATION_ADDR,
    /* binary milliseconds: 2000 ms = 2048 TMilli ticks */
    STATUS_TICKS = (uint32_t)NINEDOF_STATUS_PERIOD_MS * 1024UL / 1000UL,
    /* 1000 ms = 1024 binary ms: 128 periods of 8 binary ms */
    TEMP_TICKS = (uint32_t)NINEDOF_TEMP_PERIOD_MS * 1024UL / 1000UL,
    RETRY_TICKS = 1024,
    FLASH_TICKS = 51,            /* red flash for a failed read: 50 ms */
    /* Alarm32khz32C's counter: timer 1 (16 bits) / 2^MICA_DIVIDE_ONE_FOR_32KHZ_LOG2
     * plus an overflow count; one overflow = 2048 ticks at 8 MHz */
    NINEDOF_ALARM_WRAP = 65536UL >> MICA_DIVIDE_ONE_FOR_32KHZ_LOG2,
    PENDING = 4,                 /* samples read, not yet batched */
  };

  /* batch being filled: tasks only */
  ninedof_batch_t batch;

  /* the 125 Hz period: set up in startSampling() before the alarm is armed,
   * then used only in Alarm.fired(), before it re-arms the alarm */
  norace ninedof_clock_t clock;
  /* the expiry the alarm is armed for (alarm ticks), same rule as clock;
   * the period it was set with is clock.last */
  norace uint32_t alarmTarget;

  /* shared with the alarm and I2C interrupts */
  ninedof_counters_t counters;
  bool sampling = FALSE;
  bool reading = FALSE;
  uint16_t readSeq;
  ninedof_align_t align;             /* the read waiting for its field */
  ninedof_temp_acc_t temps;          /* TEMP_OUT readings of this second */
  /* before the first second's mean: the latest reading, for the correction */
  int16_t tempLatest;
  bool tempSeen = FALSE;             /* tempLatest holds a reading */
  bool tempFresh = FALSE;            /* tempLatest changed, not yet in force */
  bool tempMeanKnown = FALSE;        /* a second's mean is in force */
  ninedof_raw_t pending[PENDING];
  uint16_t pendingSeq[PENDING];
  uint8_t pendingHead, pendingCount;

  /* radio: tasks only */
  bool radioOn = FALSE, boardOn = FALSE, sending = FALSE;
  uint8_t attempts;
  uint16_t heartbeat;
  message_t statusMsg;
  bool statusBusy = FALSE;
  message_t tempMsg;
  bool tempBusy = FALSE;

  task void processSamples();
  task void sendNext();
  task void readFailed();

  /* ---------------------------------------------------------------- boot */
  event void Boot.booted() {
    ninedof_counters_init(&counters);
    ninedof_align_init(&align);
    ninedof_temp_init(&temps);
    ninedof_batch_init(&batch);

    call RadioControl.start();
    call BoardControl.start();
    call RetryTimer.startPeriodic(RETRY_TICKS);
  }

  /* Arm the alarm for alarmTarget relative to now, never for a time in the
   * past, and right even while the counter lags by an overflow not yet
   * counted (ninedof_clock.h: on iris either one made the alarm wait a
   * 16-bit timer wrap, 65.5 ms, and every later one too).  With interrupts
   * off, so TransformAlarmC reads the counter as it was read here. */
  void armAlarm() {
    uint32_t now = call Alarm.getNow();
    call Alarm.startAt(now, ninedof_clock_arm(alarmTarget, now, clock.last,
                                              NINEDOF_ALARM_WRAP));
  }

  void startSampling() {
    if (!radioOn || !boardOn)
      return;
    atomic {
      if (sampling)
        return;
      sampling = TRUE;
      ninedof_clock_init(&clock, call Atm128Calibrate.cyclesPerJiffy());
      alarmTarget = call Alarm.getNow() + ninedof_clock_first(&clock);
      armAlarm();
    }
  }

  event void RadioControl.startDone(error_t err) {
    if (err != SUCCESS) {
      call RadioControl.start();
      return;
    }
    radioOn = TRUE;
    /* status from now on, board or not: the host tells a dead board
     * (status messages, no samples, i2c_nacks growing) from a mote that
     * is off (nothing) */
    call StatusTimer.startPeriodic(STATUS_TICKS);
    call TempTimer.startPeriodic(TEMP_TICKS);
    startSampling();
  }

  event void RadioControl.stopDone(error_t err) { }

  event void BoardControl.startDone(error_t err) {
    if (err != SUCCESS) {
      call Leds.led0On();                     /* board not answering: RetryTimer */
      return;
    }
    call RetryTimer.stop();
    call Leds.led0Off();
    boardOn = TRUE;
    startSampling();
  }

  event void BoardControl.stopDone(error_t err) { }

  /* Every second until the board has started: the board's watchdog tick
   * (a start that hangs on the bus is aborted at the first tick 16 ms or
   * more after it began), and the start again (SUCCESS without a second
   * start while one is under way, TEP 115). */
  event void RetryTimer.fired() {
    call Health.tick();
    call BoardControl.start();
  }

  /* ------------------------------------------------------ 125 Hz period */
  async event void Alarm.fired() {
    uint16_t seq;
    bool busy;

    /* next period from this one's expiry, as long as the crystal says */
    alarmTarget += ninedof_clock_next(&clock, call Crystal.get());
    armAlarm();
    call Health.tick();                       /* a read that hangs is aborted */
    atomic {
      seq = counters.seq++;
      busy = reading;
      if (busy)
        counters.late++;                      /* previous read still running */
      else {
        reading = TRUE;
        readSeq = seq;
      }
    }
    if (busy)
      return;
    if (call Board.read() != SUCCESS) {
      atomic {
        reading = FALSE;
        counters.i2c_errors++;                /* refused: no transfer, no trigger */
      }
      post readFailed();
    }
  }

  async event void Board.readDone(error_t err, ninedof_raw_t val) {
    ninedof_raw_t rec;
    uint16_t recSeq;
    atomic {
      reading = FALSE;
#ifndef NINEDOF_ITG_RATES_ONLY   /* (a comparison build without the temperature) */
      if (err == SUCCESS) {
        ninedof_temp_add(&temps, readSeq, val.temp);   /* the temperature of sample readSeq */
        if (!tempMeanKnown && (!tempSeen || val.temp != tempLatest)) {
          tempLatest = val.temp;              /* a new reading for the correction */
          tempSeen = TRUE;
          tempFresh = TRUE;
        }
      }
#endif
      if (err != SUCCESS) {
        counters.i2c_errors++;
        ninedof_align_lost(&align);           /* its trigger may not have gone out */
      } else if (!ninedof_align_push(&align, readSeq, val.axis, rec.axis, &recSeq)) {
        /* first read after a start or a failure: completes no record */
      } else if (pendingCount == PENDING) {
        counters.dropped++;                   /* tasks did not run for 32 ms */
      } else {
        uint8_t i = (uint8_t)((pendingHead + pendingCount) % PENDING);
        pending[i] = rec;
        pendingSeq[i] = recSeq;
        pendingCount++;
      }
    }
    if (err != SUCCESS)
      post readFailed();
    else
      post processSamples();
  }

  /* Flash: red on, off again after FLASH_TICKS (a toggle would leave it on
   * after an odd number of failures, which reads as "board not answering"). */
  task void readFailed() {
    call Leds.led0On();
    call FlashTimer.startOneShot(FLASH_TICKS);
  }

  event void FlashTimer.fired() {
    call Leds.led0Off();
  }

  /* ------------------------------------------------------------ batching */
  /* Queue the batch as one message, or drop it if the queue is full. */
  void flush() {
    message_t *m;
    ninedof_samples_msg_t *p;

    if (batch.count == 0)
      return;
    if (call SamplePool.empty()) {
      atomic counters.dropped += batch.count;
      ninedof_batch_init(&batch);
      return;
    }
    m = call SamplePool.get();
    p = (ninedof_samples_msg_t *)call SampleSend.getPayload(m, sizeof(ninedof_samples_msg_t));
    if (p == NULL) {
      call SamplePool.put(m);
      atomic counters.dropped += batch.count;
      ninedof_batch_init(&batch);
      return;
    }
    ninedof_batch_pack(&batch, call Calibration.inForce(), p);
    call SendQueue.enqueue(m);
    post sendNext();
  }

  task void processSamples() {
    int16_t t;
    bool fresh;
    atomic {
      fresh = tempFresh;
      t = tempLatest;
      tempFresh = FALSE;
    }
    if (fresh)                                /* no mean yet: the latest reading */
      call Calibration.setTemperature(t);
    for (;;) {
      ninedof_raw_t v;
      uint16_t seq;
      atomic {
        if (pendingCount == 0)
          return;
        v = pending[pendingHead];
        seq = pendingSeq[pendingHead];
        pendingHead = (uint8_t)((pendingHead + 1) % PENDING);
        pendingCount--;
      }
      if (!ninedof_batch_fits(&batch, seq))
        flush();                              /* a period is missing: new message */
      if (ninedof_batch_add(&batch, seq, v.axis))
        flush();
      if (++heartbeat >= NINEDOF_RATE_HZ) {
        heartbeat = 0;
        call Leds.led1Toggle();
      }
    }
  }

  /* --------------------------------------------------------------- radio */
  uint8_t sampleLength(message_t *m) {
    ninedof_samples_msg_t *p =
      (ninedof_samples_msg_t *)call SampleSend.getPayload(m, sizeof(ninedof_samples_msg_t));
    return (uint8_t)(sizeof(ninedof_samples_msg_t) -
                     (NINEDOF_BATCH - p->count) * sizeof(ninedof_record_t));
  }

  void sendFinished(bool delivered) {
    message_t *m = call SendQueue.dequeue();
    if (!delivered)
      atomic counters.send_fail++;
    call SamplePool.put(m);
    attempts = 0;
  }

  /* Acknowledged, up to 1 + NINEDOF_RETRIES transmissions of the same frame */
  void linkRetries(message_t *m) {
    call PacketLink.setRetries(m, 1 + NINEDOF_RETRIES);
    call PacketLink.setRetryDelay(m, 0);
  }

  task void sendNext() {
    message_t *m;
    if (sending || call SendQueue.empty())
      return;
    m = call SendQueue.head();
    linkRetries(m);
    if (call SampleSend.send(BASESTATION, m, sampleLength(m)) == SUCCESS) {
      sending = TRUE;
    } else if (++attempts > NINEDOF_RETRIES) {
      sendFinished(FALSE);                    /* refused again and again */
      post sendNext();
    } else {
      post sendNext();
    }
  }

  /* The radio stack has made its tries: acknowledged, ended by a busy
   * channel (EBUSY: send it again), or given up. */
  event void SampleSend.sendDone(message_t *m, error_t err) {
    sending = FALSE;
    if (err == SUCCESS && call Acks.wasAcked(m))
      sendFinished(TRUE);
    else if (err != EBUSY || ++attempts > NINEDOF_RETRIES)
      sendFinished(FALSE);
    post sendNext();
  }

  event void StatusTimer.fired() {
    ninedof_mote_status_msg_t *p;
    ninedof_counters_t c;
    ninedof_fault_counters_t faults;
    if (statusBusy)
      return;
    p = (ninedof_mote_status_msg_t *)call StatusSend.getPayload(
      &statusMsg, sizeof(ninedof_mote_status_msg_t));
    if (p == NULL)
      return;
    atomic c = counters;
    faults = call Health.counters();
    ninedof_status_pack(&c, &faults, call Calibration.inForce(), p);
    call PacketLink.setRetries(&statusMsg, 0);          /* no ack: the next one follows */
    if (call StatusSend.send(BASESTATION, &statusMsg, sizeof(ninedof_mote_status_msg_t))
        == SUCCESS)
      statusBusy = TRUE;
  }

  event void StatusSend.sendDone(message_t *m, error_t err) {
    statusBusy = FALSE;
  }

  /* The second's temperature readings: one message, and their mean for the
   * correction of the next second.  A message still on its way: this
   * second's readings are dropped (the next message carries the next). */
  event void TempTimer.fired() {
    ninedof_mote_temp_msg_t msg, *p;
    int16_t mean;
    uint8_t have;
    atomic {
      have = ninedof_temp_pack(&temps, &msg, &mean);
      if (have) {
        tempMeanKnown = TRUE;                 /* from now on the second's mean */
        tempFresh = FALSE;
      }
    }
    if (have)
      call Calibration.setTemperature(mean);
    if (tempBusy)
      return;
    p = (ninedof_mote_temp_msg_t *)call TempSend.getPayload(
      &tempMsg, sizeof(ninedof_mote_temp_msg_t));
    if (p == NULL)
      return;
    memcpy(p, &msg, sizeof(msg));
    call PacketLink.setRetries(&tempMsg, 0);            /* no ack: the next one follows */
    if (call TempSend.send(BASESTATION, &tempMsg, sizeof(ninedof_mote_temp_msg_t)) == SUCCESS)
      tempBusy = TRUE;
  }

  event void TempSend.sendDone(message_t *m, error_t err) {
    tempBusy = FALSE;
  }
}
