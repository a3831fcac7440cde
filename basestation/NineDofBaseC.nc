/*
 * NineDofBaseC -- the BaseStation mote: radio <-> serial bridge with drop
 * counters.  See NineDofBaseP for the behaviour and the LEDs.
 *
 * @author motecal
 */
#include "NineDofBase.h"

configuration NineDofBaseC
{
}
implementation
{
  components MainC, LedsC, PlatformC, NineDofBaseP as App;
  components SerialActiveMessageC as Serial, ActiveMessageC as Radio;
  components new TimerMilliC() as StatusTimer;

  App.Boot -> MainC;
  App.Leds -> LedsC;
  App.Atm128Calibrate -> PlatformC;
  App.StatusTimer -> StatusTimer;

  App.SerialControl -> Serial;
  App.UartSend -> Serial;
  App.UartReceive -> Serial.Receive;
  App.UartPacket -> Serial;
  App.UartAMPacket -> Serial;

  App.RadioControl -> Radio;
  App.RadioSend -> Radio;
  App.RadioReceive -> Radio.Receive;
  App.RadioSnoop -> Radio.Snoop;
  App.RadioPacket -> Radio;
  App.RadioAMPacket -> Radio;
  App.RadioAcks -> Radio;
  App.RadioLink -> Radio;
}
