#include "sim/firmware/xbee_timing.h"

#include <algorithm>

namespace roomfix::firmware {

bool XbeeTimingOptions::IsValid(std::string* error) const {
  if (min_backoff_exponent < 0 || max_backoff_exponent < min_backoff_exponent ||
      max_backoff_exponent > 8) {
    *error = "need 0 <= min_backoff_exponent <= max_backoff_exponent <= 8";
    return false;
  }
  if (max_csma_backoffs < 0 || max_csma_backoffs > 5 || max_frame_retries < 0 ||
      max_frame_retries > 7) {
    *error = "max_csma_backoffs must be in [0, 5] and max_frame_retries in [0, 7] (802.15.4)";
    return false;
  }
  if (!(tx_processing_min_s >= 0 && tx_processing_max_s >= tx_processing_min_s &&
        rx_processing_min_s >= 0 && rx_processing_max_s >= rx_processing_min_s)) {
    *error = "processing times need 0 <= min <= max";
    return false;
  }
  return true;
}

double AirTimeS(int payload_bytes, bool broadcast) {
  // Frame control 2, sequence 1, PAN 2, destination 2 or 8, source 8, FCS 2.
  const int mac = 2 + 1 + 2 + (broadcast ? 2 : 8) + 8 + 2;
  return (kPhyOverheadBytes + mac + payload_bytes) * kAirByteS;
}

bool AirChannelTimes::Busy(double t_s, double d_s) const {
  for (const auto& [start, end] : busy_) {
    if (start < t_s + d_s && end > t_s) return true;
  }
  return false;
}

void AirChannelTimes::Add(double start_s, double end_s) { busy_.emplace_back(start_s, end_s); }

void AirChannelTimes::ForgetBefore(double t_s) {
  busy_.erase(std::remove_if(busy_.begin(), busy_.end(),
                             [t_s](const std::pair<double, double>& b) { return b.second < t_s; }),
              busy_.end());
}

Transmission Transmit(double ready_s, double air_s, const XbeeTimingOptions& options,
                      AirChannelTimes* channel, std::mt19937_64* rng) {
  Transmission t;
  double now = ready_s;
  int be = options.min_backoff_exponent;
  for (int nb = 0; nb <= options.max_csma_backoffs; ++nb) {
    const int slots = (1 << be) - 1;
    if (slots > 0) {
      std::uniform_int_distribution<int> pick(0, slots);
      now += pick(*rng) * kBackoffPeriodS;
    }
    t.backoffs = nb;
    if (!channel->Busy(now, kCcaS)) {
      t.sent = true;
      t.start_s = now + kCcaS + kTurnaroundS;
      t.end_s = t.start_s + air_s;
      channel->Add(t.start_s, t.end_s);
      return t;
    }
    now += kCcaS;
    be = std::min(be + 1, options.max_backoff_exponent);
  }
  t.end_s = now;
  return t;
}

}  // namespace roomfix::firmware
