/*
 * ReadAdxl345AppC -- the smallest use of one chip driver: an ADXL345
 * (Adxl345C) read with TinyOS's ReadStream<> once after start (two buffers
 * of 4 values, 10 ms apart) and then with Read<> once a second, printed as
 * text on the serial line.
 *
 * @author motecal
 */
configuration ReadAdxl345AppC
{
}
implementation
{
  components MainC, LedsC, ReadAdxl345P as App;
  components new Adxl345C() as Accel;
  components new TimerMilliC() as Timer;
  components SerialPrintfC;

  App.Boot -> MainC;
  App.Leds -> LedsC;
  App.AccelControl -> Accel;
  App.Accel -> Accel;
  App.Stream -> Accel;
  App.Timer -> Timer;
  App.Serial -> SerialPrintfC;
}
