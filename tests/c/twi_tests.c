/*
 * twi_tests.c -- the lean TWI master's state machine (tinyos/ninedof_twi.c)
 * driven by a model of the ATmega1281 TWI in master mode and one register
 * slave, built twice by tests/test_twi.py: gcc on the host, avr-gcc in
 * simavr.  Each scenario compares the bus events with the expected ones:
 *
 *   S / Sr   START / repeated START       P    STOP
 *   Axx      address byte xx, then a (ACK) or n (NACK)
 *   Wxx      data byte written, then a / n (the slave's answer)
 *   Rxx      data byte read, then a / n (the master's answer)
 *   L        arbitration lost              E    bus error
 *   r        the TWI recovered from a bus error (TWSTO, nothing on the bus)
 *
 * Prints "T<scenario>:<outcome>:<events>;" for each scenario, then
 * "CHECKS <n> FAILED <m>;END" (check_summary).
 */
#include <stdint.h>
#include <string.h>

#include "ninedof_twi.h"
#include "test_out.h"
#include "test_check.h"


/* ---------------------------------------------------------------------- */
/* The TWI and one slave, at the level of TWCR commands and TWSR codes      */
/* ---------------------------------------------------------------------- */
enum { PH_NONE, PH_ADDR, PH_MT, PH_MR, PH_MR_DONE };

typedef struct {
  uint8_t owned;          /* the master holds the bus (START .. STOP) */
  uint8_t twint;          /* hardware TWINT: SCL held low */
  uint8_t status, twdr, phase;
  uint8_t bytes;          /* bytes on the bus since the START */
  uint8_t written;        /* data bytes written since the address */
  /* the slave */
  uint8_t addr7, ptr, regs[16];
  /* faults */
  uint8_t nack_addr;      /* 1: the slave does not answer its address */
  int8_t nack_written;    /* the slave NACKs this data byte (0-based), -1 none */
  int8_t lose_at;         /* arbitration lost at this bus byte, -1 none */
  int8_t error_at;        /* bus error at this bus byte, -1 none */
  uint8_t ops;            /* commands written */
  char ev[160];
  uint8_t n;
} bus_t;

static bus_t bus;

static void ev_s(const char *s)
{
  if (bus.n && bus.n < sizeof bus.ev - 1)
    bus.ev[bus.n++] = ' ';
  while (*s && bus.n < sizeof bus.ev - 1)
    bus.ev[bus.n++] = *s++;
  bus.ev[bus.n] = 0;
}

static void ev_byte(char kind, uint8_t v, uint8_t ack)
{
  static const char hex[] = "0123456789abcdef";
  char s[5];
  s[0] = kind; s[1] = hex[v >> 4]; s[2] = hex[v & 15]; s[3] = ack ? 'a' : 'n'; s[4] = 0;
  ev_s(s);
}

static void bus_reset(uint8_t addr7)
{
  uint8_t i;
  memset(&bus, 0, sizeof bus);
  bus.addr7 = addr7;
  bus.nack_written = bus.lose_at = bus.error_at = -1;
  for (i = 0; i < sizeof bus.regs; i++)
    bus.regs[i] = (uint8_t)(0xA0 + 7 * i);
}

/* Interrupt condition on this bus byte?  Returns 1 if it took it. */
static uint8_t bus_fault(void)
{
  if (bus.lose_at == (int8_t)bus.bytes) {
    ev_s("L");
    bus.status = NINEDOF_TW_ARB_LOST;
    bus.owned = 0;
    bus.phase = PH_NONE;
    return 1;
  }
  if (bus.error_at == (int8_t)bus.bytes) {
    ev_s("E");
    bus.status = NINEDOF_TW_BUS_ERROR;
    bus.owned = 0;
    bus.phase = PH_NONE;
    return 1;
  }
  return 0;
}

/* TWDR = twdr; TWCR = cmd.  Returns 1 if an interrupt follows. */
static uint8_t bus_cmd(uint8_t cmd, uint8_t twdr)
{
  uint8_t ack;
  bus.ops++;
  CHECK(cmd & NINEDOF_TWEN);
  if (!(cmd & NINEDOF_TWINT))
    return 0;                       /* TWINT not cleared: nothing moves */
  CHECK(!(cmd & NINEDOF_TWSTA) || !(cmd & NINEDOF_TWSTO));
  bus.twint = 0;
  if (cmd & NINEDOF_TWSTO) {
    if (bus.status == NINEDOF_TW_BUS_ERROR && !bus.owned) {
      ev_s("r");
    } else {
      CHECK(bus.owned);             /* a STOP only from the bus's master */
      ev_s("P");
    }
    bus.owned = 0;
    bus.phase = PH_NONE;
    bus.status = 0xF8;              /* no relevant state */
    return 0;                       /* no TWINT after a STOP */
  }
  if (cmd & NINEDOF_TWSTA) {
    ev_s(bus.owned ? "Sr" : "S");
    bus.status = bus.owned ? NINEDOF_TW_REP_START : NINEDOF_TW_START;
    bus.owned = 1;
    bus.phase = PH_ADDR;
    bus.bytes = 0;
  } else {
    switch (bus.phase) {
    case PH_ADDR:
      if (bus_fault())
        break;
      ack = (uint8_t)(twdr >> 1) == bus.addr7 && !bus.nack_addr;
      ev_byte('A', twdr, ack);
      bus.bytes++;
      bus.written = 0;
      if (twdr & 1) {
        bus.status = ack ? NINEDOF_TW_MR_SLA_ACK : NINEDOF_TW_MR_SLA_NACK;
        bus.phase = ack ? PH_MR : PH_NONE;
      } else {
        bus.status = ack ? NINEDOF_TW_MT_SLA_ACK : NINEDOF_TW_MT_SLA_NACK;
        bus.phase = ack ? PH_MT : PH_NONE;
      }
      break;
    case PH_MT:
      if (bus_fault())
        break;
      ack = bus.nack_written != (int8_t)bus.written;
      ev_byte('W', twdr, ack);
      if (bus.written == 0)
        bus.ptr = twdr & 15;
      else
        bus.regs[bus.ptr++ & 15] = twdr;
      bus.written++;
      bus.bytes++;
      bus.status = ack ? NINEDOF_TW_MT_DATA_ACK : NINEDOF_TW_MT_DATA_NACK;
      if (!ack)
        bus.phase = PH_NONE;
      break;
    case PH_MR:
      if (bus_fault())
        break;
      ack = (cmd & NINEDOF_TWEA) != 0;
      bus.twdr = bus.regs[bus.ptr++ & 15];
      ev_byte('R', bus.twdr, ack);
      bus.bytes++;
      bus.status = ack ? NINEDOF_TW_MR_DATA_ACK : NINEDOF_TW_MR_DATA_NACK;
      if (!ack)
        bus.phase = PH_MR_DONE;     /* the slave has let go of SDA */
      break;
    default:
      if (bus.status == NINEDOF_TW_ARB_LOST && !bus.owned) {
        ev_s("-");                  /* TWINT cleared: the TWI leaves the bus */
        bus.status = 0xF8;
        return 0;
      }
      ev_s("?");                    /* a command the bus state does not allow */
      CHECK(0);
      return 0;
    }
  }
  bus.twint = 1;
  return (cmd & NINEDOF_TWIE) != 0;
}

/* One operation, run as NineDofTwiMasterP runs it: begin, then per
 * interrupt ninedof_twi_interrupt (on stand-ins for TWSR, TWDR, TWCR),
 * until the outcome.  Returns the outcome (0xEE: hung). */
static ninedof_twi_t twi;
static uint16_t rx_fast;            /* interrupts that took the byte-read fast path */
static uint16_t starts_inline;      /* STARTs served by ninedof_twi_started */

static uint8_t interrupt(void)
{
  if (twi.state == NINEDOF_TWI_START) {
    /* the master waits for its START where it asked for it (NineDofTwiMasterImplP) */
    uint8_t cmd = ninedof_twi_started(&twi, bus.status);
    starts_inline++;
    return cmd;
  }
  volatile uint8_t twsr = bus.status, twdr = bus.twdr, twcr = 0;
  uint8_t fast = ninedof_twi_rx_more(&twi, bus.status) != 0;
  (void)ninedof_twi_interrupt(&twi, &twsr, &twdr, &twcr);
  rx_fast += fast;
  return twcr;
}

static uint8_t op(uint8_t read, uint8_t flags, uint8_t addr, uint8_t len, uint8_t *buf)
{
  uint8_t cmd, irq, guard = 0;
  CHECK(twi.state == NINEDOF_TWI_IDLE);
  cmd = ninedof_twi_begin(&twi, read, flags, addr, len, buf);
  for (;;) {
    irq = bus_cmd(cmd, twi.out);
    if (twi.state == NINEDOF_TWI_DONE) {
      CHECK(!irq);                  /* the last command asks for no interrupt */
      break;
    }
    if (!irq || ++guard > 100) {    /* waiting for an interrupt that never comes */
      CHECK(0);
      return 0xEE;
    }
    cmd = interrupt();
  }
  twi.state = NINEDOF_TWI_IDLE;     /* the module does this before it signals */
  return twi.result;
}

static void release(void)
{
  uint8_t cmd = ninedof_twi_release(&twi);
  if (cmd)
    bus_cmd(cmd, 0);
}

static void report(const char *name, uint8_t result)
{
  out_c('T');
  out_s(name);
  out_c(':');
  out_u16(result);
  out_c(':');
  out_s(bus.ev);
  out_c(';');
}

static uint8_t events_are(const char *want)
{
  return strcmp(bus.ev, want) == 0;
}

/* ---------------------------------------------------------------------- */
static void test_chip_read(void)
{
  /* the chip logic's read: pointer write (START, no STOP), then a read of
   * six bytes after a repeated START, with STOP */
  uint8_t ptr = 0x02, data[6];
  bus_reset(0x53);
  ninedof_twi_init(&twi);
  CHECK(op(0, NINEDOF_I2C_START, 0x53, 1, &ptr) == NINEDOF_TWI_OK);
  CHECK(bus.owned && bus.twint && twi.open);        /* SCL held for the repeated START */
  CHECK(op(1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x53, 6, data) == NINEDOF_TWI_OK);
  report("chipread", twi.result);
  CHECK(events_are("S Aa6a W02a Sr Aa7a Raea Rb5a Rbca Rc3a Rcaa Rd1n P"));
  CHECK(memcmp(data, bus.regs + 2, 6) == 0);
  CHECK(!bus.owned && !twi.open);
  release();                                         /* nothing left to stop */
  CHECK(events_are("S Aa6a W02a Sr Aa7a Raea Rb5a Rbca Rc3a Rcaa Rd1n P"));
}

static void test_write_stop(void)
{
  /* register write, START + STOP; then the magnetometer's trigger-and-read
   * (two bytes written, repeated START, read) */
  uint8_t w[2] = { 0x03, 0x5A }, trig[2] = { 0x02, 0x01 }, d[6];
  bus_reset(0x1E);
  ninedof_twi_init(&twi);
  CHECK(op(0, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x1E, 2, w) == NINEDOF_TWI_OK);
  CHECK(bus.regs[3] == 0x5A && !bus.owned);
  CHECK(op(0, NINEDOF_I2C_START, 0x1E, 2, trig) == NINEDOF_TWI_OK);
  CHECK(op(1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x1E, 6, d) == NINEDOF_TWI_OK);
  report("write", twi.result);
  CHECK(events_are("S A3ca W03a W5aa P S A3ca W02a W01a Sr A3da R5aa Rbca Rc3a Rcaa Rd1a Rd8n P"));
  CHECK(bus.regs[2] == 0x01 && d[0] == 0x5A && d[5] == bus.regs[8]);
}

static void test_ack_end_and_continue(void)
{
  /* read 3 with ACK_END and no STOP, then 2 more without START, with STOP;
   * a read of one byte NACKs it */
  uint8_t p = 0x00, d[5], one;
  bus_reset(0x68);
  ninedof_twi_init(&twi);
  CHECK(op(0, NINEDOF_I2C_START, 0x68, 1, &p) == NINEDOF_TWI_OK);
  CHECK(op(1, NINEDOF_I2C_START | NINEDOF_I2C_ACK_END, 0x68, 3, d) == NINEDOF_TWI_OK);
  CHECK(bus.owned && twi.open == 2);
  CHECK(op(1, NINEDOF_I2C_STOP, 0x68, 2, d + 3) == NINEDOF_TWI_OK);
  CHECK(memcmp(d, bus.regs, 5) == 0);
  CHECK(op(1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x68, 1, &one) == NINEDOF_TWI_OK);
  report("ackend", twi.result);
  CHECK(events_are("S Ad0a W00a Sr Ad1a Ra0a Ra7a Raea Rb5a Rbcn P S Ad1a Rc3n P"));
  CHECK(one == bus.regs[5]);
}

static void test_write_continue(void)
{
  /* write 1 (START, no STOP), write 2 more (no START, STOP); an empty
   * operation without START but with STOP ends an open transfer */
  uint8_t a = 0x04, b[2] = { 0x11, 0x22 }, c = 0x09;
  bus_reset(0x53);
  ninedof_twi_init(&twi);
  CHECK(op(0, NINEDOF_I2C_START, 0x53, 1, &a) == NINEDOF_TWI_OK);
  CHECK(op(0, NINEDOF_I2C_STOP, 0x53, 2, b) == NINEDOF_TWI_OK);
  CHECK(bus.regs[4] == 0x11 && bus.regs[5] == 0x22 && !bus.owned);
  CHECK(op(0, NINEDOF_I2C_START, 0x53, 1, &c) == NINEDOF_TWI_OK);
  CHECK(op(0, NINEDOF_I2C_STOP, 0x53, 0, 0) == NINEDOF_TWI_OK);
  report("wcont", twi.result);
  CHECK(events_are("S Aa6a W04a W11a W22a P S Aa6a W09a P"));
  /* an address-only probe: START, address, STOP */
  CHECK(op(0, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x53, 0, 0) == NINEDOF_TWI_OK);
  CHECK(events_are("S Aa6a W04a W11a W22a P S Aa6a W09a P S Aa6a P"));
}

static void test_bad_args(void)
{
  /* no START and nothing open; a read continuing a write: refused, and
   * nothing happens on the bus */
  uint8_t a = 1, d[2];
  bus_reset(0x53);
  ninedof_twi_init(&twi);
  CHECK(op(0, 0, 0x53, 1, &a) == NINEDOF_TWI_BAD_ARGS);
  CHECK(op(1, NINEDOF_I2C_STOP, 0x53, 2, d) == NINEDOF_TWI_BAD_ARGS);
  CHECK(bus.n == 0);
  CHECK(op(0, NINEDOF_I2C_START, 0x53, 1, &a) == NINEDOF_TWI_OK);
  CHECK(op(1, NINEDOF_I2C_STOP, 0x53, 2, d) == NINEDOF_TWI_BAD_ARGS);
  CHECK(bus.owned && bus.twint);                     /* still held: release ends it */
  release();
  report("badargs", twi.result);
  CHECK(events_are("S Aa6a W01a P") && !bus.owned && !twi.open);
  release();                                         /* once */
  CHECK(events_are("S Aa6a W01a P"));
  /* an interrupt nobody asked for changes nothing */
  CHECK(ninedof_twi_step(&twi, NINEDOF_TW_MT_DATA_ACK, 0) == NINEDOF_TWCR_IDLE);
  CHECK(twi.state == NINEDOF_TWI_IDLE);
}

static void test_addr_nack(void)
{
  /* address NACK on a write and on a read after a repeated START: STOP at
   * once, ADDR_NACK; the next operation starts afresh */
  uint8_t p = 0x32, d[6];
  bus_reset(0x53);
  ninedof_twi_init(&twi);
  bus.nack_addr = 1;
  CHECK(op(0, NINEDOF_I2C_START, 0x53, 1, &p) == NINEDOF_TWI_ADDR_NACK);
  CHECK(!bus.owned && !twi.open);
  bus.nack_addr = 0;
  CHECK(op(0, NINEDOF_I2C_START, 0x53, 1, &p) == NINEDOF_TWI_OK);
  bus.nack_addr = 1;
  CHECK(op(1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x53, 6, d) == NINEDOF_TWI_ADDR_NACK);
  CHECK(!bus.owned && !twi.open);
  release();
  report("addrnack", twi.result);
  CHECK(events_are("S Aa6n P S Aa6a W32a Sr Aa7n P"));
  /* a chip that is not there at all */
  bus.nack_addr = 0;
  CHECK(op(0, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x1E, 1, &p) == NINEDOF_TWI_ADDR_NACK);
  CHECK(events_are("S Aa6n P S Aa6a W32a Sr Aa7n P S A3cn P"));
}

static void test_data_nack(void)
{
  /* the slave NACKs the second data byte: STOP, DATA_NACK, the third byte
   * is not sent */
  uint8_t w[3] = { 0x05, 0x66, 0x77 };
  bus_reset(0x68);
  ninedof_twi_init(&twi);
  bus.nack_written = 1;
  CHECK(op(0, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x68, 3, w) == NINEDOF_TWI_DATA_NACK);
  report("datanack", twi.result);
  CHECK(events_are("S Ad0a W05a W66n P") && !bus.owned && !twi.open);
  bus.nack_written = -1;
  CHECK(op(0, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x68, 3, w) == NINEDOF_TWI_OK);
  CHECK(events_are("S Ad0a W05a W66n P S Ad0a W05a W66a W77a P"));
}

static void test_arbitration(void)
{
  /* arbitration lost at the address byte, and while reading: ARB_LOST, the
   * bus is left to the other master without STOP; the next START is a
   * fresh one */
  uint8_t p = 0x00, d[4];
  bus_reset(0x68);
  ninedof_twi_init(&twi);
  bus.lose_at = 0;
  CHECK(op(0, NINEDOF_I2C_START, 0x68, 1, &p) == NINEDOF_TWI_ARB_LOST);
  CHECK(!bus.owned && !twi.open);
  bus.lose_at = 2;                                   /* address, first data byte, lost */
  CHECK(op(1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x68, 4, d) == NINEDOF_TWI_ARB_LOST);
  release();
  report("arb", twi.result);
  CHECK(events_are("S L - S Ad1a Ra0a L -"));
  bus.lose_at = -1;
  CHECK(op(1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x68, 1, d) == NINEDOF_TWI_OK);
  CHECK(events_are("S L - S Ad1a Ra0a L - S Ad1a Ra7n P"));
}

static void test_bus_error(void)
{
  /* a bus error while writing: BUS_ERROR, the TWI recovers (TWSTO) */
  uint8_t w[2] = { 0x01, 0x02 };
  bus_reset(0x53);
  ninedof_twi_init(&twi);
  bus.error_at = 1;
  CHECK(op(0, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x53, 2, w) == NINEDOF_TWI_BUS_ERROR);
  report("buserr", twi.result);
  CHECK(events_are("S Aa6a E r") && !twi.open);
  /* a status that does not belong to the step (a START answered with a
   * master-receiver code) is a bus error too */
  ninedof_twi_init(&twi);
  (void)ninedof_twi_begin(&twi, 0, NINEDOF_I2C_START, 0x53, 1, w);
  CHECK(ninedof_twi_step(&twi, NINEDOF_TW_MR_DATA_ACK, 0) == NINEDOF_TWCR_STOP);
  CHECK(twi.state == NINEDOF_TWI_DONE && twi.result == NINEDOF_TWI_BUS_ERROR);
}

static void test_commands(void)
{
  /* the commands themselves: interrupts only while an operation runs, ACK
   * for every byte read but the last, TWDR = address byte after a START */
  uint8_t d[3];
  ninedof_twi_init(&twi);
  CHECK(ninedof_twi_begin(&twi, 1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x1E, 3, d) ==
        (NINEDOF_TWINT | NINEDOF_TWSTA | NINEDOF_TWEN | NINEDOF_TWIE));
  CHECK(ninedof_twi_step(&twi, NINEDOF_TW_START, 0) == (NINEDOF_TWINT | NINEDOF_TWEN | NINEDOF_TWIE));
  CHECK(twi.out == 0x3D);
  CHECK(ninedof_twi_step(&twi, NINEDOF_TW_MR_SLA_ACK, 0) == NINEDOF_TWCR_NEXT_ACK);
  CHECK(ninedof_twi_step(&twi, NINEDOF_TW_MR_DATA_ACK, 1) == NINEDOF_TWCR_NEXT_ACK);
  CHECK(ninedof_twi_step(&twi, NINEDOF_TW_MR_DATA_ACK, 2) == NINEDOF_TWCR_NEXT);
  CHECK(ninedof_twi_step(&twi, NINEDOF_TW_MR_DATA_NACK, 3) ==
        (NINEDOF_TWINT | NINEDOF_TWSTO | NINEDOF_TWEN));
  CHECK(d[0] == 1 && d[1] == 2 && d[2] == 3 && twi.state == NINEDOF_TWI_DONE);
}

static void test_abort_and_stop_wait(void)
{
  /* the watchdog aborts an operation whose interrupt never comes (a slave
   * holds SCL low after the address byte): DONE / ABORTED, nothing left
   * open, and the next operation runs as usual */
  uint8_t d[6], ptr = 0x02;
  volatile uint8_t twcr;
  bus_reset(0x53);
  ninedof_twi_init(&twi);
  (void)ninedof_twi_begin(&twi, 0, NINEDOF_I2C_START, 0x53, 1, &ptr);
  (void)ninedof_twi_step(&twi, NINEDOF_TW_START, 0);     /* address sent, then nothing */
  CHECK(twi.state == NINEDOF_TWI_ADDR);
  CHECK(ninedof_twi_abort(&twi) == 1);
  CHECK(twi.state == NINEDOF_TWI_DONE && twi.result == NINEDOF_TWI_ABORTED && !twi.open);
  twi.state = NINEDOF_TWI_IDLE;                           /* signalled */
  CHECK(ninedof_twi_abort(&twi) == 0);                    /* nothing under way */
  CHECK(ninedof_twi_release(&twi) == 0);                  /* no STOP owed */
  CHECK(op(1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x53, 6, d) == NINEDOF_TWI_OK);
  /* a transfer left open (no STOP) and then aborted owes no STOP either:
   * the bus clear ended it */
  CHECK(op(0, NINEDOF_I2C_START, 0x53, 1, &ptr) == NINEDOF_TWI_OK && twi.open);
  CHECK(ninedof_twi_abort(&twi) == 0 && !twi.open && ninedof_twi_release(&twi) == 0);
  /* the bounded STOP wait: returns when TWSTO clears, and gives up when
   * it never does (SCL held low) */
  twcr = NINEDOF_TWEN;
  CHECK(ninedof_twi_wait_stop(&twcr) == 1);
  twcr = NINEDOF_TWEN | NINEDOF_TWSTO;
  CHECK(ninedof_twi_wait_stop(&twcr) == 0);
  out_s("Tabort:");
  out_u16(NINEDOF_TWI_ABORTED);
  out_s(":-;");
}

static void test_started_and_fast_paths(void)
{
  /* the master that waits for its START where it asked for it: the same
   * outcome as the interrupt's step; the bounded TWINT wait; the byte-read
   * fast path only while more bytes are to come */
  uint8_t d[3], p = 0x01;
  volatile uint8_t twcr;
  ninedof_twi_init(&twi);
  CHECK(ninedof_twi_started(&twi, NINEDOF_TW_START) == NINEDOF_TWCR_IDLE);  /* none asked */
  CHECK(twi.state == NINEDOF_TWI_IDLE);
  (void)ninedof_twi_begin(&twi, 1, NINEDOF_I2C_START | NINEDOF_I2C_STOP, 0x1E, 3, d);
  CHECK(ninedof_twi_started(&twi, NINEDOF_TW_REP_START) == NINEDOF_TWCR_NEXT);
  CHECK(twi.state == NINEDOF_TWI_ADDR && twi.out == 0x3D);
  CHECK(ninedof_twi_rx_more(&twi, NINEDOF_TW_MR_DATA_ACK) == 0);          /* not reading yet */
  CHECK(ninedof_twi_step(&twi, NINEDOF_TW_MR_SLA_ACK, 0) == NINEDOF_TWCR_NEXT_ACK);
  CHECK(ninedof_twi_rx_more(&twi, NINEDOF_TW_MR_DATA_NACK) == 0);         /* NACKed: the end */
  CHECK(ninedof_twi_rx_more(&twi, NINEDOF_TW_MR_DATA_ACK) == NINEDOF_TWCR_NEXT_ACK);
  ninedof_twi_rx_store(&twi, 7);
  CHECK(ninedof_twi_rx_more(&twi, NINEDOF_TW_MR_DATA_ACK) == NINEDOF_TWCR_NEXT);  /* NACK the last */
  ninedof_twi_rx_store(&twi, 8);
  CHECK(ninedof_twi_rx_more(&twi, NINEDOF_TW_MR_DATA_ACK) == 0);          /* the last: step */
  CHECK(ninedof_twi_step(&twi, NINEDOF_TW_MR_DATA_NACK, 9) == NINEDOF_TWCR_STOP);
  CHECK(d[0] == 7 && d[1] == 8 && d[2] == 9 && twi.state == NINEDOF_TWI_DONE);
  CHECK(twi.result == NINEDOF_TWI_OK && !twi.open);
  /* a START lost to another master, and a bus error at the START: the
   * operation ends, nothing is left open */
  ninedof_twi_init(&twi);
  (void)ninedof_twi_begin(&twi, 0, NINEDOF_I2C_START, 0x53, 1, &p);
  CHECK(ninedof_twi_started(&twi, NINEDOF_TW_ARB_LOST) == NINEDOF_TWCR_RELEASE);
  CHECK(twi.state == NINEDOF_TWI_DONE && twi.result == NINEDOF_TWI_ARB_LOST && !twi.open);
  ninedof_twi_init(&twi);
  (void)ninedof_twi_begin(&twi, 0, NINEDOF_I2C_START, 0x53, 1, &p);
  CHECK(ninedof_twi_started(&twi, NINEDOF_TW_BUS_ERROR) == NINEDOF_TWCR_STOP);
  CHECK(twi.state == NINEDOF_TWI_DONE && twi.result == NINEDOF_TWI_BUS_ERROR && !twi.open);
  /* the bounded TWINT wait: returns when TWINT is set, gives up when not */
  twcr = NINEDOF_TWEN | NINEDOF_TWINT;
  CHECK(ninedof_twi_wait_twint(&twcr) == 1);
  twcr = NINEDOF_TWEN;
  CHECK(ninedof_twi_wait_twint(&twcr) == 0);
}

int main(void)
{
  out_init();
  test_chip_read();
  test_write_stop();
  test_ack_end_and_continue();
  test_write_continue();
  test_bad_args();
  test_addr_nack();
  test_data_nack();
  test_arbitration();
  test_bus_error();
  test_commands();
  test_abort_and_stop_wait();
  test_started_and_fast_paths();
  CHECK(rx_fast >= 12 && starts_inline >= 12);             /* the fast path ran (all but the last byte of most reads) */
  check_summary();
  out_end();
  return 0;
}
