/*
 * NineDofAppC -- the sensor mote: 9DOF board sampled at 125 Hz of the crystal,
 * batched, corrected with the uploaded calibration, sent to the BaseStation.
 * See NineDofAppP for the behaviour and the LEDs.
 *
 * @author motecal
 */
#include "NineDofApp.h"
#include "NineDofBoard.h"

configuration NineDofAppC
{
}
implementation
{
  components MainC, LedsC, NineDofAppP as App;
  components NineDofBoardC as Board;
  components new Alarm32khz32C() as Alarm, LocalTimeMilliC as Crystal, PlatformC;
  components ActiveMessageC as Radio;
  components new AMSenderC(AM_NINEDOF_SAMPLES_MSG) as SampleSend;
  components new AMSenderC(AM_NINEDOF_MOTE_STATUS_MSG) as StatusSend;
  components new AMSenderC(AM_NINEDOF_MOTE_TEMP_MSG) as TempSend;
  components NineDofCalibrationC as Calibration;
  components new PoolC(message_t, NINEDOF_SEND_QUEUE) as SamplePool;
  components new QueueC(message_t*, NINEDOF_SEND_QUEUE) as SendQueue;
  components new TimerMilliC() as StatusTimer;
  components new TimerMilliC() as TempTimer;
  components new TimerMilliC() as RetryTimer;
  components new TimerMilliC() as FlashTimer;

  App.Boot -> MainC;
  App.Leds -> LedsC;
  App.BoardControl -> Board;
  App.Board -> Board;
  App.Health -> Board;
  App.Alarm -> Alarm;
  App.Crystal -> Crystal;
  App.Atm128Calibrate -> PlatformC;
  App.RadioControl -> Radio;
  App.SampleSend -> SampleSend;
  App.StatusSend -> StatusSend;
  App.TempSend -> TempSend;
  App.Calibration -> Calibration;
  App.Acks -> SampleSend;
  App.PacketLink -> Radio;
  App.SamplePool -> SamplePool;
  App.SendQueue -> SendQueue;
  App.StatusTimer -> StatusTimer;
  App.TempTimer -> TempTimer;
  App.RetryTimer -> RetryTimer;
  App.FlashTimer -> FlashTimer;
}
