#ifndef ROOMFIX_SIM_PSEUDO_TERMINAL_H_
#define ROOMFIX_SIM_PSEUDO_TERMINAL_H_

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace roomfix {

// The simulated ZigBee coordinator's end of a serial line: a pseudo-terminal
// pair whose slave (device_path(), or the optional symlink to it) the bridge
// opens as it would /dev/ttyUSB0.
//
// Behaviour measured on Linux 6.x (sim/pseudo_terminal_test.cc pins it down):
// - Both sides are raw (cfmakeraw, echo off) from the moment Open returns:
//   the slave's line discipline processes bytes when they arrive, so bytes
//   written while it was still cooked would be echoed back or have
//   0x11/0x13/0x0D translated, even if the reader set raw mode later.
// - The object keeps its own descriptor to the slave. Without it the master
//   reports POLLHUP whenever no bridge has the slave open (a poll loop on
//   master_fd() would spin), and whether master writes then fail with EIO or
//   are queued has differed between kernels. With it, bytes written while
//   no bridge is reading stay queued in the slave (about 14 KiB, then
//   writes fail, see Write); SerialLink discards them when it opens the
//   port, as they describe the past.
// - Destroying the object (or the simulator process dying) closes the
//   master, which hangs up every open slave descriptor: the bridge sees
//   POLLHUP and read() returning 0, as for an unplugged USB adapter. All
//   descriptors are close-on-exec so a child process cannot keep the pair
//   alive after the simulator is gone.
class PseudoTerminal {
 public:
  // How long Write waits for a slow reader before it drops the rest of the
  // bytes. At 115200 baud a whole ZigBee frame takes under 10 ms, so a
  // reader this far behind is stalled or absent.
  static constexpr int kWriteTimeoutMs = 100;

  // Opens a pair. With a non-empty symlink_path, also points a symlink there
  // at the slave so restarted simulators keep one stable path; an existing
  // symlink there is replaced atomically (a bridge never sees the path
  // missing), anything else there is an error. Returns nullptr with a
  // one-line reason on failure.
  static std::unique_ptr<PseudoTerminal> Open(const std::string& symlink_path, std::string* error);

  // Removes the symlink if it still points at this pair's slave (a newer
  // simulator may have taken the path over), then closes the pair.
  ~PseudoTerminal();
  PseudoTerminal(const PseudoTerminal&) = delete;
  PseudoTerminal& operator=(const PseudoTerminal&) = delete;

  // The slave, e.g. "/dev/pts/3".
  const std::string& device_path() const { return device_path_; }
  // "" when none was asked for.
  const std::string& symlink_path() const { return symlink_path_; }
  // Non-blocking; poll it for bytes the bridge writes to the coordinator.
  int master_fd() const { return master_fd_; }

  // Writes all of data to the master, as the coordinator's UART would.
  // Never blocks for more than kWriteTimeoutMs: when the reader does not
  // make room in time, the rest of data is dropped and false is returned
  // with a one-line reason. A frame may then reach the reader truncated
  // (its parser resynchronises on the next start delimiter, as it must on
  // a real line). While the reader stays stalled, later writes do not wait
  // again: they write what fits and fail at once, so a simulator with no
  // bridge attached loses frames as real hardware would, without slowing
  // down. The first complete write ends the stall.
  bool Write(const uint8_t* data, size_t size, std::string* error);

 private:
  PseudoTerminal() = default;

  int master_fd_ = -1;
  // Held so the pair never hangs up while the bridge is away; see above.
  int slave_fd_ = -1;
  std::string device_path_;
  std::string symlink_path_;
  bool stalled_ = false;
};

}  // namespace roomfix

#endif  // ROOMFIX_SIM_PSEUDO_TERMINAL_H_
