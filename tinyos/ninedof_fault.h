/*
 * ninedof_fault.h -- the board's fault handling in plain C: what to do when
 * an I2C operation does not end, when a chip does not answer, and when a
 * chip came back from a power loss with its registers reset.  The nesC
 * board (NineDofBoardP) only carries out the decisions taken here; tests
 * run them with gcc and in simavr (tests/c/fault_tests.c, test_avr.py).
 *
 * Three mechanisms, all counted (ninedof_fault_counters_t, sent in the
 * mote's status message):
 *
 *  1. Watchdog.  The board calls ninedof_fault_tick() once per sampling
 *     period (8 ms) with the time (binary ms of the crystal).  An operation
 *     (a sample read, a start or a stop) that has run NINEDOF_I2C_TIMEOUT_MS
 *     or longer at a tick (16 ms: 16 to 24 ms after it began, with ticks
 *     8 ms apart; a sample read takes 1.5 ms) is aborted: the board clears
 *     the bus (below), re-initialises the TWI and makes the master end the
 *     operation with an error.  If that too does not end it, it is aborted
 *     again NINEDOF_I2C_TIMEOUT_MS later, and so on: the board never stays
 *     stuck, it keeps recovering until the bus works.  Counted in
 *     bus_resets.  The bound is time, not a count of ticks, so ticks that
 *     come in a burst (a late timer catching up) never abort an operation
 *     that has not had its time.
 *
 *  2. Bus clear (UM10204, I2C-bus specification, 3.1.16).  With the TWI
 *     off, SCL is clocked by hand until the slave that holds SDA low (it
 *     was sending when the transfer broke off) lets go, at most 9 pulses,
 *     then a STOP.  ninedof_busclear_step() is the sequence as a state
 *     machine: pin levels in, the pins to drive for the next half period
 *     out.  It never drives SDA low while SCL is high except inside the
 *     STOP, and it ends after at most NINEDOF_BUSCLEAR_MAX_STEPS steps
 *     even if a line stays stuck (reported, not waited for).
 *     The board hands every clear's result to ninedof_fault_cleared().  A
 *     clear that leaves a line low (a line shorted to ground, a chip that
 *     holds SDA through 9 pulses) puts the bus "down": no read or
 *     start/stop is begun (they are refused at once, FAIL: a START would
 *     only wait for a bus that is not free), the watchdog no longer
 *     clears every NINEDOF_I2C_TIMEOUT_MS but once every
 *     NINEDOF_BUSDOWN_RETRY_MS, 256 ms (each clear busy-waits up to ~2 ms:
 *     about 1 % of the CPU instead of 12 %; the bus is up again at most
 *     that long after the line is free), an
 *     operation still under way (the stock master cannot be aborted) is
 *     aborted again on that schedule, and when a clear finds both lines
 *     high the bus is up again and every chip is checked (below) with the
 *     next reads, since a short may have cut their supply too.  Every
 *     clear, after an abort or as such a retry, counts in bus_resets.
 *
 *  3. Configuration check.  Every NINEDOF_CHECK_TICKS ticks one chip (in
 *     turn) has its witness register (NINEDOF_CHIP[chip].witness in
 *     ninedof_board.h) read back after a sample read, under the same bus
 *     grant; after any failed or aborted operation all three are checked,
 *     one per following read.  A chip whose witness is not the configured
 *     value has been reset: the board writes its register table again at
 *     once (chip_reinits).  A check that fails is repeated with the next
 *     read.
 *
 * NACKs: every operation that ended because a chip did not acknowledge
 * (its address or a byte) is counted in nacks.
 */
#ifndef NINEDOF_FAULT_H
#define NINEDOF_FAULT_H

#include <stdint.h>

#ifndef NINEDOF_I2C_TIMEOUT_MS
#define NINEDOF_I2C_TIMEOUT_MS 16       /* binary ms an operation may run before it is aborted */
#endif
#ifndef NINEDOF_BUSDOWN_RETRY_MS
#define NINEDOF_BUSDOWN_RETRY_MS 256    /* binary ms between bus clears while a line stays low */
#endif
#ifndef NINEDOF_CHECK_TICKS
#define NINEDOF_CHECK_TICKS 125         /* one witness read per second (each chip every 3 s) */
#endif

/* Counters (wrap at 65536; the host takes differences) */
typedef struct {
  uint16_t nacks;          /* operations ended by a chip's NACK */
  uint16_t bus_resets;     /* bus clears: hung operations aborted, retries while down */
  uint16_t chip_reinits;   /* chips found reset and configured again */
} ninedof_fault_counters_t;

/* How an operation ended */
enum {
  NINEDOF_OP_OK = 0,
  NINEDOF_OP_NACK = 1,     /* address or data not acknowledged */
  NINEDOF_OP_FAIL = 2,     /* any other error (bus error, refused, wrong chip id) */
  NINEDOF_OP_ABORTED = 3,  /* ended by the watchdog's abort */
};

/* What ninedof_fault_tick asks for */
enum {
  NINEDOF_FAULT_NONE = 0,
  NINEDOF_FAULT_ABORT = 1, /* abort the operation under way and clear the bus */
  NINEDOF_FAULT_CLEAR = 2, /* the bus is down and idle: clear it again (a retry) */
};

enum { NINEDOF_CHECK_NONE = 0xFF };

typedef struct {
  ninedof_fault_counters_t n;
  uint8_t busy;            /* an operation is under way */
  uint16_t since;          /* ... since this time (ms), or its last bus clear */
  uint8_t aborted;         /* the operation under way has been aborted */
  uint8_t down;            /* the last bus clear left a line low */
  uint8_t check_wait;      /* ticks until the next scheduled check */
  uint8_t check_next;      /* chip of the next scheduled check */
  uint8_t check_mask;      /* chips to check with the next reads (bit per chip) */
} ninedof_fault_t;

void ninedof_fault_init(ninedof_fault_t *f);

/* An operation began (the board has asked for the bus) at now_ms. */
void ninedof_fault_begin(ninedof_fault_t *f, uint16_t now_ms);

/* The operation ended with `outcome` (NINEDOF_OP_*); if it had been
 * aborted, it counts as NINEDOF_OP_ABORTED whatever error the master gave.
 * Returns the outcome counted. */
uint8_t ninedof_fault_end(ninedof_fault_t *f, uint8_t outcome);

/* Once per sampling period, from any context, at now_ms:
 * NINEDOF_FAULT_ABORT when the operation under way has run
 * NINEDOF_I2C_TIMEOUT_MS (NINEDOF_BUSDOWN_RETRY_MS while the bus is down;
 * counted in bus_resets; the bound starts again, so a master that still
 * does not end it is aborted again that much later); NINEDOF_FAULT_CLEAR
 * when the bus is down, nothing is under way and the last clear was
 * NINEDOF_BUSDOWN_RETRY_MS ago (counted in bus_resets); else
 * NINEDOF_FAULT_NONE.  Either answer asks for a bus clear whose result goes
 * to ninedof_fault_cleared().  Also moves the check schedule on by one
 * tick. */
uint8_t ninedof_fault_tick(ninedof_fault_t *f, uint16_t now_ms);

/* The bus clear asked for by ninedof_fault_tick ended with `result`
 * (NINEDOF_BC_DONE | NINEDOF_BC_SDA_STUCK / _SCL_STUCK).  A line still low
 * puts the bus down; both lines high bring it up (every chip is checked
 * with the next reads if it was down).  Returns 1 when the bus is up. */
uint8_t ninedof_fault_cleared(ninedof_fault_t *f, uint8_t result);

/* 1 while the bus is down: the board begins no operation (refused, FAIL). */
uint8_t ninedof_fault_bus_down(const ninedof_fault_t *f);

/* A sample read has its nine axes: the chip whose witness to read back now
 * (and removes it from the chips due), or NINEDOF_CHECK_NONE. */
uint8_t ninedof_fault_check_pick(ninedof_fault_t *f);

/* The witness read of `chip` ended with `outcome` and `value`.  Returns 1
 * when the chip must be configured again (its witness is not the
 * configured value); a failed read puts the chip back in the chips due
 * (a NACK is counted).  The sample read before it stands either way. */
uint8_t ninedof_fault_check_done(ninedof_fault_t *f, uint8_t chip, uint8_t outcome,
                                 uint8_t value);

/* The register table of `chip` was written again: counted if it
 * succeeded, else the chip is due for another check (a NACK is counted). */
void ninedof_fault_reinit_done(ninedof_fault_t *f, uint8_t chip, uint8_t outcome);

/* ---------------------------------------------------------------------- */
/* Bus clear                                                               */
/* ---------------------------------------------------------------------- */
enum {
  NINEDOF_BUSCLEAR_PULSES = 9,
  /* SCL held low by a slave (clock stretching) is waited for at most this
   * many half periods per pulse */
  NINEDOF_BUSCLEAR_STRETCH = 20,
  /* upper bound on the steps of one bus clear, whatever the pins do */
  NINEDOF_BUSCLEAR_MAX_STEPS = (NINEDOF_BUSCLEAR_PULSES + 1) * (2 * NINEDOF_BUSCLEAR_STRETCH + 6),
};

/* SCL falling edges (the STOPs' included) are counted in pulses: at most
 * NINEDOF_BUSCLEAR_PULSES + 1.  A STOP is tried as soon as SDA is high; a
 * slave that was sending a 1 bit then shifts its next bit out and may
 * hold SDA again, and the clocking goes on. */
/* ninedof_busclear_step's answer: the lines to drive for the next half
 * period (1 = released: pulled up; 0 = driven low), or DONE with the
 * result. */
enum {
  NINEDOF_BC_SCL = 0x01,           /* SCL released */
  NINEDOF_BC_SDA = 0x02,           /* SDA released */
  NINEDOF_BC_DONE = 0x80,          /* finished: both lines released */
  NINEDOF_BC_SDA_STUCK = 0x04,     /* with DONE: SDA still low */
  NINEDOF_BC_SCL_STUCK = 0x08,     /* with DONE: SCL held low throughout */
};

typedef struct {
  uint8_t phase;
  uint8_t pulses;          /* SCL pulses given */
  uint8_t wait;            /* half periods waited for SCL to go high */
  uint16_t steps;
} ninedof_busclear_t;

/* Start a bus clear: the TWI is off, both lines released. */
void ninedof_busclear_init(ninedof_busclear_t *b);

/* One half period: scl, sda = the levels read now (1 high).  Returns the
 * lines to drive until the next call (NINEDOF_BC_SCL | NINEDOF_BC_SDA bits),
 * or NINEDOF_BC_DONE (| _SDA_STUCK / _SCL_STUCK) with both released. */
uint8_t ninedof_busclear_step(ninedof_busclear_t *b, uint8_t scl, uint8_t sda);

#endif /* NINEDOF_FAULT_H */
