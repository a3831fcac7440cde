/*
 * SampleBoardP -- start the board (retried with the watchdog ticking until
 * it answers), then every 8 binary ms: the watchdog's tick and a read of
 * the nine axes (skipped, as `late`, while the previous read runs).  Once
 * a second (128 periods): reads done / failed / late, the board's fault
 * counters (NineDofHealth) and the last record, as one line of text.
 *
 * @author motecal
 */
#include <stdio.h>
#include "NineDofBoard.h"

module SampleBoardP
{
  uses {
    interface Boot;
    interface Leds;
    interface SplitControl as BoardControl;
    interface ReadNow<ninedof_raw_t> as Board;
    interface NineDofHealth as Health;
    interface Timer<TMilli> as Period;
    interface StdControl as Serial;
  }
}
implementation
{
  enum { PERIOD = 8, PER_LINE = 128 };

  bool on = FALSE;
  uint8_t count;
  uint16_t seconds;
  uint16_t ok, failed, late;            /* tasks and the read's done event */
  bool reading = FALSE;
  ninedof_raw_t last;

  event void Boot.booted() {
    call Serial.start();
    call BoardControl.start();
    call Period.startPeriodic(PERIOD);
  }

  event void BoardControl.startDone(error_t err) {
    on = err == SUCCESS;
    printf("board start %d\r\n", err);
  }

  event void BoardControl.stopDone(error_t err) { }

  void line() {
    ninedof_fault_counters_t f = call Health.counters();
    ninedof_raw_t r;
    uint16_t o, x, l;
    atomic {
      r = last;
      o = ok;
      x = failed;
      l = late;
    }
    printf("board %u ok %u fail %u late %u nack %u reset %u reinit %u last %d %d %d %d %d %d %d %d %d\r\n",
           seconds, o, x, l, f.nacks, f.bus_resets, f.chip_reinits,
           r.axis[0], r.axis[1], r.axis[2], r.axis[3], r.axis[4], r.axis[5],
           r.axis[6], r.axis[7], r.axis[8]);
  }

  event void Period.fired() {
    bool busy;
    call Health.tick();
    if (++count == PER_LINE) {
      count = 0;
      seconds++;
      line();
    }
    if (!on) {
      if (count % 125 == 0)
        call BoardControl.start();        /* SUCCESS while one is under way */
      return;
    }
    atomic {
      busy = reading;
      if (busy)
        late++;
      else
        reading = TRUE;
    }
    if (!busy && call Board.read() != SUCCESS) {
      atomic {
        reading = FALSE;
        failed++;
      }
    }
  }

  async event void Board.readDone(error_t err, ninedof_raw_t v) {
    atomic {
      reading = FALSE;
      if (err == SUCCESS) {
        ok++;
        last = v;
      } else {
        failed++;
      }
    }
  }
}
