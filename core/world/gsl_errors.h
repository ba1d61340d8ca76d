#ifndef ROOMFIX_CORE_WORLD_GSL_ERRORS_H_
#define ROOMFIX_CORE_WORLD_GSL_ERRORS_H_

#include <gsl/gsl_errno.h>

namespace roomfix {

// GSL reports a failure twice: as the status code a function returns, and
// through a process-global error handler whose default prints and aborts.
// roomfix reads every status code (a failed fit is a message and a counter,
// never a crash), so the handler is switched off for good: once, while the
// process starts, by every translation unit that calls GSL including this
// header (static initialisation runs before main, on one thread). It is
// never toggled around a call: the handler is one global pointer, and
// saving and restoring it from two threads at once loses the setting.
// Idempotent; returns true so it can initialise a constant.
inline bool SwitchOffGslErrorHandler() {
  gsl_set_error_handler_off();
  return true;
}

namespace gsl_errors_internal {
// One per including translation unit: whichever is initialised first
// switches the handler off before any of them can call GSL from main.
[[maybe_unused]] static const bool kGslErrorHandlerOff = SwitchOffGslErrorHandler();
}  // namespace gsl_errors_internal

}  // namespace roomfix

#endif  // ROOMFIX_CORE_WORLD_GSL_ERRORS_H_
