/*
 * ninedof_twi.h -- a lean interrupt-driven TWI (I2C) master for the
 * ATmega1281: the state machine of one I2CPacket operation, in plain C.
 *
 * Used by NineDofTwiMasterP (build option NINEDOF_LEAN_I2C=1) in place of
 * TinyOS's Atm128I2CMasterPacketP.  The module owns the TWI interrupt and
 * does only this per interrupt:
 *
 *     cmd = ninedof_twi_step(&twi, TWSR & 0xF8, TWDR);
 *     TWDR = twi.out;                      (harmless when nothing is sent)
 *     TWCR = cmd;
 *     if (twi.state == NINEDOF_TWI_DONE) signal the outcome, through
 *         NINEDOF_TWI_CALL_SAVING (below)
 *
 * ninedof_twi_begin() starts an operation the same way and returns the first
 * TWCR command.  Nothing here touches a register, so the host tests drive it
 * with a model of the TWI's status codes (tests/c/twi_tests.c).
 *
 * Flags, as TinyOS's I2CPacket defines them (tos/types/I2C.h):
 *   I2C_START    a START (or a repeated START, if the previous operation
 *                ended without STOP) and the address byte first
 *   I2C_STOP     a STOP after the last byte
 *   I2C_ACK_END  (read) ACK the last byte, so a following read without
 *                START continues the transfer; otherwise it is NACKed
 * Without I2C_START the operation continues the transfer the previous one
 * left open (no STOP).  An operation without I2C_STOP leaves SCL held low
 * (TWINT not cleared) until the next operation's command.
 *
 * Outcomes (NINEDOF_TWI_*), mapped to error_t by the nesC module:
 *   OK          SUCCESS
 *   ADDR_NACK   no ACK to the address byte: STOP sent (ENOACK; the stock
 *               master reports EOFF and resets the TWI without a STOP)
 *   DATA_NACK   a written byte was not ACKed: STOP sent (FAIL; the stock
 *               master ignores it and writes on)
 *   ARB_LOST    arbitration lost: the bus is left to the other master (FAIL)
 *   BUS_ERROR   any other status (a bus error, 0x00): the TWI stops itself
 *               (TWSTO without a STOP on the bus, datasheet) (FAIL)
 *   BAD_ARGS    (begin only) nothing to do: no START, no data, no STOP (FAIL)
 *   ABORTED     ended by ninedof_twi_abort: the operation did not end in
 *               time (ninedof_fault.h); the bus has been cleared (ECANCEL)
 *
 * @author motecal
 */
#ifndef NINEDOF_TWI_H
#define NINEDOF_TWI_H

#include <stdint.h>

/* Storage class of the two functions: empty for the host and simavr tests,
 * `static inline` in the nesC build so the interrupt handler has no call. */
#ifndef NINEDOF_TWI_FN
#define NINEDOF_TWI_FN
#endif

/* TWCR bits (ATmega1281 datasheet, 2-wire serial interface) */
enum {
  NINEDOF_TWINT = 0x80,
  NINEDOF_TWEA = 0x40,
  NINEDOF_TWSTA = 0x20,
  NINEDOF_TWSTO = 0x10,
  NINEDOF_TWEN = 0x04,
  NINEDOF_TWIE = 0x01,
};

/* TWSR status codes (prescaler bits masked off), master modes */
enum {
  NINEDOF_TW_BUS_ERROR = 0x00,
  NINEDOF_TW_START = 0x08,
  NINEDOF_TW_REP_START = 0x10,
  NINEDOF_TW_MT_SLA_ACK = 0x18,
  NINEDOF_TW_MT_SLA_NACK = 0x20,
  NINEDOF_TW_MT_DATA_ACK = 0x28,
  NINEDOF_TW_MT_DATA_NACK = 0x30,
  NINEDOF_TW_ARB_LOST = 0x38,
  NINEDOF_TW_MR_SLA_ACK = 0x40,
  NINEDOF_TW_MR_SLA_NACK = 0x48,
  NINEDOF_TW_MR_DATA_ACK = 0x50,
  NINEDOF_TW_MR_DATA_NACK = 0x58,
};

/* I2CPacket flags (the values of TinyOS's tos/types/I2C.h) */
enum {
  NINEDOF_I2C_START = 0x01,
  NINEDOF_I2C_STOP = 0x02,
  NINEDOF_I2C_ACK_END = 0x04,
};

/* Operation states */
enum {
  NINEDOF_TWI_IDLE = 0,    /* no operation (begin() allowed) */
  NINEDOF_TWI_DONE = 1,    /* the operation has ended: outcome in .result */
  NINEDOF_TWI_START = 2,   /* START / repeated START requested */
  NINEDOF_TWI_ADDR = 3,    /* address byte sent */
  NINEDOF_TWI_TX = 4,      /* data byte sent */
  NINEDOF_TWI_RX = 5,      /* data byte being received */
};

/* Outcomes */
enum {
  NINEDOF_TWI_OK = 0,
  NINEDOF_TWI_ADDR_NACK = 1,
  NINEDOF_TWI_DATA_NACK = 2,
  NINEDOF_TWI_ARB_LOST = 3,
  NINEDOF_TWI_BUS_ERROR = 4,
  NINEDOF_TWI_BAD_ARGS = 5,
  NINEDOF_TWI_ABORTED = 6,   /* ended by ninedof_twi_abort (the watchdog) */
};

/* The commands (TWCR values) the machine returns */
enum {
  NINEDOF_TWCR_IDLE = NINEDOF_TWEN,                                      /* on, SCL held if TWINT set */
  NINEDOF_TWCR_START = NINEDOF_TWINT | NINEDOF_TWSTA | NINEDOF_TWEN | NINEDOF_TWIE,
  NINEDOF_TWCR_NEXT = NINEDOF_TWINT | NINEDOF_TWEN | NINEDOF_TWIE,       /* send TWDR / receive + NACK */
  NINEDOF_TWCR_NEXT_ACK = NINEDOF_TWINT | NINEDOF_TWEA | NINEDOF_TWEN | NINEDOF_TWIE,
  NINEDOF_TWCR_STOP = NINEDOF_TWINT | NINEDOF_TWSTO | NINEDOF_TWEN,      /* no interrupt follows */
  NINEDOF_TWCR_RELEASE = NINEDOF_TWINT | NINEDOF_TWEN,                  /* after arbitration lost */
};

typedef struct {
  uint8_t *buf;       /* data written or read */
  uint8_t len;        /* bytes in buf */
  uint8_t *p;         /* the next byte to write or read */
  uint8_t left;       /* bytes still to write or read */
  uint8_t last;       /* the command for the last byte read: NEXT (NACK), or NEXT_ACK with ACK_END */
  uint8_t sla;        /* address byte: addr << 1 | R/W */
  uint8_t flags;      /* I2CPacket flags of the operation */
  uint8_t state;      /* NINEDOF_TWI_* state */
  uint8_t result;     /* outcome once state == DONE */
  uint8_t out;        /* the byte for TWDR with the returned command */
  uint8_t open;       /* 1: a transfer is open (no STOP yet): SCL is held */
} ninedof_twi_t;

#ifdef __AVR__
/* NINEDOF_TWI_CALL_SAVING(fn): call void fn(void) from an interrupt handler
 * that has no other call.  avr-gcc's handler prologue saves only the
 * registers the handler itself uses, but any call in it makes the prologue
 * save every call-clobbered register first (12 pushes, 24 cycles before
 * the TWCR command).  The end of an operation (readDone / writeDone, and
 * the client's next command) goes through this instead: the registers the
 * avr-gcc ABI lets fn clobber (r0, r18-r27, r30, r31) and RAMPZ are saved
 * around the call, after TWCR is written.  r1 is zero in a handler. */
#define NINEDOF_TWI_CALL_SAVING(fn)                                     \
  __asm__ __volatile__(                                                 \
    "push r0\n\tin r0, 0x3b\n\tpush r0\n\t"                              \
    "push r18\n\tpush r19\n\tpush r20\n\tpush r21\n\tpush r22\n\t"       \
    "push r23\n\tpush r24\n\tpush r25\n\tpush r26\n\tpush r27\n\t"       \
    "push r30\n\tpush r31\n\t"                                          \
    "call %x0\n\t"                                                      \
    "pop r31\n\tpop r30\n\tpop r27\n\tpop r26\n\tpop r25\n\tpop r24\n\t"  \
    "pop r23\n\tpop r22\n\tpop r21\n\tpop r20\n\tpop r19\n\tpop r18\n\t"  \
    "pop r0\n\tout 0x3b, r0\n\tpop r0"                                 \
    : : "i" (fn) : "memory")
#endif

/* A STOP goes out within one SCL period, then the TWI clears TWSTO; a
 * slave holding SCL low can delay it for ever.  Every wait for it reads
 * TWCR at most NINEDOF_TWI_STOP_SPINS times (about 6 cycles each: 0.2 ms
 * at 8 MHz, 70 SCL periods at 364 kHz, 10 at the stock 55 kHz) and
 * reports whether the STOP went out; the caller then resets the TWI
 * instead of waiting on, interrupts off. */
enum { NINEDOF_TWI_STOP_SPINS = 255 };

static inline uint8_t ninedof_twi_wait_stop(volatile uint8_t *twcr)
{
  uint8_t n = NINEDOF_TWI_STOP_SPINS;
  while (*twcr & NINEDOF_TWSTO)
    if (--n == 0)
      return 0;
  return 1;
}

/* The next TWINT, when it is due soon: a START (or repeated START) is on
 * the bus within about one SCL period (22 cycles at TWBR 3), a byte
 * within nine (198 cycles).  The master waits for it where it asked for
 * it, reading TWCR at most NINEDOF_TWI_TWINT_SPINS times (about 5 cycles
 * each: 0.1 ms at 8 MHz, 36 SCL periods at 364 kHz): after a START, to
 * send the address byte at once; in the interrupt handler, for the first
 * byte of an operation the client began from its done event.  Taking an
 * interrupt instead costs the handler's entry and exit, and it waits
 * while interrupts are off (the handler running the client's chain, the
 * scheduler's loop before it sleeps).  Returns 1 when TWINT is set; 0
 * when it has not come (the bus is busy: another master, a slave holding
 * SCL), and then the interrupt (TWIE) takes it. */
enum { NINEDOF_TWI_TWINT_SPINS = 160 };

static inline uint8_t ninedof_twi_wait_twint(volatile uint8_t *twcr)
{
  uint8_t n = NINEDOF_TWI_TWINT_SPINS;
  while (!(*twcr & NINEDOF_TWINT))
    if (--n == 0)
      return 0;
  return 1;
}

/* Power-up: no operation, no transfer open. */
void ninedof_twi_init(ninedof_twi_t *t);

/* Start one operation (read = 1: master receiver).  Returns the first TWCR
 * command; .out holds the byte for TWDR.  If the operation ends at once
 * (no START and no data: only a STOP, or nothing at all), state is DONE and
 * the command is the STOP (or NINEDOF_TWCR_IDLE).  The caller makes sure
 * state is IDLE or DONE before. */
NINEDOF_TWI_FN uint8_t ninedof_twi_begin(ninedof_twi_t *t, uint8_t read, uint8_t flags,
                                         uint8_t addr, uint8_t len, uint8_t *buf);

/* One TWI interrupt: status = TWSR & 0xF8, data = TWDR.  Returns the next
 * TWCR command (.out for TWDR); state DONE when the operation has ended. */
NINEDOF_TWI_FN uint8_t ninedof_twi_step(ninedof_twi_t *t, uint8_t status, uint8_t data);

/* A byte read while more are to come (state RX, status MR_DATA_ACK, at
 * least one byte left after this one): the command for the next byte, the
 * same ninedof_twi_step would return; 0 otherwise (then ninedof_twi_step).
 * The handler writes it to TWCR first and stores the byte after
 * (ninedof_twi_rx_store, with TWDR read before): SCL is held only for the
 * decision, and the bookkeeping runs while the next byte is on the wire. */
NINEDOF_TWI_FN uint8_t ninedof_twi_rx_more(const ninedof_twi_t *t, uint8_t status);
NINEDOF_TWI_FN void ninedof_twi_rx_store(ninedof_twi_t *t, uint8_t data);

/* The START the current operation asked for has come (TWINT after the
 * START command; status = TWSR & 0xF8): what ninedof_twi_step does in that
 * state, for a master that waits for the START where it asked for it
 * (ninedof_twi_wait_twint) instead of in its interrupt handler.  Returns
 * the next TWCR command (.out: the address byte); NINEDOF_TWCR_IDLE if no
 * START was asked.  State DONE if the START failed (arbitration lost, bus
 * error). */
NINEDOF_TWI_FN uint8_t ninedof_twi_started(ninedof_twi_t *t, uint8_t status);

/* One TWI interrupt, as every user of the machine runs it (the nesC
 * master, the tests): TWSR and TWDR read, the command written to TWCR
 * (TWDR first when a byte is to be sent).  Returns 1 when the operation
 * has ended (state DONE: the caller reports its outcome). */
static inline __attribute__((always_inline)) uint8_t
ninedof_twi_interrupt(ninedof_twi_t *t, volatile uint8_t *twsr, volatile uint8_t *twdr,
                      volatile uint8_t *twcr)
{
  uint8_t status = *twsr & 0xF8, data = *twdr;
  uint8_t cmd = ninedof_twi_rx_more(t, status);
  if (cmd) {                        /* a byte read, more to come */
    *twcr = cmd;
    ninedof_twi_rx_store(t, data);
    return 0;
  }
  cmd = ninedof_twi_step(t, status, data);
  *twdr = t->out;
  *twcr = cmd;
  return t->state == NINEDOF_TWI_DONE;
}

/* The watchdog gave up on the operation under way (the TWI is reset and
 * the bus cleared by the caller): state DONE, result ABORTED, no transfer
 * open.  Returns 1 if there was an operation to end. */
uint8_t ninedof_twi_abort(ninedof_twi_t *t);

/* The bus is released (Resource.release): the command that ends a transfer
 * left open (STOP), or 0 when there is nothing to end. */
uint8_t ninedof_twi_release(ninedof_twi_t *t);

#endif
