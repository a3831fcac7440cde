/*
 * SampleBoardAppC -- the 9DOF board's synchronized nine-axis read and its
 * fault handling, without the radio: see SampleBoardP.
 *
 * @author motecal
 */
#include "NineDofBoard.h"

configuration SampleBoardAppC
{
}
implementation
{
  components MainC, LedsC, SampleBoardP as App, NineDofBoardC as Board;
  components new TimerMilliC() as Period, SerialPrintfC;

  App.Boot -> MainC;
  App.Leds -> LedsC;
  App.BoardControl -> Board;
  App.Board -> Board;
  App.Health -> Board;
  App.Period -> Period;
  App.Serial -> SerialPrintfC;
}
