#ifndef ROOMFIX_SIM_FIRMWARE_XBEE_TIMING_H_
#define ROOMFIX_SIM_FIRMWARE_XBEE_TIMING_H_

// When an XBee module's frame is on the air and when the other modules have
// it, modelled on IEEE 802.15.4-2006 unslotted CSMA-CA as Digi's 802.15.4
// firmware (XBee S1, XBee 3 in 802.15.4 mode) runs it. Pure: random draws
// come from the caller's generator, the channel's busy times are the state.
//
// Figures (IEEE 802.15.4-2006, 2.4 GHz O-QPSK PHY; Digi's "XBee/XBee-PRO
// S1 802.15.4 User Guide", RN, MM, RR and BD commands):
// - 250 kbit/s: 32 us a byte; a PPDU has 6 bytes before the MAC frame
//   (4 preamble, 1 SFD, 1 length);
// - MAC frame: 2 frame control, 1 sequence, 2 PAN id, destination (2 for
//   broadcast 0xFFFF or a 16-bit address, 8 for a 64-bit one), source (8
//   for the 64-bit source every XBee sends with MY = 0xFFFF), payload, 2 FCS;
// - a backoff period is 20 symbols = 320 us; CCA lasts 8 symbols = 128 us;
//   RX-to-TX turnaround 12 symbols = 192 us;
// - CSMA-CA: the first backoff is random(0 .. 2^BE - 1) periods with BE =
//   macMinBE, which is the XBee's RN setting, 0 by default: no backoff on a
//   clear channel; a busy CCA raises BE (to macMaxBE = 5) and tries again,
//   at most macMaxCSMABackoffs = 4 times, then the frame is dropped
//   (transmit status 0x02, "CCA failure");
// - unicast frames are acknowledged (11-byte ACK after the turnaround) and
//   retried up to macMaxFrameRetries = 3 times after a 54-symbol (864 us)
//   wait; Digi's RR adds application retries (0 by default); broadcasts are
//   sent once and never acknowledged.
// The module's own processing (UART frame parsed to MAC start, and MAC
// reception to the first byte on its UART) is not in Digi's documentation;
// XbeeTimingOptions carries it as a parameter with its jitter.
#include <cstdint>
#include <deque>
#include <random>
#include <string>

namespace roomfix::firmware {

inline constexpr double kAirByteS = 32e-6;
inline constexpr double kBackoffPeriodS = 320e-6;
inline constexpr double kCcaS = 128e-6;
inline constexpr double kTurnaroundS = 192e-6;
inline constexpr double kAckWaitS = 864e-6;
inline constexpr int kPhyOverheadBytes = 6;
inline constexpr int kAckBytes = 11;

struct XbeeTimingOptions {
  // macMinBE (Digi's RN; 0 by default) and macMaxBE.
  int min_backoff_exponent = 0;
  int max_backoff_exponent = 5;
  int max_csma_backoffs = 4;
  int max_frame_retries = 3;
  // The module from the last byte of a transmit request on its UART to the
  // start of CSMA, and from the end of a received frame on the air to the
  // first byte of its receive frame on the UART: uniform in [min, max].
  // Means: core/radio/device_config.h's RadioTimingModel (100 us each,
  // the firmware's nominal latency), so that the constant part cancels in
  // the firmware's tof_offset_ns; spreads 50 us and 25 us (assumed: Digi
  // publishes neither; docs/devices.md's bring-up measures them).
  double tx_processing_min_s = 75e-6;
  double tx_processing_max_s = 125e-6;
  double rx_processing_min_s = 87.5e-6;
  double rx_processing_max_s = 112.5e-6;

  bool IsValid(std::string* error) const;
};

// The air time of a MAC frame carrying `payload_bytes`, s.
double AirTimeS(int payload_bytes, bool broadcast);

// The shared channel: intervals during which some module transmits.
class AirChannelTimes {
 public:
  // True when a transmission covers any part of [t, t + d).
  bool Busy(double t_s, double d_s) const;
  void Add(double start_s, double end_s);
  // Forgets intervals that ended before t_s.
  void ForgetBefore(double t_s);

 private:
  std::deque<std::pair<double, double>> busy_;
};

// One transmission attempt sequence: when it went on the air and when it
// ended, or that CSMA gave up.
struct Transmission {
  bool sent = false;
  double start_s = 0.0;
  double end_s = 0.0;
  int backoffs = 0;
};

// Runs CSMA-CA from ready_s on `channel` for a frame of `air_s` and marks
// the channel busy for it. draws come from rng.
Transmission Transmit(double ready_s, double air_s, const XbeeTimingOptions& options,
                      AirChannelTimes* channel, std::mt19937_64* rng);

}  // namespace roomfix::firmware

#endif  // ROOMFIX_SIM_FIRMWARE_XBEE_TIMING_H_
