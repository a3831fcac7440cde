/*
 * NineDofCalibrationC -- the mote's side of the calibration upload, on its
 * own: receives fragments, commits and queries (ninedof_calrx_handle,
 * ninedof_calrx.c), answers each from a reply buffer of its own, keeps the
 * set in force (NineDofCalibration) and writes each accepted set to the
 * internal EEPROM in the background; at boot it restores the newest valid
 * EEPROM image.  See NineDofCalibrationP.
 *
 * @author motecal
 */
#include "NineDofMsg.h"

configuration NineDofCalibrationC
{
  provides interface NineDofCalibration;
}
implementation
{
  components MainC, LedsC, NineDofCalibrationP as Cal, ActiveMessageC as Radio;
  components new AMSenderC(AM_NINEDOF_CAL_FRAG_ACK_MSG) as FragAckSend;
  components new AMSenderC(AM_NINEDOF_CAL_COMMIT_ACK_MSG) as CommitAckSend;
  components new AMSenderC(AM_NINEDOF_CAL_REPORT_MSG) as ReportSend;
  components new AMReceiverC(AM_NINEDOF_CAL_FRAG_MSG) as FragReceive;
  components new AMReceiverC(AM_NINEDOF_CAL_COMMIT_MSG) as CommitReceive;
  components new AMReceiverC(AM_NINEDOF_CAL_QUERY_MSG) as QueryReceive;
  components new TimerMilliC() as EepromTimer;

  NineDofCalibration = Cal;
  MainC.SoftwareInit -> Cal;
  Cal.Leds -> LedsC;
  Cal.FragAckSend -> FragAckSend;
  Cal.CommitAckSend -> CommitAckSend;
  Cal.ReportSend -> ReportSend;
  Cal.FragReceive -> FragReceive;
  Cal.CommitReceive -> CommitReceive;
  Cal.QueryReceive -> QueryReceive;
  Cal.AMPacket -> Radio;
  Cal.PacketLink -> Radio;
  Cal.EepromTimer -> EepromTimer;
}
