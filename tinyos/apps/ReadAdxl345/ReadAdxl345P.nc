/*
 * ReadAdxl345P -- start the accelerometer (SplitControl, TEP 115; retried
 * every second until it answers), then read it (Read<>, TEP 114) every
 * 1024 binary ms and print "adxl345 <n> <err> <x> <y> <z>" (counts,
 * 256 LSB/g).  Green LED: a read succeeded; red: it failed.
 *
 * @author motecal
 */
#include <stdio.h>
#include "NineDofChip.h"

module ReadAdxl345P
{
  uses {
    interface Boot;
    interface Leds;
    interface SplitControl as AccelControl;
    interface Read<ninedof_xyz_t> as Accel;
    interface ReadStream<ninedof_xyz_t> as Stream;
    interface Timer<TMilli>;
    interface StdControl as Serial;
  }
}
implementation
{
  uint16_t n;
  bool on = FALSE, streaming = FALSE;
  ninedof_xyz_t buf[2][4];

  event void Boot.booted() {
    call Serial.start();
    call AccelControl.start();
    call Timer.startPeriodic(1024);
  }

  event void AccelControl.startDone(error_t err) {
    on = err == SUCCESS;
    printf("adxl345 start %d\r\n", err);
    if (on && call Stream.postBuffer(buf[0], 4) == SUCCESS &&
        call Stream.postBuffer(buf[1], 4) == SUCCESS &&
        call Stream.read(10000) == SUCCESS)
      streaming = TRUE;
  }

  event void Stream.bufferDone(error_t err, ninedof_xyz_t *b, uint16_t count) {
    uint16_t i;
    for (i = 0; i < count; i++)
      printf("adxl345 stream %d %d %d %d\r\n", err, b[i].xyz[0], b[i].xyz[1], b[i].xyz[2]);
  }

  event void Stream.readDone(error_t err, uint32_t usPeriod) {
    streaming = FALSE;
    printf("adxl345 stream done %d %lu\r\n", err, usPeriod);
  }

  event void AccelControl.stopDone(error_t err) { }

  event void Timer.fired() {
    if (!on) {
      call AccelControl.start();          /* not answering yet: again */
      return;
    }
    if (streaming)
      return;
    if (call Accel.read() != SUCCESS)
      call Leds.led0Toggle();
  }

  event void Accel.readDone(error_t err, ninedof_xyz_t v) {
    if (err == SUCCESS)
      call Leds.led1Toggle();
    else
      call Leds.led0Toggle();
    printf("adxl345 %u %d %d %d %d\r\n", n++, err, v.xyz[0], v.xyz[1], v.xyz[2]);
  }
}
