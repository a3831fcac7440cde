/*
 * NineDofReadStreamP -- TinyOS's ReadStream<> (TEP 114) on a chip driver's
 * async ReadNow<>: buffers are filled in the order posted, one value per
 * period, each handed back by bufferDone; when no buffer is left, readDone
 * gives the period actually used.
 *
 * The period is a Timer<TMilli> period: usPeriod rounded to binary
 * milliseconds (1/1024 s, at least 1), so readDone reports
 * round(usPeriod * 1024 / 10^6) * 10^6 / 1024 us.  At most NBUF buffers
 * wait at a time (postBuffer returns ESIZE beyond).  A read that fails
 * ends the stream: the buffer being filled comes back with FAIL (its
 * count is what it asked for; the values after the failure are not set),
 * the others too, then readDone(FAIL).  A period whose read is still under
 * way is skipped.  For the HMC5883L ask for 6 ms or more (each read
 * triggers the next single measurement).
 *
 * @author motecal
 */
#include "NineDofChip.h"

generic module NineDofReadStreamP() @safe()
{
  provides interface ReadStream<ninedof_xyz_t>;
  uses interface ReadNow<ninedof_xyz_t>;
  uses interface Timer<TMilli>;
}
implementation
{
  enum { NBUF = 2 };

  ninedof_xyz_t *bufs[NBUF];
  uint16_t counts[NBUF];
  uint8_t head, queued;           /* buffers posted, bufs[head] is being filled */
  uint16_t pos;                   /* values in bufs[head] */
  uint32_t periodUs;
  bool running = FALSE, reading = FALSE;
  error_t failure = SUCCESS;
  norace ninedof_xyz_t value;     /* the read's value: set in readDone, read in the task */
  norace error_t readResult;

  command error_t ReadStream.postBuffer(ninedof_xyz_t *buf, uint16_t count) {
    if (count == 0 || buf == NULL)
      return EINVAL;
    if (queued == NBUF)
      return ESIZE;
    bufs[(head + queued) % NBUF] = buf;
    counts[(head + queued) % NBUF] = count;
    queued++;
    return SUCCESS;
  }

  command error_t ReadStream.read(uint32_t usPeriod) {
    uint32_t ms;
    if (running)
      return EBUSY;
    if (queued == 0)
      return FAIL;
    ms = (usPeriod * 128UL + 62500UL) / 125000UL;   /* * 1024 / 10^6, rounded */
    if (ms == 0)
      ms = 1;
    periodUs = ms * 1000000UL / 1024UL;
    running = TRUE;
    failure = SUCCESS;
    pos = 0;
    call Timer.startPeriodic(ms);
    return SUCCESS;
  }

  task void finish() {
    while (queued) {                /* what is left comes back unfilled */
      ninedof_xyz_t *b = bufs[head];
      uint16_t n = counts[head];
      head = (head + 1) % NBUF;
      queued--;
      signal ReadStream.bufferDone(failure == SUCCESS ? SUCCESS : FAIL, b, n);
    }
    running = FALSE;
    signal ReadStream.readDone(failure, periodUs);
  }

  void stop(error_t err) {
    call Timer.stop();
    failure = err;
    post finish();
  }

  task void readDoneTask() {
    atomic reading = FALSE;
    if (!running || failure != SUCCESS)
      return;
    if (readResult != SUCCESS) {
      stop(FAIL);
      return;
    }
    bufs[head][pos++] = value;
    if (pos == counts[head]) {
      ninedof_xyz_t *b = bufs[head];
      uint16_t n = counts[head];
      head = (head + 1) % NBUF;
      queued--;
      pos = 0;
      signal ReadStream.bufferDone(SUCCESS, b, n);
      if (queued == 0)
        stop(SUCCESS);
    }
  }

  event void Timer.fired() {
    bool busy;
    atomic {
      busy = reading;
      reading = TRUE;
    }
    if (busy)
      return;                       /* the previous read is still under way */
    if (call ReadNow.read() != SUCCESS) {
      atomic reading = FALSE;
      stop(FAIL);
    }
  }

  async event void ReadNow.readDone(error_t err, ninedof_xyz_t v) {
    atomic {
      if (!reading)
        return;                     /* another user's read (Read<> on the same driver) */
    }
    readResult = err;
    value = v;
    post readDoneTask();
  }

  default event void ReadStream.bufferDone(error_t err, ninedof_xyz_t *buf, uint16_t count) { }
  default event void ReadStream.readDone(error_t err, uint32_t usActualPeriod) { }
}
