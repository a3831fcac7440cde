/*
 * NineDofReadP -- TinyOS's split-phase Read<> (TEP 114) on a chip driver's
 * async ReadNow<>: readDone is signalled from a task.  One read at a time
 * (EBUSY while one is under way).
 *
 * @author motecal
 */
#include "NineDofChip.h"

generic module NineDofReadP() @safe()
{
  provides interface Read<ninedof_xyz_t>;
  uses interface ReadNow<ninedof_xyz_t>;
}
implementation
{
  bool busy = FALSE;
  error_t result;
  ninedof_xyz_t value;

  task void done() {
    error_t err;
    ninedof_xyz_t v;
    atomic {
      err = result;
      v = value;
      busy = FALSE;
    }
    signal Read.readDone(err, v);
  }

  command error_t Read.read() {
    error_t err;
    atomic {
      if (busy)
        return EBUSY;
      busy = TRUE;
    }
    err = call ReadNow.read();
    if (err != SUCCESS)
      atomic busy = FALSE;
    return err;
  }

  async event void ReadNow.readDone(error_t err, ninedof_xyz_t v) {
    atomic {
      if (!busy)
        return;                     /* another user's read (ReadStream<>) */
      result = err;
      value = v;
    }
    post done();
  }

  default event void Read.readDone(error_t err, ninedof_xyz_t v) { }
}
